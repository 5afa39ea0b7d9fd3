"""Render one image over a Ray cluster.

    import snell.distributed
    image = snell.distributed.render("scenes/cornell-box.xml", spp=4096, address="auto")

The samples of every pixel are split into chunks ([0, 64), [64, 128), ...);
each chunk is a Ray task that renders those samples on a worker and returns
their exact film state (fixed-point sums, see ``src/film/accumulator.rs``).
The driver adds the states as they arrive. Integer sums do not depend on
their order, so the image is **bit-identical** to ``snell.render(scene,
spp=..., seed=...)`` on one machine, whatever the chunk size, the number of
workers or the order in which tasks finish.

* Scene distribution: the scene's folder (its XML and the meshes and
  textures it names, or the folder given as ``assets``) is packed once into
  Ray's object store; each node unpacks it once into a cache folder, and
  each worker process loads the scene once.
  A dictionary's files (its ``filename`` entries) are shipped the same way.
* Tiles (``tiles=``): for films too large for one task, the image is split
  into tiles as well; a tile's state keeps the border its reconstruction
  filter spreads samples into, and the tiles of a chunk add up exactly
  (``FilmState::merge_tiles``): still bit-identical.
* Faults: a task whose worker dies is run again by Ray (``max_retries``).
  With ``checkpoint=PATH.exr`` the driver writes the image and the merged
  state after every chunk (atomically), in the format of the command line's
  ``--write-every``: calling ``render`` again with the same checkpoint
  renders only the chunks it does not hold, and ``snell render SCENE
  --resume PATH.exr`` finishes it too (and the other way round). The tiles
  of a chunk not yet complete are not in the checkpoint.
* Progress: ``progress(fraction, image_so_far)``, as :func:`snell.render`;
  ``preview=PORT`` (or a :class:`snell.Preview`) shows the render in the
  page of ``snell render --preview``.

Command line: ``python -m snell.distributed SCENE --spp N -o OUT.exr
[--address auto] [--chunk-spp K] [--tiles W[xH]] [--checkpoint FILE.exr]
[--checkpoint-every S] [--preview [PORT]]``.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import os
import shutil
import sys
import tempfile
import time
import zipfile
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _array, _mode, _params, _snell, dict_to_xml

if TYPE_CHECKING:
    from ._preview import Preview

PathLike = Union[str, "os.PathLike[str]"]

# Per worker process: scenes loaded, by source key.
_SCENES: Dict[Tuple[Any, ...], Any] = {}


def _pack(folder: str) -> bytes:
    """The files under `folder`, zipped (paths relative to it)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for root, dirs, files in os.walk(folder):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            for name in sorted(files):
                full = os.path.join(root, name)
                z.write(full, os.path.relpath(full, folder))
    return buf.getvalue()


def _unpack(digest: str, packed: bytes) -> str:
    """The folder on this node holding `packed` (unpacked once per node)."""
    base = os.path.join(tempfile.gettempdir(), "snell-distributed", digest)
    if os.path.isfile(os.path.join(base, ".complete")):
        return base
    os.makedirs(os.path.dirname(base), exist_ok=True)
    staging = tempfile.mkdtemp(prefix=digest + ".", dir=os.path.dirname(base))
    with zipfile.ZipFile(io.BytesIO(packed)) as z:
        z.extractall(staging)
    open(os.path.join(staging, ".complete"), "w").close()
    try:
        os.rename(staging, base)
    except OSError:
        # Another worker on this node unpacked it first: use theirs.
        shutil.rmtree(staging, ignore_errors=True)
    return base


def _load(source: Tuple[Any, ...], packed: Optional[bytes]) -> Any:
    key = source
    if key not in _SCENES:
        kind, digest, name, text, params, spp, seed = source
        folder = _unpack(digest, packed) if packed is not None else os.getcwd()
        path = os.path.join(folder, name)
        if kind == "file":
            _SCENES[key] = _snell.load_file(path, dict(params), spp, seed)
        else:
            _SCENES[key] = _snell.load_string(text, path, dict(params), spp, seed)
    return _SCENES[key]


def _render_chunk(source: Tuple[Any, ...], packed: Optional[bytes], mode: str, start: int, end: int, threads: int,
                  tile: Optional[Tuple[int, int, int, int]] = None) -> bytes:
    """A Ray task: samples [start, end) of every pixel (of `tile`, if given),
    as film-state bytes."""
    pid_dir = os.environ.get("SNELL_DISTRIBUTED_PID_DIR")
    if pid_dir:  # testing aid: lets a test kill the worker mid-task
        # Written whole, then renamed into place: a reader must never see a
        # half-written pid (a prefix is another process's pid, which the
        # test would kill).
        path = os.path.join(pid_dir, f"{os.getpid()}-{start}")
        with open(path + ".tmp", "w") as f:
            f.write(str(os.getpid()))
        os.replace(path + ".tmp", path)
    scene = _load(source, packed)
    return _snell.render_samples(scene, mode, start, end, threads, tile)


def chunks(spp: int, chunk_spp: int, held: Sequence[Tuple[int, int]] = ()) -> List[Tuple[int, int]]:
    """Sample ranges of `chunk_spp` covering [0, spp) minus the `held` ones."""
    out = []
    for a in range(0, spp, chunk_spp):
        b = min(a + chunk_spp, spp)
        missing = [(a, b)]
        for h0, h1 in held:
            nxt = []
            for m0, m1 in missing:
                if h1 <= m0 or h0 >= m1:
                    nxt.append((m0, m1))
                    continue
                if m0 < h0:
                    nxt.append((m0, h0))
                if h1 < m1:
                    nxt.append((h1, m1))
            missing = nxt
        out.extend(missing)
    return out


def tiling(width: int, height: int, tiles: Union[int, Tuple[int, int]]) -> List[Tuple[int, int, int, int]]:
    """Tiles (x, y, w, h) of at most `tiles` (an int: square) pixels covering
    a `width` x `height` window, row by row."""
    tw, th = (tiles, tiles) if isinstance(tiles, int) else tiles
    tw, th = int(tw), int(th)
    if tw < 1 or th < 1:
        raise ValueError(f"tiles={tiles!r}: a tile needs at least 1 x 1 pixels")
    return [(x, y, min(tw, width - x), min(th, height - y)) for y in range(0, height, th) for x in range(0, width, tw)]


def _files(d: Any) -> List[str]:
    """The existing files that a scene dictionary names (``filename`` values)."""
    out: List[str] = []
    if isinstance(d, Mapping):
        for k, v in d.items():
            if k == "filename" and isinstance(v, (str, os.PathLike)) and os.path.isfile(os.fspath(v)):
                out.append(os.path.abspath(os.fspath(v)))
            else:
                out.extend(_files(v))
    return out


def _relocated(d: Any, names: Mapping[str, str]) -> Any:
    """`d` with the ``filename`` values in `names` replaced by theirs."""
    if not isinstance(d, Mapping):
        return d
    out = {}
    for k, v in d.items():
        if k == "filename" and isinstance(v, (str, os.PathLike)) and os.path.isfile(os.fspath(v)):
            out[k] = names[os.path.abspath(os.fspath(v))]
        else:
            out[k] = _relocated(v, names)
    return out


def _pack_files(files: Sequence[str]) -> Tuple[bytes, Dict[str, str]]:
    """The files zipped, each as ``files/<k>/<its name>``, and those names."""
    names: Dict[str, str] = {}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(set(files)):
            names[f] = f"files/{len(names)}/{os.path.basename(f)}"
            z.write(f, names[f])
    return buf.getvalue(), names


def _checkpoint_path(checkpoint: PathLike) -> str:
    path = os.fspath(checkpoint)
    if not path.lower().endswith(".exr"):
        raise ValueError(f"checkpoint {path}: a checkpoint is an .exr (the image, with the exact state in its header, as the "
                         "command line's --write-every writes); name it NAME.exr")
    return path


def render(
    scene: Union[PathLike, Mapping[str, Any]],
    spp: Optional[int] = None,
    *,
    address: Optional[str] = None,
    chunk_spp: Optional[int] = None,
    tiles: Optional[Union[int, Tuple[int, int]]] = None,
    seed: int = 0,
    mode: Optional[str] = None,
    params: Optional[Mapping[str, Any]] = None,
    assets: Optional[PathLike] = None,
    threads_per_task: int = 1,
    checkpoint: Optional[PathLike] = None,
    checkpoint_every: float = 0.0,
    progress: Optional[Callable[[float, np.ndarray], Any]] = None,
    preview: Optional[Union[int, "Preview"]] = None,
    max_retries: int = 3,
) -> np.ndarray:
    """Render `scene` (an XML file, or Mitsuba's dictionary form) on a Ray
    cluster and return the image as :func:`snell.render` does — the same
    array, bit for bit, for the same spp, seed and mode.

    * ``address``: the cluster (``"auto"``, ``"ray://host:10001"``); None
      uses a cluster already joined by ``ray.init`` or starts a local one;
    * ``chunk_spp``: samples per task (default: about four tasks per CPU of
      the cluster);
    * ``tiles``: also split the image into tiles of at most this many
      pixels (an int: square tiles; or (width, height)), for films too
      large for one task: a task is then a chunk of samples of one tile, and
      each worker keeps only its tile and the border its filter reaches.
      The image is still bit-identical;
    * ``params``: the scene's ``<default>`` parameters (``-D``);
    * ``assets``: the folder shipped to the workers (default: the scene
      file's folder; for a dictionary, the files its ``filename`` entries
      name);
    * ``threads_per_task``: worker threads (and Ray CPUs) per task;
    * ``checkpoint``: an ``.exr`` holding the image and the exact state of
      the chunks merged so far, written atomically (at most every
      ``checkpoint_every`` seconds, and at the end) in the command line's
      format: ``snell render SCENE --resume CHECKPOINT.exr`` finishes it,
      and an existing one (also one the command line wrote) is resumed;
    * ``progress(fraction, image)``: called after every chunk;
    * ``preview``: a port (0: any free one; the page's address is printed)
      or a :class:`snell.Preview` to show the render in, after every chunk.
      The page's Stop button ends the render with the chunks merged so far.
    """
    import ray

    from . import Preview, read

    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
    mode = _mode(mode)
    given = _params(params or {})
    defines = [f"{k}={v}" for k, v in given.items()]
    packed_bytes: Optional[bytes] = None
    if isinstance(scene, Mapping):
        text = dict_to_xml(scene)
        source_bytes = text.encode()
        folder = os.fspath(assets) if assets is not None else None
        name = "<dict>"
        local = _snell.load_string(text, os.path.join(folder or os.getcwd(), name), given, spp, seed)
        kind = "xml"
        if folder is None:
            # Ship the files the dictionary names; workers read them from the
            # unpacked folder (relative names resolve against the scene's).
            files = _files(scene)
            if files:
                packed_bytes, names = _pack_files(files)
                text = dict_to_xml(_relocated(scene, names))
    else:
        path = os.path.abspath(os.fspath(scene))
        folder = os.fspath(assets) if assets is not None else os.path.dirname(path)
        name = os.path.relpath(path, folder)
        text = ""
        with open(path, "rb") as f:
            source_bytes = f.read()
        local = _snell.load_file(path, given, spp, seed)
        kind = "file"
    # The driver loads the scene too: errors show here, and it knows the
    # sample count (as the sampler rounds it).
    total = local.spp
    if folder is not None:
        packed_bytes = _pack(folder)
    digest = hashlib.sha256((packed_bytes or b"") + name.encode() + text.encode()).hexdigest()[:24]
    source = (kind, digest, name, text, tuple(sorted(given.items())), spp, seed)

    state: Optional[bytes] = None
    held: List[Tuple[int, int]] = []
    ckpt = _checkpoint_path(checkpoint) if checkpoint is not None else None
    if ckpt is not None and os.path.exists(ckpt):
        state = _snell.checkpoint_read(local, source_bytes, defines, mode, ckpt)
        if state is None:
            # A finished render of the command line (it keeps no state).
            return read(ckpt)
        ranges, _, _ = _snell.state_info(state)
        held = list(ranges)

    _, _, width, height = local.crop
    rects: List[Optional[Tuple[int, int, int, int]]] = [None] if tiles is None else list(tiling(width, height, tiles))
    cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
    if chunk_spp is None:
        chunk_spp = max(1, -(-total // max(1, (4 * cpus) // len(rects))))
    todo = chunks(total, int(chunk_spp), held)

    own_preview = isinstance(preview, int) and not isinstance(preview, bool)
    view: Optional[Preview] = Preview(preview, mode=mode, size=(width, height)) if own_preview else (preview or None)
    if own_preview:
        print(f"preview: {view.url}", file=sys.stderr)
    task = ray.remote(_render_chunk).options(max_retries=max_retries, num_cpus=threads_per_task)
    packed = ray.put(packed_bytes) if packed_bytes is not None else None
    # Chunk-major: the tiles of a chunk finish together, so few chunks wait
    # for their last tile.
    jobs = [(k, rect) for k in range(len(todo)) for rect in rects]
    # At most two tasks per worker slot in flight, submitted as others end.
    # A render that stops (Ctrl-C, an exception in `progress`, the preview's
    # Stop) then leaves at most these to finish in the background, their
    # results dropped: it cancels nothing, because `ray.cancel` on a task
    # whose reply is on its way crashes the driver in Ray 2.60 ("Check
    # failed: it != submissible_tasks_.end()", Ray's issue 54846), the
    # user's Python process with it.
    window = 2 * max(1, cpus // max(1, threads_per_task))
    pending: Dict[Any, Tuple[int, Optional[Tuple[int, int, int, int]]]] = {}
    submitted = 0

    def submit() -> None:
        nonlocal submitted
        while submitted < len(jobs) and len(pending) < window:
            k, rect = jobs[submitted]
            a, b = todo[k]
            pending[task.remote(source, packed, mode, a, b, threads_per_task, rect)] = (k, rect)
            submitted += 1

    submit()
    parts: Dict[int, List[bytes]] = {}
    done_spp = sum(b - a for a, b in held)
    merged = 0
    last_write = time.monotonic()
    stopped = False
    try:
        while pending:
            if view is not None and view.stop_requested:
                stopped = True
                break
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=0.25)
            for ref in ready:
                k, rect = pending.pop(ref)
                part = ray.get(ref)
                if rect is None:
                    state = part if state is None else _snell.state_merge(state, part)
                else:
                    parts.setdefault(k, []).append(part)
                    if len(parts[k]) < len(rects):
                        continue
                    state = _snell.state_merge_tiles(state, parts.pop(k))
                a, b = todo[k]
                done_spp += b - a
                merged += 1
                if ckpt is not None and ((not pending and submitted == len(jobs)) or time.monotonic() - last_write >= checkpoint_every):
                    _snell.checkpoint_write(local, source_bytes, defines, mode, state, ckpt)
                    last_write = time.monotonic()
                if view is not None:
                    view.update(state, done_spp, total, pass_=merged, passes=len(todo))
                if progress is not None:
                    data, h, w, names, _ = _snell.state_develop(state)
                    progress(done_spp / total, _array(data, h, w, names))
            submit()
    except BaseException:
        if view is not None:
            view.finish(interrupted=True)
        if own_preview:
            view.close()
        raise
    if stopped and ckpt is not None and state is not None:
        _snell.checkpoint_write(local, source_bytes, defines, mode, state, ckpt)
    if view is not None:
        view.finish(interrupted=stopped)
        if own_preview:
            view.close()
    if state is None:
        raise RuntimeError("no samples were rendered" + (" (stopped from the preview page)" if stopped else ""))
    data, h, w, names, _ = _snell.state_develop(state)
    return _array(data, h, w, names)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m snell.distributed", description="Render a Mitsuba 3 XML scene on a Ray cluster.")
    ap.add_argument("scene")
    ap.add_argument("-o", "--output", required=True, help=".exr, .png or .pfm")
    ap.add_argument("--spp", type=int)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mode", default=None)
    ap.add_argument("--address", default=None, help='the Ray cluster ("auto" to join the local one)')
    ap.add_argument("--chunk-spp", type=int)
    ap.add_argument("--tiles", metavar="W[xH]", help="also split the image into tiles of at most W x H pixels")
    ap.add_argument("--preview", type=int, nargs="?", const=8730, metavar="PORT",
                    help="watch the render in the browser (the page of snell render --preview; 0: any free port)")
    ap.add_argument("--checkpoint-every", type=float, default=0.0, metavar="S")
    ap.add_argument("--threads-per-task", type=int, default=1)
    ap.add_argument("--checkpoint", metavar="FILE.exr",
                    help="keep the merged state in this .exr (snell render --resume reads it); resumed if it exists")
    ap.add_argument("-D", action="append", default=[], metavar="NAME=VALUE")
    args = ap.parse_args(argv)
    params = dict(d.split("=", 1) for d in args.D)
    tiles = None
    if args.tiles:
        w, _, h = args.tiles.lower().partition("x")
        tiles = (int(w), int(h or w))
    from . import write

    start = time.time()
    image = render(args.scene, args.spp, address=args.address, chunk_spp=args.chunk_spp, seed=args.seed, mode=args.mode,
                   params=params, threads_per_task=args.threads_per_task, checkpoint=args.checkpoint,
                   checkpoint_every=args.checkpoint_every, tiles=tiles, preview=args.preview,
                   progress=lambda f, _img: print(f"\r{100 * f:5.1f} %", end="", file=sys.stderr))
    print(file=sys.stderr)
    write(image, args.output)
    print(f"rendered {image.shape[1]}x{image.shape[0]} in {time.time() - start:.1f} s -> {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

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
* Faults: a task whose worker dies is run again by Ray (``max_retries``).
  With ``checkpoint=PATH`` the driver writes the merged state after every
  chunk (atomically: temporary file and rename); calling ``render`` again
  with the same checkpoint renders only the chunks it does not hold.
* Progress: ``progress(fraction, image_so_far)``, as :func:`snell.render`.

Command line: ``python -m snell.distributed SCENE --spp N -o OUT.exr
[--address auto] [--chunk-spp K] [--checkpoint FILE]``.
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
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _array, _mode, _params, _snell, dict_to_xml

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


def _render_chunk(source: Tuple[Any, ...], packed: Optional[bytes], mode: str, start: int, end: int, threads: int) -> bytes:
    """A Ray task: samples [start, end) of every pixel, as film-state bytes."""
    pid_dir = os.environ.get("SNELL_DISTRIBUTED_PID_DIR")
    if pid_dir:  # testing aid: lets a test kill the worker mid-task
        with open(os.path.join(pid_dir, f"{os.getpid()}-{start}"), "w") as f:
            f.write(str(os.getpid()))
    scene = _load(source, packed)
    return _snell.render_samples(scene, mode, start, end, threads)


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


def _write_atomically(path: str, data: bytes) -> None:
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".snell-checkpoint-", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def render(
    scene: Union[PathLike, Mapping[str, Any]],
    spp: Optional[int] = None,
    *,
    address: Optional[str] = None,
    chunk_spp: Optional[int] = None,
    seed: int = 0,
    mode: Optional[str] = None,
    params: Optional[Mapping[str, Any]] = None,
    assets: Optional[PathLike] = None,
    threads_per_task: int = 1,
    checkpoint: Optional[PathLike] = None,
    progress: Optional[Callable[[float, np.ndarray], Any]] = None,
    max_retries: int = 3,
) -> np.ndarray:
    """Render `scene` (an XML file, or Mitsuba's dictionary form) on a Ray
    cluster and return the image as :func:`snell.render` does — the same
    array, bit for bit, for the same spp, seed and mode.

    * ``address``: the cluster (``"auto"``, ``"ray://host:10001"``); None
      uses a cluster already joined by ``ray.init`` or starts a local one;
    * ``chunk_spp``: samples per task (default: about four tasks per CPU of
      the cluster);
    * ``params``: the scene's ``<default>`` parameters (``-D``);
    * ``assets``: the folder shipped to the workers (default: the scene
      file's folder; for a dictionary, none — its files must be reachable
      on every node by absolute path);
    * ``threads_per_task``: worker threads (and Ray CPUs) per task;
    * ``checkpoint``: a file holding the merged state after every chunk; an
      existing one is resumed;
    * ``progress(fraction, image)``: called after every chunk.
    """
    import ray

    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
    mode = _mode(mode)
    given = _params(params or {})
    if isinstance(scene, Mapping):
        text = dict_to_xml(scene)
        digest = hashlib.sha256(text.encode()).hexdigest()[:24]
        folder = os.fspath(assets) if assets is not None else None
        name = "<dict>"
        local = _snell.load_string(text, os.path.join(folder or os.getcwd(), name), given, spp, seed)
        kind = "xml"
    else:
        path = os.path.abspath(os.fspath(scene))
        folder = os.fspath(assets) if assets is not None else os.path.dirname(path)
        name = os.path.relpath(path, folder)
        text = ""
        local = _snell.load_file(path, given, spp, seed)
        kind = "file"
    # The driver loads the scene too: errors show here, and it knows the
    # sample count (as the sampler rounds it).
    total = local.spp
    packed_bytes = _pack(folder) if folder is not None else None
    if packed_bytes is not None:
        digest = hashlib.sha256(packed_bytes + name.encode() + text.encode()).hexdigest()[:24]
    source = (kind, digest, name, text, tuple(sorted(given.items())), spp, seed)

    state: Optional[bytes] = None
    held: List[Tuple[int, int]] = []
    if checkpoint is not None and os.path.exists(checkpoint):
        with open(checkpoint, "rb") as f:
            state = f.read()
        ranges, count, complete = _snell.state_info(state)
        if count != total or not complete:
            raise ValueError(f"checkpoint {os.fspath(checkpoint)} is of another render ({count} spp, complete={complete}); delete it or render with the same scene, spp, seed and mode")
        held = list(ranges)

    if chunk_spp is None:
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        chunk_spp = max(1, -(-total // (4 * cpus)))
    todo = chunks(total, int(chunk_spp), held)
    task = ray.remote(_render_chunk).options(max_retries=max_retries, num_cpus=threads_per_task)
    packed = ray.put(packed_bytes) if packed_bytes is not None else None
    pending = {task.remote(source, packed, mode, a, b, threads_per_task): (a, b) for a, b in todo}
    done_spp = sum(b - a for a, b in held)
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            a, b = pending.pop(ref)
            part = ray.get(ref)
            state = part if state is None else _snell.state_merge(state, part)
            done_spp += b - a
            if checkpoint is not None:
                _write_atomically(os.fspath(checkpoint), state)
            if progress is not None:
                data, h, w, names, _ = _snell.state_develop(state)
                try:
                    progress(done_spp / total, _array(data, h, w, names))
                except BaseException:
                    for r in pending:
                        ray.cancel(r)
                    raise
    if state is None:
        raise RuntimeError("no samples were rendered")
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
    ap.add_argument("--threads-per-task", type=int, default=1)
    ap.add_argument("--checkpoint")
    ap.add_argument("-D", action="append", default=[], metavar="NAME=VALUE")
    args = ap.parse_args(argv)
    params = dict(d.split("=", 1) for d in args.D)
    from . import write

    start = time.time()
    image = render(args.scene, args.spp, address=args.address, chunk_spp=args.chunk_spp, seed=args.seed, mode=args.mode,
                   params=params, threads_per_task=args.threads_per_task, checkpoint=args.checkpoint,
                   progress=lambda f, _img: print(f"\r{100 * f:5.1f} %", end="", file=sys.stderr))
    print(file=sys.stderr)
    write(image, args.output)
    print(f"rendered {image.shape[1]}x{image.shape[0]} in {time.time() - start:.1f} s -> {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

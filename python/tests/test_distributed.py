"""snell.distributed on a local Ray cluster: the image equals the one-machine
render bit for bit, also when a worker is killed mid-task and when the
driver is interrupted and resumed from its checkpoint."""

import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

import snell

ray = pytest.importorskip("ray")
import snell.distributed as dist  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "cornell-box.xml"
PARAMS = {"res": 48}
SPP = 24


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    pid_dir = tmp_path_factory.mktemp("pids")
    # Two worker CPUs; the env var makes each task note its worker's pid (a testing aid).
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"SNELL_DISTRIBUTED_PID_DIR": str(pid_dir)}})
    yield pid_dir
    ray.shutdown()


@pytest.fixture(scope="module")
def reference():
    scene = snell.load_file(SCENE, **PARAMS)
    return snell.render(scene, spp=SPP, seed=3, threads=1)


def test_chunks_cover_the_range_once():
    assert dist.chunks(10, 4) == [(0, 4), (4, 8), (8, 10)]
    assert dist.chunks(10, 4, held=[(0, 4), (8, 10)]) == [(4, 8)]
    assert dist.chunks(10, 4, held=[(2, 6)]) == [(0, 2), (6, 8), (8, 10)]


def test_distributed_image_equals_the_single_machine_image(cluster, reference):
    image = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=5)
    assert image.shape == reference.shape
    assert np.array_equal(image, reference)
    # Another split gives the same bits.
    again = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=7)
    assert np.array_equal(again, reference)
    # A different seed does not (the test can fail).
    other = dist.render(SCENE, SPP, seed=4, params=PARAMS, chunk_spp=12)
    assert not np.array_equal(other, reference)


def test_dict_scene(cluster):
    d = {
        "type": "scene",
        "integrator": {"type": "path"},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": snell.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 24, "height": 16},
                   "sampler": {"type": "independent", "sample_count": 8}},
        "light": {"type": "constant", "radiance": {"type": "rgb", "value": [1, 1, 1]}},
        "ball": {"type": "sphere", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.2, 0.5, 0.8]}}},
    }
    one = snell.render(snell.load_dict(d), spp=8, seed=0, threads=1)
    image = dist.render(d, 8, seed=0, chunk_spp=3)
    assert np.array_equal(image, one)


def test_a_worker_killed_mid_task_costs_only_that_task(cluster, reference):
    pid_dir = cluster
    for f in pid_dir.iterdir():
        f.unlink()
    killed = []

    def killer():
        deadline = time.time() + 60
        while time.time() < deadline and not killed:
            for f in sorted(pid_dir.iterdir()):
                if f.suffix == ".tmp":
                    continue
                pid = int(f.read_text() or 0)
                if pid:
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)
                    return
            time.sleep(0.005)

    t = threading.Thread(target=killer)
    t.start()
    image = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=4, max_retries=3)
    t.join()
    assert killed, "no worker was killed"
    assert np.array_equal(image, reference)


def _checkpoint_ranges(path, spp=SPP, seed=3, params=PARAMS):
    """The sample ranges a checkpoint .exr holds (read as --resume reads it)."""
    given = snell._params(params)
    native = snell._snell.load_file(str(SCENE), given, spp, seed)
    state = snell._snell.checkpoint_read(native, SCENE.read_bytes(), [f"{k}={v}" for k, v in given.items()], "rgb", str(path))
    ranges, count, complete = snell._snell.state_info(state)
    assert count == spp and complete
    return ranges


def _interrupted(checkpoint, after=2, **kw):
    """A distributed render stopped (KeyboardInterrupt) after `after` chunks."""
    calls = []

    def interrupt(fraction, image):
        calls.append(fraction)
        if len(calls) == after:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=4, checkpoint=checkpoint, progress=interrupt, **kw)


def test_an_interrupted_driver_resumes_from_its_checkpoint(cluster, reference, tmp_path):
    checkpoint = tmp_path / "render.exr"
    _interrupted(checkpoint)
    assert checkpoint.exists()
    held = sum(b - a for a, b in _checkpoint_ranges(checkpoint))
    assert 0 < held < SPP
    # The checkpoint is an image too: that of the samples it holds.
    assert snell.read(checkpoint).shape == reference.shape
    fractions = []
    image = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=4, checkpoint=checkpoint,
                        progress=lambda f, _img: fractions.append(f))
    assert np.array_equal(image, reference)
    # Only the missing chunks were rendered on resume.
    assert len(fractions) == (SPP - held + 3) // 4
    assert fractions[-1] == 1.0
    # The finished checkpoint keeps its state: rendering again renders nothing.
    again = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=4, checkpoint=checkpoint,
                        progress=lambda f, _img: fractions.append(-1))
    assert np.array_equal(again, reference) and -1 not in fractions
    # A checkpoint of another render is refused.
    with pytest.raises(ValueError, match="another render"):
        dist.render(SCENE, SPP * 2, seed=3, params=PARAMS, chunk_spp=4, checkpoint=checkpoint)
    with pytest.raises(ValueError, match="another render"):
        dist.render(SCENE, SPP, seed=4, params=PARAMS, chunk_spp=4, checkpoint=checkpoint)
    with pytest.raises(ValueError, match=r"\.exr"):
        dist.render(SCENE, SPP, seed=3, params=PARAMS, checkpoint=tmp_path / "render.state")


def _cli(*args):
    """The command line (the extension's), in a process of its own."""
    code = "import sys, snell; sys.exit(snell._snell.cli_main(['snell'] + sys.argv[1:]))"
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, timeout=300)


def test_the_command_line_finishes_a_distributed_checkpoint(cluster, reference, tmp_path):
    checkpoint = tmp_path / "farm.exr"
    _interrupted(checkpoint, after=3, tiles=(20, 17))
    held = _checkpoint_ranges(checkpoint)
    assert 0 < sum(b - a for a, b in held) < SPP
    r = _cli("render", SCENE, "-D", "res=48", "--spp", SPP, "--seed", 3, "--threads", 1, "--resume", checkpoint)
    assert r.returncode == 0, r.stderr
    assert np.array_equal(snell.read(checkpoint), reference)


def test_a_distributed_render_finishes_a_command_line_checkpoint(cluster, tmp_path):
    # A render slow enough (against polling every millisecond) to copy one of
    # its checkpoints before it ends: they are written atomically, so a copy
    # is always a whole file.
    spp, params = 256, {"res": 32}
    out, snapshot = tmp_path / "cli.exr", tmp_path / "snapshot.exr"
    code = "import sys, snell; sys.exit(snell._snell.cli_main(['snell'] + sys.argv[1:]))"
    args = ["render", SCENE, "-D", "res=32", "--spp", spp, "--seed", 3, "--threads", 1, "--passes", 8,
            "--write-every", 0, "-o", out, "--quiet"]
    p = subprocess.Popen([sys.executable, "-c", code, *map(str, args)])
    while not snapshot.exists():
        try:
            shutil.copyfile(out, snapshot)
        except FileNotFoundError:
            assert p.poll() is None or out.exists(), "the command line wrote no checkpoint"
            time.sleep(0.001)
    assert p.wait(timeout=300) == 0
    held = _checkpoint_ranges(snapshot, spp=spp, params=params)
    assert held[0][0] == 0 and 0 < held[-1][1] < spp, held
    image = dist.render(SCENE, spp, seed=3, params=params, chunk_spp=64, checkpoint=snapshot)
    assert np.array_equal(image, snell.read(out))


def test_tiles_merge_into_exactly_the_single_machine_image(cluster, reference):
    scene = snell.load_file(SCENE, **PARAMS)
    assert "gaussian" in SCENE.read_text()  # radius 2: tiles overlap by 3 pixels
    assert dist.tiling(48, 48, (20, 17)) == [(x, y, min(20, 48 - x), min(17, 48 - y)) for y in (0, 17, 34) for x in (0, 20, 40)]
    image = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=12, tiles=(20, 17))
    assert image.shape == reference.shape == (scene.size[1], scene.size[0], 3)
    assert np.array_equal(image, reference)
    # Square tiles that do not divide the image, and one chunk.
    assert np.array_equal(dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=SPP, tiles=13), reference)


def _get(url):
    with urllib.request.urlopen(url, timeout=10) as r:
        return r.read()


def test_the_preview_page_shows_a_distributed_render(cluster, reference):
    seen = []
    with snell.Preview(port=0) as preview:
        assert preview.url.startswith("http://127.0.0.1:")
        progress = json.loads(_get(preview.url + "progress"))
        assert progress["spp_done"] == 0 and progress["state"] == "starting"

        def check(fraction, image):
            p = json.loads(_get(preview.url + "progress"))
            frame = _get(preview.url + "image")
            assert frame[:4] == b"SNPV"
            version, w, h, layers, pass_, passes, spp_done = struct.unpack("<7I", frame[4:32])
            rgb = np.frombuffer(frame[32:], dtype="<f4").reshape(h, w, 3)
            # What the page shows is the image so far, bit for bit.
            assert (w, h, layers) == (48, 48, 1) and np.array_equal(rgb, image[:, :, :3])
            assert p["spp_done"] == spp_done == round(fraction * SPP) and p["pass"] == pass_
            seen.append(spp_done)

        image = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=8, preview=preview, progress=check)
        assert np.array_equal(image, reference)
        assert sorted(seen) == seen and seen[-1] == SPP and len(seen) == 3
        done = json.loads(_get(preview.url + "progress"))
        assert done["state"] == "done" and done["spp_total"] == SPP
        # update() also takes an array (an image of your own render loop).
        preview.update(np.ones((4, 6, 3), np.float32), spp_done=1, spp_total=2)
        frame = _get(preview.url + "image")
        assert struct.unpack("<2I", frame[8:16]) == (6, 4)
        assert np.all(np.frombuffer(frame[32:], dtype="<f4") == 1.0)


def test_the_preview_stop_button_ends_a_distributed_render(cluster, reference, tmp_path):
    checkpoint = tmp_path / "stopped.exr"
    shown = []
    with snell.Preview(port=0) as preview:
        def stop(fraction, image):
            shown.append(image)
            if len(shown) == 1:
                req = urllib.request.Request(preview.url + "stop", method="POST", data=b"",
                                             headers={"Origin": preview.url.rstrip("/")})
                assert json.loads(_get(req))["stopping"] is True
                assert preview.stop_requested

        image = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=4, preview=preview, progress=stop,
                            checkpoint=checkpoint)
        assert json.loads(_get(preview.url + "progress"))["state"] == "stopped"
    # The image of the chunks merged when Stop was seen: not all of them.
    assert np.array_equal(image, shown[-1]) and len(shown) < SPP // 4
    assert not np.array_equal(image, reference)
    held = sum(b - a for a, b in _checkpoint_ranges(checkpoint))
    assert held == 4 * len(shown)


def test_dict_scene_files_are_shipped(cluster, tmp_path):
    mesh = tmp_path / "torus.obj"
    shutil.copyfile(ROOT / "tests" / "scenes" / "assets" / "torus.obj", mesh)
    d = {
        "type": "scene",
        "integrator": {"type": "path"},
        "sensor": {"type": "perspective", "fov": 40,
                   "to_world": snell.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 24, "height": 16},
                   "sampler": {"type": "independent", "sample_count": 4}},
        "light": {"type": "constant"},
        "torus": {"type": "obj", "filename": str(mesh)},
    }
    packed, names = dist._pack_files(dist._files(d))
    assert names == {str(mesh): "files/0/torus.obj"}
    assert dist._relocated(d, names)["torus"]["filename"] == "files/0/torus.obj"
    one = snell.render(snell.load_dict(d), spp=4, seed=0, threads=1)
    assert np.array_equal(dist.render(d, 4, seed=0, chunk_spp=2), one)

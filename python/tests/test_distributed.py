"""snell.distributed on a local Ray cluster: the image equals the one-machine
render bit for bit, also when a worker is killed mid-task and when the
driver is interrupted and resumed from its checkpoint."""

import os
import signal
import threading
import time
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


def test_an_interrupted_driver_resumes_from_its_checkpoint(cluster, reference, tmp_path):
    checkpoint = tmp_path / "render.state"
    calls = []

    def interrupt(fraction, image):
        calls.append(fraction)
        if len(calls) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=4, checkpoint=checkpoint, progress=interrupt)
    assert checkpoint.exists()
    ranges, count, complete = snell._snell.state_info(checkpoint.read_bytes())
    held = sum(b - a for a, b in ranges)
    assert count == SPP and complete and 0 < held < SPP
    fractions = []
    image = dist.render(SCENE, SPP, seed=3, params=PARAMS, chunk_spp=4, checkpoint=checkpoint,
                        progress=lambda f, _img: fractions.append(f))
    assert np.array_equal(image, reference)
    # Only the missing chunks were rendered on resume.
    assert len(fractions) == (SPP - held + 3) // 4
    assert fractions[-1] == 1.0
    # A checkpoint of another render is refused.
    with pytest.raises(ValueError, match="another render"):
        dist.render(SCENE, SPP * 2, seed=3, params=PARAMS, chunk_spp=4, checkpoint=checkpoint)

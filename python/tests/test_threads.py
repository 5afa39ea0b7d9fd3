"""The GIL is released while rendering, and Ctrl-C stops a render promptly."""

import os
import signal
import threading
import time

import numpy as np
import pytest

import snell


def slow_scene(cornell):
    # Minutes of work on two cores if nothing stopped it, in small units (a
    # tile row: 16 pixels x 512 samples) that a stop request lets finish.
    return snell.load_file(cornell, res=512, max_depth=16)


@pytest.mark.skipif(not hasattr(signal, "SIGINT") or os.name == "nt", reason="needs POSIX signals")
def test_keyboard_interrupt_stops_a_render_within_a_second(cornell):
    scene = slow_scene(cornell)
    sent = []

    def interrupt():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Timer(0.5, interrupt)
    timer.start()
    start = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        snell.render(scene, spp=512)
    end = time.perf_counter()
    timer.join()
    assert sent, "the timer never fired"
    assert end - sent[0] < 1.0, f"the render went on for {end - sent[0]:.2f} s after Ctrl-C"
    assert end - start < 2.0
    # the scene is still usable afterwards
    assert snell.render(snell.load_file(cornell, res=8), spp=1).shape == (8, 8, 3)


def test_other_python_threads_run_during_a_render(cornell):
    scene = snell.load_file(cornell, res=96)
    counts = []
    stop = threading.Event()

    def count():
        n = 0
        while not stop.is_set():
            n += 1
            if n % 1000 == 0:
                counts.append((time.perf_counter(), n))

    worker = threading.Thread(target=count)
    worker.start()
    try:
        time.sleep(0.05)
        # The render must last long enough to tell, whatever the CPU's speed:
        # 32 samples per pixel took 0.19 s on one machine, so the sample count
        # grows until one render takes at least 0.3 s.
        spp = 32
        while True:
            start = time.perf_counter()
            image = snell.render(scene, spp=spp, threads=1)
            end = time.perf_counter()
            if end - start >= 0.3 or spp >= 32 * 4**4:
                break
            spp *= 4
    finally:
        stop.set()
        worker.join()
    during = [n for t, n in counts if start < t < end]
    assert end - start > 0.2, f"the render was too quick to tell even at {spp} spp"
    # Pure-Python counting kept going while the render ran.
    assert len(during) >= 10 and during[-1] - during[0] > 10000, (len(during), end - start)
    assert image.shape == (96, 96, 3)


def test_renders_in_two_threads_at_once(cornell):
    scenes = [snell.load_file(cornell, res=16), snell.load_file(cornell, res=16)]
    out = [None, None]

    def go(i):
        out[i] = snell.render(scenes[i], spp=4)

    threads = [threading.Thread(target=go, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert np.array_equal(out[0], out[1])

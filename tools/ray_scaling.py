#!/usr/bin/env python3
"""Scaling of snell.distributed on a local Ray cluster (this machine).

For 1 and 2 worker CPUs, renders the Cornell box (--res, --spp) in chunks
of --chunk-spp samples and compares with snell.render on one thread
(speed-up), then measures the driver+Ray overhead per task: for chunk
sizes from 1 spp up, (distributed time on 1 CPU − one-thread render
time) / tasks, and the overhead as a share of the render. Needs the snell
package and ray in the Python that runs it.

With --tiles T, also renders in tiles of T x T pixels at the same chunk
size (tasks = chunks x tiles) and reports the cost per extra task.

Usage: python tools/ray_scaling.py [--res 64] [--spp 256] [--runs 3] [--tiles T]
"""
import argparse
import statistics
import time
from pathlib import Path

import numpy as np
import ray

import snell
import snell.distributed as dist

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "cornell-box.xml"


def timed(f, runs):
    times, out = [], None
    for _ in range(runs):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--chunk-spp", type=int, default=16)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--tiles", type=int, default=0)
    args = ap.parse_args()
    params = {"res": args.res}
    scene = snell.load_file(SCENE, **params)
    single, ref = timed(lambda: snell.render(scene, spp=args.spp, seed=0, threads=1), args.runs)
    print(f"one machine, 1 thread: {single:.3f} s ({args.res}², {args.spp} spp)")
    for cpus in (1, 2):
        ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False)
        dist.render(SCENE, 8, params=params, chunk_spp=4)  # warm up: workers start, scene loaded
        t, img = timed(lambda: dist.render(SCENE, args.spp, seed=0, params=params, chunk_spp=args.chunk_spp), args.runs)
        assert np.array_equal(img, ref), "distributed image differs"
        print(f"{cpus} worker CPU(s), chunk {args.chunk_spp} spp: {t:.3f} s, speed-up {single / t:.2f}x over one thread")
        if args.tiles:
            n = len(dist.tiling(args.res, args.res, args.tiles))
            tt, img = timed(lambda: dist.render(SCENE, args.spp, seed=0, params=params, chunk_spp=args.chunk_spp, tiles=args.tiles), args.runs)
            assert np.array_equal(img, ref), "tiled image differs"
            chunks = -(-args.spp // args.chunk_spp)
            extra = chunks * (n - 1)
            print(f"  in {n} tiles of {args.tiles}²: {tt:.3f} s ({chunks * n} tasks), "
                  f"{1000 * (tt - t) / max(extra, 1):.2f} ms per extra task ({cpus} CPUs)")
        if cpus == 1:
            print("chunk_spp  tasks  seconds  overhead/task (ms)  overhead share")
            for chunk in (1, 2, 4, 8, 16, 32, 64):
                if chunk > args.spp:
                    break
                tasks = -(-args.spp // chunk)
                t, img = timed(lambda: dist.render(SCENE, args.spp, seed=0, params=params, chunk_spp=chunk), args.runs)
                per = (t - single) / tasks
                print(f"{chunk:9d} {tasks:6d} {t:8.3f} {1000 * per:19.2f} {100 * (t - single) / single:13.1f} %")
        ray.shutdown()


if __name__ == "__main__":
    main()

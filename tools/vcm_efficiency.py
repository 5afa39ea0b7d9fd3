#!/usr/bin/env python3
"""Efficiency of `vcm` against `path` at (about) equal CPU time.

As tools/bdpt_efficiency.py (whose rendering and measuring it reuses): for
each resolution a long path-traced reference (--ref-spp, seed 1000; or
--ref-pfm), then --runs renders (seeds 1..runs) of `vcm` (--mode vcm, bpt
or ppm) at --spp iterations, then --runs renders of `path` at the sample
count that takes about as long (calibrated by a short render); prints for
each method

    efficiency = 1 / (relMSE x seconds),

relMSE = mean over pixels and channels of (x - ref)^2 / (ref^2 + 0.01), the
median over the runs, seconds the median CPU time of the render process
divided by --threads (wall time and the load average are printed too). The
scene's integrator block is replaced by each method's, both with the
scene's own `$max_depth` (or --max-depth). The reference's own noise is in
every relMSE; it lowers the ratio, so keep the reference long.

Usage: python3 tools/vcm_efficiency.py --scene scenes/caustic-cornell-box.xml
           [--res 64 --res 128] [--threads 2] [--ref-spp 16384] [--spp 64]
           [--mode vcm] [--runs 3] [--max-depth N] [-D key=value ...] [--ref-pfm FILE]
"""
import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from bench import read_pfm  # noqa: E402
from bdpt_efficiency import measure, render, variant  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", required=True)
    ap.add_argument("--res", type=int, action="append", default=[])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ref-spp", type=int, default=16384)
    ap.add_argument("--spp", type=int, default=64, help="vcm's iterations (samples per pixel)")
    ap.add_argument("--mode", choices=["vcm", "bpt", "ppm"], default="vcm")
    ap.add_argument("--extra", default="", help="more vcm parameters, as XML")
    ap.add_argument("--max-depth", default="$max_depth")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("-D", dest="defines", action="append", default=[])
    ap.add_argument("--ref-pfm", action="append", default=[], help="reference image per --res, in order")
    ap.add_argument("--tag", default="vcm", help="names the temporary files (runs in parallel need different tags)")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    args = ap.parse_args()
    res_list = args.res or [64]
    depth = f'<integer name="max_depth" value="{args.max_depth}"/>'
    path_scene = variant(args, f'<integrator type="path">{depth}</integrator>', "path")
    vcm_scene = variant(args, f'<integrator type="vcm">{depth}<string name="mode" value="{args.mode}"/>{args.extra}</integrator>', "vcm")
    try:
        for k, res in enumerate(res_list):
            print(f"{args.scene} at {res} px, {args.threads} threads, load average {os.getloadavg()[0]:.2f}", flush=True)
            if k < len(args.ref_pfm):
                ref = read_pfm(args.ref_pfm[k])[2]
                print(f"  reference: {args.ref_pfm[k]}")
            else:
                out = f"/tmp/vcm-eff-{args.tag}-ref-{res}.pfm"
                wall, cpu, ref = render(args, path_scene, res, args.ref_spp, 1000, out)
                print(f"  reference: path {args.ref_spp} spp, cpu/threads {cpu:.1f} s ({out})", flush=True)
            eff_vcm, t_vcm = measure(args, args.mode, vcm_scene, res, args.spp, ref)
            _, t16, _ = render(args, path_scene, res, 16, 999, f"/tmp/vcm-eff-{args.tag}-cal.pfm")
            spp = max(1, round(16 * t_vcm / max(t16, 1e-3)))
            eff_path, _ = measure(args, "path", path_scene, res, spp, ref)
            print(f"  {args.mode} / path efficiency: {eff_vcm / eff_path:.2f}x, load average {os.getloadavg()[0]:.2f}", flush=True)
    finally:
        for p in (path_scene, vcm_scene):
            if os.path.exists(p):
                os.remove(p)


if __name__ == "__main__":
    main()

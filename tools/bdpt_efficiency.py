#!/usr/bin/env python3
"""Efficiency of `bdpt` (or `vcm`, --method vcm) against `path` at (about) equal CPU time.

For each resolution: a long path-traced reference (--ref-spp, seed 1000; or
--ref-pfm), then --runs renders (seeds 1..runs) with `bdpt` at --spp, then
--runs renders with `path` at the sample count that takes about as long
(calibrated by a short render of each); prints for each method

    efficiency = 1 / (relMSE x seconds),

relMSE = mean over pixels and channels of (x - ref)^2 / (ref^2 + 0.01) (as
tools/bench.py and tools/sppm_efficiency.py compute it), the median over the
runs, seconds the median CPU time of the render process divided by
--threads (fairer than wall time on a shared machine; wall time and the
load average are printed too). The scene's integrator block is replaced by
each method's, both with the scene's own `$max_depth` (or --max-depth); the
scene's pixel filter is kept (bdpt splats through it too). Note: the
reference's own noise is in every relMSE; it lowers the ratio, so keep the
reference long.

Usage: python3 tools/bdpt_efficiency.py --scene scenes/caustic-cornell-box.xml
           [--res 64 --res 128] [--threads 2] [--ref-spp 16384] [--ref-method path] [--spp 64]
           [--runs 3] [--max-depth N] [-D key=value ...] [--ref-pfm FILE] [--render-mode rgb|spectral]
       python3 tools/bdpt_efficiency.py --method vcm [--mode vcm|bpt|ppm] [--extra XML] ...
           (--spp is then vcm's iterations)
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from bench import read_pfm, rel_mse  # noqa: E402


def variant(args, integrator, name):
    text = open(args.scene).read()
    text, n = re.subn(r"<integrator.*</integrator>", integrator, text, count=1, flags=re.S)
    if n != 1:
        sys.exit(f"{args.scene}: no <integrator> block")
    path = os.path.join(os.path.dirname(args.scene), f".bdpt-eff-{args.tag}-{name}-" + os.path.basename(args.scene))
    with open(path, "w") as f:
        f.write(text)
    return path


def render(args, scene, res, spp, seed, out):
    stats = f"/tmp/bdpt-eff-{args.tag}-stats.json"
    cmd = [args.snell, "render", scene, "-o", out, "--spp", str(spp), "--seed", str(seed),
           "--threads", str(args.threads), "--stats", stats, "--quiet", "-D", f"res={res}",
           "--mode", args.render_mode]
    for kv in args.defines:
        cmd += ["-D", kv]
    before = os.times()
    r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    after = os.times()
    if r.returncode != 0:
        print(r.stdout)
        sys.exit(f"snell failed with exit code {r.returncode}")
    with open(stats) as f:
        wall = float(json.load(f)["render_seconds"])
    cpu = (after.children_user + after.children_system) - (before.children_user + before.children_system)
    return wall, cpu / args.threads, read_pfm(out)[2]


def measure(args, name, scene, res, spp, ref):
    errs, walls, cpus = [], [], []
    for seed in range(1, args.runs + 1):
        wall, cpu, img = render(args, scene, res, spp, seed, f"/tmp/bdpt-eff-{args.tag}-{name}-{seed}.pfm")
        errs.append(rel_mse(img, ref))
        walls.append(wall)
        cpus.append(cpu)
    e, cpu, wall = statistics.median(errs), statistics.median(cpus), statistics.median(walls)
    eff = 1.0 / (e * cpu)
    print(f"  {name:5s} {spp:6d} spp: relMSE {e:.3e} (runs {', '.join(f'{x:.2e}' for x in errs)}), "
          f"cpu/threads {cpu:7.2f} s (wall {wall:7.2f} s), efficiency {eff:9.2f}", flush=True)
    return eff, cpu


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", required=True)
    ap.add_argument("--res", type=int, action="append", default=[])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ref-spp", type=int, default=16384)
    ap.add_argument("--ref-method", choices=["path", "bdpt"], default="path",
                    help="the reference's integrator (bdpt for scenes whose path reference keeps fireflies)")
    ap.add_argument("--method", choices=["bdpt", "vcm"], default="bdpt", help="the method measured against path")
    ap.add_argument("--mode", choices=["vcm", "bpt", "ppm"], default="vcm", help="vcm's mode (--method vcm)")
    ap.add_argument("--render-mode", choices=["rgb", "spectral"], default="rgb",
                    help="what the paths carry (snell's --mode), for every render including the reference")
    ap.add_argument("--extra", default="", help="more parameters of the method, as XML")
    ap.add_argument("--spp", type=int, default=64, help="the method's samples per pixel (vcm: iterations)")
    ap.add_argument("--max-depth", default="$max_depth")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("-D", dest="defines", action="append", default=[])
    ap.add_argument("--ref-pfm", action="append", default=[], help="reference image per --res, in order")
    ap.add_argument("--tag", default="run", help="names the temporary files (runs in parallel need different tags)")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    args = ap.parse_args()
    res_list = args.res or [64]
    depth = f'<integer name="max_depth" value="{args.max_depth}"/>'
    path_scene = variant(args, f'<integrator type="path">{depth}</integrator>', "path")
    bdpt_scene = variant(args, f'<integrator type="bdpt">{depth}</integrator>', "bdpt")
    mode = f'<string name="mode" value="{args.mode}"/>' if args.method == "vcm" else ""
    method_scene = variant(args, f'<integrator type="{args.method}">{depth}{mode}{args.extra}</integrator>', args.method)
    try:
        for k, res in enumerate(res_list):
            print(f"{args.scene} at {res} px, {args.threads} threads, load average {os.getloadavg()[0]:.2f}", flush=True)
            if k < len(args.ref_pfm):
                ref = read_pfm(args.ref_pfm[k])[2]
                print(f"  reference: {args.ref_pfm[k]}")
            else:
                out = f"/tmp/bdpt-eff-{args.tag}-ref-{res}.pfm"
                ref_scene = bdpt_scene if args.ref_method == "bdpt" else path_scene
                wall, cpu, ref = render(args, ref_scene, res, args.ref_spp, 1000, out)
                print(f"  reference: {args.ref_method} {args.ref_spp} spp, cpu/threads {cpu:.1f} s ({out})", flush=True)
            name = args.mode if args.method == "vcm" else "bdpt"
            eff_m, t_m = measure(args, name, method_scene, res, args.spp, ref)
            _, t16, _ = render(args, path_scene, res, 16, 999, f"/tmp/bdpt-eff-{args.tag}-cal.pfm")
            spp = max(1, round(16 * t_m / max(t16, 1e-3)))
            eff_path, _ = measure(args, "path", path_scene, res, spp, ref)
            print(f"  {name} / path efficiency: {eff_m / eff_path:.2f}x, load average {os.getloadavg()[0]:.2f}", flush=True)
    finally:
        for p in {path_scene, bdpt_scene, method_scene}:
            if os.path.exists(p):
                os.remove(p)


if __name__ == "__main__":
    main()

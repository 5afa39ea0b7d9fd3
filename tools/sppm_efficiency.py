#!/usr/bin/env python3
"""Efficiency of `sppm` against `path` at (about) equal time.

For each scene: a long path-traced reference (--ref-spp), then --runs renders
(seeds 1..runs) with `sppm` at --iterations, then --runs renders with `path`
at the sample count that takes about as long (calibrated by a short render);
prints for each method

    efficiency = 1 / (relMSE × seconds),

relMSE = mean over pixels and channels of (x − ref)² / (ref² + 0.01),
averaged over the runs, seconds the median CPU time of the render process
divided by --threads (fairer than wall time on a shared machine; wall time
is printed too). All renders use a box pixel filter (sppm's). With --ref sppm the reference is a long sppm render instead
(--ref-iterations iterations of --ref-photons photons, initial radius
--ref-radius in world units): for scenes whose light a path tracer cannot
find in any affordable time (scenes/pool-sun.xml). The scene's integrator block is replaced by each method's
(both with the scene's max_depth); --drop removes an element by a regex
(e.g. the pool's sky, which sppm cannot emit photons from).
--photon-mode may be given several times (MODE or MODE:VERTEX_RADIUS_SCALE): each
setting is measured in the same run against one `path` measurement (its spp
calibrated to the first setting's time). --sampler names the sppm camera
paths' sampler (`path` keeps the scene's).

Usage: python3 tools/sppm_efficiency.py --scene scenes/caustic-cornell-box.xml
           [--res 64] [--threads 2] [--ref-spp 8192] [--iterations 64]
           [--photons 50000] [--photon-mode caustics|all_caustics|indirect|final_gather[:SCALE] ...]
           [--radius-footprints 1.5] [--vertex-radius-scale 4] [--sampler zsobol] [--alpha 0.6667]
           [--runs 3] [--drop REGEX] [-D key=value ...]
           [--ref sppm --ref-iterations 256 --ref-photons 2000000 --ref-radius 0.01]
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


def variant(args, integrator, name="", sampler=None):
    text = open(args.scene).read()
    text, n = re.subn(r"<integrator.*</integrator>", integrator, text, count=1, flags=re.S)
    if n != 1:
        sys.exit(f"{args.scene}: no <integrator> block")
    if sampler:
        text, n = re.subn(r'<sampler type="[a-z_]*"', f'<sampler type="{sampler}"', text, count=1)
        if n != 1:
            sys.exit(f"{args.scene}: no <sampler> element")
    # Every method with a box pixel filter (sppm's), so that filters do not differ.
    text, n = re.subn(r"<rfilter[^>]*/>|<rfilter.*?</rfilter>", '<rfilter type="box"/>', text, flags=re.S)
    if n == 0:
        text = text.replace("</film>", '<rfilter type="box"/></film>', 1)
    for pattern in args.drop:
        text, n = re.subn(pattern, "", text, flags=re.S)
        if n == 0:
            sys.exit(f"--drop {pattern!r} matched nothing")
    path = os.path.join(os.path.dirname(args.scene), f".sppm-eff-{args.tag}-{name}-" + os.path.basename(args.scene))
    with open(path, "w") as f:
        f.write(text)
    return path


def render(args, scene, spp, seed, out):
    stats = f"/tmp/sppm-eff-{args.tag}-stats.json"
    cmd = [args.snell, "render", scene, "-o", out, "--spp", str(spp), "--seed", str(seed),
           "--threads", str(args.threads), "--stats", stats, "--quiet", "-D", f"res={args.res}"]
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


def measure(args, name, scene, spp, ref):
    errs, walls, cpus = [], [], []
    for seed in range(1, args.runs + 1):
        wall, cpu, img = render(args, scene, spp, seed, f"/tmp/sppm-eff-{args.tag}-{name}-{seed}.pfm")
        errs.append(rel_mse(img, ref))
        walls.append(wall)
        cpus.append(cpu)
    e, cpu, wall = statistics.mean(errs), statistics.median(cpus), statistics.median(walls)
    eff = 1.0 / (e * cpu)
    print(f"  {name:6s} {spp:6d} spp/iterations: relMSE {e:.3e}, cpu/threads {cpu:7.2f} s (wall {wall:7.2f} s), efficiency {eff:9.2f}")
    return eff, cpu


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", required=True)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ref-spp", type=int, default=8192)
    ap.add_argument("--iterations", type=int, default=64)
    ap.add_argument("--photons", type=int, default=50000)
    ap.add_argument("--photon-mode", action="append", default=[],
                    help="sppm's `photons` (caustics, all_caustics, indirect, final_gather), optionally "
                         "with :VERTEX_RADIUS_SCALE; repeat to measure several in one run")
    ap.add_argument("--radius-footprints", type=float, default=1.5,
                    help="sppm's automatic initial radius in pixel footprints")
    ap.add_argument("--vertex-radius-scale", type=float, default=0.0,
                    help="photons=all_caustics: the later vertices' radius in visible-point radii (0: sppm's default)")
    ap.add_argument("--sampler", help="the sppm camera paths' sampler (default: the scene's)")
    ap.add_argument("--alpha", type=float, default=0.0, help="sppm's alpha (0: its default)")
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--drop", action="append", default=[])
    ap.add_argument("-D", dest="defines", action="append", default=[])
    ap.add_argument("--ref", choices=["path", "sppm"], default="path")
    ap.add_argument("--ref-iterations", type=int, default=256)
    ap.add_argument("--ref-photons", type=int, default=2000000)
    ap.add_argument("--ref-radius", type=float, default=0.0, help="the sppm reference's initial radius (0: automatic)")
    ap.add_argument("--ref-pfm", help="use this reference image (.pfm) instead of rendering one")
    ap.add_argument("--tag", default="run", help="names the temporary files (runs in parallel need different tags)")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    args = ap.parse_args()
    path_xml = f'<integrator type="path"><integer name="max_depth" value="{args.max_depth}"/></integrator>'
    settings = []
    for entry in args.photon_mode or ["caustics"]:
        mode, _, scale = entry.partition(":")
        if mode not in ("caustics", "all_caustics", "indirect", "final_gather"):
            sys.exit(f"--photon-mode {entry!r}: unknown mode")
        scale = float(scale) if scale else args.vertex_radius_scale
        settings.append((entry, mode, scale))

    def sppm_xml(mode, scale):
        return (f'<integrator type="sppm"><integer name="max_depth" value="{args.max_depth}"/>'
                f'<integer name="photon_count" value="{args.photons}"/>'
                f'<string name="photons" value="{mode}"/>'
                f'<float name="radius_footprints" value="{args.radius_footprints}"/>'
                + (f'<float name="vertex_radius_scale" value="{scale}"/>' if scale > 0 else '')
                + (f'<float name="alpha" value="{args.alpha}"/>' if args.alpha > 0 else '')
                + '</integrator>')
    ref_xml = (f'<integrator type="sppm"><integer name="max_depth" value="{args.max_depth}"/>'
               f'<integer name="photon_count" value="{args.ref_photons}"/>'
               f'<float name="initial_radius" value="{args.ref_radius}"/></integrator>')
    path_scene, sppm_scenes, ref_scene = variant(args, path_xml, "path"), [], None
    try:
        for i, (entry, mode, scale) in enumerate(settings):
            sppm_scenes.append(variant(args, sppm_xml(mode, scale), f"sppm{i}", args.sampler))
        print(f"{args.scene} at {args.res} px, {args.threads} threads, drop {args.drop}; sppm {args.iterations} x {args.photons} photons, "
              f"photons={','.join(e for e, _, _ in settings)}, radius {args.radius_footprints} footprints, "
              f"sampler {args.sampler or 'as the scene'}, alpha {args.alpha or 'default'}; load {os.getloadavg()[0]:.1f}")
        if args.ref_pfm:
            ref = read_pfm(args.ref_pfm)[2]
            print(f"  reference: {args.ref_pfm}")
        elif args.ref == "sppm":
            ref_scene = variant(args, ref_xml, "ref")
            wall, cpu, ref = render(args, ref_scene, args.ref_iterations, 1000, f"/tmp/sppm-eff-{args.tag}-ref.pfm")
            print(f"  reference: sppm {args.ref_iterations} iterations of {args.ref_photons} photons, "
                  f"radius {args.ref_radius}, cpu/threads {cpu:.1f} s")
        else:
            wall, cpu, ref = render(args, path_scene, args.ref_spp, 1000, f"/tmp/sppm-eff-{args.tag}-ref.pfm")
            print(f"  reference: path {args.ref_spp} spp, cpu/threads {cpu:.1f} s")
        effs = []
        for (entry, _, _), scene in zip(settings, sppm_scenes):
            print(f"  sppm photons={entry}:")
            effs.append(measure(args, "sppm", scene, args.iterations, ref))
        t_sppm = effs[0][1]
        _, t16, _ = render(args, path_scene, 16, 999, f"/tmp/sppm-eff-{args.tag}-cal.pfm")
        spp = max(1, round(16 * t_sppm / max(t16, 1e-3)))
        eff_path, _ = measure(args, "path", path_scene, spp, ref)
        for (entry, _, _), (eff, _) in zip(settings, effs):
            print(f"  sppm ({entry}) / path efficiency: {eff / eff_path:.2f}x")
    finally:
        for p in [path_scene, ref_scene] + sppm_scenes:
            if p and os.path.exists(p):
                os.remove(p)


if __name__ == "__main__":
    main()

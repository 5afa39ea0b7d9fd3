#!/usr/bin/env python3
"""Efficiency of `sppm` settings against `path` on one scene: 1 / (relMSE × CPU s).

Renders `path` once (--runs seeds at --path-spp samples) and then each `sppm`
setting given by --config (--runs seeds at its iteration count), all against
one reference (--ref-pfm, e.g. a long `path` render made by
tools/sppm_efficiency.py or tools/sppm_split.py, or --ref-spp to render one);
prints relMSE (mean over the seeds), CPU seconds (median, / --threads) and
the efficiency of each, and each setting's efficiency over path's. path is
unbiased, so its efficiency does not depend on its sample count; sppm's
does (it is consistent, not unbiased): compare settings at similar times.

A config is `mode:radius_footprints:photons_per_pixel:iterations`, e.g.
`caustics:1.5:1:128` (the defaults at 64²) or `indirect:3:4:64`, optionally
followed by `:camera_sampler:alpha:rr_depth` (the scene's sampler, which the
camera paths use with the iteration as the sample index; sppm's `alpha` and
`rr_depth`; an empty field keeps the default), e.g.
`indirect:1.5:1:128:zsobol:0.8` or `indirect:1.5:1:128:zsobol:0.75:1`. --path-sampler
sets path's sampler. With --split each result is also split into the
variance (over the seeds, about their mean image) and the bias² (the mean
image against the reference, less the variance of that mean), both in
relMSE units (the reference's own noise counts as bias).

Usage: python3 tools/sppm_sweep.py --scene scenes/glass-of-water.xml --res 64
           --ref-pfm /tmp/ref.pfm --path-spp 256 --config caustics:1.5:1:128 ...
"""
import argparse
import os
import re
import statistics
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from bench import read_pfm, rel_mse  # noqa: E402
from sppm_efficiency import variant, render  # noqa: E402


def with_sampler(path, sampler):
    """Names `sampler` in the scene file `path` (in place)."""
    text = open(path).read()
    text, n = re.subn(r'<sampler\s+type="[a-z]+"', f'<sampler type="{sampler}"', text, count=1)
    if n != 1:
        sys.exit(f"{path}: no <sampler type=...> to replace")
    open(path, "w").write(text)


def split(imgs, ref):
    """(variance, bias²) of the images `imgs` (one per seed) against `ref`,
    in relMSE units (each pixel over ref² + 0.01, as rel_mse)."""
    s = len(imgs)
    mean = [sum(v) / s for v in zip(*imgs)]
    w = [1.0 / (r * r + 1e-2) for r in ref]
    var = sum(sum((img[i] - mean[i]) ** 2 for img in imgs) * w[i] for i in range(len(ref))) / (len(ref) * (s - 1))
    bias2 = sum((mean[i] - ref[i]) ** 2 * w[i] for i in range(len(ref))) / len(ref) - var / s
    return var, bias2


def measure(args, scene, count, ref, name):
    errs, cpus, imgs = [], [], []
    for seed in range(1, args.runs + 1):
        _, cpu, img = render(args, scene, count, seed, f"/tmp/sppm-sweep-{args.tag}-{name}.pfm")
        errs.append(rel_mse(img, ref))
        cpus.append(cpu)
        if args.split:
            imgs.append(img)
    e, t = statistics.mean(errs), statistics.median(cpus)
    if args.split and len(imgs) > 1:
        var, bias2 = split(imgs, ref)
        print(f"    split: variance {var:.3e}, bias² {bias2:.3e} (relMSE {e:.3e})")
    return e, t, 1.0 / (e * t)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", required=True)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--path-spp", type=int, default=256)
    ap.add_argument("--ref-pfm")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--config", action="append", default=[])
    ap.add_argument("--drop", action="append", default=[])
    ap.add_argument("-D", dest="defines", action="append", default=[])
    ap.add_argument("--tag", default="sweep")
    ap.add_argument("--path-sampler", default=None, help="path's sampler (default: the scene's)")
    ap.add_argument("--split", action="store_true", help="split each relMSE into variance and bias²")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    args = ap.parse_args()
    md = args.max_depth
    pixels = args.res * args.res
    path_scene = variant(args, f'<integrator type="path"><integer name="max_depth" value="{md}"/></integrator>', "path")
    if args.path_sampler:
        with_sampler(path_scene, args.path_sampler)
    scenes = [path_scene]
    try:
        load0 = os.getloadavg()[0]
        if args.ref_pfm:
            ref = read_pfm(args.ref_pfm)[2]
        else:
            ref = render(args, path_scene, args.ref_spp, 1000, f"/tmp/sppm-sweep-{args.tag}-ref.pfm")[2]
        print(f"{args.scene} at {args.res}², {args.threads} threads, {args.runs} seeds; load {load0:.1f}")
        e, t, eff_path = measure(args, path_scene, args.path_spp, ref, "path")
        print(f"  path {args.path_sampler or 'scene sampler'} {args.path_spp} spp: relMSE {e:.3e}, {t:.2f} CPU s, efficiency {eff_path:.1f}", flush=True)
        for c in args.config:
            mode, rf, ppp, its, *more = c.split(":")
            cam, alpha, rr = [m or None for m in (more + [None, None, None])[:3]]
            photons = max(1, round(float(ppp) * pixels))
            xml = (f'<integrator type="sppm"><integer name="max_depth" value="{md}"/>'
                   f'<integer name="photon_count" value="{photons}"/><string name="photons" value="{mode}"/>'
                   + (f'<float name="alpha" value="{alpha}"/>' if alpha else "")
                   + (f'<integer name="rr_depth" value="{rr}"/>' if rr else "")
                   + f'<float name="radius_footprints" value="{rf}"/></integrator>')
            s = variant(args, xml, "sppm")
            scenes.append(s)
            if cam:
                with_sampler(s, cam)
            e, t, eff = measure(args, s, int(its), ref, "sppm")
            print(f"  sppm {mode:8s} radius {rf:>4s} fp, {ppp:>4s} photons/px, {its:>4s} it, camera {cam or 'scene'}, "
                  f"alpha {alpha or '2/3'}, rr {rr or 5}: relMSE {e:.3e}, "
                  f"{t:.2f} CPU s, efficiency {eff:.1f} = {eff / eff_path:.2f}x path", flush=True)
        print(f"  load at the end {os.getloadavg()[0]:.1f}")
    finally:
        for s in scenes:
            if os.path.exists(s):
                os.remove(s)


if __name__ == "__main__":
    main()

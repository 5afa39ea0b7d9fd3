#!/usr/bin/env python3
"""Where a path tracer's error is on a caustic scene: the caustic part (what
`sppm` takes from photons) against the rest (what it path traces).

For a scene: a long `path` reference R (all light) and a long `sppm` reference
R_nc with `photons = none` (the same camera paths without the caustic paths,
so R − R_nc is the caustic part); then --runs renders each of

    path  at --spp samples           relMSE against R        (all light)
    sppm photons=none, --spp iterations, relMSE against R_nc (non-caustic light)

with relMSE = mean of (x − ref)² / (R² + 0.01) (both against the full image's
R, so they add up), CPU seconds / threads of each. Prints the non-caustic
share of path's error and the bound on `sppm`'s efficiency over `path` with
the current split: if photons cost nothing and had no error, sppm's error
would be the non-caustic part's, so

    bound = (relMSE_path × t_path) / (relMSE_nc × t_nc).

Usage: python3 tools/sppm_split.py --scene scenes/diamond.xml [--res 64]
           [--spp 128] [--ref-spp 4096] [--runs 3] [--threads 2] [-D key=value]
"""
import argparse
import os
import statistics
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from bench import read_pfm  # noqa: E402
from sppm_efficiency import variant, render  # noqa: E402


def rel(img, ref, norm):
    return sum((a - r) ** 2 / (n * n + 1e-2) for a, r, n in zip(img, ref, norm)) / len(ref)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", required=True)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--drop", action="append", default=[])
    ap.add_argument("-D", dest="defines", action="append", default=[])
    ap.add_argument("--tag", default="split")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    args = ap.parse_args()
    md = args.max_depth
    path_xml = f'<integrator type="path"><integer name="max_depth" value="{md}"/></integrator>'
    nc_xml = (f'<integrator type="sppm"><integer name="max_depth" value="{md}"/>'
              f'<string name="photons" value="none"/></integrator>')
    scenes = [variant(args, path_xml, "path"), variant(args, nc_xml, "nc")]
    try:
        _, tr, ref = render(args, scenes[0], args.ref_spp, 1000, f"/tmp/sppm-split-{args.tag}-ref.pfm")
        _, tn, ref_nc = render(args, scenes[1], args.ref_spp, 1000, f"/tmp/sppm-split-{args.tag}-refnc.pfm")
        mean = lambda img: sum(img) / len(img)
        print(f"{args.scene} at {args.res}², {args.threads} threads; references {args.ref_spp} spp "
              f"(path {tr:.1f} s, non-caustic {tn:.1f} s); mean R {mean(ref):.4f}, "
              f"caustic part {mean(ref) - mean(ref_nc):.4f} ({100 * (1 - mean(ref_nc) / mean(ref)):.1f} %)")
        out = {}
        for name, scene, r in (("path", scenes[0], ref_nc and ref), ("nc", scenes[1], ref_nc)):
            errs, cpus = [], []
            for seed in range(1, args.runs + 1):
                _, cpu, img = render(args, scene, args.spp, seed, f"/tmp/sppm-split-{args.tag}-{name}.pfm")
                errs.append(rel(img, r, ref))
                cpus.append(cpu)
            out[name] = (statistics.mean(errs), statistics.median(cpus))
            print(f"  {name:4s} {args.spp} spp: relMSE {out[name][0]:.3e}, cpu/threads {out[name][1]:.2f} s")
        (ep, tp), (en, tn) = out["path"], out["nc"]
        print(f"  non-caustic share of path's relMSE at equal spp: {100 * en / ep:.1f} %; "
              f"bound on sppm/path efficiency with this split: {ep * tp / (en * tn):.2f}x")
    finally:
        for p in scenes:
            if os.path.exists(p):
                os.remove(p)


if __name__ == "__main__":
    main()

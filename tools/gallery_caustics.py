#!/usr/bin/env python3
"""The README's caustics gallery row: each scene rendered by `path` and by a
method made for caustics (`sppm` or `bdpt`) in the same CPU time.

For each scene: the caustic method renders first (its iteration / sample
count below); then `path` renders a short calibration (16 spp) and the
sample count that takes the same CPU time (CPU seconds of the render
process, fairer than wall time on a shared machine), rendered again with a
scaled count while it is more than 10 % off. Writes
docs/images/<name>-<method>.png and docs/images/<name>-path.png and prints
the times. Efficiency figures come from tools/sppm_efficiency.py.

Usage: python3 tools/gallery_caustics.py [--res 256] [--threads 2] [--only NAME]
"""
import argparse
import json
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# name, scene, method, its integrator block, its count, extra arguments
SCENES = [
    ("pool-sun", "scenes/pool-sun.xml", "sppm",
     '<integrator type="sppm"><integer name="max_depth" value="8"/><integer name="photon_count" value="250000"/></integrator>',
     96, []),
    # photons = indirect: 3-5x the default's efficiency on this scene (docs/performance.md).
    ("caustic-cornell-box", "scenes/caustic-cornell-box.xml", "sppm",
     '<integrator type="sppm"><integer name="max_depth" value="8"/><string name="photons" value="indirect"/></integrator>',
     256, []),
    ("diamond", "scenes/diamond.xml", "sppm",
     '<integrator type="sppm"><integer name="max_depth" value="8"/></integrator>',
     256, ["--mode", "spectral"]),
]
PATH = '<integrator type="path"><integer name="max_depth" value="8"/></integrator>'


def variant(scene, integrator, tag):
    text = open(os.path.join(ROOT, scene)).read()
    text, n = re.subn(r"<integrator.*?</integrator>\s*(?=<sensor)", integrator + "\n\n    ", text, count=1, flags=re.S)
    if n != 1:
        sys.exit(f"{scene}: no <integrator> block before <sensor>")
    path = os.path.join(ROOT, os.path.dirname(scene), f".gallery-{tag}-" + os.path.basename(scene))
    with open(path, "w") as f:
        f.write(text)
    return path


def render(args, scene, count, out, extra):
    stats = "/tmp/gallery-caustics-stats.json"
    cmd = [args.snell, "render", scene, "-o", out, "--spp", str(count), "--threads", str(args.threads),
           "--stats", stats, "--quiet", "-D", f"res={args.res}"] + extra
    before = os.times()
    r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    after = os.times()
    if r.returncode != 0:
        print(r.stdout)
        sys.exit(f"snell failed: {' '.join(cmd)}")
    with open(stats) as f:
        wall = float(json.load(f)["render_seconds"])
    cpu = (after.children_user + after.children_system) - (before.children_user + before.children_system)
    return wall, cpu


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--only")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    args = ap.parse_args()
    for name, scene, method, block, count, extra in SCENES:
        if args.only and args.only != name:
            continue
        files = []
        try:
            m_scene = variant(scene, block, method)
            p_scene = variant(scene, PATH, "path")
            files = [m_scene, p_scene]
            out = os.path.join(ROOT, "docs", "images", f"{name}-{method}.png")
            wall, cpu = render(args, m_scene, count, out, extra)
            print(f"{name}: {method} {count} at {args.res}²: {cpu:.1f} CPU s ({wall:.1f} s wall) -> {out}")
            _, c16 = render(args, p_scene, 16, "/tmp/gallery-caustics-cal.pfm", extra)
            spp = max(1, round(16 * cpu / max(c16, 1e-3)))
            out = os.path.join(ROOT, "docs", "images", f"{name}-path.png")
            target = cpu
            for _ in range(3):
                wall, cpu = render(args, p_scene, spp, out, extra)
                print(f"{name}: path {spp} spp at {args.res}²: {cpu:.1f} CPU s ({wall:.1f} s wall) -> {out}")
                if abs(cpu - target) <= 0.1 * target:
                    break
                # The short calibration misjudged it (a loaded machine): again, scaled.
                spp = max(1, round(spp * target / max(cpu, 1e-3)))
        finally:
            for f in files:
                if os.path.exists(f):
                    os.remove(f)


if __name__ == "__main__":
    main()

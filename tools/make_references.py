#!/usr/bin/env python3
"""Renders the reference images that Snell's tests compare against.

For every tests/scenes/*.xml and scenes/cornell-box.xml this renders the scene
with Mitsuba 3 (llvm_ad_rgb when it loads, else scalar_rgb) at res=128 and a
high sample count, as several passes with different seeds averaged in float64,
and writes tests/references/<scene-stem>.exr (linear float32 RGB, uncompressed)
plus tests/references/README.md describing how they were made.

Usage (after tools/setup-mitsuba.sh):
  .venv-mitsuba/bin/python tools/make_references.py [--spp 65536] [--pass-spp 1024]
      [--res 128] [--variant llvm_ad_rgb] [--stderr] [scene.xml[@SPP] ...]

--stderr also writes tests/references/<scene-stem>.stderr.exr: every
channel's per-pixel standard error of the mean (from the spread of the
passes; 16-bit floats), so that a test can count the reference's own noise.

A scene's sample count is, in order of precedence: SPP after '@' on the
command line, its entry in SCENE_SPP (scenes whose caustics need more samples
for the same relative error), or --spp. The README table keeps the rows of
scenes not rendered in this run and replaces or adds the others.
"""
import argparse
import datetime
import glob
import os
import re
import sys
import time

import numpy as np

os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")
import mitsuba as mi  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from exrio import write_exr  # noqa: E402

# Sample counts for scenes that need more than --spp to reach a relative
# std-error of about 2e-3 (their caustics are found only by BSDF sampling).
SCENE_SPP = {
    "cornell-glass-gold": 131072,
    "caustics": 393216,
}

# The README gallery (scenes/*.xml) at thumbnail size for
# tests/gallery_scenes.rs: scene stem -> (variant, parameters, spp). The
# parameters are the scenes' own <default>s. prism and diamond use one of
# Mitsuba's constant named IORs (their Sellmeier glasses are Snell's own); pool and
# pool-polarizer need a polarized variant (their `stokes` integrator, the
# polarizer sheet). calcite (the `birefringent` BSDF) is Snell's own.
GALLERY = {
    "cornell-box": ("llvm_ad_rgb", {"res": "32"}, 32768),
    "caustic-cornell-box": ("llvm_ad_rgb", {"res": "32"}, 65536),
    "snells-window": ("llvm_ad_rgb", {"res": "32"}, 32768),
    "glass-of-water": ("llvm_ad_rgb", {"res": "32"}, 65536),
    "metal-showcase": ("llvm_ad_rgb", {"res": "64", "height": "32"}, 32768),
    "rough-gallery": ("llvm_ad_rgb", {"res": "48", "height": "16"}, 32768),
    "many-lights": ("llvm_ad_rgb", {"res": "32"}, 32768),
    "prism": ("llvm_ad_rgb", {"res": "32", "glass": "bk7"}, 65536),
    "diamond": ("llvm_ad_rgb", {"res": "32", "gem": "diamond"}, 65536),
    "pool": ("llvm_ad_spectral_polarized", {"res": "32"}, 32768),
    "pool-polarizer": ("llvm_ad_spectral_polarized", {"res": "32"}, 32768),
}


def pick_variant(wanted):
    for v in ([wanted] if wanted else ["llvm_ad_rgb", "scalar_rgb"]):
        try:
            mi.set_variant(v)
            # Force the backend to initialise (fails here if LLVM is missing)
            mi.load_dict({"type": "diffuse"})
            return v
        except Exception as e:  # noqa: BLE001
            print(f"variant {v} unavailable: {e}", file=sys.stderr)
    sys.exit("no usable Mitsuba variant")


def scene_defaults(path):
    return set(re.findall(r'<default\s+name="([^"]+)"', open(path).read()))


def render_reference(path, res, spp, pass_spp, extra=None):
    params = {"res": str(res), "spp": str(pass_spp), **(extra or {})}
    params = {k: v for k, v in params.items() if k in scene_defaults(path)}
    scene = mi.load_file(path, **params)
    n_passes = max(1, spp // pass_spp)
    acc = acc2 = None
    t0 = time.time()
    for i in range(n_passes):
        img = np.array(mi.render(scene, spp=pass_spp, seed=i), dtype=np.float64)
        # The aov integrator's returned tensor leaves out its nested
        # integrators' channels (Mitsuba 3.9.1); the film's bitmap has all.
        bitmap = scene.sensors()[0].film().bitmap()
        if len(list(bitmap.struct_())) != img.shape[2]:
            img = np.array(bitmap, dtype=np.float64)
        if acc is None:
            acc, acc2 = np.zeros_like(img), np.zeros_like(img)
        acc += img
        acc2 += img * img
    mean = acc / n_passes
    # Standard error of the per-pixel mean, estimated from the pass spread
    var = np.maximum(acc2 / n_passes - mean * mean, 0) / max(n_passes - 1, 1)
    stderr = np.sqrt(var)
    # Channel names: R, G, B, then any the integrator adds (Mitsuba's
    # `stokes` integrator: S0.R ... S3.B)
    struct = scene.sensors()[0].film().bitmap().struct_()
    names = [field.name for field in struct]
    return mean.astype(np.float32), stderr, n_passes * pass_spp, time.time() - t0, names


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", help="scene.xml, or scene.xml@SPP")
    ap.add_argument("--spp", type=int, default=65536)
    ap.add_argument("--pass-spp", type=int, default=1024)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--variant", default=None)
    ap.add_argument("--out", default=os.path.join(ROOT, "tests", "references"))
    ap.add_argument("--no-readme", action="store_true")
    ap.add_argument("--stderr", action="store_true",
                    help="also write <stem>.stderr.exr, the per-pixel standard error of the mean")
    ap.add_argument("--gallery", action="store_true",
                    help="render the GALLERY scenes (or those named) into tests/references/gallery")
    args = ap.parse_args()
    if args.gallery:
        return render_gallery(args.scenes, args.pass_spp)

    variant = pick_variant(args.variant)
    scenes = args.scenes or (sorted(glob.glob(os.path.join(ROOT, "tests", "scenes", "*.xml")))
                             + [os.path.join(ROOT, "scenes", "cornell-box.xml")])
    os.makedirs(args.out, exist_ok=True)
    rows = []
    for arg in scenes:
        path, _, spp_arg = arg.partition("@")
        stem = os.path.splitext(os.path.basename(path))[0]
        scene_spp = int(spp_arg) if spp_arg else SCENE_SPP.get(stem, args.spp)
        img, stderr, spp, secs, names = render_reference(path, args.res, scene_spp, args.pass_spp)
        out = os.path.join(args.out, stem + ".exr")
        write_exr(out, img, names)
        if args.stderr:
            write_exr(os.path.join(args.out, stem + ".stderr.exr"), stderr, names, half=True)
        m = img[:, :, :3].reshape(-1, 3).mean(0)
        rel = float(stderr[:, :, :3].mean() / max(img[:, :, :3].mean(), 1e-12))
        print(f"{stem}: {img.shape[1]}x{img.shape[0]}, {spp} spp, {secs:.0f}s, "
              f"mean RGB {m[0]:.5f} {m[1]:.5f} {m[2]:.5f}, "
              f"mean pixel std-error / mean = {rel:.2e} -> {os.path.relpath(out, ROOT)}",
              flush=True)
        rows.append((stem, os.path.relpath(path, ROOT), img.shape[1], img.shape[0], spp,
                     secs, m, rel))

    if args.no_readme:
        return
    # Keep the existing rows of scenes not rendered now
    readme = os.path.join(args.out, "README.md")
    done = {r[0] for r in rows}
    old_rows = []
    if os.path.exists(readme):
        for line in open(readme):
            m = re.match(r"\| ([^ |]+)\.exr \|", line)
            if m and m.group(1) not in done:
                old_rows.append(line.rstrip("\n"))
    lines = [
        "# Reference images",
        "",
        "Rendered by Mitsuba %s (variant `%s`) with `tools/make_references.py`:" % (
            mi.__version__, variant),
        "",
        "```sh",
        "bash tools/setup-mitsuba.sh",
        "export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
        ".venv-mitsuba/bin/python tools/make_references.py --spp %d --pass-spp %d --res %d"
        % (args.spp, args.pass_spp, args.res),
        "```",
        "",
        "(`SCENE_SPP` in the script gives the caustic scenes more samples; `scene.xml@SPP` "
        "renders one scene at another count; rows of scenes not rendered are kept.)",
        "",
        "Each scene is loaded with `-D res=%d` (other defaults, e.g. `height`, as in the "
        "file) and rendered as spp / %d passes of %d spp with seeds 0, 1, 2, ...; the passes "
        "are averaged in float64. Files are linear float32 RGB OpenEXR (uncompressed scanlines, "
        "channels B,G,R as EXR sorts them), written by `tools/exrio.py`."
        % (args.res, args.pass_spp, args.pass_spp),
        "",
        "Compare a Snell render made with the same parameters (`-D res=128`, other defaults "
        "untouched: scenes with a `height` default, e.g. spheres-direct and mesh-env, keep "
        "`height=96`). Every scene sets its own integrator and filter; only `spp` and the "
        "seed differ.",
        "",
        "\"rel. std-error\" is the mean per-pixel standard error of the reference "
        "(estimated from the spread of the passes) divided by the image mean.",
        "",
        "| reference | scene | size | spp | mean R | mean G | mean B | rel. std-error | render time |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    lines += old_rows
    for stem, scene, w, h, spp, secs, m, rel in rows:
        lines.append(f"| {stem}.exr | {scene} | {w}x{h} | {spp} | {m[0]:.5f} | {m[1]:.5f} | "
                     f"{m[2]:.5f} | {rel:.1e} | {secs:.0f} s |")
    lines += ["", "Rows last updated on %s on a 2-core machine." % datetime.date.today().isoformat(), ""]
    with open(readme, "w") as f:
        f.write("\n".join(lines))


def render_gallery(names, pass_spp):
    """Renders GALLERY (all, or the stems in `names`) into
    tests/references/gallery/ and updates the table in its README.md."""
    out_dir = os.path.join(ROOT, "tests", "references", "gallery")
    os.makedirs(out_dir, exist_ok=True)
    readme = os.path.join(out_dir, "README.md")
    rows = {}
    if os.path.exists(readme):
        for line in open(readme):
            m = re.match(r"\| ([^ |]+)\.exr \|", line)
            if m:
                rows[m.group(1)] = line.rstrip("\n")
    for stem in (names or list(GALLERY)):
        variant, params, spp = GALLERY[stem]
        pick_variant(variant)
        path = os.path.join(ROOT, "scenes", stem + ".xml")
        img, stderr, spp, secs, names_ = render_reference(path, params.get("res", 32), spp, pass_spp, params)
        write_exr(os.path.join(out_dir, stem + ".exr"), img, names_)
        m = img[:, :, :3].reshape(-1, 3).mean(0)
        rel = float(stderr[:, :, :3].mean() / max(img[:, :, :3].mean(), 1e-12))
        print(f"{stem}: {img.shape[1]}x{img.shape[0]}, {spp} spp, {secs:.0f}s, mean RGB "
              f"{m[0]:.5f} {m[1]:.5f} {m[2]:.5f}, rel. std-error {rel:.2e}", flush=True)
        args = " ".join(f"{k}={v}" for k, v in params.items())
        rows[stem] = (f"| {stem}.exr | `{args}` | {variant} | {img.shape[1]}x{img.shape[0]} | {spp} | "
                      f"{m[0]:.5f} | {m[1]:.5f} | {m[2]:.5f} | {rel:.1e} | {secs:.0f} s |")
    lines = [
        "# Gallery reference images",
        "",
        "The README gallery scenes (`scenes/*.xml`) at thumbnail size, rendered by Mitsuba %s "
        "with `tools/make_references.py --gallery --pass-spp %d` (scene, variant, parameters "
        "and spp from its `GALLERY` table) and compared by tests/gallery_scenes.rs. Each "
        "scene is loaded with the parameters listed (its own `<default>`s) and rendered as "
        "spp / %d passes with seeds 0, 1, 2, ..., averaged in float64; files as in "
        "../README.md. The polarized variant's files hold the Stokes channels too."
        % (mi.__version__, pass_spp, pass_spp),
        "",
        "prism and diamond are rendered with a constant named IOR (`glass=bk7`, `gem=diamond`): "
        "their default Sellmeier glasses are Snell's own. calcite (`birefringent`) has no "
        "Mitsuba reference; tests/gallery_scenes.rs checks it another way.",
        "",
        "\"rel. std-error\" is the mean per-pixel standard error of the reference "
        "(from the spread of the passes) divided by the image mean.",
        "",
        "| reference | parameters | variant | size | spp | mean R | mean G | mean B | rel. std-error | render time |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines += [rows[k] for k in GALLERY if k in rows]
    lines += ["", "Rows last updated on %s on a 2-core machine." % datetime.date.today().isoformat(), ""]
    with open(readme, "w") as f:
        f.write("\n".join(lines))


if __name__ == "__main__":
    main()

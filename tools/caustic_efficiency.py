#!/usr/bin/env python3
"""Issue 16's efficiency table in one run: every caustic method of Snell
against Snell's path tracer and Mitsuba 3's, at equal CPU time.

Scenes: the caustic Cornell box, the glass of water, the diamond (RGB mode,
its stone at the named index `diamond`, 2.419, which Mitsuba reads too) and
the pool under a small sun. Methods: Snell's `path`, `bdpt`, `vcm` and `sppm`
(each scene's best measured setting, see SCENES below) and Mitsuba 3.9.1
`llvm_ad_rgb`'s `path` on the same XML (when Mitsuba imports here or in
.venv-mitsuba). Every render has a box pixel filter (`--filter scene`: the
scene's own, for all renders and the reference) and the scene's own
max_depth and sampler (sppm's camera paths: the sampler SCENES names).

Equal time: each method is first rendered at a small count (seed 999); its
count (samples per pixel, or iterations) is then scaled so that a render
takes --seconds of CPU time per thread. Each method then renders seeds
1..--runs at that count; printed per method:

    efficiency = 1 / (relMSE x CPU seconds / threads),

relMSE = mean over pixels and channels of (x - ref)^2 / (ref^2 + 0.01) (as
tools/bench.py), averaged over the runs, less the reference's own noise
(for a path-traced reference: the variance of `path`'s runs, scaled by
their sample count over the reference's; the measured figure is printed
too); CPU seconds the median of the
render loop's (Snell's `render_cpu_seconds`, Mitsuba's process time around
mi.render after a warm-up render that compiles its kernels). The ratio
columns divide by Snell's `path` and by Mitsuba's `path`. "bias" is each
method's mean over the runs divided by the reference's mean, per channel.

References: Snell `path` at a high sample count (seed 7777), or for the pool,
which a path tracer does not converge on, a long `sppm` render (many
photons, a small fixed radius). Kept in --ref-dir and reused when present.

Usage: python3 tools/caustic_efficiency.py [--res 64] [--seconds 1.0] [--runs 3]
           [--scenes caustic-box,glass-of-water,diamond,pool] [--threads 2]
           [--mitsuba-python .venv-mitsuba/bin/python] [--json out.json]
"""
import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
from bench import LLVM_LIB, read_pfm, rel_mse, run_snell, scene_variant  # noqa: E402

VENV_PY = os.path.join(ROOT, ".venv-mitsuba", "bin", "python")

# Per scene: its file, -D settings, sppm's properties and camera sampler (the
# best measured in docs/performance.md), and the reference.
SCENES = {
    "caustic-box": dict(
        file="scenes/caustic-cornell-box.xml", defines={},
        sppm=[{"photons": "final_gather", "vertex_radius_scale": 2.0}, {"photons": "indirect"}],
        sppm_sampler="zsobol", ref=("path", 32768)),
    "glass-of-water": dict(
        file="scenes/glass-of-water.xml", defines={},
        sppm=[{"photons": "indirect", "radius_footprints": 6.0}, {"photons": "caustics", "radius_footprints": 3.0}],
        sppm_sampler="zsobol", ref=("path", 32768)),
    "diamond": dict(
        file="scenes/diamond.xml", defines={"gem": "diamond"},
        sppm=[{"photons": "caustics", "radius_footprints": 3.0},
              {"photons": "caustics", "radius_footprints": 3.0, "camera_paths": 16}], sppm_sampler="zsobol",
        ref=("path", 65536)),
    "pool": dict(
        file="scenes/pool-sun.xml", defines={},
        # About 6 photons a pixel, as measured at 128²; photon_count set in main().
        sppm=[{"photons": "caustics", "photons_per_pixel": 6.1}], sppm_sampler=None,
        ref=("sppm", 64, 1_000_000, 0.02)),
}

METHODS = ["path", "bdpt", "vcm", "sppm", "mitsuba path"]
# The short calibration render's count per method.
CALIBRATION = {"path": 32, "bdpt": 8, "vcm": 8, "sppm": 16, "mitsuba path": 32}


def prop(name, value):
    if isinstance(value, str):
        return f'<string name="{name}" value="{value}"/>'
    if isinstance(value, float):
        return f'<float name="{name}" value="{value}"/>'
    return f'<integer name="{name}" value="{value}"/>'


def integrator_xml(kind, props):
    inner = '<integer name="max_depth" value="$max_depth"/>' + "".join(prop(k, v) for k, v in props.items())
    return f'<integrator type="{kind}">{inner}</integrator>'


# The pixel filter of every render: a box (the default; `sppm` long took
# only a box) or the scene's own (--filter scene; Mitsuba's default is a
# Gaussian, which `path` splats over neighbouring pixels).
BOX_FILTER = True


def variant(scene_file, integrator, sampler, tag):
    """A copy of the scene beside it with `integrator`, a box pixel filter
    (unless --filter scene) and, if given, `sampler`."""
    return scene_variant(os.path.join(ROOT, scene_file), f".caustic-eff-{tag}-", integrator, sampler,
                         box_filter=BOX_FILTER)


def snell_render(args, xml, count, seed, out, defines):
    """Renders; returns the render loop's CPU seconds per thread."""
    return float(run_snell(args.snell, xml, out, count, seed, args.threads, defines)["render_cpu_seconds"]) / args.threads


def mitsuba_python(args):
    if args.no_mitsuba:
        return None
    if args.mitsuba_python:
        return args.mitsuba_python
    return VENV_PY if os.path.exists(VENV_PY) else None


def mitsuba_render(args, py, xml, count, seeds, out, defines):
    """Renders with Mitsuba's path tracer (bench.py's worker: a warm-up render,
    then one per seed, in chunks of ≤ 1024 spp); CPU seconds per thread per seed,
    or None if Mitsuba does not run."""
    argv = [py, os.path.join(ROOT, "tools", "bench.py"), "--mitsuba-efficiency-worker", "--scene", xml,
            "--spp", str(count), "--res", str(args.res), "--max-depth", defines["max_depth"],
            "--threads", str(args.threads), "--sampler", "independent",
            "--seeds", ",".join(map(str, seeds)), "--out", out]
    for k, v in defines.items():
        if k != "max_depth":
            argv += ["-D", f"{k}={v}"]
    env = dict(os.environ)
    env.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    r = subprocess.run(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    at = r.stdout.rfind('{"seconds"')
    if r.returncode != 0 or at < 0:
        print(f"  mitsuba: worker failed (exit {r.returncode}); skipping\n{r.stdout[-2000:]}")
        return None
    return [cpu / args.threads for _wall, cpu in json.loads(r.stdout[at:].strip())["seconds"]]


def channel_means(px):
    return [statistics.fmean(px[c::3]) for c in range(3)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--seconds", type=float, default=1.0, help="CPU seconds per thread of each render")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--ref-dir", default="/tmp/caustic-eff-refs")
    ap.add_argument("--ref-scale", type=float, default=1.0,
                    help="multiplies the references' sample and iteration counts (quick checks)")
    ap.add_argument("--mitsuba-python")
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--sppm", action="append", default=[], metavar="KEY=VALUE,...",
                    help="an sppm setting to measure instead of the scene's (repeatable), e.g. "
                         "photons=indirect,radius_footprints=3 (sampler=NAME: the camera paths' sampler)")
    ap.add_argument("--filter", choices=["box", "scene"], default="box",
                    help="every render's pixel filter: a box, or the scene's own")
    ap.add_argument("--json")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    args = ap.parse_args()
    global BOX_FILTER
    BOX_FILTER = args.filter == "box"
    methods = args.methods.split(",")
    for m in methods:
        if m not in METHODS:
            sys.exit(f"--methods: unknown {m!r} (choices: {', '.join(METHODS)})")
    py = mitsuba_python(args)
    os.makedirs(args.ref_dir, exist_ok=True)
    tag = str(os.getpid())
    results = []
    print(f"{args.res}², {args.threads} threads, {args.seconds} CPU s per thread per render, {args.runs} runs; "
          f"load {os.getloadavg()[0]:.1f}")
    for name in args.scenes.split(","):
        if name not in SCENES:
            sys.exit(f"--scenes: unknown {name!r} (choices: {', '.join(SCENES)})")
        sc = SCENES[name]
        text = open(os.path.join(ROOT, sc["file"])).read()
        m = re.search(r'<default name="max_depth" value="(\d+)"/>', text)
        defines = dict(sc["defines"], res=str(args.res), max_depth=m.group(1) if m else "8")
        files = {
            "path": variant(sc["file"], integrator_xml("path", {}), None, tag + "-path"),
            "bdpt": variant(sc["file"], integrator_xml("bdpt", {}), None, tag + "-bdpt"),
            "vcm": variant(sc["file"], integrator_xml("vcm", {}), None, tag + "-vcm"),
        }
        # Each sppm setting is a method of its own, named by its properties.
        sppm_methods = []
        settings = sc["sppm"]
        if args.sppm:
            settings = []
            for text in args.sppm:
                setting = {}
                for kv in text.split(","):
                    key, _, value = kv.partition("=")
                    try:
                        setting[key] = int(value) if value.isdigit() else float(value)
                    except ValueError:
                        setting[key] = value
                settings.append(setting)
        for k, setting in enumerate(settings):
            props = dict(setting)
            per_px = props.pop("photons_per_pixel", None)
            if per_px:
                props["photon_count"] = int(round(per_px * args.res * args.res))
            # `sampler` is the camera paths' sampler, not an sppm property.
            sampler = props.pop("sampler", sc["sppm_sampler"])
            label = "sppm " + ",".join(f"{key}={v}" for key, v in props.items())
            if sampler != sc["sppm_sampler"]:
                label += f",sampler={sampler}"
            files[label] = variant(sc["file"], integrator_xml("sppm", props), sampler, f"{tag}-sppm{k}")
            sppm_methods.append(label)
        files["mitsuba path"] = files["path"]
        try:
            print(f"== {name} ({sc['file']}, max_depth {defines['max_depth']}, -D {sc['defines']}); "
                  f"sppm's camera sampler {sc['sppm_sampler'] or 'as the scene'}")
            scale = "" if args.ref_scale == 1.0 else f"-x{args.ref_scale}"
            scale += "" if BOX_FILTER else "-scene-filter"
            ref_file = os.path.join(args.ref_dir, f"{name}-{args.res}{scale}.pfm")
            if not os.path.exists(ref_file):
                if sc["ref"][0] == "path":
                    spp = max(1, round(sc["ref"][1] * args.ref_scale))
                    secs = snell_render(args, files["path"], spp, 7777, ref_file, defines)
                    how = f"Snell path, {spp} spp"
                else:
                    _, iters, photons, radius = sc["ref"]
                    iters = max(1, round(iters * args.ref_scale))
                    xml = variant(sc["file"], integrator_xml("sppm", {"photon_count": photons, "initial_radius": radius}),
                                  None, tag + "-ref")
                    try:
                        secs = snell_render(args, xml, iters, 7777, ref_file, defines)
                    finally:
                        os.remove(xml)
                    how = f"Snell sppm, {iters} iterations of {photons} photons, radius {radius}"
                print(f"  reference: {how} ({secs:.1f} CPU s per thread) -> {ref_file}")
            else:
                print(f"  reference: {ref_file} (kept)")
            ref = read_pfm(ref_file)[2]
            ref_means = channel_means(ref)
            rows = {}
            run = [m for m in methods if m != "sppm"]
            if "sppm" in methods:
                run[run.index("mitsuba path") if "mitsuba path" in run else len(run):0] = sppm_methods
            for k, method in enumerate(run):
                out = f"/tmp/caustic-eff-{tag}-{name}-{k}"
                c0 = CALIBRATION["sppm" if method.startswith("sppm") else method]
                if method == "mitsuba path":
                    if py is None:
                        print("  mitsuba path: Mitsuba not found (tools/setup-mitsuba.sh or --mitsuba-python); skipped")
                        continue
                    cal = mitsuba_render(args, py, files[method], c0, [999], out + "-cal", defines)
                    if cal is None:
                        continue
                    os.remove(f"{out}-cal-999.pfm")
                    t0 = cal[0]
                else:
                    t0 = snell_render(args, files[method], c0, 999, out + "-cal.pfm", defines)
                    os.remove(out + "-cal.pfm")
                count = max(1, round(c0 * args.seconds / max(t0, 1e-3)))
                seeds = list(range(1, args.runs + 1))
                if method == "mitsuba path":
                    secs = mitsuba_render(args, py, files[method], count, seeds, out, defines)
                    if secs is None:
                        continue
                    images = [f"{out}-{s}.pfm" for s in seeds]
                else:
                    images = [f"{out}-{s}.pfm" for s in seeds]
                    secs = [snell_render(args, files[method], count, s, img, defines) for s, img in zip(seeds, images)]
                errs, means, pixels = [], [], []
                for img in images:
                    px = read_pfm(img)[2]
                    errs.append(rel_mse(px, ref))
                    means.append(channel_means(px))
                    pixels.append(px)
                    os.remove(img)
                e, t = statistics.fmean(errs), statistics.median(secs)
                # The variance part of relMSE (the runs' spread, per pixel and
                # channel, weighted as relMSE); the rest is bias² (with the
                # reference's own noise).
                var = (statistics.fmean(statistics.variance(v) / (r * r + 1e-2) for v, r in zip(zip(*pixels), ref))
                       if len(pixels) > 1 else float("nan"))
                bias = [statistics.fmean(mm[c] for mm in means) / ref_means[c] for c in range(3)]
                rows[method] = {"count": count, "rel_mse": e, "seconds": t, "efficiency": 1.0 / (e * t),
                                "bias": bias, "variance": var, "rel_mse_runs": errs}
                print(f"  {method}: {count} {'iterations' if method.startswith(('sppm', 'vcm')) else 'spp'}, "
                      f"relMSE {e:.3e} (variance {var:.2e})  CPU s {t:6.2f}  efficiency {1.0 / (e * t):10.2f}  "
                      f"bias {' '.join(f'{b:.3f}' for b in bias)}")
            # The reference's own noise is in every relMSE above: E[(x − ref)²]
            # = E[(x − truth)²] + Var(ref) for an unbiased reference independent
            # of x. A path-traced reference has the variance of `path`'s runs
            # scaled by their sample counts; it is subtracted, so that the
            # best methods, whose error comes near it, are not understated.
            # (The pool's sppm reference has no such estimate: not corrected.)
            ref_noise = 0.0
            if sc["ref"][0] == "path" and "path" in rows and not math.isnan(rows["path"]["variance"]):
                ref_spp = max(1, round(sc["ref"][1] * args.ref_scale))
                ref_noise = rows["path"]["variance"] * rows["path"]["count"] / ref_spp
                print(f"  the reference's noise (relMSE of a {ref_spp}-spp path render, from path's runs): {ref_noise:.2e}")
            for method, row in rows.items():
                row["ref_noise"] = ref_noise
                row["rel_mse_raw"] = row["rel_mse"]
                row["efficiency_raw"] = row["efficiency"]
                row["rel_mse"] = row["rel_mse_raw"] - ref_noise
                # A relMSE at the reference's noise cannot be told from zero.
                row["efficiency"] = 1.0 / (row["rel_mse"] * row["seconds"]) if row["rel_mse"] > 0 else float("inf")
            for method, row in rows.items():
                for base in ("path", "mitsuba path"):
                    if base in rows:
                        row[f"x {base}"] = row["efficiency"] / rows[base]["efficiency"]
            results.append({"scene": name, "file": sc["file"], "res": args.res, "rows": rows})
        finally:
            for f in set(files.values()):
                if os.path.exists(f):
                    os.remove(f)

    print("\nrelMSE: against the reference, less the reference's own noise (measured relMSE in brackets); "
          "efficiency and ratios from it")
    print(f"\n| scene | method | count | relMSE (measured) | of which variance | CPU s / thread | efficiency | x Snell path | x Mitsuba path | bias R G B |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for res in results:
        for method, r in res["rows"].items():
            xp = f"{r['x path']:.2f}" if "x path" in r else ""
            xm = f"{r['x mitsuba path']:.2f}" if "x mitsuba path" in r else ""
            print(f"| {res['scene']} | {method} | {r['count']} | {r['rel_mse']:.3e} ({r['rel_mse_raw']:.3e}) | {r['variance']:.2e} | {r['seconds']:.2f} | "
                  f"{r['efficiency']:.1f} | {xp} | {xm} | {' '.join(f'{b:.3f}' for b in r['bias'])} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()

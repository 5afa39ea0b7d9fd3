#!/usr/bin/env python3
"""Performance benchmark: Snell vs Mitsuba 3 (llvm_ad_rgb) on the same scenes.

By default two scenes: the Cornell box (diffuse) and the caustic Cornell box
(glass and metal spheres: long specular paths); --scene (repeatable) picks others.
For each scene, Snell and then Mitsuba run back to back, so both see the same
machine load. --modes rgb,spectral adds Snell's spectral mode against Mitsuba's
llvm_ad_spectral (the spectral overhead is the spectral/rgb ratio of each);
spectral-polarized measures the polarized mode against llvm_ad_spectral_polarized.

Snell half: runs, N times,
  target/release/snell render SCENE -o /tmp/bench.exr --spp 256 -D res=512 \
      -D max_depth=8 [-D k=v ...] --threads 2 --stats /tmp/stats.json
and reads `samples_per_second` and `render_seconds` from the stats JSON.

Mitsuba half (if Mitsuba imports, here or in .venv-mitsuba): loads the same XML
with the same parameters, limits Dr.Jit to the same thread count
(drjit.set_thread_count), does one warm-up render (JIT compilation excluded),
then times N renders (mi.render + dr.eval + dr.sync_thread only) and reports
width*height*spp / seconds.

Prints both medians and the ratio snell/mitsuba (samples/s; > 1 = Snell faster).

Usage: python3 tools/bench.py [--runs 3] [--scene scenes/cornell-box.xml]...
           [--spp 256] [--res 512] [--threads 2] [-D key=value ...]
           [--snell target/release/snell] [--no-snell] [--no-mitsuba] [--json out.json]
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LLVM_LIB = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"
VENV_PY = os.path.join(ROOT, ".venv-mitsuba", "bin", "python")


def scene_params(scene, res, max_depth_default, extra):
    """Parameters to pass: res, max_depth (if declared) and the -D extras."""
    declared = set(re.findall(r'<default\s+name="([^"]+)"', open(scene).read()))
    params = {"res": str(res), "max_depth": str(max_depth_default)}
    for kv in extra:
        k, _, v = kv.partition("=")
        params[k] = v
    dropped = [k for k in params if k not in declared]
    for k in dropped:
        print(f"note: scene does not declare '{k}', not passing it", file=sys.stderr)
    return {k: v for k, v in params.items() if k in declared}


# ----------------------------------------------------------------------------- Snell

def bench_snell(args, params):
    exe = args.snell
    if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        print(f"snell: {exe} not found (cargo build --release first); skipping")
        return None
    cmd = [exe, "render", args.scene, "-o", "/tmp/bench.exr", "--spp", str(args.spp)]
    for k, v in params.items():
        cmd += ["-D", f"{k}={v}"]
    cmd += ["--threads", str(args.threads), "--stats", "/tmp/stats.json", "--mode", args.mode]
    print("snell: " + " ".join(cmd))
    sps, secs = [], []
    for i in range(args.runs):
        if os.path.exists("/tmp/stats.json"):
            os.remove("/tmp/stats.json")
        r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
        if r.returncode != 0:
            print(r.stdout)
            sys.exit(f"snell failed with exit code {r.returncode}")
        with open("/tmp/stats.json") as f:
            st = json.load(f)
        sps.append(float(st["samples_per_second"]))
        secs.append(float(st["render_seconds"]))
        print(f"  run {i + 1}: {secs[-1]:.3f} s, {sps[-1] / 1e6:.3f} M samples/s")
    return {"samples_per_second": statistics.median(sps),
            "render_seconds": statistics.median(secs), "runs": len(sps)}


# --------------------------------------------------------------------------- Mitsuba

# Snell's --mode and the Mitsuba variant it is measured against.
MITSUBA_VARIANT = {"rgb": "llvm_ad_rgb", "spectral": "llvm_ad_spectral", "spectral-polarized": "llvm_ad_spectral_polarized"}


def mitsuba_worker(args, params):
    """Runs inside a Python that has mitsuba; prints one JSON line at the end."""
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(MITSUBA_VARIANT[args.mode])
    dr.set_thread_count(args.threads)
    scene = mi.load_file(args.scene, **params)
    w, h = scene.sensors()[0].film().size()
    n = int(w) * int(h) * args.spp

    def one():
        t = time.perf_counter()
        img = mi.render(scene, spp=args.spp, seed=0)
        dr.eval(img)
        dr.sync_thread()
        return time.perf_counter() - t

    warm = one()  # includes tracing + JIT compilation; not counted
    print(f"  warm-up (incl. JIT): {warm:.3f} s", file=sys.stderr)
    secs = []
    for i in range(args.runs):
        secs.append(one())
        print(f"  run {i + 1}: {secs[-1]:.3f} s, {n / secs[-1] / 1e6:.3f} M samples/s",
              file=sys.stderr)
    med = statistics.median(secs)
    print(json.dumps({"samples_per_second": n / med, "render_seconds": med,
                      "runs": len(secs), "width": int(w), "height": int(h),
                      "threads": dr.thread_count(), "mitsuba": mi.__version__,
                      "variant": mi.variant()}))


def bench_mitsuba(args):
    try:
        import mitsuba  # noqa: F401
        py = sys.executable
    except ImportError:
        py = VENV_PY if os.path.exists(VENV_PY) else None
    if py is None:
        print("mitsuba: not importable and no .venv-mitsuba (tools/setup-mitsuba.sh); skipping")
        return None
    env = dict(os.environ)
    env.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    variant = MITSUBA_VARIANT[args.mode]
    print(f"mitsuba: {variant}, {args.threads} threads, via {py}")
    argv = ["--mitsuba-worker", "--scene", args.scene, "--spp", str(args.spp),
            "--res", str(args.res), "--max-depth", str(args.max_depth),
            "--threads", str(args.threads), "--runs", str(args.runs), "--mode", args.mode]
    for kv in args.defines:
        argv += ["-D", kv]
    r = subprocess.run([py, os.path.abspath(__file__)] + argv,
                       cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    if r.returncode != 0:
        print(f"mitsuba: worker failed (exit {r.returncode}); skipping")
        return None
    return json.loads(r.stdout.strip().splitlines()[-1])


DEFAULT_SCENES = ["scenes/cornell-box.xml", "scenes/caustic-cornell-box.xml"]


def bench_scene(args):
    """Snell then Mitsuba on args.scene; prints and returns the figures."""
    params = scene_params(args.scene, args.res, args.max_depth, args.defines)
    rel = os.path.relpath(args.scene, ROOT)
    print(f"== {rel} ({args.mode}): {args.res}², {args.spp} spp, {params}, {args.threads} threads")
    res = {"scene": rel, "mode": args.mode, "spp": args.spp, "params": params, "threads": args.threads}
    res["snell"] = None if args.no_snell else bench_snell(args, params)
    res["mitsuba"] = None if args.no_mitsuba else bench_mitsuba(args)
    s, m = res["snell"], res["mitsuba"]
    if s:
        print(f"snell   median: {s['samples_per_second'] / 1e6:8.3f} M samples/s "
              f"({s['render_seconds']:.3f} s)")
    if m:
        print(f"mitsuba median: {m['samples_per_second'] / 1e6:8.3f} M samples/s "
              f"({m['render_seconds']:.3f} s, {m['variant']} {m['mitsuba']}, "
              f"{m['threads']} threads)")
    if s and m:
        res["ratio_snell_over_mitsuba"] = s["samples_per_second"] / m["samples_per_second"]
        print(f"ratio snell/mitsuba (samples/s): {res['ratio_snell_over_mitsuba']:.3f}")
    print()
    return res


def main():
    sys.stdout.reconfigure(line_buffering=True)  # keep order with the worker's stderr
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--scene", action="append", default=[],
                    help="scene to benchmark (repeatable); default: " + ", ".join(DEFAULT_SCENES))
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--res", type=int, default=512)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("-D", dest="defines", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    ap.add_argument("--no-snell", action="store_true")
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--json", help="also write the results to this file")
    ap.add_argument("--modes", default="rgb",
                    help="comma-separated: rgb, spectral, spectral-polarized (Snell --mode; Mitsuba "
                         "llvm_ad_rgb / llvm_ad_spectral / llvm_ad_spectral_polarized); e.g. --modes rgb,spectral")
    ap.add_argument("--mode", default="rgb", help=argparse.SUPPRESS)
    ap.add_argument("--mitsuba-worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    scenes = [os.path.join(ROOT, sc) if not os.path.isabs(sc) else sc
              for sc in (args.scene or DEFAULT_SCENES)]
    missing = [sc for sc in scenes if not os.path.isfile(sc)]
    if missing:
        sys.exit("error: no such scene: " + ", ".join(missing))

    if args.mitsuba_worker:
        args.scene = scenes[0]
        mitsuba_worker(args, scene_params(args.scene, args.res, args.max_depth, args.defines))
        return

    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    bad = [m for m in modes if m not in MITSUBA_VARIANT]
    if bad:
        sys.exit("error: unknown mode(s) " + ", ".join(bad) + " (valid: " + ", ".join(MITSUBA_VARIANT) + ")")
    results = []
    for sc in scenes:
        for mode in modes:
            args.scene, args.mode = sc, mode
            results.append(bench_scene(args))
    print("summary (M samples/s, median of %d runs)" % args.runs)
    print(f"{'scene':<36} {'mode':<9} {'snell':>8} {'mitsuba':>8} {'ratio':>6}")
    for r in results:
        sn = r["snell"]["samples_per_second"] / 1e6 if r["snell"] else float("nan")
        mi_ = r["mitsuba"]["samples_per_second"] / 1e6 if r["mitsuba"] else float("nan")
        ra = r.get("ratio_snell_over_mitsuba", float("nan"))
        print(f"{r['scene']:<36} {r['mode']:<9} {sn:8.3f} {mi_:8.3f} {ra:6.3f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Efficiency of light selection: 1 / (relMSE x render seconds) of Snell's
`light_sampling` = uniform, power and bvh, and of Mitsuba 3 (llvm_ad_rgb,
which selects emitters uniformly), in the same run on the same machine.

For each scene:
  1. a reference: Snell with bvh at --ref-spp samples per pixel (kept in
     /tmp between runs, keyed by scene, resolution and spp);
  2. each Snell strategy at --spp: `snell render` on a copy of the scene whose
     path integrator asks for that strategy, --threads N, render_seconds read
     from --stats; the image is compared with the reference;
  3. Mitsuba at --spp with Dr.Jit limited to N threads: one warm-up render
     (JIT compilation excluded), then a timed one (seed 1).

relMSE = mean over pixels and channels of (x - r)^2 / (r^2 + 0.01), the
definition of tests/common/mod.rs. The reference's own noise adds about
spp / ref-spp of the best method's relMSE; keep ref-spp >> spp.

Usage: python3 tools/light_efficiency.py [--scene scenes/many-lights.xml]...
           [--res 128] [--spp 32] [--ref-spp 4096] [--threads 2] [--runs 1]
           [--snell target/release/snell] [--no-mitsuba] [--json out.json]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

LLVM_LIB = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
import exrio  # noqa: E402
from bench import run_snell  # noqa: E402


def read_exr(path):
    """An EXR as float array (Snell writes compressed EXR: read through
    Mitsuba's Bitmap when Mitsuba is importable, else tools/exrio.py)."""
    try:
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
        import mitsuba as mi
        if mi.variant() is None:
            mi.set_variant("scalar_rgb")
        return np.array(mi.Bitmap(path), dtype=np.float32)
    except ImportError:
        return exrio.read_exr(path)

VENV_PY = os.path.join(ROOT, ".venv-mitsuba", "bin", "python")
MAIN_VENV_PY = "/work/main/.venv-mitsuba/bin/python"
STRATEGIES = ["uniform", "power", "bvh"]
DEFAULT_SCENES = ["scenes/cornell-box.xml", "scenes/many-lights.xml"]


def rel_mse(img, ref):
    img, ref = img[:, :, :3].astype(np.float64), ref[:, :, :3].astype(np.float64)
    return float(np.mean((img - ref) ** 2 / (ref * ref + 1e-2)))


def declared(scene):
    return set(re.findall(r'<default\s+name="([^"]+)"', open(scene).read()))


def with_strategy(scene, strategy):
    """A copy of `scene` beside it (relative paths keep working) whose
    integrator asks for `strategy`."""
    text = open(scene).read()
    m = re.search(r'<integrator\s+type="(path|direct)"\s*(/?)>', text)
    if not m:
        sys.exit(f"{scene}: no path/direct integrator to set light_sampling on")
    line = f'<string name="light_sampling" value="{strategy}"/>'
    if m.group(2) == "/":
        new = text[:m.start()] + f'<integrator type="{m.group(1)}">{line}</integrator>' + text[m.end():]
    else:
        new = text[:m.end()] + line + text[m.end():]
    fd, path = tempfile.mkstemp(suffix=".xml", prefix=".light-eff-", dir=os.path.dirname(scene))
    with os.fdopen(fd, "w") as f:
        f.write(new)
    return path


def snell_render(args, scene, strategy, spp, out):
    path = with_strategy(scene, strategy)
    try:
        defines = {"res": args.res} if "res" in declared(scene) else {}
        secs = float(run_snell(args.snell, path, out, spp, None, args.threads, defines)["render_seconds"])
        return read_exr(out), secs
    finally:
        os.remove(path)


def mitsuba_worker(args):
    """Runs inside a Python with mitsuba: renders and prints JSON (seconds, image path)."""
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    import drjit as dr
    import mitsuba as mi
    from exrio import write_exr  # noqa: F401

    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(args.threads)
    params = {"res": str(args.res)} if "res" in declared(args.scene) else {}
    scene = mi.load_file(args.scene, **params)
    img = mi.render(scene, spp=args.spp, seed=0)  # warm-up: tracing + JIT compilation
    dr.eval(img)
    dr.sync_thread()
    secs = []
    for i in range(args.runs):
        t = time.perf_counter()
        img = mi.render(scene, spp=args.spp, seed=1 + i)
        dr.eval(img)
        dr.sync_thread()
        secs.append(time.perf_counter() - t)
    write_exr(args.out, np.array(img, dtype=np.float32)[:, :, :3])
    print(json.dumps({"seconds": sorted(secs)[len(secs) // 2], "mitsuba": mi.__version__,
                      "threads": dr.thread_count()}))


def mitsuba_render(args, scene, out):
    py = None
    try:
        import mitsuba  # noqa: F401
        py = sys.executable
    except ImportError:
        py = next((p for p in [VENV_PY, MAIN_VENV_PY] if os.path.exists(p)), None)
    if py is None:
        print("mitsuba: not importable and no .venv-mitsuba; skipping")
        return None
    env = dict(os.environ)
    env.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    argv = [py, os.path.abspath(__file__), "--mitsuba-worker", "--scene", scene, "--spp", str(args.spp),
            "--res", str(args.res), "--threads", str(args.threads), "--runs", str(args.runs), "--out", out]
    r = subprocess.run(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    if r.returncode != 0:
        print(f"mitsuba: worker failed ({r.returncode}); skipping")
        return None
    info = json.loads(r.stdout.strip().splitlines()[-1])
    return read_exr(out), info


def bench_scene(args, scene):
    stem = os.path.splitext(os.path.basename(scene))[0]
    rel = os.path.relpath(scene, ROOT)
    print(f"== {rel}: {args.res}², {args.spp} spp (reference: snell bvh, {args.ref_spp} spp), "
          f"{args.threads} threads")
    ref_path = os.path.join(tempfile.gettempdir(), f"light-eff-ref-{stem}-{args.res}-{args.ref_spp}.exr")
    if not os.path.exists(ref_path):
        print(f"  rendering the reference → {ref_path}")
        snell_render(args, scene, "bvh", args.ref_spp, ref_path)
    ref = read_exr(ref_path)
    rows = []
    tmp = os.path.join(tempfile.gettempdir(), f"light-eff-{os.getpid()}.exr")
    for strategy in STRATEGIES:
        errs, secs = [], []
        for _ in range(args.runs):
            img, s = snell_render(args, scene, strategy, args.spp, tmp)
            errs.append(rel_mse(img, ref))
            secs.append(s)
        rows.append((f"snell {strategy}", float(np.median(errs)), float(np.median(secs))))
    if not args.no_mitsuba:
        m = mitsuba_render(args, scene, tmp)
        if m:
            img, info = m
            rows.append((f"mitsuba {info['mitsuba']} llvm_ad_rgb (uniform)", rel_mse(img, ref), info["seconds"]))
    mitsuba_eff = next((1 / (e * s) for n, e, s in rows if n.startswith("mitsuba")), None)
    out = []
    print(f"  {'method':42} {'relMSE':>10} {'seconds':>8} {'1/(relMSE·s)':>13} {'× mitsuba':>9}")
    for name, e, s in rows:
        eff = 1 / (e * s)
        ratio = f"{eff / mitsuba_eff:9.2f}" if mitsuba_eff else ""
        print(f"  {name:42} {e:10.3e} {s:8.2f} {eff:13.2f} {ratio}")
        out.append({"method": name, "rel_mse": e, "seconds": s, "efficiency": eff,
                    "over_mitsuba": eff / mitsuba_eff if mitsuba_eff else None})
    print()
    return {"scene": rel, "res": args.res, "spp": args.spp, "ref_spp": args.ref_spp, "threads": args.threads,
            "rows": out}


def main():
    sys.stdout.reconfigure(line_buffering=True)
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", action="append", default=[])
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--json")
    ap.add_argument("--mitsuba-worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.mitsuba_worker:
        args.scene = args.scene[0]
        return mitsuba_worker(args)
    scenes = [sc if os.path.isabs(sc) else os.path.join(ROOT, sc) for sc in (args.scene or DEFAULT_SCENES)]
    cpu = sorted(set(re.findall(r"avx512[a-z]*", open("/proc/cpuinfo").read()))) if os.path.exists("/proc/cpuinfo") else []
    print(f"CPU flags: {' '.join(cpu) or 'no avx512'}")
    results = [bench_scene(args, sc) for sc in scenes]
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"cpu_avx512": cpu, "results": results}, f, indent=1)


if __name__ == "__main__":
    main()

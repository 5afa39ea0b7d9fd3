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
Each run also prints its CPU seconds per wall second (Snell: render_cpu_seconds
over render_seconds; Mitsuba: the process's CPU time over the same span), and a
run below 0.9 of its renderer's best is named in a note: another process took
CPU from it, so the medians may be off (the JSON lists such runs).

--mesh 1M,4M: the mesh benchmark instead (bumpy spheres of that many triangles,
written once to /tmp/snell-mesh-bench as binary PLY and OBJ, on a floor under a
constant sky, 512², 16 spp): per run a fresh process; load + build seconds, render
seconds and peak RSS, and bytes per triangle as the RSS growth over a 2000-triangle
mesh; Snell's RSS is the whole run's peak, Mitsuba's the peak after loading (its
render-time memory does not depend on the mesh). Load CPU seconds (user + system,
all threads) are less disturbed by a busy machine than wall seconds: Snell's from a
second run at 16², 1 spp, Mitsuba's around load_file. Prints the CPU's SIMD width.

--simd avx2 (or avx512, baseline) limits both to that instruction set: Snell with
SNELL_SIMD; Mitsuba's Dr.Jit LLVM backend with jit_llvm_set_target (avx2: CPU
"haswell", AVX-512 features off, 8 lanes; baseline: "x86-64", 4 lanes; called
through ctypes, as the Python API does not expose it). Embree, which Mitsuba uses to
trace rays, cannot be limited: Mitsuba's bundled Embree 3 picks its kernels from the
CPU (its config string is fixed and it reads no config file), so on an AVX-512
machine its 8-wide packet kernels are the AVX-512 build's. Without --simd both use
the best the CPU has.

--efficiency measures error per second instead: for each scene it renders a
high-spp reference (--ref-spp, Mitsuba llvm_ad_rgb independent if Mitsuba is
there, else Snell's sobol), then renders --runs images per sampler (seeds
1..runs) at --spp with Snell's independent, multijitter, sobol and zsobol
(--snell-samplers; each --snell-integrator KEY=VALUE,... is a variant with
properties (integer, float, boolean) added to Snell's integrator, e.g. bsdf_samples=2, "" the
scene's own; each --snell-args "FLAGS" a variant with these command-line flags
added, e.g. "--noise-threshold 0.05", "" none) and
Mitsuba's independent, multijitter and ldsampler, in the same run, and prints
  efficiency = 1 / (relMSE × render seconds),
relMSE = mean over pixels and channels of (x − ref)² / (ref² + 0.01), averaged
over the runs; seconds the median render time (Snell: render_seconds of
--stats; Mitsuba: mi.render + dr.eval, after a warm-up render that compiles the
kernels; --cpu-time: the CPU time of the same spans / threads, fairer on a
loaded machine: Snell's render_cpu_seconds, its render loop's process CPU, and
Mitsuba's process CPU over mi.render + dr.eval; Snell's whole-process CPU,
startup and loading included, is printed beside it).
Defaults there: 128², 64 spp, reference 16384 spp.

Usage: python3 tools/bench.py [--runs 3] [--scene scenes/cornell-box.xml]...
           [--spp 256] [--res 512] [--threads 2] [-D key=value ...]
           [--snell target/release/snell] [--no-snell] [--no-mitsuba] [--json out.json]
       python3 tools/bench.py --efficiency [--spp 64] [--res 128] [--ref-spp 16384] ...
"""
import argparse
import array
import json
import os
import re
import shlex
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LLVM_LIB = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"
# --simd: Dr.Jit's LLVM target (CPU, features, vector width) per level.
DRJIT_TARGETS = {
    "avx2": ("haswell", "-avx512f,-avx512vl,-avx512dq,-avx512bw,-avx512cd", 8),
    "baseline": ("x86-64", "-avx,-avx2,-fma,-avx512f,-avx512vl,-avx512dq,-avx512bw,-avx512cd", 4),
}


def snell_env(args):
    """The environment Snell runs in: SNELL_SIMD set by --simd."""
    env = dict(os.environ)
    if args.simd:
        env["SNELL_SIMD"] = args.simd
    return env


def limit_drjit(simd):
    """In a Mitsuba worker, after set_variant: limits Dr.Jit's LLVM backend to --simd
    (jit_llvm_set_target of libdrjit-core, through ctypes); reports the target on stderr."""
    import ctypes
    import drjit as dr
    try:
        lib = ctypes.CDLL(os.path.join(os.path.dirname(dr.__file__), "libdrjit-core.so"))
        cpu, width = lib._Z19jit_llvm_target_cpuv, lib._Z21jit_llvm_vector_widthv
    except (OSError, AttributeError) as e:
        print(f"  mitsuba: cannot reach Dr.Jit's LLVM target ({e}); not limited", file=sys.stderr)
        return
    cpu.restype, width.restype = ctypes.c_char_p, ctypes.c_uint32
    if simd in DRJIT_TARGETS:
        set_target = lib._Z19jit_llvm_set_targetPKcS0_j
        set_target.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32]
        c, f, w = DRJIT_TARGETS[simd]
        set_target(c.encode(), f.encode(), w)
    print(f"  mitsuba: Dr.Jit LLVM target {cpu().decode()}, {width()} lanes (Embree: not limited)", file=sys.stderr)
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
    sps, secs, cpu_per_wall = [], [], []
    for i in range(args.runs):
        if os.path.exists("/tmp/stats.json"):
            os.remove("/tmp/stats.json")
        r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True, env=snell_env(args))
        if r.returncode != 0:
            print(r.stdout)
            sys.exit(f"snell failed with exit code {r.returncode}")
        with open("/tmp/stats.json") as f:
            st = json.load(f)
        sps.append(float(st["samples_per_second"]))
        secs.append(float(st["render_seconds"]))
        cpu_per_wall.append(float(st["render_cpu_seconds"]) / secs[-1])
        print(f"  run {i + 1}: {secs[-1]:.3f} s, {sps[-1] / 1e6:.3f} M samples/s, "
              f"CPU/wall {cpu_per_wall[-1]:.2f}")
    return {"samples_per_second": statistics.median(sps),
            "render_seconds": statistics.median(secs), "runs": len(sps),
            "cpu_per_wall": cpu_per_wall}


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
    if args.simd:
        limit_drjit(args.simd)
    scene = mi.load_file(args.scene, **params)
    w, h = scene.sensors()[0].film().size()
    n = int(w) * int(h) * args.spp

    def one():
        """Wall seconds and the process's CPU seconds (all threads) of a render."""
        t, c = time.perf_counter(), time.process_time()
        img = mi.render(scene, spp=args.spp, seed=0)
        dr.eval(img)
        dr.sync_thread()
        return time.perf_counter() - t, time.process_time() - c

    warm, _ = one()  # includes tracing + JIT compilation; not counted
    print(f"  warm-up (incl. JIT): {warm:.3f} s", file=sys.stderr)
    secs, cpu_per_wall = [], []
    for i in range(args.runs):
        wall, cpu = one()
        secs.append(wall)
        cpu_per_wall.append(cpu / wall)
        print(f"  run {i + 1}: {wall:.3f} s, {n / wall / 1e6:.3f} M samples/s, "
              f"CPU/wall {cpu_per_wall[-1]:.2f}", file=sys.stderr)
    med = statistics.median(secs)
    print(json.dumps({"samples_per_second": n / med, "render_seconds": med,
                      "runs": len(secs), "cpu_per_wall": cpu_per_wall,
                      "width": int(w), "height": int(h),
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
    if args.simd:
        argv += ["--simd", args.simd]
    for kv in args.defines:
        argv += ["-D", kv]
    r = subprocess.run([py, os.path.abspath(__file__)] + argv,
                       cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    if r.returncode != 0:
        print(f"mitsuba: worker failed (exit {r.returncode}); skipping")
        return None
    return json.loads(r.stdout.strip().splitlines()[-1])


# ------------------------------------------------------------------- mesh benchmark

MESH_DIR = "/tmp/snell-mesh-bench"
# Triangles of the small mesh whose run is subtracted to get the growth per triangle.
MESH_BASELINE = 2000


def mesh_grid(n_tris):
    """(nu, nv) of a bumpy sphere with 2·nu·nv ≈ n_tris triangles."""
    nv = max(2, int(round((n_tris / 4) ** 0.5)))
    nu = max(3, int(round(n_tris / (2 * nv))))
    return nu, nv


def write_mesh(path, n_tris):
    """A closed bumpy sphere (radius ≈ 1) as binary little-endian PLY or OBJ; cached.
    Written by a child process: the generator's Python objects leave this process's
    heap hundreds of MiB large, and a process forked from it would start with that
    resident set, which its peak RSS (ru_maxrss) then reports instead of its own."""
    if os.path.exists(path):
        return
    subprocess.run([sys.executable, os.path.abspath(__file__), "--write-mesh-worker", path, str(n_tris)],
                   check=True)


def write_mesh_here(path, n_tris):
    """write_mesh's work, in this process."""
    import array
    import math
    nu, nv = mesh_grid(n_tris)
    pos = array.array("f")
    for j in range(nv + 1):
        th = math.pi * j / nv
        st, ct = math.sin(th), math.cos(th)
        for i in range(nu):
            ph = 2 * math.pi * i / nu
            r = 1.0 + 0.05 * math.sin(37 * ph) * math.sin(23 * th)
            pos.extend((r * st * math.cos(ph), r * st * math.sin(ph), r * ct))
    tris = array.array("i")
    for j in range(nv):
        for i in range(nu):
            a, b = j * nu + i, j * nu + (i + 1) % nu
            tris.extend((a, b, b + nu, a, b + nu, a + nu))
    n_v, n_t = len(pos) // 3, len(tris) // 3
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + ".part"
    if path.endswith(".ply"):
        import struct
        if sys.byteorder != "little":
            pos.byteswap()
            tris.byteswap()
        head = ("ply\nformat binary_little_endian 1.0\n"
                f"element vertex {n_v}\nproperty float x\nproperty float y\nproperty float z\n"
                f"element face {n_t}\nproperty list uchar int vertex_indices\nend_header\n")
        tb = tris.tobytes()
        with open(tmp, "wb") as f:
            f.write(head.encode())
            f.write(pos.tobytes())
            three = b"\x03"
            f.write(b"".join(three + tb[12 * k:12 * k + 12] for k in range(n_t)))
    else:
        with open(tmp, "w") as f:
            f.write("# bumpy sphere, tools/bench.py --mesh\n")
            f.write("".join("v %.6f %.6f %.6f\n" % (pos[3 * k], pos[3 * k + 1], pos[3 * k + 2])
                            for k in range(n_v)))
            f.write("".join("f %d %d %d\n" % (tris[3 * k] + 1, tris[3 * k + 1] + 1, tris[3 * k + 2] + 1)
                            for k in range(n_t)))
    os.replace(tmp, path)


def mesh_scene(mesh_file, res, spp):
    """The XML (beside the mesh) of a diffuse mesh over a floor under a constant sky."""
    kind = "ply" if mesh_file.endswith(".ply") else "obj"
    xml = os.path.splitext(mesh_file)[0] + f"-{kind}.xml"
    with open(xml, "w") as f:
        f.write(f"""<scene version="3.0.0">
    <default name="res" value="{res}"/>
    <default name="spp" value="{spp}"/>
    <default name="max_depth" value="8"/>
    <integrator type="path"><integer name="max_depth" value="$max_depth"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, -3.2, 1.6" target="0, 0, 0" up="0, 0, 1"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm"><integer name="width" value="$res"/><integer name="height" value="$res"/></film>
    </sensor>
    <shape type="{kind}">
        <string name="filename" value="{os.path.basename(mesh_file)}"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="5"/><translate z="-1.05"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
    </shape>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
</scene>
""")
    return xml


def run_measured(cmd, env=None, cpu=None):
    """Runs cmd; returns (exit code, stdout, peak RSS in bytes) of that process alone
    (and, in the dict cpu if given, its user + system CPU seconds as "cpu")."""
    p = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out = p.stdout.read()
    _, status, ru = os.wait4(p.pid, 0)
    p.returncode = os.waitstatus_to_exitcode(status)
    if cpu is not None:
        cpu["cpu"] = ru.ru_utime + ru.ru_stime
    return p.returncode, out, ru.ru_maxrss * 1024


def mesh_snell_once(args, xml):
    stats = os.path.join(MESH_DIR, "stats.json")
    cmd = [args.snell, "render", xml, "-o", os.path.join(MESH_DIR, "out.exr"), "--threads", str(args.threads),
           "--stats", stats, "--quiet"]
    code, out, rss = run_measured(cmd, env=snell_env(args))
    if code != 0:
        sys.exit(f"snell failed ({code}):\n{out}")
    with open(stats) as f:
        st = json.load(f)
    # CPU seconds of loading: a run that renders a 16² image at 1 spp.
    cpu = {}
    code, out, _ = run_measured(cmd + ["-D", "res=16", "-D", "spp=1"], env=snell_env(args), cpu=cpu)
    if code != 0:
        sys.exit(f"snell failed ({code}):\n{out}")
    return {"load": float(st["load_seconds"]), "render": float(st["render_seconds"]), "rss": rss,
            "load_cpu": cpu["cpu"]}


def mitsuba_mesh_worker(args):
    """In a Python with mitsuba: load (timed), RSS after load, warm-up render, timed render."""
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    import resource
    import drjit as dr
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(args.threads)
    if args.simd:
        limit_drjit(args.simd)
    t = time.perf_counter()
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    scene = mi.load_file(args.scene[0])
    load = time.perf_counter() - t
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    load_cpu = (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)
    rss = r1.ru_maxrss * 1024

    def one():
        t = time.perf_counter()
        img = mi.render(scene, seed=0)
        dr.eval(img)
        dr.sync_thread()
        return time.perf_counter() - t

    one()  # JIT compilation
    print(json.dumps({"load": load, "render": one(), "rss": rss, "load_cpu": load_cpu}))


def mesh_mitsuba_once(args, xml, py):
    env = dict(os.environ)
    env.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    code, out, _ = run_measured([py, os.path.abspath(__file__), "--mitsuba-mesh-worker", "--scene", xml,
                                 "--threads", str(args.threads)] + (["--simd", args.simd] if args.simd else []), env)
    if code != 0:
        print(f"mitsuba: worker failed ({code}):\n{out}")
        return None
    return json.loads(out.strip().splitlines()[-1])


def triangle_count(text):
    """A --mesh size: an integer, or with a k/M suffix (2k = 2000, 1.5M = 1 500 000)."""
    t = text.strip()
    scale = {"k": 1e3, "K": 1e3, "m": 1e6, "M": 1e6}.get(t[-1:], 1)
    try:
        n = int(float(t[:-1] if scale != 1 else t) * scale)
    except ValueError:
        sys.exit(f"--mesh: '{text}' is not a triangle count (e.g. 2000, 2k, 1M)")
    if n < 2:
        sys.exit(f"--mesh: '{text}' is too few triangles (at least 2)")
    return n


def bench_mesh(args):
    """--mesh: load + build seconds, render seconds, peak RSS and bytes per triangle
    (RSS growth over a small mesh) for Snell and Mitsuba, medians of --runs, the two
    run in turn and their ratio taken run by run."""
    sizes = [triangle_count(s) for s in args.mesh.split(",")]
    formats = [f.strip() for f in args.mesh_formats.split(",")]
    py = None
    if args.mitsuba_python:
        py = args.mitsuba_python
    elif not args.no_mitsuba:
        try:
            import mitsuba  # noqa: F401
            py = sys.executable
        except ImportError:
            py = VENV_PY if os.path.exists(VENV_PY) else None
    have_snell = not args.no_snell and os.access(args.snell, os.X_OK)
    print(f"mesh benchmark: {args.mesh_res}², {args.mesh_spp} spp, {args.threads} threads, "
          f"{args.runs} runs; CPU SIMD: {cpu_simd()}" + (f"; limited to {args.simd}" if args.simd else ""))
    rows = []
    for fmt in formats:
        base = {}
        for n in [MESH_BASELINE] + sizes:
            nu, nv = mesh_grid(n)
            mesh = os.path.join(MESH_DIR, f"sphere-{2 * nu * nv}.{fmt}")
            write_mesh(mesh, n)
            xml = mesh_scene(mesh, args.mesh_res, args.mesh_spp)
            row = {"format": fmt, "triangles": 2 * nu * nv}
            who_once = [(who, once) for who, once in (
                ("snell", (lambda: mesh_snell_once(args, xml)) if have_snell else None),
                ("mitsuba", (lambda: mesh_mitsuba_once(args, xml, py)) if py else None)) if once is not None]
            # The renderers in turn (Snell, Mitsuba, Snell, ...), so that a
            # drift in the machine's speed reaches both alike; the ratios are
            # taken run by run.
            runs = {who: [] for who, _ in who_once}
            for _ in range(args.runs):
                for who, once in who_once:
                    runs[who].append(once())
            for who, _ in who_once:
                done = [r for r in runs[who] if r]
                if not done:
                    continue
                med = {k: statistics.median(r[k] for r in done) for k in ("load", "render", "rss", "load_cpu")}
                if n == MESH_BASELINE:
                    base[who] = dict(med, triangles=row["triangles"])
                elif who in base:
                    med["bytes_per_tri"] = (med["rss"] - base[who]["rss"]) / (row["triangles"] - base[who]["triangles"])
                row[who] = med
                print(f"  {fmt} {row['triangles']:>8} {who:<8} load+build {med['load']:7.3f} s "
                      f"(CPU {med['load_cpu']:7.3f} s)  "
                      f"render {med['render']:7.3f} s  peak RSS {med['rss'] / 2**20:8.1f} MiB"
                      + (f"  {med['bytes_per_tri']:6.1f} B/tri" if "bytes_per_tri" in med else ""))
            pairs = [(s, m) for s, m in zip(runs.get("snell", []), runs.get("mitsuba", [])) if s and m]
            if pairs:
                # Mitsuba's time over Snell's: above 1 where Snell is faster.
                row["speedup"] = {k: statistics.median(m[k] / s[k] for s, m in pairs) for k in ("load", "render")}
                ratios = " ".join(f"{m['render'] / s['render']:.2f}" for s, m in pairs)
                print(f"  {fmt} {row['triangles']:>8} Mitsuba/Snell, run by run: render {ratios} "
                      f"(median {row['speedup']['render']:.2f}), load median {row['speedup']['load']:.2f}")
            if n != MESH_BASELINE:
                rows.append(row)
    print(f"summary (medians of {args.runs} runs; speedup: Mitsuba's seconds over Snell's, median of the run pairs)")
    print(f"{'mesh':<14} {'':>8} {'load s':>8} {'load CPU':>9} {'render s':>9} {'B/tri':>7} {'speedup load':>13} {'render':>7}")
    for r in rows:
        for who in ("snell", "mitsuba"):
            if who in r:
                m = r[who]
                sp = r.get("speedup") if who == "snell" else None
                print(f"{r['format']} {r['triangles']:>9} {who:<8} {m['load']:8.3f} {m['load_cpu']:9.3f} {m['render']:9.3f} "
                      f"{m.get('bytes_per_tri', float('nan')):7.1f}"
                      + (f" {sp['load']:13.2f} {sp['render']:7.2f}" if sp else ""))
    return rows


def cpu_simd():
    """The widest x86 vector extension the CPU reports (and its model)."""
    try:
        info = open("/proc/cpuinfo").read()
    except OSError:
        return "unknown"
    flags = set(re.findall(r"^flags\s*:(.*)$", info, re.M)[0].split()) if "flags" in info else set()
    model = re.findall(r"^model name\s*:\s*(.*)$", info, re.M)
    width = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "SSE"
    return f"{width} ({model[0] if model else 'unknown model'})"


DEFAULT_SCENES = ["scenes/cornell-box.xml", "scenes/caustic-cornell-box.xml"]


def bench_scene(args):
    """Snell then Mitsuba on args.scene; prints and returns the figures."""
    params = scene_params(args.scene, args.res, args.max_depth, args.defines)
    rel = os.path.relpath(args.scene, ROOT)
    print(f"== {rel} ({args.mode}): {args.res}², {args.spp} spp, {params}, {args.threads} threads"
          + (f", limited to {args.simd}" if args.simd else ""))
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
    contended = {name: runs for name, r in (("snell", s), ("mitsuba", m))
                 if r and (runs := contended_runs(r.get("cpu_per_wall", [])))}
    if contended:
        res["contended_runs"] = contended
        which = "; ".join(f"{name} run {', '.join(str(i + 1) for i in runs)}"
                          for name, runs in contended.items())
        print(f"note: {which} got less CPU per wall second than the best run of the same "
              f"renderer: another process competed, and the medians above may be off")
    print()
    return res


def contended_runs(cpu_per_wall, tolerance=0.9):
    """Indices of the runs whose CPU seconds per wall second fell below
    `tolerance` times the best run's: on a 2-core machine a competing process
    takes CPU from the render's threads, so the ratio drops while the wall time
    grows (a render's own serial parts lower every run's ratio alike)."""
    if len(cpu_per_wall) < 2:
        return []
    best = max(cpu_per_wall)
    return [i for i, r in enumerate(cpu_per_wall) if r < tolerance * best]


# ------------------------------------------------------------------------ efficiency

SNELL_SAMPLERS = ["independent", "multijitter", "sobol", "zsobol"]
MITSUBA_SAMPLERS = ["independent", "multijitter", "ldsampler"]


def read_pfm(path):
    """(width, height, flat list of RGB floats, top row first) of a PF file."""
    with open(path, "rb") as f:
        data = f.read()
    parts = data.split(b"\n", 3)
    if parts[0] != b"PF":
        raise ValueError(f"{path}: not an RGB PFM")
    w, h = map(int, parts[1].split())
    scale = float(parts[2])
    px = array.array("f")
    px.frombytes(parts[3][:w * h * 12])
    if scale > 0:
        px.byteswap()
    rows = [px[(h - 1 - y) * w * 3:(h - y) * w * 3] for y in range(h)]
    return w, h, [v for r in rows for v in r]


def rel_mse(img, ref):
    return sum((a - r) ** 2 / (r * r + 1e-2) for a, r in zip(img, ref)) / len(ref)


def scene_variant(scene, prefix, integrator=None, sampler=None, box_filter=False):
    """A copy of `scene` beside it (so relative paths hold), named `prefix` +
    its name: with the <integrator> block replaced by the XML `integrator`,
    the <sampler> type by `sampler` and the pixel filter by a box, where
    given. Returns the copy's path (the caller removes it)."""
    text = open(scene).read()
    if integrator:
        text, n = re.subn(r"<integrator.*?</integrator>", lambda _: integrator, text, count=1, flags=re.S)
        if n != 1:
            sys.exit(f"{scene}: no <integrator> block")
    if box_filter:
        text, n = re.subn(r"<rfilter[^>]*/>|<rfilter.*?</rfilter>", '<rfilter type="box"/>', text, flags=re.S)
        if n == 0:
            text = text.replace("</film>", '<rfilter type="box"/></film>', 1)
    if sampler:
        text, n = re.subn(r'<sampler\s+type="[a-z_]+"', f'<sampler type="{sampler}"', text, count=1)
        if n != 1:
            sys.exit(f"{scene}: no <sampler type=...> to replace")
    path = os.path.join(os.path.dirname(scene), prefix + os.path.basename(scene))
    with open(path, "w") as f:
        f.write(text)
    return path


def run_snell(snell, scene, out, spp, seed, threads, defines):
    """Renders `scene` to `out` (`defines`: -D name -> value; `seed` None:
    the scene's own); returns the render's --stats as a dict. Exits with
    Snell's output if it fails."""
    stats = f"{out}.stats.json"
    cmd = [snell, "render", scene, "-o", out, "--spp", str(spp), "--threads", str(threads),
           "--stats", stats, "--quiet"]
    if seed is not None:
        cmd += ["--seed", str(seed)]
    for k, v in defines.items():
        cmd += ["-D", f"{k}={v}"]
    r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        print(r.stdout)
        sys.exit(f"snell failed with exit code {r.returncode}: {' '.join(cmd)}")
    with open(stats) as f:
        st = json.load(f)
    os.remove(stats)
    return st


def scene_with_sampler(scene, sampler, integrator_props=()):
    """A copy of `scene` (beside it, so relative paths hold) naming `sampler`,
    with properties `integrator_props` (KEY=VALUE) added to its integrator (boolean
    for true/false, float for a value with a point, else integer)."""
    text = open(scene).read()
    new, n = re.subn(r'<sampler\s+type="[a-z]+"', f'<sampler type="{sampler}"', text, count=1)
    if n != 1:
        sys.exit(f"{scene}: no <sampler type=...> to replace")
    if integrator_props:
        def prop(k, v):
            kind = "boolean" if v in ("true", "false") else "float" if "." in v else "integer"
            return f'<{kind} name="{k}" value="{v}"/>'
        props = "".join(prop(k, v) for k, _, v in (kv.partition("=") for kv in integrator_props))
        new, n = re.subn(r'(<integrator\s+type="[a-z_]+"\s*>)', lambda m: m.group(1) + props, new, count=1)
        if n != 1:
            sys.exit(f"{scene}: no <integrator type=...> to add {integrator_props} to")
    path = os.path.join(os.path.dirname(scene), f".bench-{sampler}-{os.path.basename(scene)}")
    with open(path, "w") as f:
        f.write(new)
    return path


def snell_images(args, scene, params, sampler, spp, seeds, out, variant="", flags=""):
    """Renders `scene` with Snell's `sampler` once per seed (`variant`: the
    integrator's extra KEY=VALUE,... properties; `flags`: further command-line
    flags); returns (seconds, [pfm paths])."""
    path = scene_with_sampler(scene, sampler, [kv for kv in variant.split(",") if kv])
    secs, files = [], []
    try:
        for seed in seeds:
            pfm = f"{out}-snell-{sampler}-{seed}.pfm"
            cmd = [args.snell, "render", path, "-o", pfm, "--spp", str(spp), "--seed", str(seed),
                   "--threads", str(args.threads), "--stats", "/tmp/stats.json"] + shlex.split(flags)
            for k, v in params.items():
                cmd += ["-D", f"{k}={v}"]
            before = os.times()
            r = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            after = os.times()
            if r.returncode != 0:
                print(r.stdout)
                sys.exit(f"snell failed with exit code {r.returncode}")
            with open("/tmp/stats.json") as f:
                st = json.load(f)
            wall = float(st["render_seconds"])
            process = (after.children_user + after.children_system) - (before.children_user + before.children_system)
            # The render loop's CPU (as Mitsuba's mi.render's below); the
            # whole process's (startup, loading, BVH, writing) beside it.
            secs.append((wall, float(st.get("render_cpu_seconds", process)), process))
            files.append(pfm)
    finally:
        os.remove(path)
    return secs, files


def mitsuba_efficiency_worker(args, params):
    """Runs inside a Python that has mitsuba: renders --sampler at --spp for
    each seed of --seeds, writes <out>-<seed>.pfm; prints the seconds as JSON."""
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(args.threads)
    path = scene_with_sampler(args.scene, args.sampler)
    try:
        scene = mi.load_file(path, **params)
    finally:
        os.remove(path)

    def one(seed):
        # A big sample count in chunks (a wavefront of all samples would not fit in memory).
        chunks = max(1, (args.spp + 1023) // 1024)
        t = time.perf_counter()
        c0 = time.process_time()
        acc = None
        for c in range(chunks):
            spp = args.spp * (c + 1) // chunks - args.spp * c // chunks
            img = mi.render(scene, spp=spp, seed=seed * 65537 + c)
            dr.eval(img)
            dr.sync_thread()
            a = np.array(img, dtype=np.float64)[:, :, :3] * spp
            acc = a if acc is None else acc + a
        return (time.perf_counter() - t, time.process_time() - c0), (acc / args.spp).astype(np.float32)

    one(1000)  # warm-up: kernel compilation, not counted
    secs = []
    for seed in [int(s) for s in args.seeds.split(",")]:
        t, img = one(seed)
        secs.append(t)
        h, w, _ = img.shape
        with open(f"{args.out}-{seed}.pfm", "wb") as f:
            f.write(f"PF\n{w} {h}\n-1.0\n".encode())
            f.write(np.ascontiguousarray(img[::-1], dtype="<f4").tobytes())
    print(json.dumps({"seconds": secs, "mitsuba": mi.__version__}))


def mitsuba_images(args, scene, sampler, spp, seeds, out):
    py = args.mitsuba_python or (VENV_PY if os.path.exists(VENV_PY) else None)
    if py is None:
        try:
            import mitsuba  # noqa: F401
            py = sys.executable
        except ImportError:
            pass
    if py is None or args.no_mitsuba:
        if not args.no_mitsuba:
            print("mitsuba: not importable and no .venv-mitsuba (tools/setup-mitsuba.sh, or --mitsuba-python); skipping")
        return None
    env = dict(os.environ)
    env.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    argv = ["--mitsuba-efficiency-worker", "--scene", scene, "--spp", str(spp), "--res", str(args.res),
            "--max-depth", str(args.max_depth), "--threads", str(args.threads), "--sampler", sampler,
            "--seeds", ",".join(map(str, seeds)), "--out", f"{out}-mitsuba-{sampler}"]
    for kv in args.defines:
        argv += ["-D", kv]
    r = subprocess.run([py, os.path.abspath(__file__)] + argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    if r.returncode != 0:
        print(f"mitsuba {sampler}: worker failed (exit {r.returncode}); skipping")
        return None
    # The JSON result (Mitsuba logs warnings, e.g. a rounded sample count, to
    # stdout, the last one's colour reset on the result's line).
    at = r.stdout.rfind('{"seconds"')
    if at < 0:
        print(f"mitsuba {sampler}: the worker printed no result; skipping\n{r.stdout}")
        return None
    secs = json.loads(r.stdout[at:].strip())["seconds"]
    return secs, [f"{out}-mitsuba-{sampler}-{s}.pfm" for s in seeds]


def efficiency_scene(args, scene):
    params = scene_params(scene, args.res, args.max_depth, args.defines)
    rel = os.path.relpath(scene, ROOT)
    out = os.path.join("/tmp", "snell-eff-" + os.path.splitext(os.path.basename(scene))[0])
    print(f"== {rel}: {args.res}², {args.spp} spp, {args.runs} runs, {params}, {args.threads} threads")
    ref = mitsuba_images(args, scene, "independent", args.ref_spp, [7777], out + "-ref")
    ref_by = f"Mitsuba llvm_ad_rgb independent, {args.ref_spp} spp"
    if ref is None:
        ref = snell_images(args, scene, params, "sobol", args.ref_spp, [7777], out + "-ref")
        ref_by = f"Snell sobol, {args.ref_spp} spp"
    print(f"reference: {ref_by} ({ref[0][0][0]:.1f} s)")
    _, _, ref_px = read_pfm(ref[1][0])
    seeds = list(range(1, args.runs + 1))
    rows = []
    variants = args.snell_integrator or [""]
    flag_sets = args.snell_args or [""]
    jobs = [("snell", s, v, f) for f in flag_sets for v in variants
            for s in ([] if args.no_snell else args.snell_samplers.split(","))]
    jobs += [("mitsuba", s, "", "") for s in MITSUBA_SAMPLERS]
    for who, sampler, variant, flags in jobs:
        got = (snell_images(args, scene, params, sampler, args.spp, seeds, out, variant, flags) if who == "snell"
               else mitsuba_images(args, scene, sampler, args.spp, seeds, out))
        if got is None:
            continue
        secs, files = got
        errs = []
        for fpath in files:
            _, _, px = read_pfm(fpath)
            errs.append(rel_mse(px, ref_px))
            os.remove(fpath)
        e = statistics.mean(errs)
        wall, cpu = statistics.median(s[0] for s in secs), statistics.median(s[1] for s in secs)
        process = statistics.median(s[2] if len(s) > 2 else s[1] for s in secs)
        t = cpu / args.threads if args.cpu_time else wall
        if variant:
            sampler = f"{sampler}+{variant}"
        if flags:
            sampler = f"{sampler} {flags}"
        row = {"renderer": who, "sampler": sampler, "rel_mse": e, "seconds": t, "wall_seconds": wall,
               "cpu_seconds": cpu, "process_cpu_seconds": process, "efficiency": 1.0 / (e * t)}
        rows.append(row)
        outside = f"  (process cpu {process:7.3f} s)" if who == "snell" else ""
        print(f"  {who:<8} {sampler:<34} relMSE {e:.4e}  wall {wall:7.3f} s  cpu {cpu:7.3f} s  "
              f"efficiency {row['efficiency']:10.1f}{outside}")
    os.remove(ref[1][0])
    mits = [r for r in rows if r["renderer"] == "mitsuba"]
    best = max(mits, key=lambda r: r["efficiency"]) if mits else None
    if best:
        for r in rows:
            r["vs_mitsuba_best"] = r["efficiency"] / best["efficiency"]
    return {"scene": rel, "spp": args.spp, "res": args.res, "reference": ref_by, "rows": rows,
            "mitsuba_best": best["sampler"] if best else None}


def efficiency(args, scenes):
    results = [efficiency_scene(args, sc) for sc in scenes]
    print(f"summary: efficiency = 1/(relMSE × {'CPU seconds / threads' if args.cpu_time else 'seconds'}), "
          f"{args.spp} spp, {args.res}², {args.threads} threads; "
          "× = relative to Mitsuba's best sampler on that scene")
    print(f"{'scene':<36} {'renderer':<8} {'sampler':<34} {'relMSE':>10} {'seconds':>8} {'efficiency':>11} {'×':>6}")
    for res in results:
        for r in res["rows"]:
            print(f"{res['scene']:<36} {r['renderer']:<8} {r['sampler']:<34} {r['rel_mse']:10.3e} "
                  f"{r['seconds']:8.3f} {r['efficiency']:11.1f} {r.get('vs_mitsuba_best', float('nan')):6.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


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
    ap.add_argument("--mesh", metavar="SIZES",
                    help="mesh benchmark instead of scenes: triangle counts, e.g. 2k,1M,4M")
    ap.add_argument("--mesh-formats", default="ply,obj", help="mesh files to load: ply, obj or both")
    ap.add_argument("--mesh-res", type=int, default=512)
    ap.add_argument("--mesh-spp", type=int, default=16)
    ap.add_argument("--mitsuba-mesh-worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--simd", choices=["baseline", "avx2", "avx512"],
                    help="limit Snell (SNELL_SIMD) and Mitsuba's Dr.Jit (LLVM target) to this instruction set")
    ap.add_argument("--efficiency", action="store_true",
                    help="error per second per sampler (1/(relMSE × seconds)) instead of samples per second")
    ap.add_argument("--ref-spp", type=int, default=16384, help="samples of the --efficiency reference")
    ap.add_argument("--cpu-time", action="store_true",
                    help="--efficiency: seconds = CPU time / threads instead of wall time (for a loaded machine)")
    ap.add_argument("--mitsuba-python", help="a Python that imports mitsuba, for --mesh and --efficiency (default: .venv-mitsuba)")
    ap.add_argument("--snell-samplers", default=",".join(SNELL_SAMPLERS),
                    help="--efficiency: Snell's samplers to measure (comma-separated)")
    ap.add_argument("--snell-integrator", action="append", default=[], metavar="KEY=VALUE[,...]",
                    help="--efficiency: a variant of Snell's integrator, properties added to it (boolean, float or integer) "
                         "(e.g. bsdf_samples=2; repeatable, each one measured; an empty one is the scene's own)")
    ap.add_argument("--snell-args", action="append", default=[], metavar="FLAGS",
                    help="--efficiency: a variant with these flags added to Snell's command line "
                         "(e.g. \"--noise-threshold 0.05\"; repeatable, each one measured; an empty one adds none)")
    ap.add_argument("--mitsuba-efficiency-worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--sampler", help=argparse.SUPPRESS)
    ap.add_argument("--seeds", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    ap.add_argument("--write-mesh-worker", nargs=2, metavar=("PATH", "TRIANGLES"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.write_mesh_worker:
        write_mesh_here(args.write_mesh_worker[0], int(args.write_mesh_worker[1]))
        return
    if args.mitsuba_mesh_worker:
        mitsuba_mesh_worker(args)
        return
    if args.mesh:
        rows = bench_mesh(args)
        if args.json:
            with open(args.json, "w") as f:
                json.dump(rows, f, indent=2)
        return
    if args.efficiency or args.mitsuba_efficiency_worker:
        # Error per second needs fewer pixels and samples than throughput.
        if "--res" not in sys.argv:
            args.res = 128
        if "--spp" not in sys.argv:
            args.spp = 64
    scenes = [os.path.join(ROOT, sc) if not os.path.isabs(sc) else sc
              for sc in (args.scene or DEFAULT_SCENES)]
    missing = [sc for sc in scenes if not os.path.isfile(sc)]
    if missing:
        sys.exit("error: no such scene: " + ", ".join(missing))

    if args.mitsuba_worker:
        args.scene = scenes[0]
        mitsuba_worker(args, scene_params(args.scene, args.res, args.max_depth, args.defines))
        return
    if args.mitsuba_efficiency_worker:
        args.scene = scenes[0]
        mitsuba_efficiency_worker(args, scene_params(args.scene, args.res, args.max_depth, args.defines))
        return
    if args.efficiency:
        efficiency(args, scenes)
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

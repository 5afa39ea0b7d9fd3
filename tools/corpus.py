#!/usr/bin/env python3
"""Renders Mitsuba's own scene collection with Snell and, when Mitsuba is
installed, with Mitsuba, and prints a table: does each scene load and render
in Snell, the first error, the mean ratio Snell/Mitsuba per channel, a block
z-test and both render times; then totals.

The corpus is ../shared/corpus/mitsuba-data next to the repository (a copy of
mitsuba-renderer/mitsuba-data: see its README); without it the script says so
and exits 0. Scenes: every *.xml under docs/scenes, tests/scenes and scenes/
(files in include/, includes/ or fragments/ folders are pieces included by
other scenes and are skipped). Scenes that Mitsuba itself cannot load are
listed separately and not counted.

Each scene is rendered at a low resolution (the film --width pixels wide, its
height scaled to keep the aspect ratio, any crop window reset) and --spp
samples per pixel, split into --passes passes with seeds 0, 1, ... on both
sides: Snell by `snell render SCENE --width W --spp N/passes --seed i
--threads T` (its PFM output), Mitsuba (llvm_ad_rgb, else scalar_rgb) by
loading the file, setting the film's size through mi.traverse, limiting
Dr.Jit to T threads and calling mi.render(scene, spp=N/passes, seed=i). A
scene that declares or uses the parameters `spp` and `res` (itself or in a
file it includes) gets them as N/passes and W (-D on Snell's command line).

Comparison (main image R, G, B; Y for a luminance film): mean ratio
Snell/Mitsuba per channel, and per 8x8-pixel block and channel
z = (mean_snell - mean_mitsuba) / sqrt(var_s/k + var_m/k), the variances
from the spread of each side's k passes; the table shows the mean of z^2
(about 1 + 2/(k-3) when both agree: Student t with k-1 dof) and the fraction
of blocks with |z| > 4. Seconds are the renders' own time, summed over the
passes (Snell: its stats' render_seconds; Mitsuba: the median mi.render
pass times the number of passes, so that Dr.Jit's compilation in the first
pass is left out), both with T threads in the same run.

Every render runs in its own process with a per-scene timeout (--timeout,
default 60 s per renderer), so a crash or a hang is one failed row.

Usage:
  python3 tools/corpus.py [--width 64] [--spp 16] [--passes 4] [--threads 2]
      [--timeout 60] [--mitsuba-python .venv-mitsuba/bin/python] [--no-mitsuba]
      [--filter SUBSTRING] [--json out.json] [--snell target/release/snell]
      [--corpus ../shared/corpus]
"""
import argparse
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CORPUS = os.path.join(os.path.dirname(ROOT), "shared", "corpus")
DATA = os.path.join(CORPUS, "mitsuba-data")
FOLDERS = ["docs/scenes", "tests/scenes", "scenes"]
PIECES = {"include", "includes", "fragments"}
LLVM_LIB = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"


def scene_text(path, depth=0):
    """The scene's text and that of the files it includes, comments removed."""
    try:
        text = re.sub(r"<!--.*?-->", "", open(path, errors="replace").read(), flags=re.S)
    except OSError:
        return ""
    if depth < 8:
        for inc in re.findall(r'<include\s+filename="([^"$]+)"', text):
            text += scene_text(os.path.join(os.path.dirname(path), inc), depth + 1)
    return text


def scene_params(path, values):
    """Of `values` (name -> value), those the scene declares with <default>
    or uses as $name (Mitsuba refuses parameters a scene does not use)."""
    text = scene_text(path)
    used = set(re.findall(r'<default\s+name="([^"]+)"', text)) | set(re.findall(r"\$(\w+)", text))
    return {k: str(v) for k, v in values.items() if k in used}


def mitsuba_error(e, scene):
    msg = str(e) or repr(e)
    msg = msg.replace(os.path.dirname(scene) + os.sep, "")
    msg = re.sub(r"\[[\w.]+:\d+\]\s*", "", msg)
    return short(msg, 200)


def find_scenes(name_filter):
    scenes, pieces = [], 0
    for folder in FOLDERS:
        for path in sorted(glob.glob(os.path.join(DATA, folder, "**", "*.xml"), recursive=True)):
            rel = os.path.relpath(path, DATA)
            if PIECES & set(rel.split(os.sep)[:-1]):
                pieces += 1
                continue
            if name_filter and name_filter not in rel:
                continue
            scenes.append(path)
    return scenes, pieces


def short(msg, n=90):
    msg = " ".join(msg.split())
    return msg if len(msg) <= n else msg[: n - 1] + "…"


# ---------------------------------------------------------------- workers
# Run as `python corpus.py --worker mitsuba|compare ...` by the Mitsuba
# interpreter (they need numpy, and mitsuba for the first).

def worker_mitsuba(a):
    out = {"loads": False, "renders": False, "error": "", "seconds": 0.0}
    try:
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
        import numpy as np
        import mitsuba as mi
        variant = None
        for v in ["llvm_ad_rgb", "scalar_rgb"]:
            try:
                mi.set_variant(v)
                mi.load_dict({"type": "diffuse"})
                variant = v
                break
            except Exception:  # noqa: BLE001
                continue
        if variant is None:
            out["error"] = "no usable Mitsuba variant"
            print(json.dumps(out))
            return
        out["variant"] = variant
        try:
            import drjit as dr
            dr.set_thread_count(a.threads)
        except Exception:  # noqa: BLE001
            pass
        params = scene_params(a.scene, {"spp": a.pass_spp, "res": a.width})
        try:
            scene = mi.load_file(a.scene, **params)
        except Exception as e:  # noqa: BLE001
            out["error"] = mitsuba_error(e, a.scene)
            print(json.dumps(out))
            return
        out["loads"] = True
        sensor = scene.sensors()[0]
        w0, h0 = sensor.film().size()
        w = a.width
        h = max(1, int(round(h0 * w / w0)))
        p = mi.traverse(scene)
        for key in list(p.keys()):
            if key.endswith("film.size") or key.endswith("film.crop_size"):
                p[key] = mi.ScalarVector2u(w, h)
            elif key.endswith("film.crop_offset"):
                p[key] = mi.ScalarPoint2u(0, 0)
        # Mitsuba keeps the sensor's x_fov when the film is resized through
        # its parameters; loading the XML with that film (what Snell's
        # --width does) derives it from the fov and fov_axis at the new
        # aspect ratio. Where the rounded height changes the aspect, do the
        # same here, or sharp edges shift by a fraction of a pixel.
        axis = fov_axis(a.scene) or "x"
        a0, a1 = w0 / h0, w / h
        for key in list(p.keys()):
            if key.endswith("x_fov") and abs(a1 / a0 - 1) > 1e-6:
                import math
                t0 = math.tan(math.radians(float(p[key][0] if hasattr(p[key], '__getitem__') else p[key])) / 2)
                if axis == "smaller":
                    axis = "y" if a0 > 1 else "x"
                elif axis == "larger":
                    axis = "x" if a0 > 1 else "y"
                if axis == "y":
                    t1 = t0 * a1 / a0
                elif axis == "diagonal":
                    t1 = t0 * math.sqrt(1 + 1 / a0 ** 2) / math.sqrt(1 + 1 / a1 ** 2)
                else:
                    t1 = t0
                p[key] = math.degrees(2 * math.atan(t1))
        p.update()
        out["size"] = [w, h]
        passes, times = [], []
        for i in range(a.passes):
            t0 = time.time()
            img = mi.render(scene, spp=a.pass_spp, seed=i)
            arr = np.array(img, dtype=np.float64)
            times.append(time.time() - t0)
            film = scene.sensors()[0].film()
            names = [f.name for f in film.bitmap().struct_()] if arr.shape[2] != 3 else ["R", "G", "B"]
            if arr.shape[2] != len(names):
                arr = np.array(film.bitmap(), dtype=np.float64)
            pick = [names.index(c) for c in ("R", "G", "B") if c in names]
            if not pick:
                pick = [names.index("Y")] if "Y" in names else [0]
            passes.append(arr[:, :, pick])
        np.save(a.out, np.stack(passes))
        out["renders"] = True
        # The median pass times the passes: leaves out Dr.Jit's compilation
        # in the first pass.
        out["seconds"] = sorted(times)[len(times) // 2] * len(times)
        out["first_pass_seconds"] = times[0]
    except Exception as e:  # noqa: BLE001
        out["error"] = mitsuba_error(e, a.scene)
    print(json.dumps(out))


def fov_axis(scene, seen=None):
    """The sensor's fov_axis as the XML (or a file it includes) writes it:
    x, y, diagonal, smaller or larger; "diagonal" for a focal_length without
    a fov; "x" (Mitsuba's default) if neither is found."""
    seen = seen if seen is not None else set()
    if scene in seen or not os.path.isfile(scene):
        return None
    seen.add(scene)
    text = open(scene, encoding="utf-8", errors="replace").read()
    m = re.search(r'name\s*=\s*"fov_axis"\s+value\s*=\s*"(\w+)"', text)
    if m:
        return m.group(1)
    if 'name="focal_length"' in text and 'name="fov"' not in text:
        return "diagonal"
    for inc in re.findall(r'<include\s+filename\s*=\s*"([^"]+)"', text):
        found = fov_axis(os.path.join(os.path.dirname(scene), inc), seen)
        if found:
            return found
    return None


def read_pfm(path):
    import numpy as np
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        c = 3 if kind == b"PF" else 1
        data = np.frombuffer(f.read(w * h * c * 4), dtype="<f4" if scale < 0 else ">f4")
    return data.reshape(h, w, c)[::-1].astype(np.float64)


def worker_compare(a):
    import numpy as np
    m = np.load(a.mitsuba)
    s = np.stack([read_pfm(p) for p in a.snell])
    out = {}
    if s.shape[1:3] != m.shape[1:3]:
        out["error"] = "sizes differ: Snell %dx%d, Mitsuba %dx%d" % (s.shape[2], s.shape[1], m.shape[2], m.shape[1])
        print(json.dumps(out))
        return
    c = min(s.shape[3], m.shape[3])
    s, m = s[..., :c], m[..., :c]
    ms, mm = s.mean(axis=(0, 1, 2)), m.mean(axis=(0, 1, 2))
    out["ratio"] = [float(x / y) if y > 0 else (1.0 if x == 0 else float("inf")) for x, y in zip(ms, mm)]
    b = 8
    k_s, k_m = s.shape[0], m.shape[0]
    h, w = (s.shape[1] // b) * b, (s.shape[2] // b) * b
    if h == 0 or w == 0:
        b, h, w = 1, s.shape[1], s.shape[2]
    bs = s[:, :h, :w].reshape(k_s, h // b, b, w // b, b, c).mean(axis=(2, 4))
    bm = m[:, :h, :w].reshape(k_m, h // b, b, w // b, b, c).mean(axis=(2, 4))
    se2 = bs.var(axis=0, ddof=1) / k_s + bm.var(axis=0, ddof=1) / k_m
    diff = bs.mean(axis=0) - bm.mean(axis=0)
    noisy = se2 > 1e-12
    z = np.where(noisy, diff / np.sqrt(np.where(noisy, se2, 1.0)), 0.0)
    exact_bad = (~noisy) & (np.abs(diff) > 1e-4 * (1 + np.abs(bm.mean(axis=0))))
    n = int(noisy.sum())
    out["blocks"] = n
    out["mean_z2"] = float((z[noisy] ** 2).mean()) if n else 0.0
    out["frac_z4"] = float(((np.abs(z) > 4) & noisy).sum() + exact_bad.sum()) / max(1, n + int((~noisy).sum()))
    print(json.dumps(out))


# ---------------------------------------------------------------- driver

def run_snell(args, scene, tmp):
    """k passes; returns dict with loads, renders, error, seconds, pfms, size."""
    res = {"loads": False, "renders": False, "error": "", "seconds": 0.0, "pfms": []}
    params = scene_params(scene, {"spp": args.pass_spp, "res": args.width})
    deadline = time.time() + args.timeout
    for i in range(args.passes):
        pfm = os.path.join(tmp, "snell_%d.pfm" % i)
        stats = os.path.join(tmp, "stats_%d.json" % i)
        cmd = [args.snell, "render", scene, "-o", pfm, "--spp", str(args.pass_spp), "--seed", str(i),
               "--threads", str(args.threads), "--width", str(args.width), "--stats", stats, "--quiet"]
        for k, v in params.items():
            cmd += ["-D", "%s=%s" % (k, v)]
        left = deadline - time.time()
        if left <= 0:
            res["error"] = "timeout (%g s)" % args.timeout
            return res
        try:
            r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=left,
                               errors="replace")
        except subprocess.TimeoutExpired:
            res["loads"] = res["loads"] or None  # unknown if the first pass never finished
            res["error"] = "timeout (%g s)" % args.timeout
            return res
        if r.returncode != 0:
            err = r.stderr.strip()
            first = next((ln for ln in err.splitlines() if ln.startswith("error")), err.splitlines()[0] if err else "")
            if "panicked" in err:
                first = "panic: " + next((ln for ln in err.splitlines() if "panicked" in ln), "")
                res["loads"] = None
            elif r.returncode < 0:
                first = "killed by signal %d" % -r.returncode
                res["loads"] = None
            res["error"] = short(first.replace("error: ", "", 1))
            return res
        res["loads"] = True
        try:
            st = json.load(open(stats))
            res["seconds"] += st.get("render_seconds", 0.0)
            res["size"] = [st.get("width"), st.get("height")]
        except (OSError, ValueError):
            pass
        res["pfms"].append(pfm)
    res["renders"] = True
    return res


def run_worker(args, argv, timeout):
    env = dict(os.environ)
    env.setdefault("DRJIT_LIBLLVM_PATH", LLVM_LIB)
    try:
        r = subprocess.run([args.mitsuba_python, os.path.abspath(__file__)] + argv, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, timeout=timeout, env=env, errors="replace")
    except subprocess.TimeoutExpired:
        return {"error": "timeout (%g s)" % timeout}
    line = (r.stdout.strip().splitlines() or [""])[-1]
    try:
        return json.loads(line)
    except ValueError:
        tail = (r.stderr.strip().splitlines() or ["crashed (exit %d)" % r.returncode])[-1]
        return {"error": short(tail, 200)}


def fmt_ratio(r):
    return " ".join("%.3f" % x for x in r) if r else ""


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worker", choices=["mitsuba", "compare"], help=argparse.SUPPRESS)
    ap.add_argument("--scene", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    ap.add_argument("--mitsuba", help=argparse.SUPPRESS)
    ap.add_argument("--snell-pfm", dest="snell_pfms", action="append", help=argparse.SUPPRESS)
    ap.add_argument("--pass-spp", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--passes", type=int, default=4)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--mitsuba-python", default=os.path.join(ROOT, ".venv-mitsuba", "bin", "python"))
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--filter", default="")
    ap.add_argument("--json")
    ap.add_argument("--snell", default=os.path.join(ROOT, "target", "release", "snell"))
    ap.add_argument("--corpus", default=CORPUS, help="the corpus folder (default ../shared/corpus)")
    args = ap.parse_args()
    global DATA
    DATA = os.path.join(os.path.abspath(args.corpus), "mitsuba-data")

    if args.worker == "mitsuba":
        return worker_mitsuba(args)
    if args.worker == "compare":
        args.snell = args.snell_pfms
        return worker_compare(args)

    if not os.path.isdir(DATA):
        print("corpus.py: %s not found; nothing to do (the corpus is optional)." % DATA)
        return 0
    if not os.path.exists(args.snell):
        sys.exit("corpus.py: %s not found: run `cargo build --release` first" % args.snell)
    args.passes = max(2, args.passes)
    args.pass_spp = max(1, args.spp // args.passes)
    use_mitsuba = not args.no_mitsuba and os.path.exists(args.mitsuba_python)
    scenes, pieces = find_scenes(args.filter)
    print("%d scenes (%d included pieces skipped); %dpx wide, %d spp as %d passes, %d threads, timeout %g s; Mitsuba: %s"
          % (len(scenes), pieces, args.width, args.pass_spp * args.passes, args.passes, args.threads, args.timeout,
             args.mitsuba_python if use_mitsuba else "not used"), flush=True)

    rows, mitsuba_fails = [], []
    for scene in scenes:
        rel = os.path.relpath(scene, DATA)
        tmp = tempfile.mkdtemp(prefix="snell-corpus-")
        try:
            row = {"scene": rel}
            if use_mitsuba:
                mres = run_worker(args, ["--worker", "mitsuba", "--scene", scene, "--out", os.path.join(tmp, "m.npy"),
                                         "--width", str(args.width), "--pass-spp", str(args.pass_spp),
                                         "--passes", str(args.passes), "--threads", str(args.threads)],
                                  args.timeout + 30)
                row["mitsuba"] = mres
                if not mres.get("loads"):
                    mitsuba_fails.append((rel, mres.get("error", "")))
                    print("  %-60s Mitsuba cannot load: %s" % (rel, short(mres.get("error", ""), 70)), flush=True)
                    continue
            sres = run_snell(args, scene, tmp)
            row["snell"] = {k: v for k, v in sres.items() if k != "pfms"}
            if use_mitsuba and sres["renders"] and row["mitsuba"].get("renders"):
                argv = ["--worker", "compare", "--mitsuba", os.path.join(tmp, "m.npy")]
                for p in sres["pfms"]:
                    argv += ["--snell-pfm", p]
                row["compare"] = run_worker(args, argv, 120)
            rows.append(row)
            print_row(row, flush=True)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    print_table(rows, mitsuba_fails, use_mitsuba)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rows": rows, "mitsuba_cannot_load": mitsuba_fails,
                       "settings": {"width": args.width, "spp": args.pass_spp * args.passes,
                                    "passes": args.passes, "threads": args.threads}}, f, indent=1)
    return 0


def yn(v):
    return "yes" if v else ("?" if v is None else "no")


def print_row(row, flush=False):
    s, c, m = row.get("snell", {}), row.get("compare", {}), row.get("mitsuba", {})
    print("  %-60s loads %-3s renders %-3s %s%s" % (
        row["scene"], yn(s.get("loads")), yn(s.get("renders")),
        ("ratio %s z2 %.2f |z|>4 %.0f%% " % (fmt_ratio(c.get("ratio")), c.get("mean_z2", 0), 100 * c.get("frac_z4", 0))
         if c.get("ratio") else ""),
        short(s.get("error", "") or c.get("error", "") or ("" if not m or m.get("renders") else "Mitsuba: " + m.get("error", "")), 80)),
        flush=flush)


def print_table(rows, mitsuba_fails, use_mitsuba):
    print()
    print("| scene | loads | renders | first error | mean ratio (R G B) | mean z² | blocks \\|z\\|>4 | Snell s | Mitsuba s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        s, c, m = row.get("snell", {}), row.get("compare", {}), row.get("mitsuba", {})
        print("| %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            row["scene"], yn(s.get("loads")), yn(s.get("renders")), short(s.get("error", ""), 60).replace("|", "\\|"),
            fmt_ratio(c.get("ratio")), "%.2f" % c["mean_z2"] if "mean_z2" in c else "",
            "%.0f%%" % (100 * c["frac_z4"]) if "frac_z4" in c else "",
            "%.2f" % s["seconds"] if s.get("renders") else "",
            "%.2f" % m["seconds"] if m.get("renders") else ""))
    n = len(rows)
    loads = sum(1 for r in rows if r["snell"].get("loads"))
    renders = sum(1 for r in rows if r["snell"].get("renders"))
    compared = [r for r in rows if r.get("compare", {}).get("ratio")]
    agree = [r for r in compared if all(abs(x - 1) < 0.05 for x in r["compare"]["ratio"]) and r["compare"]["frac_z4"] < 0.05]
    ts = sum(r["snell"]["seconds"] for r in compared)
    tm = sum(r["mitsuba"]["seconds"] for r in compared)
    print()
    if mitsuba_fails:
        print("Mitsuba cannot load %d scenes (not counted):" % len(mitsuba_fails))
        for rel, err in mitsuba_fails:
            print("  %s: %s" % (rel, short(err, 100)))
    errors = {}
    for r in rows:
        e = r["snell"].get("error", "")
        if e:
            key = re.sub(r'"[^"]*"', '"…"', e.split(" --> ")[0])[:70]
            errors[key] = errors.get(key, 0) + 1
    if errors:
        print("Snell's first errors, by how many scenes each blocks:")
        for e, k in sorted(errors.items(), key=lambda x: -x[1])[:25]:
            print("  %3d  %s" % (k, e))
    print()
    print("Totals: %d scenes%s; Snell loads %d, renders %d%s" % (
        n, " that Mitsuba loads" if use_mitsuba else "", loads, renders,
        ("; compared with Mitsuba %d, agree %d (every channel's mean within 5%%, < 5%% of blocks |z| > 4); "
         "render seconds on those: Snell %.1f, Mitsuba %.1f" % (len(compared), len(agree), ts, tm)) if use_mitsuba else ""))


if __name__ == "__main__":
    sys.exit(main())

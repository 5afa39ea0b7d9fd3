"""Python's overhead against the command line: the same scene at the same
spp, rendered by `snell render` (the Rust binary, target/release/snell) and
by snell.render, alternating, best of N each.

    python tools/python_overhead.py [SCENE] [SPP] [RUNS] [-D NAME=VALUE ...]

Compares (a) render time: the binary's --stats render_seconds against the
wall time of snell.render (which includes the GIL hand-off, the copy to
numpy and the worker thread), and (b) the whole job: the binary's process
wall time (load + render + EXR write) against load_file + render + write in
Python (interpreter start-up excluded), and (c) the CPU time of the whole
job, steadier than wall time on a shared machine. THREADS=n in the
environment sets the worker threads of both (default: all cores)."""

import json
import resource
import os
import subprocess
import sys
import tempfile
import time

import snell

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    args = sys.argv[1:]
    defines = []
    while "-D" in args:
        i = args.index("-D")
        defines.append(args[i + 1])
        del args[i : i + 2]
    scene = args[0] if len(args) > 0 else os.path.join(ROOT, "scenes", "cornell-box.xml")
    spp = int(args[1]) if len(args) > 1 else 64
    runs = int(args[2]) if len(args) > 2 else 5
    params = dict(d.split("=", 1) for d in defines)
    binary = os.path.join(ROOT, "target", "release", "snell")
    tmp = tempfile.mkdtemp()
    cli_render, cli_total, py_render, py_total, cli_cpu, py_cpu = [], [], [], [], [], []
    threads = os.environ.get("THREADS", "0")
    for _ in range(runs):
        stats = os.path.join(tmp, "stats.json")
        cmd = [binary, "render", scene, "--spp", str(spp), "--seed", "0", "-q", "-o", os.path.join(tmp, "cli.exr"), "--stats", stats]
        for d in defines:
            cmd += ["-D", d]
        cmd += ["--threads", threads]
        c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True)
        cli_total.append(time.perf_counter() - t0)
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cli_cpu.append(c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime)
        cli_render.append(json.load(open(stats))["render_seconds"])

        c0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        s = snell.load_file(scene, **params)
        t1 = time.perf_counter()
        img = snell.render(s, spp=spp, seed=0, threads=int(threads))
        t2 = time.perf_counter()
        snell.write(img, os.path.join(tmp, "py.exr"))
        t3 = time.perf_counter()
        c1 = resource.getrusage(resource.RUSAGE_SELF)
        py_cpu.append(c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime)
        py_render.append(t2 - t1)
        py_total.append(t3 - t0)
    same = (snell.read(os.path.join(tmp, "cli.exr")) == snell.read(os.path.join(tmp, "py.exr"))).all()
    r_cli, r_py = min(cli_render), min(py_render)
    t_cli, t_py = min(cli_total), min(py_total)
    print(f"scene {os.path.basename(scene)} {params} spp {spp}, best of {runs}; images identical: {bool(same)}")
    print(f"render: CLI {r_cli:.3f} s, Python {r_py:.3f} s: overhead {100 * (r_py / r_cli - 1):+.2f} %")
    print(f"CPU time of the whole job: CLI {min(cli_cpu):.3f} s, Python {min(py_cpu):.3f} s: {100 * (min(py_cpu) / min(cli_cpu) - 1):+.2f} %")
    print(f"whole job: CLI process {t_cli:.3f} s, Python load+render+write {t_py:.3f} s: {100 * (t_py / t_cli - 1):+.2f} %")


if __name__ == "__main__":
    main()

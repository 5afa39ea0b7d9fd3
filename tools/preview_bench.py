"""Render speed with the live preview open in browser tabs, against none.

Runs the same `snell render … --preview 0` several times, alternating: no
page open, then TABS headless-Chromium tabs watching it (opened as soon as
the URL is printed, polling all along). Reports each run's render_seconds
(from --stats) and the process's CPU seconds, and the medians.

Usage (the venv of .ci/preview-test):
  target/preview-venv/bin/python tools/preview_bench.py [--width 128] [--spp 1024] [--pairs 3] [--tabs 2]
"""
import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import tempfile
import time

from playwright.sync_api import sync_playwright

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def run(browser, args, tabs, work):
    stats = os.path.join(work, "stats.json")
    cmd = [os.path.join(ROOT, "target", "release", "snell"), "render", os.path.join(ROOT, "scenes", "cornell-box.xml"),
           "--width", str(args.width), "--spp", str(args.spp), "--threads", str(args.threads),
           "--preview", "0", "--stats", stats, "-o", os.path.join(work, "out.exr"), "-q"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    url = None
    for line in proc.stderr:
        m = re.match(r"preview: (\S+)", line)
        if m:
            url = m.group(1)
            break
    pages = []
    for _ in range(tabs):
        p = browser.new_page()
        p.goto(url)
        pages.append(p)
    # Keep the tabs' event loops running while the render goes on.
    while proc.poll() is None:
        if pages:
            pages[0].wait_for_timeout(200)
        else:
            time.sleep(0.2)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)  # snell reaped by poll()
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    shown = [p.evaluate("() => Number(document.getElementById('image').dataset.pass)") for p in pages]
    for p in pages:
        p.close()
    with open(stats) as f:
        s = json.load(f)
    return s["render_seconds"], cpu, shown


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--width", type=int, default=128)
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--tabs", type=int, default=2)
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="snell-preview-bench-")
    times = {0: [], args.tabs: []}
    cpus = {0: [], args.tabs: []}
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=FLAGS, chromium_sandbox=False)
        for i in range(args.pairs):
            for tabs in ((0, args.tabs) if i % 2 == 0 else (args.tabs, 0)):
                t, cpu, shown = run(browser, args, tabs, work)
                times[tabs].append(t)
                cpus[tabs].append(cpu)
                print("run %d: %d tabs: render %.3f s, snell CPU %.3f s%s" % (i, tabs, t, cpu, ("; tabs showed pass %s" % shown) if shown else ""), flush=True)
        browser.close()
    a, b = statistics.median(times[0]), statistics.median(times[args.tabs])
    print("median render seconds: no page %.3f, %d tabs %.3f: %+.2f %%" % (a, args.tabs, b, 100 * (b - a) / a))
    a, b = statistics.median(cpus[0]), statistics.median(cpus[args.tabs])
    print("median snell CPU seconds: no page %.3f, %d tabs %.3f: %+.2f %%" % (a, args.tabs, b, 100 * (b - a) / a))


if __name__ == "__main__":
    main()

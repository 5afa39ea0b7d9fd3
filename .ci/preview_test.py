"""Browser test of `snell render --preview` in headless Chromium (Playwright).

Run by .ci/preview-test, which installs Chromium and a venv with Playwright,
numpy and OpenEXR. Usage: preview_test.py SNELL WORKDIR [SCREENSHOT.png]

1. An RGB render with --preview 0 (a free port) and --preview-dump-passes:
   two tabs open the page; after two passes, the canvas pixels (exposure 0,
   sRGB) must equal the pass's EXR encoded as 8-bit sRGB (±1); the progress
   figures must advance; a screenshot is saved; Stop must end the render
   early, as Ctrl-C does, with the outputs written.
2. A polarized render: the AoLP/DoLP view must match the same view computed
   from the pass's EXR (±1), and that computation must match the
   --stokes-view PNG Snell writes from its final image.
"""
import json
import os
import re
import subprocess
import sys
import threading
import time

import numpy as np
import OpenEXR
from playwright.sync_api import sync_playwright

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CHROMIUM_FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]


def fail(msg):
    print("preview-test: FAIL: " + msg, file=sys.stderr)
    sys.exit(1)


def read_exr(path, prefix=""):
    """HxWx3 float32 of channels PREFIX R, G, B."""
    with OpenEXR.File(path, separate_channels=True) as f:
        ch = f.channels()
        return np.stack([np.asarray(ch[prefix + c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)


def srgb8(v):
    v = np.clip(v.astype(np.float64), 0.0, 1.0)
    e = np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)
    return np.floor(e * 255 + 0.5).astype(np.int32)


def lum(c):
    return 0.2126 * c[..., 0] + 0.7152 * c[..., 1] + 0.0722 * c[..., 2]


def stokes_view8(s0, s1, s2):
    """The AoLP/DoLP colours of src/film/stokes.rs, as 8-bit sRGB."""
    l0, l1, l2 = lum(s0).astype(np.float64), lum(s1).astype(np.float64), lum(s2).astype(np.float64)
    dark = ~(l0 > 1e-4)
    with np.errstate(divide="ignore", invalid="ignore"):
        dolp = np.clip(np.sqrt(l1 * l1 + l2 * l2) / l0, 0, 1)
    aolp = np.mod(0.5 * np.degrees(np.arctan2(l2, l1)), 180.0)
    dolp[dark | ~np.isfinite(dolp)] = 0
    aolp[dark] = 0
    h6 = np.mod(2 * aolp / 60.0, 6.0)
    x = 1 - np.abs(np.mod(h6, 2.0) - 1)
    sector = np.minimum(h6.astype(np.int32), 5)
    one, zero = np.ones_like(x), np.zeros_like(x)
    table = [(one, x, zero), (x, one, zero), (zero, one, x), (zero, x, one), (x, zero, one), (one, zero, x)]
    rgb = np.zeros(aolp.shape + (3,))
    for k, (r, g, b) in enumerate(table):
        m = sector == k
        rgb[m] = np.stack([r[m], g[m], b[m]], axis=-1)
    return np.floor(rgb * dolp[..., None] * 255 + 0.5).astype(np.int32)


class Render:
    """A `snell render … --preview 0` process; reads the URL it prints."""

    def __init__(self, snell, args, cwd):
        self.proc = subprocess.Popen([snell, "render", *args, "--preview", "0"], cwd=cwd,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.lines = []
        self.url = None
        got = threading.Event()

        def pump():
            for line in self.proc.stderr:
                self.lines.append(line.rstrip("\n"))
                m = re.match(r"preview: (http://\S+)", line)
                if m:
                    self.url = m.group(1)
                    got.set()
            got.set()

        threading.Thread(target=pump, daemon=True).start()
        if not got.wait(120) or self.url is None:
            self.proc.kill()
            fail("snell printed no preview URL:\n" + "\n".join(self.lines))
        print("preview-test: serving at " + self.url)

    def wait(self, timeout):
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            fail("the render did not end within %d s after Stop" % timeout)

    def stderr(self):
        return "\n".join(self.lines)


def check_stopped(render, stats_path, spp_total, label):
    """Stop sets the flag Ctrl-C sets: the render ends early and writes its
    outputs; exit 130 with the 'interrupted' summary if it stopped inside a
    pass, 0 if it stopped at the end of one (a whole pass, fewer spp)."""
    code = render.wait(300)
    with open(stats_path) as f:
        stats = json.load(f)
    if code == 130:
        # "… the partial image" (stopped inside the first pass) or "… the last complete pass".
        if "interrupted: wrote the" not in render.stderr() or not stats["interrupted"]:
            fail("%s: exit 130 without the 'interrupted' summary:\n%s" % (label, render.stderr()))
    elif code == 0:
        if stats["interrupted"]:
            fail("%s: exit 0 but the stats say interrupted" % label)
    else:
        fail("%s: after Stop snell exited with %s:\n%s" % (label, code, render.stderr()))
    done = stats.get("spp_done", stats["spp"])  # samples per pixel in the written image
    if not done < spp_total:
        fail("%s: Stop did not end the render early (%s of %s spp)" % (label, done, spp_total))
    print("preview-test: %s: Stop ended the render at %s of %s spp, exit %d" % (label, done, spp_total, code))


def canvas_state(page):
    """(pass, HxWx3 int array) read in one go, so both belong to the same frame."""
    data = page.evaluate("""() => {
        const c = document.getElementById('image');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        return {pass: Number(c.dataset.pass), view: c.dataset.view, w: c.width, h: c.height, px: Array.from(d)};
    }""")
    px = np.array(data["px"], dtype=np.int32).reshape(data["h"], data["w"], 4)
    if not (px[..., 3] == 255).all():
        fail("the canvas is not opaque")
    return data["pass"], data["view"], px[..., :3]


def figures(page):
    text = lambda i: page.inner_text("#" + i)
    return {k: text(k) for k in ["pass", "spp", "rate", "elapsed", "eta", "state"]}


def set_exposure(page, ev):
    page.evaluate("""ev => { const e = document.getElementById('exposure');
        e.value = String(ev); e.dispatchEvent(new Event('input')); }""", ev)


def seconds(text):
    """'3.2 s' or '1 min 4 s' as seconds."""
    m = re.fullmatch(r"(?:(\d+) h )?(?:(\d+) min ?)?(?:([\d.]+) s)?", text.strip())
    if not m or not any(m.groups()):
        fail("cannot read the time %r" % text)
    h, mi, s = m.groups()
    return 3600 * int(h or 0) + 60 * int(mi or 0) + float(s or 0)


def wait_pass(page, at_least, timeout=120):
    page.wait_for_function("n => Number(document.getElementById('image').dataset.pass) >= n", arg=at_least,
                           timeout=timeout * 1000)


def compare(label, shown, expected):
    if shown.shape != expected.shape:
        fail("%s: canvas %s, expected %s" % (label, shown.shape, expected.shape))
    diff = np.abs(shown - expected)
    print("preview-test: %s: %d pixels, largest 8-bit difference %d, %d values differ" % (
        label, shown.shape[0] * shown.shape[1], diff.max(), (diff > 0).sum()))
    if diff.max() > 1:
        y, x, c = np.unravel_index(np.argmax(diff), diff.shape)
        fail("%s: pixel (%d, %d) channel %d shows %d, the EXR encodes to %d" % (label, x, y, c, shown[y, x, c], expected[y, x, c]))


def rgb_phase(browser, snell, work, screenshot):
    dump = os.path.join(work, "passes")
    out_exr, out_png = os.path.join(work, "out.exr"), os.path.join(work, "out.png")
    for f in (out_exr, out_png):
        if os.path.exists(f):
            os.remove(f)
    scene = os.path.join(ROOT, "scenes", "cornell-box.xml")
    stats = os.path.join(work, "stats.json")
    render = Render(snell, [scene, "--width", "160", "--spp", "16384", "--preview-dump-passes", dump,
                            "-o", out_exr, "-o", out_png, "--stats", stats, "--quiet"], work)
    page = browser.new_page(viewport={"width": 900, "height": 700})
    page.goto(render.url)
    other = browser.new_page()  # a second tab watching the same render
    other.goto(render.url)

    wait_pass(page, 2)
    first = figures(page)
    n, view, shown = canvas_state(page)
    if view != "S0":
        fail("the default view is %r" % view)
    expected = srgb8(read_exr(os.path.join(dump, "pass-%03d.exr" % n)))
    compare("pass %d (sRGB, exposure 0)" % n, shown, expected)

    # The other tab shows passes too.
    wait_pass(other, 2)

    # Progress advances: a later pass, more spp, more elapsed time.
    wait_pass(page, n + 1)
    time.sleep(0.6)
    later = figures(page)
    print("preview-test: progress %s -> %s" % (first, later))
    spp = lambda f: int(f["spp"].split("/")[0])
    secs = lambda f: seconds(f["elapsed"])
    if not (int(later["pass"].split("/")[0]) > int(first["pass"].split("/")[0]) and spp(later) > spp(first)):
        fail("pass and spp did not advance: %s -> %s" % (first, later))
    if not secs(later) > secs(first):
        fail("elapsed did not advance: %s -> %s" % (first, later))
    if later["rate"] in ("–", "0") or later["eta"] == "–" or later["state"].find("rendering") < 0:
        fail("samples/s, ETA or state missing: %s" % later)

    # The latest pass, shown again after an exposure round trip, still matches.
    set_exposure(page, 2)
    set_exposure(page, 0)
    n2, _, shown2 = canvas_state(page)
    compare("pass %d after exposure +2 and back" % n2, shown2, srgb8(read_exr(os.path.join(dump, "pass-%03d.exr" % n2))))

    # False colour is a different picture of the same pass.
    page.check("#falsecolour")
    _, _, fc = canvas_state(page)
    if (np.abs(fc - shown2) > 1).sum() < fc.size // 4:
        fail("false colour changed little")
    page.uncheck("#falsecolour")
    box = page.locator("#image").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    if "pixel (" not in page.inner_text("#pixel"):
        fail("no pixel readout under the cursor: %r" % page.inner_text("#pixel"))
    if screenshot:
        page.screenshot(path=screenshot)
        print("preview-test: screenshot " + screenshot)

    page.click("#stop")
    check_stopped(render, stats, 16384, "RGB")
    for f in (out_exr, out_png):
        if not os.path.getsize(f) > 0:
            fail(f + " was not written")
    final = read_exr(out_exr)
    if final.shape != shown.shape or not np.isfinite(final).all():
        fail("the written EXR has shape %s" % (final.shape,))
    page.wait_for_function("document.getElementById('state').dataset.state !== 'rendering'", timeout=10000)
    print("preview-test: outputs written; the page says %r" % page.inner_text("#state"))
    page.close()
    other.close()


def polarized_phase(browser, snell, work):
    dump = os.path.join(work, "passes-pol")
    out_exr, view_png = os.path.join(work, "pol.exr"), os.path.join(work, "pol-view.png")
    scene = os.path.join(ROOT, "tests", "scenes", "polarized-glass-metal.xml")
    stats = os.path.join(work, "pol-stats.json")
    render = Render(snell, [scene, "--mode", "rgb-polarized", "-Dres=48", "--spp", "8192", "--preview-dump-passes", dump,
                            "-o", out_exr, "--stokes-view", view_png, "--stats", stats, "--quiet"], work)
    page = browser.new_page()
    page.goto(render.url)
    wait_pass(page, 2)
    if not page.is_visible("#views"):
        fail("no view switch in a polarized render")
    page.check("input[name=view][value=aolp]")
    n, view, shown = canvas_state(page)
    if view != "aolp":
        fail("the view did not switch: %r" % view)
    p = os.path.join(dump, "pass-%03d.exr" % n)
    compare("polarized pass %d AoLP/DoLP view" % n, shown, stokes_view8(read_exr(p, "S0."), read_exr(p, "S1."), read_exr(p, "S2.")))
    page.screenshot(path=os.path.join(work, "polarized.png"))
    for s in ("S1", "S2", "S3"):
        page.check("input[name=view][value=%s]" % s)
        if canvas_state(page)[1] != s:
            fail("the view did not switch to " + s)
    page.check("input[name=view][value=S0]")
    n, _, shown = canvas_state(page)
    compare("polarized pass %d S0" % n, shown, srgb8(read_exr(os.path.join(dump, "pass-%03d.exr" % n), "S0.")))
    page.click("#stop")
    check_stopped(render, stats, 8192, "polarized")
    for f in (out_exr, view_png):
        if not os.path.getsize(f) > 0:
            fail(f + " was not written")


def stokes_view_png_check(work):
    """The Python AoLP/DoLP view of pol.exr against Snell's --stokes-view PNG."""
    import zlib
    import struct
    path = os.path.join(work, "pol-view.png")
    data = open(path, "rb").read()
    w, h, depth, ctype = struct.unpack(">IIBB", data[16:26])
    if (depth, ctype) != (8, 2):
        fail("unexpected PNG format %s" % ((depth, ctype),))
    idat, pos = b"", 8
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if kind == b"IDAT":
            idat += data[pos + 8:pos + 8 + n]
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride = w * 3
    img = np.zeros((h, stride), dtype=np.int32)
    prev = np.zeros(stride, dtype=np.int32)
    for y in range(h):
        f, line = raw[y * (stride + 1)], np.frombuffer(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)], dtype=np.uint8).astype(np.int32)
        out = np.zeros(stride, dtype=np.int32)
        for x in range(stride):
            a = out[x - 3] if x >= 3 else 0
            b = prev[x]
            c = prev[x - 3] if x >= 3 else 0
            if f == 0:
                pr = 0
            elif f == 1:
                pr = a
            elif f == 2:
                pr = b
            elif f == 3:
                pr = (a + b) // 2
            else:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                pr = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            out[x] = (line[x] + pr) & 255
        img[y], prev = out, out
    p = os.path.join(work, "pol.exr")
    compare("--stokes-view PNG vs the view of pol.exr", img.reshape(h, w, 3), stokes_view8(read_exr(p, "S0."), read_exr(p, "S1."), read_exr(p, "S2.")))


def main():
    if len(sys.argv) < 3:
        fail("usage: preview_test.py SNELL WORKDIR [SCREENSHOT.png]")
    snell, work = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    screenshot = os.path.abspath(sys.argv[3]) if len(sys.argv) > 3 else None
    os.makedirs(work, exist_ok=True)
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_FLAGS,
                                     chromium_sandbox=False)
        try:
            rgb_phase(browser, snell, work, screenshot)
            polarized_phase(browser, snell, work)
        finally:
            browser.close()
    # The view computed here is the one Snell writes (--stokes-view) for its final image.
    stokes_view_png_check(work)
    print("preview-test: passed")


if __name__ == "__main__":
    main()

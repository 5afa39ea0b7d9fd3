#!/usr/bin/env python3
"""Point values of Mitsuba 3.9.1's principled and principledthin BSDFs.

Writes tests/data/principled_values.txt: one line per (BSDF, wi, wo) with
Mitsuba's eval (RGB) and pdf, computed with the scalar_rgb variant's Python
bindings. src/bsdf/principled.rs's tests read the file and compare Snell's
values. Each BSDF line names its parameters as key=value pairs (floats; rgb
as r,g,b), parsed back by the test.

Usage: .venv-mitsuba/bin/python tools/principled_values.py
"""
import math
import os

import mitsuba as mi

mi.set_variant("scalar_rgb")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (plugin, parameters); base_color is an rgb, the others floats.
CONFIGS = [
    ("principled", {"base_color": (0.8, 0.4, 0.1), "roughness": 0.5}),
    ("principled", {"base_color": (0.8, 0.4, 0.1), "roughness": 0.2, "metallic": 0.7, "spec_tint": 0.4}),
    ("principled", {"base_color": (0.2, 0.5, 0.9), "roughness": 0.3, "anisotropic": 0.6, "metallic": 1.0}),
    ("principled", {"base_color": (0.9, 0.9, 0.9), "roughness": 0.15, "spec_trans": 0.8, "eta": 1.45}),
    ("principled", {"base_color": (0.6, 0.7, 0.3), "roughness": 0.4, "spec_trans": 0.5, "metallic": 0.2, "specular": 0.7, "anisotropic": 0.3}),
    ("principled", {"base_color": (0.7, 0.2, 0.2), "roughness": 0.6, "sheen": 0.8, "sheen_tint": 0.5, "flatness": 0.6, "clearcoat": 0.9, "clearcoat_gloss": 0.7}),
    ("principled", {"base_color": (0.3, 0.3, 0.8), "roughness": 0.05, "clearcoat": 1.0, "clearcoat_gloss": 0.2, "spec_tint": 1.0, "specular": 0.3}),
    ("principledthin", {"base_color": (0.8, 0.4, 0.1), "roughness": 0.5}),
    ("principledthin", {"base_color": (0.7, 0.1, 0.1), "roughness": 0.15, "spec_tint": 0.1, "anisotropic": 0.5, "spec_trans": 0.8, "diff_trans": 0.3, "eta": 1.33}),
    ("principledthin", {"base_color": (0.2, 0.6, 0.3), "roughness": 0.4, "spec_trans": 0.4, "diff_trans": 1.2, "sheen": 0.7, "sheen_tint": 0.3, "flatness": 0.5, "eta": 1.6}),
]

# (θ_i, φ_i, θ_o, φ_o): front reflection, grazing, transmission, back side.
DIRECTIONS = [
    (0.3, 0.2, 0.5, 2.9), (0.7, 0.1, 0.75, 3.3), (1.2, 0.4, 0.2, 2.0), (0.1, 0.0, 1.4, 1.0),
    (0.5, 0.3, 2.6, 3.5), (0.9, 1.0, 2.2, 4.0), (2.7, 0.2, 2.5, 3.0), (2.5, 0.5, 0.6, 3.6),
]


def direction(theta, phi):
    return mi.Vector3f(math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))


def main():
    out = ["# Mitsuba 3.9.1 scalar_rgb: principled/principledthin eval (RGB) and pdf; made by tools/principled_values.py"]
    for plugin, params in CONFIGS:
        d = {"type": plugin}
        for k, v in params.items():
            d[k] = {"type": "rgb", "value": list(v)} if isinstance(v, tuple) else v
        bsdf = mi.load_dict(d)
        desc = " ".join(f"{k}={','.join(map(str, v)) if isinstance(v, tuple) else v}" for k, v in params.items())
        out.append(f"bsdf {plugin} {desc}")
        for ti, pi, to, po in DIRECTIONS:
            si = mi.SurfaceInteraction3f()
            si.wi = direction(ti, pi)
            wo = direction(to, po)
            ctx = mi.BSDFContext()
            f = bsdf.eval(ctx, si, wo)
            p = bsdf.pdf(ctx, si, wo)
            out.append(f"{ti} {pi} {to} {po} {f[0]:.7g} {f[1]:.7g} {f[2]:.7g} {p:.7g}")
    os.makedirs(os.path.join(ROOT, "tests/data"), exist_ok=True)
    path = os.path.join(ROOT, "tests/data/principled_values.txt")
    open(path, "w").write("\n".join(out) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

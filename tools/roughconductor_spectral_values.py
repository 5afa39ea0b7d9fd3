#!/usr/bin/env python3
"""Point values of Mitsuba 3.9.1's roughconductor in the scalar_spectral variant.

Writes tests/data/roughconductor_spectral_values.txt: per BSDF (η and k as
`rgb`, as `float`, or a named material), per direction pair and per set of
four wavelengths, Mitsuba's eval (one value per wavelength). The test in
src/bsdf/roughconductor.rs reads the file and compares Snell's values, which
pins down how an rgb η/k is turned into a spectrum (Mitsuba's `srgb`
texture: the colour is clamped to [0, 1] and uplifted as a reflectance).

Usage: .venv-mitsuba/bin/python tools/roughconductor_spectral_values.py
"""
import math
import os

import mitsuba as mi

mi.set_variant("scalar_spectral")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (description for the test, parameters as XML children)
CONFIGS = [
    ("rgb eta=0.2,0.9,1.1 k=3.9,2.45,2.1 alpha=0.3",
     '<rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3.9, 2.45, 2.1"/><float name="alpha" value="0.3"/>'),
    ("rgb eta=0.2,0.45,0.8 k=0.6,0.3,0.9 alpha=0.2",
     '<rgb name="eta" value="0.2, 0.45, 0.8"/><rgb name="k" value="0.6, 0.3, 0.9"/><float name="alpha" value="0.2"/>'),
    ("float eta=1.3 k=2.7 alpha=0.25",
     '<float name="eta" value="1.3"/><float name="k" value="2.7"/><float name="alpha" value="0.25"/>'),
    ("rgb eta=0.5,0.5,0.5 k=0.25,0.25,0.25 alpha=0.4",
     '<rgb name="eta" value="0.5, 0.5, 0.5"/><rgb name="k" value="0.25"/><float name="alpha" value="0.4"/>'),
]

DIRECTIONS = [(0.3, 0.2, 0.5, 2.9), (0.7, 0.1, 0.75, 3.3), (1.2, 0.4, 0.2, 2.0)]
WAVELENGTHS = [(400.0, 480.0, 560.0, 640.0), (380.0, 520.0, 610.0, 720.0)]


def direction(theta, phi):
    return mi.Vector3f(math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))


def main():
    out = ["# Mitsuba 3.9.1 scalar_spectral: roughconductor (ggx) eval at four wavelengths; made by tools/roughconductor_spectral_values.py"]
    for desc, xml in CONFIGS:
        bsdf = mi.load_string(f'<bsdf version="3.0.0" type="roughconductor"><string name="distribution" value="ggx"/>{xml}</bsdf>')
        out.append(f"bsdf {desc}")
        for wl in WAVELENGTHS:
            for ti, pi, to, po in DIRECTIONS:
                si = mi.SurfaceInteraction3f()
                si.wi = direction(ti, pi)
                si.wavelengths = mi.Spectrum(*wl)
                f = bsdf.eval(mi.BSDFContext(), si, direction(to, po))
                out.append(" ".join(f"{v:.7g}" for v in (*wl, ti, pi, to, po, *[f[i] for i in range(4)])))
    path = os.path.join(ROOT, "tests/data/roughconductor_spectral_values.txt")
    open(path, "w").write("\n".join(out) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

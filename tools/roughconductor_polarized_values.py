#!/usr/bin/env python3
"""Point values of Mitsuba 3.9.1's roughconductor Mueller matrix in the
scalar_spectral_polarized variant.

Writes tests/data/roughconductor_polarized_values.txt: per BSDF (a named
metal, or η and k as `float`), per direction pair and per set of four
wavelengths, the 4 × 4 Mueller matrix `bsdf.eval` returns (radiance
transport; light arrives along −wo and leaves along wi, in the Stokes bases
`stokes_basis(-wo)` and `stokes_basis(wi)` of the local frame, which is the
world frame here). Row by row, entry by entry, the four wavelengths of each
entry. The test in src/bsdf/roughconductor.rs compares Snell's eval with
them; the first BSDF is the copper of tests/scenes/polarized-rough.xml.

Usage: .venv-mitsuba/bin/python tools/roughconductor_polarized_values.py
"""
import math
import os

import mitsuba as mi

mi.set_variant("scalar_spectral_polarized")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (description for the test, parameters as XML children)
CONFIGS = [
    ("material=Cu alpha_u=0.05 alpha_v=0.3",
     '<string name="material" value="Cu"/><float name="alpha_u" value="0.05"/><float name="alpha_v" value="0.3"/>'),
    ("material=Au distribution=ggx alpha=0.2",
     '<string name="material" value="Au"/><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/>'),
    ("eta=0.3 k=3.2 alpha=0.3",
     '<float name="eta" value="0.3"/><float name="k" value="3.2"/><float name="alpha" value="0.3"/>'),
]

# (θ_i, φ_i, θ_o, φ_o): near the mirror direction, off-plane, and grazing.
DIRECTIONS = [(1.2, 0.4, 1.0, 3.6), (0.5, 0.1, 0.9, 2.5), (1.35, 1.0, 1.3, 4.3), (0.8, 2.0, 0.6, 4.9)]
WAVELENGTHS = [(450.0, 550.0, 620.0, 700.0), (400.0, 500.0, 590.0, 660.0)]


def direction(theta, phi):
    return mi.Vector3f(math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))


def main():
    out = ["# Mitsuba 3.9.1 scalar_spectral_polarized: roughconductor Mueller matrix (eval), "
           "made by tools/roughconductor_polarized_values.py",
           "# λ0..λ3 θi φi θo φo, then m[r][c] at λ0..λ3 for r, c = 0..3"]
    for desc, xml in CONFIGS:
        bsdf = mi.load_string(f'<bsdf version="3.0.0" type="roughconductor">{xml}</bsdf>')
        out.append(f"bsdf {desc}")
        for wl in WAVELENGTHS:
            for ti, pi, to, po in DIRECTIONS:
                si = mi.SurfaceInteraction3f()
                si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
                si.n = mi.Vector3f(0, 0, 1)
                si.wi = direction(ti, pi)
                si.wavelengths = mi.UnpolarizedSpectrum(*wl)
                f = bsdf.eval(mi.BSDFContext(), si, direction(to, po))
                values = [f[r][c][i] for r in range(4) for c in range(4) for i in range(4)]
                out.append(" ".join(f"{v:.7g}" for v in (*wl, ti, pi, to, po, *values)))
    path = os.path.join(ROOT, "tests/data/roughconductor_polarized_values.txt")
    open(path, "w").write("\n".join(out) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

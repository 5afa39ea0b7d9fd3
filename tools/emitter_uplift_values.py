#!/usr/bin/env python3
"""How Mitsuba 3.9.1 turns an emitter's RGB radiance into a spectrum, and why
it matters for the Stokes components of a rough copper sphere.

1. Writes tests/data/emitter_uplift_values.txt: for several RGB radiances,
   the spectrum of Mitsuba's `constant` emitter (scalar_spectral; its `d65`
   plugin: the reflectance fit of c/(2 max c), times 2 max c, times D65) at
   wavelengths 360..830 nm. The test in src/spectrum/uplift.rs compares
   Snell's `from_illuminant`.

2. Prints, for the sky of tests/scenes/polarized-rough.xml (rgb 0.8, 0.9, 1)
   reflected once by the scene's copper (scalar_spectral_polarized
   roughconductor, material Cu) at a grazing direction pair, the RGB of S0
   and S1 by quadrature over λ, with two spectra of the same sky colour
   made from Mitsuba's own tables: its d65 uplift (c/(2 max c)) and the
   direct reflectance fit of c (the rule Snell used for colours with max ≤ 1).
   S0 is the same; S1.R is not.

Usage: .venv-mitsuba/bin/python tools/emitter_uplift_values.py
"""
import math
import os

import mitsuba as mi

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COLOURS = [(0.8, 0.9, 1.0), (20.0, 18.0, 14.0), (1.0, 1.0, 1.0), (0.2, 0.5, 0.9), (3.0, 0.5, 0.1), (0.05, 0.3, 0.1)]
LAMBDAS = list(range(360, 831, 10))


def spectrum_at(tex, lam, si_type):
    si = si_type()
    si.wavelengths = mi.UnpolarizedSpectrum(lam, lam, lam, lam)
    return tex.eval(si)[0]


def write_values():
    mi.set_variant("scalar_spectral")
    out = ["# Mitsuba 3.9.1 scalar_spectral: constant emitter radiance (rgb) as a spectrum; "
           "made by tools/emitter_uplift_values.py",
           "# r g b, then the radiance at " + " ".join(str(l) for l in LAMBDAS) + " nm"]
    for c in COLOURS:
        # What an emitter's <rgb name="radiance"> becomes (printing a
        # `constant` emitter shows this D65Spectrum with scale 2 max c).
        tex = mi.load_dict({"type": "d65", "color": mi.ScalarColor3f(*c)})
        values = [spectrum_at(tex, l, mi.SurfaceInteraction3f) for l in LAMBDAS]
        out.append(" ".join(f"{v:.7g}" for v in (*c, *values)))
    path = os.path.join(ROOT, "tests/data/emitter_uplift_values.txt")
    open(path, "w").write("\n".join(out) + "\n")
    print(f"wrote {path}")


def stokes_demo():
    mi.set_variant("scalar_spectral_polarized")
    sky = (0.8, 0.9, 1.0)
    mitsuba_sky = mi.load_dict({"type": "d65", "color": mi.ScalarColor3f(*sky)})
    d65 = mi.load_dict({"type": "d65"})
    direct_fit = mi.load_dict({"type": "srgb", "color": mi.ScalarColor3f(*sky)})
    bsdf = mi.load_string('<bsdf version="3.0.0" type="roughconductor"><string name="material" value="Cu"/>'
                          '<float name="alpha_u" value="0.05"/><float name="alpha_v" value="0.3"/></bsdf>')

    def d(t, p):
        return mi.Vector3f(math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t))

    for (ti, pi, to, po) in [(1.35, 1.0, 1.3, 4.3), (1.2, 0.4, 1.0, 3.6)]:
        sums = {"d65 rule c/(2 max c)": [[0.0] * 3 for _ in range(4)], "direct fit of c": [[0.0] * 3 for _ in range(4)]}
        for lam in range(360, 831):
            si = mi.SurfaceInteraction3f()
            si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
            si.wi = d(ti, pi)
            si.wavelengths = mi.UnpolarizedSpectrum(lam, lam, lam, lam)
            m = bsdf.eval(mi.BSDFContext(), si, d(to, po))
            xyz = mi.cie1931_xyz(lam)
            rgb = mi.xyz_to_srgb(mi.ScalarColor3f(xyz[0], xyz[1], xyz[2]))
            light = {"d65 rule c/(2 max c)": mitsuba_sky.eval(si)[0],
                     "direct fit of c": direct_fit.eval(si)[0] * d65.eval(si)[0]}
            for name, L in light.items():
                for s in range(4):
                    for k in range(3):
                        sums[name][s][k] += m[s][0][0] * L * rgb[k]
        print(f"copper, wi = ({ti}, {pi}), wo = ({to}, {po}): sky light reflected once (arbitrary units)")
        for name, s in sums.items():
            s0 = " ".join(f"{v:.4g}" for v in s[0])
            s1 = " ".join(f"{v:.4g}" for v in s[1])
            print(f"  {name:22s} S0 RGB {s0}  S1 RGB {s1}")
        a, b = sums["d65 rule c/(2 max c)"][1][0], sums["direct fit of c"][1][0]
        print(f"  S1.R ratio (direct fit / d65 rule) {b / a:.3f}")


if __name__ == "__main__":
    write_values()
    stokes_demo()

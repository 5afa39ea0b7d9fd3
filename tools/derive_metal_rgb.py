#!/usr/bin/env python3
"""Derives the RGB complex IORs (eta, k) of Mitsuba 3's named conductors and
writes src/bsdf/metals.rs.

Mitsuba 3's `conductor` plugin accepts `material="<name>"` and loads the
measured spectra data/ior/<name>.eta.spd and data/ior/<name>.k.spd (shipped in
the mitsuba Python package; the same tables as PBRT's, from the Luxpop
database, based on Palik et al., "Handbook of Optical Constants of Solids",
and CXRO/LLNL atomic scattering factor measurements). In its RGB variants it
turns each spectrum into a linear sRGB triple with
`spectrum_list_to_srgb(wavelengths, values, bounded=false, d65=false)`:

  * 1000 wavelengths w_i = 360 + i/999 * (830 - 360) nm, i = 0..999;
  * wavelengths outside [first, last] tabulated wavelength are skipped;
  * the spectrum is linearly interpolated between its tabulated points;
  * XYZ = sum_i cie1931_xyz(w_i) * v(w_i) * (830 - 360) / 1000, where
    cie1931_xyz linearly interpolates the CIE 1931 2-degree colour matching
    functions tabulated every 5 nm from 360 to 830 nm (95 samples, stored as
    float32), divided by the CIE Y normalisation 106.7502593994140625 so that
    a unit spectrum has luminance 1;
  * linear sRGB (Rec. 709 primaries) = M * XYZ with Mitsuba's matrix;
  * negative components are clamped to 0 with a warning (this happens for a
    few non-metals, e.g. AlSb's red eta and k, CsI's k).

This script repeats that computation with its own code (no Mitsuba needed),
and also writes the spectra themselves to src/bsdf/metal_spectra.rs for
spectral mode:

  python3 tools/derive_metal_rgb.py [--data DIR] [--out src/bsdf/metals.rs]

DIR defaults to the data/ior directory of the mitsuba package in
.venv-mitsuba (tools/setup-mitsuba.sh). With --verify (run it with
.venv-mitsuba/bin/python) it also loads every material in Mitsuba's
`conductor` (variant scalar_rgb), reads eta and k back with mi.traverse and
reports the largest relative difference.
"""
import argparse
import glob
import os
import struct
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CIE_MIN, CIE_MAX, CIE_SAMPLES = 360.0, 830.0, 95
CIE_Y_NORMALIZATION = 1.0 / 106.7502593994140625

# CIE 1931 2-degree standard observer, 360..830 nm every 5 nm (CIE 015).
CIE_X = [
    0.0001299, 0.0002321, 0.0004149, 0.0007416, 0.001368, 0.002236, 0.004243, 0.00765,
    0.01431, 0.02319, 0.04351, 0.07763, 0.13438, 0.21477, 0.2839, 0.3285,
    0.34828, 0.34806, 0.3362, 0.3187, 0.2908, 0.2511, 0.19536, 0.1421,
    0.09564, 0.05795001, 0.03201, 0.0147, 0.0049, 0.0024, 0.0093, 0.0291,
    0.06327, 0.1096, 0.1655, 0.2257499, 0.2904, 0.3597, 0.4334499, 0.5120501,
    0.5945, 0.6784, 0.7621, 0.8425, 0.9163, 0.9786, 1.0263, 1.0567,
    1.0622, 1.0456, 1.0026, 0.9384, 0.8544499, 0.7514, 0.6424, 0.5419,
    0.4479, 0.3608, 0.2835, 0.2187, 0.1649, 0.1212, 0.0874, 0.0636,
    0.04677, 0.0329, 0.0227, 0.01584, 0.01135916, 0.008110916, 0.005790346, 0.004109457,
    0.002899327, 0.00204919, 0.001439971, 0.0009999493, 0.0006900786, 0.0004760213, 0.0003323011,
    0.0002348261, 0.0001661505, 0.000117413, 8.307527e-05, 5.870652e-05, 4.150994e-05,
    2.935326e-05, 2.067383e-05, 1.455977e-05, 1.025398e-05, 7.221456e-06, 5.085868e-06,
    3.581652e-06, 2.522525e-06, 1.776509e-06, 1.251141e-06,
]
CIE_Y = [
    3.917e-06, 6.965e-06, 1.239e-05, 2.202e-05, 3.9e-05, 6.4e-05, 0.00012, 0.000217,
    0.000396, 0.00064, 0.00121, 0.00218, 0.004, 0.0073, 0.0116, 0.01684,
    0.023, 0.0298, 0.038, 0.048, 0.06, 0.0739, 0.09098, 0.1126,
    0.13902, 0.1693, 0.20802, 0.2586, 0.323, 0.4073, 0.503, 0.6082,
    0.71, 0.7932, 0.862, 0.9148501, 0.954, 0.9803, 0.9949501, 1.0,
    0.995, 0.9786, 0.952, 0.9154, 0.87, 0.8163, 0.757, 0.6949,
    0.631, 0.5668, 0.503, 0.4412, 0.381, 0.321, 0.265, 0.217,
    0.175, 0.1382, 0.107, 0.0816, 0.061, 0.04458, 0.032, 0.0232,
    0.017, 0.01192, 0.00821, 0.005723, 0.004102, 0.002929, 0.002091, 0.001484,
    0.001047, 0.00074, 0.00052, 0.0003611, 0.0002492, 0.0001719, 0.00012, 8.48e-05,
    6e-05, 4.24e-05, 3e-05, 2.12e-05, 1.499e-05, 1.06e-05, 7.4657e-06, 5.2578e-06,
    3.7029e-06, 2.6078e-06, 1.8366e-06, 1.2934e-06, 9.1093e-07, 6.4153e-07, 4.5181e-07,
]
CIE_Z = [
    0.0006061, 0.001086, 0.001946, 0.003486, 0.006450001, 0.01054999, 0.02005001, 0.03621,
    0.06785001, 0.1102, 0.2074, 0.3713, 0.6456, 1.0390501, 1.3856, 1.62296,
    1.74706, 1.7826, 1.77211, 1.7441, 1.6692, 1.5281, 1.28764, 1.0419,
    0.8129501, 0.6162, 0.46518, 0.3533, 0.272, 0.2123, 0.1582, 0.1117,
    0.07824999, 0.05725001, 0.04216, 0.02984, 0.0203, 0.0134, 0.008749999, 0.005749999,
    0.0039, 0.002749999, 0.0021, 0.0018, 0.001650001, 0.0014, 0.0011, 0.001,
    0.0008, 0.0006, 0.00034, 0.00024, 0.00019, 0.0001, 4.999999e-05, 3e-05,
    2e-05, 1e-05,
] + [0.0] * 37

# XYZ -> linear sRGB (ITU-R BT.709 primaries, D65 white), as in Mitsuba's xyz_to_srgb.
XYZ_TO_SRGB = [
    [3.240479, -1.537150, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
]

assert len(CIE_X) == len(CIE_Y) == len(CIE_Z) == CIE_SAMPLES


def f32(x):
    """Rounds to float32, as Mitsuba stores its tables and its RGB results."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


CIE_TABLES = [[f32(v) for v in t] for t in (CIE_X, CIE_Y, CIE_Z)]
XYZ_TO_SRGB_F32 = [[f32(v) for v in row] for row in XYZ_TO_SRGB]


def cie1931_xyz(w):
    """Linearly interpolated CIE 1931 colour matching functions at w nm."""
    if w < CIE_MIN or w > CIE_MAX:
        return (0.0, 0.0, 0.0)
    t = (w - CIE_MIN) * ((CIE_SAMPLES - 1) / (CIE_MAX - CIE_MIN))
    i0 = min(max(int(t), 0), CIE_SAMPLES - 2)
    w1 = t - i0
    w0 = 1.0 - w1
    return tuple(w0 * tab[i0] + w1 * tab[i0 + 1] for tab in CIE_TABLES)


def read_spd(path):
    """Reads a .spd file: '#' comments, then 'wavelength value' pairs."""
    wavelengths, values = [], []
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            parts = line.split()
            if len(parts) != 2:
                raise ValueError(f"{path}: expected 'wavelength value', got {line!r}")
            wavelengths.append(float(parts[0]))
            values.append(float(parts[1]))
    if any(b <= a for a, b in zip(wavelengths, wavelengths[1:])):
        raise ValueError(f"{path}: wavelengths not strictly increasing")
    return wavelengths, values


def find_interval(xs, x):
    """Largest i in [0, len(xs) - 2] with xs[i] <= x (clamped)."""
    lo, hi = 0, len(xs) - 2
    if x < xs[0]:
        return 0
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if xs[mid] <= x:
            lo = mid
        else:
            hi = mid - 1
    return lo


def spectrum_to_srgb(wavelengths, values, steps=1000):
    """Linear sRGB of a tabulated spectrum (unbounded, no illuminant)."""
    xyz = [0.0, 0.0, 0.0]
    for i in range(steps):
        w = CIE_MIN + (i / (steps - 1)) * (CIE_MAX - CIE_MIN)
        if w < wavelengths[0] or w > wavelengths[-1]:
            continue
        j = find_interval(wavelengths, w)
        w0, w1 = wavelengths[j], wavelengths[j + 1]
        v0, v1 = values[j], values[j + 1]
        v = ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1)
        c = cie1931_xyz(w)
        for k in range(3):
            xyz[k] += c[k] * v
    scale = (CIE_MAX - CIE_MIN) / steps * CIE_Y_NORMALIZATION
    xyz = [c * scale for c in xyz]
    rgb = [sum(m * c for m, c in zip(row, xyz)) for row in XYZ_TO_SRGB_F32]
    return [f32(max(c, 0.0)) for c in rgb]


def default_data_dir():
    hits = glob.glob(os.path.join(ROOT, ".venv-mitsuba", "lib", "python3*", "site-packages",
                                  "mitsuba", "data", "ior"))
    return hits[0] if hits else None


def derive(data_dir):
    names = sorted({os.path.basename(p)[: -len(".eta.spd")]
                    for p in glob.glob(os.path.join(data_dir, "*.eta.spd"))})
    table = []
    for name in names:
        k_path = os.path.join(data_dir, name + ".k.spd")
        if not os.path.exists(k_path):
            continue
        eta = spectrum_to_srgb(*read_spd(os.path.join(data_dir, name + ".eta.spd")))
        k = spectrum_to_srgb(*read_spd(k_path))
        table.append((name, eta, k))
    return table


def fmt(x):
    """Shortest decimal that round-trips to the same float32."""
    for digits in range(6, 10):
        s = f"{x:.{digits}g}"
        if f32(float(s)) == x:
            break
    if "e" not in s and "." not in s:
        s += ".0"
    return s


def write_rust(table, out):
    lines = [
        "// @generated by tools/derive_metal_rgb.py — do not edit by hand.",
        "//! Named conductors for `conductor` `material=\"...\"`: the RGB complex",
        "//! indices of refraction (η, k) that Mitsuba 3's RGB variants use.",
        "//!",
        "//! Source data: the measured spectral η and k tables that Mitsuba 3.9.1",
        "//! ships as data/ior/<name>.{eta,k}.spd (identical to PBRT's; from the",
        "//! Luxpop database, based on Palik et al., *Handbook of Optical Constants",
        "//! of Solids*, and CXRO/LLNL atomic scattering factor measurements).",
        "//! Each spectrum is converted to linear sRGB as Mitsuba's",
        "//! `spectrum_list_to_srgb(.., bounded = false, d65 = false)` does: 1000",
        "//! uniform wavelengths over 360–830 nm, linear interpolation of the data",
        "//! (zero outside its range), CIE 1931 2° matching functions (5 nm table,",
        "//! linearly interpolated) normalised by 1/106.75026, XYZ → Rec. 709 linear",
        "//! RGB. tools/derive_metal_rgb.py --verify checks every entry against",
        "//! Mitsuba's own values. Sorted by name; the special `none` (η = 0,",
        "//! k = 1: a perfect mirror) is not in this table.",
        "",
        "/// A named conductor: RGB real (η) and imaginary (k) parts of its IOR.",
        "pub struct Metal {",
        "    pub name: &'static str,",
        "    pub eta: [f32; 3],",
        "    pub k: [f32; 3],",
        "}",
        "",
        "/// Every material name Mitsuba 3 accepts, sorted by name (byte order).",
        "pub const METALS: &[Metal] = &[",
    ]
    for name, eta, k in sorted(table, key=lambda t: t[0]):
        e = ", ".join(fmt(v) for v in eta)
        kk = ", ".join(fmt(v) for v in k)
        # One field per line: the layout rustfmt gives, so `rustfmt --check` passes.
        lines += ["    Metal {", f'        name: "{name}",', f"        eta: [{e}],",
                  f"        k: [{kk}],", "    },"]
    lines += ["];", ""]
    with open(out, "w") as f:
        f.write("\n".join(lines))


def write_spectra(data_dir, out):
    """The measured spectra themselves, for spectral mode (Mitsuba's spectral
    variants interpolate the same points linearly, zero outside their range)."""
    names = sorted({os.path.basename(p)[: -len(".eta.spd")]
                    for p in glob.glob(os.path.join(data_dir, "*.eta.spd"))})
    lines = [
        "// @generated by tools/derive_metal_rgb.py — do not edit by hand.",
        "//! Measured spectral η(λ) and k(λ) of the named conductors, as (nm, value)",
        "//! points: the tables Mitsuba 3.9.1 ships as data/ior/<name>.{eta,k}.spd",
        "//! (from the Luxpop database, based on Palik et al., *Handbook of Optical",
        "//! Constants of Solids*, and CXRO/LLNL measurements). Spectral mode",
        "//! interpolates them linearly, zero outside their range, as Mitsuba's",
        "//! spectral variants do. Sorted by name, like `metals.rs`.",
        "",
        "/// A named conductor's spectral complex index of refraction.",
        "#[derive(Debug)]",
        "pub struct MetalSpectra {",
        "    pub name: &'static str,",
        "    pub eta: &'static [[f32; 2]],",
        "    pub k: &'static [[f32; 2]],",
        "}",
        "",
        "pub static METAL_SPECTRA: &[MetalSpectra] = &[",
    ]
    for name in names:
        eta = read_spd(os.path.join(data_dir, name + ".eta.spd"))
        k = read_spd(os.path.join(data_dir, name + ".k.spd"))
        pts = lambda wv: ", ".join(f"[{fmt(w)}, {fmt(v)}]" for w, v in zip(*wv))
        lines += ["    MetalSpectra {", f'        name: "{name}",', f"        eta: &[{pts(eta)}],",
                  f"        k: &[{pts(k)}],", "    },"]
    lines += ["];", ""]
    with open(out, "w") as f:
        f.write("\n".join(lines))
    print(f"wrote {len(names)} spectra to {os.path.relpath(out, ROOT)}")


def verify(table):
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    worst = (0.0, None)
    for name, eta, k in table:
        bsdf = mi.load_dict({"type": "conductor", "material": name})
        params = mi.traverse(bsdf)
        mi_eta = list(params["eta.value"])
        mi_k = list(params["k.value"])
        for ours, theirs, what in ((eta, mi_eta, "eta"), (k, mi_k, "k")):
            for c in range(3):
                rel = abs(ours[c] - theirs[c]) / max(abs(theirs[c]), 1e-12)
                if rel > worst[0]:
                    worst = (rel, f"{name}.{what}[{c}]: ours {ours[c]!r} Mitsuba {theirs[c]!r}")
                if rel > 1e-4:
                    print(f"MISMATCH {name}.{what}[{c}]: ours {ours[c]} Mitsuba {theirs[c]}")
    print(f"verified {len(table)} materials against Mitsuba {mi.__version__}: "
          f"max relative difference {worst[0]:.2e} ({worst[1]})")
    return worst[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=default_data_dir(),
                    help="directory with <name>.eta.spd / <name>.k.spd")
    ap.add_argument("--out", default=os.path.join(ROOT, "src", "bsdf", "metals.rs"))
    ap.add_argument("--spectra-out", default=os.path.join(ROOT, "src", "bsdf", "metal_spectra.rs"))
    ap.add_argument("--verify", action="store_true",
                    help="compare with Mitsuba's own values (needs the mitsuba module)")
    args = ap.parse_args()
    if not args.data or not os.path.isdir(args.data):
        sys.exit("spectral data not found: pass --data DIR (mitsuba's data/ior)")
    table = derive(args.data)
    write_rust(table, args.out)
    print(f"wrote {len(table)} materials to {os.path.relpath(args.out, ROOT)}")
    write_spectra(args.data, args.spectra_out)
    if args.verify and verify(table) > 1e-4:
        sys.exit("verification failed")


if __name__ == "__main__":
    main()

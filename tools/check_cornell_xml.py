#!/usr/bin/env python3
"""Checks that scenes/cornell-box.xml matches mitsuba.cornell_box().

Renders both with the same variant, spp and seed and prints the per-channel
means and the max abs difference; also compares the shapes' to_world matrices.
Run with the Mitsuba venv (tools/setup-mitsuba.sh).
"""
import argparse
import os
import sys

import numpy as np

os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")
import mitsuba as mi  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    mi.set_variant(args.variant)

    d = mi.cornell_box()
    s_dict = mi.load_dict(d)
    s_xml = mi.load_file(os.path.join(ROOT, "scenes", "cornell-box.xml"),
                         spp=str(args.spp))
    # Use the dict's sampler count too.
    d["sensor"]["sampler"]["sample_count"] = args.spp
    s_dict = mi.load_dict(d)

    # Mitsuba merges meshes sharing a BSDF (the white ones get id ''), so
    # compare the sorted vertex positions of each resulting mesh.
    def verts(scene):
        out = {}
        for sh in scene.shapes():
            v = np.array(sh.vertex_positions_buffer()).reshape(-1, 3)
            out[sh.id()] = v[np.lexsort(np.round(v, 4).T[::-1])]
        return out

    vd, vx = verts(s_dict), verts(s_xml)
    ok = sorted(vd) == sorted(vx)
    for k in vd:
        same = k in vx and vd[k].shape == vx[k].shape
        dv = float(np.abs(vd[k] - vx[k]).max()) if same else float("inf")
        print(f"mesh {k or '(merged white)':16s} {len(vd[k]):4d} vertices, max diff {dv:.2e}")
        ok &= dv < 1e-5

    a = np.array(mi.render(s_dict, spp=args.spp, seed=args.seed))
    b = np.array(mi.render(s_xml, spp=args.spp, seed=args.seed))
    print("dict mean RGB:", a.reshape(-1, a.shape[-1]).mean(0))
    print("xml  mean RGB:", b.reshape(-1, b.shape[-1]).mean(0))
    diff = np.abs(a - b).max()
    print("max abs pixel diff:", diff)
    ok &= a.shape == b.shape
    print("OK" if ok else "MISMATCH")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

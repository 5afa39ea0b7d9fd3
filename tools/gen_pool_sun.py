#!/usr/bin/env python3
"""Writes scenes/assets/pool-ripples.ply, the rippled water surface of scenes/pool-sun.xml.

A height field y = h(x, z) over the square [-S, S]² (S = 5), a sum of a few
long-crested sine waves (amplitude a few millimetres to 1.5 cm, wavelengths
0.45-1.3 m), as an N × N grid of vertices with analytic normals (smooth
shading), binary little-endian PLY. Normals point up, into the air: with the
dielectric's int_ior = water, ext_ior = air the water lies below.

Usage: python3 tools/gen_pool_sun.py   (no dependencies)
"""
import math
import os
import struct

S = 5.0
N = 129  # vertices per side
# (amplitude, wavelength, direction angle in degrees, phase)
WAVES = [
    (0.012, 1.30, 20.0, 0.0),
    (0.008, 0.90, 75.0, 1.3),
    (0.006, 0.62, 140.0, 2.1),
    (0.004, 0.45, 230.0, 0.7),
]

OUT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "scenes", "assets", "pool-ripples.ply")


def height(x, z):
    """h and its partial derivatives dh/dx, dh/dz."""
    h = hx = hz = 0.0
    for a, wl, ang, ph in WAVES:
        k = 2.0 * math.pi / wl
        dx, dz = math.cos(math.radians(ang)), math.sin(math.radians(ang))
        t = k * (dx * x + dz * z) + ph
        h += a * math.sin(t)
        c = a * k * math.cos(t)
        hx += c * dx
        hz += c * dz
    return h, hx, hz


def main():
    verts = []
    for j in range(N):
        z = -S + 2.0 * S * j / (N - 1)
        for i in range(N):
            x = -S + 2.0 * S * i / (N - 1)
            h, hx, hz = height(x, z)
            n = (-hx, 1.0, -hz)
            l = math.sqrt(sum(c * c for c in n))
            verts.append((x, h, z, n[0] / l, n[1] / l, n[2] / l))
    faces = []
    for j in range(N - 1):
        for i in range(N - 1):
            a, b = j * N + i, j * N + i + 1
            c, d = a + N, b + N
            # Counter-clockwise seen from above (+y): the face normal points up.
            faces.append((a, c, b))
            faces.append((b, c, d))
    head = (
        "ply\nformat binary_little_endian 1.0\n"
        "comment rippled water surface of scenes/pool-sun.xml, made by tools/gen_pool_sun.py\n"
        f"element vertex {len(verts)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(OUT, "wb") as f:
        f.write(head.encode())
        for v in verts:
            f.write(struct.pack("<6f", *v))
        for t in faces:
            f.write(struct.pack("<B3i", 3, *t))
    print(f"{OUT}: {len(verts)} vertices, {len(faces)} triangles")


if __name__ == "__main__":
    main()

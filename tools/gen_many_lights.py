#!/usr/bin/env python3
"""Writes scenes/many-lights.xml: 100 small one-sided rectangular area lights
(facing down, tilted up to 30 degrees) whose powers span three orders of
magnitude, over a floor with a back wall, two cubes and three spheres.

Deterministic (fixed seed). Mitsuba-3-valid XML, so Mitsuba renders it too.
Usage: python3 tools/gen_many_lights.py [out.xml]
"""
import math
import os
import random
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "scenes", "many-lights.xml")
    rng = random.Random(13)
    lines = []
    w = lines.append
    w('<?xml version="1.0" encoding="utf-8"?>')
    w('<!-- Many lights: 100 small rectangular area lights, facing down and tilted up to 30°,')
    w('     whose powers span three orders of magnitude, over a floor with a back wall, two')
    w('     cubes and three spheres. Written by tools/gen_many_lights.py (seed 13); the')
    w('     light-selection benchmark and tests use it. Mitsuba 3 renders it as it is. -->')
    w('<scene version="3.0.0">')
    w('    <default name="spp" value="64"/>')
    w('    <default name="res" value="256"/>')
    w('    <default name="max_depth" value="4"/>')
    w('')
    w('    <integrator type="path">')
    w('        <integer name="max_depth" value="$max_depth"/>')
    w('    </integrator>')
    w('')
    w('    <sensor type="perspective">')
    w('        <float name="fov" value="50"/>')
    w('        <transform name="to_world">')
    w('            <lookat origin="0, 6.5, 8" target="0, 0, -0.8" up="0, 1, 0"/>')
    w('        </transform>')
    w('        <sampler type="independent">')
    w('            <integer name="sample_count" value="$spp"/>')
    w('        </sampler>')
    w('        <film type="hdrfilm">')
    w('            <integer name="width" value="$res"/>')
    w('            <integer name="height" value="$res"/>')
    w('            <rfilter type="gaussian"/>')
    w('        </film>')
    w('    </sensor>')
    w('')
    w('    <bsdf type="diffuse" id="floor"><rgb name="reflectance" value="0.6, 0.6, 0.6"/></bsdf>')
    w('    <bsdf type="diffuse" id="wall"><rgb name="reflectance" value="0.5, 0.55, 0.6"/></bsdf>')
    w('    <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.7, 0.2, 0.15"/></bsdf>')
    w('    <bsdf type="diffuse" id="blue"><rgb name="reflectance" value="0.15, 0.25, 0.7"/></bsdf>')
    w('    <bsdf type="diffuse" id="black"><rgb name="reflectance" value="0.02"/></bsdf>')
    w('')
    w('    <shape type="rectangle">')
    w('        <transform name="to_world"><scale value="6"/><rotate x="1" angle="-90"/></transform>')
    w('        <ref id="floor"/>')
    w('    </shape>')
    w('    <shape type="rectangle">')
    w('        <transform name="to_world"><scale x="6" y="2.5"/><translate y="2.5" z="-6"/></transform>')
    w('        <ref id="wall"/>')
    w('    </shape>')
    for (x, z, s, ang, bsdf) in [(-2.0, -1.0, 0.8, 25, "red"), (2.2, 0.5, 0.6, -15, "blue")]:
        w('    <shape type="cube">')
        w(f'        <transform name="to_world"><scale value="{s}"/><rotate y="1" angle="{ang}"/>'
          f'<translate x="{x}" y="{s}" z="{z}"/></transform>')
        w(f'        <ref id="{bsdf}"/>')
        w('    </shape>')
    for (x, z, r, bsdf) in [(0.0, -2.5, 1.0, "floor"), (-0.5, 2.0, 0.5, "red"), (3.5, -3.0, 0.7, "blue")]:
        w('    <shape type="sphere">')
        w(f'        <point name="center" x="{x}" y="{r}" z="{z}"/>')
        w(f'        <float name="radius" value="{r}"/>')
        w(f'        <ref id="{bsdf}"/>')
        w('    </shape>')
    w('')
    w('    <!-- Lights: radiance × area spans 1 : 1000. -->')
    for i in range(100):
        x = rng.uniform(-5.5, 5.5)
        z = rng.uniform(-5.5, 5.0)
        y = rng.uniform(0.25, 2.2)
        half = rng.uniform(0.04, 0.1)
        tilt = rng.uniform(0, 30)
        yaw = rng.uniform(0, 360)
        # Power spread: 10^U(0, 3) over the smallest, divided by the area.
        power = 10 ** rng.uniform(0.0, 3.0)
        radiance = 0.08 * power * (0.1 / half) ** 2
        tint = [rng.uniform(0.6, 1.0) for _ in range(3)]
        rgb = ", ".join(f"{radiance * t:.4g}" for t in tint)
        w(f'    <shape type="rectangle" id="light{i}">')
        w(f'        <transform name="to_world"><scale value="{half:.4f}"/><rotate x="1" angle="90"/>'
          f'<rotate x="1" angle="{tilt:.2f}"/><rotate y="1" angle="{yaw:.2f}"/>'
          f'<translate x="{x:.3f}" y="{y:.3f}" z="{z:.3f}"/></transform>')
        w('        <ref id="black"/>')
        w(f'        <emitter type="area"><rgb name="radiance" value="{rgb}"/></emitter>')
        w('    </shape>')
    w('</scene>')
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Writes scenes/rainbow.xml (and scenes/rainbow-sky.xml, the same sky for particle tracing): a sheet of rain (water drops, instanced spheres) in
front of a dark sky, lit by a sun of 0.53 degrees straight behind the camera, so the
antisolar point is the image centre and the bows are circles around it.

The drops: one shapegroup of DROPS_PER_TILE non-overlapping spheres (radius RADIUS)
in a TILE x TILE x DEPTH box, instanced on a TILES x TILES grid over the sheet, each
copy turned by a multiple of 90 degrees and shifted in depth, so the XML stays small
while the sheet holds DROPS_PER_TILE * TILES^2 drops. Tiles do not overlap and neither
do the drops in a tile (overlapping spheres would make nonsense interfaces).

Usage: python3 tools/gen_rainbow.py   (standard library only; fixed seed)
"""
import math
import os
import random

RADIUS = 0.4          # drop radius (scene units)
TILE = 12.0           # side of one tile of drops
DEPTH = 8.0           # thickness of a tile
DROPS_PER_TILE = 256
TILES = 14            # tiles per side: the sheet spans +-TILES*TILE/2 = +-84
NEAR = 40.0           # distance of the sheet's front from the camera
SUN_DIST = 1.0e5      # the sun disk's distance behind the camera
SUN_DEG = 0.53        # its angular diameter
SEED = 16

rng = random.Random(SEED)

drops = []
while len(drops) < DROPS_PER_TILE:
    m = TILE / 2 - RADIUS
    p = (rng.uniform(-m, m), rng.uniform(-m, m), rng.uniform(RADIUS, DEPTH - RADIUS))
    if all(sum((a - b) ** 2 for a, b in zip(p, q)) > (2.05 * RADIUS) ** 2 for q in drops):
        drops.append(p)

sun_radius = SUN_DIST * math.tan(math.radians(SUN_DEG / 2))
half = TILES * TILE / 2

lines = []
for x, y, z in drops:
    lines.append(f'        <shape type="sphere"><point name="center" x="{x:.3f}" y="{y:.3f}" z="{z:.3f}"/>'
                 f'<float name="radius" value="{RADIUS}"/><ref id="water"/></shape>')
group = "\n".join(lines)

inst = []
for i in range(TILES):
    for j in range(TILES):
        cx = -half + (i + 0.5) * TILE
        cy = -half + (j + 0.5) * TILE
        cz = NEAR + rng.uniform(0.0, 4.0)
        angle = 90 * rng.randrange(4)
        inst.append(f'    <shape type="instance"><ref id="drops"/><transform name="to_world">'
                    f'<rotate z="1" angle="{angle}"/><translate x="{cx:.1f}" y="{cy:.1f}" z="{cz:.2f}"/>'
                    f'</transform></shape>')
instances = "\n".join(inst)

n_drops = DROPS_PER_TILE * TILES * TILES
text = f'''<?xml version="1.0" encoding="utf-8"?>
<!-- A rainbow in the sky: {n_drops} drops of water (radius {RADIUS}) in a sheet
     {2 * half:.0f} x {2 * half:.0f} wide and {DEPTH:.0f} to {DEPTH + 4:.0f} deep, its front {NEAR:.0f} in front of the camera,
     in front of a dark sky (a dim constant emitter), lit by the sun: a disk emitter of
     radius {sun_radius:.1f} at {SUN_DIST:.0e} straight behind the camera, so it subtends {SUN_DEG} degrees
     (-D sun_radius=R for another size). The camera looks at the antisolar point;
     its 120-degree field shows the primary bow (42 degrees from the image centre, red
     outside), the secondary (51 degrees, red inside) and Alexander's dark band between.
     Written by tools/gen_rainbow.py: one shapegroup of {DROPS_PER_TILE} drops instanced on a
     {TILES} x {TILES} grid. Water is dispersive (Daimon and Masumura's Sellmeier fit), so render
     with mode spectral for the colours; -D ior=1.333 gives Mitsuba 3 (which has no dispersive
     dielectric) a file it can render.

     A hard scene for a path tracer: a camera path reaches the sun only if it leaves a drop
     inside the sun's disk, about once in 1e5 samples at the primary bow (the chance of the
     internal reflection, about 4 %, times the fraction of a drop's cross-section that sends
     light into a 0.53-degree cone) and once in 1e6 at the secondary; light paths cannot be
     joined to the pinhole through the drops' smooth surfaces at all. tests/rainbow.rs
     measures the bows in Descartes' experiment instead (one drop, a screen, particle tracing).
     For a quick look, enlarge the sun: -D sun_radius=4400 (5 degrees) converges 90 times faster
     but blurs the bows by 5 degrees. -->
<scene version="3.0.0">
    <default name="spp" value="256"/>
    <default name="res" value="256"/>
    <default name="max_depth" value="12"/>
    <default name="ior" value="sellmeier:water"/>
    <default name="sun_radius" value="{sun_radius:.1f}"/>
    <default name="sun" value="20000"/>

    <integrator type="path">
        <integer name="max_depth" value="$max_depth"/>
    </integrator>

    <sensor type="perspective">
        <float name="fov" value="120"/>
        <transform name="to_world">
            <lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/>
        </transform>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="$res"/>
            <integer name="height" value="$res"/>
            <rfilter type="gaussian"/>
        </film>
    </sensor>

    <!-- The sun: radiance $sun, seen from the drops as a disk of 0.53 degrees. -->
    <shape type="disk">
        <transform name="to_world">
            <scale value="$sun_radius"/>
            <lookat origin="0, 0, {-SUN_DIST:.0f}" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <emitter type="area">
            <rgb name="radiance" value="$sun"/>
        </emitter>
    </shape>

    <!-- A dark, slightly blue sky. -->
    <emitter type="constant">
        <rgb name="radiance" value="0.02, 0.025, 0.035"/>
    </emitter>

    <bsdf type="dielectric" id="water">
        <string name="int_ior" value="$ior"/>
        <string name="ext_ior" value="air"/>
    </bsdf>

    <shape type="shapegroup" id="drops">
{group}
    </shape>

{instances}
</scene>
'''

# The same sky for particle tracing (scenes/rainbow-sky.xml): light paths joined to the
# pinhole through each drop in closed form (ptracer's sphere_connection), the sun as its
# direction with the disk's irradiance (radiance x solid angle), since light paths from a
# disk 1e5 away would almost never reach the sheet.
sun_irradiance = 20000 * 2 * math.pi * (1 - math.cos(math.radians(SUN_DEG / 2)))
sky = text.replace(
    """    <integrator type="path">
        <integer name="max_depth" value="$max_depth"/>
    </integrator>""",
    """    <integrator type="ptracer">
        <integer name="max_depth" value="$max_depth"/>
        <boolean name="sphere_connection" value="true"/>
    </integrator>""")
a = sky.index("    <!-- The sun: radiance")
b = sky.index("    </shape>", a) + len("    </shape>")
sky = sky[:a] + f"""    <!-- The sun as its direction: the irradiance of a disk of radiance 20000 and 0.53 degrees. -->
    <emitter type="directional">
        <vector name="direction" x="0" y="0" z="1"/>
        <rgb name="irradiance" value="{sun_irradiance:.3f}"/>
    </emitter>""" + sky[b:]
a = sky.index("<!-- A rainbow in the sky")
b = sky.index("-->", a) + len("-->")
sky = sky[:a] + f"""<!-- The sky rainbow of rainbow.xml ({n_drops} drops of dispersive water in front of a dark sky,
     the sun behind the camera), made to converge: ptracer joins light paths to the pinhole
     through each drop in closed form (sphere_connection), and the 0.53-degree sun is its
     direction (directional emitter, the disk's irradiance). Written by tools/gen_rainbow.py.
     Render with mode spectral for the colours (docs/images/rainbow.png: 256 x 256, 128 spp). -->""" + sky[b:]
sky = sky.replace('    <default name="sun_radius" value="{:.1f}"/>\n'.format(sun_radius), "").replace('    <default name="sun" value="20000"/>\n', "")

here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes")
for name, body in (("rainbow.xml", text), ("rainbow-sky.xml", sky)):
    out = os.path.join(here, name)
    with open(out, "w") as f:
        f.write(body)
    print(f"wrote {os.path.normpath(out)}: {n_drops} drops")
print(f"sun radius {sun_radius:.2f} at {SUN_DIST:g}, irradiance {sun_irradiance:.4f}")

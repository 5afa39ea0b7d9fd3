#!/usr/bin/env python3
"""Writes scenes/assets/diamond.obj: a round brilliant-cut diamond (57 facets + a 32-facet girdle).

The stone is the intersection of one half-space per facet, made by clipping a big box
plane by plane, so it is convex and closed by construction. y is up, the table faces +y,
the girdle is centred in the xz plane with radius 1. Output: shared vertices, fan-
triangulated facets, counter-clockwise from outside, no normals (flat facets).

Usage: python3 tools/gen_diamond.py [output.obj]   (standard library only)
"""
import collections
import itertools
import math
import os
import sys

# Tolkowsky, Diamond Design (1919): crown 34.5 deg, pavilion 40.75 deg. As in his
# cross-section through a bezel, TABLE is the table's half-width along a bezel azimuth
# (where the bezel meets the table); the star bases form the table octagon's edges.
CROWN_ANGLE = 34.5         # bezel facets vs the girdle plane, degrees
PAVILION_ANGLE = 40.75     # pavilion mains vs the girdle plane, degrees
TABLE = 0.55               # table half-width (fraction of the girdle radius)
GIRDLE_RADIUS = 1.0
GIRDLE_HALF = 0.015        # girdle thickness 0.03, centred on y = 0
# Not Tolkowsky's: usual modern proportions. The star, upper- and lower-girdle angles are
# derived from these so that the facets meet in the classic points (no slivers).
STAR_LENGTH = 0.50         # star tip, as a fraction of the way from table edge to girdle
LOWER_HALF_LENGTH = 0.75   # lower-girdle tip, as a fraction of the way from girdle to culet

EPS = 1e-9
BOX = 4.0


def sub(a, b): return (a[0] - b[0], a[1] - b[1], a[2] - b[2])
def dot(a, b): return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def norm(a): return math.sqrt(dot(a, a))
def near(a, b): return norm(sub(a, b)) <= EPS * max(1.0, norm(a))
def polar(r, az, y): return (r * math.cos(az), y, r * math.sin(az))


def tilted(az_deg, tilt_deg, up, through):
    """Plane (normal, offset) whose outward normal leans tilt_deg from +-y towards az_deg."""
    az, t = math.radians(az_deg), math.radians(tilt_deg)
    n = (math.sin(t) * math.cos(az), math.cos(t) if up else -math.cos(t), math.sin(t) * math.sin(az))
    return n, dot(n, through)


def facet_planes():
    """[(family, normal, offset)] for all 89 facets, plus derived dimensions."""
    tc, tp = math.tan(math.radians(CROWN_ANGLE)), math.tan(math.radians(PAVILION_ANGLE))
    R, g = GIRDLE_RADIUS, GIRDLE_HALF
    crown = g + (R - TABLE) * tc                  # table plane cuts the bezels at TABLE
    culet = -(g + R * tp)                         # the 8 mains meet on the axis here
    c225, c1125 = math.cos(math.radians(22.5)), math.cos(math.radians(11.25))
    # Star tip: on the ridge where two bezels meet (azimuth 22.5), STAR_LENGTH of the way out.
    table_edge = TABLE * c225
    r_star = table_edge + STAR_LENGTH * (R - table_edge)
    y_star = g + tc * (R - r_star * c225)
    star_angle = math.degrees(math.atan2(crown - y_star, r_star - table_edge))
    # Upper girdle: from the girdle edge at its own azimuth up to the star tip.
    upper_angle = math.degrees(math.atan2(y_star - g, R - r_star * c1125))
    # Lower girdle: from the girdle edge down to the ridge between two mains.
    r_low = R * (1.0 - LOWER_HALF_LENGTH)
    y_low = -g - tp * (R - r_low * c225)
    lower_angle = math.degrees(math.atan2(-g - y_low, R - r_low * c1125))

    planes = [("table", (0.0, 1.0, 0.0), crown)]
    for k in range(8):
        a = 22.5 + 45 * k
        planes.append(("star",) + tilted(a, star_angle, True, polar(table_edge, math.radians(a), crown)))
    for k in range(8):
        a = 45 * k
        planes.append(("bezel",) + tilted(a, CROWN_ANGLE, True, polar(R, math.radians(a), g)))
    for k in range(16):
        a = 11.25 + 22.5 * k
        planes.append(("upper girdle",) + tilted(a, upper_angle, True, polar(R, math.radians(a), g)))
    for k in range(32):
        a = math.radians(11.25 * k)
        planes.append(("girdle", (math.cos(a), 0.0, math.sin(a)), R))
    for k in range(16):
        a = 11.25 + 22.5 * k
        planes.append(("lower girdle",) + tilted(a, lower_angle, False, polar(R, math.radians(a), -g)))
    for k in range(8):
        a = 45 * k
        planes.append(("pavilion",) + tilted(a, PAVILION_ANGLE, False, polar(R, math.radians(a), -g)))
    return planes, dict(crown_height=crown, total_height=crown - culet, star_angle=star_angle,
                        upper_girdle_angle=upper_angle, lower_girdle_angle=lower_angle)


def clip_polygon(poly, n, d):
    """Sutherland-Hodgman against n.p <= d; points within EPS of the plane count as on it."""
    out = []
    for a, b in zip(poly, poly[1:] + poly[:1]):
        da, db = dot(n, a) - d, dot(n, b) - d
        if da <= EPS:
            out.append(a)
        if (da < -EPS and db > EPS) or (da > EPS and db < -EPS):
            if b < a:  # same edge, same float result in both faces that share it
                a, b, da, db = b, a, db, da
            t = da / (da - db)
            out.append(tuple(a[i] + t * (b[i] - a[i]) for i in range(3)))
    # drop consecutive near-duplicates (incl. wrap-around)
    out = [p for i, p in enumerate(out) if not near(p, out[i - 1])] if len(out) > 1 else out
    return out if len(out) >= 3 else None


def cap(points, n):
    """Convex polygon of the on-plane points, counter-clockwise seen along the normal n."""
    pts = []
    for p in points:
        pts += [] if any(near(p, q) for q in pts) else [p]
    if len(pts) < 3:
        return None
    c = tuple(sum(p[i] for p in pts) / len(pts) for i in range(3))
    u = cross(n, (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0))
    u = tuple(x / norm(u) for x in u)
    v = cross(n, u)  # (u, v, n) is right-handed
    pts.sort(key=lambda p: math.atan2(dot(sub(p, c), v), dot(sub(p, c), u)))
    return pts if polygon_area(pts) > EPS else None


def polygon_area(poly):
    s = (0.0, 0.0, 0.0)
    for i in range(1, len(poly) - 1):
        s = tuple(x + y for x, y in zip(s, cross(sub(poly[i], poly[0]), sub(poly[i + 1], poly[0]))))
    return 0.5 * norm(s)


def build_solid(planes):
    """Faces as [family, index, normal, polygon]; starts as an axis-aligned box."""
    faces = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = tuple(sign if i == axis else 0.0 for i in range(3))
            corners = [p for p in itertools.product((-BOX, BOX), repeat=3) if p[axis] == sign * BOX]
            faces.append(["box", len(faces), n, cap(corners, n)])
    for index, (family, n, d) in enumerate(planes):
        kept, on_plane = [], []
        for face in faces:
            poly = clip_polygon(face[3], n, d)
            if poly:
                kept.append(face[:3] + [poly])
                on_plane += [p for p in poly if abs(dot(n, p) - d) <= EPS]
        new = cap(on_plane, n)
        faces = kept + ([[family, index, n, new]] if new else [])
    return faces


def triangulate(faces):
    """Shared vertices (merged within EPS) and fan triangles, outward by the right-hand rule."""
    verts, tris = [], []

    def index(p):
        for i, q in enumerate(verts):
            if near(p, q):
                return i
        verts.append(p)
        return len(verts) - 1

    for _, _, n, poly in faces:
        ids = [index(p) for p in poly]
        ids = [v for i, v in enumerate(ids) if v != ids[i - 1]]
        area = lambda a, b, c: cross(sub(verts[b], verts[a]), sub(verts[c], verts[a]))
        if dot(area(*ids[:3]), n) < 0:
            ids.reverse()
        # Fan from the apex whose thinnest triangle is fattest (collinear points stay shared).
        fans = [ids[k:] + ids[:k] for k in range(len(ids))]
        best = max(fans, key=lambda f: min(norm(area(f[0], f[i], f[i + 1])) for i in range(1, len(f) - 1)))
        tris += [(best[0], best[i], best[i + 1]) for i in range(1, len(best) - 1)]
    return verts, tris


def check(faces, planes, verts, tris):
    ok, expected = True, collections.Counter(family for family, _, _ in planes)
    for family in list(expected) + ["box"]:
        got = len({f[1] for f in faces if f[0] == family})
        good = got == expected[family]
        print(f"  {family:13s} {got:3d} / {expected[family]}{'' if good else '  FAIL'}")
        ok &= good
    edges = collections.Counter(e for a, b, c in tris for e in ((a, b), (b, c), (c, a)))
    closed = all(c == 1 and edges.get((b, a)) == 1 for (a, b), c in edges.items())
    volume = sum(dot(verts[a], cross(verts[b], verts[c])) for a, b, c in tris) / 6.0
    min_area = min((0.5 * norm(cross(sub(verts[b], verts[a]), sub(verts[c], verts[a]))) for a, b, c in tris),
                   default=0.0)
    print(f"  closed (each edge twice, opposite directions): {closed}")
    print(f"  signed volume: {volume:.6f}   smallest triangle area: {min_area:.3e}")
    return ok and closed and volume > 0 and min_area > 1e-8


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "scenes", "assets", "diamond.obj")
    planes, dims = facet_planes()
    faces = build_solid(planes)
    verts, tris = triangulate(faces)
    verts = [tuple(round(c, 9) + 0.0 for c in p) for p in verts]  # check exactly what is written
    for key, value in dims.items():
        print(f"{key}: {value:.6f}")
    print("faces per facet family (survived / planes):")
    if not check(faces, planes, verts, tris):
        sys.exit("gen_diamond: mesh check FAILED, nothing written")
    with open(out, "w") as f:
        f.write("# round brilliant-cut diamond, girdle radius 1, table up (+y)\n")
        f.write("# generated by tools/gen_diamond.py\n")
        f.writelines(f"v {x:.9f} {y:.9f} {z:.9f}\n" for x, y, z in verts)
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in tris)
    print(f"wrote {out}: {len(verts)} vertices, {len(tris)} triangles")


if __name__ == "__main__":
    main()

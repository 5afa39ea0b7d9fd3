//! Mitsuba's `linearcurve` and `bsplinecurve`: tubes swept by a sphere of
//! varying radius along polylines or uniform cubic B-splines (hair, fur,
//! grass, strands).
//!
//! | parameter  | type      | default  | meaning                                              |
//! |------------|-----------|----------|------------------------------------------------------|
//! | `filename` | string    | required | text file of control points, `x y z radius` per line |
//! | `to_world` | transform | identity | moves the control points; radii are not scaled (as Mitsuba) |
//!
//! ```xml
//! <shape type="bsplinecurve">
//!     <string name="filename" value="meshes/strands.txt"/>
//!     <bsdf type="twosided"><bsdf type="diffuse"/></bsdf>
//! </shape>
//! ```
//!
//! The file holds one control point per line; an empty line starts a new
//! curve. A linear curve needs two points or more (a segment between each
//! consecutive pair), a B-spline four or more (a segment per four
//! consecutive points).
//!
//! Geometry, as Embree (which Mitsuba traces curves with) defines it:
//! - a linear segment is the convex hull of the spheres at its two ends: a
//!   cone tangent to both, capped by them (so segments join smoothly at
//!   shared spheres and curves end in round caps);
//! - a B-spline segment is the union of the spheres of radius r(u) centred
//!   on c(u), u ∈ [0, 1], both cubic B-splines of the four control points,
//!   cut by the planes through c(0) and c(1) normal to the curve: segments
//!   meet on those planes (the tangent is continuous), and a B-spline curve
//!   ends open, without the round caps of linear curves.
//!
//! Curves are hollow and seen from outside only: like Mitsuba's (Embree
//! culls the back faces of curves), a ray that starts inside a tube does
//! not meet its wall.
//!
//! Surface parameters follow Mitsuba 3.9: at a point p whose sphere is
//! centred at c(u) with the curve's tangent c′, the normal is (p − c)/|p − c|;
//! uv = (angle around the tangent / 2π, (segment + u) / segment count), the
//! angle measured from a frame whose rotation axis leans towards +z;
//! ∂p/∂u = 2π t̂ × (p − c), ∂p/∂v = segment count · (c′ + r′ n).
//!
//! B-splines are intersected piecewise: each segment is cut into
//! [`BSPLINE_PIECES`] pieces (each a primitive of the BVH), bounded by the
//! round cone through the piece's end spheres padded by its chord error
//! (|c″|·Δu²/8, for centre and radius). From the padded cone's entry the
//! ray marches onto the exact swept surface: sphere-tracing steps on the
//! distance to the nearest sphere (never past the surface), Newton steps
//! where the ray meets it steeply, bisection once a step has crossed it.
//! A hit counts only between the planes normal to the curve at the piece's
//! ends, so pieces and segments join without overlap.
//!
//! Curves cannot emit (Mitsuba's cannot be sampled by area either).

use crate::math::Transform;
use glam::{DVec3, Vec2, Vec3, Vec4, Vec4Swizzles};
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CurveKind {
    Linear,
    BSpline,
}

/// Round cones each B-spline segment is cut into for intersection.
pub const BSPLINE_PIECES: u32 = 8;

#[derive(Clone, Debug)]
pub struct Curves {
    pub kind: CurveKind,
    /// Control points in world space, radius in `w`.
    pub points: Vec<Vec4>,
    /// Index of each segment's first control point.
    pub segments: Vec<u32>,
}

impl Curves {
    pub fn load(path: &Path, to_world: &Transform, kind: CurveKind) -> Result<Curves, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read curve file {}: {e}", path.display()))?;
        Curves::parse(&text, to_world, kind)
    }

    /// Reads `x y z radius` lines, curves separated by empty lines.
    pub fn parse(text: &str, to_world: &Transform, kind: CurveKind) -> Result<Curves, String> {
        let min_points = match kind {
            CurveKind::Linear => 2,
            CurveKind::BSpline => 4,
        };
        let mut points = Vec::new();
        let mut segments = Vec::new();
        let mut start: Option<(usize, usize)> = None; // (first point, its line)
        let finish = |start: Option<(usize, usize)>, points: &Vec<Vec4>, segments: &mut Vec<u32>| -> Result<(), String> {
            if let Some((first, line)) = start {
                let n = points.len() - first;
                if n < min_points {
                    let what = if kind == CurveKind::Linear { "a linear curve" } else { "a B-spline curve" };
                    return Err(format!("line {line}: {what} needs at least {min_points} control points, this one has {n}"));
                }
                for i in first..=points.len() - min_points {
                    segments.push(i as u32);
                }
            }
            Ok(())
        };
        for (i, line) in text.lines().enumerate() {
            let line_no = i + 1;
            let trimmed = line.trim();
            if trimmed.is_empty() {
                finish(start.take(), &points, &mut segments)?;
                continue;
            }
            let fields: Vec<&str> = trimmed.split_whitespace().collect();
            let values: Vec<f32> = fields.iter().filter_map(|f| f.parse::<f32>().ok()).collect();
            if fields.len() != 4 || values.len() != 4 {
                return Err(format!("line {line_no}: expected four numbers `x y z radius`, found \"{trimmed}\""));
            }
            if values.iter().any(|v| !v.is_finite()) || values[3] < 0.0 {
                return Err(format!("line {line_no}: control point needs finite coordinates and a radius ≥ 0, found \"{trimmed}\""));
            }
            if start.is_none() {
                start = Some((points.len(), line_no));
            }
            let p = to_world.point(Vec3::new(values[0], values[1], values[2]));
            if !p.is_finite() {
                return Err(format!("line {line_no}: the control point is not finite after to_world"));
            }
            points.push(p.extend(values[3]));
        }
        finish(start.take(), &points, &mut segments)?;
        if segments.is_empty() {
            return Err("the curve file holds no control points".into());
        }
        if u32::try_from(points.len()).is_err() || segments.len() as u64 * BSPLINE_PIECES as u64 >= u32::MAX as u64 {
            return Err("the curve file holds too many control points".into());
        }
        Ok(Curves { kind, points, segments })
    }

    pub fn segment_count(&self) -> usize {
        self.segments.len()
    }

    /// Primitives the BVH holds: a segment per linear segment, pieces of
    /// B-spline segments.
    pub fn primitive_count(&self) -> usize {
        match self.kind {
            CurveKind::Linear => self.segments.len(),
            CurveKind::BSpline => self.segments.len() * BSPLINE_PIECES as usize,
        }
    }

    /// The segment a BVH primitive belongs to.
    pub fn segment_of(&self, prim: u32) -> u32 {
        match self.kind {
            CurveKind::Linear => prim,
            CurveKind::BSpline => prim / BSPLINE_PIECES,
        }
    }

    /// The four control points of B-spline segment `seg` (or the two of a
    /// linear one, then two copies of the last).
    pub fn control_points(&self, seg: u32) -> [Vec4; 4] {
        let i = self.segments[seg as usize] as usize;
        let at = |k: usize| self.points[(i + k).min(self.points.len() - 1)];
        [at(0), at(1), at(2), at(3)]
    }

    /// The round cone of primitive `prim`: (centre, radius) at both ends and
    /// the segment parameters they stand for.
    pub fn piece(&self, prim: u32) -> (Vec4, Vec4, f32, f32) {
        match self.kind {
            CurveKind::Linear => {
                let i = self.segments[prim as usize] as usize;
                (self.points[i], self.points[i + 1], 0.0, 1.0)
            }
            CurveKind::BSpline => {
                let cps = self.control_points(prim / BSPLINE_PIECES);
                let k = prim % BSPLINE_PIECES;
                let (u0, u1) = (k as f32 / BSPLINE_PIECES as f32, (k + 1) as f32 / BSPLINE_PIECES as f32);
                (bspline(&cps, u0).0, bspline(&cps, u1).0, u0, u1)
            }
        }
    }

    /// World-space box of primitive `prim`.
    pub fn piece_bounds(&self, prim: u32) -> (Vec3, Vec3) {
        match self.kind {
            CurveKind::Linear => {
                let (a, b, _, _) = self.piece(prim);
                (a.xyz().min(b.xyz()) - Vec3::splat(a.w.max(b.w)), a.xyz().max(b.xyz()) + Vec3::splat(a.w.max(b.w)))
            }
            CurveKind::BSpline => {
                // The piece's part of the curve lies in the hull of the
                // segment's control points, its spheres no larger than the
                // largest control radius (B-spline weights are positive and
                // sum to 1); tighter: the piece's box padded by its chord error.
                let cps = self.control_points(prim / BSPLINE_PIECES);
                let (a, b, _, _) = self.piece(prim);
                let e = chord_error(&cps);
                let r = a.w.max(b.w) + e.1;
                (a.xyz().min(b.xyz()) - Vec3::splat(r + e.0), a.xyz().max(b.xyz()) + Vec3::splat(r + e.0))
            }
        }
    }

    /// Lateral area (Σ 2π r̄ · length), for diagnostics and the loader's
    /// sanity check; curves are never sampled by area.
    pub fn area(&self) -> f32 {
        (0..self.primitive_count() as u32)
            .map(|p| {
                let (a, b, _, _) = self.piece(p);
                std::f32::consts::PI * (a.w + b.w) * (b.xyz() - a.xyz()).length().max(a.w + b.w)
            })
            .sum()
    }

    /// What the BVH keeps of primitive `prim` to intersect it.
    pub fn piece_data(&self, prim: u32) -> CurvePiece {
        let (a, b, u0, u1) = self.piece(prim);
        let cps = match self.kind {
            CurveKind::Linear => [a, b, b, b],
            CurveKind::BSpline => self.control_points(prim / BSPLINE_PIECES),
        };
        CurvePiece { kind: self.kind, cps, a, b, u0, u1 }
    }

    /// Nearest entering hit in (0, tmax) of primitive `prim` by the ray
    /// o + t·d: (t, segment parameter), t infinite on a miss.
    pub fn intersect(&self, prim: u32, o: Vec3, d: Vec3, tmax: f32) -> (f32, f32) {
        self.piece_data(prim).intersect(o, d, tmax)
    }

    /// At a hit `p` on primitive `prim` with segment parameter `u`: the
    /// point, normal, uv, ∂p/∂u and ∂p/∂v (see the module documentation).
    pub fn surface(&self, prim: u32, u: f32, p: Vec3) -> (Vec3, Vec3, Vec2, Vec3, Vec3) {
        let seg = self.segment_of(prim);
        let u = if u.is_finite() { u.clamp(0.0, 1.0) } else { 0.0 };
        let (c, dc) = match self.kind {
            CurveKind::Linear => {
                let (a, b, _, _) = self.piece(prim);
                (a.lerp(b, u), b - a)
            }
            CurveKind::BSpline => bspline(&self.control_points(seg), u),
        };
        let (centre, radius, tangent, dradius) = (c.xyz(), c.w, dc.xyz(), dc.w);
        let tangent_dir = tangent.normalize_or(Vec3::X);
        let q = p - centre;
        let n = q.normalize_or_zero();
        let n = if n == Vec3::ZERO { rot_rad_frame(tangent_dir).1 } else { n };
        // Back onto the sphere: removes the error of o + t·d.
        let p = centre + n * radius;
        let (rot, rad) = rot_rad_frame(tangent_dir);
        let mut angle = crate::math::trig::atan2(rot.dot(n), rad.dot(n));
        if angle < 0.0 {
            angle += 2.0 * std::f32::consts::PI;
        }
        let count = self.segments.len() as f32;
        let uv = Vec2::new(angle / (2.0 * std::f32::consts::PI), (seg as f32 + u) / count);
        let dp_du = 2.0 * std::f32::consts::PI * tangent_dir.cross(n * radius);
        let dp_dv = count * (tangent + dradius * n);
        (p, n, uv, dp_du, dp_dv)
    }
}

/// One BVH primitive of a curve: a linear segment, or a piece of a
/// B-spline segment with the segment's control points.
#[derive(Clone, Debug)]
pub struct CurvePiece {
    kind: CurveKind,
    cps: [Vec4; 4],
    a: Vec4,
    b: Vec4,
    u0: f32,
    u1: f32,
}

impl CurvePiece {
    /// Nearest entering hit in (0, tmax): (t, segment parameter).
    pub fn intersect(&self, o: Vec3, d: Vec3, tmax: f32) -> (f32, f32) {
        match self.kind {
            CurveKind::Linear => round_cone(self.a, self.b, o, d, tmax),
            CurveKind::BSpline => bspline_piece(&self.cps, self.a, self.b, self.u0, self.u1, o, d, tmax),
        }
    }
}

/// Mitsuba's frame around a curve's tangent: the rotation axis is +z made
/// perpendicular to the tangent (+y where the tangent is ±z), the radial one
/// their cross product.
fn rot_rad_frame(t: Vec3) -> (Vec3, Vec3) {
    let guide = Vec3::Z;
    let rot = if t.dot(guide).abs() >= 1.0 { Vec3::Y } else { (guide - t * t.dot(guide)).normalize_or(Vec3::Y) };
    (rot, rot.cross(t))
}

/// Point (radius in w) and derivative of a uniform cubic B-spline segment.
pub fn bspline(c: &[Vec4; 4], u: f32) -> (Vec4, Vec4) {
    let (u2, u3) = (u * u, u * u * u);
    let w = [
        (1.0 - u).powi(3),
        3.0 * u3 - 6.0 * u2 + 4.0,
        -3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0,
        u3,
    ];
    let dw = [-3.0 * (1.0 - u) * (1.0 - u), 9.0 * u2 - 12.0 * u, -9.0 * u2 + 6.0 * u + 3.0, 3.0 * u2];
    let p = (c[0] * w[0] + c[1] * w[1] + c[2] * w[2] + c[3] * w[3]) / 6.0;
    let d = (c[0] * dw[0] + c[1] * dw[1] + c[2] * dw[2] + c[3] * dw[3]) / 6.0;
    (p, d)
}

/// Second derivative of the segment (linear in u: its largest value is at
/// an end).
fn bspline_second(c: &[Vec4; 4], u: f32) -> Vec4 {
    c[0] * (1.0 - u) + c[1] * (3.0 * u - 2.0) + c[2] * (1.0 - 3.0 * u) + c[3] * u
}

/// Bound on how far a piece's chord (centres, radii) strays from the curve:
/// |c″|max · Δu²/8 for the centre and the radius.
fn chord_error(c: &[Vec4; 4]) -> (f32, f32) {
    let (a, b) = (bspline_second(c, 0.0), bspline_second(c, 1.0));
    let du = 1.0 / BSPLINE_PIECES as f32;
    let k = du * du / 8.0;
    (a.xyz().length().max(b.xyz().length()) * k, a.w.abs().max(b.w.abs()) * k)
}

/// Relative margin below which a hit counts as the ray's own origin.
const T_EPS: f64 = 1e-5;

/// Entering hit of the convex hull of spheres (a.xyz, a.w) and (b.xyz, b.w):
/// (t, parameter in [0, 1] of the sphere the hit lies on), t infinite on a
/// miss. Computed in f64 (radii are small beside distances).
pub fn round_cone(a: Vec4, b: Vec4, o: Vec3, d: Vec3, tmax: f32) -> (f32, f32) {
    const MISS: (f32, f32) = (f32::INFINITY, 0.0);
    let dlen = d.as_dvec3().length();
    if !(dlen > 0.0) || !dlen.is_finite() {
        return MISS;
    }
    let dn = d.as_dvec3() / dlen;
    let o = o.as_dvec3();
    let (p0, r0, p1, r1) = (a.xyz().as_dvec3(), a.w as f64, b.xyz().as_dvec3(), b.w as f64);
    let tmax = tmax as f64 * dlen;
    let eps = T_EPS * (o.abs().max_element() + p0.abs().max_element() + r0.max(r1)).max(1e-3);
    let mut best = (f64::INFINITY, 0.0f64);
    let axis = p1 - p0;
    let len = axis.length();
    let dr = r1 - r0;
    // One sphere inside the other: the bigger one is the hull.
    if !(len > dr.abs()) {
        let (c, r, v) = if r0 >= r1 { (p0, r0, 0.0) } else { (p1, r1, 1.0) };
        if let Some(t) = sphere_entry(c, r, o, dn) {
            if t > eps && t < tmax {
                return ((t / dlen) as f32, v);
            }
        }
        return MISS;
    }
    let ax = axis / len;
    let s = dr / len; // sine of the cone's half-angle: the normal's component along −axis
    let c2 = 1.0 - s * s;
    // Cone part: (|w|² − y²)(1 − s²) = (r0 + s·y)², y = w·axis, w = o + t·d − p0.
    let wo = o - p0;
    let (yo, yd) = (wo.dot(ax), dn.dot(ax));
    let (ww, wd) = (wo.dot(wo), wo.dot(dn));
    let qa = c2 * (1.0 - yd * yd) - s * s * yd * yd;
    let qb = 2.0 * (c2 * (wd - yo * yd) - s * yd * (r0 + s * yo));
    let qc = c2 * (ww - yo * yo) - (r0 + s * yo) * (r0 + s * yo);
    if qa.abs() > 1e-12 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let q = -0.5 * (qb + disc.sqrt().copysign(qb));
            for t in [q / qa, if q != 0.0 { qc / q } else { q / qa }] {
                if !(t > eps && t < tmax && t < best.0) {
                    continue;
                }
                let y = yo + yd * t;
                if r0 + s * y < 0.0 {
                    continue; // the mirror nappe of the cone
                }
                let v = (y + r0 * s) / (len * c2);
                if !(0.0..=1.0).contains(&v) {
                    continue;
                }
                let w = wo + dn * t;
                let radial = (w - ax * y).normalize_or_zero();
                let n = radial * c2.sqrt() - ax * s;
                if n.dot(dn) < 0.0 {
                    best = (t, v);
                }
            }
        }
    }
    // The caps: each sphere where its normal leans beyond the cone's.
    for (c, r, v, cap) in [(p0, r0, 0.0, -1.0), (p1, r1, 1.0, 1.0)] {
        if let Some(t) = sphere_entry(c, r, o, dn) {
            if t > eps && t < tmax && t < best.0 {
                let n = (o + dn * t - c) / r.max(1e-30);
                if cap * (n.dot(ax) + s) >= 0.0 {
                    best = (t, v);
                }
            }
        }
    }
    if best.0.is_finite() { ((best.0 / dlen) as f32, best.1 as f32) } else { MISS }
}

/// The smaller root of the unit-direction ray with a sphere (its entry),
/// if the ray meets it.
fn sphere_entry(c: DVec3, r: f64, o: DVec3, d: DVec3) -> Option<f64> {
    let oc = o - c;
    let b = oc.dot(d);
    // Stable form: the discriminant from the distance of the line to c.
    let perp = oc - d * b;
    let disc = r * r - perp.dot(perp);
    if disc < 0.0 {
        return None;
    }
    Some(-b - disc.sqrt())
}

/// Entering hit of a B-spline piece: the round cone through the piece's
/// ends, then Newton steps onto the exact swept surface.
#[allow(clippy::too_many_arguments)]
fn bspline_piece(cps: &[Vec4; 4], a: Vec4, b: Vec4, u0: f32, u1: f32, o: Vec3, d: Vec3, tmax: f32) -> (f32, f32) {
    let (err_c, err_r) = chord_error(cps);
    let pad = err_c + err_r;
    // The padded cone holds the exact piece: its entry is at or before the surface's.
    let (t_pad, v_pad) = round_cone(a + Vec4::new(0.0, 0.0, 0.0, pad), b + Vec4::new(0.0, 0.0, 0.0, pad), o, d, tmax);
    if !t_pad.is_finite() {
        return (f32::INFINITY, 0.0);
    }
    let dlen = d.length();
    let dn = d / dlen;
    // Sphere tracing from the padded entry on the exact distance to the
    // piece's spheres (never steps through the surface), then Newton.
    let mut t = t_pad * dlen;
    let mut u = u0 + (u1 - u0) * v_pad;
    let tmax_n = tmax * dlen;
    let tol = 1e-5 * a.w.max(b.w).max(1e-6);
    // The hit at t, if it faces the ray and lies between the planes across
    // the piece's ends: pieces and segments meet on these planes (the
    // tangent is continuous), so a point of a piece's end sphere beyond
    // them lies inside its neighbour, and at the segment's ends the curve
    // is open (no caps).
    let accept = |t: f32, u: f32, p: Vec3, q: Vec3| -> (f32, f32) {
        if !(q.dot(dn) < 0.0 && t > 0.0 && t < tmax_n) {
            return (f32::INFINITY, 0.0);
        }
        for (end, side) in [(u0, -1.0), (u1, 1.0)] {
            let (ce, de) = bspline(cps, end);
            if side * (p - ce.xyz()).dot(de.xyz()) > 0.0 {
                return (f32::INFINITY, 0.0);
            }
        }
        (t / dlen, u)
    };
    let t_limit = (t + 4.0 * (pad + a.w.max(b.w)) + (b.xyz() - a.xyz()).length()).min(tmax_n);
    // A bracket [lo, hi] of the surface once a step has crossed it (the
    // swept surface is concave in places, where Newton steps overshoot).
    let (mut lo, mut hi) = (t, f32::INFINITY);
    for i in 0..64 {
        let p = o + dn * t;
        u = closest_sphere(cps, p, u, u0, u1);
        let (c, _) = bspline(cps, u);
        let q = p - c.xyz();
        let dist = q.length();
        let h = dist - c.w;
        if h.abs() <= tol || (h < 0.0 && i == 0) || hi - lo <= tol {
            // (Inside at the padded entry: the hit is within the padding.)
            return accept(t, u, p, q);
        }
        if h < 0.0 {
            hi = t;
            t = 0.5 * (lo + hi);
            continue;
        }
        lo = t;
        let cos = -(q / dist.max(1e-30)).dot(dn);
        // Newton along the ray where it meets the sphere steeply, else a safe sphere-tracing step.
        t += if cos > 0.25 { h / cos } else { h };
        if t >= hi {
            t = 0.5 * (lo + hi);
        }
        if t > t_limit {
            return (f32::INFINITY, 0.0);
        }
    }
    (f32::INFINITY, 0.0)
}

/// The parameter in [u0, u1] of the sphere nearest to p (minimising
/// |p − c(u)| − r(u)), by Newton steps from `u` on its derivative.
fn closest_sphere(cps: &[Vec4; 4], p: Vec3, mut u: f32, u0: f32, u1: f32) -> f32 {
    for _ in 0..4 {
        let (c, dc) = bspline(cps, u);
        let dd = bspline_second(cps, u);
        let q = p - c.xyz();
        let dist = q.length().max(1e-30);
        // g(u) = d/du (|p − c| − r) = −q·c′/|q| − r′
        let g = -q.dot(dc.xyz()) / dist - dc.w;
        // g′ ≈ (|c′|² − q·c″)/|q| − (q·c′)²/|q|³ − r″
        let qc = q.dot(dc.xyz());
        let gp = (dc.xyz().length_squared() - q.dot(dd.xyz())) / dist - qc * qc / (dist * dist * dist) - dd.w;
        let step = if gp > 1e-12 { g / gp } else { g.signum() * (u1 - u0) * 0.25 };
        let next = (u - step).clamp(u0, u1);
        if (next - u).abs() < 1e-7 {
            return next;
        }
        u = next;
    }
    u
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Pcg32;

    const DOC: &str = "-1    0 -1 0.1\n-0.5  0  1 0.1\n-0.25 0 -1 0.1\n 0    0  1 0.1\n 0.25 0 -1 0.1\n 0.5  0  1 0.1\n 1    0 -1 0.1\n";

    fn first_hit(c: &Curves, o: Vec3, d: Vec3) -> Option<(u32, f32, f32)> {
        (0..c.primitive_count() as u32)
            .map(|p| {
                let (t, u) = c.intersect(p, o, d, f32::INFINITY);
                (p, t, u)
            })
            .filter(|h| h.1.is_finite())
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    #[test]
    fn parses_curves_and_refuses_bad_files() {
        let c = Curves::parse("0 0 0 1\n1 0 0 1\n\n\n0 1 0 .5\n0 2 0 .5\n0 3 0 .5\n", &Transform::IDENTITY, CurveKind::Linear).unwrap();
        assert_eq!(c.segments, vec![0, 2, 3]);
        let b = Curves::parse(DOC, &Transform::IDENTITY, CurveKind::BSpline).unwrap();
        assert_eq!(b.segments, vec![0, 1, 2, 3]);
        for (text, kind, needle) in [
            ("0 0 0 1\n", CurveKind::Linear, "at least 2"),
            ("0 0 0 1\n1 1 1 1\n2 2 2 1\n", CurveKind::BSpline, "at least 4"),
            ("0 0 0\n1 0 0 1\n", CurveKind::Linear, "line 1"),
            ("0 0 0 1\n1 0 x 1\n", CurveKind::Linear, "line 2"),
            ("0 0 0 1\n1 0 nan 1\n", CurveKind::Linear, "finite"),
            ("0 0 0 -1\n1 0 0 1\n", CurveKind::Linear, "radius"),
            ("\n\n", CurveKind::Linear, "no control points"),
        ] {
            let e = Curves::parse(text, &Transform::IDENTITY, kind).unwrap_err();
            assert!(e.contains(needle), "{e}");
        }
    }

    /// A straight segment of equal radii is a capsule: its hits are those of
    /// the cylinder and of the two spheres, in closed form.
    #[test]
    fn a_straight_linear_segment_is_a_capsule() {
        let c = Curves::parse("0 0 0 0.5\n2 0 0 0.5\n", &Transform::IDENTITY, CurveKind::Linear).unwrap();
        let (t, v) = c.intersect(0, Vec3::new(0.5, -3.0, 0.0), Vec3::Y, f32::INFINITY);
        assert!((t - 2.5).abs() < 1e-5 && (v - 0.25).abs() < 1e-5, "{t} {v}");
        // A ray along the axis meets the cap sphere.
        let (t, v) = c.intersect(0, Vec3::new(-3.0, 0.1, 0.0), Vec3::X * 2.0, f32::INFINITY);
        let expect = (3.0 - (0.25f32 - 0.01).sqrt()) / 2.0;
        assert!((t - expect).abs() < 1e-5 && v == 0.0, "{t} {v} {expect}");
        // From inside: culled, as Embree does.
        assert!(c.intersect(0, Vec3::new(1.0, 0.0, 0.0), Vec3::Y, f32::INFINITY).0.is_infinite());
        // Past the ends, and tmax.
        assert!(c.intersect(0, Vec3::new(2.6, -3.0, 0.0), Vec3::Y, f32::INFINITY).0.is_infinite());
        assert!(c.intersect(0, Vec3::new(0.5, -3.0, 0.0), Vec3::Y, 2.0).0.is_infinite());
    }

    /// Hull of two spheres of different radii: every hit lies on the sphere
    /// of its parameter, with the normal facing the ray, and rays aimed at
    /// points inside the hull all hit.
    #[test]
    fn a_tapered_segment_is_the_hull_of_its_spheres() {
        let a = Vec4::new(0.0, 0.0, 0.0, 0.6);
        let b = Vec4::new(2.0, 1.0, 0.5, 0.2);
        let mut rng = Pcg32::new(3, 5);
        let mut hits = 0;
        for _ in 0..2000 {
            let v = rng.next_f32();
            let inner = a.lerp(b, v);
            let dir = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5).normalize();
            let target = inner.xyz() + dir * inner.w * 0.9 * rng.next_f32();
            let o = target - dir * 10.0 + Vec3::new(0.01, 0.02, 0.03);
            let d = (target - o).normalize();
            let (t, v) = round_cone(a, b, o, d, f32::INFINITY);
            assert!(t.is_finite(), "a ray through an inner point must hit");
            hits += 1;
            let p = o + d * t;
            let s = a.lerp(b, v);
            let q = p - s.xyz();
            assert!((q.length() - s.w).abs() < 2e-4, "on the sphere of its parameter: {} vs {}", q.length(), s.w);
            assert!(q.dot(d) < 0.0);
            // No point of the hull before the hit: its nearest sphere is at distance ≥ 0.
            let p_before = o + d * (t - 1e-3);
            let min_dist = (0..=200).map(|k| a.lerp(b, k as f32 / 200.0)).map(|s| (p_before - s.xyz()).length() - s.w).fold(f32::INFINITY, f32::min);
            assert!(min_dist > -1e-4, "a point before the hit is inside: {min_dist}");
        }
        assert_eq!(hits, 2000);
    }

    /// Collinear, evenly spaced control points of equal radius make a
    /// straight B-spline: the tube of a cylinder.
    #[test]
    fn a_straight_bspline_is_a_cylinder() {
        let c = Curves::parse("0 0 0 0.3\n1 0 0 0.3\n2 0 0 0.3\n3 0 0 0.3\n4 0 0 0.3\n", &Transform::IDENTITY, CurveKind::BSpline).unwrap();
        let mut rng = Pcg32::new(7, 1);
        for _ in 0..200 {
            let x = 1.1 + 1.8 * rng.next_f32();
            let z = (rng.next_f32() - 0.5) * 0.55;
            let o = Vec3::new(x, -5.0, z);
            let (_, t, u) = first_hit(&c, o, Vec3::Y).expect("hit");
            let expect = 5.0 - (0.09f32 - z * z).sqrt();
            assert!((t - expect).abs() < 1e-4, "{t} vs {expect}");
            // The parameter maps back to x: c(u) = 1 + seg + u.
            let seg = c.segment_of(first_hit(&c, o, Vec3::Y).unwrap().0);
            assert!((1.0 + seg as f32 + u - x).abs() < 1e-3, "u {u} seg {seg} x {x}");
        }
    }

    /// Measured with Mitsuba 3.9.1 (scalar_rgb `ray_intersect`) on this
    /// straight B-spline: the tube is cut flat across at x = 1 and x = 3
    /// (c(0) of the first segment, c(1) of the last), open at its ends.
    #[test]
    fn a_bspline_ends_open_and_flat() {
        let c = Curves::parse("0 0 0 0.3\n1 0 0 0.3\n2 0 0 0.3\n3 0 0 0.3\n4 0 0 0.3\n", &Transform::IDENTITY, CurveKind::BSpline).unwrap();
        for (x, hits) in [(0.8, false), (0.9, false), (1.02, true), (1.1, true), (2.95, true), (3.05, false), (3.2, false)] {
            assert_eq!(first_hit(&c, Vec3::new(x, -5.0, 0.0), Vec3::Y).is_some(), hits, "x = {x}");
        }
        // Along the axis, through the open end: the inside is culled.
        assert!(first_hit(&c, Vec3::new(-3.0, 0.0, 0.0), Vec3::X).is_none());
        assert!(first_hit(&c, Vec3::new(-3.0, 0.1, 0.0), Vec3::X).is_none());
        let (prim, t, u) = first_hit(&c, Vec3::new(1.0, -5.0, 0.25), Vec3::Y).unwrap();
        assert!((t - 4.834168).abs() < 1e-4, "{t}");
        let (_, n, uv, _, _) = c.surface(prim, u, Vec3::new(1.0, -5.0 + t, 0.25));
        assert!((n - Vec3::new(0.0, -0.552772, 0.833333)).length() < 1e-3 && (uv.x - 0.343215).abs() < 1e-3, "{n} {uv}");
    }

    /// A bent B-spline against brute force: the first point along the ray
    /// where the distance to the union of spheres changes sign.
    #[test]
    fn a_bent_bspline_matches_brute_force() {
        let c = Curves::parse(DOC, &Transform::IDENTITY, CurveKind::BSpline).unwrap();
        let mut rng = Pcg32::new(11, 2);
        // The distance to the uncut union of spheres (a safe marching step),
        // and whether p lies inside the cut tube: inside a sphere of a
        // segment, between that segment's end planes.
        let spheres: Vec<(u32, Vec4)> = (0..c.segment_count() as u32).flat_map(|s| (0..=400).map(move |k| (s, k))).map(|(s, k)| (s, bspline(&c.control_points(s), k as f32 / 400.0).0)).collect();
        let planes: Vec<[(Vec3, Vec3); 2]> = (0..c.segment_count() as u32)
            .map(|s| {
                let cps = c.control_points(s);
                let ((a, da), (b, db)) = (bspline(&cps, 0.0), bspline(&cps, 1.0));
                [(a.xyz(), da.xyz()), (b.xyz(), db.xyz())]
            })
            .collect();
        let sdf = |p: Vec3| spheres.iter().map(|(_, q)| (p - q.xyz()).length() - q.w).fold(f32::INFINITY, f32::min);
        let inside = |p: Vec3| {
            spheres.iter().any(|(s, q)| {
                let [(a, da), (b, db)] = planes[*s as usize];
                (p - q.xyz()).length() < q.w && (p - a).dot(da) >= 0.0 && (p - b).dot(db) <= 0.0
            })
        };
        let mut hits = 0;
        for _ in 0..150 {
            // Aimed near a point of the curve (within 1.3 radii, so some miss).
            let (q, _) = bspline(&c.control_points(rng.next_u32() % 4), rng.next_f32());
            let aim = q.xyz() + Vec3::new(rng.next_f32() - 0.5, 0.0, rng.next_f32() - 0.5) * 2.6 * q.w;
            let o = Vec3::new(aim.x + (rng.next_f32() - 0.5), -3.0, aim.z + (rng.next_f32() - 0.5));
            let d = (aim - o).normalize();
            let found = first_hit(&c, o, d);
            // March the brute-force distance.
            let mut t = 0.0;
            let mut brute = None;
            while t < 6.0 {
                if inside(o + d * t) {
                    // Unless the ray came in through an open end (from inside
                    // the uncut spheres, across an end plane): that is the
                    // inside of the tube, culled.
                    if sdf(o + d * (t - 1e-3)) > -5e-4 {
                        brute = Some(t);
                    }
                    break;
                }
                t += sdf(o + d * t).max(2e-4);
            }
            match (found, brute) {
                (Some((_, t, _)), Some(b)) => {
                    hits += 1;
                    assert!((t - b).abs() < 2e-3, "t {t} brute {b}");
                    assert!(!inside(o + d * (t - 2e-3)), "a point before the hit is inside");
                }
                (None, None) => {}
                (f, b) => {
                    // Only at a silhouette may the two disagree.
                    let closest = (0..600).map(|k| sdf(o + d * (k as f32 * 0.01))).fold(f32::INFINITY, f32::min);
                    assert!(closest.abs() < 2e-3, "found {f:?} brute {b:?} closest approach {closest}; o {o:?} d {d:?}");
                }
            }
        }
        assert!(hits > 30, "{hits}");
    }

    /// Fixture: Mitsuba 3.9.1 (scalar_rgb) `scene.ray_intersect` on the
    /// corpus file `curve_doc.txt` with `to_world` = scale(2, 1, 0.5):
    /// origin, direction, then t, normal, uv.
    #[test]
    fn matches_mitsuba_on_its_documentation_curve() {
        let to_world = Transform::from_matrix(glam::Mat4::from_scale(Vec3::new(2.0, 1.0, 0.5))).unwrap();
        type Row = ([f32; 3], [f32; 3], f32, [f32; 3], [f32; 2]);
        let linear: [Row; 4] = [
            ([0.1, -5.0, 0.3], [0.0, 1.0, 0.0], 4.9, [0.0, -1.0, 0.0], [0.5, 0.533333]),
            ([-2.0, -5.0, -0.5], [0.0, 1.0, 0.0], 4.9, [0.0, -1.0, 0.0], [0.5, 0.0]),
            ([0.0, 0.0, 5.0], [0.0, 0.0, -1.0], 4.4, [0.0, 0.0, 1.0], [0.25, 0.5]),
            ([0.3, 0.05, 5.0], [0.0, 0.0, -1.0], 4.906351, [0.774597, 0.5, 0.387298], [0.166667, 0.57418]),
        ];
        let bspline_rows: [Row; 2] = [
            ([0.0, 0.0, 5.0], [0.0, 0.0, -1.0], 4.733334, [0.0, 0.0, 1.0], [0.25, 0.5]),
            ([0.3, 0.05, 5.0], [0.0, 0.0, -1.0], 4.927533, [0.61176, 0.5, 0.612984], [0.166667, 0.619412]),
        ];
        for (kind, rows) in [(CurveKind::Linear, &linear[..]), (CurveKind::BSpline, &bspline_rows[..])] {
            let c = Curves::parse(DOC, &to_world, kind).unwrap();
            for (o, d, t, n, uv) in rows {
                let (o, d) = (Vec3::from(*o), Vec3::from(*d));
                let (prim, th, u) = first_hit(&c, o, d).unwrap_or_else(|| panic!("{kind:?} {o} misses"));
                assert!((th - t).abs() < 1e-4, "{kind:?} t {th} vs {t}");
                let (_, nh, uvh, _, _) = c.surface(prim, u, o + d * th);
                assert!((nh - Vec3::from(*n)).length() < 1e-3, "{kind:?} n {nh} vs {n:?}");
                assert!((uvh - Vec2::from(*uv)).length() < 1e-3, "{kind:?} uv {uvh} vs {uv:?}");
            }
            // Rays Mitsuba reports as misses.
            for (o, d) in [(Vec3::new(0.0, -5.0, 0.0), Vec3::Y), (Vec3::new(0.0, -5.0, 0.02), Vec3::Y)] {
                assert!(first_hit(&c, o, d).is_none(), "{kind:?} {o}");
            }
        }
    }
}

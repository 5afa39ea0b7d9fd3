//! Solid-angle sampling of rectangular area lights (Ureña, Fajardo and
//! King 2013, "An area-preserving parametrization for spherical
//! rectangles").
//!
//! An `area` emitter on a `rectangle` shape (or any mesh of two triangles
//! forming a rectangle, no per-vertex normals) is sampled for direct light
//! by solid angle: the rectangle seen from the shading point p is a
//! spherical rectangle of solid angle Ω, and the two uniform numbers map,
//! area-preservingly, to a point of it; the density is 1/Ω everywhere.
//! Sampling by area instead (Mitsuba's way) has the solid-angle density
//! ‖x − p‖² / (A cos θ_x), which varies across a light that is large or
//! near, and its variance with it (the 1/r² and cos θ_x of the geometry
//! term); by solid angle only the cosine at p and the radiance remain.
//!
//! No parameter: it is chosen per shading point. Where the light is seen
//! wide from p — A / ‖c − p‖² ≥ [`MIN_AREA_OVER_DIST2`] = 0.3, c its
//! centre, i.e. p within about two light widths of it, where area
//! sampling's 1/r² and cos θ_x vary most — it is sampled by solid angle;
//! elsewhere by area, and so where Ω is tiny (below [`MIN_SOLID_ANGLE`]),
//! p lies in the light's plane or behind it (where nothing is lit either
//! way: the Cornell box's ceiling around its light). The choice is a function of p alone,
//! made the same way when the density of a direction is asked (multiple
//! importance sampling), so sampling and density always agree.
//!
//! Cost: Ω by Van Oosterom and Strackee's formula (four square roots, one
//! arc tangent), Ureña's k by its cosine and sine (no arc cosine), and the
//! sample by one sine-cosine and a chain of four square roots and four
//! divisions. The density at a BSDF-sampled hit of the light computes Ω
//! alone. The threshold was chosen by efficiency, 1 / (relMSE × CPU s),
//! sobol, 64 spp, max_depth 8, against 4096-spp references, 2 threads,
//! on a loaded machine (medians of 3): on the Cornell box (light seen at
//! A/d² ≤ 0.3 from every surface it lights) solid angle everywhere it was
//! above 0.01 cut relMSE by 6 % for 16 % more CPU (128²: efficiency 649
//! against 724 by area), and on the many-light scene by 5 % for 4 %
//! more CPU (128²: 754 against 747, flat within noise from 0.01 to area
//! sampling). At 0.3 the Cornell box is sampled by area exactly (704–724)
//! and the many-light scene nearly so (739), and only lights seen close,
//! where the variance of area sampling grows without bound, get
//! solid-angle sampling.
//!
//! ```xml
//! <shape type="rectangle">
//!     <emitter type="area"><rgb name="radiance" value="10"/></emitter>
//! </shape>
//! ```

use crate::geometry::mesh::Mesh;
use crate::geometry::sphere::DirectionSample;
use glam::{Vec2, Vec3};

/// Below this A / d² (area over the squared distance to the centre, about
/// the solid angle) area sampling is used.
pub const MIN_AREA_OVER_DIST2: f32 = 0.3;
/// Below this solid angle (sr) area sampling is used.
pub const MIN_SOLID_ANGLE: f32 = 1e-4;

/// A rectangle: corner `s`, unit edge directions `ex`, `ey` (orthogonal)
/// with lengths `w`, `h`, and the emitting side's geometric normal `n`.
#[derive(Clone, Copy, Debug)]
pub struct Rectangle {
    s: Vec3,
    ex: Vec3,
    ey: Vec3,
    ez: Vec3,
    w: f32,
    h: f32,
    n: Vec3,
    center: Vec3,
    area: f32,
    /// Each triangle's plane: a corner and its normal (the emitting side's;
    /// equal to `n` up to `from_mesh`'s tolerance).
    planes: [(Vec3, Vec3); 2],
    /// |s|'s largest component plus w and h: the scale of the rounding in
    /// a sampled point (see [`Rectangle::behind`]).
    extent: f32,
}

/// The spherical rectangle seen from a point, in the rectangle's frame
/// (z flipped so that the rectangle lies at z0 < 0).
#[derive(Clone, Copy, Debug)]
pub struct Spherical {
    o: Vec3,
    x0: f32,
    x1: f32,
    y0: f32,
    y1: f32,
    z0: f32,
    b0: f32,
    b1: f32,
    /// 1 − b0².
    q: f32,
    /// cos k and sin k, k = 2π − γ2 − γ3 (Ureña et al.'s k).
    cos_k: f32,
    sin_k: f32,
    /// The solid angle Ω.
    pub solid_angle: f32,
}

impl Rectangle {
    /// The rectangle a mesh is, if it is one: four vertices, two triangles
    /// covering the parallelogram p0 p1 p2 p3 with orthogonal edges and one
    /// normal, and no per-vertex normals.
    pub fn from_mesh(m: &Mesh) -> Option<Rectangle> {
        if m.positions.len() != 4 || m.triangles.len() != 2 || m.normals.is_some() {
            return None;
        }
        let p = &m.positions;
        let (e1, e2) = (p[1] - p[0], p[3] - p[0]);
        let (w, h) = (e1.length(), e2.length());
        if !(w > 0.0 && h > 0.0 && w.is_finite() && h.is_finite()) {
            return None;
        }
        let scale = w.max(h);
        let area = e1.cross(e2).length();
        let (n0, n1) = (m.face_normal(0), m.face_normal(1));
        let rectangle = (p[0] + p[2] - p[1] - p[3]).length() <= 1e-5 * scale
            && e1.dot(e2).abs() <= 1e-5 * w * h
            && n0.dot(n1) > 1.0 - 1e-5
            && (m.area() - area).abs() <= 1e-4 * area;
        if !rectangle {
            return None;
        }
        let (ex, ey) = (e1 / w, e2 / h);
        let planes = [(m.vertices(0)[0], n0), (m.vertices(1)[0], n1)];
        let extent = p[0].abs().max_element() + w + h;
        Some(Rectangle { s: p[0], ex, ey, ez: ex.cross(ey), w, h, n: n0, center: (p[0] + p[2]) * 0.5, area, planes, extent })
    }

    /// The rectangle in its own frame as seen from `o` (x0, y0, z0 < 0)
    /// and its solid angle Ω, or `None` where area sampling is used (see
    /// the module documentation). Ω by Van Oosterom and Strackee's formula
    /// for the two triangles (s, s+w, s+w+h) and (s, s+w+h, s+h), summed as
    /// one angle: tan(Ω_i/2) = N / D_i with N the triple product of the
    /// corners (|z0|·w·h for both), so Ω/2 = arg((D1 + iN)(D2 + iN)): four
    /// square roots and one arc tangent, exact to rounding for small Ω
    /// too (no difference of angles near 2π).
    /// Its callers ask [`Rectangle::seen_wide`] first.
    #[inline]
    fn local(&self, o: Vec3) -> Option<(f32, f32, f32, f32)> {
        let d = self.s - o;
        let (x0, y0, z) = (d.dot(self.ex), d.dot(self.ey), d.dot(self.ez).abs());
        if !(z > 1e-6 * (self.w + self.h)) {
            return None;
        }
        let (x1, y1, z2) = (x0 + self.w, y0 + self.h, z * z);
        let (xx0, xx1, yy0, yy1, x01, y01) = (x0 * x0, x1 * x1, y0 * y0, y1 * y1, x0 * x1, y0 * y1);
        // Corner distances a = (x0, y0), b = (x1, y0), c = (x1, y1), d = (x0, y1).
        let (la, lb, lc, ld) = ((xx0 + yy0 + z2).sqrt(), (xx1 + yy0 + z2).sqrt(), (xx1 + yy1 + z2).sqrt(), (xx0 + yy1 + z2).sqrt());
        let ac = x01 + y01 + z2;
        let d1 = la * lb * lc + (x01 + yy0 + z2) * lc + ac * lb + (xx1 + y01 + z2) * la;
        let d2 = la * lc * ld + ac * ld + (xx0 + y01 + z2) * lc + (x01 + yy1 + z2) * la;
        let n = z * self.w * self.h;
        let solid_angle = 2.0 * crate::math::trig::atan2(n * (d1 + d2), d1 * d2 - n * n);
        if !(solid_angle >= MIN_SOLID_ANGLE && solid_angle.is_finite()) {
            return None;
        }
        Some((x0, y0, -z, solid_angle))
    }

    /// The solid angle of the rectangle seen from `o`, where it is sampled
    /// by solid angle ([`Rectangle::spherical`] is `Some` exactly there).
    #[inline(always)]
    pub fn solid_angle(&self, o: Vec3) -> Option<f32> {
        if !self.seen_wide(o) {
            return None;
        }
        self.local(o).map(|l| l.3)
    }

    /// Whether the rectangle is seen wide enough from `o` to be sampled by
    /// solid angle (the first test of `spherical` and `solid_angle`,
    /// inlined into every caller: from most shading points it fails, and
    /// then costs no call), and not from behind its emitting side
    /// (`behind`): no point is lit from there whichever way it is sampled,
    /// and area sampling finds that out more cheaply.
    #[inline(always)]
    pub fn seen_wide(&self, o: Vec3) -> bool {
        !(self.area < MIN_AREA_OVER_DIST2 * (self.center - o).length_squared()) && !self.behind(o)
    }

    /// Whether `o` lies behind the emitting side of both triangles' planes
    /// by more than the rounding of a sampled point and of its direction
    /// from `o` (10⁻⁴ of their coordinates' scale, some 10³ ulps): every
    /// direction from `o` to the light then meets its back, so a sample by
    /// solid angle (which tests the side against `n`, triangle 0's normal)
    /// and one by area (against its triangle's) are both refused: no
    /// light, no shadow ray. The choice between them changes no image, and
    /// next-event estimation can skip such points. (In the Cornell box the
    /// ceiling, 0.01 above the light, sees it wide and is behind it.)
    #[inline(always)]
    pub fn behind(&self, o: Vec3) -> bool {
        let margin = 1e-4 * (self.extent + o.abs().max_element());
        self.planes.iter().all(|&(a, n)| (a - o).dot(n) > margin)
    }

    /// The spherical rectangle seen from `o`, or `None` where area sampling
    /// is used (see the module documentation).
    #[inline(always)]
    pub fn spherical(&self, o: Vec3) -> Option<Spherical> {
        if !self.seen_wide(o) {
            return None;
        }
        self.spherical_wide(o)
    }

    #[inline(never)]
    fn spherical_wide(&self, o: Vec3) -> Option<Spherical> {
        let (x0, y0, z0, solid_angle) = self.local(o)?;
        let (x1, y1) = (x0 + self.w, y0 + self.h);
        // z components of the unit normals of the four edges' planes
        // through o (their other components are products of z0 with these
        // over the same lengths, so the dot products of neighbours are
        // products of the z components): the interior angles γ_i have
        // cos γ_i = −n_i n_(i+1), and k = 2π − γ2 − γ3 is needed as its
        // cosine and sine only, by the angle-sum identities (no arc cosine).
        let nz = |a: f32, b: f32| b / (a * a + b * b).sqrt();
        let (n0, n2, n3) = (nz(z0, -y0), nz(z0, y1), nz(z0, -x0));
        let (c2, c3) = ((-n2 * n3).clamp(-1.0, 1.0), (-n3 * n0).clamp(-1.0, 1.0));
        let (s2, s3) = ((1.0 - c2 * c2).max(0.0).sqrt(), (1.0 - c3 * c3).max(0.0).sqrt());
        // cos k = cos(γ2 + γ3), sin k = −sin(γ2 + γ3).
        let (cos_k, sin_k) = (c2 * c3 - s2 * s3, -(s2 * c3 + c2 * s3));
        let q = z0 * z0 / (z0 * z0 + y0 * y0);
        Some(Spherical { o, x0, x1, y0, y1, z0, b0: n0, b1: n2, q, cos_k, sin_k, solid_angle })
    }

    /// A point of the rectangle uniform in solid angle seen from `sp.o`.
    #[inline]
    pub fn sample(&self, sp: &Spherical, u: Vec2) -> Option<DirectionSample> {
        // The x of the point: the sub-rectangle [x0, xu] has solid angle
        // u.x Ω; au = u.x Ω + k, its cosine and sine by the angle sum.
        let (sin_u, cos_u) = (u.x * sp.solid_angle).sin_cos();
        let (cos_au, sin_au) = (cos_u * sp.cos_k - sin_u * sp.sin_k, sin_u * sp.cos_k + cos_u * sp.sin_k);
        // Ureña et al.'s fu = A / sin au, cu = sign(fu) / √(fu² + b0²) and
        // xu = −cu z0 / √(1 − cu²), folded into one square root and one
        // division: xu = −z0 sin au / (sign(A) √(A² − q sin² au)), with
        // A = b0 cos au − b1 and q = 1 − b0² (kept exact as z0²/(z0² + y0²)).
        let a = cos_au * sp.b0 - sp.b1;
        let root = (a * a - sp.q * sin_au * sin_au).max(0.0).sqrt();
        let xu = (-(sp.z0 * sin_au) / root.copysign(a)).clamp(sp.x0, sp.x1);
        let xu = if xu.is_finite() { xu } else { sp.x0 };
        // The y: uniform in the height of the projection onto the unit
        // sphere; yv = hv dd / √(1 − hv²) as hv √(dd² / (1 − hv²)).
        let dd2 = xu * xu + sp.z0 * sp.z0;
        let h0 = sp.y0 / (dd2 + sp.y0 * sp.y0).sqrt();
        let h1 = sp.y1 / (dd2 + sp.y1 * sp.y1).sqrt();
        let hv = h0 + u.y * (h1 - h0);
        let hv2 = hv * hv;
        let yv = if hv2 < 1.0 - 1e-6 { hv * (dd2 / (1.0 - hv2)).sqrt() } else { sp.y1 };
        let yv = if yv.is_finite() { yv.clamp(sp.y0, sp.y1) } else { sp.y1 };
        // On the rectangle itself (not through o), so the point is on the plane.
        let p = self.s + self.ex * (xu - sp.x0) + self.ey * (yv - sp.y0);
        let v = p - sp.o;
        let dist = v.length();
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        Some(DirectionSample { p, n: self.n, sh_n: self.n, d: v / dist, dist, pdf: 1.0 / sp.solid_angle })
    }

    pub fn normal(&self) -> Vec3 {
        self.n
    }

    /// The corners, counter-clockwise about `ez` = ex × ey.
    pub fn corners(&self) -> [Vec3; 4] {
        let (a, b) = (self.ex * self.w, self.ey * self.h);
        [self.s, self.s + a, self.s + a + b, self.s + b]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{PI, Pcg32, Transform};
    use glam::Mat4;

    fn tf(m: Mat4) -> Transform {
        Transform::from_matrix(m).expect("invertible")
    }

    fn rect(m: Mat4) -> Rectangle {
        Rectangle::from_mesh(&Mesh::rectangle(&tf(m), false)).expect("a rectangle")
    }

    /// ∫ cos θ_x / ‖x − o‖² dA over the part [a0, a1] × [b0, b1] (in edge
    /// units, 0..1) of the rectangle, by the midpoint rule.
    fn solid_angle_of(r: &Rectangle, o: Vec3, (a0, a1): (f32, f32), (b0, b1): (f32, f32), n: usize) -> f64 {
        let mut sum = 0.0f64;
        let [s, ..] = r.corners();
        for i in 0..n {
            for j in 0..n {
                let a = a0 + (a1 - a0) * (i as f32 + 0.5) / n as f32;
                let b = b0 + (b1 - b0) * (j as f32 + 0.5) / n as f32;
                let x = s + r.ex * (a * r.w) + r.ey * (b * r.h);
                let v = x - o;
                let d2 = v.length_squared() as f64;
                sum += (r.ez.dot(v).abs() as f64) / d2.sqrt() / d2;
            }
        }
        sum * ((a1 - a0) * r.w * (b1 - b0) * r.h) as f64 / (n * n) as f64
    }

    fn test_rects() -> Vec<Rectangle> {
        vec![
            // The Cornell box's light.
            rect(Mat4::from_translation(Vec3::new(0.0, 0.99, 0.01)) * Mat4::from_rotation_x(PI / 2.0) * Mat4::from_scale(Vec3::new(0.23, 0.19, 0.19))),
            rect(Mat4::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.6) * Mat4::from_scale(Vec3::new(2.0, 0.5, 1.0))),
        ]
    }

    fn points(r: &Rectangle, rng: &mut Pcg32) -> Vec<Vec3> {
        let mut out = vec![];
        while out.len() < 12 {
            let o = r.center + Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * 3.0;
            if r.spherical(o).is_some() {
                out.push(o);
            }
        }
        out
    }

    #[test]
    fn from_mesh_finds_rectangles_only() {
        assert!(Rectangle::from_mesh(&Mesh::rectangle(&tf(Mat4::from_scale(Vec3::new(2.0, 3.0, 1.0))), false)).is_some());
        // A sheared rectangle is a parallelogram, not a rectangle.
        let shear = tf(Mat4::from_cols_array(&[1.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]));
        assert!(Rectangle::from_mesh(&Mesh::rectangle(&shear, false)).is_none());
        assert!(Rectangle::from_mesh(&Mesh::cube(&Transform::IDENTITY, false)).is_none());
        // Flipped normals: the emitting side is the other one.
        let r = Rectangle::from_mesh(&Mesh::rectangle(&Transform::IDENTITY, true)).expect("rectangle");
        assert!((r.normal() + Vec3::Z).length() < 1e-6);
    }

    /// From behind the emitting side (beyond the margin) the rectangle is
    /// not sampled by solid angle, and there a sample by solid angle would
    /// have met the back every time: the choice changes no image. From the
    /// front it still is, and the Cornell box's ceiling is behind its light.
    #[test]
    fn no_solid_angle_sampling_from_behind() {
        let mut rng = Pcg32::new(7, 11);
        for r in test_rects() {
            let (mut behind, mut front) = (0, 0);
            while behind < 40 || front < 40 {
                let o = r.center + Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * 3.0;
                let wide_by_area = !(r.area < MIN_AREA_OVER_DIST2 * (r.center - o).length_squared());
                let Some(sp) = r.spherical_wide(o) else { continue };
                if !wide_by_area {
                    continue;
                }
                if r.behind(o) {
                    behind += 1;
                    assert!(r.spherical(o).is_none() && r.solid_angle(o).is_none(), "{o:?}");
                    for _ in 0..64 {
                        if let Some(ds) = r.sample(&sp, Vec2::new(rng.next_f32(), rng.next_f32())) {
                            assert!(ds.sh_n.dot(-ds.d) <= 0.0, "a point lit from behind, {o:?}");
                        }
                    }
                } else if (o - r.s).dot(r.n) > 0.0 {
                    front += 1;
                    assert!(r.spherical(o).is_some(), "{o:?}");
                }
            }
        }
        let cornell = &test_rects()[0];
        assert!(cornell.behind(Vec3::new(0.1, 1.0, -0.05)) && !cornell.seen_wide(Vec3::new(0.1, 1.0, -0.05)));
        assert!(cornell.seen_wide(Vec3::new(0.1, 0.7, -0.05)));
    }

    #[test]
    fn solid_angle_matches_the_integral() {
        let mut rng = Pcg32::new(3, 5);
        for r in test_rects() {
            for o in points(&r, &mut rng) {
                let sp = r.spherical(o).expect("spherical");
                let numeric = solid_angle_of(&r, o, (0.0, 1.0), (0.0, 1.0), 400);
                assert!((sp.solid_angle as f64 - numeric).abs() < 2e-3 * numeric + 1e-5, "{} vs {numeric} at {o:?}", sp.solid_angle);
            }
        }
    }

    /// Chi-square test of the sampled points over an 8×8 grid of cells of
    /// the rectangle: each cell's expected share is its solid angle over Ω
    /// (the density 1/Ω integrates to one over the spherical rectangle).
    #[test]
    fn samples_are_uniform_in_solid_angle() {
        const N: usize = 200_000;
        const G: usize = 8;
        let mut rng = Pcg32::new(9, 1);
        for r in test_rects() {
            for o in points(&r, &mut rng).into_iter().take(4) {
                let sp = r.spherical(o).expect("spherical");
                let mut counts = [0usize; G * G];
                let [s, ..] = r.corners();
                for _ in 0..N {
                    let ds = r.sample(&sp, Vec2::new(rng.next_f32(), rng.next_f32())).expect("sample");
                    assert_eq!(ds.pdf, 1.0 / sp.solid_angle);
                    assert!((ds.d - (ds.p - o).normalize()).length() < 1e-4);
                    let q = ds.p - s;
                    let (a, b) = (q.dot(r.ex) / r.w, q.dot(r.ey) / r.h);
                    assert!((-1e-4..=1.0001).contains(&a) && (-1e-4..=1.0001).contains(&b) && r.ez.dot(q).abs() < 1e-4, "{a} {b}");
                    let (i, j) = (((a * G as f32) as usize).min(G - 1), ((b * G as f32) as usize).min(G - 1));
                    counts[j * G + i] += 1;
                }
                let mut chi2 = 0.0;
                let mut total = 0.0;
                for j in 0..G {
                    for i in 0..G {
                        let cell = (i as f32 / G as f32, (i + 1) as f32 / G as f32);
                        let row = (j as f32 / G as f32, (j + 1) as f32 / G as f32);
                        let share = solid_angle_of(&r, o, cell, row, 40) / sp.solid_angle as f64;
                        total += share;
                        let expected = share * N as f64;
                        chi2 += (counts[j * G + i] as f64 - expected).powi(2) / expected;
                    }
                }
                assert!((total - 1.0).abs() < 3e-3, "cells' solid angles sum to {total} Ω");
                // 63 degrees of freedom: mean 63, sd 11.2; 120 is 5 sd out.
                assert!(chi2 < 120.0, "chi² = {chi2} at {o:?}");
            }
        }
    }

    /// Irradiance from a rectangle of radiance 1 at o with normal n, by
    /// Lambert's polygon formula: E = ½ Σ_i Θ_i (n · û_i), Θ_i the angle
    /// between the directions to corners i and i+1, û_i the unit normal of
    /// their plane (corners clockwise as seen from o).
    fn lambert(corners: [Vec3; 4], o: Vec3, n: Vec3) -> f64 {
        let v: Vec<glam::DVec3> = corners.iter().map(|c| (*c - o).as_dvec3().normalize()).collect();
        let mut e = 0.0;
        for i in 0..4 {
            let (a, b) = (v[i], v[(i + 1) % 4]);
            let theta = a.dot(b).clamp(-1.0, 1.0).acos();
            e += theta * n.as_dvec3().dot(a.cross(b).normalize());
        }
        (0.5 * e).abs()
    }

    #[test]
    fn irradiance_matches_lamberts_formula() {
        let mut rng = Pcg32::new(11, 4);
        let mut tested = 0;
        for r in test_rects() {
            for o in points(&r, &mut rng) {
                let sp = r.spherical(o).expect("spherical");
                // A normal facing the light (the polygon formula needs the
                // whole rectangle above the surface).
                let n = (r.center - o).normalize();
                let n = (n + Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * 0.2).normalize();
                if r.corners().iter().any(|c| (*c - o).dot(n) <= 0.0) {
                    continue;
                }
                let expected = lambert(r.corners(), o, n);
                tested += 1;
                const N: usize = 100_000;
                let (mut sum, mut sum2) = (0.0f64, 0.0f64);
                for _ in 0..N {
                    let ds = r.sample(&sp, Vec2::new(rng.next_f32(), rng.next_f32())).expect("sample");
                    let x = (ds.d.dot(n).max(0.0) / ds.pdf) as f64;
                    sum += x;
                    sum2 += x * x;
                }
                let mean = sum / N as f64;
                let se = ((sum2 / N as f64 - mean * mean).max(0.0) / N as f64).sqrt();
                assert!((mean - expected).abs() < 5.0 * se + 1e-4 * expected, "E {mean} ± {se} vs Lambert {expected} at {o:?}");
            }
        }
        assert!(tested >= 8, "only {tested} points tested");
    }
}

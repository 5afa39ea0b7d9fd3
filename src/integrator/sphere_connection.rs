//! Light paths joined to a pinhole camera THROUGH a smooth dielectric
//! sphere (a drop of water, a glass bead), in closed form: the special case
//! of manifold next-event estimation (Hanika et al. 2015) in which the
//! sphere's symmetry gives the specular chain's solution directly.
//!
//! `ptracer` uses it behind its `sphere_connection` parameter:
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `sphere_connection` | boolean | false | where a light path meets a `sphere` with a smooth `dielectric` BSDF from outside, also send its light to the camera along every specular chain through that sphere: external reflection and 1 to [`MAX_CHORDS`] chords (0 to 5 internal reflections), capped by `max_depth` |
//!
//! ```xml
//! <integrator type="ptracer">
//!     <integer name="max_depth" value="12"/>
//!     <boolean name="sphere_connection" value="true"/>
//! </integrator>
//! ```
//!
//! The chain. A ray of direction d meets a sphere (centre c, radius a,
//! relative index n) at impact parameter b = a·x (x = sin i, i the angle of
//! incidence, sin i = n sin r). With p chords inside (p = 0: external
//! reflection; p = 1: straight through; p = 2: one internal reflection, the
//! primary bow; p = 3: the secondary; …) it leaves in the plane of d and the
//! impact point, its direction turned by ψ_p from d, its exit point on the
//! circle at polar angle φ_p (measured from d, same sense):
//!
//! ψ₀ = π − 2i,  ψ_p = −(2i − 2p·r + (p − 1)π),  φ_p = π − i − p(π − 2r),
//!
//! with the unpolarised Fresnel factor R(i) for p = 0 and
//! (1 − R)² R^(p−1) otherwise (R(r) inside equals R(i) outside), times the
//! BSDF's `specular_reflectance` / `specular_transmittance` scales. No η²:
//! a light path carries flux, and flux crosses an interface with T = 1 − R.
//!
//! The change of variables, at finite distance. The light path arrives
//! from a point y (the emitter point it was sampled at, or its last
//! non-delta scattering vertex), D = ‖c − y‖ from the centre; given y, its direction
//! ω was sampled with a density p(ω) and it carries β, so the light y sends
//! out has intensity I(ω) = β p(ω). It hits the sphere when ω lies in the
//! sphere's cone, of solid angle Ω = 2π(1 − √(1 − a²/D²)). The estimator
//! splats β · K / Ω, with K the irradiance at the pinhole per unit intensity
//! of y: its mean given y is ∫_cone β p dω · K / Ω = Ī K, the light that
//! reaches the pinhole through the sphere from y, up to the variation of I
//! across the cone (I at a root differs from the cone's mean Ī by about
//! a/D times I's relative slope: tan θ · a/D for a Lambertian emitter
//! seen at θ from its normal, and it averages out over the emitter).
//!
//! K, exactly. Every ray from y through the sphere lies in a plane through
//! the axis y → c (unit d); the pinhole's plane is the one holding the eye,
//! and the eye lies ρ from the axis. A ray at angle γ from the axis has
//! impact parameter D sin γ = a x; it leaves at the exit point at polar
//! angle φ_p(x) + γ from d, turned to ψ_p(x) + γ, both in its plane. It
//! passes through the eye when g(x) = ψ_p(x) + γ(x) − τ(x) = 2πm, τ the
//! angle of (eye − e(x)) from d; g is monotone but for one extremum (the
//! caustic at this distance, near Descartes' point), and each piece is
//! solved by Newton steps in a bisection bracket. The ray tube around a
//! root: the solid angle at y is dω = sin γ dγ dα = a² x dx dα / (D² cos γ)
//! (γ′ = a / (D cos γ)), carrying the Fresnel fraction F(x) of the chain;
//! at the eye it spans |M| dx within the plane, where
//!
//! M = ‖eye − e‖ g′(x) = a (φ′ + γ′) cos(φ − ψ) + ‖eye − e‖ (ψ′ + γ′),
//!
//! (the exit point's motion across the ray plus the turn of the direction
//! times the distance), and ρ dα across it (the rotation about the axis
//! moves the eye's copy by ρ dα). So
//!
//! K = F(x) a² x / (D² cos γ |M| ρ),   β K / Ω = β F x (1 + √(1 − a²/D²)) / (2π cos γ |M| ρ),
//!
//! splatted with the camera's importance at the film position of e, if e
//! sees the camera (a shadow ray). Far away (D, ‖eye − e‖ → ∞; ρ → L sin Θ,
//! M → L ψ′) this is F x / (π |sin ψ| |ψ′|) / L² = J / L²: the far-field
//! intensity per unit flux on the cross-section,
//!
//! J = F(x) · x / (π |sin ψ| |ψ′(x)|)   [1/sr],
//!
//! the role `f·|cos θ|` plays at an ordinary vertex of `ptracer`. A light
//! at infinity (a `directional` or environment emitter) sends a parallel
//! beam (D = ∞, γ = 0, the axis d the path's direction); that case keeps
//! the earlier root search (`connect_beam`: roots aimed from the centre,
//! refined by fixed-point rounds from the exit point, a root dropped if they
//! do not settle, which happens only at the caustic's edge). The light-side
//! γ′ = a/D matters as much as the camera side: near the bow ψ′ is small,
//! and a parallel-beam Jacobian over-counted the primary bow of a drop of
//! radius 0.3, 20 from a disk light and 10 from the camera, by 7–10 %.
//!
//! Wavelengths. In spectral mode a dispersive sphere has its own n(λ), roots
//! and exit points for each of the path's wavelengths: each is splatted
//! separately, at its own exit point, before the light path (which carries
//! on through the sphere) drops its secondary wavelengths at the first
//! dispersive refraction. (A drop that is smaller than a pixel would let one
//! use the centre; the exit point costs nothing more and keeps large
//! spheres right.) Polarised modes use the unpolarised Fresnel factors.
//!
//! No double counting: a pinhole cannot be hit, so no light path `ptracer`
//! traces ever reaches the camera through a delta surface; the ordinary
//! continuation through the sphere is still traced, and counted where it
//! meets a non-delta surface or another sphere. Every path whose last
//! scattering before the camera is such a sphere is counted once, at that
//! sphere.
//!
//! Limits: the sphere must be an analytic `sphere` (placed directly or by
//! an `instance` with a uniform scale; the instanced sphere's size is found
//! by a ray along the inward normal), not flipped, with a plain smooth
//! `dielectric` BSDF, met from outside. The point-source model is exact for
//! light sampled at a point with a smooth directional density (area, point
//! and spot lights; a rough scattering vertex) up to the variation of that
//! density across the sphere's cone. After a delta vertex (a mirror, another
//! sphere: drop-to-drop light) the beam's virtual source is not known
//! (behind a flat mirror it lies farther back, behind a drop near its
//! focus), and the connection takes a parallel beam along the path's
//! direction, as for a light at infinity: approximate to the order of the
//! sphere's radius over the distance to that source.

use crate::bsdf::{Bsdf, Dielectric};
use crate::geometry::ray::offset_origin;
use crate::geometry::{Ray, ShapeGeometry, SurfaceInteraction};
use crate::math::SHADOW_EPSILON;
use crate::scene::Scene;
use crate::sensor::Perspective;
use crate::spectrum::{Rgb, Spectrum};
use glam::{DVec3, Vec2, Vec3};
use std::f64::consts::PI;

/// Most chords followed through the sphere (5 internal reflections: the
/// sixth order's Fresnel weight R⁵ is below 1e-6 for water).
pub const MAX_CHORDS: u32 = 6;

/// Turn of the direction after `p` chords at x = sin i (see the module doc).
#[inline]
pub fn psi(p: u32, n: f64, x: f64) -> f64 {
    let i = x.clamp(0.0, 1.0).asin();
    if p == 0 {
        return PI - 2.0 * i;
    }
    let r = (x / n).clamp(-1.0, 1.0).asin();
    -(2.0 * i - 2.0 * p as f64 * r + (p as f64 - 1.0) * PI)
}

/// dψ/dx.
#[inline]
pub fn dpsi_dx(p: u32, n: f64, x: f64) -> f64 {
    let cos_i = (1.0 - x * x).max(1e-300).sqrt();
    if p == 0 {
        return -2.0 / cos_i;
    }
    let n_cos_r = (n * n - x * x).max(1e-300).sqrt();
    -(2.0 / cos_i - 2.0 * p as f64 / n_cos_r)
}

/// dφ/dx.
#[inline]
pub fn dphi_dx(p: u32, n: f64, x: f64) -> f64 {
    let cos_i = (1.0 - x * x).max(1e-300).sqrt();
    let n_cos_r = (n * n - x * x).max(1e-300).sqrt();
    -1.0 / cos_i + 2.0 * p as f64 / n_cos_r
}

/// Polar angle of the exit point, from d.
#[inline]
pub fn phi_exit(p: u32, n: f64, x: f64) -> f64 {
    let i = x.clamp(0.0, 1.0).asin();
    let r = (x / n).clamp(-1.0, 1.0).asin();
    PI - i - p as f64 * (PI - 2.0 * r)
}

/// The unpolarised Fresnel weight of the chain (scales apart): R(i) for
/// p = 0, (1 − R)² R^(p−1) otherwise.
pub fn fresnel_chain(p: u32, n: f64, x: f64) -> f64 {
    let cos_i = (1.0 - x * x).max(0.0).sqrt();
    let r = crate::bsdf::fresnel::fresnel_dielectric(cos_i as f32, n as f32).r as f64;
    if p == 0 {
        r
    } else {
        (1.0 - r) * (1.0 - r) * r.powi(p as i32 - 1)
    }
}

/// Intensity per unit flux (1/sr) the chain sends at root x (see the doc).
pub fn intensity(p: u32, n: f64, x: f64) -> f64 {
    let s = psi(p, n, x).sin().abs();
    let dd = dpsi_dx(p, n, x).abs();
    let den = PI * s * dd;
    if !(den > 0.0) || !den.is_finite() {
        return 0.0;
    }
    let j = fresnel_chain(p, n, x) * x / den;
    if j.is_finite() { j } else { 0.0 }
}

/// The monotone pieces of ψ_p over x ∈ [0, 1]: split at Descartes' point.
pub fn pieces(p: u32, n: f64) -> ([(f64, f64); 2], usize) {
    const LO: f64 = 1e-9;
    const HI: f64 = 1.0 - 1e-12;
    if p >= 2 {
        let c2 = (n * n - 1.0) / ((p * p) as f64 - 1.0);
        if c2 > 0.0 && c2 < 1.0 {
            let xs = (1.0 - c2).sqrt();
            return ([(LO, xs), (xs, HI)], 2);
        }
    }
    ([(LO, HI), (0.0, 0.0)], 1)
}

/// The x in [lo, hi] with ψ_p(x) = t on a monotone piece (Newton steps from
/// `x0`, kept in a shrinking bisection bracket); `None` if t is outside the
/// piece's range.
pub fn solve_piece(p: u32, n: f64, lo: f64, hi: f64, t: f64, x0: Option<f64>) -> Option<f64> {
    let (f_lo, f_hi) = (psi(p, n, lo) - t, psi(p, n, hi) - t);
    if f_lo == 0.0 {
        return Some(lo);
    }
    if f_lo * f_hi > 0.0 || !(f_lo.is_finite() && f_hi.is_finite()) {
        return None;
    }
    let rising = f_hi > f_lo;
    let (mut a, mut b) = (lo, hi);
    let mut x = x0.filter(|x| *x > lo && *x < hi).unwrap_or(0.5 * (lo + hi));
    for _ in 0..60 {
        let f = psi(p, n, x) - t;
        if f.abs() < 1e-12 {
            return Some(x);
        }
        if (f > 0.0) == rising {
            b = x
        } else {
            a = x
        }
        let d = dpsi_dx(p, n, x);
        let newton = x - f / d;
        x = if d != 0.0 && newton > a && newton < b {
            newton
        } else {
            0.5 * (a + b)
        };
        if (b - a) < 1e-13 {
            return Some(x);
        }
    }
    Some(x)
}

/// Every (x, s, t) with ψ_p(x) = t = s·Θ + 2πm on a piece: s = +1 when the
/// impact point lies on the camera's side of the axis d, −1 opposite.
pub fn roots(p: u32, n: f64, theta: f64, out: &mut impl FnMut(usize, f64, f64, f64)) {
    let (ps, count) = pieces(p, n);
    for (k, &(lo, hi)) in ps.iter().enumerate().take(count) {
        let (a, b) = (psi(p, n, lo), psi(p, n, hi));
        let (min, max) = (a.min(b), a.max(b));
        for s in [1.0f64, -1.0] {
            let base = s * theta;
            let m_lo = ((min - base) / (2.0 * PI)).ceil() as i64;
            let m_hi = ((max - base) / (2.0 * PI)).floor() as i64;
            for m in m_lo..=m_hi {
                let t = base + 2.0 * PI * m as f64;
                if let Some(x) = solve_piece(p, n, lo, hi, t, None) {
                    out(k, s, t - base, x);
                }
            }
        }
    }
}

/// A sphere with a smooth dielectric BSDF met from outside by a light path.
pub struct SphereHit<'a> {
    pub center: Vec3,
    pub radius: f32,
    pub bsdf: &'a Dielectric,
}

/// The sphere at `si` if the connection applies there (see the doc).
pub fn sphere_at<'a>(
    scene: &'a Scene,
    si: &SurfaceInteraction,
    bsdf: &'a Bsdf,
) -> Option<SphereHit<'a>> {
    let Bsdf::Dielectric(dielectric) = bsdf else {
        return None;
    };
    let ShapeGeometry::Sphere(s) = &scene.shapes[si.shape as usize].geometry else {
        return None;
    };
    if s.flip_normals || !(si.wi.z > 0.0) {
        return None;
    }
    let off = si.p - s.center;
    if (off.length() - s.radius).abs() <= 1e-4 * s.radius
        && off.normalize_or_zero().dot(si.n) > 0.9999
    {
        return Some(SphereHit {
            center: s.center,
            radius: s.radius,
            bsdf: dielectric,
        });
    }
    // Placed by an instance: the chord along the inward normal is a diameter.
    let inward = -si.n;
    let back = scene.intersect(&Ray::new(offset_origin(si.p, si.n, inward), inward))?;
    if back.shape != si.shape || back.n.dot(si.n) > -0.999 {
        return None;
    }
    let diameter = (back.p - si.p).length();
    (diameter > 0.0).then(|| SphereHit {
        center: si.p + inward * (0.5 * diameter),
        radius: 0.5 * diameter,
        bsdf: dielectric,
    })
}

/// Splats the light of a light path (throughput `beta`, arriving along
/// direction `d`) that meets sphere `hit`, along every chain of at most
/// `max_chords` chords that reaches the pinhole.
#[allow(clippy::too_many_arguments)]
pub fn connect<S: Spectrum>(
    scene: &Scene,
    camera: &Perspective,
    hit: &SphereHit,
    si: &SurfaceInteraction,
    d: Vec3,
    source: Option<Vec3>,
    beta: S,
    max_chords: i64,
    wl: &S::Wavelengths,
    splat: &mut impl FnMut(Vec2, Rgb),
) {
    let max_chords = max_chords.min(MAX_CHORDS as i64);
    if max_chords < 0 {
        return;
    }
    let rho: S = hit.bsdf.specular_reflectance.eval_spectrum::<S>(si.uv, wl);
    let tau: S = hit
        .bsdf
        .specular_transmittance
        .eval_spectrum::<S>(si.uv, wl);
    match (&hit.bsdf.dispersion, S::hero_wavelength(wl)) {
        (Some(disp), Some(_)) => {
            // Each live wavelength on its own.
            let lambdas = std::cell::RefCell::new(Vec::with_capacity(8));
            let l = S::Channels::from_function(Rgb::BLACK, |l| l, wl);
            let _ = l.zip_map(l, |a, _| {
                lambdas.borrow_mut().push(a);
                a
            });
            let lambdas = lambdas.into_inner();
            for (k, &lambda) in lambdas.iter().enumerate() {
                if lambdas[..k].contains(&lambda) {
                    continue;
                }
                let mask =
                    S::from_function(Rgb::WHITE, |l| if l == lambda { 1.0 } else { 0.0 }, wl);
                if mask.to_rgb(wl) == Rgb::BLACK {
                    continue; // a terminated secondary wavelength
                }
                let eta = disp.eta(lambda) as f64;
                connect_one(
                    scene,
                    camera,
                    hit,
                    d,
                    source,
                    beta * mask,
                    rho,
                    tau,
                    eta,
                    max_chords as u32,
                    wl,
                    splat,
                );
            }
        }
        _ => connect_one(
            scene,
            camera,
            hit,
            d,
            source,
            beta,
            rho,
            tau,
            hit.bsdf.eta as f64,
            max_chords as u32,
            wl,
            splat,
        ),
    }
}

/// The roots x of "the chain's ray passes through the eye" on one side `s`
/// of the plane, at finite distance: g(x) = ψ(x) + γ(x) − τ(x) − 2πm = 0,
/// with τ(x) the angle of (eye − e(x)) from the axis (unwrapped around the
/// centre's angle `base`). g is split at its one extremum (the caustic at
/// finite distance, near Descartes' point) into monotone pieces, each solved
/// by Newton steps in a bisection bracket.
struct Plane {
    /// The eye in the plane: along the axis, and across it (on the side s).
    ex: f64,
    ey: f64,
    a: f64,
    n: f64,
    p: u32,
    /// Distance of the point source from the centre (∞: a parallel beam).
    dist: f64,
    /// The angle of (eye − c), the branch τ is unwrapped around.
    base: f64,
}

impl Plane {
    #[inline]
    fn gamma(&self, x: f64) -> (f64, f64) {
        if !self.dist.is_finite() {
            return (0.0, 0.0);
        }
        let s = (self.a * x / self.dist).clamp(-1.0, 1.0);
        let g = s.asin();
        (g, self.a / (self.dist * g.cos()))
    }

    /// (g(x) without the 2πm, g′(x), the distance exit point → eye).
    fn eval(&self, x: f64) -> (f64, f64, f64) {
        let (p, n, a) = (self.p, self.n, self.a);
        let (gam, dgam) = self.gamma(x);
        let phi = phi_exit(p, n, x) + gam;
        let (vx, vy) = (self.ex - a * phi.cos(), self.ey - a * phi.sin());
        let len = vx.hypot(vy);
        let mut tau = vy.atan2(vx) - self.base;
        tau -= (tau / (2.0 * PI)).round() * 2.0 * PI;
        tau += self.base;
        let g = psi(p, n, x) + gam - tau;
        // τ′ = −a (φ′ + γ′) cos(φ + γ − τ) / |eye − e|.
        let dtau = -a * (dphi_dx(p, n, x) + dgam) * (phi - (tau)).cos() / len;
        (g, dpsi_dx(p, n, x) + dgam - dtau, len)
    }

    /// Every root (x, |eye − e|, g′) on [LO, HI].
    fn roots(&self, out: &mut impl FnMut(f64, f64, f64)) {
        const LO: f64 = 1e-9;
        const HI: f64 = 1.0 - 1e-12;
        let mut cuts = [LO, HI, HI];
        let mut count = 1;
        let (pc, npc) = pieces(self.p, self.n);
        if npc == 2 {
            // The extremum of g: where g′ changes sign, near Descartes' x.
            let (mut lo, mut hi) = (LO, HI);
            let d_lo = self.eval(lo).1;
            if d_lo * self.eval(hi).1 < 0.0 {
                let mut mid = pc[0].1;
                for _ in 0..80 {
                    let dm = self.eval(mid).1;
                    if (dm > 0.0) == (d_lo > 0.0) {
                        lo = mid
                    } else {
                        hi = mid
                    }
                    mid = 0.5 * (lo + hi);
                    if hi - lo < 1e-14 {
                        break;
                    }
                }
                cuts = [LO, mid, HI];
                count = 2;
            }
        }
        for k in 0..count {
            let (lo, hi) = (cuts[k], cuts[k + 1]);
            let (g_lo, g_hi) = (self.eval(lo).0, self.eval(hi).0);
            if !(g_lo.is_finite() && g_hi.is_finite()) {
                continue;
            }
            let (min, max) = (g_lo.min(g_hi), g_lo.max(g_hi));
            let m_lo = (min / (2.0 * PI)).ceil() as i64;
            let m_hi = (max / (2.0 * PI)).floor() as i64;
            for m in m_lo..=m_hi {
                let t = 2.0 * PI * m as f64;
                if let Some(x) = self.solve(lo, hi, t) {
                    let (_, dg, len) = self.eval(x);
                    out(x, len, dg);
                }
            }
        }
    }

    /// x in [lo, hi] with g(x) = t on a monotone piece.
    fn solve(&self, lo: f64, hi: f64, t: f64) -> Option<f64> {
        let (f_lo, f_hi) = (self.eval(lo).0 - t, self.eval(hi).0 - t);
        if f_lo == 0.0 {
            return Some(lo);
        }
        if f_lo * f_hi > 0.0 {
            return None;
        }
        let rising = f_hi > f_lo;
        let (mut a, mut b) = (lo, hi);
        let mut x = 0.5 * (lo + hi);
        for _ in 0..100 {
            let (g, d, _) = self.eval(x);
            let f = g - t;
            if f.abs() < 1e-13 {
                return Some(x);
            }
            if (f > 0.0) == rising {
                b = x
            } else {
                a = x
            }
            let newton = x - f / d;
            x = if d != 0.0 && newton > a && newton < b {
                newton
            } else {
                0.5 * (a + b)
            };
            if b - a < 1e-14 {
                return Some(x);
            }
        }
        Some(x)
    }
}

#[allow(clippy::too_many_arguments)]
fn connect_one<S: Spectrum>(
    scene: &Scene,
    camera: &Perspective,
    hit: &SphereHit,
    d: Vec3,
    source: Option<Vec3>,
    beta: S,
    rho: S,
    tau: S,
    n: f64,
    max_chords: u32,
    wl: &S::Wavelengths,
    splat: &mut impl FnMut(Vec2, Rgb),
) {
    if !(n > 0.0) || (n - 1.0).abs() < 1e-9 {
        return;
    }
    let (c, a) = (hit.center.as_dvec3(), hit.radius as f64);
    let eye = camera.origin().as_dvec3();
    // The axis: from the point source through the centre, or the beam's
    // direction.
    let (d, dist) = match source.map(|y| c - y.as_dvec3()) {
        Some(v) if v.length() > a * (1.0 + 1e-9) => (v / v.length(), v.length()),
        _ => {
            // A parallel beam: the earlier root search (aim from the centre,
            // fixed-point rounds from the exit point), whose images the sky
            // rainbow's test measured.
            return connect_beam(scene, camera, hit, d, beta, rho, tau, n, max_chords, wl, splat);
        }
    };
    if !(d.is_finite()) {
        return;
    }
    let q = eye - c;
    let along = d.dot(q);
    let perp = q - d * along;
    let rho_axis = perp.length();
    if !(rho_axis > 1e-9 * q.length()) {
        return; // the eye on the axis: the glory's focus, measure zero
    }
    let u_plus = perp / rho_axis;
    // The intensity per unit intensity of the source is spread over the
    // cone of the sphere (solid angle Ω); see the doc for the factor.
    let cone = if dist.is_finite() {
        let s2 = (a / dist) * (a / dist);
        (1.0 + (1.0 - s2).max(0.0).sqrt()) / 2.0
    } else {
        1.0
    };
    for (p, scale) in chord_weights(rho, tau, max_chords) {
        for s in [1.0f64, -1.0] {
            let u = u_plus * s;
            let plane = Plane {
                ex: along,
                ey: s * rho_axis,
                a,
                n,
                p,
                dist,
                base: (s * rho_axis).atan2(along),
            };
            plane.roots(&mut |x, len, dg| {
                let gam = plane.gamma(x).0;
                let phi = phi_exit(p, n, x) + gam;
                let psi_x = psi(p, n, x) + gam;
                let e = c + a * (phi.cos() * d + phi.sin() * u);
                let w = psi_x.cos() * d + psi_x.sin() * u;
                let to_eye = (eye - e).normalize_or_zero();
                if w.dot(to_eye) < 1.0 - 1e-6 {
                    return; // the root is not a ray towards the eye (g wrapped)
                }
                // Irradiance at the pinhole per unit flux (see the doc):
                // the rays' spread across the pinhole is |M| dx in the plane
                // (M = |eye − e| g′) and ρ dα around the axis.
                let m = len * dg;
                let den = PI * m.abs() * rho_axis * gam.cos();
                let irradiance = fresnel_chain(p, n, x) * x * cone / den;
                if !(den > 0.0) || !(irradiance > 0.0 && irradiance.is_finite()) {
                    return;
                }
                splat_exit(scene, camera, c, a, e, irradiance, beta * scale, wl, splat);
            });
        }
    }
}

/// The parallel-beam connection (a light at infinity, or past a delta
/// vertex): roots aimed from the centre and refined by fixed-point rounds
/// from the exit point; the far-field ray tube with the camera side at
/// finite distance (γ′ = 0).
#[allow(clippy::too_many_arguments)]
fn connect_beam<S: Spectrum>(
    scene: &Scene,
    camera: &Perspective,
    hit: &SphereHit,
    d: Vec3,
    beta: S,
    rho: S,
    tau: S,
    n: f64,
    max_chords: u32,
    wl: &S::Wavelengths,
    splat: &mut impl FnMut(Vec2, Rgb),
) {
    // (n was checked by `connect_one`, the only caller.)
    let (c, a) = (hit.center.as_dvec3(), hit.radius as f64);
    let d = d.as_dvec3().normalize();
    let eye = camera.origin().as_dvec3();
    // The frame (Θ, u⁺) of the direction towards the camera from `from`.
    let frame = |from: DVec3| -> Option<(f64, DVec3, DVec3)> {
        let v = (eye - from).normalize_or_zero();
        let perp = v - d * d.dot(v);
        let len = perp.length();
        if !(len > 1e-9) {
            return None;
        }
        Some((d.dot(v).clamp(-1.0, 1.0).acos(), perp / len, v))
    };
    let Some((theta0, _, _)) = frame(c) else {
        return;
    };
    for (p, scale) in chord_weights(rho, tau, max_chords) {
        let (ps, _) = pieces(p, n);
        roots(p, n, theta0, &mut |piece, s, shift, x0| {
            // Fixed-point rounds: aim from the exit point, not the centre.
            let (lo, hi) = ps[piece];
            let Some((_, u0, _)) = frame(c) else { return };
            let mut u = u0 * s;
            let mut x = x0;
            for _ in 0..4 {
                let phi = phi_exit(p, n, x);
                let e = c + a * (phi.cos() * d + phi.sin() * u);
                let Some((theta, u_plus, _)) = frame(e) else {
                    return;
                };
                u = u_plus * s;
                let Some(nx) = solve_piece(p, n, lo, hi, s * theta + shift, Some(x)) else {
                    return;
                };
                let settled = (nx - x).abs() < 1e-10;
                x = nx;
                if settled {
                    break;
                }
            }
            let (phi, psi_x) = (phi_exit(p, n, x), psi(p, n, x));
            let e = c + a * (phi.cos() * d + phi.sin() * u);
            let w = psi_x.cos() * d + psi_x.sin() * u;
            let to_eye = (eye - e).normalize_or_zero();
            if w.dot(to_eye) < 1.0 - 5e-7 {
                return; // the fixed point did not settle (at a caustic's edge)
            }
            // Irradiance at the pinhole per unit flux on the cross-section,
            // exact at finite distance: the rays' spread across the pinhole
            // is |M| dx in the plane of d (M from the exit point's motion and
            // the direction's turn) and ρ dα around the axis (the pinhole's
            // distance from the line through c along d); far away this is
            // J / distance².
            let along = (eye - e).length();
            let rho_axis = {
                let q = eye - c;
                (q - d * d.dot(q)).length()
            };
            let m = a * dphi_dx(p, n, x) * (phi - psi_x).cos() + along * dpsi_dx(p, n, x);
            let den = PI * m.abs() * rho_axis;
            let irradiance = fresnel_chain(p, n, x) * x / den;
            if !(den > 0.0) || !(irradiance > 0.0 && irradiance.is_finite()) {
                return;
            }
            splat_exit(scene, camera, c, a, e, irradiance, beta * scale, wl, splat);
        });
    }
}

/// The weight of each number of chords p = 0..=max_chords inside the
/// sphere: ρ for the reflection off the surface (p = 0), τ²ρ^(p−1) for a
/// ray that enters, reflects p − 1 times inside and leaves; zero weights
/// are skipped.
fn chord_weights<S: Spectrum>(rho: S, tau: S, max_chords: u32) -> impl Iterator<Item = (u32, S)> {
    let mut tau_pow = tau * tau;
    (0..=max_chords).filter_map(move |p| {
        if p >= 2 {
            tau_pow *= rho;
        }
        let scale = if p == 0 { rho } else { tau_pow };
        (!scale.is_zero()).then_some((p, scale))
    })
}

/// Light leaving the sphere (centre `c`, radius `a`) at `e` towards the
/// pinhole, with `irradiance` there per unit of the light path's weight:
/// the camera's importance and film position at `e`, visibility from just
/// outside the surface, and the splat of weight · irradiance · importance.
#[allow(clippy::too_many_arguments)]
#[inline]
fn splat_exit<S: Spectrum>(
    scene: &Scene,
    camera: &Perspective,
    c: DVec3,
    a: f64,
    e: DVec3,
    irradiance: f64,
    weight: S,
    wl: &S::Wavelengths,
    splat: &mut impl FnMut(Vec2, Rgb),
) {
    let e32 = e.as_vec3();
    let Some(cc) = camera.connect(e32, scene.film.width, scene.film.height) else {
        return;
    };
    let normal = ((e - c) / a).as_vec3();
    let o = offset_origin(e32, normal, cc.d);
    let to = camera.origin() - o;
    let len = to.length();
    if !(len > 0.0) {
        return;
    }
    let tr = scene.transmittance(&Ray {
        o,
        d: to / len,
        tmax: len * (1.0 - SHADOW_EPSILON),
    });
    if !(tr > 0.0) {
        return;
    }
    let k = (irradiance as f32) * tr * cc.importance;
    let rgb = (weight * finite_or_zero(k)).to_rgb(wl);
    if rgb.is_finite() {
        let size = Vec2::new(scene.film.width as f32, scene.film.height as f32);
        splat(cc.film * size, rgb);
    }
}

#[inline]
fn finite_or_zero(k: f32) -> f32 {
    if k.is_finite() { k } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed form against brute force: rays uniform over the
    /// cross-section traced through a circle with the unpolarised Fresnel
    /// weights, binned by scattering angle Θ; each bin's share of the flux
    /// equals the closed-form intensity integrated over the bin's solid angle.
    #[test]
    fn intensity_matches_traced_rays() {
        let n = 1.333f64;
        let bins = 90usize; // 2° bins of Θ
        let mut traced = vec![[0.0f64; 4]; bins];
        let count = 400_000usize;
        for k in 0..count {
            // x² uniform: uniform over the disk (the azimuth does not matter).
            let x = ((k as f64 + 0.5) / count as f64).sqrt();
            for p in 0..4u32 {
                let psi_x = psi(p, n, x);
                // Θ = the angle of the direction (cos ψ, sin ψ) from d.
                let theta = psi_x.sin().atan2(psi_x.cos()).abs();
                let b = ((theta / PI * bins as f64) as usize).min(bins - 1);
                traced[b][p as usize] += fresnel_chain(p, n, x) / count as f64;
            }
        }
        // Closed form: Σ_roots J(x) integrated over each bin (2π sin Θ dΘ),
        // the bin split at the caustic (Descartes' angle, J ~ 1/√ there) and
        // each part integrated in v with Θ = Θa + (Θb − Θa)(3v² − 2v³),
        // whose vanishing slope at both ends cancels the singularity.
        let w = PI / bins as f64;
        for p in 0..4u32 {
            let (ps, count) = pieces(p, n);
            let caustic = (count == 2).then(|| {
                let v = psi(p, n, ps[0].1);
                v.sin().atan2(v.cos()).abs()
            });
            for (b, row) in traced.iter().enumerate() {
                let (lo, hi) = (b as f64 * w, (b + 1) as f64 * w);
                let mut cuts = vec![lo];
                cuts.extend(caustic.filter(|c| *c > lo && *c < hi));
                cuts.push(hi);
                let sub = 400;
                let mut closed = 0.0;
                for seg in cuts.windows(2) {
                    let (ta, tb) = (seg[0], seg[1]);
                    for q in 0..sub {
                        let v = (q as f64 + 0.5) / sub as f64;
                        let theta = ta + (tb - ta) * v * v * (3.0 - 2.0 * v);
                        let dtheta = (tb - ta) * 6.0 * v * (1.0 - v) / sub as f64;
                        let mut sum = 0.0;
                        roots(p, n, theta, &mut |_, _, _, x| sum += intensity(p, n, x));
                        closed += sum * 2.0 * PI * theta.sin() * dtheta;
                    }
                }
                let t = row[p as usize];
                // 2 %: the traced side is a 400 000-ray quadrature in x.
                let tol = 0.02 * t.max(closed) + 2e-5;
                assert!(
                    (closed - t).abs() <= tol,
                    "p={p} bin {b} (Θ {}°): closed {closed:.6} traced {t:.6}",
                    2 * b
                );
            }
        }
    }

    #[test]
    fn descartes_angles() {
        // The primary's minimum deviation: Θ = 180° − 42.4° for n = 1.3317.
        let n = 1.3317f64;
        let (ps, count) = pieces(2, n);
        assert_eq!(count, 2);
        let theta = -psi(2, n, ps[0].1);
        let bow = 180.0 - (theta.to_degrees().rem_euclid(360.0));
        assert!((bow.abs() - 42.3).abs() < 0.3, "primary at {bow}°");
        // Each side of the bow: two roots inside, none outside.
        let mut c = 0;
        roots(2, n, (180.0f64 - 40.0).to_radians(), &mut |_, _, _, _| {
            c += 1
        });
        assert_eq!(c, 2);
        let mut c = 0;
        roots(2, n, (180.0f64 - 44.0).to_radians(), &mut |_, _, _, _| {
            c += 1
        });
        assert_eq!(c, 0);
    }
}

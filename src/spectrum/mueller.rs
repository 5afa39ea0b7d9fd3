//! Polarization algebra: Stokes vectors and Mueller matrices (the seed's
//! "polarizing filter" slide), with their reference frames.
//!
//! A Stokes vector (S0, S1, S2, S3) describes light travelling along a
//! direction w relative to a *reference frame*: a unit vector x ⟂ w (and
//! y = w × x). S0 is the intensity, S1 = I(x) − I(y) the excess of light
//! linearly polarised along x over y, S2 the same for the diagonals at ±45°,
//! S3 the excess of right- over left-circular light. A Mueller matrix maps
//! the Stokes vector of incident light (in its frame) to that of the
//! outgoing light (in another frame), so it is only meaningful together with
//! both frames; [`rotate_mueller_basis`] re-expresses it for other frames.
//! As in Mitsuba 3, every frame along a path is the canonical
//! [`stokes_basis`] of its propagation direction, so matrices chain without
//! carrying frames.
//!
//! Interfaces (`specular_reflection`, `specular_transmission`) use the s/p
//! frame of the plane of incidence: x = s (perpendicular to the plane), so a
//! positive S1 is s-polarised light.

use crate::bsdf::fresnel::fresnel_amplitudes;
use glam::{Mat4, Vec3, Vec4};
use num_complex::Complex32;

/// Mueller matrix of an ideal depolarizer of transmittance `v`: whatever
/// comes in, unpolarised light of intensity v·S0 goes out (diffuse surfaces).
pub fn depolarizer(v: f32) -> Mat4 {
    Mat4::from_cols(Vec4::new(v, 0.0, 0.0, 0.0), Vec4::ZERO, Vec4::ZERO, Vec4::ZERO)
}

/// Rotation of the reference frame by `theta` (radians, counter-clockwise
/// looking against the propagation direction): the same light, described in
/// a frame whose x axis is turned by θ. Linear polarisation components turn
/// by 2θ.
pub fn rotator(theta: f32) -> Mat4 {
    let (s, c) = (2.0 * theta).sin_cos();
    rotator_from_double_angle(s, c)
}

/// [`rotator`] given sin 2θ and cos 2θ.
fn rotator_from_double_angle(s: f32, c: f32) -> Mat4 {
    Mat4::from_cols(
        Vec4::new(1.0, 0.0, 0.0, 0.0),
        Vec4::new(0.0, c, -s, 0.0),
        Vec4::new(0.0, s, c, 0.0),
        Vec4::new(0.0, 0.0, 0.0, 1.0),
    )
}

/// An ideal linear polarizer whose transmission axis makes angle `theta`
/// with the frame's x axis.
pub fn linear_polarizer(theta: f32) -> Mat4 {
    // Along x: passes the x component only: ½[[1,1,0,0],[1,1,0,0],0,0].
    let along_x = Mat4::from_cols(
        Vec4::new(0.5, 0.5, 0.0, 0.0),
        Vec4::new(0.5, 0.5, 0.0, 0.0),
        Vec4::ZERO,
        Vec4::ZERO,
    );
    rotate_element(along_x, theta)
}

/// A linear retarder (wave plate) with its fast axis at `theta` from the x
/// axis, delaying the slow component by `delta` radians (π/2: quarter wave).
pub fn linear_retarder(theta: f32, delta: f32) -> Mat4 {
    let (s, c) = delta.sin_cos();
    let along_x = Mat4::from_cols(
        Vec4::new(1.0, 0.0, 0.0, 0.0),
        Vec4::new(0.0, 1.0, 0.0, 0.0),
        Vec4::new(0.0, 0.0, c, -s),
        Vec4::new(0.0, 0.0, s, c),
    );
    rotate_element(along_x, theta)
}

/// An optical element `m` (defined with its axis along x) turned by
/// `theta` about the propagation direction: R(−θ) · M · R(θ).
pub fn rotate_element(m: Mat4, theta: f32) -> Mat4 {
    rotator(-theta) * m * rotator(theta)
}

/// The Mueller matrix of an interface with complex amplitude ratios
/// `a_s`, `a_p` (s/p frame): intensities scale by |a|², and the
/// components' relative phase δ = arg(a_p) − arg(a_s) turns S2 into S3.
fn interface(a_s: Complex32, a_p: Complex32) -> Mat4 {
    interface_from_parameters(interface_parameters(a_s, a_p))
}

/// The four numbers an interface's Mueller matrix is made of (s/p frames):
/// ½(|a_s|² + |a_p|²), ½(|a_s|² − |a_p|²) and the real and imaginary parts
/// of a_p·conj(a_s) = |a_s||a_p| e^{iδ}.
///
/// The matrix is Mitsuba 3.9.1's: its `specular_reflection` takes the
/// evanescent cos θ_t under total internal reflection as −i·√(sin²θ_t − 1)
/// and a conductor's index as η − ik, so its amplitudes are the complex
/// conjugates of the ones Snell computes (+i branch, η + ik), its phase
/// δ_M = −δ, and its S2/S3 block (c cos δ_M, −c sin δ_M; c sin δ_M,
/// c cos δ_M) is [`interface_from_parameters`]' with these parameters. (With
/// a_s·conj(a_p) instead, the S2 → S3 conversion of a gold mirror and of
/// total internal reflection came out with the opposite sign.)
pub fn interface_parameters(a_s: Complex32, a_p: Complex32) -> [f32; 4] {
    let (r_s, r_p) = (a_s.norm_sqr(), a_p.norm_sqr());
    let cross = a_p * a_s.conj();
    [0.5 * (r_s + r_p), 0.5 * (r_s - r_p), cross.re, cross.im]
}

/// The interface matrix from its [`interface_parameters`] (a, b, c cos δ,
/// c sin δ); linear in them.
pub fn interface_from_parameters([a, b, c_cos, c_sin]: [f32; 4]) -> Mat4 {
    Mat4::from_cols(
        Vec4::new(a, b, 0.0, 0.0),
        Vec4::new(b, a, 0.0, 0.0),
        Vec4::new(0.0, 0.0, c_cos, -c_sin),
        Vec4::new(0.0, 0.0, c_sin, c_cos),
    )
}

/// Amplitude ratios (r_s, r_p) for reflection of light with cosine `cos_i`
/// (> 0 outside, < 0 inside) at a dielectric interface of relative index
/// `eta` = η_int / η_ext. Under total internal reflection |r| = 1 and the
/// phases differ: the evanescent wave's cos θ_t is taken as +i·√(sin²θ_t − 1).
pub fn dielectric_amplitudes(cos_i: f32, eta: f32) -> (Complex32, Complex32) {
    // From inside, the same interface seen with the reciprocal index. The
    // complex square root in `fresnel_amplitudes` takes the +i branch under TIR.
    let (eta, cos_i) = if cos_i >= 0.0 { (eta, cos_i) } else { (1.0 / eta, -cos_i) };
    let (r_p, r_s) = fresnel_amplitudes(cos_i, Complex32::new(eta, 0.0));
    (r_s, r_p)
}

/// Reflection at a dielectric interface (s/p frames, incident and
/// reflected), including the phase shift of total internal reflection.
pub fn specular_reflection(cos_i: f32, eta: f32) -> Mat4 {
    let (r_s, r_p) = dielectric_amplitudes(cos_i, eta);
    interface(r_s, r_p)
}

/// Reflection at a conductor of complex relative index `eta` + i`k`.
pub fn conductor_reflection(cos_i: f32, eta: f32, k: f32) -> Mat4 {
    interface_from_parameters(conductor_parameters(cos_i, eta, k))
}

/// The [`interface_parameters`] of a conductor; η = k = 0 is Mitsuba's
/// "no Fresnel" perfect mirror.
pub fn conductor_parameters(cos_i: f32, eta: f32, k: f32) -> [f32; 4] {
    if eta == 0.0 && k == 0.0 {
        return PERFECT_MIRROR;
    }
    let (r_p, r_s) = fresnel_amplitudes(cos_i, Complex32::new(eta, k));
    interface_parameters(r_s, r_p)
}

/// A perfect mirror (the limit η → ∞): r_s = −1, r_p = 1, every polarisation
/// reflected in full with S2 and S3 mirrored in the s/p frames.
const PERFECT_MIRROR: [f32; 4] = [1.0, 0.0, -1.0, 0.0];

/// Transmission through a dielectric interface (s/p frames): the power
/// transmittances T = (η_t cos θ_t / η_i cos θ_i)|t|², with t_s = 1 + r_s and
/// t_p = (1 + r_p)·η_i/η_t; no phase difference. Zero under total internal
/// reflection. (The η² change of radiance is the BSDF's business.)
pub fn specular_transmission(cos_i: f32, eta: f32) -> Mat4 {
    let (eta_rel, ci) = if cos_i >= 0.0 { (eta, cos_i) } else { (1.0 / eta, -cos_i) };
    let sin2_t = (1.0 - ci * ci) / (eta_rel * eta_rel);
    if sin2_t >= 1.0 || ci <= 0.0 {
        return Mat4::ZERO;
    }
    let ct = (1.0 - sin2_t).sqrt();
    let (r_s, r_p) = dielectric_amplitudes(cos_i, eta);
    let (t_s, t_p) = (r_s.re + 1.0, (r_p.re + 1.0) / eta_rel);
    let factor = eta_rel * ct / ci;
    let (tt_s, tt_p) = (factor * t_s * t_s, factor * t_p * t_p);
    interface(Complex32::new(tt_s.sqrt(), 0.0), Complex32::new(tt_p.sqrt(), 0.0))
}

/// The canonical Stokes frame of light travelling along unit `w`: an x axis
/// perpendicular to w, a function of w alone (Duff et al.'s orthonormal basis).
pub fn stokes_basis(w: Vec3) -> Vec3 {
    let sign = 1.0f32.copysign(w.z);
    let a = -1.0 / (sign + w.z);
    let b = w.x * w.y * a;
    Vec3::new(1.0 + sign * w.x * w.x * a, sign * b, -sign * w.x)
}

/// The rotator taking Stokes vectors of light along `forward` from frame
/// `basis_current` to frame `basis_target` (both ⟂ forward).
pub fn rotate_stokes_basis(forward: Vec3, basis_current: Vec3, basis_target: Vec3) -> Mat4 {
    // The turn θ has sin θ ∝ (current × target)·forward and cos θ ∝
    // current·target; the rotator needs only cos 2θ and sin 2θ, which follow
    // from those without an atan2 and a sin_cos (this runs at every vertex).
    let (s, c) = (basis_current.cross(basis_target).dot(forward), basis_current.dot(basis_target));
    let r2 = s * s + c * c;
    if !(r2 > 0.0) {
        return Mat4::IDENTITY;
    }
    rotator_from_double_angle((2.0 * s * c) / r2, (c * c - s * s) / r2)
}

/// Re-expresses Mueller matrix `m` (incident light along `in_forward` in
/// frame `in_current`, outgoing along `out_forward` in `out_current`) for
/// the frames `in_target` and `out_target`.
pub fn rotate_mueller_basis(
    m: Mat4,
    in_forward: Vec3,
    in_current: Vec3,
    in_target: Vec3,
    out_forward: Vec3,
    out_current: Vec3,
    out_target: Vec3,
) -> Mat4 {
    // Incident light arrives in in_target; bring it to in_current, apply m,
    // and take the result from out_current to out_target.
    let r_in = rotate_stokes_basis(in_forward, in_target, in_current);
    let r_out = rotate_stokes_basis(out_forward, out_current, out_target);
    r_out * m * r_in
}

/// An interface's Mueller matrix `m_sp`, given in the s/p frames (x = s for
/// both beams), re-expressed in the canonical Stokes frames of the incident
/// light's direction of travel `in_forward` and the outgoing light's
/// `out_forward`, at a surface of normal `n`.
pub fn interface_to_canonical(m_sp: Mat4, n: Vec3, in_forward: Vec3, out_forward: Vec3) -> Mat4 {
    // s is perpendicular to the plane of incidence, which holds both beams.
    let s = in_forward.cross(n);
    let s = if s.length_squared() > 1e-12 { s.normalize() } else { stokes_basis(in_forward) };
    rotate_mueller_basis(m_sp, in_forward, s, stokes_basis(in_forward), out_forward, s, stokes_basis(out_forward))
}

/// A thin sheet's element `m` (defined with its axis along the frame's x)
/// for light travelling along `w`, the sheet's axis being `axis`:
/// re-expressed in the canonical Stokes frame of `w`, with the axis
/// projected across `w`. `None` when light travels along the axis itself.
pub fn sheet_to_canonical(m: Mat4, w: Vec3, axis: Vec3) -> Option<Mat4> {
    let axis = (axis - w * axis.dot(w)).normalize_or_zero();
    if axis == Vec3::ZERO {
        return None;
    }
    let basis = stokes_basis(w);
    Some(rotate_mueller_basis(m, w, axis, basis, w, axis, basis))
}

/// Degree of (total) polarisation of a Stokes vector.
pub fn degree_of_polarization(s: Vec4) -> f32 {
    if s.x > 0.0 { (s.y * s.y + s.z * s.z + s.w * s.w).sqrt() / s.x } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::fresnel::fresnel_dielectric;
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    const UNPOLARIZED: Vec4 = Vec4::new(1.0, 0.0, 0.0, 0.0);

    fn close(a: Vec4, b: Vec4, tol: f32) -> bool {
        (a - b).abs().max_element() < tol
    }

    #[test]
    fn malus_law_for_two_polarizers() {
        for i in 0..=36 {
            let theta = i as f32 * PI / 36.0;
            let out = linear_polarizer(theta) * (linear_polarizer(0.0) * UNPOLARIZED);
            let malus = 0.5 * theta.cos() * theta.cos();
            assert!((out.x - malus).abs() < 1e-6, "θ = {theta}: {} vs ½cos²θ = {malus}", out.x);
            // What leaves is fully polarised along the second polarizer.
            if out.x > 1e-4 {
                assert!((degree_of_polarization(out) - 1.0).abs() < 1e-4);
                let expected = Vec4::new(1.0, (2.0 * theta).cos(), (2.0 * theta).sin(), 0.0) * out.x;
                assert!(close(out, expected, 1e-5), "{out:?} vs {expected:?}");
            }
        }
    }

    #[test]
    fn reflection_at_brewsters_angle_is_s_polarized() {
        for eta in [1.333f32, 1.5, 2.4] {
            let brewster = eta.atan();
            let m = specular_reflection(brewster.cos(), eta);
            let out = m * UNPOLARIZED;
            // R_p = 0: all reflected light is s-polarised (S1 = S0 > 0).
            assert!(out.x > 0.0 && (out.y / out.x - 1.0).abs() < 1e-5, "η = {eta}: {out:?}");
            assert!((degree_of_polarization(out) - 1.0).abs() < 1e-5);
            // A polarizer passing p only (axis ⟂ s) removes the reflection.
            let through = linear_polarizer(FRAC_PI_2) * out;
            assert!(through.x.abs() < 1e-7, "η = {eta}: {}", through.x);
            // Away from Brewster's angle the reflection is only partly polarised.
            let other = specular_reflection(0.5f32.cos(), eta) * UNPOLARIZED;
            assert!(degree_of_polarization(other) < 0.95);
        }
    }

    #[test]
    fn intensity_row_is_the_unpolarized_fresnel_term_and_energy_is_conserved() {
        for eta in [1.333f32, 1.5, 0.75] {
            for i in 0..=40 {
                let cos_i = (i as f32 / 40.0).max(1e-3);
                for c in [cos_i, -cos_i] {
                    let r = specular_reflection(c, eta);
                    let t = specular_transmission(c, eta);
                    let f = fresnel_dielectric(c, eta);
                    assert!((r.x_axis.x - f.r).abs() < 2e-6, "η {eta} cos {c}: {} vs {}", r.x_axis.x, f.r);
                    assert!((r.x_axis.x + t.x_axis.x - 1.0).abs() < 2e-5, "η {eta} cos {c}: R + T = {}", r.x_axis.x + t.x_axis.x);
                    // Each polarisation on its own: R_s + T_s = 1, R_p + T_p = 1.
                    let (rs, ts) = ((r * Vec4::new(1.0, 1.0, 0.0, 0.0)).x, (t * Vec4::new(1.0, 1.0, 0.0, 0.0)).x);
                    assert!((rs + ts - 1.0).abs() < 2e-5);
                    assert!((rs - f.r_perpendicular).abs() < 2e-6);
                }
            }
        }
    }

    #[test]
    fn total_internal_reflection_retardance_matches_the_closed_form() {
        // Glass (1.5) to air, past the critical angle asin(1/1.5) = 41.8°.
        let n = 1.5f32;
        for deg in [45.0f32, 50.0, 55.0, 60.0, 70.0, 80.0] {
            let theta = deg.to_radians();
            let m = specular_reflection(-theta.cos(), n);
            // Total: every polarisation is reflected in full.
            assert!((m.x_axis.x - 1.0).abs() < 1e-5 && m.x_axis.y.abs() < 1e-5);
            // Relative phase δ between s and p: the S2/S3 block is a rotation by δ.
            let delta = m.z_axis.w.atan2(m.z_axis.z);
            // Born & Wolf: tan(δ/2) = cos θ √(sin²θ − (1/n)²) / sin²θ.
            let s2 = theta.sin() * theta.sin();
            let closed = 2.0 * (theta.cos() * (s2 - 1.0 / (n * n)).sqrt() / s2).atan();
            assert!((delta.abs() - closed).abs() < 1e-4, "{deg}°: δ = {delta} vs {closed}");
        }
        // Fresnel's rhomb: two TIRs at 54.6° in glass of 1.51 add a quarter wave.
        let theta = 54.6f32.to_radians();
        let m = specular_reflection(-theta.cos(), 1.51);
        let two = m * m;
        let delta = two.z_axis.w.atan2(two.z_axis.z).abs();
        assert!((delta - FRAC_PI_2).abs() < 5e-3, "rhomb retardance {delta}");
    }

    #[test]
    fn conductor_reflection_reduces_to_the_dielectric_for_k_zero() {
        for i in 1..=20 {
            let cos_i = i as f32 / 20.0;
            let a = conductor_reflection(cos_i, 1.5, 0.0);
            let b = specular_reflection(cos_i, 1.5);
            assert!(a.abs_diff_eq(b, 2e-6), "{a:?} vs {b:?}");
        }
        // Gold at 45°: partly converts linear to elliptical polarisation.
        let m = conductor_reflection(FRAC_PI_4.cos(), 0.2, 3.4);
        let out = m * Vec4::new(1.0, 0.0, 1.0, 0.0);
        assert!(out.w.abs() > 0.05, "{out:?}");
        assert!((degree_of_polarization(out) - 1.0).abs() < 1e-4, "a pure state stays pure: {out:?}");
    }

    #[test]
    fn phase_sign_matches_mitsuba() {
        // Mitsuba 3.9.1 (scalar_spectral_polarized, mueller.specular_reflection):
        // gold-like η = 0.2 + 3.6i at cos θ_i = 0.5 turns S2 = 1 into
        // (S2, S3) = (−0.674379, 0.651593); glass of 1.5 seen from inside at
        // cos θ_i = 0.3 (total internal reflection) has row 2 (…, 0.903678, −0.428212).
        let out = conductor_reflection(0.5, 0.2, 3.6) * Vec4::new(0.0, 0.0, 1.0, 0.0);
        assert!((out.z + 0.674_379).abs() < 1e-5 && (out.w - 0.651_593).abs() < 1e-5, "{out:?}");
        let m = specular_reflection(-0.3, 1.5);
        assert!((m.z_axis.z - 0.903_678).abs() < 1e-5 && (m.w_axis.z + 0.428_212).abs() < 1e-5, "{m:?}");
    }

    #[test]
    fn quarter_wave_plate_makes_circular_light() {
        let linear_45 = Vec4::new(1.0, 0.0, 1.0, 0.0);
        let out = linear_retarder(0.0, FRAC_PI_2) * linear_45;
        assert!(close(out, Vec4::new(1.0, 0.0, 0.0, 1.0), 1e-6) || close(out, Vec4::new(1.0, 0.0, 0.0, -1.0), 1e-6), "{out:?}");
        // A half-wave plate at 22.5° turns horizontal into 45° light.
        let out = linear_retarder(PI / 8.0, PI) * Vec4::new(1.0, 1.0, 0.0, 0.0);
        assert!(close(out, linear_45, 1e-5), "{out:?}");
    }

    #[test]
    fn frames_rotate_consistently() {
        assert!(rotator(0.3).mul_mat4(&rotator(0.4)).abs_diff_eq(rotator(0.7), 1e-6));
        assert!(rotator(PI).abs_diff_eq(Mat4::IDENTITY, 1e-6));
        for w in [Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.5, 0.8).normalize(), Vec3::new(-0.9, 0.1, -0.2).normalize()] {
            let x = stokes_basis(w);
            assert!((x.length() - 1.0).abs() < 1e-5 && x.dot(w).abs() < 1e-5);
            // Rotating the frame by θ about w: light polarised along x is, in the
            // new frame, polarised at −θ.
            let theta = 0.4f32;
            let target = glam::Quat::from_axis_angle(w, theta) * x;
            let r = rotate_stokes_basis(w, x, target);
            let out = r * Vec4::new(1.0, 1.0, 0.0, 0.0);
            let expected = Vec4::new(1.0, (2.0 * theta).cos(), -(2.0 * theta).sin(), 0.0);
            assert!(close(out, expected, 1e-5), "{w}: {out:?} vs {expected:?}");
            // Intensity and degree of polarisation never depend on the frame.
            let s = Vec4::new(2.0, 0.3, -0.8, 0.5);
            let t = r * s;
            assert!((t.x - 2.0).abs() < 1e-6 && (degree_of_polarization(t) - degree_of_polarization(s)).abs() < 1e-6);
        }
    }
}

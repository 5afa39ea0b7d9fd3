//! Ideal specular reflection and refraction at a smooth interface, and the
//! exact Fresnel equations (no Schlick approximation).
//!
//! Everything is in the local shading frame (z = normal). `eta` is the
//! relative index of refraction η_int / η_ext of the interface: the normal
//! points to the exterior, so a direction with z > 0 lies outside.
//!
//! For light crossing from medium 1 into medium 2 the seed's amplitude
//! ratios are
//!
//! ρ∥ = (η₂ cos θ₁ − η₁ cos θ₂) / (η₂ cos θ₁ + η₁ cos θ₂),
//! ρ⊥ = (η₁ cos θ₁ − η₂ cos θ₂) / (η₁ cos θ₁ + η₂ cos θ₂),
//!
//! with η₁ sin θ₁ = η₂ sin θ₂ (Snell's law), and unpolarised light reflects
//! F_r = ½(ρ∥² + ρ⊥²). Past the critical angle asin(η₂/η₁) there is no real
//! θ₂ and all light is reflected (total internal reflection). A conductor
//! has a complex index η + ik; the same amplitude ratios, evaluated in
//! complex arithmetic, give its reflectance — the dielectric case is k = 0.

use glam::Vec3;
use num_complex::Complex32;

/// The result of [`fresnel_dielectric`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DielectricFresnel {
    /// Unpolarised reflectance F_r = ½(R∥ + R⊥).
    pub r: f32,
    /// Reflectance of light polarised parallel to the plane of incidence, ρ∥².
    pub r_parallel: f32,
    /// Reflectance of light polarised perpendicular to it, ρ⊥².
    pub r_perpendicular: f32,
    /// cos θ of the refracted direction, signed (on the other side of the
    /// interface from the incident direction); 0 under total internal reflection.
    pub cos_t: f32,
    /// η_t / η_i: relative index in the direction of travel.
    pub eta_it: f32,
    /// η_i / η_t, its reciprocal (also the tangential scale of the refracted direction).
    pub eta_ti: f32,
}

impl DielectricFresnel {
    /// Whether the incident direction is totally internally reflected.
    pub fn total_internal_reflection(&self) -> bool {
        self.r >= 1.0 && self.cos_t == 0.0
    }
}

/// Exact Fresnel reflectance of a smooth dielectric interface of relative
/// index `eta` for a direction with cosine `cos_i` to the normal (negative:
/// the direction is on the interior side).
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> DielectricFresnel {
    let outside = cos_i >= 0.0;
    let (eta_it, eta_ti) = if outside { (eta, 1.0 / eta) } else { (1.0 / eta, eta) };
    let cos_i_abs = cos_i.abs().min(1.0);
    // Snell's law: sin²θ_t = (η_i/η_t)² sin²θ_i.
    let sin2_t = eta_ti * eta_ti * (1.0 - cos_i_abs * cos_i_abs).max(0.0);
    if sin2_t >= 1.0 {
        return DielectricFresnel { r: 1.0, r_parallel: 1.0, r_perpendicular: 1.0, cos_t: 0.0, eta_it, eta_ti };
    }
    let cos_t_abs = (1.0 - sin2_t).sqrt();
    // The seed's ρ⊥ and ρ∥, divided through by η_i.
    let rho_perp = (cos_i_abs - eta_it * cos_t_abs) / (cos_i_abs + eta_it * cos_t_abs);
    let rho_par = (eta_it * cos_i_abs - cos_t_abs) / (eta_it * cos_i_abs + cos_t_abs);
    let (r_perp, r_par) = (rho_perp * rho_perp, rho_par * rho_par);
    DielectricFresnel {
        r: 0.5 * (r_perp + r_par),
        r_parallel: r_par,
        r_perpendicular: r_perp,
        cos_t: if outside { -cos_t_abs } else { cos_t_abs },
        eta_it,
        eta_ti,
    }
}

/// Complex amplitude ratios (ρ∥, ρ⊥) for light arriving from outside
/// (cos_i > 0) at an interface of complex relative index `eta` = η + ik.
pub fn fresnel_amplitudes(cos_i: f32, eta: Complex32) -> (Complex32, Complex32) {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_i = 1.0 - cos_i * cos_i;
    // Snell's law in complex form: cos θ_t = √(1 − sin²θ_i / η²).
    let cos_t = (Complex32::new(1.0, 0.0) - sin2_i / (eta * eta)).sqrt();
    let rho_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rho_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (rho_par, rho_perp)
}

/// Unpolarised reflectance of a conductor of complex index `eta` + i`k`
/// (relative to the exterior) for light arriving from outside.
///
/// In real arithmetic (the amplitudes' squared moduli, Born & Wolf §14.2):
/// with a + ib = √(η̃² − sin²θ_i), η̃ = η + ik,
/// R_s = ((a² + b²) + cos²θ − 2a cos θ) / ((a² + b²) + cos²θ + 2a cos θ) and
/// R_p = R_s ((a² + b²) cos²θ + sin⁴θ − 2a cos θ sin²θ) / (… + 2a cos θ sin²θ).
/// Equal to |ρ_s|², |ρ_p|² of [`fresnel_amplitudes`] (checked in the tests),
/// without its complex square root (an atan2 and a sin_cos): this runs at
/// every rough-metal vertex per channel.
#[inline]
pub fn fresnel_conductor(cos_i: f32, eta: f32, k: f32) -> f32 {
    if eta == 0.0 && k == 0.0 {
        // A vanishing index is Mitsuba's "no Fresnel"; avoid 0/0.
        return 1.0;
    }
    let c = cos_i.clamp(0.0, 1.0);
    let (c2, s2) = (c * c, 1.0 - c * c);
    // η̃² − sin²θ = t + 2iηk; its modulus a² + b², and a² without the
    // cancellation of (|z| + t)/2 when t < 0.
    let t = eta * eta - k * k - s2;
    let two_ek = 2.0 * eta * k;
    let modulus = (t * t + two_ek * two_ek).sqrt();
    let a2 = if t >= 0.0 { 0.5 * (modulus + t) } else { 0.5 * two_ek * two_ek / (modulus - t) };
    let a = a2.max(0.0).sqrt();
    let (t1, t2) = (modulus + c2, 2.0 * c * a);
    let r_s = (t1 - t2) / (t1 + t2);
    let (t3, t4) = (modulus * c2 + s2 * s2, t2 * s2);
    let r_p = r_s * (t3 - t4) / (t3 + t4);
    let r = 0.5 * (r_s + r_p);
    if r.is_finite() { r.clamp(0.0, 1.0) } else { 1.0 }
}

/// Mirror reflection about the normal, ω_r = 2(n·ω)n − ω, in the local frame.
#[inline]
pub fn reflect(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Refraction in the local frame, given `cos_t` and `eta_ti` from
/// [`fresnel_dielectric`]: the seed's
/// ω_t = −(η₁/η₂)(ω − (ω·n)n) − n √(1 − (η₁/η₂)²(1 − (ω·n)²)).
#[inline]
pub fn refract(w: Vec3, cos_t: f32, eta_ti: f32) -> Vec3 {
    Vec3::new(-eta_ti * w.x, -eta_ti * w.y, cos_t)
}

/// Hemispherically averaged ("diffuse") Fresnel reflectance of an interface
/// of relative index `eta`, as the fits Mitsuba's `plastic` uses: Egan and
/// Hilgeman (1973) for η < 1, d'Eon and Irving (2011) otherwise (errors
/// below 0.6 % for 1 ≤ η ≤ 2).
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    if eta < 1.0 {
        -1.4399 * eta * eta + 0.7099 * eta + 0.6681 + 0.0636 / eta
    } else {
        let x = 1.0 / eta;
        // 0.919317 − 3.4793 x + 6.75335 x² − 7.80989 x³ + 4.98554 x⁴ − 1.36881 x⁵, x = 1/η.
        let poly = [0.919_317f32, -3.4793, 6.75335, -7.80989, 4.98554, -1.36881];
        poly.iter().rev().fold(0.0, |acc, &c| acc * x + c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn real_conductor_formula_equals_the_complex_amplitudes() {
        let mut worst = 0.0f32;
        for &(eta, k) in &[(0.2f32, 3.6), (0.0, 1.0), (1.5, 0.0), (0.05, 5.0), (1.1, 2.2), (2.5, 0.3), (0.9, 0.0), (0.3, 0.01), (3.0, 7.0)] {
            for i in 0..=200 {
                let cos = i as f32 / 200.0;
                let (par, perp) = fresnel_amplitudes(cos, Complex32::new(eta, k));
                let expected = (0.5 * (par.norm_sqr() + perp.norm_sqr())).clamp(0.0, 1.0);
                let expected = if expected.is_finite() { expected } else { 1.0 };
                let got = fresnel_conductor(cos, eta, k);
                worst = worst.max((got - expected).abs());
                assert!((got - expected).abs() <= 2e-6 + 2e-5 * expected, "η {eta} k {k} cos {cos}: {got} vs {expected}");
            }
        }
        eprintln!("largest difference {worst:e}");
    }
    use crate::math::Pcg32;
    use crate::math::sampling::square_to_uniform_sphere;
    use glam::Vec2;

    const DEG: f32 = std::f32::consts::PI / 180.0;

    #[test]
    fn normal_incidence_is_the_closed_form() {
        for eta in [1.000_277f32, 1.31, 1.333, 1.5046, 2.419, 1.0 / 1.5] {
            let expected = ((eta - 1.0) / (eta + 1.0)).powi(2);
            let f = fresnel_dielectric(1.0, eta);
            assert!((f.r - expected).abs() < 1e-6, "eta {eta}: {} vs {expected}", f.r);
            // From inside the same interface (relative index 1/η) the normal reflectance is equal.
            assert!((fresnel_dielectric(-1.0, eta).r - expected).abs() < 1e-6);
        }
        assert_eq!(fresnel_dielectric(0.7, 1.0).r, 0.0, "index-matched interfaces do not reflect");
    }

    #[test]
    fn brewster_angle_has_no_parallel_reflection() {
        for eta in [1.333f32, 1.5, 2.419] {
            let theta_b = eta.atan(); // atan(η₂/η₁)
            let f = fresnel_dielectric(theta_b.cos(), eta);
            assert!(f.r_parallel < 1e-9, "R∥ at Brewster's angle for η={eta}: {}", f.r_parallel);
            assert!(f.r_perpendicular > 0.01);
            // and not just near zero anywhere: one degree off it is clearly positive
            assert!(fresnel_dielectric((theta_b + 5.0 * DEG).cos(), eta).r_parallel > 1e-4);
            // From inside, Brewster's angle is atan(η₁/η₂).
            let inside = fresnel_dielectric(-(1.0 / eta).atan().cos(), eta);
            assert!(inside.r_parallel < 1e-9);
        }
    }

    #[test]
    fn grazing_incidence_reflects_everything() {
        for eta in [1.333f32, 1.5, 2.419] {
            let f = fresnel_dielectric(1e-4, eta);
            assert!(f.r > 0.999, "η={eta}: {}", f.r);
            assert!(fresnel_dielectric(0.0, eta).r == 1.0);
        }
        // Monotone growth from normal to grazing for an air-to-glass interface.
        let mut last = 0.0;
        for i in 0..=90 {
            let r = fresnel_dielectric((i as f32 * DEG).cos(), 1.5).r;
            assert!(r + 1e-6 >= last, "unpolarised R decreases at {i}°");
            last = r;
        }
    }

    #[test]
    fn total_internal_reflection_beyond_the_critical_angle() {
        for eta in [1.31f32, 1.333, 1.5046, 2.419] {
            // Light inside the dense medium (cos_i < 0) meets the interface to air.
            let critical = (1.0 / eta).asin();
            let just_below = fresnel_dielectric(-(critical - 0.2 * DEG).cos(), eta);
            let just_above = fresnel_dielectric(-(critical + 0.05 * DEG).cos(), eta);
            assert!(just_below.r < 1.0 && !just_below.total_internal_reflection(), "η={eta}");
            assert!(just_above.total_internal_reflection(), "η={eta}: R={}", just_above.r);
            assert_eq!(just_above.r, 1.0);
            for deg in [critical / DEG + 1.0, 60.0, 75.0, 89.0] {
                assert_eq!(fresnel_dielectric(-(deg * DEG).cos(), eta).r, 1.0, "{deg}°");
            }
            // Coming from the thin side there is never TIR.
            assert!(fresnel_dielectric((89.0 * DEG).cos(), eta).r < 1.0);
        }
    }

    #[test]
    fn reflected_plus_transmitted_is_one_and_flux_balances() {
        // R + T = 1 with T computed independently from the transmitted amplitudes
        // τ⊥ = 2η₁cosθ₁/(η₁cosθ₁+η₂cosθ₂), τ∥ = 2η₁cosθ₁/(η₂cosθ₁+η₁cosθ₂),
        // T = (η₂cosθ₂)/(η₁cosθ₁) · ½(τ⊥² + τ∥²).
        for eta in [1.2f32, 1.5, 2.4] {
            for i in 0..89 {
                let c1 = (i as f32 * DEG).cos();
                let f = fresnel_dielectric(c1, eta);
                let c2 = -f.cos_t;
                let tau_perp = 2.0 * c1 / (c1 + eta * c2);
                let tau_par = 2.0 * c1 / (eta * c1 + c2);
                let t = eta * c2 / c1 * 0.5 * (tau_perp * tau_perp + tau_par * tau_par);
                assert!((f.r + t - 1.0).abs() < 1e-5, "η={eta}, θ={i}°: R={} T={t}", f.r);
            }
        }
    }

    #[test]
    fn dielectric_is_the_k_zero_conductor() {
        for eta in [1.1f32, 1.5, 2.419, 4.0] {
            for i in 0..90 {
                let c = (i as f32 * DEG).cos();
                let d = fresnel_dielectric(c, eta).r;
                let k = fresnel_conductor(c, eta, 0.0);
                assert!((d - k).abs() < 2e-6, "η={eta}, θ={i}°: {d} vs {k}");
            }
        }
    }

    #[test]
    fn conductor_matches_tabulated_values() {
        // Reflectance at normal incidence ((η−1)² + k²)/((η+1)² + k²), and the
        // classic oblique values for gold at 550 nm (η = 0.33, k = 2.38, Palik via
        // refractiveindex.info) computed independently in f64 from the
        // Moeller closed form (a², b² for the complex cos θ_t).
        let closed = |cos: f64, n: f64, k: f64| -> f64 {
            let s2 = 1.0 - cos * cos;
            let t1 = n * n - k * k - s2;
            let a2b2 = (t1 * t1 + 4.0 * n * n * k * k).sqrt();
            let a = (0.5 * (a2b2 + t1)).sqrt();
            let rs = (a2b2 + cos * cos - 2.0 * a * cos) / (a2b2 + cos * cos + 2.0 * a * cos);
            let rp = rs * (a2b2 * cos * cos + s2 * s2 - 2.0 * a * cos * s2) / (a2b2 * cos * cos + s2 * s2 + 2.0 * a * cos * s2);
            0.5 * (rs + rp)
        };
        for (n, k) in [(0.33f32, 2.38f32), (0.2, 3.6), (1.5, 5.0), (2.6, 3.2)] {
            let normal = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
            assert!((fresnel_conductor(1.0, n, k) - normal).abs() < 1e-5);
            for i in 0..90 {
                let c = (i as f32 * DEG).cos();
                let expected = closed(c as f64, n as f64, k as f64) as f32;
                let got = fresnel_conductor(c, n, k);
                assert!((got - expected).abs() < 2e-5, "η={n} k={k} θ={i}°: {got} vs {expected}");
            }
        }
        // Gold at 550 nm reflects ≈ 0.81 at normal incidence.
        assert!((fresnel_conductor(1.0, 0.33, 2.38) - 0.817).abs() < 0.01);
        // η = 0, k = 1 (Mitsuba's material "none") is a perfect mirror at every angle.
        for i in 0..90 {
            assert!((fresnel_conductor((i as f32 * DEG).cos(), 0.0, 1.0) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn snells_law_holds_for_random_directions() {
        let mut rng = Pcg32::new(3, 1);
        for _ in 0..10_000 {
            let w = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let eta = 1.0 + 1.5 * rng.next_f32();
            let f = fresnel_dielectric(w.z, eta);
            if f.total_internal_reflection() {
                // TIR is only possible from the dense side, beyond the critical angle.
                assert!(w.z < 0.0 && (1.0 - w.z * w.z).sqrt() * eta >= 1.0 - 1e-4);
                continue;
            }
            let t = refract(w, f.cos_t, f.eta_ti);
            assert!((t.length() - 1.0).abs() < 1e-4, "refracted direction not unit: {t}");
            assert!(t.z * w.z <= 0.0, "refraction must cross the interface");
            let (eta_1, eta_2) = if w.z >= 0.0 { (1.0, eta) } else { (eta, 1.0) };
            let sin_1 = (w.x * w.x + w.y * w.y).sqrt();
            let sin_2 = (t.x * t.x + t.y * t.y).sqrt();
            assert!((eta_1 * sin_1 - eta_2 * sin_2).abs() < 1e-4, "η₁ sinθ₁ = {} vs η₂ sinθ₂ = {}", eta_1 * sin_1, eta_2 * sin_2);
            // In the plane of incidence: the tangential parts are antiparallel.
            assert!(Vec2::new(w.x, w.y).perp_dot(Vec2::new(t.x, t.y)).abs() < 1e-4);
            // Refracting back returns the original direction.
            let back = fresnel_dielectric(t.z, eta);
            let w2 = refract(t, back.cos_t, back.eta_ti);
            assert!((w2 - w).length() < 1e-3, "refract(refract(w)) = {w2} vs {w}");
            // Reflection preserves the angle to the normal and stays in the plane.
            let r = reflect(w);
            assert!((r.z - w.z).abs() < 1e-7 && (r.length() - 1.0).abs() < 1e-5);
            assert!((r.dot(Vec3::Z) - w.dot(Vec3::Z)).abs() < 1e-6);
        }
    }

    #[test]
    fn refraction_matches_the_seed_vector_formula() {
        // The seed's world-space ω_t for a normal n, compared with the local form.
        let mut rng = Pcg32::new(5, 2);
        for _ in 0..1000 {
            let w = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            if w.z <= 0.0 {
                continue;
            }
            let eta = 1.333;
            let r = 1.0 / eta; // η₁/η₂ from air into water
            let n = Vec3::Z;
            let wn = w.dot(n);
            let seed = -r * (w - wn * n) - n * (1.0 - r * r * (1.0 - wn * wn)).sqrt();
            let f = fresnel_dielectric(w.z, eta);
            assert!((refract(w, f.cos_t, f.eta_ti) - seed).length() < 1e-5);
        }
    }

    #[test]
    fn diffuse_fresnel_reflectance_matches_the_integral() {
        // Fdr(η) = ∫ F(cos θ) 2 cos θ sin θ dθ, against the fits (claimed < 0.6 %).
        for eta in [1.0f32 / 1.5, 1.0 / 1.33, 1.33, 1.49, 1.5] {
            let n = 20_000;
            let mut sum = 0.0f64;
            for i in 0..n {
                let mu = (i as f64 + 0.5) / n as f64; // cos θ, uniform: ∫ F 2μ dμ
                sum += fresnel_dielectric(mu as f32, eta).r as f64 * 2.0 * mu / n as f64;
            }
            let fit = fresnel_diffuse_reflectance(eta) as f64;
            assert!((fit - sum).abs() / sum < 0.01, "η={eta}: fit {fit} vs integral {sum}");
        }
    }
}

//! Phase functions: how a medium scatters light, per unit solid angle.
//!
//! | plugin | parameters | p(cos θ), θ between the incident travel direction and the scattered one |
//! |---|---|---|
//! | `isotropic` | — | 1 / 4π |
//! | `hg` | `g` in (−1, 1), default 0.8 | Henyey–Greenstein: (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}); g > 0 scatters forward |
//!
//! Both are sampled exactly (the weight of a sample is 1 and its density is
//! the value), and both are reciprocal: p depends on cos θ alone.
//!
//! ```xml
//! <phase type="hg"><float name="g" value="0.7"/></phase>
//! ```

use crate::math::sampling::{square_to_uniform_sphere, uniform_sphere_pdf};
use crate::math::Frame;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PhaseFunction {
    Isotropic,
    HenyeyGreenstein { g: f32 },
}

impl PhaseFunction {
    /// The value (and density) for a path that arrived travelling along
    /// `-wi` (`wi` points back where it came from, as a BSDF's does) and
    /// leaves along `wo`; both unit vectors.
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> f32 {
        match *self {
            PhaseFunction::Isotropic => uniform_sphere_pdf(),
            PhaseFunction::HenyeyGreenstein { g } => hg(g, -wi.dot(wo)),
        }
    }

    /// A scattered direction for a path arriving as in [`PhaseFunction::eval`]
    /// and its density (the weight is 1).
    #[inline]
    pub fn sample(&self, wi: Vec3, u: Vec2) -> (Vec3, f32) {
        match *self {
            PhaseFunction::Isotropic => (square_to_uniform_sphere(u), uniform_sphere_pdf()),
            PhaseFunction::HenyeyGreenstein { g } => {
                // Inverse of the CDF of cos θ about the forward direction.
                let cos = if g.abs() < 1e-3 {
                    1.0 - 2.0 * u.x
                } else {
                    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u.x);
                    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
                };
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let frame = Frame::from_normal(-wi);
                let wo = frame.to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos));
                (wo, hg(g, cos))
            }
        }
    }
}

/// Henyey–Greenstein's density of the cosine `cos` between the travel
/// directions before and after scattering.
#[inline]
fn hg(g: f32, cos: f32) -> f32 {
    let denom = 1.0 + g * g - 2.0 * g * cos;
    (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::Pcg32;

    fn directions(n: usize, seed: u64) -> impl Iterator<Item = (Vec2, Vec2)> {
        let mut rng = Pcg32::new(seed, 7);
        (0..n).map(move |_| (Vec2::new(rng.next_f32(), rng.next_f32()), Vec2::new(rng.next_f32(), rng.next_f32())))
    }

    /// The mean cosine of Henyey–Greenstein's scattering angle is g (its
    /// defining property), and the sample's density is the value.
    #[test]
    fn hg_samples_have_mean_cosine_g_and_density_equal_to_value() {
        for g in [-0.7f32, -0.2, 0.0, 0.3, 0.8, 0.95] {
            let phase = PhaseFunction::HenyeyGreenstein { g };
            let n = 400_000;
            let mut sum = 0.0f64;
            for (u, v) in directions(n, 11) {
                let wi = square_to_uniform_sphere(v);
                let (wo, pdf) = phase.sample(wi, u);
                assert!((wo.length() - 1.0).abs() < 1e-4);
                let value = phase.eval(wi, wo);
                assert!((pdf - value).abs() <= 2e-3 * value.max(1.0), "g {g}: pdf {pdf} value {value}");
                sum += (-wi.dot(wo)) as f64;
            }
            let mean = sum / n as f64;
            assert!((mean - g as f64).abs() < 4e-3, "g {g}: mean cosine {mean}");
        }
    }

    /// Every phase function integrates to 1 over the sphere (Monte Carlo
    /// with uniform directions).
    #[test]
    fn phase_functions_integrate_to_one() {
        for phase in [PhaseFunction::Isotropic, PhaseFunction::HenyeyGreenstein { g: 0.5 }, PhaseFunction::HenyeyGreenstein { g: -0.3 }] {
            let n = 400_000;
            let wi = Vec3::new(0.3, -0.4, 0.866).normalize();
            let sum: f64 = directions(n, 3).map(|(u, _)| (phase.eval(wi, square_to_uniform_sphere(u)) / uniform_sphere_pdf()) as f64).sum();
            let integral = sum / n as f64;
            assert!((integral - 1.0).abs() < 0.01, "{phase:?}: ∫p = {integral}");
        }
    }
}

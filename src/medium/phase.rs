//! Phase functions: how a medium scatters light, per unit solid angle.
//!
//! | plugin | parameters | p(cos θ), θ between the incident travel direction and the scattered one |
//! |---|---|---|
//! | `isotropic` | — | 1 / 4π |
//! | `hg` | `g` in (−1, 1), default 0.8 | Henyey–Greenstein: (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}); g > 0 scatters forward |
//! | `rayleigh` | — | 3 (1 + cos² θ) / 16π: scattering by particles far smaller than the wavelength (unpolarized) |
//! | `tabphase` | `values`: a string of at least two comma- or space-separated numbers | the values at cos θ evenly spaced from −1 to 1, linearly interpolated and normalized (cos θ = 1 is forward) |
//! | `blendphase` | `weight` (required): a float or a volume, clamped to [0, 1]; two nested phases | (1 − w) p₀ + w p₁, p₀ the first nested phase in the document |
//!
//! Each is sampled exactly: the weight of a sample is 1 and its density is
//! the value (the blend picks one of its two by the weight, and its density
//! is the blend's). All are reciprocal: p depends on cos θ alone (and the
//! blend's weight on the position).
//!
//! ```xml
//! <phase type="hg"><float name="g" value="0.7"/></phase>
//! <phase type="blendphase">
//!     <float name="weight" value="0.3"/>
//!     <phase type="rayleigh"/>
//!     <phase type="tabphase"><string name="values" value="0.5, 0.8, 1.2, 3"/></phase>
//! </phase>
//! ```

use super::Volume;
use crate::math::sampling::{square_to_uniform_sphere, uniform_sphere_pdf};
use crate::math::Frame;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::Arc;

#[derive(Clone, Debug)]
pub enum PhaseFunction {
    Isotropic,
    HenyeyGreenstein { g: f32 },
    Rayleigh,
    Tabulated(Arc<Tabulated>),
    /// `(1 − weight) · phases[0] + weight · phases[1]`.
    Blend { weight: Arc<Volume>, phases: Arc<[PhaseFunction; 2]> },
}

impl PhaseFunction {
    /// The value (and density) at `p` for a path that arrived travelling
    /// along `-wi` (`wi` points back where it came from, as a BSDF's does)
    /// and leaves along `wo`; both unit vectors.
    #[inline]
    pub fn eval(&self, p: Vec3, wi: Vec3, wo: Vec3) -> f32 {
        let cos = -wi.dot(wo);
        match self {
            PhaseFunction::Isotropic => uniform_sphere_pdf(),
            PhaseFunction::HenyeyGreenstein { g } => hg(*g, cos),
            PhaseFunction::Rayleigh => rayleigh(cos),
            PhaseFunction::Tabulated(t) => t.pdf(cos) / (2.0 * PI),
            PhaseFunction::Blend { weight, phases } => blend(blend_weight(weight, p), phases, p, wi, wo),
        }
    }

    /// A scattered direction at `p` for a path arriving as in
    /// [`PhaseFunction::eval`] and its density (the weight is 1).
    #[inline]
    pub fn sample(&self, p: Vec3, wi: Vec3, u: Vec2) -> (Vec3, f32) {
        match self {
            PhaseFunction::Isotropic => (square_to_uniform_sphere(u), uniform_sphere_pdf()),
            PhaseFunction::HenyeyGreenstein { g } => {
                let g = *g;
                // Inverse of the CDF of cos θ about the forward direction.
                let cos = if g.abs() < 1e-3 {
                    1.0 - 2.0 * u.x
                } else {
                    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u.x);
                    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
                };
                (about_forward(wi, cos, u.y), hg(g, cos))
            }
            PhaseFunction::Rayleigh => {
                // The CDF 1/2 + 3/8 (c + c³/3) = u is the cubic
                // c³ + 3c − 2z = 0 with z = 4u − 2, whose one real root
                // Cardano's formula gives.
                let z = 4.0 * u.x - 2.0;
                let root = (z * z + 1.0).sqrt();
                let cos = ((z + root).cbrt() + (z - root).cbrt()).clamp(-1.0, 1.0);
                (about_forward(wi, cos, u.y), rayleigh(cos))
            }
            PhaseFunction::Tabulated(t) => {
                let cos = t.sample(u.x);
                (about_forward(wi, cos, u.y), t.pdf(cos) / (2.0 * PI))
            }
            PhaseFunction::Blend { weight, phases } => {
                // One of the two by the weight, u.x stretched back to [0, 1).
                let w = blend_weight(weight, p);
                let (pick, ux) = if u.x < w { (1, u.x / w) } else { (0, (u.x - w) / (1.0 - w)) };
                let (wo, _) = phases[pick].sample(p, wi, Vec2::new(ux.min(ONE_MINUS_EPSILON), u.y));
                (wo, blend(w, phases, p, wi, wo))
            }
        }
    }
}

const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// The direction at angle acos(`cos`) from the travel direction `-wi`, at
/// azimuth 2π `v` about it.
#[inline]
fn about_forward(wi: Vec3, cos: f32, v: f32) -> Vec3 {
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = 2.0 * PI * v;
    Frame::from_normal(-wi).to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos))
}

/// The blend's weight at `p`: the mean of the volume's channels (one value
/// for a float or a one-channel grid), clamped to [0, 1] as Mitsuba's is.
#[inline]
fn blend_weight(weight: &Volume, p: Vec3) -> f32 {
    let v = weight.eval(p).0;
    let w = (v[0] + v[1] + v[2]) / 3.0;
    if w > 0.0 { w.min(1.0) } else { 0.0 }
}

/// The blend (1 − w)·p₀ + w·p₁ of the two phases' values (a part of weight
/// zero is not evaluated).
#[inline]
fn blend(w: f32, phases: &[PhaseFunction; 2], p: Vec3, wi: Vec3, wo: Vec3) -> f32 {
    let a = if w < 1.0 { phases[0].eval(p, wi, wo) } else { 0.0 };
    let b = if w > 0.0 { phases[1].eval(p, wi, wo) } else { 0.0 };
    (1.0 - w) * a + w * b
}

/// Henyey–Greenstein's density of the cosine `cos` between the travel
/// directions before and after scattering.
#[inline]
fn hg(g: f32, cos: f32) -> f32 {
    let denom = 1.0 + g * g - 2.0 * g * cos;
    (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
}

/// Rayleigh's density per unit solid angle.
#[inline]
fn rayleigh(cos: f32) -> f32 {
    3.0 / (16.0 * PI) * (1.0 + cos * cos)
}

/// A density of cos θ on [−1, 1], piecewise linear between values at evenly
/// spaced nodes, and its inverse CDF.
#[derive(Debug)]
pub struct Tabulated {
    /// The values, scaled so that the density integrates to 1.
    values: Vec<f32>,
    /// The CDF at each node (`cdf[0] = 0`, the last 1).
    cdf: Vec<f32>,
}

impl Tabulated {
    /// From the values at the nodes; an error (as text) unless there are at
    /// least two, none negative or non-finite, and their integral is positive.
    pub fn new(values: &[f32]) -> Result<Tabulated, String> {
        if values.len() < 2 {
            return Err(format!("needs at least two values, not {}", values.len()));
        }
        if let Some(v) = values.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
            return Err(format!("values must be finite and not negative, not {v}"));
        }
        let dx = 2.0 / (values.len() - 1) as f64;
        let mut cdf = Vec::with_capacity(values.len());
        let mut sum = 0.0f64;
        cdf.push(0.0);
        for pair in values.windows(2) {
            sum += 0.5 * (pair[0] as f64 + pair[1] as f64) * dx;
            cdf.push(sum);
        }
        if !(sum > 0.0 && sum.is_finite()) {
            return Err("the values' integral must be positive".into());
        }
        Ok(Tabulated {
            values: values.iter().map(|&v| (v as f64 / sum) as f32).collect(),
            cdf: cdf.iter().map(|&c| (c / sum) as f32).collect(),
        })
    }

    fn step(&self) -> f32 {
        2.0 / (self.values.len() - 1) as f32
    }

    /// The density of cos θ at `x`.
    #[inline]
    pub fn pdf(&self, x: f32) -> f32 {
        let n = self.values.len() - 1;
        let s = ((x + 1.0) / self.step()).clamp(0.0, n as f32);
        let i = (s as usize).min(n - 1);
        let t = s - i as f32;
        self.values[i] * (1.0 - t) + self.values[i + 1] * t
    }

    /// The x whose CDF is `u`.
    #[inline]
    pub fn sample(&self, u: f32) -> f32 {
        let n = self.values.len() - 1;
        // The interval whose CDF range holds u.
        let i = self.cdf.partition_point(|&c| c <= u).clamp(1, n) - 1;
        let (a, b) = (self.values[i], self.values[i + 1]);
        let h = self.step();
        // Within it the density is a + (b − a) t for t in [0, 1]: solve
        // h (a t + (b − a) t² / 2) = u − cdf[i] for t.
        let r = (u - self.cdf[i]) / h;
        let t = if (b - a).abs() < 1e-6 * (a + b) {
            if a > 0.0 { r / a } else { 0.5 }
        } else {
            // The root in [0, 1] of (b − a)/2 t² + a t − r = 0, in the form
            // that does not cancel.
            2.0 * r / (a + (a * a + 2.0 * (b - a) * r).max(0.0).sqrt())
        };
        (-1.0 + h * (i as f32 + t.clamp(0.0, 1.0))).clamp(-1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::Pcg32;

    fn directions(n: usize, seed: u64) -> impl Iterator<Item = (Vec2, Vec2)> {
        let mut rng = Pcg32::new(seed, 7);
        (0..n).map(move |_| (Vec2::new(rng.next_f32(), rng.next_f32()), Vec2::new(rng.next_f32(), rng.next_f32())))
    }

    /// A few of each kind: a blend of a tabulated lobe and Rayleigh.
    fn examples() -> Vec<PhaseFunction> {
        let tab = |v: &[f32]| PhaseFunction::Tabulated(Arc::new(Tabulated::new(v).expect("table")));
        let blend = |w: f32, a: PhaseFunction, b: PhaseFunction| PhaseFunction::Blend {
            weight: Arc::new(Volume::constant(crate::spectrum::Rgb::new(w, w, w), crate::math::Transform::IDENTITY)),
            phases: Arc::new([a, b]),
        };
        vec![
            PhaseFunction::Isotropic,
            PhaseFunction::HenyeyGreenstein { g: 0.5 },
            PhaseFunction::HenyeyGreenstein { g: -0.3 },
            PhaseFunction::Rayleigh,
            tab(&[1.0, 1.0]),
            tab(&[0.0, 1.0]),
            tab(&[0.2, 0.0, 0.5, 3.0, 9.0]),
            blend(0.3, PhaseFunction::Rayleigh, tab(&[0.1, 0.4, 4.0])),
            blend(0.0, PhaseFunction::Rayleigh, PhaseFunction::HenyeyGreenstein { g: 0.9 }),
            blend(1.0, PhaseFunction::Rayleigh, PhaseFunction::HenyeyGreenstein { g: 0.9 }),
        ]
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
                let (wo, pdf) = phase.sample(Vec3::ZERO, wi, u);
                assert!((wo.length() - 1.0).abs() < 1e-4);
                let value = phase.eval(Vec3::ZERO, wi, wo);
                assert!((pdf - value).abs() <= 2e-3 * value.max(1.0), "g {g}: pdf {pdf} value {value}");
                sum += (-wi.dot(wo)) as f64;
            }
            let mean = sum / n as f64;
            assert!((mean - g as f64).abs() < 4e-3, "g {g}: mean cosine {mean}");
        }
    }

    /// Every phase function integrates to 1 over the sphere (a midpoint
    /// rule over cos θ and φ about the forward direction, fine enough in
    /// cos θ for HG 0.9's peak).
    #[test]
    fn phase_functions_integrate_to_one() {
        let wi = Vec3::new(0.3, -0.4, 0.866).normalize();
        let frame = Frame::from_normal(-wi);
        let (nc, nphi) = (4000, 32);
        for phase in examples() {
            let mut sum = 0.0f64;
            for i in 0..nc {
                let c = -1.0 + 2.0 * (i as f32 + 0.5) / nc as f32;
                let s = (1.0 - c * c).max(0.0).sqrt();
                for j in 0..nphi {
                    let phi = 2.0 * PI * (j as f32 + 0.5) / nphi as f32;
                    let wo = frame.to_world(Vec3::new(s * phi.cos(), s * phi.sin(), c));
                    sum += phase.eval(Vec3::ZERO, wi, wo) as f64;
                }
            }
            let integral = sum * (2.0 / nc as f64) * (2.0 * std::f64::consts::PI / nphi as f64);
            assert!((integral - 1.0).abs() < 2e-3, "{phase:?}: ∫p = {integral}");
        }
    }

    /// Sampling draws cos θ with the density the value gives: a histogram
    /// of 20 bins of cos θ against the value's integral over each bin (2π
    /// times a fine midpoint sum), within 5 standard errors and 0.2 % of
    /// all samples; each sample's density is its value and it is a unit vector.
    #[test]
    fn samples_follow_the_value() {
        let wi = Vec3::new(-0.2, 0.5, 0.84).normalize();
        let forward = -wi;
        let side = Frame::from_normal(forward).s;
        for phase in examples() {
            let n = 200_000;
            let bins = 20;
            let mut hist = vec![0.0f64; bins];
            for (u, _) in directions(n, 5) {
                let (wo, pdf) = phase.sample(Vec3::ZERO, wi, u);
                assert!((wo.length() - 1.0).abs() < 1e-4, "{phase:?}");
                let value = phase.eval(Vec3::ZERO, wi, wo);
                assert!((pdf - value).abs() <= 1e-3 * value.max(1.0), "{phase:?}: pdf {pdf} value {value}");
                let cos = forward.dot(wo).clamp(-1.0, 1.0);
                hist[(((cos + 1.0) * 0.5 * bins as f32) as usize).min(bins - 1)] += 1.0;
            }
            for (b, &count) in hist.iter().enumerate() {
                // The value at cos θ = x, along a direction in the plane of
                // forward and side.
                let at = |x: f32| phase.eval(Vec3::ZERO, wi, x * forward + (1.0 - x * x).max(0.0).sqrt() * side) as f64;
                let steps = 200;
                let (lo, width) = (-1.0 + 2.0 * b as f64 / bins as f64, 2.0 / bins as f64);
                let expected: f64 = (0..steps)
                    .map(|k| at((lo + width * (k as f64 + 0.5) / steps as f64) as f32) * width / steps as f64)
                    .sum::<f64>()
                    * 2.0
                    * std::f64::consts::PI
                    * n as f64;
                let tolerance = 5.0 * expected.sqrt() + 2e-3 * n as f64;
                assert!((count - expected).abs() < tolerance, "{phase:?}: bin {b}: {count} samples against {expected:.0}");
            }
        }
    }

    /// Closed forms: Rayleigh's mean cos² θ is 2/5; the table (0, 1) is the
    /// density (1 + cos θ)/2 of cos θ, of mean 1/3; a blend's mean cosine is
    /// the blend of its parts' (0.7 · 0 + 0.3 · 0.6 for Rayleigh and HG 0.6).
    #[test]
    fn mean_cosines_match_closed_forms() {
        let wi = Vec3::new(0.6, 0.0, 0.8);
        let moments = |phase: &PhaseFunction| {
            let n = 400_000;
            let (mut m1, mut m2) = (0.0f64, 0.0f64);
            for (u, _) in directions(n, 9) {
                let c = -wi.dot(phase.sample(Vec3::ZERO, wi, u).0) as f64;
                m1 += c;
                m2 += c * c;
            }
            (m1 / n as f64, m2 / n as f64)
        };
        let (m1, m2) = moments(&PhaseFunction::Rayleigh);
        assert!(m1.abs() < 4e-3 && (m2 - 0.4).abs() < 3e-3, "Rayleigh: {m1} {m2}");
        let tab = PhaseFunction::Tabulated(Arc::new(Tabulated::new(&[0.0, 1.0]).expect("table")));
        let (m1, _) = moments(&tab);
        assert!((m1 - 1.0 / 3.0).abs() < 4e-3, "table: {m1}");
        let blend = PhaseFunction::Blend {
            weight: Arc::new(Volume::constant(crate::spectrum::Rgb::new(0.3, 0.3, 0.3), crate::math::Transform::IDENTITY)),
            phases: Arc::new([PhaseFunction::Rayleigh, PhaseFunction::HenyeyGreenstein { g: 0.6 }]),
        };
        let (m1, _) = moments(&blend);
        assert!((m1 - 0.18).abs() < 4e-3, "blend: {m1}");
    }

    #[test]
    fn bad_tables_are_refused() {
        assert!(Tabulated::new(&[1.0]).is_err());
        assert!(Tabulated::new(&[0.0, 0.0, 0.0]).is_err());
        assert!(Tabulated::new(&[1.0, -1.0]).is_err());
        assert!(Tabulated::new(&[1.0, f32::NAN]).is_err());
    }
}

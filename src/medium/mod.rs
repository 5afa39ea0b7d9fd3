//! Participating media: smoke, fog, murky water, the inside of a
//! subsurface-scattering object. A medium fills the inside (or outside) of
//! the shapes that name it as `interior` (or `exterior`); light travelling
//! through it is absorbed and scattered at rates σₐ, σₛ per unit length
//! (extinction σₜ = σₐ + σₛ, albedo σₛ/σₜ), and a scattered path leaves
//! in a direction drawn from the medium's [`phase`] function. Only the
//! `volpath` integrator ([`crate::integrator::volpath`]) sees media; the
//! others render as if space were empty, as Mitsuba's do.
//!
//! | plugin | parameter | type | default | meaning |
//! |---|---|---|---|---|
//! | `homogeneous` | `sigma_t` | float, rgb, spectrum or `constvolume` | 1 | extinction per unit length (before `scale`) |
//! | | `albedo` | float, rgb, spectrum or a volume | 0.75 | single-scattering albedo σₛ/σₜ (a `gridvolume` varies it in space) |
//! | | `scale` | float | 1 | multiplies `sigma_t` (changes the units) |
//! | | `sample_emitters` | boolean | true | next-event estimation at the medium's scattering points |
//! | | `has_spectral_extinction` | boolean | true | Mitsuba's speed hint; the image does not depend on it |
//! | `heterogeneous` | `sigma_t`, `albedo` | a `gridvolume` / `constvolume` or a constant | 1, 0.75 | as above; no extinction outside the box of `sigma_t` |
//! | | `scale`, `sample_emitters`, `has_spectral_extinction` | | | as above |
//! | | `majorant_resolution_factor`, `majorant_factor` | | | Mitsuba's speed hints, read and ignored |
//!
//! A `<phase>` inside the medium chooses its phase function (default
//! `isotropic`). Distances are sampled by delta tracking against one
//! majorant (the largest extinction of the medium over all channels) with
//! Kutz et al.'s spectral tracking (2017, history-aware probabilities): at
//! each tentative collision the path scatters or goes on with probabilities
//! proportional to the largest channel of σₛ·β and σₙ·β (σₙ = majorant − σₜ,
//! β the path's throughput), and β is weighted so that every channel stays
//! unbiased. A grey medium thus takes plain analogue delta tracking (no
//! null collisions in a homogeneous one); a coloured one never gives a
//! channel a weight that can run away. Transmittance along shadow rays is
//! exact (Beer–Lambert) where σₜ is constant and ratio tracking elsewhere.
//!
//! ```xml
//! <medium id="fog" type="homogeneous">
//!     <rgb name="sigma_t" value="1, 1, 1"/>
//!     <rgb name="albedo" value="0.9, 0.9, 0.9"/>
//!     <float name="scale" value="2"/>
//!     <phase type="hg"><float name="g" value="0.5"/></phase>
//! </medium>
//! <shape type="sphere"><bsdf type="null"/><ref id="fog" name="interior"/></shape>
//! ```

pub mod phase;
pub mod volume;

pub use phase::PhaseFunction;
pub use volume::{Grid, Volume, WrapMode};

use crate::sampler::Sampler;
use crate::spectrum::Spectrum;
use glam::Vec3;

/// Most tentative collisions one tracking loop takes before it gives up
/// (a path in a medium of vast optical depth; its weight is then zero).
const MAX_COLLISIONS: u32 = 1 << 20;

#[derive(Clone, Debug)]
pub struct Medium {
    pub sigma_t: Volume,
    pub albedo: Volume,
    pub scale: f32,
    pub phase: PhaseFunction,
    pub sample_emitters: bool,
    /// Mitsuba's `homogeneous`: constant extinction filling all of the
    /// space the medium is named for (not clipped to a box).
    pub homogeneous: bool,
}

impl Medium {
    #[inline]
    fn sigma_t_at<S: Spectrum>(&self, p: Vec3, wl: &S::Wavelengths) -> S {
        S::from_unbounded(self.sigma_t.eval(p), wl) * self.scale
    }

    #[inline]
    fn albedo_at<S: Spectrum>(&self, p: Vec3, wl: &S::Wavelengths) -> S {
        S::from_reflectance(self.albedo.eval(p), wl)
    }

    /// An extinction no channel exceeds anywhere (for this path's
    /// wavelengths): exact for constant σₜ; for a grid the largest value,
    /// which in the spectral modes may be uplifted to at most max(1, value).
    fn majorant<S: Spectrum>(&self, wl: &S::Wavelengths) -> f32 {
        if self.sigma_t.is_constant() {
            return self.sigma_t_at::<S>(Vec3::ZERO, wl).max_component();
        }
        let m = if S::SPECTRAL { self.sigma_t.max.max(1.0) } else { self.sigma_t.max };
        m * self.scale
    }

    /// The stretch [t0, t1] of the ray `o + t d`, 0 ≤ t ≤ `tmax`, where
    /// the medium can interact.
    #[inline]
    fn range(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<(f32, f32)> {
        if self.homogeneous {
            return Some((0.0, tmax));
        }
        let (t0, t1) = self.sigma_t.clip(o, d)?;
        let (t0, t1) = (t0.max(0.0), t1.min(tmax));
        (t0 < t1).then_some((t0, t1))
    }

    /// Samples where a path travelling from `o` along `d` first scatters
    /// before `tmax` (the next surface): `Some(t)` for a scattering at
    /// `o + t d`, `None` if it reaches `tmax`. `beta`, the path's
    /// throughput, takes the estimator's weights (zero if the path is
    /// absorbed for good).
    pub fn sample_scattering<S: Spectrum>(&self, o: Vec3, d: Vec3, tmax: f32, beta: &mut S, sampler: &mut Sampler, wl: &S::Wavelengths) -> Option<f32> {
        let (t0, t1) = self.range(o, d, tmax)?;
        let mu_bar = self.majorant::<S>(wl);
        if !(mu_bar > 0.0) {
            return None;
        }
        let mut t = t0;
        for _ in 0..MAX_COLLISIONS {
            t -= (1.0 - sampler.next_1d()).ln() / mu_bar;
            if !(t < t1) {
                return None;
            }
            let p = o + d * t;
            let mu_t = self.sigma_t_at::<S>(p, wl);
            let mu_s = mu_t * self.albedo_at::<S>(p, wl);
            let mu_n = mu_t.zip_map(mu_t, |m, _| (mu_bar - m).max(0.0));
            let p_s = (mu_s * *beta).max_component();
            let p_n = (mu_n * *beta).max_component();
            let total = p_s + p_n;
            if !(total > 0.0) || !total.is_finite() {
                *beta = S::zero();
                return None;
            }
            if sampler.next_1d() * total < p_s {
                *beta *= mu_s * (total / (mu_bar * p_s));
                return Some(t);
            }
            *beta *= mu_n * (total / (mu_bar * p_n));
        }
        *beta = S::zero();
        None
    }

    /// The fraction of light that crosses the medium from `o` to
    /// `o + tmax d`: exact where σₜ is constant, else a ratio-tracking
    /// estimate (unbiased, never negative).
    pub fn transmittance<S: Spectrum>(&self, o: Vec3, d: Vec3, tmax: f32, sampler: &mut Sampler, wl: &S::Wavelengths) -> S {
        let Some((t0, t1)) = self.range(o, d, tmax) else { return S::splat(1.0) };
        if self.sigma_t.is_constant() {
            let mu = self.sigma_t_at::<S>(o, wl);
            let len = t1 - t0;
            return mu.zip_map(mu, |m, _| if m > 0.0 { (-m * len).exp() } else { 1.0 });
        }
        let mu_bar = self.majorant::<S>(wl);
        if !(mu_bar > 0.0) {
            return S::splat(1.0);
        }
        let mut tr = S::splat(1.0);
        let mut t = t0;
        for _ in 0..MAX_COLLISIONS {
            t -= (1.0 - sampler.next_1d()).ln() / mu_bar;
            if !(t < t1) {
                return tr;
            }
            let mu_t = self.sigma_t_at::<S>(o + d * t, wl);
            tr *= mu_t.zip_map(mu_t, |m, _| (1.0 - m / mu_bar).max(0.0));
            if tr.is_zero() {
                return tr;
            }
        }
        S::zero()
    }
}

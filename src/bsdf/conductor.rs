//! `conductor` — a smooth metal: ideal mirror reflection weighted by the
//! exact Fresnel reflectance of a complex index of refraction η + ik.
//!
//! The seed's ideal specular BRDF f_r = F_r(ω_i) δ(ω_r − R(ω_i, n)) / cos θ_i
//! with R(ω, n) = 2(n·ω)n − ω: all reflected light leaves in the mirror
//! direction, the cosine in the denominator cancelling the one of the
//! reflection equation, so L_r = F_r L_i. F_r is evaluated per colour
//! channel from the conductor Fresnel equations (no Schlick). The lobe is a
//! delta: `eval` and `pdf` are zero and only `sample` produces it.
//!
//! η and k are relative to the exterior medium; they are given directly or
//! by `material` name: the metals Mitsuba 3 accepts, with Mitsuba's RGB
//! values of their measured spectral data (see `metals.rs` for the source),
//! or `none`, a perfect mirror (η = 0, k = 1, F = 1 at every angle).
//! One-sided like Mitsuba's: the back is black (use `twosided`).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `material` | string | `none` | named metal (`Au`, `Ag`, `Al`, `Cu`, `Cr`, …) |
//! | `eta`, `k` | rgb / spectrum / float | 0, 1 | complex index, instead of `material` |
//!
//! In the spectral modes η and k are read as Mitsuba 3.9.1 reads them: a
//! `float` (or constant `<spectrum>`) is the same at every wavelength, a
//! `<spectrum>` of `wavelength:value` pairs is used as listed, and an `rgb`
//! becomes Mitsuba's `srgb` texture: the colour is clamped to [0, 1] and
//! uplifted as a reflectance (so an rgb k of (3.9, 2.45, 2.1) is k(λ) ≈ 1).
//! The RGB modes use the rgb values as given.
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale (not physical; leave at 1) |
//!
//! ```xml
//! <bsdf type="conductor"><string name="material" value="Au"/></bsdf>
//! ```

use super::fresnel::{fresnel_conductor, reflect};
use super::{BsdfContext, BsdfModel, BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use super::metal_spectra::MetalSpectra;
use crate::scene::error::{Result, SceneError};
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::mueller::{conductor_parameters, interface_from_parameters, interface_to_canonical};
use crate::spectrum::{ListedSpectrum, Rgb, Spectrum, UpliftCache};
use crate::texture::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Conductor {
    pub eta: Rgb,
    pub k: Rgb,
    /// The measured spectra of a named metal, used in spectral modes.
    pub spectra: Option<&'static MetalSpectra>,
    pub specular_reflectance: Texture,
    /// How `eta` and `k` were given, which decides their spectral-mode
    /// values when there are no measured `spectra`.
    pub given: [IndexInput; 2],
}

/// How one of a conductor's η, k was given in the scene (its spectral-mode
/// value follows Mitsuba 3.9.1; the RGB modes use the RGB value).
#[derive(Clone, Debug)]
pub enum IndexInput {
    /// `rgb`: Mitsuba's `srgb` texture, the colour clamped to [0, 1] and
    /// uplifted as a reflectance (the uplift kept once computed).
    Rgb(UpliftCache),
    /// `float` or constant `<spectrum>`: that value at every wavelength.
    Uniform,
    /// A `<spectrum>` of `wavelength:value` pairs.
    Listed(ListedSpectrum),
}

impl Default for IndexInput {
    fn default() -> Self {
        IndexInput::Rgb(UpliftCache::default())
    }
}

impl IndexInput {
    /// How `name` is given in `props` (an absent one is a float default).
    fn of(props: &Props, name: &str) -> IndexInput {
        use crate::scene::xml::Value;
        if let Some(listed) = props.listed_opt(name) {
            return IndexInput::Listed(listed);
        }
        match props.node.props.iter().find(|p| p.name == name).map(|p| &p.value) {
            Some(Value::Rgb(_)) => IndexInput::default(),
            _ => IndexInput::Uniform,
        }
    }

    /// The value at the path's channels of the quantity whose RGB value is `rgb`.
    #[inline]
    fn value<S: Spectrum>(&self, rgb: Rgb, wl: &S::Wavelengths) -> S {
        match self {
            IndexInput::Rgb(cache) => S::from_reflectance_cached(rgb, cache, wl),
            IndexInput::Uniform => S::from_function(rgb, |_| rgb.0[0], wl),
            IndexInput::Listed(s) => S::from_function(rgb, |l| s.eval(l), wl),
        }
    }
}

/// Reads a conductor's complex index: `eta`/`k` given directly, or a named
/// `material` (or `none`, a perfect mirror); with a named metal, its
/// measured spectra for the spectral modes.
pub fn read_index(props: &Props) -> Result<(Rgb, Rgb, Option<&'static MetalSpectra>, [IndexInput; 2])> {
    let node = props.node;
    let material = props.string_opt("material")?;
    let given = props.has("eta") || props.has("k");
    let mut spectra = None;
    let given_as = [IndexInput::of(props, "eta"), IndexInput::of(props, "k")];
    let (eta, k) = match material {
        Some(name) if name != "none" => {
            let loc = node.props.iter().find(|p| p.name == "material").map_or(&node.loc, |p| &p.loc);
            if given {
                return Err(SceneError::at(loc, "give either \"material\" or \"eta\"/\"k\", not both"));
            }
            let metal = super::metals::METALS.iter().find(|m| m.name == name).ok_or_else(|| {
                let mut names: Vec<&str> = super::metals::METALS.iter().map(|m| m.name).collect();
                names.push("none");
                SceneError::at(loc, format!("unknown conductor material \"{name}\"")).with_choices(&names)
            })?;
            spectra = super::metal_spectra::METAL_SPECTRA.iter().find(|m| m.name == name);
            (Rgb(metal.eta), Rgb(metal.k))
        }
        _ => (props.color("eta", Rgb::BLACK)?, props.color("k", Rgb::WHITE)?),
    };
    if !(eta.is_finite() && k.is_finite() && eta.0.iter().chain(&k.0).all(|&v| v >= 0.0)) {
        return Err(SceneError::at(&node.loc, format!("{} \"eta\" and \"k\" must be finite and not negative", node.plugin)));
    }
    Ok((eta, k, spectra, given_as))
}

impl Conductor {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<Conductor> {
        let specular_reflectance = loader.reflectance(props, "specular_reflectance", Rgb::WHITE)?;
        let (eta, k, spectra, given) = read_index(props)?;
        Ok(Conductor { eta, k, spectra, specular_reflectance, given })
    }

    /// The complex index η + ik at the path's channels.
    pub fn index<S: Spectrum>(&self, wl: &S::Wavelengths) -> (S, S) {
        match self.spectra {
            Some(m) => (S::from_function(self.eta, |l| tabulated(m.eta, l), wl), S::from_function(self.k, |l| tabulated(m.k, l), wl)),
            None => (self.given[0].value(self.eta, wl), self.given[1].value(self.k, wl)),
        }
    }

    /// The Fresnel reflectance per channel for incidence cosine `cos_i`.
    pub fn fresnel<S: Spectrum>(&self, cos_i: f32, wl: &S::Wavelengths) -> S {
        let (eta, k) = self.index::<S>(wl);
        eta.zip_map(k, |e, k| fresnel_conductor(cos_i, e, k))
    }

    /// The Fresnel reflection per channel as a Mueller matrix (polarized
    /// modes): incidence cosine `cos_i` on a mirror of world normal `n`,
    /// light arriving along `incident` and leaving along `outgoing` (world),
    /// in the canonical Stokes frames of those directions.
    #[inline]
    pub fn fresnel_mueller<S: Spectrum>(&self, cos_i: f32, n: Vec3, incident: Vec3, outgoing: Vec3, wl: &S::Wavelengths) -> S {
        let (eta, k) = self.index::<S>(wl);
        let (eta, k) = (eta.channels(), k.channels());
        // The s/p matrix is linear in its four parameters, and so is the
        // change to canonical frames: rotate the four unit matrices once,
        // then combine them with each channel's parameters.
        let unit = |i: usize| {
            let mut p = [0.0; 4];
            p[i] = 1.0;
            interface_to_canonical(interface_from_parameters(p), n, incident, outgoing)
        };
        let basis = [unit(0), unit(1), unit(2), unit(3)];
        let params = [0, 1, 2, 3].map(|i| eta.zip_map(k, |e, kk| conductor_parameters(cos_i, e, kk)[i]));
        S::mueller_channels(|r, c| {
            let mut v = params[0] * basis[0].col(c)[r];
            for i in 1..4 {
                v += params[i] * basis[i].col(c)[r];
            }
            v
        })
    }
}

impl BsdfModel for Conductor {
    fn lobes(&self) -> Lobe {
        Lobe::DELTA_REFLECTION
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    #[inline]
    fn eval<S: Spectrum>(&self, _ctx: &BsdfContext, _si: &SurfaceInteraction, _wi: Vec3, _wo: Vec3, _wl: &S::Wavelengths) -> S {
        S::zero()
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, _ctx: &BsdfContext, _si: &SurfaceInteraction, _wi: Vec3, _wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        0.0
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, _u1: f32, _u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z <= 0.0 || !ctx.wants(Lobe::DELTA_REFLECTION) {
            return None;
        }
        let wo = reflect(wi);
        let scale = self.specular_reflectance.eval_spectrum::<S>(si.uv, wl);
        let weight = if S::POLARIZED {
            // The Fresnel matrix in the canonical frames of the incident
            // (along −wo) and outgoing (along wi) light.
            self.fresnel_mueller::<S>(wo.z, si.frame.n, -si.to_world(wo), si.to_world(wi), wl) * scale
        } else {
            self.fresnel::<S>(wi.z, wl) * scale
        };
        Some(BsdfSample { wo, weight, pdf: 1.0, eta: 1.0, lobe: Lobe::DELTA_REFLECTION })
    }
}

/// Linear interpolation in (λ, value) points; zero outside them (as
/// Mitsuba's irregular spectra).
fn tabulated(points: &[[f32; 2]], lambda: f32) -> f32 {
    let i = points.partition_point(|p| p[0] < lambda);
    if i == 0 || i == points.len() {
        // Exactly on the first point, or outside the range.
        return match points.first() {
            Some(p) if i == 0 && p[0] == lambda => p[1],
            _ => 0.0,
        };
    }
    let ([l0, v0], [l1, v1]) = (points[i - 1], points[i]);
    v0 + (v1 - v0) * (lambda - l0) / (l1 - l0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::testing::*;
    use crate::bsdf::{Bsdf, BsdfContext};

    fn gold() -> Bsdf {
        Bsdf::Conductor(Conductor {
            eta: Rgb::new(0.2, 0.45, 1.4),
            k: Rgb::new(3.6, 2.5, 1.9),
            spectra: None,
            specular_reflectance: Texture::constant(Rgb::WHITE),
            given: Default::default(),
        })
    }

    #[test]
    fn mirror_direction_with_fresnel_weight() {
        let b = gold();
        let si = dummy_interaction();
        for theta in [0.0f32, 0.5, 1.0, 1.5] {
            let wi = incident(theta, 0.7);
            let s = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, 0.3, Vec2::new(0.2, 0.9), &()).expect("front side reflects");
            assert!((s.wo - Vec3::new(-wi.x, -wi.y, wi.z)).length() < 1e-6);
            assert!(s.lobe == Lobe::DELTA_REFLECTION);
            for c in 0..3 {
                let Bsdf::Conductor(g) = &b else { unreachable!() };
                let f = fresnel_conductor(wi.z, g.eta[c], g.k[c]);
                assert!((s.weight[c] - f).abs() < 1e-6 && f > 0.3 && f <= 1.0);
            }
        }
    }

    #[test]
    fn delta_lobe_has_no_density_and_back_is_black() {
        let b = gold();
        let si = dummy_interaction();
        let wi = incident(0.4, 0.0);
        check_sample_consistency(&b, wi, 3);
        assert!(b.eval::<Rgb>(&BsdfContext::RADIANCE, &si, wi, Vec3::new(-wi.x, -wi.y, wi.z), &()).is_zero());
        assert_eq!(b.pdf::<Rgb>(&BsdfContext::RADIANCE, &si, wi, Vec3::new(-wi.x, -wi.y, wi.z), &()), 0.0);
        let back = Vec3::new(wi.x, wi.y, -wi.z);
        assert!(b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, back, 0.5, Vec2::splat(0.5), &()).is_none());
    }

    #[test]
    fn measured_spectra_reduce_to_the_rgb_table() {
        // Converting each metal's measured η(λ), k(λ) to linear sRGB as Mitsuba
        // does (1000 wavelengths over 360–830 nm, CIE 1931, zero outside the
        // data) gives back the RGB values of metals.rs: the spectra and
        // `tabulated` agree with the table the RGB mode uses.
        use crate::bsdf::metal_spectra::METAL_SPECTRA;
        use crate::bsdf::metals::METALS;
        use crate::spectrum::cie::{cie_xyz, xyz_to_linear_srgb};
        let to_rgb = |points: &[[f32; 2]]| {
            let mut xyz = [0.0f64; 3];
            for i in 0..1000 {
                let l = 360.0 + i as f32 / 999.0 * 470.0;
                let c = cie_xyz(l);
                let v = tabulated(points, l) as f64;
                for k in 0..3 {
                    xyz[k] += c[k] as f64 * v * 0.47 / 106.750_259_4;
                }
            }
            xyz_to_linear_srgb(xyz.map(|v| v as f32)).map(|v| v.max(0.0))
        };
        assert_eq!(METAL_SPECTRA.len(), METALS.len());
        for (spectra, metal) in METAL_SPECTRA.iter().zip(METALS) {
            assert_eq!(spectra.name, metal.name);
            for (points, rgb) in [(spectra.eta, metal.eta), (spectra.k, metal.k)] {
                let got = to_rgb(points);
                for c in 0..3 {
                    assert!((got.0[c] - rgb[c]).abs() <= 2e-3 * (1.0 + rgb[c].abs()), "{}: {got:?} vs {rgb:?}", metal.name);
                }
            }
        }
        // Interpolation: exact at points, linear between, zero outside.
        let p = [[400.0, 1.0], [500.0, 3.0]];
        assert_eq!((tabulated(&p, 400.0), tabulated(&p, 450.0), tabulated(&p, 500.0)), (1.0, 2.0, 3.0));
        assert_eq!((tabulated(&p, 399.0), tabulated(&p, 501.0)), (0.0, 0.0));
    }
}

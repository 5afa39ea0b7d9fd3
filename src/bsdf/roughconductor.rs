//! `roughconductor` — a rough metal: the microfacet model of Walter et al.
//! (2007) over the conductor Fresnel reflectance, as Mitsuba 3's.
//!
//! Each microfacet is a smooth conductor mirror (`conductor`); with
//! h = (wi + wo)/‖wi + wo‖ the half vector,
//!
//! f(wi, wo) = F(wi·h) D(h) G(wi, wo, h) / (4 cos θ_i cos θ_o),
//!
//! with D and G from `microfacet.rs`. Only single scattering between
//! facets is modelled, so rough metals lose energy at high α (as in
//! Mitsuba). Sampling draws a microfacet normal (visible normals by
//! default) and reflects wi about it; the weight is then F G1(wo) (visible
//! normals) or F G (wi·m)/(cos θ_i cos θ_m). One-sided: the back is black.
//!
//! Polarisation (polarized modes): each facet reflects by the Fresnel
//! equations of the complex index in Mueller form, in the s/p frame of its
//! own plane of incidence (spanned by wi and the facet normal h), turned to
//! the canonical Stokes frames of the incident and outgoing beams.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `material` | string | `none` | named metal (`Au`, `Ag`, `Al`, `Cu`, `Cr`, …; see `conductor`) |
//! | `eta`, `k` | rgb / spectrum / float | 0, 1 | complex index, instead of `material` |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale (not physical; leave at 1) |
//! | `distribution` | string | `beckmann` | `beckmann` or `ggx` |
//! | `alpha` | float / texture | 0.1 | roughness |
//! | `alpha_u`, `alpha_v` | float / texture | — | anisotropic roughness along ∂p/∂u and across it |
//! | `sample_visible` | boolean | true | sample visible normals only |
//!
//! ```xml
//! <bsdf type="roughconductor">
//!     <string name="material" value="Al"/>
//!     <string name="distribution" value="ggx"/>
//!     <float name="alpha_u" value="0.05"/>
//!     <float name="alpha_v" value="0.3"/>
//! </bsdf>
//! ```

use super::conductor::{Conductor, read_index};
use super::microfacet::MicrofacetParams;
use super::{BsdfContext, BsdfModel, BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::{Rgb, Spectrum};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct RoughConductor {
    /// The complex index and the reflectance scale (a smooth conductor's).
    pub facet: Conductor,
    pub roughness: MicrofacetParams,
}

impl RoughConductor {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<RoughConductor> {
        let specular_reflectance = loader.texture(props, "specular_reflectance", Rgb::WHITE)?;
        let (eta, k, spectra, given) = read_index(props)?;
        let roughness = MicrofacetParams::from_props(props, loader)?;
        Ok(RoughConductor { facet: Conductor { eta, k, spectra, specular_reflectance, given }, roughness })
    }

    /// The Fresnel factor of facet `m` (local) for wi, times the reflectance scale.
    #[inline]
    fn fresnel<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, m: Vec3, wl: &S::Wavelengths) -> S {
        let scale = self.facet.specular_reflectance.eval_spectrum::<S>(si.uv, wl);
        let cos = wi.dot(m);
        if S::POLARIZED {
            // Light arrives along −wo and leaves along wi (towards the camera),
            // reflected by the facet of world normal m.
            self.facet.fresnel_mueller::<S>(cos, si.to_world(m), -si.to_world(wo), si.to_world(wi), wl) * scale
        } else {
            self.facet.fresnel::<S>(cos, wl) * scale
        }
    }
}

impl BsdfModel for RoughConductor {
    fn lobes(&self) -> Lobe {
        Lobe::GLOSSY_REFLECTION
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    fn needs_tangent_frame(&self) -> bool {
        self.roughness.is_anisotropic()
    }

    #[inline]
    fn eval<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> S {
        if wi.z <= 0.0 || wo.z <= 0.0 || !ctx.wants(Lobe::GLOSSY_REFLECTION) {
            return S::zero();
        }
        let h = (wi + wo).normalize();
        let mf = self.roughness.at(si);
        let d = mf.d(h);
        if d == 0.0 {
            return S::zero();
        }
        let g = mf.g(wi, wo, h);
        if g == 0.0 {
            return S::zero();
        }
        self.fresnel::<S>(si, wi, wo, h, wl) * (d * g / (4.0 * wi.z))
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 || !ctx.wants(Lobe::GLOSSY_REFLECTION) {
            return 0.0;
        }
        let h = (wi + wo).normalize();
        if wi.dot(h) <= 0.0 || wo.dot(h) <= 0.0 {
            return 0.0;
        }
        // The density of h, times the Jacobian of reflection dω_h/dω_o = 1/(4 wo·h).
        self.roughness.at(si).pdf(wi, h) / (4.0 * wo.dot(h))
    }

    /// `eval` and `pdf` sharing the half vector, the distribution, D and
    /// G1(wi); the same floating-point operations as the two apart.
    #[inline]
    fn eval_pdf<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, wo: Vec3, wl: &S::Wavelengths) -> (S, f32) {
        if wi.z <= 0.0 || wo.z <= 0.0 || !ctx.wants(Lobe::GLOSSY_REFLECTION) {
            return (S::zero(), 0.0);
        }
        let h = (wi + wo).normalize();
        let (cos_ih, cos_oh) = (wi.dot(h), wo.dot(h));
        let mf = self.roughness.at(si);
        let d = mf.d(h);
        if d == 0.0 {
            return (S::zero(), 0.0);
        }
        let g1_wi = mf.g1(wi, h);
        let pdf = if cos_ih <= 0.0 || cos_oh <= 0.0 {
            0.0
        } else if mf.sample_visible {
            d * g1_wi * cos_ih.abs() / wi.z / (4.0 * cos_oh)
        } else {
            d * h.z / (4.0 * cos_oh)
        };
        let g = g1_wi * mf.g1(wo, h);
        if g == 0.0 {
            return (S::zero(), pdf);
        }
        (self.fresnel::<S>(si, wi, wo, h, wl) * (d * g / (4.0 * wi.z)), pdf)
    }

    #[inline]
    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, _u1: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if wi.z <= 0.0 || !ctx.wants(Lobe::GLOSSY_REFLECTION) {
            return None;
        }
        let mf = self.roughness.at(si);
        let (m, pdf_m) = mf.sample(wi, u2);
        let cos_im = wi.dot(m);
        let wo = 2.0 * cos_im * m - wi;
        if !(pdf_m > 0.0) || wo.z <= 0.0 || cos_im <= 0.0 {
            return None;
        }
        let g = if mf.sample_visible { mf.g1(wo, m) } else { mf.g(wi, wo, m) * cos_im / (wi.z * m.z) };
        if !(g > 0.0) {
            return None;
        }
        let pdf = pdf_m / (4.0 * cos_im);
        Some(BsdfSample { wo, weight: self.fresnel::<S>(si, wi, wo, m, wl) * g, pdf, eta: 1.0, lobe: Lobe::GLOSSY_REFLECTION })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::microfacet::MicrofacetType;
    use crate::bsdf::testing::*;
    use crate::bsdf::{Bsdf, Conductor};
    use crate::texture::Texture;

    fn metal(kind: MicrofacetType, au: f32, av: Option<f32>, visible: bool) -> RoughConductor {
        RoughConductor {
            facet: Conductor {
                eta: Rgb::new(0.2, 0.45, 1.4),
                k: Rgb::new(3.6, 2.5, 1.9),
                spectra: None,
                specular_reflectance: Texture::constant(Rgb::WHITE),
                given: Default::default(),
            },
            roughness: MicrofacetParams {
                kind,
                alpha_u: Texture::constant(Rgb::new(au, au, au)),
                alpha_v: av.map(|a| Texture::constant(Rgb::new(a, a, a))),
                sample_visible: visible,
            },
        }
    }

    fn all_kinds() -> Vec<(RoughConductor, &'static str)> {
        let mut v = vec![];
        for kind in [MicrofacetType::Beckmann, MicrofacetType::Ggx] {
            for visible in [true, false] {
                for (au, av) in [(0.05, None), (0.3, None), (1.0, None), (0.1, Some(0.4))] {
                    v.push((metal(kind, au, av, visible), "metal"));
                }
            }
        }
        v
    }

    #[test]
    fn chi2_sampling_matches_pdf() {
        let mut seed = 300;
        for (m, _) in all_kinds() {
            let b = Bsdf::RoughConductor(m);
            for theta in [0.1f32, 0.9, 1.45] {
                seed += 1;
                // 48 tests at 1 % overall.
                chi2_test_at(&b, incident(theta, 0.6), seed, 0.01 / 48.0);
            }
        }
    }

    #[test]
    fn reciprocal_consistent_and_energy_conserving() {
        let mut seed = 400;
        for (m, _) in all_kinds() {
            let b = Bsdf::RoughConductor(m);
            seed += 1;
            check_reciprocity(&b, seed);
            for theta in [0.0f32, 0.8, 1.4] {
                check_sample_consistency(&b, incident(theta, 1.1), seed + 50);
                let albedo = estimate_albedo_sampled(&b, incident(theta, 1.1), 100_000, seed + 90);
                for c in 0..3 {
                    assert!(albedo[c] <= 1.0 + 0.01, "albedo {albedo:?}");
                }
            }
        }
    }

    #[test]
    fn white_furnace_loss_is_mitsubas_single_scattering_loss() {
        // A perfect mirror (η = 0, k = 1: F = 1): the albedo is the fraction
        // of light that leaves after one facet bounce; the rest (multiple
        // scattering between facets) is lost, as in every single-scattering
        // model. Mitsuba 3.9.1's roughconductor (scalar_rgb, mean sample
        // weight over 40 000 samples, computed once with its Python bindings) gives:
        let mitsuba = [
            (MicrofacetType::Ggx, 0.05, 0.0, 0.9973),
            (MicrofacetType::Ggx, 0.5, 0.0, 0.6869),
            (MicrofacetType::Ggx, 0.5, 1.2, 0.7027),
            (MicrofacetType::Ggx, 1.0, 0.0, 0.3063),
            (MicrofacetType::Ggx, 1.0, 1.2, 0.4491),
            (MicrofacetType::Beckmann, 0.05, 1.2, 1.0),
            (MicrofacetType::Beckmann, 0.5, 0.0, 0.9431),
            (MicrofacetType::Beckmann, 0.5, 1.2, 0.8825),
            (MicrofacetType::Beckmann, 1.0, 0.0, 0.4603),
            (MicrofacetType::Beckmann, 1.0, 1.2, 0.8139),
        ];
        for (i, (kind, alpha, theta, expected)) in mitsuba.into_iter().enumerate() {
            let mut m = metal(kind, alpha, None, true);
            m.facet.eta = Rgb::BLACK;
            m.facet.k = Rgb::WHITE;
            let albedo = estimate_albedo_sampled(&Bsdf::RoughConductor(m), incident(theta, 0.0), 200_000, i as u64)[0];
            assert!((albedo - expected).abs() < 0.012, "{kind:?} α={alpha} θ={theta}: {albedo} vs Mitsuba {expected}");
        }
    }

    #[test]
    fn alpha_to_zero_is_the_smooth_conductor() {
        // As α → 0 the lobe narrows onto the mirror direction and its
        // albedo becomes the smooth conductor's Fresnel reflectance.
        let smooth = metal(MicrofacetType::Ggx, 0.0, None, true).facet;
        for theta in [0.2f32, 0.9, 1.3] {
            let wi = incident(theta, 0.3);
            let f: Rgb = smooth.fresnel(wi.z, &());
            let rough = Bsdf::RoughConductor(metal(MicrofacetType::Ggx, 0.001, None, true));
            let albedo = estimate_albedo_sampled(&rough, wi, 20_000, 7);
            let si = dummy_interaction();
            let s = rough.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, 0.5, Vec2::new(0.3, 0.7), &()).expect("reflects");
            assert!((s.wo - Vec3::new(-wi.x, -wi.y, wi.z)).length() < 0.01);
            for c in 0..3 {
                assert!((albedo[c] - f[c]).abs() < 0.01, "θ={theta}: {albedo:?} vs {f:?}");
            }
        }
    }

    #[test]
    fn eval_pdf_is_eval_and_pdf() {
        use crate::spectrum::Polarized;
        let si = dummy_interaction();
        let mut rng = crate::math::Pcg32::new(5, 9);
        for (m, _) in all_kinds() {
            let b = Bsdf::RoughConductor(m);
            for _ in 0..300 {
                let mut dir = || Vec3::new(2.0 * rng.next_f32() - 1.0, 2.0 * rng.next_f32() - 1.0, 2.0 * rng.next_f32() - 0.3).normalize();
                let (wi, wo) = (dir(), dir());
                let ctx = BsdfContext::RADIANCE;
                let (f, p): (Rgb, f32) = b.eval_pdf(&ctx, &si, wi, wo, &());
                assert_eq!((f, p), (b.eval::<Rgb>(&ctx, &si, wi, wo, &()), b.pdf::<Rgb>(&ctx, &si, wi, wo, &())));
                let (f, p): (Polarized<Rgb>, f32) = b.eval_pdf(&ctx, &si, wi, wo, &());
                assert_eq!((f, p), (b.eval::<Polarized<Rgb>>(&ctx, &si, wi, wo, &()), b.pdf::<Polarized<Rgb>>(&ctx, &si, wi, wo, &())));
            }
        }
    }

    #[test]
    fn rotating_the_frame_swaps_alpha_u_and_alpha_v() {
        let a = Bsdf::RoughConductor(metal(MicrofacetType::Beckmann, 0.1, Some(0.5), true));
        let b = Bsdf::RoughConductor(metal(MicrofacetType::Beckmann, 0.5, Some(0.1), true));
        assert!(a.needs_tangent_frame());
        let rot = |v: Vec3| Vec3::new(-v.y, v.x, v.z);
        let si = dummy_interaction();
        let mut rng = crate::math::Pcg32::new(3, 3);
        for _ in 0..500 {
            let wi = crate::math::sampling::square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let wo = crate::math::sampling::square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let (x, y): (Rgb, Rgb) = (a.eval(&BsdfContext::RADIANCE, &si, wi, wo, &()), b.eval(&BsdfContext::RADIANCE, &si, rot(wi), rot(wo), &()));
            for c in 0..3 {
                assert!((x[c] - y[c]).abs() <= 1e-4 * x[c].max(1.0));
            }
        }
    }

    #[test]
    fn polarized_weights_have_the_unpolarized_intensity_and_polarize() {
        use crate::spectrum::Polarized;
        use crate::spectrum::mueller::degree_of_polarization;
        use glam::Vec4;
        let n = Vec3::new(0.2, -0.4, 0.9).normalize();
        let si = SurfaceInteraction { n, frame: crate::math::Frame::from_normal(n), ..dummy_interaction() };
        let b = Bsdf::RoughConductor(metal(MicrofacetType::Beckmann, 0.2, Some(0.4), true));
        let mut rng = crate::math::Pcg32::new(32, 4);
        let mut max_dop = 0.0f32;
        for _ in 0..3000 {
            let wi = crate::math::sampling::square_to_cosine_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            let u2 = Vec2::new(rng.next_f32(), rng.next_f32());
            let x = b.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, 0.5, u2, &());
            let y = b.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, 0.5, u2, &());
            let (Some(x), Some(y)) = (x, y) else {
                assert!(x.is_none() && y.is_none());
                continue;
            };
            assert!(x.wo == y.wo && x.pdf == y.pdf);
            for c in 0..3 {
                assert!((y.weight.0[0][0][c] - x.weight[c]).abs() <= 1e-4 * (1.0 + x.weight[c]));
            }
            let st = y.weight.stokes();
            max_dop = max_dop.max(degree_of_polarization(Vec4::new(st[0][0], st[1][0], st[2][0], st[3][0])));
            let (f, g): (Rgb, Polarized<Rgb>) = (b.eval(&BsdfContext::RADIANCE, &si, wi, x.wo, &()), b.eval(&BsdfContext::RADIANCE, &si, wi, x.wo, &()));
            assert!((g.0[0][0][0] - f[0]).abs() <= 1e-4 * (1.0 + f[0]));
        }
        // Gold reflects unpolarised light partly polarised (a few per cent
        // in RGB at oblique angles): not a depolarizer.
        assert!(max_dop > 0.02, "{max_dop}");
        // Nearly smooth, the Mueller weight is the smooth conductor's.
        let rough = Bsdf::RoughConductor(metal(MicrofacetType::Beckmann, 0.0005, None, true));
        let Bsdf::RoughConductor(m) = &rough else { unreachable!() };
        let smooth = Bsdf::Conductor(m.facet.clone());
        for theta in [0.4f32, 1.0, 1.3] {
            let wi = incident(theta, 0.7);
            let a = rough.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, 0.5, Vec2::new(0.3, 0.6), &()).expect("reflects");
            let b = smooth.sample::<Polarized<Rgb>>(&BsdfContext::RADIANCE, &si, wi, 0.5, Vec2::new(0.3, 0.6), &()).expect("reflects");
            for r in 0..4 {
                for c in 0..4 {
                    for k in 0..3 {
                        assert!((a.weight.0[r][c][k] - b.weight.0[r][c][k]).abs() < 0.01, "θ={theta} m[{r}][{c}]: {:?} vs {:?}", a.weight.0[r][c], b.weight.0[r][c]);
                    }
                }
            }
        }
    }

    /// Spectral η and k as Mitsuba 3.9.1 reads them (an `rgb` clamped to
    /// [0, 1] and uplifted as a reflectance, a `float` constant): Snell's
    /// eval at four wavelengths against tests/data/roughconductor_spectral_values.txt,
    /// Mitsuba's scalar_spectral values made by
    /// tools/roughconductor_spectral_values.py. The BSDFs are read from XML,
    /// so the test covers how each input type is recognised.
    #[test]
    fn spectral_eval_matches_mitsuba() {
        use crate::spectrum::sampled::Wavelengths;
        use crate::spectrum::Sampled;
        let dir = |t: f32, p: f32| Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let si = dummy_interaction();
        let mut bsdf: Option<Bsdf> = None;
        let mut compared = 0;
        for line in include_str!("../../tests/data/roughconductor_spectral_values.txt").lines() {
            if line.starts_with('#') {
                continue;
            }
            if let Some(desc) = line.strip_prefix("bsdf ") {
                let mut it = desc.split_whitespace();
                let tag = it.next().expect("rgb or float");
                let mut children = String::new();
                for kv in it {
                    let (k, v) = kv.split_once('=').expect("key=value");
                    let t = if k == "alpha" { "float" } else { tag };
                    children += &format!(r#"<{t} name="{k}" value="{v}"/>"#);
                }
                let xml = format!(
                    r#"<scene version="3.0.0"><sensor type="perspective"/><shape type="sphere"><bsdf type="roughconductor"><string name="distribution" value="ggx"/>{children}</bsdf></shape></scene>"#
                );
                let scene = crate::scene::loader::load_str(std::path::Path::new("values.xml"), &xml, &Default::default()).expect("scene");
                bsdf = scene.bsdfs.into_iter().find(|b| matches!(b, Bsdf::RoughConductor(_)));
                continue;
            }
            let v: Vec<f32> = line.split_whitespace().map(|x| x.parse().expect("number")).collect();
            let wl = Wavelengths { lambda: [v[0], v[1], v[2], v[3]], pdf: [1.0; 4] };
            let (wi, wo) = (dir(v[4], v[5]), dir(v[6], v[7]));
            let b = bsdf.as_ref().expect("a bsdf line first");
            let f: Sampled = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &wl);
            let f = f.0.to_array();
            for i in 0..4 {
                let m = v[8 + i];
                // Snell's uplift table is its own fit of the same model: 1 %.
                assert!((f[i] - m).abs() <= 0.01 * m + 1e-5, "{line}: λ {} Snell {} vs Mitsuba {m}", v[i], f[i]);
            }
            compared += 1;
        }
        assert!(compared >= 24, "{compared}");
    }
}

#[cfg(test)]
mod polarized_values {
    use super::*;
    use crate::bsdf::testing::dummy_interaction;
    use crate::bsdf::{Bsdf, BsdfContext};
    use crate::spectrum::sampled::Wavelengths;
    use crate::spectrum::{Polarized, Sampled};

    /// The Mueller matrix against Mitsuba 3.9.1's `scalar_spectral_polarized`
    /// eval at fixed directions and wavelengths
    /// (tests/data/roughconductor_polarized_values.txt, made by
    /// tools/roughconductor_polarized_values.py): every entry, including the
    /// signs of the S1/S2 terms and the S2 ↔ S3 phase terms, for named
    /// metals (their measured spectra) and a float η, k.
    #[test]
    fn polarized_eval_matches_mitsuba() {
        let dir = |t: f32, p: f32| Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let si = dummy_interaction();
        let mut bsdf: Option<Bsdf> = None;
        let mut compared = 0;
        let mut worst = 0.0f32;
        for line in include_str!("../../tests/data/roughconductor_polarized_values.txt").lines() {
            if line.starts_with('#') {
                continue;
            }
            if let Some(desc) = line.strip_prefix("bsdf ") {
                let mut children = String::new();
                for kv in desc.split_whitespace() {
                    let (k, v) = kv.split_once('=').expect("key=value");
                    let t = if k == "material" || k == "distribution" { "string" } else { "float" };
                    children += &format!(r#"<{t} name="{k}" value="{v}"/>"#);
                }
                let xml = format!(r#"<scene version="3.0.0"><sensor type="perspective"/><shape type="sphere"><bsdf type="roughconductor">{children}</bsdf></shape></scene>"#);
                let scene = crate::scene::loader::load_str(std::path::Path::new("values.xml"), &xml, &Default::default()).expect("scene");
                bsdf = scene.bsdfs.into_iter().find(|b| matches!(b, Bsdf::RoughConductor(_)));
                continue;
            }
            let v: Vec<f32> = line.split_whitespace().map(|x| x.parse().expect("number")).collect();
            assert_eq!(v.len(), 8 + 64);
            let wl = Wavelengths { lambda: [v[0], v[1], v[2], v[3]], pdf: [1.0; 4] };
            let (wi, wo) = (dir(v[4], v[5]), dir(v[6], v[7]));
            let b = bsdf.as_ref().expect("a bsdf line first");
            let f: Polarized<Sampled> = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &wl);
            for i in 0..4 {
                let scale = v[8 + i];
                for r in 0..4 {
                    for c in 0..4 {
                        let m = v[8 + (r * 4 + c) * 4 + i];
                        let s = f.0[r][c].0.to_array()[i];
                        let err = (s - m).abs() / scale;
                        worst = worst.max(err);
                        assert!(err <= 0.003, "{line:.60}: λ {} m[{r}][{c}]: Snell {s} vs Mitsuba {m}", v[i]);
                    }
                }
            }
            compared += 1;
        }
        eprintln!("largest difference {worst} of m00");
        assert!(compared >= 24, "{compared}");
    }
}

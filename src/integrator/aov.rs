//! `aov` and `moment` — integrators that write further named channels beside
//! the image (Mitsuba's `aov.cpp` and `moment.cpp`).
//!
//! **`aov`** records what the camera ray sees first (Arbitrary Output
//! Variables: what denoisers and compositors read), and runs its nested
//! integrators, each of which gets channels `NAME.R`, `NAME.G`, `NAME.B`,
//! `NAME.A` (its image and its alpha). The main image (R, G, B) is the first
//! nested integrator's, black without one. Unnamed nested integrators are
//! called `_arg_0`, `_arg_1`, … as Mitsuba calls them.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `aovs` | string | — | comma-separated `NAME:TYPE` pairs |
//! | (nested) | integrator | — | integrators whose images become channels `NAME.R/G/B/A` |
//!
//! | AOV type | channels | value (0 where the ray misses) |
//! |---|---|---|
//! | `depth` | `NAME.T` | distance along the camera ray from where it starts, on the near clip plane (Mitsuba's `si.t`) |
//! | `position` | `NAME.X/Y/Z` | world-space hit point |
//! | `uv` | `NAME.U/V` | surface UV coordinates |
//! | `geo_normal` | `NAME.X/Y/Z` | geometric normal (after `flip_normals`) |
//! | `sh_normal` | `NAME.X/Y/Z` | shading normal |
//! | `albedo` | `NAME.R/G/B` | diffuse reflectance (`diffuse`: reflectance, `plastic`: diffuse_reflectance, others: f(wi, n)·π) |
//! | `prim_index` | `NAME.I` | triangle index within its mesh (0 for spheres, disks; a `rectangle` is two triangles, 0 and 1, where Mitsuba has one primitive) |
//! | `shape_index` | `NAME.I` | 1 + the shape's index in the scene (in file order) |
//!
//! Like colour, every channel is filtered: at an object's edge a pixel holds
//! a weighted mean (Mitsuba notes that integer AOVs become fractional there).
//! `shape_index` numbers shapes in file order; Mitsuba numbers them in the
//! order its loader created them, which may differ. `dp_du`, `dp_dv`,
//! `duv_dx`, `duv_dy` and `boundary_test` are refused (not supported yet).
//!
//! **`moment`** runs its nested integrators on the same camera ray and
//! writes, for each, its value as CIE XYZ in `NAME.X/Y/Z` and the squares of
//! those (and of the nested integrator's own channels) in `m2_NAME.X/Y/Z`:
//! per pixel the first and second moments of the samples, from which
//! Var = m2 − m1² and the variance of the pixel mean (Var / spp, for a box
//! filter) follow. The main image is the first nested integrator's.
//!
//! ```xml
//! <integrator type="aov">
//!     <string name="aovs" value="dd.y:depth, nn:sh_normal"/>
//!     <integrator type="path" name="my_image"/>
//! </integrator>
//! <integrator type="moment"><integrator type="path"/></integrator>
//! ```

use super::Integrator;
use crate::bsdf::Bsdf;
use crate::film::srgb_to_xyz;
use crate::geometry::Ray;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::spectrum::{Rgb, Spectrum};
use glam::Vec3;

/// What an AOV records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AovKind {
    Albedo,
    Depth,
    Position,
    Uv,
    GeoNormal,
    ShNormal,
    PrimIndex,
    ShapeIndex,
}

impl AovKind {
    /// Mitsuba's type names, accepted in `aovs`.
    pub const NAMES: [&'static str; 8] = ["albedo", "depth", "position", "uv", "geo_normal", "sh_normal", "prim_index", "shape_index"];
    /// Mitsuba's AOV types Snell does not compute yet.
    pub const UNSUPPORTED: [&'static str; 5] = ["dp_du", "dp_dv", "duv_dx", "duv_dy", "boundary_test"];

    pub fn from_name(name: &str) -> Option<AovKind> {
        use AovKind::*;
        let all = [Albedo, Depth, Position, Uv, GeoNormal, ShNormal, PrimIndex, ShapeIndex];
        AovKind::NAMES.iter().position(|n| *n == name).map(|i| all[i])
    }

    /// Channel suffixes, as Mitsuba names them.
    pub fn suffixes(self) -> &'static [&'static str] {
        match self {
            AovKind::Albedo => &["R", "G", "B"],
            AovKind::Depth => &["T"],
            AovKind::Position | AovKind::GeoNormal | AovKind::ShNormal => &["X", "Y", "Z"],
            AovKind::Uv => &["U", "V"],
            AovKind::PrimIndex | AovKind::ShapeIndex => &["I"],
        }
    }
}

#[derive(Clone, Debug)]
pub struct Aov {
    pub aovs: Vec<(String, AovKind)>,
    pub integrators: Vec<(String, Integrator)>,
}

#[derive(Clone, Debug)]
pub struct Moment {
    pub integrators: Vec<(String, Integrator)>,
}

impl Aov {
    pub fn channel_names(&self) -> Vec<String> {
        let mut names = vec![];
        for (name, _) in &self.integrators {
            names.extend(["R", "G", "B", "A"].map(|c| format!("{name}.{c}")));
        }
        for (name, integrator) in &self.integrators {
            names.extend(integrator.channel_names().into_iter().map(|c| format!("{name}.{c}")));
        }
        for (name, kind) in &self.aovs {
            names.extend(kind.suffixes().iter().map(|c| format!("{name}.{c}")));
        }
        names
    }

    /// The first nested integrator's value, with every channel written to
    /// `out` (as many as [`Aov::channel_names`]) and the first nested
    /// integrator's alpha.
    pub fn sample<S: Spectrum>(&self, scene: &Scene, ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths, out: &mut [f32]) -> (S, f32) {
        let n_rgba = 4 * self.integrators.len();
        let (rgba, rest) = out.split_at_mut(n_rgba);
        let mut rest = rest;
        let mut result = (S::zero(), 0.0);
        let wl0 = *wl;
        for (i, (_, integrator)) in self.integrators.iter().enumerate() {
            // Each nested integrator starts from the camera ray's wavelengths;
            // the first one's (possibly cut to the hero) are the image's.
            let mut wl_i = wl0;
            let n = integrator.channel_count();
            let (mine, tail) = rest.split_at_mut(n);
            rest = tail;
            let (l, alpha) = integrator.sample::<S>(scene, ray, sampler, if i == 0 { &mut *wl } else { &mut wl_i }, mine);
            let rgb = l.to_rgb(if i == 0 { wl } else { &wl_i });
            rgba[4 * i..4 * i + 4].copy_from_slice(&[rgb[0], rgb[1], rgb[2], alpha]);
            if i == 0 {
                result = (l, alpha);
            }
        }
        let hit = scene.accel.intersect(&ray);
        let si = hit.map(|h| scene.shapes[h.shape as usize].interaction(h.shape, h.prim, ray.o, ray.d, h.t, h.bary));
        let mut k = 0;
        for (_, kind) in &self.aovs {
            let values: [f32; 3] = match (&si, hit) {
                (Some(si), Some(h)) => match kind {
                    AovKind::Depth => [h.t, 0.0, 0.0],
                    AovKind::Position => si.p.to_array(),
                    AovKind::Uv => [si.uv.x, si.uv.y, 0.0],
                    AovKind::GeoNormal => si.n.to_array(),
                    AovKind::ShNormal => si.frame.n.to_array(),
                    AovKind::PrimIndex => [h.prim as f32, 0.0, 0.0],
                    AovKind::ShapeIndex => [(h.shape + 1) as f32, 0.0, 0.0],
                    AovKind::Albedo => albedo::<S>(scene.bsdf(si), si, si.wi, wl).0,
                },
                _ => [0.0; 3],
            };
            let n = kind.suffixes().len();
            rest[k..k + n].copy_from_slice(&values[..n]);
            k += n;
        }
        result
    }
}

impl Moment {
    pub fn channel_names(&self) -> Vec<String> {
        let mut names = vec![];
        for (name, integrator) in &self.integrators {
            names.extend(integrator.channel_names().into_iter().map(|c| format!("{name}.{c}")));
            names.extend(["X", "Y", "Z"].map(|c| format!("{name}.{c}")));
        }
        let m2: Vec<String> = names.iter().map(|n| format!("m2_{n}")).collect();
        names.extend(m2);
        names
    }

    /// The first nested integrator's value and alpha; `out` receives each
    /// nested integrator's channels and XYZ, then their squares.
    pub fn sample<S: Spectrum>(&self, scene: &Scene, ray: Ray, sampler: &mut Sampler, wl: &mut S::Wavelengths, out: &mut [f32]) -> (S, f32) {
        let half = out.len() / 2;
        let (first, second) = out.split_at_mut(half);
        let mut k = 0;
        let mut result = (S::zero(), 0.0);
        let wl0 = *wl;
        for (i, (_, integrator)) in self.integrators.iter().enumerate() {
            let mut wl_i = wl0;
            let n = integrator.channel_count();
            let (l, alpha) = integrator.sample::<S>(scene, ray, sampler, if i == 0 { &mut *wl } else { &mut wl_i }, &mut first[k..k + n]);
            let rgb = l.to_rgb(if i == 0 { wl } else { &wl_i });
            first[k + n..k + n + 3].copy_from_slice(&srgb_to_xyz(rgb));
            k += n + 3;
            if i == 0 {
                result = (l, alpha);
            }
        }
        for (m2, v) in second.iter_mut().zip(first.iter()) {
            *m2 = v * v;
        }
        result
    }
}

/// Mitsuba's `eval_diffuse_reflectance`: the diffuse reflectance where a
/// BSDF has one, else f(wi, n)·π (zero for purely specular BSDFs).
fn albedo<S: Spectrum>(bsdf: &Bsdf, si: &crate::geometry::SurfaceInteraction, wi: Vec3, wl: &S::Wavelengths) -> Rgb {
    match bsdf {
        Bsdf::Diffuse(d) => d.reflectance.eval(si),
        Bsdf::Plastic(p) => p.diffuse_reflectance.eval(si),
        Bsdf::TwoSided(t) => {
            if wi.z >= 0.0 {
                albedo::<S>(&t.front, si, wi, wl)
            } else {
                albedo::<S>(&t.back, si, Vec3::new(wi.x, wi.y, -wi.z), wl)
            }
        }
        _ => {
            let f: S = bsdf.eval(&crate::bsdf::BsdfContext::RADIANCE, si, wi, Vec3::Z, wl);
            f.to_rgb(wl) * std::f32::consts::PI
        }
    }
}

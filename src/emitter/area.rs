//! `area` — a diffuse area light: the shape it is nested in emits constant
//! radiance from its front side (the side its normal points to).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `radiance` | rgb / spectrum / float / texture | — | emitted radiance L_e (a texture: evaluated at the surface's uv) |
//!
//! Direct lighting samples a point x'' on the shape and weights by the
//! geometry term of the surface-area form of the reflection equation,
//! G = V cos θ' cos θ'' / ‖x'' − x'‖²: the shape's area pdf is turned into a
//! solid-angle pdf by ‖x'' − x'‖² / cos θ'' (spheres are sampled by solid
//! angle directly).
//!
//! On a rectangle, direct lighting from the integrators (`Scene::sample_emitter`)
//! samples by solid angle instead where the light is large as seen from the
//! shading point ([`super::sphrect`]); light paths and `bdpt`, which reason
//! in area densities, keep sampling by area.
//!
//! A textured radiance (e.g. a `bitmap` or `checkerboard`, uplifted as an
//! illuminant in spectral modes) is still sampled by area; the uv of a
//! sampled point is found by a short ray onto the shape just in front of it.
//!
//! ```xml
//! <shape type="rectangle">
//!     <emitter type="area"><rgb name="radiance" value="10"/></emitter>
//! </shape>
//! ```

use super::sphrect::Rectangle;
use super::{EmissionSample, EmitterSample};
use crate::geometry::ray::offset_origin;
use crate::geometry::{Ray, SurfaceInteraction};
use crate::math::sampling::square_to_cosine_hemisphere;
use crate::math::{Frame, PI, RAY_EPSILON};
use crate::scene::Scene;
use crate::texture::Texture;
use crate::spectrum::{Emission, Spectrum};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct AreaLight {
    pub shape: u32,
    pub radiance: Emission,
    /// A spatially varying radiance, used instead of `radiance`.
    pub texture: Option<Texture>,
    /// The shape as a rectangle, if it is one (set by
    /// [`AreaLight::find_rectangle`]): direct lighting samples it by solid
    /// angle.
    pub rect: Option<Rectangle>,
}

impl AreaLight {
    /// Whether nothing is emitted anywhere.
    pub fn is_black(&self) -> bool {
        match &self.texture {
            Some(t) => !(t.max_value() > 0.0),
            None => self.radiance.is_zero(),
        }
    }

    /// The radiance at surface position `uv` (front side).
    #[inline]
    fn radiance_at<S: Spectrum>(&self, uv: Vec2, wl: &S::Wavelengths) -> S {
        match &self.texture {
            Some(t) => super::texture_illuminant(t, uv, wl),
            None => self.radiance.eval(wl),
        }
    }

    /// The uv of the point `p` (geometric normal `n`) of this light's shape,
    /// by a short ray from just in front of it along `d` (pointing into
    /// the surface). Only textured lights need it.
    fn uv_at(&self, scene: &Scene, p: Vec3, d: Vec3) -> Option<Vec2> {
        let delta = 10.0 * RAY_EPSILON * (1.0 + p.abs().max_element());
        let hit = scene.intersect(&Ray { o: p - d * delta, d, tmax: 2.0 * delta })?;
        (hit.shape == self.shape).then_some(hit.uv)
    }

    /// Radiance leaving the hit point `si` back along the ray.
    #[inline]
    pub fn eval<S: Spectrum>(&self, si: &SurfaceInteraction, wl: &S::Wavelengths) -> S {
        if si.frame.n.dot(si.frame.to_world(si.wi)) > 0.0 { self.radiance_at(si.uv, wl) } else { S::zero() }
    }

    /// A point on the shape seen from `p` (by the shape's own direction
    /// sampling: by area, or by solid angle for spheres).
    #[inline(always)]
    pub fn sample_direction<S: Spectrum>(&self, scene: &Scene, p: Vec3, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        let ds = scene.shapes[self.shape as usize].sample_direction(p, u)?;
        // Only the front side emits.
        if ds.pdf <= 0.0 || !ds.pdf.is_finite() || ds.sh_n.dot(-ds.d) <= 0.0 || self.is_black() {
            return None;
        }
        let radiance: S = match &self.texture {
            None => self.radiance.eval(wl),
            Some(_) => self.radiance_at(self.uv_at(scene, ds.p, ds.d)?, wl),
        };
        Some(EmitterSample { d: ds.d, dist: ds.dist, p: Some(ds.p), n: ds.n, weight: radiance / ds.pdf, pdf: ds.pdf, delta: false })
    }

    /// Notes whether the light's shape (in `shapes`) is a rectangle.
    pub fn find_rectangle(&mut self, shapes: &[crate::geometry::Shape]) {
        self.rect = match shapes.get(self.shape as usize).map(|s| &s.geometry) {
            Some(crate::geometry::ShapeGeometry::Mesh(m)) => Rectangle::from_mesh(m),
            _ => None,
        };
    }

    /// As [`AreaLight::sample_direction`], for direct lighting: by solid
    /// angle on a rectangle where that pays (see [`super::sphrect`]).
    /// (Always inlined into `Scene::sample_emitter_ray`: returned through
    /// memory, the sample was stored in pieces and reloaded in pieces of
    /// other sizes, a store-forwarding stall in the path tracers.)
    #[inline(always)]
    pub fn sample_direct<S: Spectrum>(&self, scene: &Scene, p: Vec3, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        let Some((rect, sp)) = self.rect.as_ref().and_then(|r| Some((r, r.spherical(p)?))) else {
            return self.sample_direction(scene, p, u, wl);
        };
        let ds = rect.sample(&sp, u)?;
        if ds.sh_n.dot(-ds.d) <= 0.0 || self.is_black() {
            return None;
        }
        let radiance: S = match &self.texture {
            None => self.radiance.eval(wl),
            Some(_) => self.radiance_at(self.uv_at(scene, ds.p, ds.d)?, wl),
        };
        Some(EmitterSample { d: ds.d, dist: ds.dist, p: Some(ds.p), n: ds.n, weight: radiance / ds.pdf, pdf: ds.pdf, delta: false })
    }

    /// Solid-angle density with which [`AreaLight::sample_direct`] from `p`
    /// picks the point `hit` (geometric normal `n`) of the light.
    #[inline]
    pub fn pdf_direct(&self, scene: &Scene, p: Vec3, hit: Vec3, n: Vec3) -> f32 {
        match self.rect.as_ref().and_then(|r| r.solid_angle(p)) {
            Some(solid_angle) => 1.0 / solid_angle,
            None => scene.shapes[self.shape as usize].pdf_direction(p, hit, n),
        }
    }

    /// A point uniformly on the shape's area and a cosine-weighted direction
    /// about its front side.
    pub fn sample_ray<S: Spectrum>(&self, scene: &Scene, u_pos: Vec2, u_dir: Vec2, wl: &S::Wavelengths) -> Option<EmissionSample<S>> {
        let ps = scene.shapes[self.shape as usize].sample_position(u_pos)?;
        if !(ps.pdf_area > 0.0) || self.is_black() {
            return None;
        }
        // Diffuse emission: cosine-weighted about the front side, so
        // Le·cos/pdf = Le·π.
        let local = square_to_cosine_hemisphere(u_dir);
        let d = Frame::from_normal(ps.sh_n).to_world(local);
        let radiance: S = match &self.texture {
            None => self.radiance.eval(wl),
            Some(_) => self.radiance_at(self.uv_at(scene, ps.p, -ps.n)?, wl),
        };
        let position_weight = radiance / ps.pdf_area;
        Some(EmissionSample {
            ray: Ray::new(offset_origin(ps.p, ps.n, d), d),
            p: ps.p,
            n: ps.sh_n,
            weight: position_weight * PI,
            position_weight: Some(position_weight),
            pdf_pos: ps.pdf_area,
            pdf_dir: local.z.max(0.0) / PI,
        })
    }
}

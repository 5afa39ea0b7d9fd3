//! `area` — a diffuse area light: the shape it is nested in emits constant
//! radiance from its front side (the side its normal points to).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `radiance` | rgb / spectrum / float | — | emitted radiance L_e |
//!
//! Direct lighting samples a point x'' on the shape and weights by the
//! geometry term of the surface-area form of the reflection equation,
//! G = V cos θ' cos θ'' / ‖x'' − x'‖²: the shape's area pdf is turned into a
//! solid-angle pdf by ‖x'' − x'‖² / cos θ'' (spheres are sampled by solid
//! angle directly).
//!
//! ```xml
//! <shape type="rectangle">
//!     <emitter type="area"><rgb name="radiance" value="10"/></emitter>
//! </shape>
//! ```

use super::{EmissionSample, EmitterSample};
use crate::geometry::ray::offset_origin;
use crate::geometry::{Ray, Shape, SurfaceInteraction};
use crate::math::sampling::square_to_cosine_hemisphere;
use crate::math::{Frame, PI};
use crate::spectrum::{Emission, Spectrum};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct AreaLight {
    pub shape: u32,
    pub radiance: Emission,
}

impl AreaLight {
    /// Radiance leaving the surface with shading normal `sh_n` in direction
    /// `w`: `None` from the back, which does not emit.
    #[inline]
    pub fn radiance_towards(&self, sh_n: Vec3, w: Vec3) -> Option<&Emission> {
        (sh_n.dot(w) > 0.0).then_some(&self.radiance)
    }

    /// Radiance leaving the hit point `si` back along the ray.
    #[inline]
    pub fn eval<S: Spectrum>(&self, si: &SurfaceInteraction, wl: &S::Wavelengths) -> S {
        self.radiance_towards(si.frame.n, si.frame.to_world(si.wi)).map_or(S::zero(), |le| le.eval(wl))
    }

    /// A point on `shape` seen from `p` (by the shape's own direction
    /// sampling: by area, or by solid angle for spheres).
    #[inline]
    pub fn sample_direction<S: Spectrum>(&self, shape: &Shape, p: Vec3, u: Vec2, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        let ds = shape.sample_direction(p, u)?;
        // Only the front side emits.
        let radiance = self.radiance_towards(ds.sh_n, -ds.d)?;
        if ds.pdf <= 0.0 || !ds.pdf.is_finite() || radiance.is_zero() {
            return None;
        }
        Some(EmitterSample {
            d: ds.d,
            dist: ds.dist,
            p: Some(ds.p),
            n: ds.n,
            weight: radiance.eval::<S>(wl) / ds.pdf,
            pdf: ds.pdf,
            delta: false,
        })
    }

    /// A point uniformly on the shape's area and a cosine-weighted direction
    /// about its front side.
    pub fn sample_ray<S: Spectrum>(&self, shape: &Shape, u_pos: Vec2, u_dir: Vec2, wl: &S::Wavelengths) -> Option<EmissionSample<S>> {
        let ps = shape.sample_position(u_pos)?;
        if !(ps.pdf_area > 0.0) || self.radiance.is_zero() {
            return None;
        }
        // Diffuse emission: cosine-weighted about the front side, so
        // Le·cos/pdf = Le·π.
        let local = square_to_cosine_hemisphere(u_dir);
        let d = Frame::from_normal(ps.sh_n).to_world(local);
        let position_weight = self.radiance.eval::<S>(wl) / ps.pdf_area;
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

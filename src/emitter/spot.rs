//! `spot` — a point light that shines into a cone, as Mitsuba's `spot`.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `intensity` | rgb / spectrum / float | — | radiant intensity I on the axis (W/sr) |
//! | `cutoff_angle` | float | 20 | half-angle (degrees) beyond which nothing is emitted |
//! | `beam_width` | float | ¾ · cutoff_angle | half-angle (degrees) of the full-intensity core |
//! | `texture` | texture | — | image projected inside the cone (times `intensity`) |
//! | `to_world` | transform | identity | placement; the light shines along +z |
//!
//! Between `beam_width` and `cutoff_angle` the intensity falls off linearly
//! in the angle (Mitsuba's falloff curve). A delta light, like `point`: only
//! emitter sampling (or a particle tracer, which starts paths on it) sees it.
//! A narrow spot is the beam of white light of the prism scene.
//!
//! With a `texture`, the direction with local coordinates (x, y, z) (in
//! `to_world`'s frame) shows the texture at uv = ½ + ½ (x, y) / (z tan
//! cutoff_angle), as in Mitsuba: the image's square spans the cone's
//! cross-section. In spectral modes the texture is uplifted as a
//! reflectance-like factor on the intensity's spectrum (as Mitsuba does).
//!
//! ```xml
//! <emitter type="spot">
//!     <rgb name="intensity" value="100"/>
//!     <float name="cutoff_angle" value="1.5"/>
//!     <transform name="to_world"><lookat origin="-2,0.5,0" target="0,0.5,0" up="0,1,0"/></transform>
//! </emitter>
//! ```

use super::{EmissionSample, EmitterSample, point_light_sample};
use crate::geometry::Ray;
use crate::math::Frame;
use crate::math::sampling::{square_to_uniform_cone, uniform_cone_pdf};
use crate::math::Transform;
use crate::spectrum::{Emission, Spectrum};
use crate::texture::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct SpotLight {
    pub position: Vec3,
    /// Unit axis of the cone (world space).
    pub axis: Vec3,
    pub intensity: Emission,
    /// Cutoff half-angle (radians) and its cosine.
    pub cutoff: f32,
    pub cos_cutoff: f32,
    pub cos_beam_width: f32,
    /// 1 / (cutoff − beam_width), radians⁻¹.
    inv_transition: f32,
    /// A texture projected inside the cone, and the light's frame.
    texture: Option<(Texture, Transform)>,
}

impl SpotLight {
    /// `cutoff_deg` in (0, 90], `beam_deg` in (0, cutoff_deg].
    pub fn new(position: Vec3, axis: Vec3, intensity: Emission, cutoff_deg: f32, beam_deg: f32) -> SpotLight {
        let (cutoff, beam) = (cutoff_deg.to_radians(), beam_deg.to_radians());
        let transition = cutoff - beam;
        SpotLight {
            position,
            axis,
            intensity,
            cutoff,
            cos_cutoff: cutoff.cos(),
            cos_beam_width: beam.cos(),
            inv_transition: if transition > 0.0 { 1.0 / transition } else { 0.0 },
            texture: None,
        }
    }

    /// Projects `texture` inside the cone; `to_world` is the light's frame
    /// (its +z the axis).
    pub fn with_texture(mut self, texture: Texture, to_world: Transform) -> SpotLight {
        self.texture = Some((texture, to_world));
        self
    }

    /// Intensity emitted in the unit world direction `d` (falloff excluded).
    #[inline]
    fn intensity_towards<S: Spectrum>(&self, d: Vec3, wl: &S::Wavelengths) -> S {
        let i = self.intensity.eval::<S>(wl);
        match &self.texture {
            None => i,
            Some((tex, to_world)) => {
                let l = to_world.inverse_vector(d);
                let k = 0.5 / (l.z * self.cutoff.tan());
                i * tex.eval_spectrum::<S>(glam::Vec2::new(0.5 + l.x * k, 0.5 + l.y * k), wl)
            }
        }
    }

    /// Mean of the projected texture (1 without one), for the light's flux.
    pub fn texture_mean(&self) -> f32 {
        self.texture.as_ref().map_or(1.0, |(t, _)| t.mean().max(0.0))
    }

    /// Fraction of the axial intensity emitted in the unit direction `d`.
    #[inline]
    pub fn falloff(&self, d: Vec3) -> f32 {
        let cos_theta = self.axis.dot(d);
        if cos_theta <= self.cos_cutoff {
            0.0
        } else if cos_theta >= self.cos_beam_width {
            1.0
        } else {
            ((self.cutoff - cos_theta.clamp(-1.0, 1.0).acos()) * self.inv_transition).clamp(0.0, 1.0)
        }
    }
}

impl SpotLight {
    #[inline]
    pub fn sample_direction<S: Spectrum>(&self, p: Vec3, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        point_light_sample(p, self.position, |d| self.falloff(d), |d| self.intensity_towards::<S>(d, wl))
    }

    /// A direction uniformly within the cone.
    pub fn sample_ray<S: Spectrum>(&self, u_dir: Vec2, wl: &S::Wavelengths) -> Option<EmissionSample<S>> {
        let d = Frame::from_normal(self.axis).to_world(square_to_uniform_cone(u_dir, self.cos_cutoff));
        let falloff = self.falloff(d);
        if falloff <= 0.0 {
            return None;
        }
        let pdf_dir = uniform_cone_pdf(self.cos_cutoff);
        Some(EmissionSample {
            ray: Ray::new(self.position, d),
            p: self.position,
            n: Vec3::ZERO,
            weight: self.intensity_towards::<S>(d, wl) * (falloff / pdf_dir),
            position_weight: None,
            pdf_pos: 1.0,
            pdf_dir,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn falloff_is_one_in_the_beam_zero_outside_and_linear_between() {
        let s = SpotLight::new(Vec3::ZERO, Vec3::Z, Emission::rgb(crate::spectrum::Rgb::WHITE), 20.0, 10.0);
        let dir = |deg: f32| Vec3::new(deg.to_radians().sin(), 0.0, deg.to_radians().cos());
        assert_eq!(s.falloff(dir(0.0)), 1.0);
        assert_eq!(s.falloff(dir(9.9)), 1.0);
        assert!((s.falloff(dir(15.0)) - 0.5).abs() < 1e-3);
        assert_eq!(s.falloff(dir(20.1)), 0.0);
        assert_eq!(s.falloff(-Vec3::Z), 0.0);
    }
}

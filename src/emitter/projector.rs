//! `projector` — a pinhole that projects an image into the scene, as
//! Mitsuba 3's `projector` (the reciprocal of the `perspective` camera).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `irradiance` | texture / rgb / float | — | the image on the virtual image plane at distance 1 from the pinhole |
//! | `scale` | float | 1 | factor on `irradiance` |
//! | `fov` | float | — | field of view in degrees, along `fov_axis` (without it: `focal_length`) |
//! | `fov_axis` | string | `x` | `x`, `y`, `smaller`, `larger` or `diagonal` |
//! | `focal_length` | string | `50mm` | 35 mm film equivalent focal length, if `fov` is not given |
//! | `to_world` | transform | identity | placement; it shines along +z, image +x to the left as the camera's |
//!
//! The image's aspect ratio is the texture's (1 for a constant). A point x
//! at depth z in the projector's frame, seen at angle θ from its axis and
//! projecting to image position uv, receives (as Mitsuba defines it) the
//! contribution π · scale · E(uv) / (z² cos θ) — so a plane facing the
//! projector at depth h receives the uniform irradiance π · scale · E / h²
//! over the projected rectangle, nothing outside. A delta light (a single
//! position): only emitter sampling and light paths see it. Light paths
//! start at a uniformly chosen image position.
//!
//! In spectral modes E is uplifted as an illuminant (times D65), as
//! Mitsuba's D65 `intensity` factor does.
//!
//! ```xml
//! <emitter type="projector">
//!     <float name="fov" value="40"/>
//!     <transform name="to_world"><lookat origin="0,3,0" target="0,0,0" up="0,0,1"/></transform>
//!     <texture type="bitmap" name="irradiance"><string name="filename" value="slide.png"/></texture>
//! </emitter>
//! ```

use super::{EmissionSample, EmitterSample};
use crate::geometry::Ray;
use crate::math::{PI, Transform};
use crate::spectrum::Spectrum;
use crate::texture::Texture;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Projector {
    pub to_world: Transform,
    pub irradiance: Texture,
    pub scale: f32,
    /// tan(fov_x / 2).
    pub tan_half_x: f32,
    /// Image width / height.
    pub aspect: f32,
    position: Vec3,
    axis: Vec3,
}

impl Projector {
    pub fn new(to_world: Transform, irradiance: Texture, scale: f32, fov_x_deg: f32, aspect: f32) -> Projector {
        Projector {
            position: to_world.point(Vec3::ZERO),
            axis: to_world.vector(Vec3::Z).normalize_or_zero(),
            to_world,
            irradiance,
            scale,
            tan_half_x: (fov_x_deg.to_radians() * 0.5).tan(),
            aspect,
        }
    }

    /// The pinhole's position and the unit axis it shines along.
    pub fn position_axis(&self) -> (Vec3, Vec3) {
        (self.position, self.axis)
    }

    /// Image position of the local point (or direction) `l`, if in front of
    /// the projector and inside the image.
    #[inline]
    fn image_uv(&self, l: Vec3) -> Option<Vec2> {
        if !(l.z > 0.0) {
            return None;
        }
        let uv = Vec2::new(0.5 - 0.5 * l.x / (l.z * self.tan_half_x), 0.5 - 0.5 * self.aspect * l.y / (l.z * self.tan_half_x));
        (uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0).then_some(uv)
    }

    #[inline]
    fn value<S: Spectrum>(&self, uv: Vec2, wl: &S::Wavelengths) -> S {
        super::texture_illuminant::<S>(&self.irradiance, uv, wl) * self.scale
    }

    pub fn sample_direction<S: Spectrum>(&self, p: Vec3, wl: &S::Wavelengths) -> Option<EmitterSample<S>> {
        let l = self.to_world.inverse_point(p);
        let uv = self.image_uv(l)?;
        let v = self.position - p;
        let dist = v.length();
        if !(dist > 0.0) {
            return None;
        }
        let d = v / dist;
        let cos_theta = -self.axis.dot(d);
        if !(cos_theta > 0.0) {
            return None;
        }
        let value: S = self.value(uv, wl);
        if value.is_zero() {
            return None;
        }
        Some(EmitterSample { d, dist, p: Some(self.position), n: Vec3::ZERO, weight: value * (PI / (l.z * l.z * cos_theta)), pdf: 0.0, delta: true })
    }

    /// A uniformly chosen image position and the ray through it.
    pub fn sample_ray<S: Spectrum>(&self, u_dir: Vec2, wl: &S::Wavelengths) -> Option<EmissionSample<S>> {
        let (w, h) = (2.0 * self.tan_half_x, 2.0 * self.tan_half_x / self.aspect);
        let local = Vec3::new((0.5 - u_dir.x) * w, (0.5 - u_dir.y) * h, 1.0);
        let d = self.to_world.vector(local).normalize_or_zero();
        if d == Vec3::ZERO {
            return None;
        }
        let value: S = self.value(u_dir, wl);
        if value.is_zero() {
            return None;
        }
        let area = w * h;
        let cos_theta = 1.0 / local.length();
        Some(EmissionSample {
            ray: Ray::new(self.position, d),
            p: self.position,
            n: Vec3::ZERO,
            weight: value * (PI * area),
            position_weight: None,
            pdf_pos: 1.0,
            pdf_dir: 1.0 / (area * cos_theta * cos_theta * cos_theta),
        })
    }
}

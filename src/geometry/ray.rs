//! Rays and the robust spawning of rays off surfaces.

use crate::math::RAY_EPSILON;
use glam::Vec3;

#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
    pub tmax: f32,
}

impl Ray {
    #[inline]
    pub fn new(o: Vec3, d: Vec3) -> Ray {
        Ray { o, d, tmax: f32::INFINITY }
    }

    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// Moves `p` off its surface along the geometric normal `n`, to the side
/// `d` points to. The offset scales with the coordinates' magnitude, as
/// single-precision error does (Mitsuba's `spawn_ray`).
#[inline]
pub fn offset_origin(p: Vec3, n: Vec3, d: Vec3) -> Vec3 {
    let mag = (1.0 + p.abs().max_element()) * RAY_EPSILON;
    let offset = n * mag;
    if n.dot(d) >= 0.0 { p + offset } else { p - offset }
}

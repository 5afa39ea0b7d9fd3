//! The record of a ray hitting a surface.

use crate::math::Frame;
use glam::{Vec2, Vec3};

#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteraction {
    pub p: Vec3,
    pub t: f32,
    /// Geometric normal (flip_normals applied).
    pub n: Vec3,
    /// Shading frame (interpolated vertex normal where the mesh has them).
    pub frame: Frame,
    pub uv: Vec2,
    /// ∂p/∂u and ∂p/∂v in Mitsuba's parametrisation of the shape (world
    /// space, unnormalised); zero unless the shape builds tangent frames
    /// ([`crate::bsdf::BsdfModel::needs_tangent_frame`]).
    pub dp_du: Vec3,
    pub dp_dv: Vec3,
    pub shape: u32,
    /// The primitive (triangle) hit and the hit's barycentrics (b1, b2) on
    /// it (zero for other shapes): for textures that read mesh attributes.
    pub prim: u32,
    pub bary: Vec2,
    /// Direction towards where the ray came from, in the local shading frame.
    pub wi: Vec3,
}

impl SurfaceInteraction {
    /// An all-zero interaction: a slot for the `_into` queries
    /// ([`crate::scene::Scene::intersect_into`]) to write into, reused
    /// across a path's bounces.
    pub const EMPTY: SurfaceInteraction = SurfaceInteraction {
        p: Vec3::ZERO,
        t: 0.0,
        n: Vec3::ZERO,
        frame: Frame { s: Vec3::ZERO, t: Vec3::ZERO, n: Vec3::ZERO },
        uv: Vec2::ZERO,
        dp_du: Vec3::ZERO,
        dp_dv: Vec3::ZERO,
        shape: 0,
        prim: 0,
        bary: Vec2::ZERO,
        wi: Vec3::ZERO,
    };

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        self.frame.to_local(v)
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.frame.to_world(v)
    }

    /// Origin for a ray leaving this point in direction `d`.
    #[inline]
    pub fn spawn_origin(&self, d: Vec3) -> Vec3 {
        super::ray::offset_origin(self.p, self.n, d)
    }
}

//! A shape: geometry plus the material and (optionally) the area emitter
//! attached to it.

use super::curve::Curves;
use super::cylinder::Cylinder;
use super::disk::Disk;
use super::interaction::SurfaceInteraction;
use super::sdfgrid::SdfGrid;
use super::mesh::{Mesh, PositionSample, area_pdf_to_solid_angle};
use super::sphere::{DirectionSample, Sphere};
use crate::math::{Frame, Transform};
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub enum ShapeGeometry {
    Mesh(Mesh),
    Sphere(Sphere),
    Disk(Disk),
    Cylinder(Cylinder),
    Curves(Curves),
    SdfGrid(SdfGrid),
}

#[derive(Clone, Debug)]
pub struct Shape {
    pub geometry: ShapeGeometry,
    pub bsdf: u32,
    pub emitter: Option<u32>,
    /// Build shading frames with their tangent along ∂p/∂u (for BSDFs
    /// oriented within the surface); otherwise the tangent is a function of
    /// the normal alone, which is cheaper and all isotropic BSDFs need.
    pub tangent_frame: bool,
    /// Rays pass (stochastically) through this shape: its BSDF has a null
    /// lobe (`mask`, `null`) and it does not emit. Scenes where no shape has
    /// it keep the plain closest-hit and any-hit paths.
    pub pass_through: bool,
    /// Something in the scene reads a hit's texture coordinates (a bitmap
    /// or checkerboard texture, a `uv` AOV). Where nothing does, a sphere's
    /// or disk's hit skips them (two arc tangents, a fifth of a sphere
    /// hit's cost) and reports zero.
    pub reads_uv: bool,
    /// The media inside and outside this shape ([`crate::medium`]), indices
    /// into [`crate::scene::Scene::media`]; a shape that names either is a
    /// medium boundary for `volpath`.
    pub interior: Option<u32>,
    pub exterior: Option<u32>,
}

impl Shape {
    pub fn primitive_count(&self) -> usize {
        match &self.geometry {
            ShapeGeometry::Mesh(m) => m.triangles.len(),
            ShapeGeometry::Sphere(_) | ShapeGeometry::Disk(_) | ShapeGeometry::Cylinder(_) | ShapeGeometry::SdfGrid(_) => 1,
            ShapeGeometry::Curves(c) => c.primitive_count(),
        }
    }

    pub fn area(&self) -> f32 {
        match &self.geometry {
            ShapeGeometry::Mesh(m) => m.area(),
            ShapeGeometry::Sphere(s) => s.area(),
            ShapeGeometry::Disk(d) => d.area,
            ShapeGeometry::Cylinder(c) => c.area(),
            ShapeGeometry::Curves(c) => c.area(),
            // Not computed (nor is it by Mitsuba): an SDF grid never emits.
            ShapeGeometry::SdfGrid(_) => 0.0,
        }
    }

    /// The full interaction at a hit found by the accelerator, with the
    /// barycentrics (b1, b2) it reported for a triangle.
    #[inline]
    pub fn interaction(&self, shape_index: u32, prim: u32, ray_o: Vec3, ray_d: Vec3, t: f32, bary: (f32, f32)) -> SurfaceInteraction {
        let mut si = SurfaceInteraction::EMPTY;
        self.interaction_into(shape_index, prim, ray_o, ray_d, t, bary, &mut si);
        si
    }

    /// As [`Shape::interaction`], written straight into `out` (the caller's
    /// slot): returned by value, the record was stored in pieces and copied
    /// on in 16-byte loads, which stalled on store forwarding.
    ///
    /// A triangle hit without a tangent frame (the common case) is inlined
    /// into the caller's loop; the other shapes take one out-of-line call.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn interaction_into(&self, shape_index: u32, prim: u32, ray_o: Vec3, ray_d: Vec3, t: f32, bary: (f32, f32), out: &mut SurfaceInteraction) {
        match &self.geometry {
            ShapeGeometry::Mesh(m) if !self.tangent_frame => {
                let (p, n, sh_n, uv, bary) = mesh_hit(m, prim, bary);
                let frame = Frame::from_normal(sh_n);
                *out = SurfaceInteraction {
                    p,
                    t,
                    n,
                    frame,
                    uv,
                    dp_du: Vec3::ZERO,
                    dp_dv: Vec3::ZERO,
                    shape: shape_index,
                    prim,
                    bary,
                    wi: frame.to_local(-ray_d),
                };
            }
            _ => self.interaction_general_into(shape_index, prim, ray_o, ray_d, t, bary, out),
        }
    }

    /// [`Shape::interaction_into`] for every shape and frame.
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn interaction_general_into(&self, shape_index: u32, prim: u32, ray_o: Vec3, ray_d: Vec3, t: f32, bary: (f32, f32), out: &mut SurfaceInteraction) {
        let (p, n, sh_n, uv, bary) = match &self.geometry {
            ShapeGeometry::Mesh(m) => mesh_hit(m, prim, bary),
            ShapeGeometry::Sphere(s) => {
                let p = ray_o + ray_d * t;
                // Project onto the surface to remove the error of o + t·d.
                let p = s.center + (p - s.center).normalize_or_zero() * s.radius;
                let n = s.normal_at(p);
                (p, n, n, if self.reads_uv { s.uv_at(p) } else { Vec2::ZERO }, Vec2::ZERO)
            }
            ShapeGeometry::Disk(d) => {
                let p = ray_o + ray_d * t;
                (p, d.normal, d.normal, if self.reads_uv { d.uv_at(p) } else { Vec2::ZERO }, Vec2::ZERO)
            }
            ShapeGeometry::Cylinder(c) => {
                let (p, n, uv, _) = c.surface(ray_o + ray_d * t);
                (p, n, n, uv, Vec2::ZERO)
            }
            ShapeGeometry::Curves(c) => {
                let (p, n, uv, _, _) = c.surface(prim, bary.0, ray_o + ray_d * t);
                (p, n, n, uv, Vec2::new(bary.0, 0.0))
            }
            ShapeGeometry::SdfGrid(g) => {
                let (p, n, sh_n, uv) = g.surface(ray_o + ray_d * t, ray_d);
                (p, n, sh_n, uv, Vec2::ZERO)
            }
        };
        let (frame, dp_du, dp_dv) = match self.tangent_frame.then(|| self.dp_duv(prim, p, (bary.x, bary.y))).flatten() {
            Some((dp_du, dp_dv)) => (Frame::from_normal_and_tangent(sh_n, dp_du), dp_du, dp_dv),
            None => {
                let frame = Frame::from_normal(sh_n);
                // Mitsuba's choice without a parametrisation: the frame's tangents.
                (frame, if self.tangent_frame { frame.s } else { Vec3::ZERO }, if self.tangent_frame { frame.t } else { Vec3::ZERO })
            }
        };
        *out = SurfaceInteraction { p, t, n, frame, uv, dp_du, dp_dv, shape: shape_index, prim, bary, wi: frame.to_local(-ray_d) };
    }

    /// As [`Shape::interaction`] for a shape of a shape group placed by an
    /// instance with group-to-world transform `to_world`: the hit is found
    /// in the group's space (the ray mapped there) and moved to world space,
    /// normals by the inverse transpose, as Mitsuba's `instance` does.
    #[inline]
    pub fn interaction_instanced(
        &self,
        to_world: &Transform,
        shape_index: u32,
        prim: u32,
        ray_o: Vec3,
        ray_d: Vec3,
        t: f32,
        bary: (f32, f32),
    ) -> SurfaceInteraction {
        let mut si = SurfaceInteraction::EMPTY;
        self.interaction_instanced_into(to_world, shape_index, prim, ray_o, ray_d, t, bary, &mut si);
        si
    }

    /// As [`Shape::interaction_instanced`], written straight into `out`.
    #[allow(clippy::too_many_arguments)]
    pub fn interaction_instanced_into(
        &self,
        to_world: &Transform,
        shape_index: u32,
        prim: u32,
        ray_o: Vec3,
        ray_d: Vec3,
        t: f32,
        bary: (f32, f32),
        out: &mut SurfaceInteraction,
    ) {
        self.interaction_into(shape_index, prim, to_world.inverse_point(ray_o), to_world.inverse_vector(ray_d), t, bary, out);
        let local = &*out;
        let n = to_world.normal(local.n).normalize_or_zero();
        let sh_n = to_world.normal(local.frame.n).normalize_or_zero();
        let frame = if self.tangent_frame {
            Frame::from_normal_and_tangent(sh_n, to_world.vector(local.frame.s))
        } else {
            Frame::from_normal(sh_n)
        };
        let (p, dp_du, dp_dv) = (to_world.point(local.p), to_world.vector(local.dp_du), to_world.vector(local.dp_dv));
        out.p = p;
        out.t = t;
        out.n = n;
        out.frame = frame;
        out.dp_du = dp_du;
        out.dp_dv = dp_dv;
        out.wi = frame.to_local(-ray_d);
    }

    /// ∂p/∂u and ∂p/∂v at `p` on primitive `prim`, as Mitsuba 3.9 computes
    /// them (magnitudes included, which bump mapping needs): a mesh's
    /// texture coordinates; the sphere's u = φ/2π, v = θ/π; the disk's
    /// u = r, v = φ/2π; a curve's angle around and length along (from its
    /// parameter, carried in `bary`). None for an SDF grid (no parameterisation).
    fn dp_duv(&self, prim: u32, p: Vec3, bary: (f32, f32)) -> Option<(Vec3, Vec3)> {
        use std::f32::consts::PI;
        match &self.geometry {
            ShapeGeometry::Mesh(m) => m.dp_duv(prim as usize),
            ShapeGeometry::Sphere(s) => {
                let l = s.to_object.point(p);
                let rd = (l.x * l.x + l.y * l.y).sqrt();
                let dp_du = s.to_object.inverse_vector(Vec3::new(-l.y, l.x, 0.0) * (2.0 * PI));
                let (cos_phi, sin_phi) = if rd > 0.0 { (l.x / rd, l.y / rd) } else { (1.0, 0.0) };
                let dp_dv = s.to_object.inverse_vector(Vec3::new(l.z * cos_phi, l.z * sin_phi, -rd) * PI);
                Some((dp_du, dp_dv))
            }
            ShapeGeometry::Disk(d) => {
                let l = d.to_world.inverse_point(p);
                let r = (l.x * l.x + l.y * l.y).sqrt();
                let (cos_phi, sin_phi) = if r > 0.0 { (l.x / r, l.y / r) } else { (1.0, 0.0) };
                Some((d.to_world.vector(Vec3::new(cos_phi, sin_phi, 0.0)), d.to_world.vector(Vec3::new(-l.y, l.x, 0.0) * (2.0 * PI))))
            }
            ShapeGeometry::Cylinder(c) => Some((c.surface(p).3, c.to_world.vector(Vec3::Z * c.length))),
            ShapeGeometry::Curves(c) => {
                let (_, _, _, dp_du, dp_dv) = c.surface(prim, bary.0, p);
                Some((dp_du, dp_dv))
            }
            ShapeGeometry::SdfGrid(_) => None,
        }
    }

    /// A point uniformly distributed over the surface (by area).
    #[inline(always)]
    pub fn sample_position(&self, u: Vec2) -> Option<PositionSample> {
        match &self.geometry {
            ShapeGeometry::Sphere(s) => Some(s.sample_position(u)),
            ShapeGeometry::Mesh(m) => m.sample_position(u),
            ShapeGeometry::Disk(d) => Some(d.sample_position(u)),
            ShapeGeometry::Cylinder(c) => Some(c.sample_position(u)),
            // Never an emitter (the loader refuses one).
            ShapeGeometry::Curves(_) | ShapeGeometry::SdfGrid(_) => None,
        }
    }

    /// A direction from `p` towards this shape, for emitter sampling.
    /// (Inlined down to the shapes' sampling, as are they: samples returned
    /// by value through memory were written in pieces and read back whole,
    /// a store-forwarding stall.)
    #[inline(always)]
    pub fn sample_direction(&self, p: Vec3, u: Vec2) -> Option<DirectionSample> {
        let ps = match &self.geometry {
            ShapeGeometry::Sphere(s) => return s.sample_direction(p, u),
            ShapeGeometry::Mesh(m) => m.sample_position(u)?,
            ShapeGeometry::Disk(d) => d.sample_position(u),
            ShapeGeometry::Cylinder(c) => c.sample_position(u),
            ShapeGeometry::Curves(_) | ShapeGeometry::SdfGrid(_) => return None,
        };
        ps.towards(p)
    }

    /// Solid-angle density of `sample_direction` from `p` for the point
    /// `hit` on this shape with geometric normal `n`.
    pub fn pdf_direction(&self, p: Vec3, hit: Vec3, n: Vec3) -> f32 {
        if let ShapeGeometry::Sphere(s) = &self.geometry {
            return s.pdf_direction(p, hit, n);
        }
        area_pdf_to_solid_angle(p, hit, n, self.area())
    }
}

/// A triangle hit's point, geometric normal, shading normal, texture
/// coordinates and barycentrics, from the barycentrics (b1, b2) the
/// intersection test reported.
#[inline(always)]
fn mesh_hit(m: &Mesh, prim: u32, bary: (f32, f32)) -> (Vec3, Vec3, Vec3, Vec2, Vec2) {
    let i = prim as usize;
    let [a, b, c] = m.vertices(i);
    let e1 = b - a;
    let e2 = c - a;
    // Barycentrics from the intersection test, inside the triangle by
    // construction; clamped against rounding.
    let (b1, b2) = bary;
    let (b1, b2) = if b1.is_finite() && b2.is_finite() { (b1.clamp(0.0, 1.0), b2.clamp(0.0, 1.0)) } else { (0.0, 0.0) };
    let p = a + e1 * b1 + e2 * b2;
    let n = m.face_normal_at(i, e1, e2);
    let (sh_n, uv) = m.shading(i, b1, b2, n);
    (p, n, sh_n, uv, Vec2::new(b1, b2))
}

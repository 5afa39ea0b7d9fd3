//! `perspective` — a pinhole camera.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `fov` | float | — | field of view in degrees, along `fov_axis` |
//! | `fov_axis` | string | `x` | `x`, `y`, `smaller`, `larger` or `diagonal` |
//! | `focal_length` | string | `50mm` | used when `fov` is not given: the focal length of a 35 mm film camera (36 × 24 mm), so the field of view along the image diagonal is 2·atan(43.27 mm / (2·f)) (Mitsuba's `parse_fov`); `"35mm"` or `"35"` |
//! | `principal_point_offset_x/y` | float | 0 | shift of the image centre (the optical axis), in fractions of the film width/height |
//! | `to_world` | transform | identity | camera placement (usually a `lookat`) |
//! | `near_clip`, `far_clip` | float | 0.01, 10000 | clip distances along the view axis |
//!
//! ```xml
//! <sensor type="perspective">
//!     <float name="fov" value="39.3"/>
//!     <transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
//!     <film type="hdrfilm"><integer name="width" value="256"/><integer name="height" value="256"/></film>
//! </sensor>
//! ```

use crate::geometry::Ray;
use crate::geometry::accel::SimdLevel;
use crate::math::Transform;
use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub struct Perspective {
    pub to_world: Transform,
    /// tan(fov_x / 2).
    pub tan_half_x: f32,
    /// width / height.
    pub aspect: f32,
    pub near_clip: f32,
    pub far_clip: f32,
    /// Added to the film position of every ray (Mitsuba's
    /// `principal_point_offset_x/y`, fractions of the film).
    pub principal_offset: Vec2,
    /// Precomputed so a camera ray costs two multiply-adds and one
    /// normalisation: the world-space origin, and the world-space images of
    /// the camera's x and y half-extents at depth 1 and of its axis.
    origin: Vec3,
    half_x: Vec3,
    half_y: Vec3,
    axis: Vec3,
}
/// The field of view (degrees) along the image diagonal of a 35 mm film
/// camera (36 × 24 mm) of focal length `mm` millimetres (Mitsuba's `parse_fov`).
pub fn focal_length_fov(mm: f64) -> f64 {
    2.0 * ((36.0f64 * 36.0 + 24.0 * 24.0).sqrt() / (2.0 * mm)).atan().to_degrees()
}

/// A focal length as Mitsuba writes it: a number, optionally followed by `mm`.
pub fn parse_focal_length(text: &str) -> Option<f64> {
    let t = text.trim();
    let t = t.strip_suffix("mm").unwrap_or(t);
    t.trim().parse::<f64>().ok().filter(|v| v.is_finite() && *v > 0.0)
}

/// The horizontal field of view (degrees) for a `fov` given along `axis`.
pub fn horizontal_fov(fov: f32, axis: &str, aspect: f32) -> f32 {
    let axis = match axis {
        "smaller" => if aspect > 1.0 { "y" } else { "x" },
        "larger" => if aspect > 1.0 { "x" } else { "y" },
        a => a,
    };
    let half = (fov.to_radians() * 0.5).tan();
    match axis {
        "y" => 2.0 * (half * aspect).atan().to_degrees(),
        "diagonal" => {
            let diagonal = 2.0 * half;
            let width = diagonal / (1.0 + 1.0 / (aspect * aspect)).sqrt();
            2.0 * (width * 0.5).atan().to_degrees()
        }
        _ => fov,
    }
}

impl Perspective {
    pub fn new(to_world: Transform, tan_half_x: f32, aspect: f32, near_clip: f32, far_clip: f32) -> Perspective {
        let tan_half_y = tan_half_x / aspect;
        Perspective {
            origin: to_world.point(Vec3::ZERO),
            half_x: to_world.vector(Vec3::new(tan_half_x, 0.0, 0.0)),
            half_y: to_world.vector(Vec3::new(0.0, tan_half_y, 0.0)),
            axis: to_world.vector(Vec3::Z),
            to_world,
            tan_half_x,
            aspect,
            near_clip,
            far_clip,
            principal_offset: Vec2::ZERO,
        }
    }

    /// The same camera with its image centre shifted by `offset` (fractions
    /// of the film).
    pub fn with_principal_offset(mut self, offset: Vec2) -> Perspective {
        self.principal_offset = offset;
        self
    }

    /// The ray through film position `film` ∈ [0,1]² (top left (0,0)),
    /// starting at the near clip plane and ending at the far one.
    #[inline]
    pub fn generate_ray(&self, film: Vec2) -> Ray {
        // Camera space: (x, y, 1) through the film point; its length converts
        // clip depths along the axis into distances along the ray.
        let film = film + self.principal_offset;
        let (sx, sy) = (1.0 - 2.0 * film.x, 1.0 - 2.0 * film.y);
        let local_len = (sx * sx * self.tan_half_x * self.tan_half_x
            + sy * sy * (self.tan_half_x / self.aspect) * (self.tan_half_x / self.aspect)
            + 1.0)
            .sqrt();
        let d = (self.half_x * sx + self.half_y * sy + self.axis).normalize();
        let t_near = self.near_clip * local_len;
        let t_far = self.far_clip * local_len;
        Ray { o: self.origin + d * t_near, d, tmax: t_far - t_near }
    }
}

/// Lanes of a [`RayChunk`]: one AVX-512 register of `f32`.
pub const LANES: usize = 16;

/// Camera rays of up to [`LANES`] film positions, lane-major so that
/// [`Perspective::generate_rays`] runs as vector instructions: the film
/// positions in, the rays out.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayChunk {
    pub film: [[f32; LANES]; 2],
    pub o: [[f32; LANES]; 3],
    pub d: [[f32; LANES]; 3],
    pub tmax: [f32; LANES],
}

impl RayChunk {
    /// The ray of lane `k`.
    #[inline]
    pub fn ray(&self, k: usize) -> Ray {
        Ray {
            o: Vec3::new(self.o[0][k], self.o[1][k], self.o[2][k]),
            d: Vec3::new(self.d[0][k], self.d[1][k], self.d[2][k]),
            tmax: self.tmax[k],
        }
    }
}

impl Perspective {
    /// [`Perspective::generate_ray`] for every lane of `chunk`, the same
    /// bits: each lane takes the scalar code's IEEE operations in its order
    /// (no fused multiply-add; square root and division are exact in
    /// vector registers too), compiled for the CPU's `level` as the BVH's
    /// traversal is.
    pub fn generate_rays(&self, level: SimdLevel, chunk: &mut RayChunk) {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2")]
        unsafe fn avx512(cam: &Perspective, chunk: &mut RayChunk) {
            cam.rays_body(chunk)
        }
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        unsafe fn avx2(cam: &Perspective, chunk: &mut RayChunk) {
            cam.rays_body(chunk)
        }
        match level {
            // SAFETY: the accelerator's level is one the CPU supports.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => unsafe { avx512(self, chunk) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { avx2(self, chunk) },
            _ => self.rays_body(chunk),
        }
    }

    /// `generate_ray` written out per component (glam's `Vec3` arithmetic:
    /// component-wise products and sums, `normalize` as `v * (1 / sqrt(v·v))`
    /// with the dot product summed x, y, z).
    #[inline(always)]
    fn rays_body(&self, c: &mut RayChunk) {
        let (thx, tha) = (self.tan_half_x, self.tan_half_x / self.aspect);
        let (hx, hy, ax, org) = (self.half_x.to_array(), self.half_y.to_array(), self.axis.to_array(), self.origin.to_array());
        for k in 0..LANES {
            let fx = c.film[0][k] + self.principal_offset.x;
            let fy = c.film[1][k] + self.principal_offset.y;
            let (sx, sy) = (1.0 - 2.0 * fx, 1.0 - 2.0 * fy);
            let local_len = (sx * sx * thx * thx + sy * sy * tha * tha + 1.0).sqrt();
            let v = [0, 1, 2].map(|j| hx[j] * sx + hy[j] * sy + ax[j]);
            let inv_len = 1.0 / (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let t_near = self.near_clip * local_len;
            let t_far = self.far_clip * local_len;
            for j in 0..3 {
                let d = v[j] * inv_len;
                c.d[j][k] = d;
                c.o[j][k] = org[j] + d * t_near;
            }
            c.tmax[k] = t_far - t_near;
        }
    }
}

/// A world point seen by the camera: where it lands on the film and how
/// much it counts (for particle tracing, which splats light paths onto the film).
#[derive(Clone, Copy, Debug)]
pub struct CameraConnection {
    /// Film position in [0,1]², as taken by `generate_ray`.
    pub film: Vec2,
    /// Unit direction from the point towards the pinhole, and the distance.
    pub d: Vec3,
    pub dist: f32,
    /// The pinhole's importance for that direction, per unit solid angle and
    /// per pixel: W·H / (A cos³θ), A = 4 tan(fov_x/2) tan(fov_y/2) the film's
    /// area at unit depth. A pixel of a uniform-weight path-traced image is
    /// the mean of L over its film area; dω = cos³θ dA at unit depth turns
    /// that mean into ∫ L · importance dω over the pixel's directions.
    pub importance: f32,
}

impl Perspective {
    /// Projects world point `p` onto the film; `None` outside the image or
    /// the clip range.
    pub fn connect(&self, p: Vec3, width: u32, height: u32) -> Option<CameraConnection> {
        let local = self.to_world.inverse_point(p);
        if !(local.z >= self.near_clip && local.z <= self.far_clip) {
            return None;
        }
        let tan_half_y = self.tan_half_x / self.aspect;
        let (sx, sy) = (local.x / (local.z * self.tan_half_x), local.y / (local.z * tan_half_y));
        let film = Vec2::new(0.5 * (1.0 - sx), 0.5 * (1.0 - sy)) - self.principal_offset;
        if !((0.0..=1.0).contains(&film.x) && (0.0..=1.0).contains(&film.y)) {
            return None;
        }
        let v = self.origin - p;
        let dist = v.length();
        if !(dist > 0.0) {
            return None;
        }
        let cos_theta = local.z / local.length();
        let area = 4.0 * self.tan_half_x * tan_half_y;
        let importance = (width as f32 * height as f32) / (area * cos_theta * cos_theta * cos_theta);
        Some(CameraConnection { film, d: v / dist, dist, importance })
    }

    pub fn origin(&self) -> Vec3 {
        self.origin
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fov_axis_conversions() {
        assert!((horizontal_fov(40.0, "x", 2.0) - 40.0).abs() < 1e-4);
        // fov along y on a 2:1 film: tan(x/2) = 2 tan(y/2).
        let x = horizontal_fov(40.0, "y", 2.0);
        assert!(((x.to_radians() / 2.0).tan() - 2.0 * (20.0f32.to_radians()).tan()).abs() < 1e-5);
        assert_eq!(horizontal_fov(40.0, "smaller", 2.0), x);
        assert_eq!(horizontal_fov(40.0, "larger", 0.5), x.min(horizontal_fov(40.0, "y", 0.5)));
        let d = horizontal_fov(60.0, "diagonal", 1.0);
        assert!(((d.to_radians() / 2.0).tan() * 2f32.sqrt() - (30.0f32.to_radians()).tan()).abs() < 1e-5);
    }

    #[test]
    fn focal_length_gives_mitsubas_diagonal_fov() {
        // 50 mm on 36 × 24 mm film: diagonal 43.267 mm, fov 2·atan(43.267/100) = 46.793°.
        assert!((focal_length_fov(50.0) - 46.7930).abs() < 1e-3, "{}", focal_length_fov(50.0));
        assert_eq!(parse_focal_length("50mm"), Some(50.0));
        assert_eq!(parse_focal_length(" 28 "), Some(28.0));
        assert_eq!(parse_focal_length("mm"), None);
        assert_eq!(parse_focal_length("-3mm"), None);
        // On a 3:2 film the diagonal fov of a 50 mm lens is 39.6° horizontally (36 mm wide).
        let x = horizontal_fov(focal_length_fov(50.0) as f32, "diagonal", 1.5);
        assert!(((x.to_radians() * 0.5).tan() - 18.0 / 50.0).abs() < 1e-5, "{x}");
    }

    #[test]
    fn principal_point_offset_shifts_the_image() {
        let to_world = Transform::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        let cam = Perspective::new(to_world, 1.0, 1.0, 0.01, 100.0);
        let shifted = cam.clone().with_principal_offset(Vec2::new(0.1, -0.2));
        let a = shifted.generate_ray(Vec2::new(0.3, 0.6));
        let b = cam.generate_ray(Vec2::new(0.4, 0.4));
        assert!((a.d - b.d).length() < 1e-6);
        let c = shifted.connect(a.at(3.0), 10, 10).unwrap();
        assert!((c.film - Vec2::new(0.3, 0.6)).length() < 1e-4, "{:?}", c.film);
    }

    #[test]
    fn ray_chunks_are_the_scalar_rays_bit_for_bit() {
        let to_world = Transform::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::new(0.1, -0.3, 0.2), Vec3::Y).unwrap();
        let cam = Perspective::new(to_world, 0.7, 1.5, 0.01, 1e4).with_principal_offset(Vec2::new(0.03, -0.01));
        let mut chunk = RayChunk::default();
        let mut film = [Vec2::ZERO; LANES];
        let mut state = 12345u32;
        for f in film.iter_mut() {
            let mut u = || {
                state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
                (state >> 8) as f32 / 16_777_216.0
            };
            *f = Vec2::new(u(), u());
        }
        film[0] = Vec2::ZERO;
        film[1] = Vec2::ONE;
        for (k, f) in film.iter().enumerate() {
            chunk.film[0][k] = f.x;
            chunk.film[1][k] = f.y;
        }
        for level in SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
            let mut c = chunk;
            cam.generate_rays(level, &mut c);
            for (k, f) in film.iter().enumerate() {
                let (a, b) = (c.ray(k), cam.generate_ray(*f));
                let bits = |r: Ray| [r.o.to_array(), r.d.to_array(), [r.tmax; 3]].map(|v| v.map(f32::to_bits));
                assert_eq!(bits(a), bits(b), "{level:?} lane {k}");
            }
        }
    }

    #[test]
    fn image_corners_follow_mitsuba() {
        let to_world = Transform::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        let cam = Perspective::new(to_world, 1.0, 1.0, 0.0, 100.0);
        let top_left = cam.generate_ray(Vec2::new(0.0, 0.0));
        // Looking down -z with +y up, the image's left is world -x and its top world +y.
        assert!(top_left.d.x < 0.0 && top_left.d.y > 0.0 && top_left.d.z < 0.0);
        let centre = cam.generate_ray(Vec2::splat(0.5));
        assert!((centre.d - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
    }

    #[test]
    fn connect_inverts_generate_ray() {
        let to_world = Transform::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        let cam = Perspective::new(to_world, 0.7, 1.5, 0.01, 100.0);
        for &(x, y) in &[(0.1f32, 0.2f32), (0.5, 0.5), (0.93, 0.71)] {
            let ray = cam.generate_ray(Vec2::new(x, y));
            let c = cam.connect(ray.at(3.0), 96, 64).unwrap();
            assert!((c.film - Vec2::new(x, y)).length() < 1e-4, "{:?}", c.film);
            assert!((c.d + ray.d).length() < 1e-4);
        }
        // Importance integrates to the pixel count over the field of view:
        // ∫ W·H/(A cos³θ) dω = W·H, since dω = cos³θ dA at unit depth.
        let n = 400;
        let mut sum = 0.0f64;
        for j in 0..n {
            for i in 0..n {
                let film = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let ray = cam.generate_ray(film);
                let c = cam.connect(ray.at(2.0), 96, 64).unwrap();
                let local = cam.to_world.inverse_vector(ray.d);
                let cos = local.z / local.length();
                let d_area = 4.0 * 0.7 * (0.7 / 1.5) / (n * n) as f32;
                sum += (c.importance * d_area * cos * cos * cos) as f64;
            }
        }
        assert!((sum / (96.0 * 64.0) - 1.0).abs() < 1e-3, "{sum}");
    }
}

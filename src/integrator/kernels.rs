//! SIMD kernels of the batched path tracer ([`super::wavefront`]): work of
//! one stage over all its lanes at once, in lane-major chunks of
//! [`LANES`] (16 `f32` per field, one AVX-512 register), so that the
//! compiler turns each kernel's loop into vector instructions.
//!
//! Each kernel evaluates, lane by lane, exactly the IEEE operations
//! (add, subtract, multiply, divide, square root, compare, select) of the
//! scalar code it replaces, in the same order and without fused
//! multiply-add, so its results are the same bits: the wavefront stays
//! bit-identical to the scalar `path` (tests/wavefront.rs). Selects the
//! scalar code does by arithmetic (`math::sampling::select`) are done by
//! the same arithmetic here.
//!
//! Runtime dispatch as the BVH's ([`crate::geometry::accel::SimdLevel`]):
//! one body, compiled three times — for AVX-512, for AVX2 and for the
//! baseline x86-64 (SSE2; any other CPU) — and chosen by the accelerator's
//! level (`SNELL_SIMD`).
//!
//! | kernel | replaces | lanes |
//! |---|---|---|
//! | [`area_light_directions`] | `AreaLight::sample_direct` by area on a mesh light without vertex normals or texture (`Mesh::sample_position`, `PositionSample::towards`), then `Scene::sample_emitter_ray`'s shadow ray | paths at a smooth BSDF that picked such a light |
//! | [`environment_light_rays`] | the shadow ray of a `constant` emitter's sample (`Scene::sample_emitter_ray`: from the spawn origin, to infinity); its direction (`square_to_uniform_sphere`, a libm sine and cosine) and density are filled in per lane | paths at a `diffuse` BSDF that picked a `constant` emitter (not in pass-through scenes) |
//! | [`diffuse_light_contributions`] | the shading of those samples at a `diffuse` BSDF: the sample's weight, `Diffuse::eval_pdf`, `math::mis_power`, throughput · f · weight · w | the same lanes at a `diffuse` BSDF (not in pass-through scenes) |
//! | [`diffuse_directions`] | `Diffuse::sample`'s direction and density (`square_to_cosine_hemisphere`), `Frame::to_world`, `SurfaceInteraction::spawn_origin` | paths at a `diffuse` BSDF lit from its front side |

use crate::geometry::Ray;
use glam::Vec3;
use crate::geometry::accel::SimdLevel;
use crate::math::{RAY_EPSILON, SHADOW_EPSILON};

/// Lanes per chunk.
pub const LANES: usize = 16;

/// Runs the kernel body `$body` (`#[inline(always)]`) on `$chunks`,
/// compiled for the CPU's level: inside a function with AVX-512's or
/// AVX2's features enabled, or as plain code (baseline x86-64, other
/// CPUs). One body, three compilations, as the BVH's traversal.
macro_rules! dispatch {
    ($level:expr, $body:ident, $chunks:expr, $chunk:ty) => {{
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,bmi1,bmi2,popcnt,lzcnt")]
        unsafe fn avx512(chunks: &mut [$chunk]) {
            $body(chunks)
        }
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,bmi1,bmi2,popcnt,lzcnt")]
        unsafe fn avx2(chunks: &mut [$chunk]) {
            $body(chunks)
        }
        match $level {
            // SAFETY: the accelerator's level is one the CPU supports.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => unsafe { avx512($chunks) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { avx2($chunks) },
            _ => $body($chunks),
        }
    }};
}


/// One chunk of area-light samples: inputs (shading point, its geometric
/// normal, the 2-D sample already re-scaled within the picked triangle,
/// the triangle's corners and unit normal, 1 / the light's area) and
/// outputs (direction, density, the light's point, the shadow ray, and
/// whether the sample stands).
#[derive(Clone, Copy, Default)]
pub struct AreaChunk {
    pub p: [[f32; LANES]; 3],
    pub n: [[f32; LANES]; 3],
    pub u: [[f32; LANES]; 2],
    pub a: [[f32; LANES]; 3],
    pub b: [[f32; LANES]; 3],
    pub c: [[f32; LANES]; 3],
    pub tri_n: [[f32; LANES]; 3],
    pub inv_area: [f32; LANES],
    // Outputs.
    pub d: [[f32; LANES]; 3],
    pub dist: [f32; LANES],
    pub pdf: [f32; LANES],
    pub target: [[f32; LANES]; 3],
    pub ray_o: [[f32; LANES]; 3],
    pub ray_d: [[f32; LANES]; 3],
    pub tmax: [f32; LANES],
    pub ok: [bool; LANES],
    // Inputs of [`diffuse_light_contributions`] (filled for the lanes at a
    // `diffuse` BSDF only): the shading normal, wi's z in the shading
    // frame, the selection's probability, and per channel (RGB: the
    // fourth unused) the path's throughput, the reflectance and the
    // light's radiance.
    pub fn_: [[f32; LANES]; 3],
    pub wi_z: [f32; LANES],
    pub pmf: [f32; LANES],
    pub throughput: [[f32; LANES]; 4],
    pub reflectance: [[f32; LANES]; 4],
    pub radiance: [[f32; LANES]; 4],
    // Its outputs: the contribution, and whether there is one (a sample
    // that stands and a BSDF value that is not zero; the shadow test is
    // still to come).
    pub contrib: [[f32; LANES]; 4],
    pub lit: [bool; LANES],
}

impl AreaChunk {
    /// Lane `l`'s shadow ray (the kernels' outputs).
    #[inline]
    pub fn shadow_ray(&self, l: usize) -> Ray {
        Ray { o: lane_vec3(&self.ray_o, l), d: lane_vec3(&self.ray_d, l), tmax: self.tmax[l] }
    }
}

/// Lane `l` of a chunk's three coordinate rows.
#[inline(always)]
pub fn lane_vec3(a: &[[f32; LANES]; 3], l: usize) -> Vec3 {
    Vec3::new(a[0][l], a[1][l], a[2][l])
}

/// Directions towards area lights sampled by area, for the lanes of
/// `chunks` (inputs filled): what `AreaLight::sample_direct` (its area
/// branch) and `Scene::sample_emitter_ray` compute, before the radiance
/// and the selection's probability are divided in.
pub fn area_light_directions(level: SimdLevel, chunks: &mut [AreaChunk]) {
    dispatch!(level, area_body, chunks, AreaChunk)
}

/// The shadow rays of environment-emitter samples for the lanes of
/// `chunks` whose direction `d` is filled (with the shading point `p` and
/// its geometric normal `n`): `Scene::sample_emitter_ray`'s ray for a
/// sample at infinity — from the spawn origin (`offset_origin`) along `d`
/// without end. Every such sample stands (`ok`); [`diffuse_light_contributions`]
/// then shades them as the area-light samples (`pdf`, `pmf` and the
/// shading inputs filled too).
pub fn environment_light_rays(level: SimdLevel, chunks: &mut [AreaChunk]) {
    dispatch!(level, environment_body, chunks, AreaChunk)
}

#[inline(always)]
fn environment_body(chunks: &mut [AreaChunk]) {
    for ch in chunks.iter_mut() {
        for k in 0..LANES {
            let d = [ch.d[0][k], ch.d[1][k], ch.d[2][k]];
            let o = spawn_origin([ch.p[0][k], ch.p[1][k], ch.p[2][k]], [ch.n[0][k], ch.n[1][k], ch.n[2][k]], d);
            for j in 0..3 {
                ch.ray_o[j][k] = o[j];
                ch.ray_d[j][k] = d[j];
            }
            ch.tmax[k] = f32::INFINITY;
            ch.ok[k] = true;
        }
    }
}

/// `geometry::ray::offset_origin(p, n, d)`: `p` moved along its geometric
/// normal `n` (by (1 + max |p_i|) · ε) to the side `d` leaves to.
#[inline(always)]
fn spawn_origin(p: [f32; 3], n: [f32; 3], d: [f32; 3]) -> [f32; 3] {
    let mag = (1.0 + max3(p[0].abs(), p[1].abs(), p[2].abs())) * RAY_EPSILON;
    let front = n[0] * d[0] + n[1] * d[1] + n[2] * d[2] >= 0.0;
    let mut o = [0.0f32; 3];
    for j in 0..3 {
        let off = n[j] * mag;
        o[j] = if front { p[j] + off } else { p[j] - off };
    }
    o
}

/// glam's `Vec3::max_element` on one component triple.
#[inline(always)]
fn max3(x: f32, y: f32, z: f32) -> f32 {
    let max = |a: f32, b: f32| if a > b { a } else { b };
    max(x, max(y, z))
}

#[inline(always)]
fn area_body(chunks: &mut [AreaChunk]) {
    for ch in chunks.iter_mut() {
        for k in 0..LANES {
            // math::sampling::square_to_uniform_triangle (its arithmetic select).
            let (ux, uy) = (ch.u[0][k], ch.u[1][k]);
            let (hx, hy) = (ux * 0.5, uy * 0.5);
            let m = (uy > ux) as u32 as f32;
            let bx = hx * m + (ux - hy) * (1.0 - m);
            let by = (uy - hx) * m + hy * (1.0 - m);
            // Mesh::sample_position: p = a (1 − b.x − b.y) + b b.x + c b.y.
            let w = 1.0 - bx - by;
            let mut q = [0.0f32; 3];
            for j in 0..3 {
                q[j] = ch.a[j][k] * w + ch.b[j][k] * bx + ch.c[j][k] * by;
            }
            // PositionSample::towards(p).
            let v = [q[0] - ch.p[0][k], q[1] - ch.p[1][k], q[2] - ch.p[2][k]];
            let dist2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
            let dist = dist2.sqrt();
            let ok_dist = dist > 0.0 && dist < f32::INFINITY;
            let d = [v[0] / dist, v[1] / dist, v[2] / dist];
            let tn = [ch.tri_n[0][k], ch.tri_n[1][k], ch.tri_n[2][k]];
            let cos = (tn[0] * d[0] + tn[1] * d[1] + tn[2] * d[2]).abs();
            let ok_cos = !(cos <= 1e-7);
            let pdf = ch.inv_area[k] * dist2 / cos;
            // AreaLight::sample_direction's checks (the shading normal is
            // the face normal: no vertex normals).
            let facing = tn[0] * -d[0] + tn[1] * -d[1] + tn[2] * -d[2];
            let ok_light = !(pdf <= 0.0) && pdf.is_finite() && !(facing <= 0.0);
            // Scene::sample_emitter_ray: the shadow ray from the shading
            // point's spawn origin to just before the light's point.
            let n = [ch.n[0][k], ch.n[1][k], ch.n[2][k]];
            let p = [ch.p[0][k], ch.p[1][k], ch.p[2][k]];
            let mag = (1.0 + max3(p[0].abs(), p[1].abs(), p[2].abs())) * RAY_EPSILON;
            let front = n[0] * d[0] + n[1] * d[1] + n[2] * d[2] >= 0.0;
            let mut o = [0.0f32; 3];
            for j in 0..3 {
                let off = n[j] * mag;
                o[j] = if front { p[j] + off } else { p[j] - off };
            }
            let has_n = tn[0] != 0.0 || tn[1] != 0.0 || tn[2] != 0.0;
            let mag_t = (1.0 + max3(q[0].abs(), q[1].abs(), q[2].abs())) * RAY_EPSILON;
            let front_t = tn[0] * -d[0] + tn[1] * -d[1] + tn[2] * -d[2] >= 0.0;
            let mut r = [0.0f32; 3];
            for j in 0..3 {
                let off = tn[j] * mag_t;
                let t = if front_t { q[j] + off } else { q[j] - off };
                r[j] = (if has_n { t } else { q[j] }) - o[j];
            }
            let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            let ok_ray = !(len <= 0.0);
            for j in 0..3 {
                ch.d[j][k] = d[j];
                ch.target[j][k] = q[j];
                ch.ray_o[j][k] = o[j];
                ch.ray_d[j][k] = r[j] / len;
            }
            ch.dist[k] = dist;
            ch.pdf[k] = pdf;
            ch.tmax[k] = len * (1.0 - SHADOW_EPSILON);
            ch.ok[k] = ok_dist & ok_cos & ok_light & ok_ray;
        }
    }
}

/// The next-event contributions of area-light samples at `diffuse`
/// (Lambertian) BSDFs, for the lanes of `chunks` after
/// [`area_light_directions`] (its outputs and the shading inputs filled):
/// what the path tracer computes after the shadow test — the emitter
/// sample's weight (radiance / pdf / selection, `AreaLight::sample_direct`
/// and `Scene::sample_emitter_ray`), `Diffuse::eval_pdf` of the direction
/// in the shading frame, the power heuristic (`math::mis_power`) and
/// throughput · f · weight · w.
pub fn diffuse_light_contributions(level: SimdLevel, chunks: &mut [AreaChunk]) {
    dispatch!(level, contrib_body, chunks, AreaChunk)
}

#[inline(always)]
fn contrib_body(chunks: &mut [AreaChunk]) {
    use crate::math::INV_PI;
    for ch in chunks.iter_mut() {
        // Per lane first, then per channel: each loop runs over the lanes,
        // so that it becomes vector instructions (a loop over the
        // channels inside one over the lanes would be vectorized across
        // the four channels instead).
        let mut cos = [0.0f32; LANES];
        let mut black = [false; LANES];
        let mut inv_pdf = [0.0f32; LANES];
        let mut inv_pmf = [0.0f32; LANES];
        let mut w = [0.0f32; LANES];
        for k in 0..LANES {
            // SurfaceInteraction::to_local(d).z (glam's dot, left to right).
            let wo_z = ch.d[0][k] * ch.fn_[0][k] + ch.d[1][k] * ch.fn_[1][k] + ch.d[2][k] * ch.fn_[2][k];
            let wi_z = ch.wi_z[k];
            // Diffuse::eval (ρ · (1/π · cos), zero unless both sides are
            // above the surface) and ::pdf (cosine_hemisphere_pdf).
            black[k] = (wi_z <= 0.0) | (wo_z <= 0.0);
            cos[k] = INV_PI * wo_z;
            let pdf_bsdf = if wi_z <= 0.0 { 0.0 } else if wo_z > 0.0 { wo_z * INV_PI } else { 0.0 };
            // The emitter sample: weight = radiance / pdf / pmf (an `Rgb`
            // or `Sampled` divided by x is multiplied by 1 / x), density
            // pdf · pmf; then mis_power(emitter's, BSDF's).
            let (pdf, pmf) = (ch.pdf[k], ch.pmf[k]);
            inv_pdf[k] = 1.0 / pdf;
            inv_pmf[k] = 1.0 / pmf;
            let a = pdf * pmf;
            let a = a * a;
            let b = pdf_bsdf * pdf_bsdf;
            let sum = a + b;
            let ratio = a / sum;
            w[k] = if (sum > 0.0) & a.is_finite() {
                ratio
            } else if a.is_infinite() {
                1.0
            } else {
                0.0
            };
        }
        // throughput · f · weight · w, channel by channel; the BSDF value
        // is zero where all its channels are.
        let mut nonzero = [false; LANES];
        for c in 0..4 {
            for k in 0..LANES {
                let f = if black[k] { 0.0 } else { ch.reflectance[c][k] * cos[k] };
                nonzero[k] |= f != 0.0;
                let weight = ch.radiance[c][k] * inv_pdf[k] * inv_pmf[k];
                ch.contrib[c][k] = ch.throughput[c][k] * f * weight * w[k];
            }
        }
        for k in 0..LANES {
            ch.lit[k] = ch.ok[k] & nonzero[k];
        }
    }
}

/// One chunk of diffuse (Lambertian) BSDF samples: inputs (the 2-D sample,
/// the shading frame s, t, n, the point and its geometric normal) and
/// outputs (the cosine-weighted direction in world space, its density,
/// the next ray's origin, and whether the sample stands). The caller has
/// checked `wi.z > 0` and the context.
#[derive(Clone, Copy, Default)]
pub struct DiffuseChunk {
    pub u: [[f32; LANES]; 2],
    pub s: [[f32; LANES]; 3],
    pub t: [[f32; LANES]; 3],
    pub fn_: [[f32; LANES]; 3],
    pub p: [[f32; LANES]; 3],
    pub n: [[f32; LANES]; 3],
    // Outputs.
    pub d: [[f32; LANES]; 3],
    pub pdf: [f32; LANES],
    pub o: [[f32; LANES]; 3],
    pub ok: [bool; LANES],
}

/// Cosine-weighted directions for the lanes of `chunks`: what
/// `Diffuse::sample` (`square_to_cosine_hemisphere` with its concentric
/// disk and `sin_cos_quarter`, `cosine_hemisphere_pdf`), `Frame::to_world`
/// and `SurfaceInteraction::spawn_origin` compute.
pub fn diffuse_directions(level: SimdLevel, chunks: &mut [DiffuseChunk]) {
    dispatch!(level, diffuse_body, chunks, DiffuseChunk)
}

#[inline(always)]
fn diffuse_body(chunks: &mut [DiffuseChunk]) {
    use crate::math::{INV_PI, PI};
    for ch in chunks.iter_mut() {
        for k in 0..LANES {
            // square_to_uniform_disk_concentric: one of its two branches,
            // chosen per lane (the same division and polynomial).
            let x = 2.0 * ch.u[0][k] - 1.0;
            let y = 2.0 * ch.u[1][k] - 1.0;
            let zero = x == 0.0 && y == 0.0;
            let wide = x.abs() > y.abs();
            let (num, den) = if wide { (y, x) } else { (x, y) };
            let (s, c) = crate::math::trig::sin_cos_quarter((PI / 4.0) * (num / den));
            let (dx, dy) = if wide { (x * c, x * s) } else { (y * s, y * c) };
            let (dx, dy) = if zero { (0.0, 0.0) } else { (dx, dy) };
            // square_to_cosine_hemisphere, cosine_hemisphere_pdf.
            let z = (1.0 - (dx * dx + dy * dy)).max(0.0).sqrt();
            let pdf = if z > 0.0 { z * INV_PI } else { 0.0 };
            // Frame::to_world, then the spawn origin.
            let mut d = [0.0f32; 3];
            for j in 0..3 {
                d[j] = ch.s[j][k] * dx + ch.t[j][k] * dy + ch.fn_[j][k] * z;
            }
            let o = spawn_origin([ch.p[0][k], ch.p[1][k], ch.p[2][k]], [ch.n[0][k], ch.n[1][k], ch.n[2][k]], d);
            for j in 0..3 {
                ch.o[j][k] = o[j];
                ch.d[j][k] = d[j];
            }
            ch.pdf[k] = pdf;
            ch.ok[k] = !(pdf <= 0.0);
        }
    }
}

//! Path reuse across neighbouring pixels (`path`'s `reuse_pixels`): the
//! first bounces of a few neighbouring pixels' samples share the light
//! their second vertices found — the idea of Bekaert, Sbert and Halton,
//! "Accelerating path tracing by re-using paths" (EGWR 2002), as a
//! multi-sample MIS estimator with the balance heuristic.
//!
//! A group is `n` camera samples of the same sample index in `n`
//! consecutive pixels of a row (the group's cut shifts with the index, so
//! no pixel always shares with the same neighbours). Member k's first
//! vertex x_k is a *technique* when its BSDF is `diffuse`, seen from its
//! lit side, with a reflectance above zero in every channel: its bounce
//! direction was drawn from the cosine density p_k. Its second vertex y_k
//! is *shareable* when it lies on a flat-shaded `diffuse` surface with x_k
//! in front: a Lambertian surface reflects the same radiance L(y) towards
//! every point in front of it, and the light the path found after y_k,
//! divided by the path's throughput at y_k, estimates L(y_k) — for every
//! member's x_i, not only x_k.
//!
//! Each technique pixel i then estimates the light it receives from
//! shareable second vertices by
//!
//!   R_i = Σ_j f_i(x_i → y_j) G(x_i, y_j) V(x_i, y_j) L(y_j) / Σ_k p_k(y_j),
//!
//! the sum over the group's shareable y_j, p_k(y) = the density (per unit
//! area) with which technique k samples y, counted only where y is visible
//! from x_k and x_k is in front of y. It replaces the pixel's own
//! estimate of that light (its own y_i is one of the y_j); light through
//! a second vertex that is not shareable (glass, metal, the environment,
//! a surface seen from behind) stays the pixel's own. Unbiased: for every
//! y that pixel i can receive light from, Σ_j p_j(y) / Σ_k p_k(y) = 1
//! (its own technique among the k). Variance: each technique pixel's
//! indirect light averages up to `n` second vertices instead of one, at
//! the cost of up to n(n−1) shadow rays and densities a group. (For a
//! `diffuse` x, f · G is ρ times x's density p(y): one number a pair.)
//!
//! Where it applies: the batched path tracer in RGB (`wavefront.rs`),
//! with no pass-through shapes and `rr_depth` ≥ 2 (Russian roulette at
//! the first vertex would make the techniques' densities random). Other
//! renders ignore it. The image is as deterministic as without it (the
//! groups depend on the sample index and the pixel only): the same for
//! any thread count and pass split. Groups do not cross a render tile
//! (64 pixels wide with reuse, `render.rs`), a crop window or a cluster
//! tile: pixels at such an edge differ in noise (not in expectation) from
//! a full render's.

use crate::bsdf::Bsdf;
use crate::math::INV_PI;
use crate::geometry::ray::offset_origin;
use crate::geometry::{Ray, SurfaceInteraction};
use crate::integrator::path::PathTracer;
use crate::math::SHADOW_EPSILON;
use crate::math::rng::mix64;
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use glam::Vec3;

/// What a path records for reuse: its first vertex and its light before
/// and after the second.
#[derive(Clone, Copy, Debug)]
pub struct ReuseLane<S: Spectrum> {
    /// The first vertex is a technique (see the module's text).
    pub technique: bool,
    pub x: FirstVertex,
    /// x's reflectance (its `diffuse` BSDF's, evaluated once).
    pub rho: S,
    /// Throughput arriving at x, and after x's bounce (arriving at y).
    pub t_x: S,
    pub t_y: S,
    /// The path reached its second vertex and it is shareable.
    pub shareable: bool,
    pub y_p: Vec3,
    /// y's geometric normal.
    pub y_n: Vec3,
    /// The path's light counted up to and including the emission at y.
    pub result_at_y: S,
}

/// What the combination reads of a first vertex: its point, geometric
/// normal (for the shadow ray's offset) and shading normal (the cosine).
#[derive(Clone, Copy, Debug, Default)]
pub struct FirstVertex {
    pub p: Vec3,
    pub n: Vec3,
    pub shading_n: Vec3,
}

impl<S: Spectrum> Default for ReuseLane<S> {
    fn default() -> Self {
        ReuseLane { technique: false, x: FirstVertex::default(), rho: S::zero(), t_x: S::zero(), t_y: S::zero(), shareable: false, y_p: Vec3::ZERO, y_n: Vec3::ZERO, result_at_y: S::zero() }
    }
}

/// Whether `pt` reuses paths in a render of `scene` whose paths carry RGB
/// (`rgb`: not spectral, not polarized) — the one rule, also behind the
/// command line's warning where it does not.
pub fn applies_to(scene: &Scene, pt: &PathTracer, rgb: bool) -> bool {
    pt.reuse_pixels > 1 && rgb && !scene.pass_through && pt.rr_depth >= 2 && !pt.splits() && !pt.guides()
}

/// [`applies_to`] for paths carrying the spectrum type `S`.
pub fn applies<S: Spectrum>(scene: &Scene, pt: &PathTracer) -> bool {
    applies_to(scene, pt, !S::SPECTRAL && !S::POLARIZED)
}

/// Where sample `index`'s groups start in a row: at the pixels x (full-film
/// coordinates) with (x + shift) mod n = 0, the shift a hash of the index.
#[inline]
pub fn group_shift(index: u32, n: u32) -> u32 {
    (mix64(index as u64 ^ 0x7e05_e000) % n as u64) as u32
}

/// Splits the pixels `xs` (full-film coordinates) of sample `index` into
/// groups of at most `n`, calling `group(first, end)` for each.
pub fn for_each_group(xs: std::ops::Range<u32>, index: u32, n: u32, mut group: impl FnMut(u32, u32)) {
    let shift = group_shift(index, n);
    let mut x = xs.start;
    while x < xs.end {
        let to_cut = n - (x + shift) % n;
        let end = (x + to_cut).min(xs.end);
        group(x, end);
        x = end;
    }
}

/// Records the first vertex of the paths `live` (their hits in `si`, the
/// paths that go on from there), as `technique` or not.
pub fn record_first<S: Spectrum>(scene: &Scene, live: &[u32], si: &[SurfaceInteraction], throughput: &[S], wl: &[S::Wavelengths], lanes: &mut [ReuseLane<S>]) {
    for &i in live {
        let i = i as usize;
        let si = &si[i];
        let lane = &mut lanes[i];
        lane.technique = false;
        let Bsdf::Diffuse(d) = scene.bsdf(si) else { continue };
        if !(si.wi.z > 0.0) {
            continue;
        }
        let rho: S = d.reflectance.eval_spectrum::<S>(si, &wl[i]).depolarize();
        let (Some(r), Some(t)) = (rho.to_channels4(), throughput[i].to_channels4()) else { continue };
        if r[..3].iter().chain(&t[..3]).all(|&v| v > 0.0 && v.is_finite()) {
            lane.technique = true;
            lane.x = FirstVertex { p: si.p, n: si.n, shading_n: si.frame.n };
            lane.rho = rho;
            lane.t_x = throughput[i];
        }
    }
}

/// Records the throughput of the paths `live` after their first bounce.
pub fn record_bounce<S: Spectrum>(live: &[u32], throughput: &[S], lanes: &mut [ReuseLane<S>]) {
    for &i in live {
        lanes[i as usize].t_y = throughput[i as usize];
    }
}

/// Records the second vertex of the paths `reached` (those that traced
/// their second ray; `hit` whether it met a surface, `si` where) and their
/// light so far.
pub fn record_second<S: Spectrum>(scene: &Scene, reached: &[u32], hit: &[bool], si: &[SurfaceInteraction], result: &[S], lanes: &mut [ReuseLane<S>]) {
    for &i in reached {
        let i = i as usize;
        let lane = &mut lanes[i];
        lane.result_at_y = result[i];
        lane.shareable = false;
        if !lane.technique || !hit[i] {
            continue;
        }
        let y = &si[i];
        let flat = y.frame.n.dot(y.n) > 1.0 - 1e-5;
        if flat && matches!(scene.bsdf(y), Bsdf::Diffuse(_)) && y.n.dot(lane.x.p - y.p) > 0.0 {
            lane.shareable = true;
            lane.y_p = y.p;
            lane.y_n = y.n;
        }
    }
}

/// Reusable buffers of [`combine`].
#[derive(Default)]
pub struct ReuseBuffers {
    rays: Vec<Ray>,
    blocked: Vec<bool>,
    /// Per shadow ray: the technique member k, the shareable member j and
    /// p_k(y_j).
    pairs: Vec<(u32, u32, f32)>,
    /// The techniques that see one second vertex, with their densities.
    seen: Vec<(usize, f32)>,
}

/// The density (per unit area at y) with which the technique `x` (a
/// `diffuse` BSDF seen from its lit side) samples the point y (normal
/// `y_n`), visibility aside: `Diffuse::pdf`'s cosine density cos θ_x / π
/// times cos θ_y / r²; 0 where x is behind y or y below x's horizon. It is
/// also the pixel's own term: `Diffuse::eval` (ρ/π · cos θ_x) times the
/// geometry term cos θ_y / r² is ρ times it. With the unit direction.
#[inline]
fn area_pdf(x: &FirstVertex, y_p: Vec3, y_n: Vec3) -> (f32, Vec3) {
    let v = y_p - x.p;
    let d2 = v.length_squared();
    let d = v / d2.sqrt();
    let (cos_x, cos_y) = (x.shading_n.dot(d), y_n.dot(-d));
    if !(d2 > 0.0) || !(cos_y > 0.0) || !(cos_x > 0.0) {
        return (0.0, d);
    }
    let p = cos_x * INV_PI * cos_y / d2;
    (if p.is_finite() { p } else { 0.0 }, d)
}

/// A shadow ray from x to y (offset at both ends), `d` the unit direction
/// from x's point to y's.
#[inline]
fn connection(x: &FirstVertex, y_p: Vec3, y_n: Vec3, d: Vec3) -> Option<Ray> {
    let o = offset_origin(x.p, x.n, d);
    let target = offset_origin(y_p, y_n, -d);
    let v = target - o;
    let len = v.length();
    if !(len > 0.0) || !len.is_finite() {
        return None;
    }
    Some(Ray { o, d: v / len, tmax: len * (1.0 - SHADOW_EPSILON) })
}

/// Replaces, in `result`, each technique path's light through shareable
/// second vertices by the group's estimate R_i (see the module's text).
/// `groups` are the lengths of consecutive groups of the batch's paths.
pub fn combine<S: Spectrum>(scene: &Scene, groups: &[u32], lanes: &[ReuseLane<S>], result: &mut [S], buf: &mut ReuseBuffers) {
    // Every pair (k, j), k ≠ j, of a technique k and a shareable j of the
    // same group where k could have sampled y_j (p_k(y_j) > 0): the
    // density, and the visibility by a shadow ray.
    buf.rays.clear();
    buf.pairs.clear();
    let mut start = 0usize;
    for &len in groups {
        let g = start..start + len as usize;
        start = g.end;
        for j in g.clone().filter(|&j| lanes[j].shareable) {
            let (y_p, y_n) = (lanes[j].y_p, lanes[j].y_n);
            for k in g.clone().filter(|&k| k != j && lanes[k].technique) {
                let (p, d) = area_pdf(&lanes[k].x, y_p, y_n);
                if !(p > 0.0) {
                    continue;
                }
                if let Some(ray) = connection(&lanes[k].x, y_p, y_n, d) {
                    buf.rays.push(ray);
                    buf.pairs.push((k as u32, j as u32, p));
                }
            }
        }
    }
    buf.blocked.clear();
    buf.blocked.resize(buf.rays.len(), true);
    scene.accel.occluded_stream(&buf.rays, &mut buf.blocked);

    // Group by group: each shareable j's denominator Σ_k p_k(y_j) over the
    // techniques that see y_j, then its terms ρ_k p_k(y_j) / Σ · L(y_j) to
    // them. The pairs of a j are consecutive.
    let mut start = 0usize;
    let mut pair = 0usize;
    let mut estimate = [S::zero(); MAX_GROUP];
    for &len in groups {
        let g = start..start + len as usize;
        start = g.end;
        estimate[..g.len()].fill(S::zero());
        for j in g.clone().filter(|&j| lanes[j].shareable) {
            let lj = &lanes[j];
            // j itself sees y_j: it sampled it.
            buf.seen.clear();
            buf.seen.push((j, area_pdf(&lj.x, lj.y_p, lj.y_n).0));
            while pair < buf.pairs.len() && buf.pairs[pair].1 as usize == j {
                if !buf.blocked[pair] {
                    buf.seen.push((buf.pairs[pair].0 as usize, buf.pairs[pair].2));
                }
                pair += 1;
            }
            let den: f32 = buf.seen.iter().map(|s| s.1).sum();
            if !(den > 0.0) {
                continue;
            }
            // L(y_j): the light found after y_j over the throughput there.
            let (Some(end), Some(before), Some(at)) = (result[j].to_channels4(), lj.result_at_y.to_channels4(), lj.t_y.to_channels4()) else { continue };
            let mut l = [0.0f32; 4];
            for c in 0..3 {
                l[c] = if at[c] > 0.0 { ((end[c] - before[c]) / at[c]).max(0.0) } else { 0.0 };
            }
            let Some(l) = S::from_channels4(l) else { continue };
            let l = l * (1.0 / den);
            for &(k, p) in &buf.seen {
                estimate[k - g.start] += lanes[k].rho * l * p;
            }
        }
        for i in g.clone() {
            let li = &lanes[i];
            if !li.technique {
                continue;
            }
            // The pixel's own light through a shareable y is replaced.
            let kept = if li.shareable { li.result_at_y } else { result[i] };
            result[i] = kept + li.t_x * estimate[i - g.start];
        }
    }
}

/// The largest group (`reuse_pixels`' upper bound).
pub const MAX_GROUP: usize = 64;

#[cfg(test)]
mod tests {
    use super::*;

    /// The groups of a row cover it once, in order, at most `n` pixels
    /// each, cut where (x + shift) mod n = 0; the cut moves with the index.
    #[test]
    fn groups_tile_the_row() {
        for n in [2u32, 3, 4, 8, 16] {
            let mut shifts = std::collections::HashSet::new();
            for index in 0..64u32 {
                let shift = group_shift(index, n);
                assert!(shift < n);
                shifts.insert(shift);
                for xs in [0..37u32, 5..6, 13..64, 7..7] {
                    let mut next = xs.start;
                    for_each_group(xs.clone(), index, n, |first, end| {
                        assert_eq!(first, next);
                        assert!(end > first && end - first <= n && end <= xs.end);
                        if end < xs.end {
                            assert_eq!((end + shift) % n, 0);
                        }
                        next = end;
                    });
                    assert_eq!(next, xs.end.max(xs.start));
                }
            }
            assert!(shifts.len() > 1, "n = {n}: the cut never moves");
        }
    }
}

//! Warps from the unit square to the domains the renderer samples, each with
//! its density. The chi² tests of the BSDFs rely on these pdfs being exact.

use super::trig::{sin_cos_quarter, sin_cos_turn};
use super::{INV_FOUR_PI, INV_PI, PI};
use crate::geometry::accel::SimdLevel;
use glam::{Vec2, Vec3};

/// Shirley–Chiu concentric map to the unit disk (area-preserving, low distortion).
#[inline]
pub fn square_to_uniform_disk_concentric(u: Vec2) -> Vec2 {
    let x = 2.0 * u.x - 1.0;
    let y = 2.0 * u.y - 1.0;
    if x == 0.0 && y == 0.0 {
        return Vec2::ZERO;
    }
    // φ = π/4 · y/x, or π/2 − π/4 · x/y (sine and cosine swapped): the
    // angle the polynomials take stays within ±π/4 ([`super::trig`]).
    // One evaluation with its operands selected, not two branches: which
    // side wins is random, and a jump on it is mispredicted half the time.
    let wide = x.abs() > y.abs();
    let (num, den) = if wide { (y, x) } else { (x, y) };
    let (s, c) = sin_cos_quarter((PI / 4.0) * (num / den));
    let (a, b) = if wide { (c, s) } else { (s, c) };
    Vec2::new(den * a, den * b)
}

/// Cosine-weighted hemisphere around +z (Malley's method); pdf = cosθ/π.
#[inline]
pub fn square_to_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = square_to_uniform_disk_concentric(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

#[inline]
pub fn cosine_hemisphere_pdf(v: Vec3) -> f32 {
    if v.z > 0.0 { v.z * INV_PI } else { 0.0 }
}

#[inline]
pub fn square_to_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.y;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = sin_cos_turn(u.x);
    Vec3::new(r * c, r * s, z)
}

#[inline]
pub fn uniform_sphere_pdf() -> f32 {
    INV_FOUR_PI
}

/// Uniform direction inside the cone of half-angle acos(cos_max) around +z.
///
/// Works with 1 − cos θ, not cos θ: for a narrow cone (a 0.2° spot) cos θ
/// has only a few hundred f32 values between cos_max and 1, and sin θ taken
/// from it would put the directions on as many rings.
#[inline]
pub fn square_to_uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let one_minus_cos = u.y * (1.0 - cos_max);
    let cos_t = 1.0 - one_minus_cos;
    let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let (s, c) = sin_cos_turn(u.x);
    Vec3::new(c * sin_t, s * sin_t, cos_t)
}

#[inline]
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Uniform barycentrics (b1, b2) on a triangle (Heitz 2019 low-distortion map).
#[inline]
pub fn square_to_uniform_triangle(u: Vec2) -> Vec2 {
    // Both halves computed and one kept: the choice is a coin flip per
    // sample, which a branch mispredicts half the time.
    let (hx, hy) = (u.x * 0.5, u.y * 0.5);
    let upper = u.y > u.x;
    Vec2::new(select(upper, hx, u.x - hy), select(upper, u.y - hx, hy))
}

/// `if c { a } else { b }` for finite `a` and `b`, by arithmetic
/// (a·1 + b·0, exact; only a −0 may come out as +0): the compiler turned selects, even
/// `std::hint::select_unpredictable` and bit masks, back into branches.
#[inline(always)]
pub fn select(c: bool, a: f32, b: f32) -> f32 {
    let m = c as u32 as f32;
    a * m + b * (1.0 - m)
}

/// A discrete distribution over non-negative weights, sampled by its CDF.
#[derive(Clone, Debug, Default)]
pub struct DiscreteDistribution {
    cdf: Vec<f32>,
    sum: f32,
}

impl DiscreteDistribution {
    pub fn new(weights: impl IntoIterator<Item = f32>) -> Self {
        let weights = weights.into_iter();
        let mut cdf = Vec::with_capacity(weights.size_hint().0);
        let mut acc = 0.0f64;
        for w in weights {
            acc += w.max(0.0) as f64;
            cdf.push(acc as f32);
        }
        let sum = acc as f32;
        if sum > 0.0 {
            for c in &mut cdf {
                *c /= sum;
            }
        }
        DiscreteDistribution { cdf, sum }
    }

    pub fn sum(&self) -> f32 {
        self.sum
    }

    pub fn len(&self) -> usize {
        self.cdf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cdf.is_empty()
    }

    pub fn pmf(&self, i: usize) -> f32 {
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        self.cdf[i] - lo
    }

    /// Returns the index and the sample re-scaled to [0,1) within that bin.
    #[inline]
    pub fn sample_reuse(&self, u: f32) -> (usize, f32) {
        sample_cdf_reuse(&self.cdf, u)
    }

    /// The normalised cumulative weights (for callers that keep a copy next
    /// to their own per-bin data and sample it with [`sample_cdf_reuse`]).
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }
}

/// [`DiscreteDistribution::sample_reuse`] on a copy of its CDF (not empty):
/// the bin for `u` and `u` re-scaled to [0,1) within it.
#[inline]
pub fn sample_cdf_reuse(cdf: &[f32], u: f32) -> (usize, f32) {
    let n = cdf.len();
    // The CDF is sorted, so the partition point is the count of entries
    // ≤ u: for a few bins (an emitting rectangle's two triangles) counted
    // without a jump, whose outcome is a coin flip per sample.
    let count = if n <= 8 {
        cdf.iter().map(|&c| usize::from(c <= u)).sum::<usize>()
    } else {
        cdf.partition_point(|&c| c <= u)
    };
    let i = count.min(n - 1);
    // The bin's lower end without a branch on i (for a few bins, as an
    // emitting rectangle's two triangles, it is a coin flip).
    let lo = cdf[i.saturating_sub(1)] * (i as f32).min(1.0);
    let w = cdf[i] - lo;
    let r = if w > 0.0 { ((u - lo) / w).clamp(0.0, 1.0 - f32::EPSILON / 2.0) } else { 0.0 };
    (i, r)
}

/// A grid of non-negative cell weights sampled by descending a pyramid of
/// their sums (a quadtree, padded to powers of two with empty cells): at
/// each level the column half is chosen by the two columns' sums, then the
/// row half within it, each time re-scaling the sample. Unlike a marginal
/// row then a conditional column, nearby points of the unit square land in
/// nearby cells in both directions, so stratified samples stay stratified
/// over the grid; and the children of a node are stored side by side, so
/// each level costs one cache line.
#[derive(Clone, Debug, Default)]
pub struct CellHierarchy {
    /// From the finest level (the cells) to the 2 × 2 (or 2 × 1) below the
    /// root: each node's children contiguous, in the order (y bit, x bit).
    levels: Vec<HierarchyLevel>,
    sum: f32,
}

#[derive(Clone, Debug, Default)]
struct HierarchyLevel {
    /// Width of the parent level (in nodes).
    parent_width: usize,
    /// Whether this level splits its parents' nodes in x and in y.
    split_x: bool,
    split_y: bool,
    values: Vec<f32>,
}

impl CellHierarchy {
    /// `weight(i, j)` of cell column i < `width`, row j < `height`.
    pub fn new(width: usize, height: usize, weight: impl Fn(usize, usize) -> f32) -> Self {
        let (mut w, mut h) = (width.max(1).next_power_of_two(), height.max(1).next_power_of_two());
        // The finest level in row-major order, padded.
        let mut grid: Vec<f64> = vec![0.0; w * h];
        for j in 0..height {
            for i in 0..width {
                grid[j * w + i] = weight(i, j).max(0.0) as f64;
            }
        }
        let mut levels = Vec::new();
        while w > 1 || h > 1 {
            let (sx, sy) = (usize::from(w > 1), usize::from(h > 1));
            let (pw, ph) = (w >> sx, h >> sy);
            let mut values = vec![0.0f32; w * h];
            let mut parent = vec![0.0f64; pw * ph];
            for y in 0..h {
                for x in 0..w {
                    let block = (y >> sy) * pw + (x >> sx);
                    let within = ((y & sy) << sx) | (x & sx);
                    values[(block << (sx + sy)) | within] = grid[y * w + x] as f32;
                    parent[block] += grid[y * w + x];
                }
            }
            levels.push(HierarchyLevel { parent_width: pw, split_x: sx == 1, split_y: sy == 1, values });
            grid = parent;
            (w, h) = (pw, ph);
        }
        CellHierarchy { levels, sum: grid[0] as f32 }
    }

    /// The sum of the weights.
    pub fn sum(&self) -> f32 {
        self.sum
    }

    /// The cell (column, row) for `u` in [0, 1)², and `u` re-scaled to
    /// [0, 1)² within it; `None` if every weight is zero.
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<(usize, usize, Vec2)> {
        if !(self.sum > 0.0) {
            return None;
        }
        let mut walk = (0usize, 0usize, u);
        for level in self.levels.iter().rev() {
            level.step(&mut walk);
        }
        Some(walk)
    }

    /// [`CellHierarchy::sample`] of each of `us` into `out` (same length),
    /// level by level across them: the samples' descents are independent,
    /// so their loads and divisions overlap where one descent alone waits
    /// on each in turn; with AVX2 (`level`), eight at a time in vectors
    /// (gathers), with the same arithmetic, so the same cells and offsets.
    pub fn sample_batch(&self, level: SimdLevel, us: &[Vec2], out: &mut [Option<(usize, usize, Vec2)>]) {
        if !(self.sum > 0.0) {
            out.fill(None);
            return;
        }
        let mut done = 0;
        #[cfg(target_arch = "x86_64")]
        if matches!(level, SimdLevel::Avx2 | SimdLevel::Avx512) && self.levels.iter().all(|l| l.values.len() <= i32::MAX as usize) {
            while done + 8 <= us.len() {
                // SAFETY: the level is one this CPU runs (it has AVX2), and
                // the indices fit gathers' 32 bits (checked above).
                unsafe { descend8_avx2(&self.levels, &us[done..done + 8], &mut out[done..done + 8]) };
                done += 8;
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = level;
        const GROUP: usize = 16;
        for (us, out) in us[done..].chunks(GROUP).zip(out[done..].chunks_mut(GROUP)) {
            let mut walks = [(0usize, 0usize, Vec2::ZERO); GROUP];
            let walks = &mut walks[..us.len()];
            for (w, &u) in walks.iter_mut().zip(us) {
                w.2 = u;
            }
            for level in self.levels.iter().rev() {
                for w in walks.iter_mut() {
                    level.step(w);
                }
            }
            for (o, &w) in out.iter_mut().zip(walks.iter()) {
                *o = Some(w);
            }
        }
    }
}

/// [`CellHierarchy::sample_batch`] of eight samples in AVX2 vectors: the
/// steps of [`HierarchyLevel::step`] and [`pick`], operation for operation.
///
/// # Safety
/// The CPU must have AVX2; every level's values must be indexable by i32.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn descend8_avx2(levels: &[HierarchyLevel], us: &[Vec2], out: &mut [Option<(usize, usize, Vec2)>]) {
    use std::arch::x86_64::*;
    // SAFETY (all intrinsics): the caller's CPU has AVX2; the gathers read
    // only children of nodes the descent reached, inside each level.
    unsafe {
        let lane = |k: usize| us[k];
        let mut ux = _mm256_setr_ps(lane(0).x, lane(1).x, lane(2).x, lane(3).x, lane(4).x, lane(5).x, lane(6).x, lane(7).x);
        let mut uy = _mm256_setr_ps(lane(0).y, lane(1).y, lane(2).y, lane(3).y, lane(4).y, lane(5).y, lane(6).y, lane(7).y);
        let (mut x, mut y) = (_mm256_setzero_si256(), _mm256_setzero_si256());
        let one = _mm256_set1_epi32(1);
        // `pick`: the choice (0 or 1 per lane) and u re-scaled within it.
        let pick = |u: __m256, a: __m256, b: __m256| {
            let t = _mm256_mul_ps(u, _mm256_add_ps(a, b));
            let second = _mm256_cmp_ps::<_CMP_GE_OQ>(t, a);
            let start = _mm256_and_ps(second, a);
            let width = _mm256_blendv_ps(a, b, second);
            let v = _mm256_div_ps(_mm256_sub_ps(t, start), width);
            let v = _mm256_min_ps(_mm256_max_ps(v, _mm256_setzero_ps()), _mm256_set1_ps(ONE_MINUS_EPSILON));
            (second, _mm256_and_si256(_mm256_castps_si256(second), one), v)
        };
        for level in levels.iter().rev() {
            let (sx, sy) = (i32::from(level.split_x), i32::from(level.split_y));
            let node = _mm256_add_epi32(_mm256_mullo_epi32(y, _mm256_set1_epi32(level.parent_width as i32)), x);
            let base = _mm256_sll_epi32(node, _mm_cvtsi32_si128(sx + sy));
            let values = level.values.as_ptr();
            let child = |k: i32| _mm256_i32gather_ps::<4>(values, _mm256_add_epi32(base, _mm256_set1_epi32(k)));
            match (level.split_x, level.split_y) {
                (true, true) => {
                    let (c00, c10, c01, c11) = (child(0), child(1), child(2), child(3));
                    let (right, bx, u) = pick(ux, _mm256_add_ps(c00, c01), _mm256_add_ps(c10, c11));
                    ux = u;
                    let (_, by, u) = pick(uy, _mm256_blendv_ps(c00, c10, right), _mm256_blendv_ps(c01, c11, right));
                    uy = u;
                    x = _mm256_or_si256(_mm256_slli_epi32::<1>(x), bx);
                    y = _mm256_or_si256(_mm256_slli_epi32::<1>(y), by);
                }
                (true, false) => {
                    let (_, bx, u) = pick(ux, child(0), child(1));
                    ux = u;
                    x = _mm256_or_si256(_mm256_slli_epi32::<1>(x), bx);
                }
                (false, true) => {
                    let (_, by, u) = pick(uy, child(0), child(1));
                    uy = u;
                    y = _mm256_or_si256(_mm256_slli_epi32::<1>(y), by);
                }
                (false, false) => {}
            }
        }
        let (mut xs, mut ys, mut vx, mut vy) = ([0i32; 8], [0i32; 8], [0f32; 8], [0f32; 8]);
        _mm256_storeu_si256(xs.as_mut_ptr().cast(), x);
        _mm256_storeu_si256(ys.as_mut_ptr().cast(), y);
        _mm256_storeu_ps(vx.as_mut_ptr(), ux);
        _mm256_storeu_ps(vy.as_mut_ptr(), uy);
        for k in 0..8 {
            out[k] = Some((xs[k] as usize, ys[k] as usize, Vec2::new(vx[k], vy[k])));
        }
    }
}

impl HierarchyLevel {
    /// One level down: from node (x, y) of the parent level to its child,
    /// the sample re-scaled within it.
    #[inline(always)]
    fn step(&self, (x, y, u): &mut (usize, usize, Vec2)) {
        let (sx, sy) = (usize::from(self.split_x), usize::from(self.split_y));
        let base = (*y * self.parent_width + *x) << (sx + sy);
        let c = |bx: usize, by: usize| self.values[base + ((by << sx) | bx)];
        let mut bx = 0;
        if sx == 1 {
            let (left, right) = if sy == 1 { (c(0, 0) + c(0, 1), c(1, 0) + c(1, 1)) } else { (c(0, 0), c(1, 0)) };
            (bx, u.x) = pick(u.x, left, right);
        }
        let mut by = 0;
        if sy == 1 {
            (by, u.y) = pick(u.y, c(bx, 0), c(bx, 1));
        }
        *x = (*x << sx) | bx;
        *y = (*y << sy) | by;
    }
}

/// Of two weights (not both zero), the first for u below its share, with u
/// re-scaled to [0, 1) within the choice. Without a branch: the choice is
/// a coin flip a branch predictor cannot learn.
#[inline(always)]
fn pick(u: f32, a: f32, b: f32) -> (usize, f32) {
    let t = u * (a + b);
    let second = t >= a;
    let (start, width) = (if second { a } else { 0.0 }, if second { b } else { a });
    // max, then min: NaN (0 / 0, never reached from a non-zero node) to 0,
    // as the vector form does.
    (usize::from(second), ((t - start) / width).max(0.0).min(ONE_MINUS_EPSILON))
}

const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Pcg32;

    #[test]
    fn concentric_disk_stays_inside() {
        let mut r = Pcg32::new(3, 0);
        for _ in 0..10000 {
            let p = square_to_uniform_disk_concentric(Vec2::new(r.next_f32(), r.next_f32()));
            assert!(p.length() <= 1.0 + 1e-5);
        }
    }

    #[test]
    fn triangle_barycentrics_are_uniform() {
        // The mean of uniform barycentrics over a triangle is (1/3, 1/3).
        let mut r = Pcg32::new(5, 0);
        let n = 100_000;
        let mut m = Vec2::ZERO;
        for _ in 0..n {
            let b = square_to_uniform_triangle(Vec2::new(r.next_f32(), r.next_f32()));
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
            m += b;
        }
        m /= n as f32;
        assert!((m.x - 1.0 / 3.0).abs() < 0.005 && (m.y - 1.0 / 3.0).abs() < 0.005);
    }

    #[test]
    fn narrow_cone_directions_are_not_quantized() {
        // A 0.2° cone: uniform in solid angle means sin²θ ≈ θ² uniform, so the
        // direction drawn with u.y = k/1000 has sin θ = sin θ_max·√(k/1000)
        // (within 0.1 %), and a thousand u.y give a thousand distinct angles.
        let cos_max = 0.2f32.to_radians().cos();
        let sin_max = (1.0 - (cos_max as f64).powi(2)).sqrt();
        let mut last = 0.0f64;
        for k in 1..=1000 {
            let d = square_to_uniform_cone(Vec2::new(0.3, k as f32 / 1000.0), cos_max);
            let sin_t = (d.x as f64).hypot(d.y as f64);
            let want = sin_max * (k as f64 / 1000.0).sqrt();
            assert!((sin_t / want - 1.0).abs() < 1e-3, "u.y = {k}/1000: sin θ {sin_t}, want {want}");
            assert!(sin_t > last);
            last = sin_t;
            assert!((d.length() - 1.0).abs() < 1e-6 && d.z >= cos_max);
        }
    }

    #[test]
    fn discrete_distribution_matches_weights() {
        let d = DiscreteDistribution::new([1.0, 0.0, 3.0]);
        assert!((d.pmf(0) - 0.25).abs() < 1e-6 && d.pmf(1) == 0.0 && (d.pmf(2) - 0.75).abs() < 1e-6);
        assert_eq!(d.sample_reuse(0.1).0, 0);
        assert_eq!(d.sample_reuse(0.3).0, 2);
        let (_, r) = d.sample_reuse(0.625);
        assert!((r - 0.5).abs() < 1e-5);
    }

    /// The counted bin of short CDFs is the binary search's, for zero-weight
    /// bins (repeated entries), u exactly on an entry, at 0 and past 1.
    #[test]
    fn short_cdfs_pick_the_binary_searchs_bin() {
        let mut rng = crate::math::Pcg32::new(11, 2);
        for n in 1..=12 {
            for _ in 0..2000 {
                let weights: Vec<f32> = (0..n)
                    .map(|_| if rng.next_f32() < 0.3 { 0.0 } else { rng.next_f32() })
                    .collect();
                let d = DiscreteDistribution::new(weights);
                if d.sum() <= 0.0 {
                    continue;
                }
                let cdf = d.cdf();
                let pick = cdf[(rng.next_f32() * n as f32) as usize % n];
                for u in [rng.next_f32(), pick, 0.0, 1.0, 1.5] {
                    let want = cdf.partition_point(|&c| c <= u).min(n - 1);
                    assert_eq!(sample_cdf_reuse(cdf, u).0, want, "u {u} in {cdf:?}");
                }
            }
        }
    }

    /// Cells are chosen in proportion to their weights (χ² over the grid,
    /// zero cells never), for grids not a power of two in size and with a
    /// single row; the re-scaled sample is uniform within the cell.
    #[test]
    fn cell_hierarchy_samples_by_weight() {
        let mut rng = crate::math::Pcg32::new(3, 8);
        for (w, h) in [(5usize, 3usize), (8, 1), (1, 6), (16, 9)] {
            let weights: Vec<f32> = (0..w * h).map(|_| if rng.next_f32() < 0.25 { 0.0 } else { 0.1 + rng.next_f32() }).collect();
            let hier = CellHierarchy::new(w, h, |i, j| weights[j * w + i]);
            let total: f32 = weights.iter().sum();
            assert!((hier.sum() - total).abs() < 1e-5 * total);
            let n = 200_000;
            let mut count = vec![0.0f64; w * h];
            let mut rest_mean = Vec2::ZERO;
            for _ in 0..n {
                let (i, j, r) = hier.sample(Vec2::new(rng.next_f32(), rng.next_f32())).unwrap();
                assert!(i < w && j < h && (0.0..1.0).contains(&r.x) && (0.0..1.0).contains(&r.y));
                count[j * w + i] += 1.0;
                rest_mean += r / n as f32;
            }
            let mut chi2 = 0.0;
            let mut dof = -1i32;
            for k in 0..w * h {
                let e = weights[k] as f64 / total as f64 * n as f64;
                if e == 0.0 {
                    assert_eq!(count[k], 0.0, "a zero-weight cell was chosen");
                    continue;
                }
                chi2 += (count[k] - e).powi(2) / e;
                dof += 1;
            }
            // χ² well within its distribution (mean dof, sd √(2 dof)).
            assert!(chi2 < dof as f64 + 5.0 * (2.0 * dof as f64).sqrt() + 5.0, "{w}×{h}: χ² {chi2} for {dof} dof");
            assert!((rest_mean - Vec2::splat(0.5)).abs().max_element() < 0.01);
        }
        assert!(CellHierarchy::new(3, 2, |_, _| 0.0).sample(Vec2::splat(0.5)).is_none());
    }

    /// The batch descends exactly as one sample at a time does, at every
    /// SIMD level this CPU runs (100 samples: vectors and a remainder).
    #[test]
    fn cell_hierarchy_batch_equals_single_samples() {
        let mut rng = crate::math::Pcg32::new(21, 4);
        let weights: Vec<f32> = (0..37 * 11).map(|_| rng.next_f32() * rng.next_f32()).collect();
        let hier = CellHierarchy::new(37, 11, |i, j| weights[j * 37 + i]);
        let us: Vec<Vec2> = (0..100).map(|_| Vec2::new(rng.next_f32(), rng.next_f32())).collect();
        for level in SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
            let mut out = vec![None; us.len()];
            hier.sample_batch(level, &us, &mut out);
            for (u, o) in us.iter().zip(&out) {
                let single = hier.sample(*u).unwrap();
                let batch = o.unwrap();
                assert_eq!((single.0, single.1, single.2.x.to_bits(), single.2.y.to_bits()), (batch.0, batch.1, batch.2.x.to_bits(), batch.2.y.to_bits()), "{}", level.name());
            }
        }
    }

    /// Stratified samples stay spread over the grid: 4 × 4 strata of the
    /// square over 4 × 4 equal cells put one sample in each.
    #[test]
    fn cell_hierarchy_keeps_strata_apart() {
        let hier = CellHierarchy::new(4, 4, |_, _| 1.0);
        let mut seen = [0; 16];
        for a in 0..4 {
            for b in 0..4 {
                let (i, j, _) = hier.sample(Vec2::new((a as f32 + 0.5) / 4.0, (b as f32 + 0.5) / 4.0)).unwrap();
                seen[j * 4 + i] += 1;
            }
        }
        assert_eq!(seen, [1; 16]);
    }
}

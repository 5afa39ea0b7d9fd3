//! Reconstruction filters (`rfilter`), defined as in Mitsuba 3.
//!
//! | plugin | parameters | footprint |
//! |---|---|---|
//! | `box` | — | radius ½: each sample lands in its own pixel |
//! | `tent` | `radius` (1) | w(x) = max(0, 1 − \|x\|/radius) |
//! | `gaussian` | `stddev` (0.5) | w(x) = max(0, e^(−x²/2σ²) − e^(−r²/2σ²)), radius r = 4σ |
//! | `mitchell` | `B` (⅓), `C` (⅓) | Mitchell–Netravali cubic, radius 2 |
//! | `catmullrom` | — | the Mitchell–Netravali cubic with B = 0, C = ½, radius 2 |
//! | `lanczos` | `lobes` (3, at most 4) | sinc(x)·sinc(x/lobes) for \|x\| ≤ lobes, radius = lobes |
//!
//! Filters are separable: w(x, y) = w(x)·w(y). Mitchell (for C > 0),
//! Catmull–Rom and Lanczos have negative lobes: a pixel is still Σ w·L / Σ w
//! over its samples (as in Mitsuba), and the film leaves a pixel black where
//! that sum of weights is zero or the quotient is not finite.
//!
//! ```xml
//! <film type="hdrfilm">
//!     <rfilter type="lanczos"><integer name="lobes" value="2"/></rfilter>
//! </film>
//! ```

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FilterKind {
    Box,
    Tent { radius: f32 },
    Gaussian { stddev: f32, radius: f32 },
    /// Mitchell–Netravali (Catmull–Rom: B = 0, C = ½).
    Mitchell { b: f32, c: f32 },
    Lanczos { lobes: u32 },
}

/// A filter with a lookup table of its values, so splatting a sample costs
/// no transcendental functions (Mitsuba discretises its filters likewise).
#[derive(Clone, Debug, PartialEq)]
pub struct Filter {
    pub kind: FilterKind,
    radius: f32,
    /// (LUT − 1) / radius: maps |x| to a table position.
    scale: f32,
    /// Segment i: the values at |x| = i·radius/(LUT − 1) and the next one,
    /// stored together so a lookup reads one entry (a fixed size, so a
    /// lookup needs no bounds check).
    segments: Box<[[f32; 2]; LUT - 1]>,
    /// Whether every value [`Filter::eval`] returns lies within ±1 (so a
    /// sink need not check each sample's weights).
    within_one: bool,
}

const LUT: usize = 256;

impl FilterKind {
    pub fn radius(&self) -> f32 {
        match self {
            FilterKind::Box => 0.5,
            FilterKind::Tent { radius } => *radius,
            FilterKind::Gaussian { radius, .. } => *radius,
            FilterKind::Mitchell { .. } => 2.0,
            FilterKind::Lanczos { lobes } => *lobes as f32,
        }
    }

    /// The exact filter value at offset `x` (pixels).
    pub fn eval(&self, x: f32) -> f32 {
        match *self {
            FilterKind::Box => {
                if (-0.5..0.5).contains(&x) { 1.0 } else { 0.0 }
            }
            FilterKind::Tent { radius } => (1.0 - x.abs() / radius).max(0.0),
            FilterKind::Gaussian { stddev, radius } => {
                let alpha = -1.0 / (2.0 * stddev * stddev);
                ((alpha * x * x).exp() - (alpha * radius * radius).exp()).max(0.0)
            }
            FilterKind::Mitchell { b, c } => {
                let x = x.abs();
                let (x2, x3) = (x * x, x * x * x);
                let v = if x < 1.0 {
                    (12.0 - 9.0 * b - 6.0 * c) * x3 + (-18.0 + 12.0 * b + 6.0 * c) * x2 + (6.0 - 2.0 * b)
                } else if x < 2.0 {
                    (-b - 6.0 * c) * x3 + (6.0 * b + 30.0 * c) * x2 + (-12.0 * b - 48.0 * c) * x + (8.0 * b + 24.0 * c)
                } else {
                    0.0
                };
                v / 6.0
            }
            FilterKind::Lanczos { lobes } => {
                let (x, r) = (x.abs(), lobes as f32);
                if x < f32::EPSILON {
                    1.0
                } else if x > r {
                    0.0
                } else {
                    let a = crate::math::PI * x;
                    let b = a / r;
                    (a.sin() * b.sin()) / (a * b)
                }
            }
        }
    }
}

impl Filter {
    pub fn new(kind: FilterKind) -> Filter {
        let radius = kind.radius();
        let value = |i: usize| kind.eval(radius * i as f32 / (LUT - 1) as f32);
        let segments: Box<[[f32; 2]; LUT - 1]> = Box::new(std::array::from_fn(|i| [value(i), value(i + 1)]));
        // A lookup a + (b − a)·t (0 ≤ t < 1) lies between a and b up to a
        // few roundings (< 10⁻⁶ relative); the box filter returns 0 or 1.
        let peak = segments.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
        let within_one = matches!(kind, FilterKind::Box) || (peak.is_finite() && peak * (1.0 + 1e-6) <= 1.0);
        Filter { kind, radius, scale: (LUT - 1) as f32 / radius, segments, within_one }
    }

    pub fn catmull_rom() -> Filter {
        Filter::new(FilterKind::Mitchell { b: 0.0, c: 0.5 })
    }

    pub fn gaussian(stddev: f32) -> Filter {
        Filter::new(FilterKind::Gaussian { stddev, radius: 4.0 * stddev })
    }

    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Whether every value of [`Filter::eval`] lies within ±1.
    #[inline]
    pub fn within_one(&self) -> bool {
        self.within_one
    }

    #[inline]
    pub fn eval(&self, x: f32) -> f32 {
        if let FilterKind::Box = self.kind {
            return box_value(x);
        }
        self.lookup(x)
    }

    /// The values at the pixel centres `first` + i + ½ (i = 0, 1, …) seen
    /// from position `pos`: `out[i]` = [`Filter::eval`]`((first + i) as f32
    /// + 0.5 − pos)`, the same bits, with the filter's kind tested once (and
    /// the table looked up four values at a time on x86-64).
    #[inline]
    pub fn eval_span(&self, first: i32, pos: f32, out: &mut [f32]) {
        let x = |i: usize| (first + i as i32) as f32 + 0.5 - pos;
        if let FilterKind::Box = self.kind {
            for (i, w) in out.iter_mut().enumerate() {
                *w = box_value(x(i));
            }
            return;
        }
        #[cfg(target_arch = "x86_64")]
        for (k, chunk) in out.chunks_mut(4).enumerate() {
            let v = self.lookup4(first + 4 * k as i32, pos);
            chunk.copy_from_slice(&v[..chunk.len()]);
        }
        #[cfg(not(target_arch = "x86_64"))]
        for (i, w) in out.iter_mut().enumerate() {
            *w = self.lookup(x(i));
        }
    }

    /// [`Filter::lookup`] at the pixel centres `first` + i + ½ (i < 4) seen
    /// from `pos`, in SSE2 (part of x86-64): lane by lane the same IEEE
    /// operations (conversions exact for pixel coordinates), so the same
    /// bits; a lane outside the table is +0, as there.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn lookup4(&self, first: i32, pos: f32) -> [f32; 4] {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of the x86-64 baseline; the stores write
        // 16 bytes into 16-byte arrays.
        unsafe {
            let centre = _mm_cvtepi32_ps(_mm_add_epi32(_mm_set1_epi32(first), _mm_set_epi32(3, 2, 1, 0)));
            let x = _mm_sub_ps(_mm_add_ps(centre, _mm_set1_ps(0.5)), _mm_set1_ps(pos));
            let abs = _mm_and_ps(x, _mm_castsi128_ps(_mm_set1_epi32(0x7fff_ffff)));
            let f = _mm_mul_ps(abs, _mm_set1_ps(self.scale));
            // f < LUT − 1 (false for NaN); other lanes look up entry 0 and
            // are zeroed at the end.
            let inside = _mm_cmplt_ps(f, _mm_set1_ps((LUT - 1) as f32));
            let i = _mm_cvttps_epi32(_mm_and_ps(f, inside));
            let t = _mm_sub_ps(f, _mm_cvtepi32_ps(i));
            let mut idx = [0i32; 4];
            _mm_storeu_si128(idx.as_mut_ptr() as *mut __m128i, i);
            let seg = idx.map(|i| self.segments[(i as usize).min(LUT - 2)]);
            let a = _mm_set_ps(seg[3][0], seg[2][0], seg[1][0], seg[0][0]);
            let b = _mm_set_ps(seg[3][1], seg[2][1], seg[1][1], seg[0][1]);
            let v = _mm_and_ps(_mm_add_ps(a, _mm_mul_ps(_mm_sub_ps(b, a), t)), inside);
            let mut out = [0.0f32; 4];
            _mm_storeu_ps(out.as_mut_ptr(), v);
            out
        }
    }

    /// [`Filter::eval_span`] of four pixels along x from pixel `x0` and four
    /// along y from pixel `y0`, seen from `pos`, in one AVX2 vector: lanes
    /// 0–3 hold x's values, lanes 4–7 y's. Lane by lane the same IEEE
    /// operations as `eval_span` (the box's comparisons, or
    /// [`Filter::lookup4`]'s with the table's entries read by 64-bit
    /// loads), so the same bits.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) unsafe fn eval_spans4_avx2(&self, x0: i32, y0: i32, pos: glam::Vec2) -> std::arch::x86_64::__m256 {
        use std::arch::x86_64::*;
        let first = _mm256_setr_epi32(x0, x0, x0, x0, y0, y0, y0, y0);
        let centre = _mm256_cvtepi32_ps(_mm256_add_epi32(first, _mm256_setr_epi32(0, 1, 2, 3, 0, 1, 2, 3)));
        let p = _mm256_setr_ps(pos.x, pos.x, pos.x, pos.x, pos.y, pos.y, pos.y, pos.y);
        let x = _mm256_sub_ps(_mm256_add_ps(centre, _mm256_set1_ps(0.5)), p);
        if let FilterKind::Box = self.kind {
            // `box_value`: 1 on [−½, ½) (false for NaN).
            let inside = _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(x, _mm256_set1_ps(-0.5)), _mm256_cmp_ps::<_CMP_LT_OQ>(x, _mm256_set1_ps(0.5)));
            return _mm256_and_ps(inside, _mm256_set1_ps(1.0));
        }
        let abs = _mm256_and_ps(x, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff)));
        let f = _mm256_mul_ps(abs, _mm256_set1_ps(self.scale));
        let inside = _mm256_cmp_ps::<_CMP_LT_OQ>(f, _mm256_set1_ps((LUT - 1) as f32));
        let i = _mm256_cvttps_epi32(_mm256_and_ps(f, inside));
        let t = _mm256_sub_ps(f, _mm256_cvtepi32_ps(i));
        // 0 ≤ i < LUT − 1 already (f ≥ 0; outside lanes read entry 0): the
        // `min`, as `lookup4`'s, bounds the loads by the table's size.
        let i = _mm256_min_epi32(i, _mm256_set1_epi32((LUT - 2) as i32));
        // The eight entries (a, b) read as 64-bit loads, not by gathers:
        // AMD's Zen cores (and Intel's since the gather-data-sampling
        // microcode) take longer for two 8-lane gathers than for eight
        // loads and a few shuffles.
        let mut idx = [0i32; 8];
        // SAFETY: 32 bytes into a 32-byte array.
        unsafe { _mm256_storeu_si256(idx.as_mut_ptr() as *mut __m256i, i) };
        let base = self.segments.as_ptr();
        // SAFETY: 0 ≤ idx[k] ≤ LUT − 2, an entry of the table (8 bytes).
        let pairs = |j: usize, k: usize| unsafe {
            let entry = |k: usize| base.add(idx[k] as usize) as *const f64;
            _mm_loadh_pd(_mm_load_sd(entry(j)), entry(k))
        };
        // [a0 b0 a1 b1 | a4 b4 a5 b5] and [a2 b2 a3 b3 | a6 b6 a7 b7].
        let v0 = _mm256_castpd_ps(_mm256_set_m128d(pairs(4, 5), pairs(0, 1)));
        let v1 = _mm256_castpd_ps(_mm256_set_m128d(pairs(6, 7), pairs(2, 3)));
        let a = _mm256_shuffle_ps::<0b10_00_10_00>(v0, v1);
        let b = _mm256_shuffle_ps::<0b11_01_11_01>(v0, v1);
        _mm256_and_ps(_mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), t)), inside)
    }

    /// The table's value at `x` (every kind but the box).
    #[inline(always)]
    fn lookup(&self, x: f32) -> f32 {
        let f = x.abs() * self.scale;
        if !(f < (LUT - 1) as f32) {
            return 0.0;
        }
        // SAFETY: 0 ≤ f < LUT − 1 here (a NaN fails the test above), so the
        // conversion is in range and truncates as `as` would.
        let i = unsafe { f.to_int_unchecked::<u32>() } as usize;
        let t = f - i as f32;
        // `min` is a no-op (i < LUT − 1) that spares the bounds check.
        let [a, b] = self.segments[i.min(LUT - 2)];
        a + (b - a) * t
    }
}

/// The box filter: 1 on [−½, ½), else 0.
#[inline(always)]
fn box_value(x: f32) -> f32 {
    if (-0.5..0.5).contains(&x) { 1.0 } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_matches_the_exact_filter() {
        for f in [Filter::new(FilterKind::Tent { radius: 1.5 }), Filter::gaussian(0.5)] {
            for i in 0..1000 {
                let x = -2.5 + 5.0 * i as f32 / 999.0;
                assert!((f.eval(x) - f.kind.eval(x)).abs() < 2e-4, "{:?} at {x}", f.kind);
            }
        }
    }

    #[test]
    fn within_one_holds_for_every_lookup() {
        let kinds = [
            FilterKind::Box,
            FilterKind::Tent { radius: 1.5 },
            FilterKind::Gaussian { stddev: 0.5, radius: 2.0 },
            FilterKind::Gaussian { stddev: 0.3, radius: 1.2 },
            FilterKind::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 },
            FilterKind::Mitchell { b: 0.0, c: 0.5 },
            FilterKind::Lanczos { lobes: 3 },
        ];
        let mut known = 0;
        for k in kinds {
            let f = Filter::new(k);
            if !f.within_one() {
                continue;
            }
            known += 1;
            let r = f.radius();
            for i in 0..200_000 {
                let x = -r - 0.5 + (2.0 * r + 1.0) * i as f32 / 199_999.0;
                for x in [x, f32::from_bits(x.to_bits() + 1), f32::from_bits(x.to_bits().saturating_sub(1))] {
                    assert!(f.eval(x).abs() <= 1.0, "{k:?} at {x}: {}", f.eval(x));
                }
            }
        }
        // The box, the Gaussians and Mitchell's (B, C) = (⅓, ⅓) at least.
        assert!(known >= 4, "{known}");
    }

    /// ∫ w(x) dx by the midpoint rule over [−radius, radius].
    fn integral(f: impl Fn(f32) -> f32, radius: f32) -> f64 {
        let n = 200_000;
        let h = 2.0 * radius as f64 / n as f64;
        (0..n).map(|i| f((-radius as f64 + (i as f64 + 0.5) * h) as f32) as f64 * h).sum()
    }

    #[test]
    fn cubic_and_lanczos_filters_match_their_closed_forms() {
        // Mitchell–Netravali cubics integrate to 1 for every B, C (they
        // reproduce constants); w(0) = (6 − 2B)/6, w(1) = B/6, w(2) = 0.
        for (b, c) in [(1.0 / 3.0, 1.0 / 3.0), (0.0, 0.5), (1.0, 0.0), (0.2, 0.7)] {
            let k = FilterKind::Mitchell { b, c };
            assert!((integral(|x| k.eval(x), 2.0) - 1.0).abs() < 1e-5, "B {b} C {c}");
            assert!((k.eval(0.0) - (6.0 - 2.0 * b) / 6.0).abs() < 1e-6);
            assert!((k.eval(1.0) - b / 6.0).abs() < 1e-6 && (k.eval(-1.0) - b / 6.0).abs() < 1e-6);
            assert!(k.eval(2.0).abs() < 1e-6 && k.eval(2.5) == 0.0);
            // The table agrees with the exact filter.
            let f = Filter::new(k);
            for i in 0..1000 {
                let x = -2.5 + 5.0 * i as f32 / 999.0;
                assert!((f.eval(x) - k.eval(x)).abs() < 2e-4, "{k:?} at {x}");
            }
        }
        // Catmull–Rom interpolates: 1 at 0, 0 at the other integers; its lobe
        // between 1 and 2 is negative: w(1.5) = −1/16.
        let cr = Filter::catmull_rom().kind;
        assert!((cr.eval(1.5) + 0.0625).abs() < 1e-6, "{}", cr.eval(1.5));
        // Lanczos: w(0) = 1, zero at every non-zero integer, negative on (1, 2),
        // and the sinc product at x = ½.
        for lobes in 1..=4u32 {
            let k = FilterKind::Lanczos { lobes };
            assert_eq!(k.eval(0.0), 1.0);
            for n in 1..=lobes {
                assert!(k.eval(n as f32).abs() < 1e-6, "lobes {lobes} at {n}");
            }
            let a = lobes as f32;
            let x = 0.5f32;
            let expect = (std::f32::consts::PI * x).sin() * (std::f32::consts::PI * x / a).sin()
                / (std::f32::consts::PI * x * std::f32::consts::PI * x / a);
            assert!((k.eval(x) - expect).abs() < 1e-6);
            assert_eq!(k.eval(a + 0.01), 0.0);
            let f = Filter::new(k);
            assert_eq!(f.radius(), a);
            for i in 0..1000 {
                let x = -(a + 0.5) + (2.0 * a + 1.0) * i as f32 / 999.0;
                assert!((f.eval(x) - k.eval(x)).abs() < 5e-4, "{k:?} at {x}");
            }
        }
        assert!(FilterKind::Lanczos { lobes: 3 }.eval(1.5) < 0.0);
    }

    #[test]
    fn filters_vanish_at_their_radius() {
        for f in [Filter::new(FilterKind::Tent { radius: 1.5 }), Filter::gaussian(0.5)] {
            assert!(f.eval(0.0) > 0.0);
            assert_eq!(f.eval(f.radius()), 0.0);
            assert_eq!(f.eval(-f.radius() - 0.1), 0.0);
            assert!((f.eval(0.3) - f.eval(-0.3)).abs() < 1e-7);
        }
        let b = Filter::new(FilterKind::Box);
        assert_eq!(b.eval(0.49), 1.0);
        assert_eq!(b.eval(0.5), 0.0);
    }

    #[test]
    fn span_matches_single_values_to_the_bit() {
        let kinds = [
            FilterKind::Box,
            FilterKind::Tent { radius: 1.5 },
            FilterKind::Gaussian { stddev: 0.5, radius: 2.0 },
            FilterKind::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 },
            FilterKind::Lanczos { lobes: 4 },
        ];
        let mut state = 99u32;
        for k in kinds {
            let f = Filter::new(k);
            for _ in 0..20_000 {
                state = state.wrapping_mul(747796405).wrapping_add(2891336453);
                let pos = (state >> 8) as f32 / (1u32 << 24) as f32 * 300.0 - 20.0;
                let n = 1 + (state % 9) as usize;
                let first = (pos - 0.5 - f.radius()).ceil() as i32 - (state >> 29) as i32;
                let mut out = [f32::NAN; 9];
                f.eval_span(first, pos, &mut out[..n]);
                for (i, &w) in out[..n].iter().enumerate() {
                    let want = f.eval((first + i as i32) as f32 + 0.5 - pos);
                    assert_eq!(w.to_bits(), want.to_bits(), "{k:?} pos {pos} pixel {}", first + i as i32);
                }
                assert!(out[n..].iter().all(|w| w.is_nan()));
            }
        }
    }

    /// The AVX2 evaluation of four x and four y values gives `eval_span`'s
    /// bits, for positions anywhere around their pixels (and NaN).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_spans_match_eval_span_to_the_bit() {
        if !is_x86_feature_detected!("avx2") {
            return;
        }
        let kinds = [
            FilterKind::Box,
            FilterKind::Tent { radius: 1.0 },
            FilterKind::Gaussian { stddev: 0.5, radius: 2.0 },
            FilterKind::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 },
        ];
        let mut state = 7u32;
        let mut next = || {
            state = state.wrapping_mul(747796405).wrapping_add(2891336453);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        for k in kinds {
            let f = Filter::new(k);
            for n in 0..20_000 {
                let mut pos = glam::Vec2::new(next() * 300.0 - 20.0, next() * 300.0 - 20.0);
                if n % 97 == 0 {
                    pos.y = f32::NAN;
                } else if n % 7 == 0 {
                    pos.x = pos.x.floor() + 0.5 + f.radius();
                }
                let x0 = (pos.x - 0.5 - f.radius()).ceil() as i32 - (next() * 2.0) as i32;
                let y0 = (pos.y - 0.5 - f.radius()).ceil() as i32 + (next() * 2.0) as i32;
                let mut got = [0.0f32; 8];
                // SAFETY: the CPU has AVX2 (checked above).
                unsafe { std::arch::x86_64::_mm256_storeu_ps(got.as_mut_ptr(), f.eval_spans4_avx2(x0, y0, pos)) };
                let (mut wx, mut wy) = ([0.0f32; 4], [0.0f32; 4]);
                f.eval_span(x0, pos.x, &mut wx);
                f.eval_span(y0, pos.y, &mut wy);
                for (i, (&g, &w)) in got.iter().zip(wx.iter().chain(&wy)).enumerate() {
                    assert_eq!(g.to_bits(), w.to_bits(), "{k:?} pos {pos} lane {i}");
                }
            }
        }
    }
}

//! Camera samples added to a [`Sink`] in batches ([`Sink::add_samples`]):
//! the wavefront path tracer's way into the film, once per batch of paths.
//!
//! The batch is dispatched once to code compiled for the CPU's level
//! ([`SimdLevel`], `SNELL_SIMD`), which takes each sample whose footprint
//! is at most 4 × 4 pixels (filters of radius ≤ 2 within ±1: the box,
//! tents, the default Gaussian, Mitchell's) and whose values are narrow
//! through vectors:
//!
//! - the footprint's four bounds in one SSE vector (`ceil` / `floor`,
//!   clamped to the sink);
//! - the three values and the weight's 1 in fixed point in one AVX2 vector
//!   (`f64`, rounded as [`fixed_value`]);
//! - the eight filter values (x and y) in one vector
//!   ([`Filter::eval_spans4_avx2`]), and the 16 weights
//!   trunc(wx · (wy · 2^20)) as their outer product, one multiply and one
//!   truncation a pixel, as [`add_narrow_rows`];
//! - a pixel's four sums w · (R, G, B, 2^32) added as one AVX2 vector, or
//!   with AVX-512 two pixels at a time by a 64-bit multiply.
//!
//! The same integers as [`Sink::add_sample`]'s; any other sample (wide
//! values, NaN, larger footprints) goes through it.

use super::*;
#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

impl Sink {
    /// Adds the camera samples `samples` (film position in pixels, colour)
    /// as [`Sink::add_sample`] does each with no Stokes components nor
    /// further channels: the same integers in every sum.
    pub fn add_samples(&mut self, filter: &Filter, samples: impl IntoIterator<Item = (Vec2, Rgb)>) {
        let samples = samples.into_iter();
        // Radius ≤ 2: footprints of at most 5 pixels a side, 5 only where a
        // pixel centre lies exactly at the radius (taken one by one).
        #[cfg(target_arch = "x86_64")]
        if !self.narrow.is_empty() && filter.within_one() && filter.radius() <= 2.0 {
            match self.level {
                // SAFETY: the level is one the CPU runs.
                SimdLevel::Avx512 => return unsafe { add_samples_avx512(self, filter, samples) },
                SimdLevel::Avx2 => return unsafe { add_samples_avx2(self, filter, samples) },
                SimdLevel::Baseline => {}
            }
        }
        for (pos, rgb) in samples {
            self.add_sample(filter, pos, rgb, None, &[]);
        }
    }

    /// [`Sink::add_sample`] for a sample the vector code leaves (not
    /// inlined there: rare, and large).
    #[inline(never)]
    fn add_one(&mut self, filter: &Filter, pos: Vec2, rgb: Rgb) {
        self.add_sample(filter, pos, rgb, None, &[]);
    }
}

/// # Safety
/// The CPU must have AVX2; the sink narrow sums, the filter within ±1 and
/// of radius ≤ 2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn add_samples_avx2(sink: &mut Sink, filter: &Filter, samples: impl Iterator<Item = (Vec2, Rgb)>) {
    // SAFETY: as this function's.
    unsafe { add_samples_body::<false>(sink, filter, samples) }
}

/// # Safety
/// As [`add_samples_avx2`], and the CPU must have AVX-512 F/VL/DQ.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx2")]
unsafe fn add_samples_avx512(sink: &mut Sink, filter: &Filter, samples: impl Iterator<Item = (Vec2, Rgb)>) {
    // SAFETY: as this function's.
    unsafe { add_samples_body::<true>(sink, filter, samples) }
}

/// The body of [`Sink::add_samples`]'s vector paths, inlined into a
/// function with AVX2's features (and AVX-512's where `AVX512`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn add_samples_body<const AVX512: bool>(sink: &mut Sink, filter: &Filter, samples: impl Iterator<Item = (Vec2, Rgb)>) {
    let r = filter.radius();
    let (sx0, sy0, width) = (sink.x0, sink.y0, sink.width);
    // SAFETY (all intrinsics): the caller's features include AVX2 (and
    // AVX-512 F/VL/DQ where `AVX512`).
    unsafe {
        let low = _mm_setr_epi32(sx0, sy0, i32::MIN, i32::MIN);
        let high = _mm_setr_epi32(i32::MAX, i32::MAX, sx0 + sink.width as i32 - 1, sy0 + sink.height as i32 - 1);
        let reach = _mm_setr_ps(-r, -r, r, r);
        for (pos, rgb) in samples {
            // The footprint as `add_sample` finds it: pixels ceil(p − ½ − r)
            // to floor(p − ½ + r) (p − ½ − r is p − ½ + (−r) to the bit),
            // clamped to the sink; within ±2^30 the conversions are exact,
            // the rest (huge or NaN positions) is left to `add_sample`.
            let e = _mm_add_ps(_mm_sub_ps(_mm_setr_ps(pos.x, pos.y, pos.x, pos.y), _mm_set1_ps(0.5)), reach);
            let abs = _mm_and_ps(e, _mm_castsi128_ps(_mm_set1_epi32(0x7fff_ffff)));
            if _mm_movemask_ps(_mm_cmplt_ps(abs, _mm_set1_ps((1u32 << 30) as f32))) != 0b1111 {
                sink.add_one(filter, pos, rgb);
                continue;
            }
            let bounds = _mm_cvttps_epi32(_mm_blend_ps::<0b1100>(_mm_ceil_ps(e), _mm_floor_ps(e)));
            let bounds = _mm_min_epi32(_mm_max_epi32(bounds, low), high);
            let n = _mm_sub_epi32(_mm_shuffle_epi32::<0b1110>(bounds), bounds);
            let (x0, y0) = (_mm_cvtsi128_si32(bounds), _mm_extract_epi32::<1>(bounds));
            // The footprint's size less one: negative where it is empty.
            let (mx, my) = (_mm_cvtsi128_si32(n), _mm_extract_epi32::<1>(n));
            if mx < 0 || my < 0 {
                continue;
            }
            if mx > 3 || my > 3 {
                sink.add_one(filter, pos, rgb);
                continue;
            }
            let (nx, ny) = (mx as usize + 1, my as usize + 1);

            // The values R, G, B and the weight's 1 as `fixed_value` rounds
            // them: t = v · 2^32 + ½·sign, truncated. Narrow where every
            // |t| < 2^36 (NaN is not: `add_sample` takes it).
            let scaled = _mm256_mul_pd(_mm256_cvtps_pd(_mm_setr_ps(rgb[0], rgb[1], rgb[2], 1.0)), _mm256_set1_pd(VALUE_SCALE));
            let sign = _mm256_and_pd(scaled, _mm256_set1_pd(-0.0));
            let t = _mm256_add_pd(scaled, _mm256_or_pd(sign, _mm256_set1_pd(0.5)));
            let abs_t = _mm256_andnot_pd(_mm256_set1_pd(-0.0), t);
            if _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(abs_t, _mm256_set1_pd(NARROW_LIMIT as f64))) != 0b1111 {
                sink.add_one(filter, pos, rgb);
                continue;
            }
            let whole = _mm256_round_pd::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(t);
            // Integers below 2^51 in magnitude, to i64 exactly: added to
            // 1.5 · 2^52 they sit in the mantissa.
            let magic = _mm256_set1_pd(6755399441055744.0);
            let v = _mm256_sub_epi64(_mm256_castpd_si256(_mm256_add_pd(whole, magic)), _mm256_castpd_si256(magic));
            // The largest |value| (the weight's 2^32 among them), which
            // `add_sample` bounds the sample's terms by.
            let m = _mm256_max_pd(abs_t, _mm256_permute2f128_pd::<1>(abs_t, abs_t));
            let m = _mm_max_sd(_mm256_castpd256_pd128(m), _mm_unpackhi_pd(_mm256_castpd256_pd128(m), _mm256_castpd256_pd128(m)));
            // Below 2^36 (checked above): the conversion truncates as `as`.
            let peak = _mm_cvtsd_f64(m).to_int_unchecked::<i64>() as u64;
            let bound = peak << WEIGHT_BITS;
            if sink.load > i64::MAX as u64 - bound {
                sink.flush_narrow();
            }
            sink.load += bound;

            // The weights trunc(wx[i] · (wy[j] · 2^20)), rows 0–1 and 2–3.
            let w = filter.eval_spans4_avx2(x0, y0, pos);
            let wx = _mm256_permute2f128_ps::<0x00>(w, w);
            let wy = _mm256_mul_ps(w, _mm256_set1_ps(WEIGHT_SCALE));
            let w01 = _mm256_cvttps_epi32(_mm256_mul_ps(wx, _mm256_permutevar8x32_ps(wy, _mm256_setr_epi32(4, 4, 4, 4, 5, 5, 5, 5))));
            let w23 = _mm256_cvttps_epi32(_mm256_mul_ps(wx, _mm256_permutevar8x32_ps(wy, _mm256_setr_epi32(6, 6, 6, 6, 7, 7, 7, 7))));

            let first = (y0 - sy0) as usize * width + (x0 - sx0) as usize;
            let cells = sink.narrow[first..first + (ny - 1) * width + nx].as_mut_ptr();
            if AVX512 && nx == 4 && ny == 4 {
                // Two pixels a vector: weights sign-extended to 64 bits,
                // each pair's spread over its pixels' four lanes.
                let v2 = _mm512_broadcast_i64x4(v);
                let rows = [_mm512_cvtepi32_epi64(w01), _mm512_cvtepi32_epi64(w23)];
                let pairs = [
                    _mm512_setr_epi64(0, 0, 0, 0, 1, 1, 1, 1),
                    _mm512_setr_epi64(2, 2, 2, 2, 3, 3, 3, 3),
                    _mm512_setr_epi64(4, 4, 4, 4, 5, 5, 5, 5),
                    _mm512_setr_epi64(6, 6, 6, 6, 7, 7, 7, 7),
                ];
                for j in 0..4 {
                    for k in 0..2 {
                        let wk = _mm512_permutexvar_epi64(pairs[2 * (j % 2) + k], rows[j / 2]);
                        // SAFETY: pixels 2k and 2k + 1 of row j < ny, in
                        // `cells`; unaligned loads and stores.
                        let p = cells.add(j * width + 2 * k) as *mut __m512i;
                        _mm512_storeu_si512(p, _mm512_add_epi64(_mm512_loadu_si512(p), _mm512_mullo_epi64(wk, v2)));
                    }
                }
            } else {
                // A pixel a vector. No 64-bit multiply in AVX2: v = hi · 2^32
                // + lo with lo = v's low half as a signed 32-bit integer
                // (what `_mm256_mul_epi32` reads of v), hi = v's high half
                // plus one where lo < 0 (|v| < 2^36), and w · v = w · lo +
                // (w · hi) · 2^32, as `add_narrow_rows_avx2`.
                let hi = _mm256_sub_epi32(_mm256_srli_epi64::<32>(v), _mm256_srai_epi32::<31>(v));
                let mut ws = [0i32; 16];
                _mm256_storeu_si256(ws.as_mut_ptr() as *mut __m256i, w01);
                _mm256_storeu_si256(ws.as_mut_ptr().add(8) as *mut __m256i, w23);
                // SAFETY: pixel i < nx of row j < ny, in `cells`.
                let add = |j: usize, i: usize| {
                    let wb = _mm256_set1_epi32(ws[4 * j + i]);
                    let term = _mm256_add_epi64(_mm256_mul_epi32(wb, v), _mm256_slli_epi64::<32>(_mm256_mul_epi32(wb, hi)));
                    let p = cells.add(j * width + i) as *mut __m256i;
                    _mm256_storeu_si256(p, _mm256_add_epi64(_mm256_loadu_si256(p), term));
                };
                if nx == 4 {
                    // The common footprint, its rows unrolled.
                    for j in 0..ny {
                        for i in 0..4 {
                            add(j, i);
                        }
                    }
                } else {
                    for j in 0..ny {
                        for i in 0..nx {
                            add(j, i);
                        }
                    }
                }
            }
        }
    }
}

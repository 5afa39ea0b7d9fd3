//! The exact film accumulator: what a render of a range of samples leaves
//! behind ([`FilmState`]), the sink that integrators write into ([`Sink`]),
//! and its (de)serialisation for checkpoints and distributed rendering.
//!
//! # Why fixed point
//!
//! A pixel is Σ w·L / Σ w over the samples that reach it (w the
//! reconstruction filter's weight), plus, for light tracing, Σ splats / N.
//! Floating-point sums depend on the order of their terms, so an image
//! rendered in passes, or on several threads, or merged from several
//! machines, would differ in its last bits from the one-piece render. Here
//! every term is rounded once, on its own, to a fixed-point integer, and
//! the sums are integer sums: associative and commutative, so the image is
//! bit-identical whatever the thread count, the split of the sample range
//! into passes, or the order in which [`FilmState::merge`] adds ranges.
//!
//! # Range and precision
//!
//! Each accumulator is an `i128` counting units of 2^−[`FRACTION_BITS`]
//! (2^−52). A sample's values are rounded once to multiples of 2^−32
//! (≈ 2.3·10^−10, far below an `f32` pixel's precision for any value above
//! 10^−3, and unbiased: rounded to nearest), clamped to ±2^31 ≈ ±2.1·10^9 (a
//! sample brighter than that is a firefly no image can show); each filter
//! weight is truncated to a multiple of 2^−20 (≈ 10^−6, the same weight in
//! a pixel's sum and in its sum of weights, so the pixel stays a weighted
//! mean). A term w·v is then an exact integer product, below 2^20 · 2^63 =
//! 2^83 units. A pixel receives terms from at most the 9 × 9 pixels of the
//! widest filter footprint, each with at most 2^32 samples (sample indices
//! are `u32`), so camera sums stay below 2^83 · 81 · 2^32 < 2^122 and cannot
//! overflow. Splats (light tracing: any number per path) and merges add with
//! saturation instead. NaN values count as zero (the render loop zeroes and
//! counts them before). In a [`Sink`], the colour and weight sums of
//! samples below 16 (in film units) go to `i64` sums first. Their terms are
//! below 2^56, and the sink keeps a bound on every such sum (the sum of the
//! samples' largest terms): before it could pass `i64::MAX`, all of them move
//! into the `i128` ones. So adding needs no overflow check — exact either
//! way, and nearly as cheap as the float sums they replace.

use super::{Channel, Filter, Image, Layer, PixelFormat};
use crate::geometry::accel::SimdLevel;
use crate::math::rounding::{ceil_i32, floor_i32};
use crate::spectrum::Rgb;
use glam::Vec2;
use serde::{Deserialize, Serialize};
use std::ops::Range;

mod batch;

/// Fractional bits of the fixed-point accumulators: those of a value plus
/// those of a weight.
pub const FRACTION_BITS: u32 = VALUE_BITS + WEIGHT_BITS;
/// Fractional bits of a sample's values, and of a filter weight.
pub const VALUE_BITS: u32 = 32;
pub const WEIGHT_BITS: u32 = 20;
const VALUE_SCALE: f64 = (1u64 << VALUE_BITS) as f64;
const WEIGHT_SCALE: f32 = (1u32 << WEIGHT_BITS) as f32;
const SCALE: f64 = (1u64 << FRACTION_BITS) as f64;

/// A sample's value in units of 2^−32: rounded to nearest, saturated to
/// the `i64` range (±2^31 in film units), NaN as zero.
#[inline(always)]
pub fn fixed_value(v: f32) -> i64 {
    let x = v as f64 * VALUE_SCALE;
    (x + 0.5f64.copysign(x)) as i64
}

/// A filter weight in units of 2^−20: truncated, within ±1.
#[inline(always)]
pub fn fixed_weight(w: f32) -> i64 {
    ((w * WEIGHT_SCALE) as i32).clamp(-(1 << WEIGHT_BITS), 1 << WEIGHT_BITS) as i64
}

/// The exact term `w`·`v` of fixed-point weight and value, in units of 2^−52.
#[inline(always)]
pub fn term(w: i64, v: i64) -> i128 {
    w as i128 * v as i128
}

/// A fixed-point sum back in film units.
#[inline]
pub fn unfixed(v: i128) -> f64 {
    wide_to_f64(v) / SCALE
}

/// `v as f64`, through the CPU's 64-bit conversion where `v` fits in an
/// `i64` (nearly always: sums of values below 2^11 over 2^20 weights),
/// instead of the library's 128-bit one. Both round the same integer to
/// the nearest `f64` (ties to even), so the result is the same. (The
/// `black_box` keeps the compiler from seeing that, which made it fold
/// both branches back into the 128-bit call.)
#[inline(always)]
fn wide_to_f64(v: i128) -> f64 {
    match i64::try_from(v) {
        Ok(x) => std::hint::black_box(x) as f64,
        Err(_) => v as f64,
    }
}

/// Which sums a film keeps per pixel, in this order: the filtered camera
/// samples (R, G, B and the weight), light-tracing splats (R, G, B), the
/// Stokes components S1–S3 of a polarized render (R, G, B each, filtered
/// with the camera samples' weights), then further scalar channels (alpha,
/// AOVs, moments) filtered likewise.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Layout {
    pub camera: bool,
    pub splats: bool,
    pub stokes: bool,
    pub extra: Vec<String>,
}

impl Layout {
    /// Accumulators per pixel.
    pub fn stride(&self) -> usize {
        4 * self.camera as usize + 3 * self.splats as usize + 9 * self.stokes as usize + self.extra.len()
    }
    fn splat_offset(&self) -> usize {
        4 * self.camera as usize
    }
    fn stokes_offset(&self) -> usize {
        self.splat_offset() + 3 * self.splats as usize
    }
    fn extra_offset(&self) -> usize {
        self.stokes_offset() + 9 * self.stokes as usize
    }
}

/// Widest filter footprint in pixels (radius ≤ 4).
const MAX_FOOTPRINT: usize = 9;
/// Further channels whose values are rounded once per sample (more are
/// rounded per pixel: the same values, more slowly).
const MAX_EXTRA: usize = 32;

/// A rectangle of the film (a tile with a border of the filter's radius, or
/// the whole crop window with one) that one worker adds samples and splats
/// to; [`FilmState::add_sink`] adds it to the film.
pub struct Sink {
    x0: i32,
    y0: i32,
    width: usize,
    height: usize,
    stride: usize,
    splat_offset: usize,
    stokes_offset: usize,
    extra_offset: usize,
    n_extra: usize,
    /// The sums, in fixed point: the wide accumulators. Made (zeroed) when
    /// first written to ([`Sink::wide`]): a sink whose samples all stay
    /// narrow never needs them, nor the time to clear and add them.
    data: Vec<i128>,
    /// Colour and weight sums of camera samples in `i64` (cheaper to add
    /// to), moved into `data` before they could overflow (see `load`).
    narrow: Vec<[i64; 4]>,
    /// A bound on |every narrow sum| since they were last moved: the sum
    /// over the narrow samples of their largest possible term (a sample adds
    /// at most one term to each sum). While it stays within `i64::MAX` no
    /// narrow sum can overflow, so adding to them needs no checks.
    load: u64,
    /// The instruction set the narrow sums are added with (the CPU's best,
    /// or less as `SNELL_SIMD` says): the same integers at every level.
    level: SimdLevel,
}

/// Calls `add` with each pixel's sums of a narrow camera sample's footprint
/// in the narrow sums `narrow` of a sink `width` pixels wide, and the pixel's
/// fixed-point weight w = trunc(`wx`[i] · `wy`[j] · 2^20): row j starts at
/// pixel `first` + j · `width`. Only for samples [`Sink::add_sample`] found
/// narrow: weights within ±1, values below `NARROW_LIMIT`, the sink's `load`
/// raised by the sample's bound, so no sum can overflow (every |sum| ≤
/// `load` ≤ i64::MAX).
#[inline(always)]
fn for_each_narrow_pixel(narrow: &mut [[i64; 4]], width: usize, first: usize, wx: &[f32], wy: &[f32], mut add: impl FnMut(&mut [i64; 4], i64)) {
    for (j, &wyj) in wy.iter().enumerate() {
        if wyj == 0.0 {
            continue;
        }
        let row = first + j * width;
        let Some(dst) = narrow.get_mut(row..row + wx.len()) else { continue };
        // wx·(wy·2^20) is (wx·wy)·2^20 to the bit: scaling by a power of two
        // is exact, and where wx·wy would be subnormal both are below 1 and
        // truncate to 0.
        let wy_scaled = wyj * WEIGHT_SCALE;
        for (n, &wxi) in dst.iter_mut().zip(wx) {
            add(n, narrow_weight(wxi, wy_scaled) as i64);
        }
    }
}

/// Adds a narrow camera sample's terms to the narrow sums: each pixel of the
/// footprint ([`for_each_narrow_pixel`]) gains w · `rgb` (fixed point) and
/// the weight's w · 2^32.
#[inline(always)]
fn add_narrow_rows(narrow: &mut [[i64; 4]], width: usize, first: usize, wx: &[f32], wy: &[f32], rgb: [i64; 3]) {
    for_each_narrow_pixel(narrow, width, first, wx, wy, |n, w| {
        n[0] += w * rgb[0];
        n[1] += w * rgb[1];
        n[2] += w * rgb[2];
        n[3] += w << VALUE_BITS;
    });
}

/// A pixel's fixed-point weight trunc(`wx` · `wy_scaled`), both weights
/// within ±1 (`wy_scaled` times 2^20).
#[inline(always)]
fn narrow_weight(wx: f32, wy_scaled: f32) -> i32 {
    // SAFETY: both weights are within ±1 (`within_one` or `in_range` in
    // `add_sample`), so the product is within ±2^20, finite and
    // representable: the unchecked conversion truncates as `as` would.
    unsafe { (wx * wy_scaled).to_int_unchecked::<i32>() }
}

/// [`add_narrow_rows`] with a pixel's four sums (R, G, B, weight) added as
/// one AVX2 vector. AVX2 has no 64-bit multiply, so each value v is split
/// into v = hi · 2^32 + lo with lo, hi signed 32-bit (|v| < 2^36 here), and
/// w · v = w · lo + (w · hi) · 2^32, two 32 × 32 → 64-bit products: the
/// same integers as the plain code's.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn add_narrow_rows_avx2(narrow: &mut [[i64; 4]], width: usize, first: usize, wx: &[f32], wy: &[f32], rgb: [i64; 3]) {
    use std::arch::x86_64::*;
    let split = |v: i64| {
        let lo = v as i32 as i64;
        (lo, (v - lo) >> 32)
    };
    let [(r0, r1), (g0, g1), (b0, b1)] = rgb.map(split);
    // The weight's value 2^32: lo 0, hi 1.
    let lo = _mm256_set_epi64x(0, b0, g0, r0);
    let hi = _mm256_set_epi64x(1, b1, g1, r1);
    for_each_narrow_pixel(narrow, width, first, wx, wy, |n, w| {
        let w = _mm256_set1_epi64x(w);
        let t = _mm256_add_epi64(_mm256_mul_epi32(w, lo), _mm256_slli_epi64::<32>(_mm256_mul_epi32(w, hi)));
        let p = n.as_mut_ptr() as *mut __m256i;
        // SAFETY: `p` points to the pixel's four i64 sums (32 bytes);
        // unaligned loads and stores.
        unsafe { _mm256_storeu_si256(p, _mm256_add_epi64(_mm256_loadu_si256(p), t)) };
    });
}

/// Samples whose largest fixed-point value (colour, and the weight's 1) is
/// below this (16 in film units) go to the narrow sums: a term then stays
/// below 2^20 · 2^36 = 2^56, so at least 2^7 such samples (2^11 of values
/// below 1) fit the `i64` sums between two moves into the wide ones.
const NARROW_LIMIT: u64 = 1 << 36;

impl Sink {
    /// A sink of `width` × `height` pixels whose top-left pixel is (`x0`,
    /// `y0`) in crop-window coordinates, keeping the sums `layout` names.
    pub fn new(layout: &Layout, x0: i32, y0: i32, width: usize, height: usize) -> Sink {
        let stride = layout.stride();
        Sink {
            x0,
            y0,
            width,
            height,
            stride,
            splat_offset: layout.splat_offset(),
            stokes_offset: layout.stokes_offset(),
            extra_offset: layout.extra_offset(),
            n_extra: layout.extra.len(),
            data: vec![],
            narrow: if layout.camera { vec![[0; 4]; width * height] } else { vec![] },
            load: 0,
            level: SimdLevel::current(),
        }
    }

    /// The wide sums, made (zeroed) on first use.
    #[inline]
    fn wide(&mut self) -> &mut Vec<i128> {
        if self.data.is_empty() {
            self.data = vec![0; self.width * self.height * self.stride];
        }
        &mut self.data
    }

    /// Moves the narrow sums into the wide ones.
    fn flush_narrow(&mut self) {
        let stride = self.stride;
        self.wide();
        for (px, n) in self.data.chunks_exact_mut(stride).zip(self.narrow.iter_mut()) {
            for k in 0..4 {
                px[k] += n[k] as i128;
            }
            *n = [0; 4];
        }
        self.load = 0;
    }

    /// Adds a camera sample taken at continuous film position `pos` (pixels,
    /// crop-window coordinates) with colour `rgb`, the Stokes components
    /// `s123` (polarized renders) and further channels `extra` (as many as
    /// the layout names), each weighted by the filter; the weights are
    /// summed too. Only for a layout with `camera`.
    #[inline]
    pub fn add_sample(&mut self, filter: &Filter, pos: Vec2, rgb: Rgb, s123: Option<&[Rgb; 3]>, extra: &[f32]) {
        let r = filter.radius();
        // Pixel i has its centre at i + 0.5; clamp the footprint to the sink.
        let x0 = ceil_i32(pos.x - 0.5 - r).max(self.x0);
        let x1 = floor_i32(pos.x - 0.5 + r).min(self.x0 + self.width as i32 - 1);
        let y0 = ceil_i32(pos.y - 0.5 - r).max(self.y0);
        let y1 = floor_i32(pos.y - 0.5 + r).min(self.y0 + self.height as i32 - 1);
        if x1 < x0 || y1 < y0 {
            return;
        }
        let (nx, ny) = (((x1 - x0 + 1) as usize).min(MAX_FOOTPRINT), ((y1 - y0 + 1) as usize).min(MAX_FOOTPRINT));
        let (mut wx, mut wy) = ([0.0f32; MAX_FOOTPRINT], [0.0f32; MAX_FOOTPRINT]);
        filter.eval_span(x0, pos.x, &mut wx[..nx]);
        filter.eval_span(y0, pos.y, &mut wy[..ny]);
        // Values rounded once per sample; weights once per pixel.
        let v = [fixed_value(rgb[0]), fixed_value(rgb[1]), fixed_value(rgb[2]), 1 << VALUE_BITS];
        let s = s123.map(|s| [0, 1, 2, 3, 4, 5, 6, 7, 8].map(|k| fixed_value(s[k / 3][k % 3])));
        let stride = self.stride;
        let peak = v.iter().map(|q| q.unsigned_abs()).max().unwrap_or(0);
        // Every term of a sample below the limit is below 2^56 (|w| ≤ 2^20);
        // the filter's values are within ±1 (known for the filter or checked
        // here, so a weight needs no clamp: it is the same as `fixed_weight`'s).
        let in_range = |w: &[f32]| w.iter().all(|x| x.abs() <= 1.0);
        let narrow = peak < NARROW_LIMIT && !self.narrow.is_empty() && (filter.within_one() || (in_range(&wx[..nx]) && in_range(&wy[..ny])));
        if narrow {
            let bound = peak << WEIGHT_BITS;
            if self.load > i64::MAX as u64 - bound {
                self.flush_narrow();
            }
            self.load += bound;
            let first = (y0 - self.y0) as usize * self.width + (x0 - self.x0) as usize;
            let rgb = [v[0], v[1], v[2]];
            #[cfg(target_arch = "x86_64")]
            if self.level >= SimdLevel::Avx2 {
                // SAFETY: the level is one the CPU runs.
                unsafe { add_narrow_rows_avx2(&mut self.narrow, self.width, first, &wx[..nx], &wy[..ny], rgb) };
            } else {
                add_narrow_rows(&mut self.narrow, self.width, first, &wx[..nx], &wy[..ny], rgb);
            }
            #[cfg(not(target_arch = "x86_64"))]
            add_narrow_rows(&mut self.narrow, self.width, first, &wx[..nx], &wy[..ny], rgb);
            if s.is_none() {
                return self.add_extra_of(x0, y0, &wx[..nx], &wy[..ny], extra);
            }
        }
        self.wide();
        for j in 0..ny {
            if wy[j] == 0.0 {
                continue;
            }
            let row = ((y0 - self.y0) as usize + j) * self.width + (x0 - self.x0) as usize;
            for i in 0..nx {
                let w = fixed_weight(wx[i] * wy[j]);
                if w == 0 {
                    continue;
                }
                let px = &mut self.data[(row + i) * stride..(row + i + 1) * stride];
                if !narrow {
                    if let Some((c, _)) = px.split_first_chunk_mut::<4>() {
                        for k in 0..4 {
                            c[k] += term(w, v[k]);
                        }
                    }
                }
                if let Some(s) = &s {
                    for (d, &q) in px[self.stokes_offset..self.stokes_offset + 9].iter_mut().zip(s) {
                        *d += term(w, q);
                    }
                }
            }
        }
        self.add_extra_of(x0, y0, &wx[..nx], &wy[..ny], extra);
    }

    /// The further channels `extra` (those the layout names) of a sample
    /// with the footprint and weights of [`Sink::add_sample`].
    #[inline(always)]
    fn add_extra_of(&mut self, x0: i32, y0: i32, wx: &[f32], wy: &[f32], extra: &[f32]) {
        let n_extra = self.n_extra.min(extra.len());
        if n_extra > 0 {
            self.add_extra(x0, y0, wx, wy, &extra[..n_extra]);
        }
    }

    /// The further channels of a sample with the footprint (from pixel
    /// (`x0`, `y0`)) and weights of [`Sink::add_sample`].
    fn add_extra(&mut self, x0: i32, y0: i32, wx: &[f32], wy: &[f32], extra: &[f32]) {
        let mut e = [0i64; MAX_EXTRA];
        let quantized = extra.len() <= MAX_EXTRA;
        for (q, &x) in e.iter_mut().zip(extra) {
            *q = fixed_value(x);
        }
        let (stride, o) = (self.stride, self.extra_offset);
        self.wide();
        for (j, &wyj) in wy.iter().enumerate() {
            let row = ((y0 - self.y0) as usize + j) * self.width + (x0 - self.x0) as usize;
            for (i, &wxi) in wx.iter().enumerate() {
                let w = fixed_weight(wxi * wyj);
                if w == 0 {
                    continue;
                }
                let at = (row + i) * stride + o;
                let dst = &mut self.data[at..at + extra.len()];
                if quantized {
                    for (d, &q) in dst.iter_mut().zip(&e) {
                        *d += term(w, q);
                    }
                } else {
                    for (d, &x) in dst.iter_mut().zip(extra) {
                        *d += term(w, fixed_value(x));
                    }
                }
            }
        }
    }

    /// Adds `value` at film position `pos` (pixels, crop-window
    /// coordinates) to the splat sums, spread over the filter's footprint
    /// with weights that sum to one (so a splat deposits exactly its value;
    /// the part that falls outside the window is lost). Only for a layout
    /// with `splats`.
    pub fn splat(&mut self, filter: &Filter, pos: Vec2, value: Rgb) {
        let SplatFootprint { x0, y0, nx, ny, wx, wy } = SplatFootprint::new(filter, pos);
        let norm = wx[..nx].iter().sum::<f32>() * wy[..ny].iter().sum::<f32>();
        if !(norm > 0.0) {
            return;
        }
        let v = [fixed_value(value[0]), fixed_value(value[1]), fixed_value(value[2])];
        self.wide();
        for j in 0..ny {
            let y = y0 + j as i32 - self.y0;
            if y < 0 || y >= self.height as i32 || wy[j] == 0.0 {
                continue;
            }
            for i in 0..nx {
                let x = x0 + i as i32 - self.x0;
                if x < 0 || x >= self.width as i32 {
                    continue;
                }
                let w = fixed_weight(wx[i] * wy[j] / norm);
                let at = (y as usize * self.width + x as usize) * self.stride + self.splat_offset;
                for (d, &q) in self.data[at..at + 3].iter_mut().zip(&v) {
                    *d = d.saturating_add(term(w, q));
                }
            }
        }
    }
}

impl Sink {
    /// Adds `value` at `pos` (pixels, crop-window coordinates) to the splat
    /// sums as the camera samples there are weighed: pixel p receives
    /// value · f(pos − p) / ∫_window f(x − p) dx, the filter's mass inside
    /// the window being `mass_x[column] · mass_y[row]` ([`window_filter_mass`]).
    /// In expectation a pixel then gets the average that
    /// [`FilmState::develop`] makes of its camera samples (Σ w·L / Σ w),
    /// also at the window's border, where [`Sink::splat`] loses the part of
    /// the footprint outside. Splats outside the window are dropped (no
    /// camera sample lands there). Only for a layout with `splats`.
    pub fn splat_in_window(&mut self, filter: &Filter, pos: Vec2, value: Rgb, mass_x: &[f32], mass_y: &[f32]) {
        if !(pos.x >= 0.0 && pos.x < mass_x.len() as f32 && pos.y >= 0.0 && pos.y < mass_y.len() as f32) {
            return;
        }
        let SplatFootprint { x0, y0, nx, ny, wx, wy } = SplatFootprint::new(filter, pos);
        self.wide();
        // value / mass in fixed point, recomputed only where the mass changes
        // (it is the same for every pixel away from the window's border).
        let (mut last_mass, mut v) = (f32::NAN, [0i64; 3]);
        for j in 0..ny {
            let py = y0 + j as i32;
            let (y, wy) = (py - self.y0, wy[j]);
            if py < 0 || py as usize >= mass_y.len() || y < 0 || y >= self.height as i32 || wy == 0.0 {
                continue;
            }
            for i in 0..nx {
                let px = x0 + i as i32;
                let x = px - self.x0;
                if px < 0 || px as usize >= mass_x.len() || x < 0 || x >= self.width as i32 {
                    continue;
                }
                let mass = mass_x[px as usize] * mass_y[py as usize];
                if !(mass > 0.0) {
                    continue;
                }
                if mass.to_bits() != last_mass.to_bits() {
                    last_mass = mass;
                    v = [fixed_value(value[0] / mass), fixed_value(value[1] / mass), fixed_value(value[2] / mass)];
                }
                let w = fixed_weight(wx[i] * wy);
                let at = (y as usize * self.width + x as usize) * self.stride + self.splat_offset;
                for (d, &q) in self.data[at..at + 3].iter_mut().zip(&v) {
                    *d = d.saturating_add(term(w, q));
                }
            }
        }
    }
}

/// The pixels a splat at `pos` reaches (first `x0`, `y0`; `nx` × `ny` of
/// them, not clipped to any sink) and the filter's value at each column and
/// row, for [`Sink::splat`] and [`Sink::splat_in_window`].
struct SplatFootprint {
    x0: i32,
    y0: i32,
    nx: usize,
    ny: usize,
    wx: [f32; MAX_FOOTPRINT],
    wy: [f32; MAX_FOOTPRINT],
}

impl SplatFootprint {
    fn new(filter: &Filter, pos: Vec2) -> SplatFootprint {
        let r = filter.radius();
        let x0 = (pos.x - 0.5 - r).ceil() as i32;
        let y0 = (pos.y - 0.5 - r).ceil() as i32;
        let nx = (((pos.x - 0.5 + r).floor() as i32 - x0 + 1).max(0) as usize).min(MAX_FOOTPRINT);
        let ny = (((pos.y - 0.5 + r).floor() as i32 - y0 + 1).max(0) as usize).min(MAX_FOOTPRINT);
        let (mut wx, mut wy) = ([0.0f32; MAX_FOOTPRINT], [0.0f32; MAX_FOOTPRINT]);
        for (i, w) in wx[..nx].iter_mut().enumerate() {
            *w = filter.eval((x0 + i as i32) as f32 + 0.5 - pos.x);
        }
        for (j, w) in wy[..ny].iter_mut().enumerate() {
            *w = filter.eval((y0 + j as i32) as f32 + 0.5 - pos.y);
        }
        SplatFootprint { x0, y0, nx, ny, wx, wy }
    }
}

/// ∫ f(x − c) dx over [0, n] for the centre c = i + ½ of each pixel i of a
/// window row (or column) of `n` pixels: the filter's mass inside the
/// window ([`Sink::splat_in_window`]); the same for every pixel farther than
/// the filter's radius from the window's edges. Midpoint rule, 64 steps a
/// pixel.
pub fn window_filter_mass(filter: &Filter, n: u32) -> Vec<f32> {
    let r = filter.radius();
    let steps_per_pixel = 64.0f64;
    (0..n)
        .map(|i| {
            let c = i as f64 + 0.5;
            let (a, b) = ((c - r as f64).max(0.0), (c + r as f64).min(n as f64));
            let k = ((b - a) * steps_per_pixel).ceil().max(1.0) as usize;
            let h = (b - a) / k as f64;
            let sum: f64 = (0..k).map(|j| filter.eval((a + (j as f64 + 0.5) * h - c) as f32) as f64).sum();
            (sum * h) as f32
        })
        .collect()
}

/// The accumulated sums of a render of some sample ranges of every pixel of
/// the crop window: what [`crate::render::render_samples`] returns, what
/// [`FilmState::merge`] adds exactly, and what [`FilmState::develop`] turns
/// into the image. Serialises with [`FilmState::to_bytes`].
#[derive(Clone, Debug, PartialEq)]
pub struct FilmState {
    pub header: StateHeader,
    /// For the state of one tile of the crop window (a distributed render
    /// split over the image): where it lies; its sums cover `tile.window`.
    tile: Option<TileRegion>,
    data: Vec<i128>,
}

/// Where the state of a tile lies: the pixels whose samples it holds, and
/// the pixels whose sums it keeps — the tile grown by the reach of the
/// reconstruction filter (samples near the tile's edge add to the pixels
/// beyond it), clipped to the crop window. Both are (x, y, width, height)
/// in crop-window coordinates. [`FilmState::merge_tiles`] adds the states
/// of tiles that cover the crop window into the state of the whole window,
/// bit for bit the state of one render.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TileRegion {
    pub pixels: [u32; 4],
    pub window: [u32; 4],
}

/// What [`FilmState::to_bytes`] writes as JSON: the header, and the tile
/// of a tile's state (absent for a whole window: such states read and write
/// as before tiles existed).
#[derive(Serialize, Deserialize)]
struct StoredHeader {
    #[serde(flatten)]
    header: StateHeader,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    tile: Option<TileRegion>,
}

/// What a [`FilmState`] holds, beside its sums.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StateHeader {
    /// The full film (the camera's projection) and the crop window rendered:
    /// offset (x, y) and size (width, height).
    pub film_size: [u32; 2],
    pub crop: [u32; 4],
    /// The sampler's seed and samples per pixel of the full render.
    pub seed: u64,
    pub sample_count: u32,
    /// A digest of the scene and the mode: states only merge when it agrees.
    pub fingerprint: u64,
    /// The pixel format the image is developed in (its name).
    pub pixel_format: String,
    pub layout: Layout,
    /// The sample indices rendered for every pixel: disjoint ranges, sorted
    /// and coalesced. Meaningful only when `complete`.
    pub ranges: Vec<Range<u32>>,
    /// Whether every pixel has every sample of `ranges` (false: a render
    /// stopped part-way, whose image is partial).
    pub complete: bool,
    /// Samples (camera samples or light paths) actually taken, and those
    /// whose value was NaN or infinite (counted as zero).
    pub samples_taken: u64,
    pub invalid_samples: u64,
    /// What the camera samples' radiance is multiplied by when developed
    /// (the sensor's constant sample weight: π for an irradiance meter).
    #[serde(default = "unit_scale", skip_serializing_if = "is_unit_scale")]
    pub radiance_scale: f32,
}

fn unit_scale() -> f32 {
    1.0
}

fn is_unit_scale(v: &f32) -> bool {
    *v == 1.0
}

const MAGIC: &[u8; 8] = b"SNELLFS\0";
const VERSION: u32 = 1;

impl FilmState {
    /// An empty state (no samples) of a film with `header` (its ranges empty).
    pub fn empty(mut header: StateHeader) -> FilmState {
        header.ranges.clear();
        header.complete = true;
        header.samples_taken = 0;
        header.invalid_samples = 0;
        let n = header.crop[2] as usize * header.crop[3] as usize * header.layout.stride();
        FilmState { header, tile: None, data: vec![0; n] }
    }

    /// An empty state of the tile `pixels` (x, y, width, height in
    /// crop-window coordinates) of a film with `header`, keeping the sums of
    /// the pixels within `reach` pixels of it (clipped to the crop window).
    /// An error if the tile is empty or leaves the crop window.
    pub fn empty_tile(header: StateHeader, pixels: [u32; 4], reach: u32) -> anyhow::Result<FilmState> {
        let [x, y, w, h] = pixels;
        let [_, _, cw, ch] = header.crop;
        if w == 0 || h == 0 || x as u64 + w as u64 > cw as u64 || y as u64 + h as u64 > ch as u64 {
            anyhow::bail!("the tile {w}×{h} at ({x}, {y}) is not a part of the {cw}×{ch} film");
        }
        let (x0, y0) = (x.saturating_sub(reach), y.saturating_sub(reach));
        let (x1, y1) = ((x + w).saturating_add(reach).min(cw), (y + h).saturating_add(reach).min(ch));
        let window = [x0, y0, x1 - x0, y1 - y0];
        let n = window[2] as usize * window[3] as usize * header.layout.stride();
        let mut state = FilmState { header, tile: Some(TileRegion { pixels, window }), data: vec![0; n] };
        let h = &mut state.header;
        (h.complete, h.samples_taken, h.invalid_samples) = (true, 0, 0);
        h.ranges.clear();
        Ok(state)
    }

    /// The tile this state is of (None: the whole crop window).
    pub fn tile(&self) -> Option<&TileRegion> {
        self.tile.as_ref()
    }

    /// The pixels whose sums the state keeps: (x, y, width, height) in
    /// crop-window coordinates.
    fn extent(&self) -> [u32; 4] {
        self.tile.map_or([0, 0, self.header.crop[2], self.header.crop[3]], |t| t.window)
    }

    /// The pixels whose samples the state holds.
    pub fn pixels(&self) -> [u32; 4] {
        self.tile.map_or([0, 0, self.header.crop[2], self.header.crop[3]], |t| t.pixels)
    }

    pub fn width(&self) -> u32 {
        self.header.crop[2]
    }

    pub fn height(&self) -> u32 {
        self.header.crop[3]
    }

    /// The sample ranges held (every pixel has these samples when complete).
    pub fn ranges(&self) -> &[Range<u32>] {
        &self.header.ranges
    }

    /// Samples per pixel held: the total length of the ranges.
    pub fn spp(&self) -> u32 {
        self.header.ranges.iter().map(|r| r.end - r.start).sum()
    }

    /// The one range `[0, k)` held, if the state holds exactly a prefix of
    /// the samples (what a checkpoint of a pass loop holds); `Some(0..0)`
    /// for an empty state.
    pub fn prefix(&self) -> Option<u32> {
        match self.header.ranges.as_slice() {
            [] => Some(0),
            [r] if r.start == 0 => Some(r.end),
            _ => None,
        }
    }

    /// Whether every sample of the render is held.
    pub fn is_finished(&self) -> bool {
        self.header.complete && self.prefix() == Some(self.header.sample_count)
    }

    /// Records that samples `range` of every pixel were added.
    pub(crate) fn add_range(&mut self, range: Range<u32>) {
        if !range.is_empty() {
            self.header.ranges.push(range);
            self.header.ranges = coalesce(std::mem::take(&mut self.header.ranges));
        }
    }

    /// Adds a sink's sums (the parts inside the crop window).
    pub fn add_sink(&mut self, sink: &Sink) {
        // The sink's pixels, shifted to the state's extent (a tile's window).
        let [ex, ey, ew, eh] = self.extent();
        let (w, h) = (ew as i32, eh as i32);
        let (sx0, sy0) = (sink.x0 - ex as i32, sink.y0 - ey as i32);
        let stride = self.header.layout.stride();
        debug_assert_eq!(stride, sink.stride);
        for sy in 0..sink.height {
            let y = sy0 + sy as i32;
            if y < 0 || y >= h {
                continue;
            }
            let xs = sx0.max(0);
            let xe = (sx0 + sink.width as i32).min(w);
            if xe <= xs {
                continue;
            }
            let dst = &mut self.data[(y as usize * w as usize + xs as usize) * stride..(y as usize * w as usize + xe as usize) * stride];
            // (A sink whose samples all stayed narrow has no wide sums.)
            let s0 = (sy * sink.width + (xs - sx0) as usize) * stride;
            for (d, s) in dst.iter_mut().zip(sink.data.get(s0..).unwrap_or_default()) {
                *d = d.saturating_add(*s);
            }
            if !sink.narrow.is_empty() {
                let n0 = sy * sink.width + (xs - sx0) as usize;
                for (d, n) in dst.chunks_exact_mut(stride).zip(&sink.narrow[n0..]) {
                    for k in 0..4 {
                        d[k] += n[k] as i128;
                    }
                }
            }
        }
    }

    /// Checks that `other` can be merged into this state: the same film,
    /// scene, seed and layout, and disjoint sample ranges.
    pub fn check_compatible(&self, other: &FilmState) -> anyhow::Result<()> {
        let (a, b) = (&self.header, &other.header);
        let differs = |what: &str, x: String, y: String| anyhow::anyhow!("cannot merge film states: {what} differs ({x} vs {y})");
        if a.film_size != b.film_size || a.crop != b.crop {
            return Err(differs("the film or crop window", format!("{:?} {:?}", a.film_size, a.crop), format!("{:?} {:?}", b.film_size, b.crop)));
        }
        if self.tile != other.tile {
            let name = |t: Option<TileRegion>| t.map_or("the whole window".to_string(), |t| format!("tile {:?}", t.pixels));
            return Err(differs("the tile (merge tiles of a window with merge_tiles)", name(self.tile), name(other.tile)));
        }
        if a.seed != b.seed {
            return Err(differs("the seed", a.seed.to_string(), b.seed.to_string()));
        }
        if a.sample_count != b.sample_count {
            return Err(differs("the sample count", a.sample_count.to_string(), b.sample_count.to_string()));
        }
        if a.fingerprint != b.fingerprint || a.layout != b.layout || a.pixel_format != b.pixel_format {
            return Err(differs("the scene or mode", format!("{:016x}", a.fingerprint), format!("{:016x}", b.fingerprint)));
        }
        for r in &a.ranges {
            if let Some(o) = b.ranges.iter().find(|o| o.start < r.end && r.start < o.end) {
                anyhow::bail!("cannot merge film states: both hold samples {}..{}", r.start.max(o.start), r.end.min(o.end));
            }
        }
        Ok(())
    }

    /// Adds the samples of `other` (disjoint sample ranges of the same
    /// render) to this state. Exact: merging states in any order and any
    /// grouping gives the same sums, bit for bit, as rendering their ranges
    /// at once.
    pub fn merge(&mut self, other: &FilmState) -> anyhow::Result<()> {
        self.check_compatible(other)?;
        for (d, s) in self.data.iter_mut().zip(&other.data) {
            *d = d.saturating_add(*s);
        }
        let h = &mut self.header;
        h.ranges.extend(other.header.ranges.iter().cloned());
        h.ranges = coalesce(std::mem::take(&mut h.ranges));
        h.complete &= other.header.complete;
        h.samples_taken += other.header.samples_taken;
        h.invalid_samples += other.header.invalid_samples;
        Ok(())
    }

    /// Adds the states of `tiles` — tiles that together cover the crop
    /// window once, each holding the same sample ranges (disjoint from this
    /// state's) — to this state of the whole window: each tile's sums,
    /// border included, at its place. Exact, as [`FilmState::merge`] is: the
    /// result is bit for bit the state of rendering those ranges in one
    /// piece. An error (and this state unchanged) if a tile is of another
    /// render, the tiles overlap or leave a gap, or their ranges differ.
    pub fn merge_tiles(&mut self, tiles: &[FilmState]) -> anyhow::Result<()> {
        if self.tile.is_some() {
            anyhow::bail!("cannot merge tiles into the state of a tile: merge them into the state of the whole window");
        }
        let Some(first) = tiles.first() else { anyhow::bail!("cannot merge tiles: none given") };
        let [_, _, w, h] = self.header.crop;
        let mut area = 0u64;
        for (k, t) in tiles.iter().enumerate() {
            let Some(region) = t.tile else { anyhow::bail!("cannot merge tiles: state {k} is of the whole window, not a tile") };
            let mut whole = t.clone_header_only();
            whole.tile = None;
            self.check_compatible(&whole)?;
            if t.header.ranges != first.header.ranges || !t.header.complete {
                anyhow::bail!("cannot merge tiles: tile {:?} holds samples {:?}, tile {:?} {:?} (each tile must hold the same complete ranges)", region.pixels, t.header.ranges, first.pixels(), first.header.ranges);
            }
            let [x, y, tw, th] = region.pixels;
            area += tw as u64 * th as u64;
            for o in &tiles[..k] {
                let [ox, oy, ow, oh] = o.pixels();
                if x < ox + ow && ox < x + tw && y < oy + oh && oy < y + th {
                    anyhow::bail!("cannot merge tiles: tiles {:?} and {:?} overlap", region.pixels, o.pixels());
                }
            }
        }
        if area != w as u64 * h as u64 {
            anyhow::bail!("cannot merge tiles: they cover {area} of the {w}×{h} window's {} pixels", w as u64 * h as u64);
        }
        let stride = self.header.layout.stride();
        for t in tiles {
            let [x0, y0, tw, th] = t.extent();
            for row in 0..th as usize {
                let at = ((y0 as usize + row) * w as usize + x0 as usize) * stride;
                let src = &t.data[row * tw as usize * stride..(row + 1) * tw as usize * stride];
                for (d, s) in self.data[at..at + src.len()].iter_mut().zip(src) {
                    *d = d.saturating_add(*s);
                }
            }
            self.header.samples_taken += t.header.samples_taken;
            self.header.invalid_samples += t.header.invalid_samples;
        }
        let h = &mut self.header;
        h.ranges.extend(first.header.ranges.iter().cloned());
        h.ranges = coalesce(std::mem::take(&mut h.ranges));
        Ok(())
    }

    /// An empty copy of the state (its header and tile, no sums): what
    /// [`FilmState::check_compatible`] looks at.
    fn clone_header_only(&self) -> FilmState {
        FilmState { header: self.header.clone(), tile: self.tile, data: vec![] }
    }

    /// The image: Σ w·L / Σ w per pixel for camera samples (black where no
    /// weight landed or the quotient is not finite) plus Σ splats / (light
    /// paths traced), with the Stokes layers and scalar channels.
    pub fn develop(&self) -> Image {
        let h = &self.header;
        let layout = &h.layout;
        // A tile's state develops its window (the border pixels partial).
        let [_, _, w, ht] = self.extent();
        let stride = layout.stride();
        let pixels_n = w as usize * ht as usize;
        let px = |i: usize| &self.data[i * stride..(i + 1) * stride];
        // unfixed(weight) > 1e-9, without a second conversion and division:
        // dividing by 2^52 is exact, so it is the same test.
        let least = 1e-9 * SCALE;
        let scale = h.radiance_scale as f64;
        let normalize = |sum: &[i128], weight: i128| {
            let wf = wide_to_f64(weight);
            let v = Rgb::new((wide_to_f64(sum[0]) / wf * scale) as f32, (wide_to_f64(sum[1]) / wf * scale) as f32, (wide_to_f64(sum[2]) / wf * scale) as f32);
            if wf > least && v.is_finite() { v } else { Rgb::BLACK }
        };
        let paths = h.samples_taken.max(1) as f64;
        let pixels = (0..pixels_n)
            .map(|i| {
                let p = px(i);
                let mut v = if layout.camera { normalize(&p[..3], p[3]) } else { Rgb::BLACK };
                if layout.splats {
                    let s = &p[layout.splat_offset()..layout.splat_offset() + 3];
                    let splat = Rgb::new((unfixed(s[0]) / paths) as f32, (unfixed(s[1]) / paths) as f32, (unfixed(s[2]) / paths) as f32);
                    if splat.is_finite() {
                        v += splat;
                    }
                }
                v
            })
            .collect();
        let mut image = Image::new(w, ht, pixels);
        image.pixel_format = PixelFormat::from_name(&h.pixel_format).unwrap_or(PixelFormat::Rgb);
        if layout.stokes && layout.camera {
            let o = layout.stokes_offset();
            for (k, name) in ["S1", "S2", "S3"].into_iter().enumerate() {
                let pixels = (0..pixels_n).map(|i| normalize(&px(i)[o + 3 * k..o + 3 * k + 3], px(i)[3])).collect();
                image.layers.push(Layer { name: name.to_string(), pixels });
            }
        }
        let o = layout.extra_offset();
        for (k, name) in layout.extra.iter().enumerate() {
            let values = (0..pixels_n)
                .map(|i| {
                    let p = px(i);
                    let v = (wide_to_f64(p[o + k]) / wide_to_f64(p[3])) as f32;
                    if p[3] > 0 && v.is_finite() { v } else { 0.0 }
                })
                .collect();
            image.channels.push(Channel { name: name.clone(), values });
        }
        if !layout.camera && image.pixel_format.has_alpha() {
            // Light paths have no camera ray to cover a pixel: opaque everywhere.
            image.channels.push(Channel { name: "A".into(), values: vec![1.0; pixels_n] });
        }
        image
    }

    /// The state as bytes: a magic tag and version, the header as JSON, and
    /// the sums as zigzag LEB128 integers, deflated.
    pub fn to_bytes(&self) -> Vec<u8> {
        use std::io::Write;
        let header = serde_json::to_vec(&StoredHeader { header: self.header.clone(), tile: self.tile }).unwrap_or_default();
        let mut raw = Vec::with_capacity(self.data.len() * 8);
        for &v in &self.data {
            let mut z = ((v << 1) ^ (v >> 127)) as u128;
            loop {
                let byte = (z & 0x7f) as u8;
                z >>= 7;
                if z == 0 {
                    raw.push(byte);
                    break;
                }
                raw.push(byte | 0x80);
            }
        }
        let mut enc = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::fast());
        // Writing to a Vec cannot fail.
        let _ = enc.write_all(&raw);
        let packed = enc.finish().unwrap_or_default();
        let mut out = Vec::with_capacity(24 + header.len() + packed.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(&header);
        out.extend_from_slice(&(packed.len() as u64).to_le_bytes());
        out.extend_from_slice(&packed);
        out
    }

    /// Reads a state written by [`FilmState::to_bytes`]; any damage or
    /// inconsistency is an error.
    pub fn from_bytes(bytes: &[u8]) -> anyhow::Result<FilmState> {
        use std::io::Read;
        let bad = |what: &str| anyhow::anyhow!("not a valid Snell film state: {what}");
        let take = |at: usize, n: usize| bytes.get(at..at + n).ok_or_else(|| bad("truncated"));
        if take(0, 8)? != MAGIC {
            return Err(bad("wrong magic tag"));
        }
        let version = u32::from_le_bytes(take(8, 4)?.try_into()?);
        if version != VERSION {
            anyhow::bail!("film state version {version} is not the {VERSION} this Snell reads");
        }
        let hlen = u32::from_le_bytes(take(12, 4)?.try_into()?) as usize;
        let StoredHeader { header, tile } = serde_json::from_slice(take(16, hlen)?).map_err(|e| bad(&format!("header: {e}")))?;
        if let Some(t) = &tile {
            let [_, _, cw, ch] = header.crop;
            let inside = |r: [u32; 4]| r[0] as u64 + r[2] as u64 <= cw as u64 && r[1] as u64 + r[3] as u64 <= ch as u64;
            let [px, py, pw, ph] = t.pixels;
            let [wx, wy, ww, wh] = t.window;
            if !inside(t.pixels) || !inside(t.window) || px < wx || py < wy || px + pw > wx + ww || py + ph > wy + wh {
                return Err(bad("a tile outside its film"));
            }
        }
        let [_, _, ew, eh] = tile.map_or(header.crop, |t| t.window);
        let plen = u64::from_le_bytes(take(16 + hlen, 8)?.try_into()?) as usize;
        let packed = take(24 + hlen, plen.min(bytes.len()))?;
        let n = (ew as u64 * eh as u64).saturating_mul(header.layout.stride() as u64);
        if n > crate::limits::max_film_bytes() / 16 {
            return Err(bad("film larger than the memory budget"));
        }
        let n = n as usize;
        let mut raw = Vec::new();
        flate2::read::DeflateDecoder::new(packed).take(n as u64 * 19 + 1).read_to_end(&mut raw).map_err(|e| bad(&format!("sums: {e}")))?;
        let mut data = Vec::with_capacity(n);
        let mut z: u128 = 0;
        let mut shift = 0;
        for &byte in &raw {
            if shift >= 128 {
                return Err(bad("integer too long"));
            }
            z |= ((byte & 0x7f) as u128) << shift;
            shift += 7;
            if byte & 0x80 == 0 {
                data.push(((z >> 1) as i128) ^ -((z & 1) as i128));
                (z, shift) = (0, 0);
            }
        }
        if data.len() != n || shift != 0 {
            return Err(bad(&format!("{} sums where the header says {n}", data.len())));
        }
        let mut state = FilmState { header, tile, data };
        let ranges = std::mem::take(&mut state.header.ranges);
        if ranges.iter().any(|r| r.start >= r.end || r.end > state.header.sample_count) {
            return Err(bad("sample ranges outside the render"));
        }
        state.header.ranges = coalesce(ranges.clone());
        if state.header.ranges.iter().map(|r| r.end - r.start).sum::<u32>() != ranges.iter().map(|r| r.end - r.start).sum::<u32>() {
            return Err(bad("overlapping sample ranges"));
        }
        Ok(state)
    }
}

/// Sorted, adjacent ranges joined.
fn coalesce(mut ranges: Vec<Range<u32>>) -> Vec<Range<u32>> {
    ranges.sort_by_key(|r| r.start);
    let mut out: Vec<Range<u32>> = Vec::with_capacity(ranges.len());
    for r in ranges {
        match out.last_mut() {
            Some(last) if last.end >= r.start => last.end = last.end.max(r.end),
            _ => out.push(r),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::FilterKind;

    fn header(layout: Layout) -> StateHeader {
        StateHeader {
            film_size: [8, 8],
            crop: [0, 0, 8, 8],
            seed: 1,
            sample_count: 16,
            fingerprint: 7,
            pixel_format: "rgb".into(),
            layout,
            ranges: vec![],
            complete: true,
            samples_taken: 0,
            invalid_samples: 0,
            radiance_scale: 1.0,
        }
    }

    fn camera() -> Layout {
        Layout { camera: true, splats: false, stokes: false, extra: vec!["A".into()] }
    }

    /// Uniform numbers in [0, 1) from a xorshift stream seeded by `seed`.
    fn uniforms(mut seed: u64) -> impl FnMut() -> f32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// One sink of the given extent at every SIMD level this CPU runs.
    fn sinks_at_every_level(layout: &Layout, x0: i32, y0: i32, width: usize, height: usize) -> Vec<Sink> {
        SimdLevel::ALL
            .into_iter()
            .filter(|l| l.supported())
            .map(|level| {
                let mut s = Sink::new(layout, x0, y0, width, height);
                s.level = level;
                s
            })
            .collect()
    }

    #[test]
    fn fixed_point_rounds_saturates_and_zeroes_nan() {
        assert_eq!(fixed_value(1.0), 1i64 << 32);
        assert_eq!(fixed_value(-0.5), -(1i64 << 31));
        assert_eq!(fixed_value(f32::NAN), 0);
        assert_eq!(fixed_value(1e30), i64::MAX);
        assert_eq!(fixed_value(-1e30), i64::MIN);
        // Rounded to nearest: no bias toward zero.
        assert_eq!(fixed_value(3.0 / VALUE_SCALE as f32 * 0.75), 2);
        assert_eq!(fixed_weight(1.0), 1 << 20);
        assert_eq!(fixed_weight(2.0), 1 << 20);
        assert_eq!(fixed_weight(-0.25), -(1 << 18));
        assert_eq!(unfixed(term(fixed_weight(0.5), fixed_value(1234.5))), 617.25);
        // Sums of the most terms a pixel can get stay far from overflow.
        assert!(term(1 << 20, i64::MIN).abs().checked_mul(81 << 32).is_some());
    }

    #[test]
    fn wide_to_f64_rounds_as_the_128_bit_conversion() {
        // Values within i64 (taking the 64-bit conversion, rounding where
        // they pass 2^53) and beyond it (the 128-bit one).
        let mut values = vec![0i128, 1, -1, i64::MAX as i128, i64::MIN as i128, i64::MAX as i128 + 1, i64::MIN as i128 - 1, i128::MAX, i128::MIN];
        for k in 50..64 {
            for d in [-3i128, -1, 0, 1, 3] {
                values.push((1i128 << k) + d);
                values.push(-(1i128 << k) + d);
                values.push((3i128 << k) / 2 + 1 + d);
            }
        }
        for v in values {
            assert_eq!(wide_to_f64(v).to_bits(), (v as f64).to_bits(), "{v}");
        }
    }

    #[test]
    fn box_filter_adds_into_one_pixel() {
        let layout = camera();
        let mut s = Sink::new(&layout, 0, 0, 4, 4);
        s.add_sample(&Filter::new(FilterKind::Box), Vec2::new(1.3, 2.9), Rgb::new(1.0, 2.0, 3.0), None, &[1.0]);
        let mut h = header(layout.clone());
        h.crop = [0, 0, 4, 4];
        let mut state = FilmState::empty(h);
        state.add_sink(&s);
        let nonzero: Vec<usize> = (0..16).filter(|&i| state.data[i * layout.stride() + 3] != 0).collect();
        assert_eq!(nonzero, vec![2 * 4 + 1]);
    }

    #[test]
    fn narrow_sums_spill_exactly_and_bright_samples_go_wide() {
        let layout = Layout { camera: true, splats: false, stokes: false, extra: vec![] };
        let mut state = FilmState::empty(header(layout.clone()));
        let mut sink = Sink::new(&layout, 0, 0, 8, 8);
        let filter = Filter::new(FilterKind::Box);
        // 15 is narrow, each term near 2^56: the i64 sums must move to the
        // wide ones every 2^7 samples or so.
        let values = [15.0f32, 14.5, -15.0, 1e6, 3.0e9, 15.0, 0.25];
        for _ in 0..100 {
            for &v in &values {
                sink.add_sample(&filter, Vec2::new(2.5, 3.5), Rgb::new(v, -v, 0.5), None, &[]);
            }
        }
        // Narrow samples only, at another pixel: they moved to the wide sums.
        for _ in 0..1000 {
            sink.add_sample(&filter, Vec2::new(5.5, 1.5), Rgb::new(15.5, 0.0, 0.0), None, &[]);
        }
        let j = (8 + 5) * layout.stride();
        assert!(sink.data[j] != 0 && sink.load <= i64::MAX as u64);
        state.add_sink(&sink);
        let i = (3 * 8 + 2) * layout.stride();
        let want = |v: f32| 100 * values.iter().map(|&x| term(1 << WEIGHT_BITS, fixed_value(x * v))).sum::<i128>();
        assert_eq!(state.data[i], want(1.0));
        assert_eq!(state.data[i + 1], want(-1.0));
        assert_eq!(state.data[i + 3], 700 * term(1 << WEIGHT_BITS, 1 << VALUE_BITS));
        assert_eq!(state.data[j], 1000 * term(1 << WEIGHT_BITS, fixed_value(15.5)));
        assert_eq!(state.data[j + 3], 1000 * term(1 << WEIGHT_BITS, 1 << VALUE_BITS));
    }

    /// The narrow sums, added at every level the CPU runs (AVX-512 and AVX2
    /// where it has them, the plain code), and the wide sums alone hold the
    /// same integers, for footprints of 1 to 7 pixels a side.
    #[test]
    fn narrow_rows_avx2_plain_and_wide_add_the_same_integers() {
        let layout = Layout { camera: true, splats: false, stokes: false, extra: vec![] };
        let filters = [
            Filter::new(FilterKind::Box),
            Filter::new(FilterKind::Tent { radius: 1.5 }),
            Filter::gaussian(0.5),
            Filter::new(FilterKind::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 }),
            Filter::new(FilterKind::Lanczos { lobes: 3 }),
        ];
        let mut next = uniforms(0x2545_f491_4f6c_dd1du64);
        for filter in &filters {
            let mut sinks = sinks_at_every_level(&layout, -4, -4, 20, 20);
            let mut wide = Sink::new(&layout, -4, -4, 20, 20);
            wide.narrow.clear();
            sinks.push(wide);
            for _ in 0..3000 {
                let pos = Vec2::new(12.0 * next(), 12.0 * next());
                let rgb = Rgb::new(15.0 * next() - 3.0, 2.0 * next(), 15.9 * next());
                for s in sinks.iter_mut() {
                    s.add_sample(filter, pos, rgb, None, &[]);
                }
            }
            for s in sinks.iter_mut() {
                if !s.narrow.is_empty() {
                    s.flush_narrow();
                }
            }
            assert!(sinks[0].data.iter().any(|&v| v != 0), "{filter:?}");
            for s in &sinks[1..] {
                assert!(s.data == sinks[0].data, "{filter:?} at {:?}", s.level);
            }
        }
    }

    /// Batches of samples ([`Sink::add_samples`], at every level the CPU
    /// runs) leave the same integers as the samples added one by one by the
    /// plain code: random positions, footprints cut by the sink's edge or
    /// passing the 4 × 4 pixels of the vector code (a pixel centre exactly
    /// at the radius), huge and NaN positions, values on either side of
    /// the narrow limit (16), NaN and infinite ones, for the box, tents,
    /// Gaussians, Mitchell's and Lanczos' filters.
    #[test]
    fn batches_add_the_same_integers_as_single_samples() {
        let layout = Layout { camera: true, splats: false, stokes: false, extra: vec!["A".into()] };
        let filters = [
            Filter::new(FilterKind::Box),
            Filter::new(FilterKind::Tent { radius: 1.0 }),
            Filter::new(FilterKind::Tent { radius: 1.5 }),
            Filter::gaussian(0.5),
            Filter::gaussian(0.3),
            Filter::new(FilterKind::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 }),
            Filter::catmull_rom(),
            Filter::new(FilterKind::Lanczos { lobes: 2 }),
        ];
        let mut next = uniforms(0x9e37_79b9_7f4a_7c15u64);
        let below_16 = f32::from_bits(16.0f32.to_bits() - 1);
        let special = [16.0, -16.0, below_16, -below_16, 15.999, f32::NAN, f32::INFINITY, -f32::INFINITY, 1e30, 0.0, -0.0, 3.0e9];
        for filter in &filters {
            let mut reference = Sink::new(&layout, -3, -2, 12, 10);
            reference.level = SimdLevel::Baseline;
            let mut sinks = sinks_at_every_level(&layout, -3, -2, 12, 10);
            let mut batch = Vec::new();
            for round in 0..400 {
                batch.clear();
                for _ in 0..64 {
                    let u = next();
                    let mut pos = Vec2::new(16.0 * next() - 5.0, 14.0 * next() - 4.0);
                    if u < 0.05 {
                        // A pixel centre exactly at the radius.
                        pos.x = (pos.x.floor() + 0.5 + filter.radius()).min(1e6);
                    } else if u < 0.06 {
                        pos.y = [f32::NAN, 1e12, -1e12, f32::INFINITY][(16.0 * next()) as usize % 4];
                    }
                    let value = |next: &mut dyn FnMut() -> f32| {
                        let k = next();
                        if k < 0.1 {
                            special[(special.len() as f32 * next()) as usize % special.len()]
                        } else if k < 0.5 {
                            32.0 * next() - 16.0
                        } else {
                            next()
                        }
                    };
                    let rgb = Rgb::new(value(&mut next), value(&mut next), value(&mut next));
                    batch.push((pos, rgb));
                }
                for &(pos, rgb) in &batch {
                    reference.add_sample(filter, pos, rgb, None, &[]);
                }
                for s in sinks.iter_mut() {
                    s.add_samples(filter, batch.iter().copied());
                }
                if round == 200 {
                    // Moves the narrow sums mid-way in one sink only.
                    sinks[0].flush_narrow();
                }
            }
            reference.flush_narrow();
            assert!(reference.data.iter().filter(|&&v| v != 0).count() > 300, "{:?}", filter.kind);
            for s in sinks.iter_mut() {
                s.flush_narrow();
                assert!(s.data == reference.data, "{:?} at {:?}", filter.kind, s.level);
            }
        }
    }

    #[test]
    fn constant_signal_develops_to_itself() {
        let filter = Filter::gaussian(0.5);
        let mut state = FilmState::empty(header(camera()));
        let mut sink = Sink::new(&camera(), -2, -2, 12, 12);
        for j in 0..32 {
            for i in 0..32 {
                sink.add_sample(&filter, Vec2::new((i as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 4.0), Rgb::new(0.5, 1.0, 2.0), None, &[1.0]);
            }
        }
        state.add_sink(&sink);
        let image = state.develop();
        for p in &image.pixels {
            assert!((p[0] - 0.5).abs() < 1e-5 && (p[2] - 2.0).abs() < 1e-5);
        }
        assert!(image.channel("A").unwrap().values.iter().all(|&a| (a - 1.0).abs() < 1e-6));
    }

    /// Splats of a constant signal spread evenly over the window develop to
    /// that signal in every pixel, the border's too, as camera samples do
    /// (`constant_signal_develops_to_itself`) — with [`Sink::splat_in_window`];
    /// [`Sink::splat`] leaves a corner pixel dark by the filter's mass lost
    /// outside.
    #[test]
    fn splats_in_window_develop_a_constant_signal_to_itself() {
        let layout = Layout { camera: false, splats: true, stokes: false, extra: vec![] };
        for filter in [Filter::gaussian(0.5), Filter::new(FilterKind::Tent { radius: 1.5 }), Filter::new(FilterKind::Box)] {
            let (mx, my) = (window_filter_mass(&filter, 8), window_filter_mass(&filter, 8));
            let develop = |in_window: bool| {
                let mut state = FilmState::empty(header(layout.clone()));
                let mut sink = Sink::new(&layout, -3, -3, 14, 14);
                // 16 × 16 splats a pixel on a regular grid.
                for j in 0..128 {
                    for i in 0..128 {
                        let pos = Vec2::new((i as f32 + 0.5) / 16.0, (j as f32 + 0.5) / 16.0);
                        if in_window {
                            sink.splat_in_window(&filter, pos, Rgb::new(0.5, 1.0, 2.0), &mx, &my);
                        } else {
                            sink.splat(&filter, pos, Rgb::new(0.5, 1.0, 2.0));
                        }
                    }
                }
                state.add_sink(&sink);
                state.header.samples_taken = 256;
                state.develop()
            };
            let image = develop(true);
            for p in &image.pixels {
                assert!((p[0] - 0.5).abs() < 1e-3 && (p[1] - 1.0).abs() < 2e-3 && (p[2] - 2.0).abs() < 4e-3, "{:?}: {p:?}", filter.kind);
            }
            let corner = develop(false).pixels[0][1];
            if !matches!(filter.kind, FilterKind::Box) {
                assert!(corner < 0.9, "{:?}: corner {corner}", filter.kind);
            }
        }
    }

    #[test]
    fn merge_is_exact_in_any_order_and_refuses_overlaps() {
        let filter = Filter::gaussian(0.5);
        let part = |k: u32| {
            let mut s = FilmState::empty(header(camera()));
            let mut sink = Sink::new(&camera(), -2, -2, 12, 12);
            for i in 0..50 {
                let t = (k * 50 + i) as f32;
                sink.add_sample(&filter, Vec2::new((t * 0.37) % 8.0, (t * 0.61) % 8.0), Rgb::new(t.sin() * 1e3, 1e-6 * t, 0.3), None, &[0.5]);
            }
            s.add_sink(&sink);
            s.add_range(4 * k..4 * k + 4);
            s.header.samples_taken = 50;
            s
        };
        let (a, b, c) = (part(0), part(1), part(2));
        let mut abc = a.clone();
        abc.merge(&b).unwrap();
        abc.merge(&c).unwrap();
        let mut cba = c.clone();
        cba.merge(&b).unwrap();
        cba.merge(&a).unwrap();
        assert_eq!(abc, cba);
        assert_eq!(abc.ranges(), &[0..12]);
        assert_eq!(abc.prefix(), Some(12));
        let e = abc.clone().merge(&b).unwrap_err().to_string();
        assert!(e.contains("both hold samples 4..8"), "{e}");
        let bytes = abc.to_bytes();
        assert_eq!(FilmState::from_bytes(&bytes).unwrap(), abc);
        assert!(FilmState::from_bytes(&bytes[..bytes.len() - 3]).is_err());
        assert!(FilmState::from_bytes(b"SNELLFS\0garbage").is_err());
    }
}

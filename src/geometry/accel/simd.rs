//! Eight f32 lanes, and the choice at run time of the instruction set the
//! BVH traversal runs with.
//!
//! The traversal (`accel.rs`) is generic over [`Lanes`], with two
//! implementations:
//! - [`Avx`] (x86-64): AVX2 + FMA registers and intrinsics. Its values are
//!   only ever made inside functions compiled with
//!   `#[target_feature(enable = "avx2,fma")]` (or the AVX-512 set), which
//!   `Accel` enters only after the CPU was found to have those features.
//! - [`Portable`]: plain arrays that LLVM vectorises for the build target
//!   (SSE2 on any x86-64, NEON on aarch64). Multiply-adds are fused where the
//!   target has FMA (aarch64, or an x86 build with `-C target-feature=+fma`)
//!   and separate elsewhere (a software `fmaf` would be slow), so on an old
//!   x86-64 the results may differ from the AVX2 path in the last bits.
//!
//! [`Level`] picks the path: the best the CPU has (`is_x86_feature_detected!`,
//! checked once), or the one named by the environment variable
//! `SNELL_SIMD=baseline|avx2|avx512` (capped at what the CPU has; for tests
//! and measurements). The AVX-512 level runs the same 8-wide code compiled
//! with AVX-512F/VL/DQ/BW enabled (compares into mask registers, 32 vector
//! registers).
//!
//! Comparisons return lanes that are all-ones or zero; `bitmask` collects
//! their sign bits.

use std::ops::{Add, BitAnd, Div, Mul, Sub};
use std::sync::OnceLock;

/// Eight f32 lanes.
pub trait Lanes: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + BitAnd<Output = Self> {
    fn splat(x: f32) -> Self;
    fn from_array(a: [f32; 8]) -> Self;
    fn load(a: &[f32; 8]) -> Self;
    /// Eight bytes widened to f32 (0..=255, exact).
    fn from_u8(a: &[u8; 8]) -> Self;
    fn to_array(self) -> [f32; 8];
    /// self · b − c (fused on FMA hardware).
    fn mul_sub(self, b: Self, c: Self) -> Self;
    /// self · b + c (fused on FMA hardware).
    fn mul_add(self, b: Self, c: Self) -> Self;
    /// Like `minps`: the second operand when either is NaN.
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    fn lt(self, o: Self) -> Self;
    fn le(self, o: Self) -> Self;
    fn bitmask(self) -> u32;
    /// The sign bits alone.
    fn sign(self) -> Self;
    fn xor(self, o: Self) -> Self;
    /// Lanes `o .. o + 8` of the sixteen of `self` then `hi` (`o` < 8).
    fn window(self, hi: Self, o: usize) -> Self;

    /// Lane `i` (< 8).
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self.to_array()[i]
    }

    /// The traversal keys of the children in `mask` (at least two bits),
    /// `self` holding their entry distances (non-negative): entry distance
    /// bits above the child word, sorted descending into
    /// `out[..mask.count_ones()]` (the rest of `out` unspecified).
    #[inline(always)]
    fn sorted_keys(self, mask: u32, children: &[u32; 8], out: &mut [u64; 8]) {
        let t = self.to_array();
        let mut k = 0;
        let mut m = mask;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let key = (t[i].to_bits() as u64) << 32 | children[i] as u64;
            // SAFETY: `k` counts the bits of `mask` taken so far, and `mask`
            // has one bit per lane. (Lets the sort go without bounds checks.)
            unsafe { std::hint::assert_unchecked(k < 8) };
            // Insertion sort, descending.
            let mut j = k;
            while j > 0 && out[j - 1] < key {
                out[j] = out[j - 1];
                j -= 1;
            }
            out[j] = key;
            k += 1;
        }
    }

    /// The lane of `mask` (not empty) holding the least value, when that
    /// value is below `bound`, no other lane of `mask` holds it and none is
    /// NaN; else `None` (always for the types without a cheap vector
    /// reduction: the caller then weighs the lanes one by one).
    #[inline(always)]
    fn unique_least_below(self, mask: u32, bound: f32) -> Option<usize> {
        let _ = (mask, bound);
        None
    }
}

/// An instruction-set level of the traversal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// Portable code for the build target (SSE2 on x86-64, NEON on aarch64).
    Baseline,
    /// AVX2 + FMA (x86-64-v3).
    Avx2,
    /// AVX2 + FMA + AVX-512 F/VL/DQ/BW.
    Avx512,
}

impl Level {
    pub const ALL: [Level; 3] = [Level::Baseline, Level::Avx2, Level::Avx512];

    pub fn name(self) -> &'static str {
        match self {
            Level::Baseline => "baseline",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
        }
    }

    /// Whether this CPU can run the level.
    pub fn supported(self) -> bool {
        match self {
            Level::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"),
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => {
                Level::Avx2.supported()
                    && is_x86_feature_detected!("avx512f")
                    && is_x86_feature_detected!("avx512vl")
                    && is_x86_feature_detected!("avx512dq")
                    && is_x86_feature_detected!("avx512bw")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The best level this CPU runs.
    pub fn best() -> Level {
        Level::ALL.into_iter().rev().find(|l| l.supported()).unwrap_or(Level::Baseline)
    }

    /// The level new BVHs use: `SNELL_SIMD` if set (capped at the best this
    /// CPU runs; an unknown name is reported once and ignored), else the best.
    pub fn current() -> Level {
        static LEVEL: OnceLock<Level> = OnceLock::new();
        *LEVEL.get_or_init(|| {
            let best = Level::best();
            let Ok(want) = std::env::var("SNELL_SIMD") else { return best };
            match Level::ALL.into_iter().find(|l| l.name() == want.trim()) {
                Some(l) if l <= best => l,
                Some(l) => {
                    eprintln!("warning: SNELL_SIMD={}: this CPU cannot run it, using {}", l.name(), best.name());
                    best
                }
                None => {
                    eprintln!("warning: SNELL_SIMD={want:?} is not one of baseline, avx2, avx512; using {}", best.name());
                    best
                }
            }
        })
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::Lanes;
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, Div, Mul, Sub};

    /// AVX2 + FMA lanes. Only made inside functions compiled with those
    /// target features (see the module documentation).
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct Avx(__m256);

    /// The same eight lanes for code compiled with AVX-512 F/VL/DQ/BW as
    /// well (and only made there): the operations of [`Avx`], and the
    /// traversal's scalar steps done in vector registers (`sorted_keys`: a
    /// sorting network over eight 64-bit keys in one 512-bit register;
    /// `unique_least_below`: a masked reduction), which AVX2 has no
    /// instructions for (64-bit unsigned min/max, mask registers).
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct Avx512(__m256);

    /// The lanes operations both types share; `$extra`: the methods one
    /// type does its own way.
    macro_rules! avx_lanes {
        ($T:ident { $($extra:tt)* }) => {
            // SAFETY (all `unsafe` blocks below): an `Avx` (`Avx512`) is only
            // made and used in code inlined into `#[target_feature(enable =
            // "avx2,fma", ..)]` (and "avx512f,avx512vl,avx512dq,avx512bw")
            // functions, which `Accel` calls only after checking that the
            // CPU has those features (`Level::supported`).
            impl Lanes for $T {
                #[inline(always)]
                fn splat(x: f32) -> $T {
                    $T(unsafe { _mm256_set1_ps(x) })
                }
                #[inline(always)]
                fn from_array(a: [f32; 8]) -> $T {
                    $T(unsafe { _mm256_loadu_ps(a.as_ptr()) })
                }
                #[inline(always)]
                fn load(a: &[f32; 8]) -> $T {
                    $T(unsafe { _mm256_loadu_ps(a.as_ptr()) })
                }
                #[inline(always)]
                fn from_u8(a: &[u8; 8]) -> $T {
                    $T(unsafe { _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(a.as_ptr() as *const __m128i))) })
                }
                #[inline(always)]
                fn to_array(self) -> [f32; 8] {
                    let mut a = [0.0; 8];
                    unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
                    a
                }
                #[inline(always)]
                fn mul_sub(self, b: $T, c: $T) -> $T {
                    $T(unsafe { _mm256_fmsub_ps(self.0, b.0, c.0) })
                }
                #[inline(always)]
                fn mul_add(self, b: $T, c: $T) -> $T {
                    $T(unsafe { _mm256_fmadd_ps(self.0, b.0, c.0) })
                }
                #[inline(always)]
                fn min(self, o: $T) -> $T {
                    $T(unsafe { _mm256_min_ps(self.0, o.0) })
                }
                #[inline(always)]
                fn max(self, o: $T) -> $T {
                    $T(unsafe { _mm256_max_ps(self.0, o.0) })
                }
                #[inline(always)]
                fn lt(self, o: $T) -> $T {
                    $T(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
                }
                #[inline(always)]
                fn le(self, o: $T) -> $T {
                    $T(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
                }
                #[inline(always)]
                fn bitmask(self) -> u32 {
                    unsafe { _mm256_movemask_ps(self.0) as u32 }
                }
                #[inline(always)]
                fn sign(self) -> $T {
                    $T(unsafe { _mm256_and_ps(_mm256_set1_ps(-0.0), self.0) })
                }
                #[inline(always)]
                fn xor(self, o: $T) -> $T {
                    $T(unsafe { _mm256_xor_ps(self.0, o.0) })
                }
                #[inline(always)]
                fn window(self, hi: $T, o: usize) -> $T {
                    // Both rotated left by o; lane j takes `hi` where j + o ≥ 8,
                    // that is where the rotated index (j + o) mod 8 is below o.
                    unsafe {
                        let o = _mm256_set1_epi32(o as i32);
                        let idx = _mm256_and_si256(_mm256_add_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), o), _mm256_set1_epi32(7));
                        let take_hi = _mm256_castsi256_ps(_mm256_cmpgt_epi32(o, idx));
                        $T(_mm256_blendv_ps(_mm256_permutevar8x32_ps(self.0, idx), _mm256_permutevar8x32_ps(hi.0, idx), take_hi))
                    }
                }
                $($extra)*
            }

            avx_binop!($T, Add, add, _mm256_add_ps);
            avx_binop!($T, Sub, sub, _mm256_sub_ps);
            avx_binop!($T, Mul, mul, _mm256_mul_ps);
            avx_binop!($T, Div, div, _mm256_div_ps);
            avx_binop!($T, BitAnd, bitand, _mm256_and_ps);
        };
    }

    macro_rules! avx_binop {
        ($T:ident, $tr:ident, $f:ident, $intr:ident) => {
            impl $tr for $T {
                type Output = $T;
                #[inline(always)]
                fn $f(self, o: $T) -> $T {
                    $T(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }

    avx_lanes!(Avx {});

    avx_lanes!(Avx512 {
        #[inline(always)]
        fn lane(self, i: usize) -> f32 {
            // (No store and reload: a 4-byte load from a just-stored
            // register waits for the store to forward.)
            unsafe { _mm256_cvtss_f32(_mm256_permutevar8x32_ps(self.0, _mm256_set1_epi32(i as i32))) }
        }

        #[inline(always)]
        fn sorted_keys(self, mask: u32, children: &[u32; 8], out: &mut [u64; 8]) {
            unsafe {
                let t = _mm512_cvtepu32_epi64(_mm256_castps_si256(self.0));
                let c = _mm512_cvtepu32_epi64(_mm256_loadu_si256(children.as_ptr() as *const __m256i));
                // Lanes outside `mask` are 0 and sort last.
                let keys = _mm512_maskz_or_epi64(mask as __mmask8, _mm512_slli_epi64::<32>(t), c);
                _mm512_storeu_epi64(out.as_mut_ptr() as *mut i64, sort8_descending(keys));
            }
        }

        #[inline(always)]
        fn unique_least_below(self, mask: u32, bound: f32) -> Option<usize> {
            unsafe {
                let k = mask as __mmask8;
                let v = _mm256_mask_blend_ps(k, _mm256_set1_ps(f32::INFINITY), self.0);
                let m = _mm256_min_ps(v, _mm256_permute2f128_ps::<1>(v, v));
                let m = _mm256_min_ps(m, _mm256_permute_ps::<0b01_00_11_10>(m));
                let m = _mm256_min_ps(m, _mm256_permute_ps::<0b10_11_00_01>(m));
                let least = _mm256_cvtss_f32(m);
                // Below the bound, no lane below it or NaN (`minps` may skip
                // a NaN lane's neighbour), and exactly one lane equal.
                let below = _mm256_mask_cmp_ps_mask::<_CMP_NGE_UQ>(k, v, m);
                let equal = _mm256_mask_cmp_ps_mask::<_CMP_EQ_OQ>(k, v, m);
                if least < bound && below == 0 && equal.count_ones() == 1 { Some(equal.trailing_zeros() as usize) } else { None }
            }
        }
    });

    /// Eight unsigned 64-bit keys sorted descending (lane 0 the largest):
    /// Batcher's odd-even merge sort, 19 compare-exchanges in six layers,
    /// each layer one permutation, a min, a max and a blend.
    #[inline(always)]
    unsafe fn sort8_descending(v: __m512i) -> __m512i {
        // Per layer: each lane's partner (itself when idle), and the lanes
        // that take the larger key (the lower lane of each pair).
        #[inline(always)]
        unsafe fn layer(v: __m512i, partner: [i64; 8], upper: u8) -> __m512i {
            unsafe {
                let idx = _mm512_loadu_epi64(partner.as_ptr());
                let p = _mm512_permutexvar_epi64(idx, v);
                _mm512_mask_blend_epi64(upper, _mm512_min_epu64(v, p), _mm512_max_epu64(v, p))
            }
        }
        unsafe {
            let v = layer(v, [1, 0, 3, 2, 5, 4, 7, 6], 0b0101_0101);
            let v = layer(v, [2, 3, 0, 1, 6, 7, 4, 5], 0b0011_0011);
            let v = layer(v, [0, 2, 1, 3, 4, 6, 5, 7], 0b0010_0010);
            let v = layer(v, [4, 5, 6, 7, 0, 1, 2, 3], 0b0000_1111);
            let v = layer(v, [0, 1, 4, 5, 2, 3, 6, 7], 0b0000_1100);
            layer(v, [0, 2, 1, 4, 3, 6, 5, 7], 0b0010_1010)
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub use avx::{Avx, Avx512};

/// Portable lanes: plain arrays.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct Portable([f32; 8]);

#[inline(always)]
fn map2(a: Portable, b: Portable, f: impl Fn(f32, f32) -> f32) -> Portable {
    Portable(std::array::from_fn(|i| f(a.0[i], b.0[i])))
}

#[inline(always)]
fn mask(b: bool) -> f32 {
    if b { f32::from_bits(!0) } else { 0.0 }
}

/// a · b + c: fused where the target has FMA instructions.
#[inline(always)]
fn madd(a: f32, b: f32, c: f32) -> f32 {
    if cfg!(any(target_arch = "aarch64", target_feature = "fma")) { a.mul_add(b, c) } else { a * b + c }
}

impl Lanes for Portable {
    #[inline(always)]
    fn splat(x: f32) -> Portable {
        Portable([x; 8])
    }
    #[inline(always)]
    fn from_array(a: [f32; 8]) -> Portable {
        Portable(a)
    }
    #[inline(always)]
    fn load(a: &[f32; 8]) -> Portable {
        Portable(*a)
    }
    #[inline(always)]
    fn from_u8(a: &[u8; 8]) -> Portable {
        Portable(a.map(f32::from))
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 8] {
        self.0
    }
    #[inline(always)]
    fn mul_sub(self, b: Portable, c: Portable) -> Portable {
        Portable(std::array::from_fn(|i| madd(self.0[i], b.0[i], -c.0[i])))
    }
    #[inline(always)]
    fn mul_add(self, b: Portable, c: Portable) -> Portable {
        Portable(std::array::from_fn(|i| madd(self.0[i], b.0[i], c.0[i])))
    }
    #[inline(always)]
    fn min(self, o: Portable) -> Portable {
        map2(self, o, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn max(self, o: Portable) -> Portable {
        map2(self, o, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn lt(self, o: Portable) -> Portable {
        map2(self, o, |a, b| mask(a < b))
    }
    #[inline(always)]
    fn le(self, o: Portable) -> Portable {
        map2(self, o, |a, b| mask(a <= b))
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        (0..8).fold(0, |m, i| m | ((self.0[i].to_bits() >> 31) << i))
    }
    #[inline(always)]
    fn sign(self) -> Portable {
        Portable(self.0.map(|x| f32::from_bits(x.to_bits() & 0x8000_0000)))
    }
    #[inline(always)]
    fn xor(self, o: Portable) -> Portable {
        map2(self, o, |a, b| f32::from_bits(a.to_bits() ^ b.to_bits()))
    }
    #[inline(always)]
    fn window(self, hi: Portable, o: usize) -> Portable {
        Portable(std::array::from_fn(|i| if i + o < 8 { self.0[i + o] } else { hi.0[i + o - 8] }))
    }
}

impl BitAnd for Portable {
    type Output = Portable;
    #[inline(always)]
    fn bitand(self, o: Portable) -> Portable {
        map2(self, o, |a, b| f32::from_bits(a.to_bits() & b.to_bits()))
    }
}
impl Add for Portable {
    type Output = Portable;
    #[inline(always)]
    fn add(self, o: Portable) -> Portable {
        map2(self, o, |a, b| a + b)
    }
}
impl Sub for Portable {
    type Output = Portable;
    #[inline(always)]
    fn sub(self, o: Portable) -> Portable {
        map2(self, o, |a, b| a - b)
    }
}
impl Mul for Portable {
    type Output = Portable;
    #[inline(always)]
    fn mul(self, o: Portable) -> Portable {
        map2(self, o, |a, b| a * b)
    }
}
impl Div for Portable {
    type Output = Portable;
    #[inline(always)]
    fn div(self, o: Portable) -> Portable {
        map2(self, o, |a, b| a / b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lanes<F: Lanes>() {
        let a = F::from_array([1.0, -2.0, 3.0, -4.0, 5.0, -6.0, 7.0, f32::INFINITY]);
        let b = F::splat(2.0);
        assert_eq!((a * b).to_array(), [2.0, -4.0, 6.0, -8.0, 10.0, -12.0, 14.0, f32::INFINITY]);
        assert_eq!(a.mul_sub(b, b).to_array()[0], 0.0);
        assert_eq!(a.mul_add(b, b).to_array()[1], -2.0);
        assert_eq!(a.lt(b).bitmask(), 0b0010_1011);
        assert_eq!(a.le(F::splat(1.0)).bitmask(), 0b0010_1011);
        assert_eq!((a.lt(b) & a.le(F::splat(-3.0))).bitmask(), 0b0010_1000);
        assert_eq!(a.min(b).max(F::splat(0.0)).to_array(), [1.0, 0.0, 2.0, 0.0, 2.0, 0.0, 2.0, 2.0]);
        assert_eq!((a / b - b + b).to_array()[2], 1.5);
        assert_eq!(a.sign().bitmask(), 0b0010_1010);
        assert_eq!(a.xor(a.sign()).to_array(), a.to_array().map(f32::abs));
        assert_eq!(F::load(&[4.0; 8]).to_array(), [4.0; 8]);
        let hi = F::from_array([8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0]);
        let lo = F::from_array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        for o in 0..8 {
            assert_eq!(lo.window(hi, o).to_array(), std::array::from_fn(|i| (i + o) as f32), "window at {o}");
        }
        assert_eq!(F::from_u8(&[0, 1, 2, 127, 128, 200, 254, 255]).to_array(), [0.0, 1.0, 2.0, 127.0, 128.0, 200.0, 254.0, 255.0]);
    }

    #[test]
    fn portable_lanes() {
        lanes::<Portable>();
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn avx_lanes() {
        lanes::<Avx>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_lanes() {
        if Level::Avx2.supported() {
            // SAFETY: the CPU has AVX2 and FMA.
            unsafe { avx_lanes() };
        } else {
            eprintln!("avx2_lanes: this CPU has no AVX2 + FMA; not tested");
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")]
    fn avx512_lanes() {
        lanes::<Avx512>();
    }

    /// `sorted_keys` and `unique_least_below` of `F` against the plain
    /// versions (`Portable`'s): every mask of a few lane patterns (ties,
    /// zeros, infinities, NaN, equal keys) and random values.
    fn traversal_steps<F: Lanes>() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let nan = f32::NAN;
        let mut patterns = vec![
            [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0],
            [7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0, 0.0],
            [1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 0.5, 0.5],
            [0.0, 0.0, 3.0, f32::INFINITY, f32::INFINITY, 1e-30, 2.0, 2.0],
            [nan, 1.0, 0.5, nan, 3.0, 0.25, nan, 9.0],
        ];
        for _ in 0..200 {
            // Few distinct values, so that ties are common.
            patterns.push(std::array::from_fn(|_| (next() % 6) as f32 * 0.75));
            patterns.push(std::array::from_fn(|_| f32::from_bits((next() >> 40) as u32 | 0x3000_0000)));
        }
        for (p, t) in patterns.iter().enumerate() {
            let children: [u32; 8] = std::array::from_fn(|i| if p % 3 == 0 { 5 } else { (next() as u32) | (i as u32) << 28 });
            for mask in 1u32..256 {
                for bound in [0.6, 1.0, 2.0, 100.0, f32::INFINITY] {
                    assert_eq!(F::from_array(*t).unique_least_below(mask, bound), Portable::from_array(*t).unique_least_below_checked(mask, bound), "{t:?} {mask:#b} {bound}");
                }
                if mask.count_ones() < 2 || t.iter().any(|x| x.is_nan() || *x < 0.0) {
                    continue;
                }
                let (mut a, mut b) = ([0u64; 8], [0u64; 8]);
                F::from_array(*t).sorted_keys(mask, &children, &mut a);
                Portable::from_array(*t).sorted_keys(mask, &children, &mut b);
                let k = mask.count_ones() as usize;
                assert_eq!(a[..k], b[..k], "{t:?} {mask:#b}");
            }
        }
        for i in 0..8 {
            assert_eq!(F::from_array(std::array::from_fn(|j| j as f32 * 1.5)).lane(i), i as f32 * 1.5);
        }
    }

    impl Portable {
        /// `unique_least_below` lane by lane (what the vector reductions
        /// must give).
        fn unique_least_below_checked(self, mask: u32, bound: f32) -> Option<usize> {
            let lanes: Vec<usize> = (0..8).filter(|i| mask & (1 << i) != 0).collect();
            if lanes.iter().any(|&i| self.0[i].is_nan()) {
                return None;
            }
            let least = lanes.iter().map(|&i| self.0[i]).fold(f32::INFINITY, f32::min);
            let at: Vec<usize> = lanes.into_iter().filter(|&i| self.0[i] == least).collect();
            (least < bound && at.len() == 1).then(|| at[0])
        }
    }

    #[test]
    fn portable_traversal_steps_are_the_plain_ones() {
        // (The plain `unique_least_below` decides nothing: `None`.)
        assert_eq!(Portable::from_array([1.0; 8]).unique_least_below(1, 2.0), None);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")]
    fn avx512_steps() {
        traversal_steps::<Avx512>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_lanes_and_traversal_steps() {
        if Level::Avx512.supported() {
            // SAFETY: the CPU has AVX-512 F/VL/DQ/BW, AVX2 and FMA.
            unsafe {
                avx512_lanes();
                avx512_steps();
            }
        } else {
            eprintln!("avx512_lanes_and_traversal_steps: this CPU has no AVX-512; not tested");
        }
    }

    #[test]
    fn levels_are_ordered_and_named() {
        assert!(Level::Baseline.supported());
        assert!(Level::best().supported());
        for l in Level::ALL {
            if l <= Level::best() {
                assert!(l.supported(), "{l:?}");
            }
        }
        assert_eq!(Level::ALL.map(Level::name), ["baseline", "avx2", "avx512"]);
    }
}

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

    // SAFETY (all `unsafe` blocks below): an `Avx` is only made and used in
    // code inlined into `#[target_feature(enable = "avx2,fma", ..)]`
    // functions, which `Accel` calls only after checking that the CPU has
    // those features (`Level::supported`).
    impl Lanes for Avx {
        #[inline(always)]
        fn splat(x: f32) -> Avx {
            Avx(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn from_array(a: [f32; 8]) -> Avx {
            Avx(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn load(a: &[f32; 8]) -> Avx {
            Avx(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn from_u8(a: &[u8; 8]) -> Avx {
            Avx(unsafe { _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(a.as_ptr() as *const __m128i))) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut a = [0.0; 8];
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn mul_sub(self, b: Avx, c: Avx) -> Avx {
            Avx(unsafe { _mm256_fmsub_ps(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn mul_add(self, b: Avx, c: Avx) -> Avx {
            Avx(unsafe { _mm256_fmadd_ps(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn min(self, o: Avx) -> Avx {
            Avx(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: Avx) -> Avx {
            Avx(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn lt(self, o: Avx) -> Avx {
            Avx(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn le(self, o: Avx) -> Avx {
            Avx(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn bitmask(self) -> u32 {
            unsafe { _mm256_movemask_ps(self.0) as u32 }
        }
        #[inline(always)]
        fn sign(self) -> Avx {
            Avx(unsafe { _mm256_and_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn xor(self, o: Avx) -> Avx {
            Avx(unsafe { _mm256_xor_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn window(self, hi: Avx, o: usize) -> Avx {
            // Both rotated left by o; lane j takes `hi` where j + o ≥ 8,
            // that is where the rotated index (j + o) mod 8 is below o.
            unsafe {
                let o = _mm256_set1_epi32(o as i32);
                let idx = _mm256_and_si256(_mm256_add_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), o), _mm256_set1_epi32(7));
                let take_hi = _mm256_castsi256_ps(_mm256_cmpgt_epi32(o, idx));
                Avx(_mm256_blendv_ps(_mm256_permutevar8x32_ps(self.0, idx), _mm256_permutevar8x32_ps(hi.0, idx), take_hi))
            }
        }
    }

    macro_rules! binop {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for Avx {
                type Output = Avx;
                #[inline(always)]
                fn $f(self, o: Avx) -> Avx {
                    Avx(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }
    binop!(Add, add, _mm256_add_ps);
    binop!(Sub, sub, _mm256_sub_ps);
    binop!(Mul, mul, _mm256_mul_ps);
    binop!(Div, div, _mm256_div_ps);
    binop!(BitAnd, bitand, _mm256_and_ps);
}

#[cfg(target_arch = "x86_64")]
pub use avx::Avx;

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

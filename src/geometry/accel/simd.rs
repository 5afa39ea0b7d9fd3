//! Eight f32 lanes: AVX2 + FMA registers when the build targets them (the
//! default x86-64-v3, see `.cargo/config.toml`), plain arrays otherwise.
//! Comparisons return an `F8` whose lanes are all-ones or zero; `bitmask`
//! collects their sign bits.

#[cfg(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma"))]
mod imp {
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, Div, Mul, Sub};

    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub struct F8(__m256);

    // SAFETY (all `unsafe` blocks below): the AVX, AVX2 and FMA target
    // features are enabled at compile time (see the `cfg` above).
    #[allow(unused_unsafe)]
    impl F8 {
        #[inline(always)]
        pub fn splat(x: f32) -> F8 {
            F8(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        pub fn from_array(a: [f32; 8]) -> F8 {
            F8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        pub fn to_array(self) -> [f32; 8] {
            let mut a = [0.0; 8];
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        /// self · b − c, fused.
        #[inline(always)]
        pub fn mul_sub(self, b: F8, c: F8) -> F8 {
            F8(unsafe { _mm256_fmsub_ps(self.0, b.0, c.0) })
        }
        /// self · b + c, fused.
        #[inline(always)]
        pub fn mul_add(self, b: F8, c: F8) -> F8 {
            F8(unsafe { _mm256_fmadd_ps(self.0, b.0, c.0) })
        }
        #[inline(always)]
        pub fn min(self, o: F8) -> F8 {
            F8(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn max(self, o: F8) -> F8 {
            F8(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        pub fn lt(self, o: F8) -> F8 {
            F8(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        pub fn le(self, o: F8) -> F8 {
            F8(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        pub fn bitmask(self) -> u32 {
            unsafe { _mm256_movemask_ps(self.0) as u32 }
        }
        /// The sign bits alone.
        #[inline(always)]
        pub fn sign(self) -> F8 {
            F8(unsafe { _mm256_and_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        pub fn xor(self, o: F8) -> F8 {
            F8(unsafe { _mm256_xor_ps(self.0, o.0) })
        }
    }

    macro_rules! binop {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for F8 {
                type Output = F8;
                #[inline(always)]
                #[allow(unused_unsafe)]
                fn $f(self, o: F8) -> F8 {
                    F8(unsafe { $intr(self.0, o.0) })
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

#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2", target_feature = "fma")))]
mod imp {
    use std::ops::{Add, BitAnd, Div, Mul, Sub};

    #[derive(Clone, Copy, Debug)]
    #[repr(C, align(32))]
    pub struct F8([f32; 8]);

    #[inline(always)]
    fn map2(a: F8, b: F8, f: impl Fn(f32, f32) -> f32) -> F8 {
        F8(std::array::from_fn(|i| f(a.0[i], b.0[i])))
    }

    #[inline(always)]
    fn mask(b: bool) -> f32 {
        if b { f32::from_bits(!0) } else { 0.0 }
    }

    impl F8 {
        #[inline(always)]
        pub fn splat(x: f32) -> F8 {
            F8([x; 8])
        }
        #[inline(always)]
        pub fn from_array(a: [f32; 8]) -> F8 {
            F8(a)
        }
        #[inline(always)]
        pub fn to_array(self) -> [f32; 8] {
            self.0
        }
        #[inline(always)]
        pub fn mul_sub(self, b: F8, c: F8) -> F8 {
            F8(std::array::from_fn(|i| self.0[i].mul_add(b.0[i], -c.0[i])))
        }
        #[inline(always)]
        pub fn mul_add(self, b: F8, c: F8) -> F8 {
            F8(std::array::from_fn(|i| self.0[i].mul_add(b.0[i], c.0[i])))
        }
        /// Like `minps`: the second operand when either is NaN.
        #[inline(always)]
        pub fn min(self, o: F8) -> F8 {
            map2(self, o, |a, b| if a < b { a } else { b })
        }
        #[inline(always)]
        pub fn max(self, o: F8) -> F8 {
            map2(self, o, |a, b| if a > b { a } else { b })
        }
        #[inline(always)]
        pub fn lt(self, o: F8) -> F8 {
            map2(self, o, |a, b| mask(a < b))
        }
        #[inline(always)]
        pub fn le(self, o: F8) -> F8 {
            map2(self, o, |a, b| mask(a <= b))
        }
        #[inline(always)]
        pub fn bitmask(self) -> u32 {
            (0..8).fold(0, |m, i| m | ((self.0[i].to_bits() >> 31) << i))
        }
        #[inline(always)]
        pub fn sign(self) -> F8 {
            F8(self.0.map(|x| f32::from_bits(x.to_bits() & 0x8000_0000)))
        }
        #[inline(always)]
        pub fn xor(self, o: F8) -> F8 {
            map2(self, o, |a, b| f32::from_bits(a.to_bits() ^ b.to_bits()))
        }
    }

    impl BitAnd for F8 {
        type Output = F8;
        #[inline(always)]
        fn bitand(self, o: F8) -> F8 {
            map2(self, o, |a, b| f32::from_bits(a.to_bits() & b.to_bits()))
        }
    }
    impl Add for F8 {
        type Output = F8;
        #[inline(always)]
        fn add(self, o: F8) -> F8 {
            map2(self, o, |a, b| a + b)
        }
    }
    impl Sub for F8 {
        type Output = F8;
        #[inline(always)]
        fn sub(self, o: F8) -> F8 {
            map2(self, o, |a, b| a - b)
        }
    }
    impl Mul for F8 {
        type Output = F8;
        #[inline(always)]
        fn mul(self, o: F8) -> F8 {
            map2(self, o, |a, b| a * b)
        }
    }
    impl Div for F8 {
        type Output = F8;
        #[inline(always)]
        fn div(self, o: F8) -> F8 {
            map2(self, o, |a, b| a / b)
        }
    }
}

pub use imp::F8;

#[cfg(test)]
mod tests {
    use super::F8;

    #[test]
    fn lanes() {
        let a = F8::from_array([1.0, -2.0, 3.0, -4.0, 5.0, -6.0, 7.0, f32::INFINITY]);
        let b = F8::splat(2.0);
        assert_eq!((a * b).to_array(), [2.0, -4.0, 6.0, -8.0, 10.0, -12.0, 14.0, f32::INFINITY]);
        assert_eq!(a.mul_sub(b, b).to_array()[0], 0.0);
        assert_eq!(a.mul_add(b, b).to_array()[1], -2.0);
        assert_eq!(a.lt(b).bitmask(), 0b0010_1011);
        assert_eq!(a.le(F8::splat(1.0)).bitmask(), 0b0010_1011);
        assert_eq!((a.lt(b) & a.le(F8::splat(-3.0))).bitmask(), 0b0010_1000);
        assert_eq!(a.min(b).max(F8::splat(0.0)).to_array(), [1.0, 0.0, 2.0, 0.0, 2.0, 0.0, 2.0, 2.0]);
        assert_eq!((a / b - b + b).to_array()[2], 1.5);
        assert_eq!(a.sign().bitmask(), 0b0010_1010);
        assert_eq!(a.xor(a.sign()).to_array(), a.to_array().map(f32::abs));
    }
}

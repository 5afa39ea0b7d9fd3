//! Float-to-integer rounding without a call into the C library: the
//! baseline x86-64 target has no rounding instruction, so `x.floor()` and
//! `x.ceil()` become calls to libm's `floorf`/`ceilf` on hot paths (the
//! film's footprint, the photon grid's cells and fixed-point sums).

/// `x.floor() as i32` (saturating, NaN to 0).
#[inline(always)]
pub fn floor_i32(x: f32) -> i32 {
    let t = x as i32;
    if (t as f32) > x { t.saturating_sub(1) } else { t }
}

/// `x.ceil() as i32` (saturating, NaN to 0).
#[inline(always)]
pub fn ceil_i32(x: f32) -> i32 {
    let t = x as i32;
    if (t as f32) < x { t.saturating_add(1) } else { t }
}

/// `x.floor() as i64` for |x| < 2^53.
#[inline(always)]
pub fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    i - (x < i as f64) as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_ceil_and_floor_match_the_library() {
        let mut xs = vec![0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 1.5, -1.5, 2.999, -2.999, 8388607.5, -8388607.5, 2.0 - 1e-7, -2.0 + 1e-7, 1e-30, -1e-30];
        xs.extend([1e9, -1e9, 16777217.0, -16777217.0, 2147483520.0, 2147483648.0, -2147483648.0, 3e9, -3e9, 1e30, -1e30]);
        xs.extend([f32::INFINITY, f32::NEG_INFINITY, f32::NAN, f32::MAX, f32::MIN, f32::MIN_POSITIVE]);
        let mut state = 12345u32;
        for _ in 0..100_000 {
            state = state.wrapping_mul(747796405).wrapping_add(2891336453);
            xs.push(((state >> 8) as f32 / (1u32 << 24) as f32 - 0.5) * 2000.0);
        }
        for x in xs {
            assert_eq!(ceil_i32(x), x.ceil() as i32, "ceil {x}");
            assert_eq!(floor_i32(x), x.floor() as i32, "floor {x}");
        }
    }

    #[test]
    fn floor_i64_matches_the_library() {
        for x in [0.0f64, -0.0, 0.5, -0.5, 1.0, -1.0, 2.999, -2.999, 65535.99, -65535.99, 1e15 + 0.5, -1e15 - 0.5] {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }
}

//! Reconstruction filters (`rfilter`), defined as in Mitsuba 3.
//!
//! | plugin | parameters | footprint |
//! |---|---|---|
//! | `box` | — | radius ½: each sample lands in its own pixel |
//! | `tent` | `radius` (1) | w(x) = max(0, 1 − \|x\|/radius) |
//! | `gaussian` | `stddev` (0.5) | w(x) = max(0, e^(−x²/2σ²) − e^(−r²/2σ²)), radius r = 4σ |
//!
//! Filters are separable: w(x, y) = w(x)·w(y).

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    Box,
    Tent { radius: f32 },
    Gaussian { stddev: f32, radius: f32 },
}

impl Filter {
    pub fn gaussian(stddev: f32) -> Filter {
        Filter::Gaussian { stddev, radius: 4.0 * stddev }
    }

    pub fn radius(&self) -> f32 {
        match self {
            Filter::Box => 0.5,
            Filter::Tent { radius } => *radius,
            Filter::Gaussian { radius, .. } => *radius,
        }
    }

    #[inline]
    pub fn eval(&self, x: f32) -> f32 {
        match *self {
            Filter::Box => {
                if (-0.5..0.5).contains(&x) { 1.0 } else { 0.0 }
            }
            Filter::Tent { radius } => (1.0 - x.abs() / radius).max(0.0),
            Filter::Gaussian { stddev, radius } => {
                let alpha = -1.0 / (2.0 * stddev * stddev);
                ((alpha * x * x).exp() - (alpha * radius * radius).exp()).max(0.0)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filters_vanish_at_their_radius() {
        for f in [Filter::Tent { radius: 1.5 }, Filter::gaussian(0.5)] {
            assert!(f.eval(0.0) > 0.0);
            assert_eq!(f.eval(f.radius()), 0.0);
            assert_eq!(f.eval(-f.radius() - 0.1), 0.0);
            assert!((f.eval(0.3) - f.eval(-0.3)).abs() < 1e-7);
        }
        assert_eq!(Filter::Box.eval(0.49), 1.0);
        assert_eq!(Filter::Box.eval(0.5), 0.0);
    }
}

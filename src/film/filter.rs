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
pub enum FilterKind {
    Box,
    Tent { radius: f32 },
    Gaussian { stddev: f32, radius: f32 },
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
    /// stored together so a lookup reads one entry.
    segments: Vec<[f32; 2]>,
}

const LUT: usize = 256;

impl FilterKind {
    pub fn radius(&self) -> f32 {
        match self {
            FilterKind::Box => 0.5,
            FilterKind::Tent { radius } => *radius,
            FilterKind::Gaussian { radius, .. } => *radius,
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
        }
    }
}

impl Filter {
    pub fn new(kind: FilterKind) -> Filter {
        let radius = kind.radius();
        let value = |i: usize| kind.eval(radius * i as f32 / (LUT - 1) as f32);
        let segments = (0..LUT - 1).map(|i| [value(i), value(i + 1)]).collect();
        Filter { kind, radius, scale: (LUT - 1) as f32 / radius, segments }
    }

    pub fn gaussian(stddev: f32) -> Filter {
        Filter::new(FilterKind::Gaussian { stddev, radius: 4.0 * stddev })
    }

    pub fn radius(&self) -> f32 {
        self.radius
    }

    #[inline]
    pub fn eval(&self, x: f32) -> f32 {
        if let FilterKind::Box = self.kind {
            return if (-0.5..0.5).contains(&x) { 1.0 } else { 0.0 };
        }
        let f = x.abs() * self.scale;
        if !(f < (LUT - 1) as f32) {
            return 0.0;
        }
        let i = f as usize;
        let t = f - i as f32;
        let [a, b] = self.segments[i];
        a + (b - a) * t
    }
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
}

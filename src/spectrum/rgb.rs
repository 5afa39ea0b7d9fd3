//! Linear RGB (Rec. 709 primaries, the colour space of Mitsuba's `*_rgb` variants).

use super::Spectrum;
use std::ops::{Add, AddAssign, Div, Index, Mul, MulAssign, Sub};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rgb(pub [f32; 3]);

impl Rgb {
    pub const BLACK: Rgb = Rgb([0.0; 3]);
    pub const WHITE: Rgb = Rgb([1.0; 3]);

    #[inline]
    pub const fn new(r: f32, g: f32, b: f32) -> Rgb {
        Rgb([r, g, b])
    }

    #[inline]
    pub fn map(self, f: impl Fn(f32) -> f32) -> Rgb {
        Rgb([f(self.0[0]), f(self.0[1]), f(self.0[2])])
    }

    #[inline]
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|c| c.is_finite())
    }

    pub fn mean(&self) -> f32 {
        (self.0[0] + self.0[1] + self.0[2]) / 3.0
    }
}

impl Index<usize> for Rgb {
    type Output = f32;
    fn index(&self, i: usize) -> &f32 {
        &self.0[i]
    }
}

macro_rules! componentwise {
    ($tr:ident, $f:ident, $op:tt, $tra:ident, $fa:ident) => {
        impl $tr for Rgb {
            type Output = Rgb;
            #[inline]
            fn $f(self, o: Rgb) -> Rgb {
                Rgb([self.0[0] $op o.0[0], self.0[1] $op o.0[1], self.0[2] $op o.0[2]])
            }
        }
        impl $tr<f32> for Rgb {
            type Output = Rgb;
            #[inline]
            fn $f(self, o: f32) -> Rgb {
                Rgb([self.0[0] $op o, self.0[1] $op o, self.0[2] $op o])
            }
        }
        impl $tra for Rgb {
            #[inline]
            fn $fa(&mut self, o: Rgb) {
                *self = *self $op o;
            }
        }
        impl $tra<f32> for Rgb {
            #[inline]
            fn $fa(&mut self, o: f32) {
                *self = *self $op o;
            }
        }
    };
}

componentwise!(Add, add, +, AddAssign, add_assign);
componentwise!(Mul, mul, *, MulAssign, mul_assign);

impl Sub for Rgb {
    type Output = Rgb;
    #[inline]
    fn sub(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}

impl Div<f32> for Rgb {
    type Output = Rgb;
    #[inline]
    fn div(self, o: f32) -> Rgb {
        self * (1.0 / o)
    }
}

impl Spectrum for Rgb {
    type Wavelengths = ();
    type Channels = Self;

    #[inline]
    fn channels(&self) -> Self {
        *self
    }
    #[inline]
    fn mueller_channels(entry: impl Fn(usize, usize) -> Self) -> Self {
        entry(0, 0)
    }

    #[inline]
    fn zero() -> Self {
        Rgb::BLACK
    }
    #[inline]
    fn splat(v: f32) -> Self {
        Rgb([v; 3])
    }
    #[inline]
    fn sample_wavelengths(_u: f32) {}
    #[inline]
    fn hero_wavelength(_: &()) -> Option<f32> {
        None
    }
    #[inline]
    fn terminate_secondary(_: &mut ()) {}
    #[inline]
    fn from_reflectance(rgb: Rgb, _: &()) -> Self {
        rgb
    }
    #[inline]
    fn from_illuminant(rgb: Rgb, _: &()) -> Self {
        rgb
    }
    #[inline]
    fn from_unbounded(rgb: Rgb, _: &()) -> Self {
        rgb
    }
    #[inline]
    fn from_function(rgb: Rgb, _: impl Fn(f32) -> f32, _: &()) -> Self {
        rgb
    }
    #[inline]
    fn zip_map(self, o: Rgb, f: impl Fn(f32, f32) -> f32) -> Self {
        Rgb([f(self.0[0], o.0[0]), f(self.0[1], o.0[1]), f(self.0[2], o.0[2])])
    }
    #[inline]
    fn to_rgb(&self, _: &()) -> Rgb {
        *self
    }
    #[inline]
    fn max_component(&self) -> f32 {
        self.0[0].max(self.0[1]).max(self.0[2])
    }
    #[inline]
    fn channel_mean(&self) -> f32 {
        self.mean()
    }
    #[inline]
    fn is_zero(&self) -> bool {
        self.0 == [0.0; 3]
    }
    #[inline]
    fn to_channels4(&self) -> Option<[f32; 4]> {
        Some([self.0[0], self.0[1], self.0[2], 0.0])
    }
    #[inline]
    fn from_channels4(c: [f32; 4]) -> Option<Self> {
        Some(Rgb([c[0], c[1], c[2]]))
    }
}

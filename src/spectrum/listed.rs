//! Spectra given in the scene as `wavelength:value` pairs, and emission
//! (radiance, intensity, irradiance) as the scene gave it.
//!
//! RGB mode uses the colour Mitsuba's RGB variants derive from a listed
//! spectrum; spectral mode evaluates the listed spectrum itself at the path's
//! wavelengths (as Mitsuba's spectral variants do), rather than an uplift of
//! that colour.

use super::cie::spectrum_to_linear_srgb;
use super::{Rgb, Spectrum, UpliftCache};
use std::sync::Arc;

/// A piecewise-linear spectrum, zero outside its wavelength range (Mitsuba's
/// `irregular` spectrum).
#[derive(Clone, Debug, PartialEq)]
pub struct ListedSpectrum {
    /// (wavelength nm, value), wavelengths strictly increasing, at least two.
    samples: Vec<(f32, f32)>,
}

impl ListedSpectrum {
    /// `None` unless there are two or more pairs with increasing wavelengths.
    pub fn new(samples: Vec<(f32, f32)>) -> Option<ListedSpectrum> {
        let increasing = samples.windows(2).all(|w| w[0].0 < w[1].0);
        (samples.len() >= 2 && increasing).then_some(ListedSpectrum { samples })
    }

    /// The constant `value` over the whole simulated range.
    pub fn constant(value: f32) -> ListedSpectrum {
        ListedSpectrum { samples: vec![(360.0, value), (830.0, value)] }
    }

    pub fn samples(&self) -> &[(f32, f32)] {
        &self.samples
    }

    #[inline]
    pub fn eval(&self, lambda: f32) -> f32 {
        let s = &self.samples;
        let i = s.partition_point(|&(l, _)| l < lambda);
        if i == 0 {
            return if s[0].0 == lambda { s[0].1 } else { 0.0 };
        }
        if i == s.len() {
            return 0.0;
        }
        let ((l0, v0), (l1, v1)) = (s[i - 1], s[i]);
        v0 + (v1 - v0) * (lambda - l0) / (l1 - l0)
    }

    /// Linear sRGB as a reflectance (under D65) or as emission.
    pub fn to_rgb(&self, illuminant: bool) -> Rgb {
        spectrum_to_linear_srgb(&self.samples, illuminant)
    }
}

/// An emitter's radiance (or intensity, irradiance): an RGB colour, uplifted
/// with D65 in spectral mode, or a listed spectrum used as it is.
#[derive(Clone, Debug)]
pub struct Emission {
    pub rgb: Rgb,
    pub spectrum: Option<Arc<ListedSpectrum>>,
    cache: UpliftCache,
}

impl Emission {
    pub fn rgb(rgb: Rgb) -> Emission {
        Emission { rgb, spectrum: None, cache: UpliftCache::default() }
    }

    pub fn listed(spectrum: ListedSpectrum) -> Emission {
        Emission { rgb: spectrum.to_rgb(true), spectrum: Some(Arc::new(spectrum)), cache: UpliftCache::default() }
    }

    /// Emission whose RGB-mode colour is `rgb` and whose spectral-mode
    /// spectrum is `spectrum` (given separately where the scene fixes both).
    pub fn with_spectrum(rgb: Rgb, spectrum: ListedSpectrum) -> Emission {
        Emission { rgb, spectrum: Some(Arc::new(spectrum)), cache: UpliftCache::default() }
    }

    /// Flat emission `value` at every wavelength (a constant `<spectrum>`),
    /// whose RGB colour is `rgb`.
    pub fn flat(rgb: Rgb, value: f32) -> Emission {
        Emission::with_spectrum(rgb, ListedSpectrum::constant(value))
    }

    pub fn is_zero(&self) -> bool {
        self.rgb.is_zero() && self.spectrum.as_ref().is_none_or(|s| s.samples().iter().all(|&(_, v)| v == 0.0))
    }

    /// The emission at the path's wavelengths.
    #[inline]
    pub fn eval<S: Spectrum>(&self, wl: &S::Wavelengths) -> S {
        match &self.spectrum {
            Some(s) => S::from_function(self.rgb, |l| s.eval(l), wl),
            None => S::from_illuminant_cached(self.rgb, &self.cache, wl),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn piecewise_linear_and_zero_outside() {
        let s = ListedSpectrum::new(vec![(400.0, 1.0), (500.0, 3.0), (600.0, 0.0)]).unwrap();
        assert_eq!(s.eval(399.0), 0.0);
        assert_eq!(s.eval(400.0), 1.0);
        assert_eq!(s.eval(450.0), 2.0);
        assert_eq!(s.eval(600.0), 0.0);
        assert_eq!(s.eval(650.0), 0.0);
        assert!(ListedSpectrum::new(vec![(500.0, 1.0), (400.0, 1.0)]).is_none());
        assert!(ListedSpectrum::new(vec![(500.0, 1.0)]).is_none());
    }
}

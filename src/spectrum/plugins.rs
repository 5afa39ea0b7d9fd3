//! Mitsuba 3's spectrum plugins, written `<spectrum type="…" name="…">` with
//! their parameters nested, wherever a colour is read (reflectances,
//! radiances, textures' colours):
//!
//! | plugin | parameters | meaning |
//! |---|---|---|
//! | `uniform` | `value`, (`wavelength_min`, `wavelength_max`: accepted, as Mitsuba does, without effect on the value) | `value` at every wavelength; grey `value` in RGB mode |
//! | `regular` | `wavelength_min`, `wavelength_max`, `values` (a list) | values at evenly spaced wavelengths, linear in between, zero outside |
//! | `irregular` | `wavelengths`, `values` (lists of equal length) | the same at the given (increasing) wavelengths |
//! | `blackbody` | `temperature` (K), `wavelength_min` (360), `wavelength_max` (830) | Planck's law in W m⁻² sr⁻¹ nm⁻¹, zero outside the range |
//! | `d65` | `color` (white), `scale` (1) | CIE D65 scaled to unit luminance, times the colour's uplift: what an emitter's `<rgb>` means |
//! | `srgb` | `color` (in [0, 1] unless `unbounded`), `unbounded` (false) | the colour's smooth reflectance spectrum, with no illuminant even for an emitter |
//!
//! ```xml
//! <emitter type="area">
//!     <spectrum type="blackbody" name="radiance">
//!         <float name="temperature" value="3000"/>
//!     </spectrum>
//! </emitter>
//! ```
//!
//! In spectral mode each is evaluated at the path's wavelengths as Mitsuba
//! 3.9.1's spectral variants evaluate it. In RGB mode `uniform`, `d65` and
//! `srgb` give Mitsuba's RGB values; Mitsuba's RGB variants refuse
//! `regular`, `irregular` and `blackbody`, which Snell converts to the colour
//! of the spectrum (as a reflectance under D65, or as emission), so an RGB
//! render agrees with the spectral one.

use super::cie::{d65_unit, spectrum_to_linear_srgb};
use super::cie_data::{LAMBDA_MAX, LAMBDA_MIN};
use super::uplift::RgbUplift;
use super::{Emission, ListedSpectrum, Rgb};

/// Physical constants as Mitsuba's `blackbody` uses them (CODATA 2014).
const SPEED_OF_LIGHT: f64 = 2.997_924_58e8;
const PLANCK: f64 = 6.626_070_04e-34;
const BOLTZMANN: f64 = 1.380_648_52e-23;

/// The plugins' names, for error messages.
pub const NAMES: [&str; 6] = ["blackbody", "d65", "irregular", "regular", "srgb", "uniform"];

/// The parameters `plugin` takes (the table above); `None` for an unknown plugin.
pub fn parameters(plugin: &str) -> Option<&'static [&'static str]> {
    Some(match plugin {
        "uniform" => &["value", "wavelength_min", "wavelength_max"],
        "regular" => &["wavelength_min", "wavelength_max", "values"],
        "irregular" => &["wavelengths", "values"],
        "blackbody" => &["temperature", "wavelength_min", "wavelength_max"],
        "d65" => &["color", "scale"],
        "srgb" => &["color", "unbounded"],
        _ => return None,
    })
}

/// A spectrum plugin as the scene gave it.
#[derive(Clone, Debug, PartialEq)]
pub enum SpectrumPlugin {
    Uniform { value: f32 },
    /// `regular`, `irregular` and `blackbody` (tabulated at 1 nm, where
    /// linear interpolation is within 4e-5 of Planck's law).
    Tabulated(ListedSpectrum),
    D65 { color: Rgb, scale: f32 },
    Srgb { color: Rgb, unbounded: bool },
}

/// Black-body spectral radiance (W m⁻² sr⁻¹ nm⁻¹) at `lambda_nm` and
/// `temperature` (K), by Planck's law.
pub fn planck(lambda_nm: f64, temperature: f64) -> f64 {
    let lambda = lambda_nm * 1e-9;
    let c0 = 2.0 * PLANCK * SPEED_OF_LIGHT * SPEED_OF_LIGHT;
    let c1 = PLANCK * SPEED_OF_LIGHT / BOLTZMANN;
    1e-9 * c0 / (lambda.powi(5) * ((c1 / (lambda * temperature)).exp_m1()))
}

/// `f` sampled on `[lo, hi]` at most 1 nm apart (both ends included).
fn tabulate(lo: f32, hi: f32, f: impl Fn(f32) -> f32) -> ListedSpectrum {
    let n = ((hi - lo).ceil() as usize).clamp(1, 100_000);
    let samples = (0..=n)
        .map(|i| {
            let l = if i == n { hi } else { lo + (hi - lo) * i as f32 / n as f32 };
            (l, f(l))
        })
        .collect();
    // Increasing by construction when lo < hi (checked by the callers).
    ListedSpectrum::new(samples).unwrap_or_else(|| ListedSpectrum::constant(0.0))
}

impl SpectrumPlugin {
    /// Planck's law on `[wavelength_min, wavelength_max]` (nm), zero outside.
    /// `None` unless 0 < temperature and 0 < min < max.
    pub fn blackbody(temperature: f32, wavelength_min: f32, wavelength_max: f32) -> Option<SpectrumPlugin> {
        let ok = temperature > 0.0 && wavelength_min > 0.0 && wavelength_min < wavelength_max;
        ok.then(|| {
            SpectrumPlugin::Tabulated(tabulate(wavelength_min, wavelength_max, |l| planck(l as f64, temperature as f64) as f32))
        })
    }

    /// `values` at evenly spaced wavelengths from `min` to `max` (nm).
    /// `None` unless there are two or more values and 0 < min < max.
    pub fn regular(wavelength_min: f32, wavelength_max: f32, values: &[f32]) -> Option<SpectrumPlugin> {
        if values.len() < 2 || !(wavelength_min > 0.0 && wavelength_min < wavelength_max) {
            return None;
        }
        let step = (wavelength_max - wavelength_min) / (values.len() - 1) as f32;
        let samples = values.iter().enumerate().map(|(i, &v)| (wavelength_min + step * i as f32, v)).collect();
        ListedSpectrum::new(samples).map(SpectrumPlugin::Tabulated)
    }

    /// `values` at `wavelengths` (nm, increasing). `None` unless the lists
    /// have the same length, at least two, and the wavelengths increase.
    pub fn irregular(wavelengths: &[f32], values: &[f32]) -> Option<SpectrumPlugin> {
        if wavelengths.len() != values.len() || wavelengths.first().is_some_and(|&l| l <= 0.0) {
            return None;
        }
        ListedSpectrum::new(wavelengths.iter().copied().zip(values.iter().copied()).collect()).map(SpectrumPlugin::Tabulated)
    }

    /// As a reflectance (or any colour that is not emission): its RGB-mode
    /// colour, and the spectrum spectral mode evaluates.
    pub fn reflectance(&self) -> (Rgb, ListedSpectrum) {
        match self {
            SpectrumPlugin::Uniform { value } => (Rgb::new(*value, *value, *value), ListedSpectrum::constant(*value)),
            SpectrumPlugin::Tabulated(s) => (spectrum_to_linear_srgb(s.samples(), false), s.clone()),
            SpectrumPlugin::D65 { color, scale } => {
                // Mitsuba multiplies the colour's emission uplift by D65 here
                // too: a `d65` reflectance is tinted by the illuminant.
                let rgb = *color * *scale;
                let (s, shape) = RgbUplift::get().illuminant(rgb);
                (rgb, tabulate(LAMBDA_MIN, LAMBDA_MAX, |l| s * shape.eval(l) * d65_unit(l)))
            }
            SpectrumPlugin::Srgb { color, unbounded } => (*color, srgb_spectrum(*color, *unbounded)),
        }
    }

    /// As emission (radiance, intensity, irradiance).
    pub fn emission(&self) -> Emission {
        match self {
            SpectrumPlugin::Uniform { value } => Emission::flat(Rgb::new(*value, *value, *value), *value),
            SpectrumPlugin::Tabulated(s) => Emission::listed(s.clone()),
            // Exactly what an emitter's <rgb> is in either mode.
            SpectrumPlugin::D65 { color, scale } => Emission::rgb(*color * *scale),
            SpectrumPlugin::Srgb { color, unbounded } => Emission::with_spectrum(*color, srgb_spectrum(*color, *unbounded)),
        }
    }
}

/// The smooth spectrum of `color` (a reflectance's uplift, scaled when
/// unbounded), tabulated at 1 nm.
fn srgb_spectrum(color: Rgb, unbounded: bool) -> ListedSpectrum {
    let (scale, shape) = if unbounded { RgbUplift::get().unbounded(color) } else { (1.0, RgbUplift::get().reflectance(color)) };
    tabulate(LAMBDA_MIN, LAMBDA_MAX, |l| scale * shape.eval(l))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planck_matches_wiens_displacement_law_and_a_known_value() {
        // The peak of B_λ lies at b / T, b = 2.897771955e-3 m K.
        let t = 5778.0;
        let peak = 2.897_771_955e-3 / t * 1e9;
        let (lo, hi) = (planck(peak - 1.0, t), planck(peak + 1.0, t));
        let mid = planck(peak, t);
        assert!(mid > lo && mid > hi, "no maximum at Wien's wavelength {peak} nm");
        // 3000 K at 500 nm: 2hc²/λ⁵ / (e^{hc/λkT} − 1), by hand:
        // c0 = 1.191042972e-16 W m² sr⁻¹, c1 = 1.438777354e-2 m K.
        let x: f64 = 1.438_777_354e-2 / (500e-9 * 3000.0);
        let expected = 1e-9 * 1.191_042_972e-16 / (500e-9f64).powi(5) / (x.exp() - 1.0);
        // (The constants above are rounded to 10 digits.)
        assert!((planck(500.0, 3000.0) / expected - 1.0).abs() < 1e-7);
    }

    #[test]
    fn tabulated_blackbody_is_planck_inside_and_zero_outside() {
        let SpectrumPlugin::Tabulated(s) = SpectrumPlugin::blackbody(3000.0, 380.0, 780.0).expect("valid") else { panic!() };
        for l in [380.0f32, 400.3, 555.5, 779.9, 780.0] {
            let exact = planck(l as f64, 3000.0);
            assert!((s.eval(l) as f64 / exact - 1.0).abs() < 1e-4, "{l} nm: {} vs {exact}", s.eval(l));
        }
        assert_eq!(s.eval(379.0), 0.0);
        assert_eq!(s.eval(781.0), 0.0);
        assert!(SpectrumPlugin::blackbody(0.0, 360.0, 830.0).is_none());
        assert!(SpectrumPlugin::blackbody(3000.0, 600.0, 500.0).is_none());
    }

    #[test]
    fn regular_and_irregular_interpolate_their_values() {
        let SpectrumPlugin::Tabulated(r) = SpectrumPlugin::regular(400.0, 700.0, &[0.1, 0.5, 0.9]).expect("valid") else { panic!() };
        assert_eq!(r.samples(), &[(400.0, 0.1), (550.0, 0.5), (700.0, 0.9)]);
        let SpectrumPlugin::Tabulated(i) = SpectrumPlugin::irregular(&[400.0, 500.0, 700.0], &[0.1, 0.5, 0.9]).expect("valid") else { panic!() };
        assert!((i.eval(600.0) - 0.7).abs() < 1e-6);
        assert!(SpectrumPlugin::regular(400.0, 700.0, &[0.5]).is_none());
        assert!(SpectrumPlugin::irregular(&[400.0, 500.0], &[0.1]).is_none());
        assert!(SpectrumPlugin::irregular(&[500.0, 400.0], &[0.1, 0.2]).is_none());
    }

    #[test]
    fn d65_emission_is_an_rgb_emitter_and_its_reflectance_is_tinted_by_d65() {
        let d65 = SpectrumPlugin::D65 { color: Rgb::new(0.2, 0.4, 0.6), scale: 2.0 };
        let e = d65.emission();
        assert_eq!(e.rgb, Rgb::new(0.4, 0.8, 1.2));
        assert!(e.spectrum.is_none());
        let (rgb, spectrum) = d65.reflectance();
        assert_eq!(rgb, Rgb::new(0.4, 0.8, 1.2));
        let (s, shape) = RgbUplift::get().illuminant(rgb);
        for l in [400.0f32, 500.0, 600.0, 700.0] {
            let want = s * shape.eval(l) * d65_unit(l);
            assert!((spectrum.eval(l) - want).abs() < 1e-5 * want.max(1.0));
        }
    }

    #[test]
    fn uniform_is_grey_in_rgb_and_flat_in_spectral_mode() {
        let u = SpectrumPlugin::Uniform { value: 0.5 };
        let e = u.emission();
        assert_eq!(e.rgb, Rgb::new(0.5, 0.5, 0.5));
        assert_eq!(e.spectrum.as_ref().map(|s| s.eval(451.0)), Some(0.5));
        assert_eq!(u.reflectance().0, Rgb::new(0.5, 0.5, 0.5));
    }
}

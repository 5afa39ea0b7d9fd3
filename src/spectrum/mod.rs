//! What a light path carries. Integrators and BSDFs are generic over
//! [`Spectrum`], so a spectral mode (several sampled wavelengths per path) or a
//! polarized one (Stokes vectors and Mueller matrices) is a new type
//! implementing this trait, not a rewrite of the integrators.
//!
//! Scene inputs (reflectances, radiances) are stored as linear RGB and turned
//! into the path's spectrum type at the point of use, given the path's
//! wavelengths.

pub mod cie;
mod cie_data;
pub mod listed;
pub mod mueller;
pub mod plugins;
pub mod polarized;
mod rgb;
pub mod sampled;
pub mod uplift;

pub use listed::{Emission, ListedSpectrum};
pub use rgb::Rgb;
pub use polarized::Polarized;
pub use sampled::Sampled;
pub use uplift::UpliftCache;

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign};

pub trait Spectrum:
    Copy
    + Debug
    + Send
    + Sync
    + Add<Output = Self>
    + AddAssign
    + Mul<Output = Self>
    + MulAssign
    + Mul<f32, Output = Self>
    + MulAssign<f32>
    + Div<f32, Output = Self>
{
    /// Per-path context the spectrum needs to interpret inputs: the sampled
    /// wavelengths in a spectral mode, nothing in RGB mode.
    type Wavelengths: Copy + Send + Sync + Debug;
    /// The per-channel (unpolarised) values this type carries: itself for
    /// unpolarised types, one Mueller-matrix entry's type for polarized ones.
    type Channels: Spectrum<Wavelengths = Self::Wavelengths>;

    /// The per-channel values: itself, or a Mueller matrix's intensity entry m₀₀.
    fn channels(&self) -> Self::Channels;
    /// A Mueller matrix whose entries differ per channel (e.g. a conductor's
    /// Fresnel matrix at each wavelength), entry (row, column) from `entry`;
    /// unpolarised types take m₀₀, its effect on unpolarised light.
    fn mueller_channels(entry: impl Fn(usize, usize) -> Self::Channels) -> Self;

    fn zero() -> Self;
    fn splat(v: f32) -> Self;
    /// Draws the wavelengths a camera path carries (u uniform in [0,1)).
    fn sample_wavelengths(u: f32) -> Self::Wavelengths;
    /// The wavelength (nm) that decides directions at a dispersive
    /// interface; `None` where there are no wavelengths (RGB).
    fn hero_wavelength(wavelengths: &Self::Wavelengths) -> Option<f32>;
    /// Keeps only the hero wavelength, after the path has taken a direction
    /// that only it can take (refraction by a dispersive interface). The
    /// film then weights the whole path's estimate by the hero alone, which
    /// stays unbiased since the hero's marginal density is unchanged.
    fn terminate_secondary(wavelengths: &mut Self::Wavelengths);
    /// A reflectance-like input (albedo in [0,1]) as this spectrum.
    fn from_reflectance(rgb: Rgb, wavelengths: &Self::Wavelengths) -> Self;
    /// An emission input (radiance, intensity, irradiance) as this spectrum.
    fn from_illuminant(rgb: Rgb, wavelengths: &Self::Wavelengths) -> Self;
    /// [`Spectrum::from_reflectance`] of a colour that never changes, with
    /// its uplift kept in `cache`.
    #[inline]
    fn from_reflectance_cached(rgb: Rgb, _cache: &UpliftCache, wavelengths: &Self::Wavelengths) -> Self {
        Self::from_reflectance(rgb, wavelengths)
    }
    /// [`Spectrum::from_illuminant`] of a colour that never changes, with
    /// its uplift kept in `cache`.
    #[inline]
    fn from_illuminant_cached(rgb: Rgb, _cache: &UpliftCache, wavelengths: &Self::Wavelengths) -> Self {
        Self::from_illuminant(rgb, wavelengths)
    }
    /// An unbounded per-channel quantity that is not a colour (e.g. a
    /// conductor's η and k) as this spectrum.
    fn from_unbounded(rgb: Rgb, wavelengths: &Self::Wavelengths) -> Self;
    /// A quantity known both as RGB (used in RGB mode) and as a function of
    /// the wavelength in nm (used in spectral modes), e.g. measured η(λ).
    fn from_function(rgb: Rgb, f: impl Fn(f32) -> f32, wavelengths: &Self::Wavelengths) -> Self;
    /// Applies `f` channel by channel to `self` and `other`.
    fn zip_map(self, other: Self, f: impl Fn(f32, f32) -> f32) -> Self;
    /// The film's linear RGB value of this path's radiance estimate.
    fn to_rgb(&self, wavelengths: &Self::Wavelengths) -> Rgb;
    fn max_component(&self) -> f32;
    /// The mean over the channels (RGB) or wavelengths (spectral) of the
    /// unpolarised values (Mitsuba's `dr::mean` of a spectrum).
    fn channel_mean(&self) -> f32;
    fn is_zero(&self) -> bool;
    /// Forgets polarisation (a diffuse surface's Mueller matrix keeps S0
    /// only); nothing to do for unpolarised types.
    #[inline]
    fn depolarize(self) -> Self {
        self
    }
    /// An optical element known by its Mueller matrix `m` (in the canonical
    /// Stokes frames of the directions involved), scaled by `scale`.
    /// Unpolarised types see only what it does to unpolarised light, m₀₀.
    #[inline]
    fn mueller(m: glam::Mat4, scale: Self) -> Self {
        scale * m.x_axis.x
    }
    /// The Stokes vector (S0, S1, S2, S3) per channel of the light this
    /// estimate describes, in the canonical Stokes frame of its direction
    /// of travel (`mueller::stokes_basis`); unpolarised light for
    /// unpolarised types.
    #[inline]
    fn stokes(&self) -> [Self::Channels; 4] {
        let zero = Self::Channels::zero();
        [self.channels(), zero, zero, zero]
    }
    /// Whether this type carries polarisation.
    const POLARIZED: bool = false;
    /// Whether paths of this type carry sampled wavelengths (the spectral
    /// modes); in RGB modes `Wavelengths` is empty and the wavelength draw
    /// is unused.
    const SPECTRAL: bool = std::mem::size_of::<Self::Wavelengths>() != 0;
    /// The values as up to four plain channels (RGB: the fourth is 0), for
    /// the SIMD kernels that keep one channel of many paths per register
    /// (`integrator::kernels`); `None` for types that are not a few plain
    /// numbers (Mueller matrices).
    #[inline]
    fn to_channels4(&self) -> Option<[f32; 4]> {
        None
    }
    /// The inverse of [`Spectrum::to_channels4`] (RGB ignores the fourth);
    /// `None` where that gives `None`.
    #[inline]
    fn from_channels4(_c: [f32; 4]) -> Option<Self> {
        None
    }
}

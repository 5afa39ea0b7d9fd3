//! Textures: functions of the surface's uv returning linear RGB.
//!
//! `to_uv` (a `<transform name="to_uv">`) maps the shape's uv before lookup;
//! its 2-D affine part (upper-left 2×2 and the x/y translation) is used, as
//! in Mitsuba.

pub mod bitmap;
pub mod checkerboard;
pub mod mesh_attribute;

pub use bitmap::Bitmap;
pub use checkerboard::Checkerboard;
pub use mesh_attribute::MeshAttributeTexture;

use crate::spectrum::{ListedSpectrum, Rgb, Spectrum, UpliftCache};
use glam::{Affine2, Mat2, Mat4, Vec2};
use std::sync::Arc;

/// Where a texture is evaluated: the surface's uv and, for textures that
/// read mesh data (`mesh_attribute`), the shape, triangle and barycentrics
/// of the hit. A bare uv converts into one with no shape.
#[derive(Clone, Copy, Debug)]
pub struct TexPoint {
    pub uv: Vec2,
    pub shape: u32,
    pub prim: u32,
    pub bary: Vec2,
}

impl From<Vec2> for TexPoint {
    #[inline]
    fn from(uv: Vec2) -> TexPoint {
        TexPoint { uv, shape: u32::MAX, prim: 0, bary: Vec2::ZERO }
    }
}

impl From<&crate::geometry::SurfaceInteraction> for TexPoint {
    #[inline]
    fn from(si: &crate::geometry::SurfaceInteraction) -> TexPoint {
        TexPoint { uv: si.uv, shape: si.shape, prim: si.prim, bary: si.bary }
    }
}

#[derive(Clone, Debug)]
pub enum Texture {
    /// A constant colour (and, in spectral mode, its uplift once computed).
    Constant(Rgb, UpliftCache),
    /// A `<spectrum>` of `wavelength:value` pairs: its colour in RGB mode,
    /// the spectrum itself in spectral mode.
    Spectral { rgb: Rgb, spectrum: Arc<ListedSpectrum> },
    Bitmap(Arc<Bitmap>),
    Checkerboard(Checkerboard),
    MeshAttribute(Arc<MeshAttributeTexture>),
}

impl Texture {
    #[inline]
    pub fn eval(&self, at: impl Into<TexPoint>) -> Rgb {
        let at = at.into();
        let uv = at.uv;
        match self {
            Texture::Constant(c, _) | Texture::Spectral { rgb: c, .. } => *c,
            Texture::Bitmap(b) => b.eval(uv),
            Texture::Checkerboard(c) => c.eval(uv),
            Texture::MeshAttribute(m) => m.eval(&at),
        }
    }

    /// The texture as a reflectance at the path's wavelengths.
    #[inline]
    pub fn eval_spectrum<S: Spectrum>(&self, uv: impl Into<TexPoint>, wl: &S::Wavelengths) -> S {
        match self {
            Texture::Constant(rgb, cache) => S::from_reflectance_cached(*rgb, cache, wl),
            Texture::Spectral { rgb, spectrum } => S::from_function(*rgb, |l| spectrum.eval(l), wl),
            _ => S::from_reflectance(self.eval(uv), wl),
        }
    }

    /// A scalar value (Mitsuba's `eval_1`): the luminance of the colour
    /// (the value itself for a grey or a float). Pass the surface
    /// interaction, not only its uv, so that a `mesh_attribute` finds its
    /// mesh. Mitsuba 3.9.1's checkerboard answers `eval_1` with the other
    /// square's value than `eval` (color1 where `eval` gives color0); Snell
    /// does the same, so that a checkered roughness, blend weight or opacity
    /// renders as in Mitsuba.
    #[inline]
    pub fn eval_1(&self, at: impl Into<TexPoint>) -> f32 {
        match self {
            Texture::Constant(c, _) if c.0[0] == c.0[1] && c.0[1] == c.0[2] => c.0[0],
            Texture::Checkerboard(cb) => {
                let swapped = Checkerboard { color0: cb.color1, color1: cb.color0, to_uv: cb.to_uv };
                luminance(swapped.eval(at.into().uv))
            }
            _ => luminance(self.eval(at)),
        }
    }

    /// The gradient of [`Texture::eval_1`] in uv (Mitsuba's `eval_1_grad`):
    /// that of the bilinear interpolation for a bilinear bitmap, zero for
    /// the piecewise-constant ones (constant, nearest bitmap, checkerboard).
    #[inline]
    pub fn eval_1_grad(&self, uv: Vec2) -> Vec2 {
        match self {
            Texture::Bitmap(b) => b.eval_1_grad(uv),
            _ => Vec2::ZERO,
        }
    }

    /// A constant colour.
    pub fn constant(rgb: Rgb) -> Texture {
        Texture::Constant(rgb, UpliftCache::default())
    }

    /// As [`Texture::eval_spectrum`], with `f` applied to the reflectance
    /// (per channel, or per wavelength).
    #[inline]
    pub fn eval_spectrum_map<S: Spectrum>(&self, uv: impl Into<TexPoint>, wl: &S::Wavelengths, f: impl Fn(f32) -> f32) -> S {
        match self {
            Texture::Spectral { rgb, spectrum } => S::from_function(rgb.map(&f), |l| f(spectrum.eval(l)), wl),
            _ => S::from_reflectance(self.eval(uv).map(f), wl),
        }
    }

    /// The mean value over uv space and channels (Mitsuba's `Texture::mean`;
    /// `plastic` steers its lobe choice by it).
    pub fn mean(&self) -> f32 {
        match self {
            Texture::Constant(c, _) | Texture::Spectral { rgb: c, .. } => c.mean(),
            Texture::Bitmap(b) => b.mean(),
            Texture::Checkerboard(c) => 0.5 * (c.color0.mean() + c.color1.mean()),
            Texture::MeshAttribute(m) => m.stats().0,
        }
    }

    /// The largest value the texture takes (for energy checks).
    pub fn max_value(&self) -> f32 {
        match self {
            Texture::Constant(c, _) => c.0.into_iter().fold(0.0, f32::max),
            Texture::Spectral { spectrum, .. } => spectrum.samples().iter().fold(0.0, |m, &(_, v)| m.max(v)),
            Texture::Bitmap(b) => b.max_value(),
            Texture::Checkerboard(c) => c.color0.0.into_iter().chain(c.color1.0).fold(0.0, f32::max),
            Texture::MeshAttribute(m) => m.stats().1,
        }
    }
}

/// Luminance of linear sRGB (Rec. 709 Y, Mitsuba's `luminance`).
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.212671 * c[0] + 0.715160 * c[1] + 0.072169 * c[2]
}

/// The 2-D affine part of a 4×4 `to_uv` matrix.
pub fn uv_transform(m: &Mat4) -> Affine2 {
    Affine2 {
        matrix2: Mat2::from_cols(Vec2::new(m.x_axis.x, m.x_axis.y), Vec2::new(m.y_axis.x, m.y_axis.y)),
        translation: Vec2::new(m.w_axis.x, m.w_axis.y),
    }
}

//! The film: where samples are accumulated into pixels, through a
//! reconstruction filter, and developed into an image.
//!
//! `hdrfilm` parameters:
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `width`, `height` | integer | 768, 576 | film size in pixels (the camera's projection) |
//! | `crop_offset_x`, `crop_offset_y` | integer | 0 | top-left pixel of the rendered window |
//! | `crop_width`, `crop_height` | integer | width, height | size of the rendered window = size of the output image |
//! | `pixel_format` | string | `rgb` | channels written: `rgb` (R,G,B), `rgba` (R,G,B,A), `luminance` (Y), `luminance_alpha` (Y,A), `xyz` (X,Y,Z), `xyza` (X,Y,Z,A) |
//! | `component_format`, `file_format`, `banner` | string, string, boolean | `float32`, `openexr`, false | accepted for compatibility |
//! | (nested) | `rfilter` | `gaussian` | reconstruction filter |
//!
//! As in Mitsuba, a crop window renders only its pixels, with the camera
//! keeping the full film's projection: a cropped render is that window of
//! the full render. Alpha (A) is the integrator's coverage — for `path`, 1
//! where the camera ray hits a surface or a visible environment emitter
//! exists, for `direct` and the AOV integrators' nested ones where it hits a
//! surface — filtered like colour, so an edge pixel holds the fraction of
//! its (filter-weighted) samples that hit. Y is the luminance of linear sRGB
//! (Rec. 709 weights) and XYZ its CIE 1931 transform, as Mitsuba converts.
//!
//! ```xml
//! <film type="hdrfilm">
//!     <integer name="width" value="640"/> <integer name="height" value="480"/>
//!     <integer name="crop_offset_x" value="100"/> <integer name="crop_offset_y" value="50"/>
//!     <integer name="crop_width" value="200"/> <integer name="crop_height" value="100"/>
//!     <string name="pixel_format" value="rgba"/>
//! </film>
//! ```
//!
//! Each sample at continuous film position p contributes to every pixel whose
//! centre c lies within the filter's radius, with weight w = filter(c − p);
//! a pixel's value is Σ w·L / Σ w. The sums are exact fixed-point integers
//! ([`accumulator`]), so an image does not depend on how its samples were
//! split over threads, passes or machines.

pub mod accumulator;
pub mod adaptive;
pub mod filter;
pub mod output;
pub mod stokes;

pub use accumulator::{FilmState, Layout, Sink, StateHeader, TileRegion, window_filter_mass};
pub use filter::{Filter, FilterKind};

use crate::spectrum::Rgb;

#[derive(Clone, Debug)]
pub struct FilmSpec {
    /// The full film, which the camera's projection spans.
    pub width: u32,
    pub height: u32,
    pub filter: Filter,
    /// The rendered window: offset (x, y) and size (width, height) in pixels.
    pub crop: [u32; 4],
    pub pixel_format: PixelFormat,
}

impl FilmSpec {
    /// A film of `width` × `height` pixels, rendered whole, written as RGB.
    pub fn new(width: u32, height: u32, filter: Filter) -> FilmSpec {
        FilmSpec { width, height, filter, crop: [0, 0, width, height], pixel_format: PixelFormat::Rgb }
    }
}

/// What the main image's channels are (Mitsuba's `pixel_format`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelFormat {
    Rgb,
    Rgba,
    Luminance,
    LuminanceAlpha,
    Xyz,
    Xyza,
}

impl PixelFormat {
    pub const NAMES: [&'static str; 6] = ["rgb", "rgba", "luminance", "luminance_alpha", "xyz", "xyza"];

    pub fn from_name(name: &str) -> Option<PixelFormat> {
        let all = [PixelFormat::Rgb, PixelFormat::Rgba, PixelFormat::Luminance, PixelFormat::LuminanceAlpha, PixelFormat::Xyz, PixelFormat::Xyza];
        PixelFormat::NAMES.iter().position(|n| *n == name).map(|i| all[i])
    }

    pub fn has_alpha(self) -> bool {
        matches!(self, PixelFormat::Rgba | PixelFormat::LuminanceAlpha | PixelFormat::Xyza)
    }

    /// The colour channels' names (the alpha channel, if any, is `A`).
    pub fn colour_channels(self) -> &'static [&'static str] {
        match self {
            PixelFormat::Rgb | PixelFormat::Rgba => &["R", "G", "B"],
            PixelFormat::Luminance | PixelFormat::LuminanceAlpha => &["Y"],
            PixelFormat::Xyz | PixelFormat::Xyza => &["X", "Y", "Z"],
        }
    }

    /// A linear-sRGB pixel in this format's colour channels (up to three).
    pub fn convert(self, p: Rgb) -> [f32; 3] {
        match self {
            PixelFormat::Rgb | PixelFormat::Rgba => p.0,
            PixelFormat::Luminance | PixelFormat::LuminanceAlpha => [luminance(p), 0.0, 0.0],
            PixelFormat::Xyz | PixelFormat::Xyza => srgb_to_xyz(p),
        }
    }
}

/// Luminance Y of linear sRGB (Rec. 709 primaries, D65), as Mitsuba's `luminance()`.
pub fn luminance(p: Rgb) -> f32 {
    0.212671 * p[0] + 0.715160 * p[1] + 0.072169 * p[2]
}

/// CIE 1931 XYZ of linear sRGB (D65), as Mitsuba's `srgb_to_xyz`.
pub fn srgb_to_xyz(p: Rgb) -> [f32; 3] {
    [
        0.412453 * p[0] + 0.357580 * p[1] + 0.180423 * p[2],
        luminance(p),
        0.019334 * p[0] + 0.119193 * p[1] + 0.950227 * p[2],
    ]
}

/// The developed image: linear RGB, row-major, top row first, and any
/// further layers of the same size (the Stokes components S1–S3 of a
/// polarized render), which an EXR keeps as channels `NAME.R` etc., and
/// further scalar channels (alpha `A`, AOVs such as `dd.y.T`, moments).
#[derive(Clone, Debug)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
    pub layers: Vec<Layer>,
    /// How `pixels` is written (RGB, luminance Y or XYZ; alpha is the
    /// channel `A` when the format has one).
    pub pixel_format: PixelFormat,
    /// Named scalar channels, written after the colour in this order.
    pub channels: Vec<Channel>,
}

/// One named scalar channel of an [`Image`], row-major like its pixels.
#[derive(Clone, Debug)]
pub struct Channel {
    pub name: String,
    pub values: Vec<f32>,
}

#[derive(Clone, Debug)]
pub struct Layer {
    pub name: String,
    pub pixels: Vec<Rgb>,
}

impl Image {
    /// An RGB image without further layers.
    pub fn new(width: u32, height: u32, pixels: Vec<Rgb>) -> Image {
        Image { width, height, pixels, layers: vec![], pixel_format: PixelFormat::Rgb, channels: vec![] }
    }

    pub fn layer(&self, name: &str) -> Option<&Layer> {
        self.layers.iter().find(|l| l.name == name)
    }

    /// The scalar channel `name` (e.g. `A`, `dd.y.T`).
    pub fn channel(&self, name: &str) -> Option<&Channel> {
        self.channels.iter().find(|c| c.name == name)
    }

    /// The values of the channel an EXR file would call `name`: `R`, `G`,
    /// `B` of the image, `NAME.R` etc. of a layer, or a scalar channel.
    pub fn values(&self, name: &str) -> Option<Vec<f32>> {
        if let Some(c) = self.channel(name) {
            return Some(c.values.clone());
        }
        let component = |suffix: &str| ["R", "G", "B"].iter().position(|c| *c == suffix);
        if let Some(k) = component(name) {
            return Some(self.pixels.iter().map(|p| p[k]).collect());
        }
        let (layer, suffix) = name.rsplit_once('.')?;
        let k = component(suffix)?;
        Some(self.layer(layer)?.pixels.iter().map(|p| p[k]).collect())
    }
}

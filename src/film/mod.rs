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
//! a pixel's value is Σ w·L / Σ w.

pub mod accumulator;
pub mod filter;
pub mod output;
pub mod stokes;

pub use accumulator::{FilmState, Layout, Sink, StateHeader};
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

/// A rectangle of pixels (with a border of the filter's radius) that one
/// thread accumulates into.
pub struct TileBuffer {
    pub x0: i32,
    pub y0: i32,
    pub width: usize,
    pub height: usize,
    /// Weighted RGB sum and weight sum per pixel.
    pub data: Vec<[f32; 4]>,
    /// Weighted S1, S2, S3 sums (RGB each) per pixel; empty unless the
    /// render is polarized.
    pub stokes: Vec<[f32; 9]>,
    /// Weighted sums of `n_extra` further scalar channels per pixel (alpha,
    /// AOVs), pixel after pixel; empty unless asked for.
    pub extra: Vec<f32>,
    pub n_extra: usize,
}

impl TileBuffer {
    pub fn new(x0: i32, y0: i32, width: usize, height: usize) -> TileBuffer {
        TileBuffer { x0, y0, width, height, data: vec![[0.0; 4]; width * height], stokes: vec![], extra: vec![], n_extra: 0 }
    }

    /// With room for `n` further scalar channels per pixel (alpha, AOVs),
    /// splatted by [`TileBuffer::splat_extra`].
    pub fn with_extra(mut self, n: usize) -> TileBuffer {
        self.extra = vec![0.0; self.width * self.height * n];
        self.n_extra = n;
        self
    }

    /// Adds the further channels `values` of a sample at `pos` with the same
    /// filter weights as its colour (the colour itself goes through
    /// [`TileBuffer::splat`], which also accumulates the weights).
    pub fn splat_extra(&mut self, filter: &Filter, pos: (f32, f32), values: &[f32]) {
        let n = self.n_extra;
        if n == 0 || values.len() != n {
            return;
        }
        let Some(fp) = self.footprint(filter, pos) else { return };
        for j in 0..fp.ny {
            let wy = fp.wy[j];
            if wy == 0.0 {
                continue;
            }
            let row = (fp.y0 + j) * self.width + fp.first;
            for (i, &wx) in fp.wx[..fp.nx].iter().enumerate() {
                let w = wx * wy;
                for (d, v) in self.extra[(row + i) * n..(row + i + 1) * n].iter_mut().zip(values) {
                    *d += w * v;
                }
            }
        }
    }

    /// With room for the Stokes components S1, S2, S3 (RGB each) of the
    /// polarized modes.
    pub fn with_stokes(mut self) -> TileBuffer {
        self.stokes = vec![[0.0; 9]; self.width * self.height];
        self
    }

    /// The pixels of this tile that a sample at continuous film position
    /// `pos` (pixels) reaches, and their filter weights along x and y.
    #[inline]
    fn footprint(&self, filter: &Filter, pos: (f32, f32)) -> Option<Footprint> {
        let r = filter.radius();
        // Pixel i has its centre at i + 0.5; clamp the footprint to the tile.
        let x0 = ((pos.0 - 0.5 - r).ceil() as i32).max(self.x0);
        let x1 = ((pos.0 - 0.5 + r).floor() as i32).min(self.x0 + self.width as i32 - 1);
        let y0 = ((pos.1 - 0.5 - r).ceil() as i32).max(self.y0);
        let y1 = ((pos.1 - 0.5 + r).floor() as i32).min(self.y0 + self.height as i32 - 1);
        if x1 < x0 || y1 < y0 {
            return None;
        }
        let (nx, ny) = (((x1 - x0 + 1) as usize).min(MAX_FOOTPRINT), ((y1 - y0 + 1) as usize).min(MAX_FOOTPRINT));
        let mut fp = Footprint { first: (x0 - self.x0) as usize, nx, ny, wx: [0.0; MAX_FOOTPRINT], wy: [0.0; MAX_FOOTPRINT], y0: (y0 - self.y0) as usize };
        for (i, w) in fp.wx[..nx].iter_mut().enumerate() {
            *w = filter.eval((x0 + i as i32) as f32 + 0.5 - pos.0);
        }
        for (j, w) in fp.wy[..ny].iter_mut().enumerate() {
            *w = filter.eval((y0 + j as i32) as f32 + 0.5 - pos.1);
        }
        Some(fp)
    }

    /// Adds sample `value` taken at continuous film position `pos` (pixels).
    #[inline]
    pub fn splat(&mut self, filter: &Filter, pos: (f32, f32), value: Rgb) {
        if let Some(fp) = self.footprint(filter, pos) {
            self.splat_footprint(&fp, value);
        }
    }

    #[inline]
    fn splat_footprint(&mut self, fp: &Footprint, value: Rgb) {
        let [r0, g0, b0] = value.0;
        let v = glam::Vec4::new(r0, g0, b0, 1.0);
        for j in 0..fp.ny {
            let wy = fp.wy[j];
            if wy == 0.0 {
                continue;
            }
            let row = (fp.y0 + j) * self.width + fp.first;
            for (px, &w) in self.data[row..row + fp.nx].iter_mut().zip(&fp.wx[..fp.nx]) {
                // (r, g, b, weight) accumulated as one 4-wide multiply-add.
                *px = (glam::Vec4::from_array(*px) + v * (w * wy)).to_array();
            }
        }
    }

    /// [`TileBuffer::splat`] of the intensity S0 = `value`, and the same
    /// filter weights applied to the Stokes components `s123` (a tile made
    /// [`TileBuffer::with_stokes`]).
    pub fn splat_stokes(&mut self, filter: &Filter, pos: (f32, f32), value: Rgb, s123: [Rgb; 3]) {
        let Some(fp) = self.footprint(filter, pos) else { return };
        self.splat_footprint(&fp, value);
        if self.stokes.is_empty() {
            return;
        }
        for j in 0..fp.ny {
            let row = (fp.y0 + j) * self.width + fp.first;
            for (px, &wx) in self.stokes[row..row + fp.nx].iter_mut().zip(&fp.wx[..fp.nx]) {
                let w = wx * fp.wy[j];
                for (k, v) in px.iter_mut().enumerate() {
                    *v += w * s123[k / 3][k % 3];
                }
            }
        }
    }
}

/// Where one sample lands in a tile: `nx` × `ny` pixels from column `first`
/// and row `y0` (tile coordinates), with separable filter weights.
struct Footprint {
    first: usize,
    y0: usize,
    nx: usize,
    ny: usize,
    wx: [f32; MAX_FOOTPRINT],
    wy: [f32; MAX_FOOTPRINT],
}

/// Widest filter footprint in pixels (radius ≤ 4).
const MAX_FOOTPRINT: usize = 9;

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

/// Accumulates tiles into the full image.
pub struct Film {
    pub width: u32,
    pub height: u32,
    sums: Vec<[f64; 4]>,
    /// S1–S3 sums (RGB each) of a polarized render, else empty.
    stokes: Vec<[f64; 9]>,
    /// Sums of the further scalar channels (names below), pixel after pixel.
    extra: Vec<f64>,
    extra_names: Vec<String>,
    pixel_format: PixelFormat,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        Film { width, height, sums: vec![[0.0; 4]; width as usize * height as usize], stokes: vec![], extra: vec![], extra_names: vec![], pixel_format: PixelFormat::Rgb }
    }

    /// A film that also develops the scalar channels `names` (tiles made
    /// [`TileBuffer::with_extra`] with as many), and writes its colour as
    /// `format` says.
    pub fn with_channels(mut self, format: PixelFormat, names: Vec<String>) -> Film {
        self.extra = vec![0.0; self.sums.len() * names.len()];
        self.extra_names = names;
        self.pixel_format = format;
        self
    }

    /// A film that also develops the Stokes layers S1, S2, S3.
    pub fn with_stokes(mut self) -> Film {
        self.stokes = vec![[0.0; 9]; self.sums.len()];
        self
    }

    pub fn merge(&mut self, tile: &TileBuffer) {
        for ty in 0..tile.height {
            let y = tile.y0 + ty as i32;
            if y < 0 || y >= self.height as i32 {
                continue;
            }
            for tx in 0..tile.width {
                let x = tile.x0 + tx as i32;
                if x < 0 || x >= self.width as i32 {
                    continue;
                }
                let (i, t) = (y as usize * self.width as usize + x as usize, ty * tile.width + tx);
                for (dst, src) in self.sums[i].iter_mut().zip(tile.data[t]) {
                    *dst += src as f64;
                }
                if let (Some(dst), Some(src)) = (self.stokes.get_mut(i), tile.stokes.get(t)) {
                    for (d, s) in dst.iter_mut().zip(src) {
                        *d += *s as f64;
                    }
                }
                let n = self.extra_names.len();
                if n > 0 && tile.n_extra == n {
                    for (d, s) in self.extra[i * n..(i + 1) * n].iter_mut().zip(&tile.extra[t * n..(t + 1) * n]) {
                        *d += *s as f64;
                    }
                }
            }
        }
    }

    pub fn develop(&self) -> Image {
        // Σ w·L / Σ w, with black where no sample landed. Filters with
        // negative lobes (Mitchell, Catmull–Rom, Lanczos) can make Σ w ≤ 0
        // in a sparsely sampled pixel: black there too, never Inf/NaN.
        let normalize = |sum: &[f64], weight: f64| {
            let v = Rgb::new((sum[0] / weight) as f32, (sum[1] / weight) as f32, (sum[2] / weight) as f32);
            if weight > 1e-9 && v.is_finite() { v } else { Rgb::BLACK }
        };
        let pixels = self.sums.iter().map(|s| normalize(&s[..3], s[3])).collect();
        let mut image = Image::new(self.width, self.height, pixels);
        if !self.stokes.is_empty() {
            for (k, name) in ["S1", "S2", "S3"].into_iter().enumerate() {
                let pixels = self.stokes.iter().zip(&self.sums).map(|(s, w)| normalize(&s[3 * k..3 * k + 3], w[3])).collect();
                image.layers.push(Layer { name: name.to_string(), pixels });
            }
        }
        image.pixel_format = self.pixel_format;
        let n = self.extra_names.len();
        for (k, name) in self.extra_names.iter().enumerate() {
            let values = self
                .sums
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    let v = (self.extra[i * n + k] / s[3]) as f32;
                    if s[3] > 0.0 && v.is_finite() { v } else { 0.0 }
                })
                .collect();
            image.channels.push(Channel { name: name.clone(), values });
        }
        image
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_filter_splats_into_one_pixel() {
        let mut t = TileBuffer::new(0, 0, 4, 4);
        t.splat(&Filter::new(FilterKind::Box), (1.3, 2.9), Rgb::new(1.0, 2.0, 3.0));
        let nonzero: Vec<usize> = (0..16).filter(|&i| t.data[i][3] > 0.0).collect();
        assert_eq!(nonzero, vec![2 * 4 + 1]);
    }

    #[test]
    fn constant_signal_develops_to_itself() {
        let filter = Filter::gaussian(0.5);
        let mut film = Film::new(8, 8);
        let mut tile = TileBuffer::new(-2, -2, 12, 12);
        for j in 0..32 {
            for i in 0..32 {
                tile.splat(&filter, ((i as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 4.0), Rgb::new(0.5, 1.0, 2.0));
            }
        }
        film.merge(&tile);
        for p in film.develop().pixels {
            assert!((p[0] - 0.5).abs() < 1e-5 && (p[2] - 2.0).abs() < 1e-5);
        }
    }
}

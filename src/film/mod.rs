//! The film: where samples are accumulated into pixels, through a
//! reconstruction filter, and developed into an image.
//!
//! `hdrfilm` parameters: `width`, `height` (integers, default 768 × 576),
//! `rfilter` (nested; default `gaussian` as in Mitsuba), and Mitsuba's
//! `pixel_format` / `component_format` / `file_format` accepted for
//! compatibility when they name what Snell writes anyway (rgb, float32, openexr).
//!
//! Each sample at continuous film position p contributes to every pixel whose
//! centre c lies within the filter's radius, with weight w = filter(c − p);
//! a pixel's value is Σ w·L / Σ w.

pub mod filter;
pub mod output;
pub mod stokes;

pub use filter::{Filter, FilterKind};

use crate::spectrum::Rgb;

#[derive(Clone, Debug)]
pub struct FilmSpec {
    pub width: u32,
    pub height: u32,
    pub filter: Filter,
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
}

impl TileBuffer {
    pub fn new(x0: i32, y0: i32, width: usize, height: usize) -> TileBuffer {
        TileBuffer { x0, y0, width, height, data: vec![[0.0; 4]; width * height], stokes: vec![] }
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
/// polarized render), which an EXR keeps as channels `NAME.R` etc.
#[derive(Clone, Debug)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
    pub layers: Vec<Layer>,
}

#[derive(Clone, Debug)]
pub struct Layer {
    pub name: String,
    pub pixels: Vec<Rgb>,
}

impl Image {
    /// An RGB image without further layers.
    pub fn new(width: u32, height: u32, pixels: Vec<Rgb>) -> Image {
        Image { width, height, pixels, layers: vec![] }
    }

    pub fn layer(&self, name: &str) -> Option<&Layer> {
        self.layers.iter().find(|l| l.name == name)
    }
}

/// Accumulates tiles into the full image.
pub struct Film {
    pub width: u32,
    pub height: u32,
    sums: Vec<[f64; 4]>,
    /// S1–S3 sums (RGB each) of a polarized render, else empty.
    stokes: Vec<[f64; 9]>,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        Film { width, height, sums: vec![[0.0; 4]; width as usize * height as usize], stokes: vec![] }
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

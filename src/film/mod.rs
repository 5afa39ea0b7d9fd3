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
}

impl TileBuffer {
    pub fn new(x0: i32, y0: i32, width: usize, height: usize) -> TileBuffer {
        TileBuffer { x0, y0, width, height, data: vec![[0.0; 4]; width * height] }
    }

    /// Adds sample `value` taken at continuous film position `pos` (pixels).
    #[inline]
    pub fn splat(&mut self, filter: &Filter, pos: (f32, f32), value: Rgb) {
        let r = filter.radius();
        // Pixel i has its centre at i + 0.5; clamp the footprint to the tile.
        let x0 = ((pos.0 - 0.5 - r).ceil() as i32).max(self.x0);
        let x1 = ((pos.0 - 0.5 + r).floor() as i32).min(self.x0 + self.width as i32 - 1);
        let y0 = ((pos.1 - 0.5 - r).ceil() as i32).max(self.y0);
        let y1 = ((pos.1 - 0.5 + r).floor() as i32).min(self.y0 + self.height as i32 - 1);
        if x1 < x0 || y1 < y0 {
            return;
        }
        let (nx, ny) = (((x1 - x0 + 1) as usize).min(MAX_FOOTPRINT), ((y1 - y0 + 1) as usize).min(MAX_FOOTPRINT));
        let mut wx = [0.0f32; MAX_FOOTPRINT];
        for (i, w) in wx[..nx].iter_mut().enumerate() {
            *w = filter.eval((x0 + i as i32) as f32 + 0.5 - pos.0);
        }
        let [r0, g0, b0] = value.0;
        let v = glam::Vec4::new(r0, g0, b0, 1.0);
        for j in 0..ny {
            let wy = filter.eval((y0 + j as i32) as f32 + 0.5 - pos.1);
            if wy == 0.0 {
                continue;
            }
            let row = (y0 + j as i32 - self.y0) as usize * self.width + (x0 - self.x0) as usize;
            for (px, &w) in self.data[row..row + nx].iter_mut().zip(&wx[..nx]) {
                // (r, g, b, weight) accumulated as one 4-wide multiply-add.
                *px = (glam::Vec4::from_array(*px) + v * (w * wy)).to_array();
            }
        }
    }
}

/// Widest filter footprint in pixels (radius ≤ 4).
const MAX_FOOTPRINT: usize = 9;

/// The developed image: linear RGB, row-major, top row first.
#[derive(Clone, Debug)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
}

/// Accumulates tiles into the full image.
pub struct Film {
    pub width: u32,
    pub height: u32,
    sums: Vec<[f64; 4]>,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        Film { width, height, sums: vec![[0.0; 4]; width as usize * height as usize] }
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
                let src = tile.data[ty * tile.width + tx];
                let dst = &mut self.sums[y as usize * self.width as usize + x as usize];
                for c in 0..4 {
                    dst[c] += src[c] as f64;
                }
            }
        }
    }

    pub fn develop(&self) -> Image {
        let pixels = self
            .sums
            .iter()
            .map(|s| {
                if s[3] > 0.0 {
                    let v = Rgb::new((s[0] / s[3]) as f32, (s[1] / s[3]) as f32, (s[2] / s[3]) as f32);
                    if v.is_finite() { v } else { Rgb::BLACK }
                } else {
                    Rgb::BLACK
                }
            })
            .collect();
        Image { width: self.width, height: self.height, pixels }
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

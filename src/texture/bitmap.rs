//! `bitmap` — an image texture (PNG, JPEG or OpenEXR).
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `filename` | string | — | image file, relative to the scene file |
//! | `filter_type` | string | `bilinear` | `bilinear` or `nearest` |
//! | `wrap_mode` | string | `repeat` | `repeat`, `mirror` or `clamp` |
//! | `raw` | boolean | false | use 8-bit values as they are (no sRGB decoding) |
//! | `to_uv` | transform | identity | uv transform |
//!
//! As in Mitsuba, integer-valued images (PNG, JPEG) are sRGB-encoded and
//! decoded to linear unless `raw` is set; EXR is linear. uv (0,0) is the
//! image's top-left corner; texel centres are at (i + ½)/width.
//!
//! ```xml
//! <texture type="bitmap" name="reflectance">
//!     <string name="filename" value="textures/wood.png"/>
//! </texture>
//! ```

use crate::spectrum::Rgb;
use glam::{Affine2, Vec2};
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    Nearest,
    Bilinear,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    Mirror,
    Clamp,
}

#[derive(Clone, Debug)]
pub struct Bitmap {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<Rgb>,
    pub filter: Filter,
    pub wrap: Wrap,
    pub to_uv: Affine2,
}

pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.0031308 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// Reads an image as linear RGB texels (row 0 at the top).
pub fn read_image(path: &Path, raw: bool) -> Result<(usize, usize, Vec<Rgb>), String> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if ext == "exr" {
        use exr::prelude::*;
        let image = read_first_rgba_layer_from_file(
            path,
            |res, _| (res.width(), res.height(), vec![Rgb::BLACK; res.width() * res.height()]),
            |(w, _, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = Rgb::new(r, g, b),
        )
        .map_err(|e| format!("cannot read EXR image {}: {e}", path.display()))?;
        let (w, h, px) = image.layer_data.channel_data.pixels;
        if px.iter().any(|p| !p.is_finite()) {
            return Err(format!("EXR image {} contains NaN or infinite values", path.display()));
        }
        return Ok((w, h, px));
    }
    if ext == "pfm" {
        return read_pfm(path);
    }
    let img = image::ImageReader::open(path)
        .map_err(|e| format!("cannot open image {}: {e}", path.display()))?
        .with_guessed_format()
        .map_err(|e| format!("cannot read image {}: {e}", path.display()))?
        .decode()
        .map_err(|e| format!("cannot decode image {}: {e}", path.display()))?;
    // Floating-point images (Radiance RGBE) are linear already.
    let float = matches!(img.color(), image::ColorType::Rgb32F | image::ColorType::Rgba32F);
    let rgb = img.to_rgb32f();
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let decode = |v: f32| if raw || float { v } else { srgb_to_linear(v) };
    let px = rgb.pixels().map(|p| Rgb::new(decode(p[0]), decode(p[1]), decode(p[2]))).collect();
    Ok((w, h, px))
}

/// Reads a Portable Float Map (`PF` colour or `Pf` greyscale; the scale's
/// sign gives the byte order; rows stored bottom to top) as linear RGB.
fn read_pfm(path: &Path) -> Result<(usize, usize, Vec<Rgb>), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot open image {}: {e}", path.display()))?;
    let bad = |what: &str| format!("cannot read PFM image {}: {what}", path.display());
    // Header: three whitespace-separated tokens after the magic, then one whitespace byte.
    let mut tokens = Vec::new();
    let mut pos = 0;
    while tokens.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos || pos >= bytes.len() {
            return Err(bad("truncated header"));
        }
        tokens.push(std::str::from_utf8(&bytes[start..pos]).map_err(|_| bad("header is not text"))?);
    }
    pos += 1;
    let channels = match tokens[0] {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(bad("not a PFM file (it must start with PF or Pf)")),
    };
    let (w, h, scale) = match (tokens[1].parse::<usize>(), tokens[2].parse::<usize>(), tokens[3].parse::<f32>()) {
        (Ok(w), Ok(h), Ok(s)) if w > 0 && h > 0 && s != 0.0 && s.is_finite() => (w, h, s),
        _ => return Err(bad("invalid width, height or scale")),
    };
    let need = w.checked_mul(h).and_then(|n| n.checked_mul(4 * channels)).ok_or_else(|| bad("image too large"))?;
    let data = bytes.get(pos..pos + need).ok_or_else(|| bad("truncated pixel data"))?;
    let value = |k: usize| {
        let b = [data[4 * k], data[4 * k + 1], data[4 * k + 2], data[4 * k + 3]];
        if scale < 0.0 { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) }
    };
    let mut px = vec![Rgb::BLACK; w * h];
    for y in 0..h {
        for x in 0..w {
            let k = ((h - 1 - y) * w + x) * channels;
            px[y * w + x] = if channels == 3 { Rgb::new(value(k), value(k + 1), value(k + 2)) } else { Rgb::new(value(k), value(k), value(k)) };
        }
    }
    if px.iter().any(|p| !p.is_finite()) {
        return Err(format!("PFM image {} contains NaN or infinite values", path.display()));
    }
    Ok((w, h, px))
}

fn wrap(i: i64, n: usize, mode: Wrap) -> usize {
    let n = n as i64;
    (match mode {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let p = i.rem_euclid(2 * n);
            if p < n { p } else { 2 * n - 1 - p }
        }
    }) as usize
}

impl Bitmap {
    #[inline]
    fn texel(&self, x: i64, y: i64) -> Rgb {
        self.texels[wrap(y, self.height, self.wrap) * self.width + wrap(x, self.width, self.wrap)]
    }

    pub fn eval(&self, uv: Vec2) -> Rgb {
        let uv = self.to_uv.transform_point2(uv);
        if !uv.is_finite() {
            return Rgb::BLACK;
        }
        let x = uv.x * self.width as f32;
        let y = uv.y * self.height as f32;
        match self.filter {
            Filter::Nearest => self.texel(x.floor() as i64, y.floor() as i64),
            Filter::Bilinear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                self.texel(x0, y0) * ((1.0 - fx) * (1.0 - fy))
                    + self.texel(x0 + 1, y0) * (fx * (1.0 - fy))
                    + self.texel(x0, y0 + 1) * ((1.0 - fx) * fy)
                    + self.texel(x0 + 1, y0 + 1) * (fx * fy)
            }
        }
    }

    pub fn max_value(&self) -> f32 {
        self.texels.iter().flat_map(|t| t.0).fold(0.0, f32::max)
    }

    /// Mean over all texels and channels.
    pub fn mean(&self) -> f32 {
        let sum: f64 = self.texels.iter().map(|t| t.mean() as f64).sum();
        (sum / self.texels.len().max(1) as f64) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip() {
        for i in 0..=100 {
            let v = i as f32 / 100.0;
            assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 1e-5);
        }
        assert!((srgb_to_linear(0.5) - 0.214).abs() < 1e-3);
    }

    #[test]
    fn bilinear_interpolates_between_texel_centres() {
        let b = Bitmap {
            width: 2,
            height: 1,
            texels: vec![Rgb::BLACK, Rgb::WHITE],
            filter: Filter::Bilinear,
            wrap: Wrap::Clamp,
            to_uv: Affine2::IDENTITY,
        };
        assert_eq!(b.eval(Vec2::new(0.25, 0.5)), Rgb::BLACK);
        assert_eq!(b.eval(Vec2::new(0.75, 0.5)), Rgb::WHITE);
        assert!((b.eval(Vec2::new(0.5, 0.5))[0] - 0.5).abs() < 1e-6);
    }
}

#[cfg(test)]
mod pfm_tests {
    use super::*;

    #[test]
    fn pfm_rows_are_stored_bottom_up_in_either_byte_order() {
        let dir = std::env::temp_dir().join(format!("snell-pfm-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // 2×2 colour image; stored rows: bottom (1, 2), then top (3, 4).
        for (scale, le) in [("-1.0", true), ("1.0", false)] {
            let mut bytes = format!("PF\n2 2\n{scale}\n").into_bytes();
            for v in [1.0f32, 1.0, 1.0, 2.0, 2.0, 2.0, 3.0, 3.0, 3.0, 4.0, 4.0, 4.0] {
                bytes.extend(if le { v.to_le_bytes() } else { v.to_be_bytes() });
            }
            let path = dir.join(format!("t{le}.pfm"));
            std::fs::write(&path, &bytes).unwrap();
            let (w, h, px) = read_image(&path, false).unwrap();
            assert_eq!((w, h), (2, 2));
            assert_eq!(px.iter().map(|p| p[0]).collect::<Vec<_>>(), vec![3.0, 4.0, 1.0, 2.0]);
            // Truncated data is an error, not a panic.
            std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
            assert!(read_image(&path, false).unwrap_err().contains("truncated"));
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Radiance RGBE (`.hdr`) images are linear: no sRGB decoding.
    #[test]
    fn radiance_hdr_is_read_linear_top_row_first() {
        let dir = std::env::temp_dir().join(format!("snell-hdr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // 2×2, flat (width < 8: no run-length encoding). RGBE value = m · 2^(e − 136).
        let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 2\n".to_vec();
        // Top row: 0.5 (m 128, e 128) and 2.0 (m 128, e 130); bottom: 1.0 and 0.25 in red only.
        bytes.extend([128, 128, 128, 128, 128, 128, 128, 130, 128, 0, 0, 129, 128, 0, 0, 127]);
        let path = dir.join("t.hdr");
        std::fs::write(&path, &bytes).unwrap();
        let (w, h, px) = read_image(&path, false).unwrap();
        assert_eq!((w, h), (2, 2));
        let expect = [[0.5, 0.5, 0.5], [2.0, 2.0, 2.0], [1.0, 0.0, 0.0], [0.25, 0.0, 0.0]];
        for (p, e) in px.iter().zip(expect) {
            for c in 0..3 {
                assert!((p[c] - e[c]).abs() <= 0.01 * e[c] + 1e-6, "{px:?}");
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

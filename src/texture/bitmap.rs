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
//! An image's size is read from its header before it is decoded, and an
//! image with more pixels than the budget ([`crate::limits::max_image_pixels`],
//! `--max-image-pixels` or `SNELL_MAX_IMAGE_PIXELS`) is refused, so that a
//! small file claiming a huge size cannot exhaust the memory.
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

/// Refuses an image of `width` × `height` pixels above the pixel budget.
fn check_budget(path: &Path, width: u64, height: u64) -> Result<(), String> {
    let max = crate::limits::max_image_pixels();
    let pixels = width.saturating_mul(height);
    if pixels > max {
        return Err(format!(
            "image {} is {width} × {height} = {pixels} pixels, above the budget of {max} pixels \
             (raise it with --max-image-pixels or the environment variable SNELL_MAX_IMAGE_PIXELS)",
            path.display()
        ));
    }
    Ok(())
}

/// Reads an image as linear RGB texels (row 0 at the top).
pub fn read_image(path: &Path, raw: bool) -> Result<(usize, usize, Vec<Rgb>), String> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if ext == "exr" {
        use exr::prelude::*;
        // The header's size, before anything is allocated for the pixels.
        let meta = exr::meta::MetaData::read_from_file(path, false)
            .map_err(|e| format!("cannot read EXR image {}: {e}", path.display()))?;
        for header in &meta.headers {
            check_budget(path, header.layer_size.0 as u64, header.layer_size.1 as u64)?;
        }
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
    let open = || {
        image::ImageReader::open(path)
            .map_err(|e| format!("cannot open image {}: {e}", path.display()))?
            .with_guessed_format()
            .map_err(|e| format!("cannot read image {}: {e}", path.display()))
    };
    let (w, h) = open()?.into_dimensions().map_err(|e| format!("cannot read image {}: {e}", path.display()))?;
    check_budget(path, w as u64, h as u64)?;
    let mut reader = open()?;
    // Let the decoder allocate what the budget allows (16 bytes a pixel:
    // RGBA, 32-bit float at most), instead of the image crate's default.
    let mut limits = image::Limits::no_limits();
    limits.max_alloc = Some(crate::limits::max_image_pixels().saturating_mul(16).max(1 << 26));
    reader.limits(limits);
    let img = reader.decode().map_err(|e| format!("cannot decode image {}: {e}", path.display()))?;
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
    check_budget(path, w as u64, h as u64)?;
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

    /// The uv gradient of the luminance of the bilinear interpolation, as
    /// Mitsuba's `eval_1_grad`: the partials in texel units on the cell
    /// holding the point, taken back through `to_uv` (transpose of its
    /// linear part) and scaled by the resolution. Zero for `nearest`.
    pub fn eval_1_grad(&self, uv: Vec2) -> Vec2 {
        if self.filter == Filter::Nearest {
            return Vec2::ZERO;
        }
        let st = self.to_uv.transform_point2(uv);
        if !st.is_finite() {
            return Vec2::ZERO;
        }
        let (x, y) = (st.x * self.width as f32 - 0.5, st.y * self.height as f32 - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let lum = |x, y| super::luminance(self.texel(x, y));
        let (f00, f10, f01, f11) = (lum(x0, y0), lum(x0 + 1, y0), lum(x0, y0 + 1), lum(x0 + 1, y0 + 1));
        let dx = (1.0 - fy) * (f10 - f00) + fy * (f11 - f01);
        let dy = (1.0 - fx) * (f01 - f00) + fx * (f11 - f10);
        // df/du = Σ_k df/dst_k · dst_k/du: the transpose of to_uv's matrix.
        let m = self.to_uv.matrix2;
        let (dx, dy) = (dx * self.width as f32, dy * self.height as f32);
        Vec2::new(m.x_axis.x * dx + m.x_axis.y * dy, m.y_axis.x * dx + m.y_axis.y * dy)
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

    #[test]
    fn gradient_is_that_of_the_bilinear_interpolation_through_to_uv() {
        let texels = (0..25).map(|i| {
            let v = ((i * 7) % 11) as f32 / 10.0;
            Rgb::new(v, 0.5 * v, 1.0 - v)
        });
        let to_uv = Affine2::from_cols(Vec2::new(1.5, 0.3), Vec2::new(-0.2, 2.0), Vec2::new(0.1, 0.05));
        let b = Bitmap { width: 5, height: 5, texels: texels.collect(), filter: Filter::Bilinear, wrap: Wrap::Repeat, to_uv };
        let lum = |uv: Vec2| super::super::luminance(b.eval(uv));
        for uv in [Vec2::new(0.13, 0.27), Vec2::new(0.61, 0.44), Vec2::new(0.9, 0.02)] {
            let g = b.eval_1_grad(uv);
            let h = 1e-3;
            let fd = Vec2::new((lum(uv + Vec2::X * h) - lum(uv - Vec2::X * h)) / (2.0 * h), (lum(uv + Vec2::Y * h) - lum(uv - Vec2::Y * h)) / (2.0 * h));
            assert!((g - fd).length() < 2e-2 * (1.0 + fd.length()), "uv {uv}: {g} vs finite difference {fd}");
        }
        let nearest = Bitmap { filter: Filter::Nearest, ..b.clone() };
        assert_eq!(nearest.eval_1_grad(Vec2::new(0.3, 0.3)), Vec2::ZERO);
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

    /// The 8-bit formats Mitsuba's Bitmap reads besides PNG and JPEG — BMP
    /// (Mitsuba's docs/scenes/emitter_projector_textured.xml uses one), TGA
    /// and PPM — decode to the same sRGB-decoded texels as a PNG.
    #[test]
    fn bmp_tga_and_ppm_read_like_png() {
        let dir = std::env::temp_dir().join(format!("snell-8bit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let img = image::RgbImage::from_fn(3, 2, |x, y| image::Rgb([(40 * x + 10) as u8, (100 * y + 20) as u8, 200]));
        let mut reference = None;
        for ext in ["png", "bmp", "tga", "ppm"] {
            let path = dir.join(format!("t.{ext}"));
            img.save(&path).unwrap_or_else(|e| panic!("{ext}: {e}"));
            let (w, h, px) = read_image(&path, false).unwrap_or_else(|e| panic!("{ext}: {e}"));
            assert_eq!((w, h), (3, 2), "{ext}");
            assert!((px[4][1] - srgb_to_linear(120.0 / 255.0)).abs() < 1e-6, "{ext}: {:?}", px[4]);
            match &reference {
                None => reference = Some(px),
                Some(r) => assert_eq!(&px, r, "{ext} differs from png"),
            }
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

//! Writing developed images: OpenEXR (linear float32 RGB), PNG (8-bit sRGB,
//! clamped) and PFM (linear float32, bottom row first as the format says).

use super::Image;
use crate::texture::bitmap::linear_to_srgb;
use std::io::Write;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Exr,
    Png,
    Pfm,
}

impl Format {
    pub const EXTENSIONS: [&'static str; 3] = ["exr", "png", "pfm"];

    pub fn from_path(path: &Path) -> Option<Format> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "exr" => Some(Format::Exr),
            "png" => Some(Format::Png),
            "pfm" => Some(Format::Pfm),
            _ => None,
        }
    }
}

pub fn write_image(image: &Image, path: &Path) -> anyhow::Result<()> {
    let format = Format::from_path(path).ok_or_else(|| {
        anyhow::anyhow!("cannot tell the image format of {}: use one of .{}", path.display(), Format::EXTENSIONS.join(", ."))
    })?;
    let (w, h) = (image.width as usize, image.height as usize);
    match format {
        Format::Exr => {
            exr::prelude::write_rgb_file(path, w, h, |x, y| {
                let p = image.pixels[y * w + x];
                (p[0], p[1], p[2])
            })
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
        }
        Format::Png => {
            let mut buf = Vec::with_capacity(w * h * 3);
            for p in &image.pixels {
                for c in 0..3 {
                    buf.push((linear_to_srgb(p[c].clamp(0.0, 1.0)) * 255.0 + 0.5) as u8);
                }
            }
            image::save_buffer(path, &buf, w as u32, h as u32, image::ExtendedColorType::Rgb8)
                .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
        }
        Format::Pfm => {
            let mut f = std::io::BufWriter::new(
                std::fs::File::create(path).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?,
            );
            write!(f, "PF\n{w} {h}\n-1.0\n")?;
            for y in (0..h).rev() {
                for x in 0..w {
                    for c in 0..3 {
                        f.write_all(&image.pixels[y * w + x][c].to_le_bytes())?;
                    }
                }
            }
            f.flush()?;
        }
    }
    Ok(())
}

/// Reads a 3-channel EXR (as written by Snell or Mitsuba) back into an image.
pub fn read_exr(path: &Path) -> anyhow::Result<Image> {
    let (w, h, pixels) = crate::texture::bitmap::read_image(path, true).map_err(|e| anyhow::anyhow!(e))?;
    Ok(Image { width: w as u32, height: h as u32, pixels })
}

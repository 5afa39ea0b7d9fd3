//! Writing developed images: OpenEXR (linear float32, the channels the
//! film's `pixel_format` names — R,G,B / R,G,B,A / Y / Y,A / X,Y,Z / X,Y,Z,A
//! — plus named channels for further layers such as the Stokes components
//! and scalar channels such as AOVs), PNG (8-bit sRGB, clamped; RGBA when
//! the image has alpha, grey for luminance) and PFM (linear float32, bottom
//! row first as the format says; greyscale for luminance). PNG and PFM hold
//! the main image only.
//!
//! Every write is atomic and checked: the image goes to a temporary file in
//! the same folder, which is flushed and synced, then renamed over the
//! destination; any failure (a full disk, a missing folder) is an error that
//! names the file, and leaves no partial file behind.

use super::{Channel, Image, Layer, PixelFormat};
use crate::spectrum::Rgb;
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

/// Checks, before a render, that `path` can be written: its format is known,
/// its folder exists and is a folder, and a file can be created there (a
/// probe file is created and removed). The destination itself is not
/// touched.
pub fn check_writable(path: &Path) -> anyhow::Result<()> {
    if Format::from_path(path).is_none() {
        anyhow::bail!("cannot tell the image format of {}: use one of .{}", path.display(), Format::EXTENSIONS.join(", ."));
    }
    let dir = folder_of(path);
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => anyhow::bail!("cannot write {}: {} is not a folder", path.display(), dir.display()),
        Err(e) => anyhow::bail!("cannot write {}: its folder {} does not exist ({e})", path.display(), dir.display()),
    }
    if path.is_dir() {
        anyhow::bail!("cannot write {}: it is a folder", path.display());
    }
    let probe = temp_path(path, "probe");
    std::fs::File::create(&probe).map_err(|e| anyhow::anyhow!("cannot write {}: {e} (in folder {})", path.display(), dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A hidden temporary name next to `path`, unique to this process.
fn temp_path(path: &Path, what: &str) -> std::path::PathBuf {
    let name = path.file_name().map_or_else(|| "image".into(), |n| n.to_string_lossy().to_string());
    folder_of(path).join(format!(".{name}.{what}-{}", std::process::id()))
}

/// Writes through `body` into a temporary file next to `path`, flushes and
/// syncs it, and renames it to `path`; on any error removes the temporary
/// file and reports `path`.
fn write_atomically(path: &Path, body: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> anyhow::Result<()>) -> anyhow::Result<()> {
    let tmp = temp_path(path, "tmp");
    let result = (|| -> anyhow::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        body(&mut w)?;
        w.flush()?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, path)?;
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(anyhow::anyhow!("cannot write {}: {e:#}", path.display()));
    }
    Ok(())
}

pub fn write_image(image: &Image, path: &Path) -> anyhow::Result<()> {
    write_image_with(image, path, &ExrMetadata::default())
}

/// Further EXR header attributes: text attributes, and an optional block of
/// bytes (a serialised [`super::FilmState`], the exact state of a checkpoint).
/// Other formats ignore them.
#[derive(Clone, Debug, Default)]
pub struct ExrMetadata {
    pub text: Vec<(String, String)>,
    pub state: Option<Vec<u8>>,
}

/// The header attribute that holds a checkpoint's film state (type `bytes`).
pub const STATE_ATTRIBUTE: &str = "snell.state";

/// [`write_image`] with further EXR header attributes.
pub fn write_image_with(image: &Image, path: &Path, meta: &ExrMetadata) -> anyhow::Result<()> {
    let format = Format::from_path(path).ok_or_else(|| {
        anyhow::anyhow!("cannot tell the image format of {}: use one of .{}", path.display(), Format::EXTENSIONS.join(", ."))
    })?;
    let (w, h) = (image.width as usize, image.height as usize);
    let alpha = image.pixel_format.has_alpha().then(|| image.channel("A")).flatten();
    let grey = matches!(image.pixel_format, PixelFormat::Luminance | PixelFormat::LuminanceAlpha);
    let srgb8 = |v: f32| (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8;
    write_atomically(path, |f| {
        match format {
            Format::Exr if image.layers.is_empty() && image.channels.is_empty() && image.pixel_format == PixelFormat::Rgb && meta.text.is_empty() && meta.state.is_none() => {
                use exr::prelude::WritableImage;
                let channels = exr::prelude::SpecificChannels::rgb(|exr::math::Vec2(x, y)| {
                    let p: Rgb = image.pixels[y * w + x];
                    (p[0], p[1], p[2])
                });
                exr::prelude::Image::from_channels((w, h), channels).write().to_buffered(f)?;
            }
            Format::Exr => write_layered_exr(image, meta, f)?,
            Format::Png => {
                use image::ImageEncoder;
                let mut buf = Vec::with_capacity(w * h * 4);
                for (i, p) in image.pixels.iter().enumerate() {
                    if grey {
                        buf.push(srgb8(super::luminance(*p)));
                    } else {
                        for c in 0..3 {
                            buf.push(srgb8(p[c]));
                        }
                    }
                    if let Some(a) = alpha {
                        // Alpha is coverage: stored linearly.
                        buf.push((a.values[i].clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
                    }
                }
                let color = match (grey, alpha.is_some()) {
                    (false, false) => image::ExtendedColorType::Rgb8,
                    (false, true) => image::ExtendedColorType::Rgba8,
                    (true, false) => image::ExtendedColorType::L8,
                    (true, true) => image::ExtendedColorType::La8,
                };
                image::codecs::png::PngEncoder::new(&mut *f).write_image(&buf, w as u32, h as u32, color)?;
            }
            Format::Pfm => {
                write!(f, "{}\n{w} {h}\n-1.0\n", if grey { "Pf" } else { "PF" })?;
                for y in (0..h).rev() {
                    for x in 0..w {
                        let p = image.pixels[y * w + x];
                        if grey {
                            f.write_all(&super::luminance(p).to_le_bytes())?;
                            continue;
                        }
                        for c in 0..3 {
                            f.write_all(&p[c].to_le_bytes())?;
                        }
                    }
                }
            }
        }
        Ok(())
    })
}

/// The colour channels of the pixel format (R, G, B; Y; or X, Y, Z), then
/// each layer as channels `NAME.R`, `NAME.G`, `NAME.B` (a render with Stokes
/// layers also repeats R, G, B as `S0.*`, so the file has the channels
/// Mitsuba's `stokes` integrator writes), then the scalar channels (`A`,
/// AOVs) by name.
fn write_layered_exr(image: &Image, meta: &ExrMetadata, out: &mut std::io::BufWriter<std::fs::File>) -> anyhow::Result<()> {
    use exr::prelude as x;
    use exr::prelude::WritableImage;
    let channel = |name: String, pixels: &[Rgb], c: usize| {
        x::AnyChannel::new(name.as_str(), x::FlatSamples::F32(pixels.iter().map(|p| p[c]).collect()))
    };
    let mut layers: Vec<(String, &[Rgb])> = vec![];
    if image.layer("S1").is_some() {
        layers.push(("S0.".to_string(), &image.pixels));
    }
    layers.extend(image.layers.iter().map(|l| (format!("{}.", l.name), l.pixels.as_slice())));
    let mut channels = x::SmallVec::new();
    let format = image.pixel_format;
    for (c, name) in format.colour_channels().iter().enumerate() {
        let values = image.pixels.iter().map(|p| format.convert(*p)[c]).collect();
        channels.push(x::AnyChannel::new(*name, x::FlatSamples::F32(values)));
    }
    for Channel { name, values } in &image.channels {
        if name == "A" && !format.has_alpha() {
            continue;
        }
        channels.push(x::AnyChannel::new(name.as_str(), x::FlatSamples::F32(values.clone())));
    }
    for (prefix, pixels) in layers {
        for (c, rgb) in ["R", "G", "B"].into_iter().enumerate() {
            channels.push(channel(format!("{prefix}{rgb}"), pixels, c));
        }
    }
    let mut attributes = x::LayerAttributes::default();
    let text = |s: &str| x::Text::new_or_none(s).ok_or_else(|| anyhow::anyhow!("EXR attribute text must be Latin-1: {s}"));
    for (name, value) in &meta.text {
        attributes.other.insert(text(name)?, x::AttributeValue::Text(text(value)?));
    }
    if let Some(bytes) = &meta.state {
        let value = x::AttributeValue::Bytes { type_hint: text("snell-film-state")?, bytes: x::SmallVec::from_vec(bytes.clone()) };
        attributes.other.insert(text(STATE_ATTRIBUTE)?, value);
    }
    let layer = x::Layer::new(
        (image.width as usize, image.height as usize),
        attributes,
        x::Encoding::FAST_LOSSLESS,
        x::AnyChannels::sort(channels),
    );
    x::Image::from_layer(layer).write().to_buffered(out)?;
    Ok(())
}

/// The further header attributes of an EXR file (its text attributes, and
/// the bytes of [`STATE_ATTRIBUTE`] if present), read without its pixels.
pub fn read_exr_metadata(path: &Path) -> anyhow::Result<ExrMetadata> {
    use exr::meta::attribute::AttributeValue;
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| anyhow::anyhow!("cannot read EXR image {}: {e}", path.display()))?;
    let mut out = ExrMetadata::default();
    for header in meta.headers.iter().take(1) {
        for (name, value) in header.own_attributes.other.iter().chain(&header.shared_attributes.other) {
            match value {
                AttributeValue::Text(t) => out.text.push((name.to_string(), t.to_string())),
                AttributeValue::Bytes { bytes, .. } if name.to_string() == STATE_ATTRIBUTE => out.state = Some(bytes.to_vec()),
                _ => {}
            }
        }
    }
    out.text.sort();
    Ok(out)
}

/// Reads an EXR (as written by Snell or Mitsuba): R, G, B (or a grey Y) as
/// the image, every other complete `NAME.R`/`.G`/`.B` triple (S0–S3 of a
/// polarized render) as a layer, and every remaining channel (A, AOVs such
/// as `dd.y.T`) as a scalar channel.
pub fn read_exr(path: &Path) -> anyhow::Result<Image> {
    use exr::prelude as x;
    use exr::prelude::ReadChannels;
    use exr::prelude::ReadLayers;
    let file = x::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| anyhow::anyhow!("cannot read EXR image {}: {e}", path.display()))?;
    let size = file.layer_data.size;
    let channels = &file.layer_data.channel_data.list;
    let find = |name: &str| -> Option<Vec<f32>> {
        channels.iter().find(|c| c.name.to_string() == name).map(|c| c.sample_data.values_as_f32().collect())
    };
    let triple = |prefix: &str| -> Option<Vec<Rgb>> {
        let (r, g, b) = (find(&format!("{prefix}R"))?, find(&format!("{prefix}G"))?, find(&format!("{prefix}B"))?);
        let pixels: Vec<Rgb> = r.iter().zip(&g).zip(&b).map(|((&r, &g), &b)| Rgb::new(r, g, b)).collect();
        (pixels.len() == size.0 * size.1).then_some(pixels)
    };
    let grey = || -> Option<Vec<Rgb>> { find("Y").map(|y| y.iter().map(|&v| Rgb::new(v, v, v)).collect()) };
    let pixels = triple("").or_else(grey).ok_or_else(|| anyhow::anyhow!("EXR image {} has no R, G, B (or Y) channels", path.display()))?;
    let mut image = Image::new(size.0 as u32, size.1 as u32, pixels);
    let mut prefixes: Vec<String> = channels.iter().filter_map(|c| c.name.to_string().strip_suffix(".R").map(str::to_string)).collect();
    prefixes.sort();
    for name in prefixes {
        if let Some(pixels) = triple(&format!("{name}.")) {
            image.layers.push(Layer { name, pixels });
        }
    }
    let main: &[&str] = if find("R").is_some() { &["R", "G", "B"] } else { &["Y"] };
    for c in channels {
        let name = c.name.to_string();
        let in_layer = name.rsplit_once('.').is_some_and(|(l, s)| ["R", "G", "B"].contains(&s) && image.layer(l).is_some());
        if !main.contains(&name.as_str()) && !in_layer {
            let values: Vec<f32> = c.sample_data.values_as_f32().collect();
            if values.len() == size.0 * size.1 {
                image.channels.push(Channel { name, values });
            }
        }
    }
    if image.channel("A").is_some() {
        image.pixel_format = if main.len() == 1 { PixelFormat::LuminanceAlpha } else { PixelFormat::Rgba };
    } else if main.len() == 1 {
        image.pixel_format = PixelFormat::Luminance;
    }
    Ok(image)
}

//! Live preview: watch a progressive render converge in the browser.
//!
//! `snell render SCENE --preview [PORT]` renders in passes and serves a page
//! (`page.html`, embedded in the binary) that shows the image after each
//! pass. The render thread only *publishes*: after each pass it encodes the
//! image into a byte buffer and swaps it into shared state ([`Preview::publish`]);
//! server threads hand the latest buffer to whoever asks. A slow, stalled or
//! closed browser tab therefore never holds up the render, and any number of
//! tabs can watch.
//!
//! | option            | type      | default     | meaning                                          |
//! |-------------------|-----------|-------------|--------------------------------------------------|
//! | `--preview`       | port      | 8730        | serve the preview on this port (0: any free one) |
//! | `--preview-bind`  | IP address| 127.0.0.1   | the address to listen on (loopback: this machine only) |
//! | `--preview-dump-passes` | folder | —      | testing aid: also write each pass as `pass-NNN.exr` |
//!
//! Endpoints (anything else is 404; a known path with another method is 405):
//!
//! | path         | method     | answer                                                      |
//! |--------------|------------|-------------------------------------------------------------|
//! | `/`, `/index.html` | GET  | the page                                                    |
//! | `/progress`  | GET        | JSON: mode, size, layers, pass, passes, spp, samples/s, elapsed, ETA, state |
//! | `/image`     | GET        | the latest pass as floats (see [`encode_frame`]); 503 before the first |
//! | `/stop`      | POST       | sets the render's stop flag (the one Ctrl-C sets): the render ends and writes its outputs |
//!
//! The page tonemaps the float image itself (exposure, sRGB or linear, false
//! colour of luminance) and, for polarized renders, shows S0, the AoLP/DoLP
//! view of `--stokes-view` ([`crate::film::stokes`]) or one of S1–S3.

mod server;

pub use server::Preview;

use crate::film::Image;
use crate::render::PassReport;

/// The port `--preview` uses when none is given.
pub const DEFAULT_PORT: u16 = 8730;

/// The number of passes a preview renders an `spp`-sample image in when the
/// user asks for none: doubling sample counts from 1 spp (1, 2, 4, …, spp),
/// at most 16 passes.
pub fn default_passes(spp: u32) -> u32 {
    (spp.max(1).ilog2() + 1).min(16)
}

/// Magic bytes that open an encoded frame.
pub const FRAME_MAGIC: &[u8; 4] = b"SNPV";
/// Bytes of the frame header: magic, then seven little-endian u32
/// (version, width, height, layers, pass, passes, spp done).
pub const FRAME_HEADER: usize = 32;

/// The names of the layers a frame of `image` carries: `S0` (the image),
/// then `S1`–`S3` when the image has them (polarized renders).
pub fn frame_layers(image: &Image) -> Vec<&'static str> {
    let stokes = ["S1", "S2", "S3"].iter().all(|n| image.layer(n).is_some());
    if stokes { vec!["S0", "S1", "S2", "S3"] } else { vec!["S0"] }
}

/// Encodes a pass for the page: a [`FRAME_HEADER`]-byte header (see
/// [`FRAME_MAGIC`]) then, layer after layer ([`frame_layers`]), the linear
/// RGB of every pixel (row-major, top row first) as little-endian f32.
pub fn encode_frame(report: &PassReport) -> Vec<u8> {
    encode_image(report.image, report.pass, report.passes, report.spp_done)
}

/// [`encode_frame`] of `image`, pass `pass` of `passes`, `spp_done` samples
/// per pixel (for images that no [`PassReport`] carries: a distributed
/// render's).
pub fn encode_image(image: &Image, pass: u32, passes: u32, spp_done: u32) -> Vec<u8> {
    let layers: Vec<&[crate::spectrum::Rgb]> = frame_layers(image)
        .iter()
        .map(|&n| if n == "S0" { image.pixels.as_slice() } else { image.layer(n).map_or(&[][..], |l| l.pixels.as_slice()) })
        .collect();
    let n = image.pixels.len();
    let mut out = Vec::with_capacity(FRAME_HEADER + layers.len() * n * 12);
    out.extend_from_slice(FRAME_MAGIC);
    for v in [1, image.width, image.height, layers.len() as u32, pass, passes, spp_done] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for pixels in layers {
        for p in pixels {
            for c in 0..3 {
                // The film never holds NaN/Inf; zero them anyway so the page needs no checks.
                let v = if p[c].is_finite() { p[c] } else { 0.0 };
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_passes_start_at_one_sample() {
        assert_eq!(default_passes(0), 1);
        assert_eq!(default_passes(1), 1);
        assert_eq!(default_passes(4), 3);
        assert_eq!(default_passes(256), 9);
        assert_eq!(default_passes(1000), 10);
        assert_eq!(default_passes(1 << 24), 16);
        for spp in [3, 16, 100, 4096] {
            assert_eq!(crate::render::pass_schedule(spp, default_passes(spp))[0], 1, "{spp}");
        }
    }
}

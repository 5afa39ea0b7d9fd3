//! Resource limits that keep a hostile or broken input from exhausting the
//! stack, the memory or the time of a run. Each has a default that real
//! scenes stay far below, and can be raised (or lowered) through an
//! environment variable, or for some through a command-line flag:
//!
//! | limit | default | environment variable | flag |
//! |---|---|---|---|
//! | XML nesting depth (elements inside elements) | 64 | `SNELL_MAX_XML_DEPTH` | — |
//! | included files in all (each `<include>` counts) | 1 000 | `SNELL_MAX_INCLUDES` | — |
//! | XML elements in all, includes expanded | 10 000 000 | `SNELL_MAX_XML_NODES` | — |
//! | pixels of one texture image (read from its header before decoding) | 268 435 456 (2²⁸, 16 384²) | `SNELL_MAX_IMAGE_PIXELS` | `--max-image-pixels` |
//! | memory of the film while rendering (estimate) | 8 GiB | `SNELL_MAX_FILM_BYTES` | `--max-film-mb` |
//!
//! The XML depth cannot be raised past [`XML_DEPTH_CEILING`]: the reader is
//! recursive, and deeper documents would overflow the stack.

use std::sync::atomic::{AtomicU64, Ordering};

/// Hard ceiling on the XML nesting depth, whatever the environment says.
pub const XML_DEPTH_CEILING: u64 = 1000;

const UNSET: u64 = u64::MAX;

struct Limit {
    value: AtomicU64,
    env: &'static str,
    default: u64,
}

impl Limit {
    const fn new(env: &'static str, default: u64) -> Limit {
        Limit { value: AtomicU64::new(UNSET), env, default }
    }

    fn get(&self) -> u64 {
        let v = self.value.load(Ordering::Relaxed);
        if v != UNSET {
            return v;
        }
        let v = std::env::var(self.env).ok().and_then(|s| parse_count(&s)).unwrap_or(self.default);
        self.value.store(v, Ordering::Relaxed);
        v
    }

    fn set(&self, v: u64) {
        self.value.store(v.min(UNSET - 1), Ordering::Relaxed);
    }
}

/// A count such as `1000`, `1e6` or `16384*16384` (a product of factors).
pub fn parse_count(s: &str) -> Option<u64> {
    let mut product: u64 = 1;
    for factor in s.split(['*', 'x', '×']) {
        let f = factor.trim();
        let v = match f.parse::<u64>() {
            Ok(v) => v,
            Err(_) => {
                let x = f.parse::<f64>().ok()?;
                if !(x.is_finite() && x >= 0.0 && x < 1.8e19) {
                    return None;
                }
                x.round() as u64
            }
        };
        product = product.checked_mul(v)?;
    }
    Some(product)
}

static XML_DEPTH: Limit = Limit::new("SNELL_MAX_XML_DEPTH", 64);
static INCLUDES: Limit = Limit::new("SNELL_MAX_INCLUDES", 1000);
static XML_NODES: Limit = Limit::new("SNELL_MAX_XML_NODES", 10_000_000);
static IMAGE_PIXELS: Limit = Limit::new("SNELL_MAX_IMAGE_PIXELS", 1 << 28);
static FILM_BYTES: Limit = Limit::new("SNELL_MAX_FILM_BYTES", 8 << 30);

pub fn max_xml_depth() -> u64 {
    XML_DEPTH.get().min(XML_DEPTH_CEILING)
}

pub fn max_includes() -> u64 {
    INCLUDES.get()
}

pub fn max_xml_nodes() -> u64 {
    XML_NODES.get()
}

pub fn max_image_pixels() -> u64 {
    IMAGE_PIXELS.get()
}

pub fn set_max_image_pixels(n: u64) {
    IMAGE_PIXELS.set(n)
}

pub fn max_film_bytes() -> u64 {
    FILM_BYTES.get()
}

pub fn set_max_film_bytes(n: u64) {
    FILM_BYTES.set(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_parse_as_products_and_floats() {
        assert_eq!(parse_count("1000"), Some(1000));
        assert_eq!(parse_count("1e6"), Some(1_000_000));
        assert_eq!(parse_count("16384*16384"), Some(1 << 28));
        assert_eq!(parse_count("100x200"), Some(20_000));
        assert_eq!(parse_count("-3"), None);
        assert_eq!(parse_count("abc"), None);
        assert_eq!(parse_count("99999999999*99999999999"), None);
    }
}

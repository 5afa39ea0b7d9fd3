//! A false-colour picture of linear polarization, from the Stokes layers of
//! a polarized render: the view polarization cameras show.
//!
//! Each pixel's hue is the angle of linear polarization (AoLP, measured
//! from the image's horizontal, counter-clockwise as seen by the camera:
//! 0° red, 45° yellow-green, 90° cyan, 135° violet; the hue turns twice as
//! fast as the angle since AoLP is defined modulo 180°), and its brightness
//! the degree of linear polarization DoLP = √(S1² + S2²)/S0: unpolarized
//! light is black, fully linearly polarized light fully bright. Both are
//! computed from the luminance of S0, S1, S2.

use super::Image;
use crate::spectrum::Rgb;
use crate::texture::bitmap::srgb_to_linear;

/// Below this S0 luminance a pixel counts as black: no polarization to show
/// (and noise would dominate the ratio).
const DARK: f32 = 1e-4;

fn luminance(c: Rgb) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// DoLP in [0, 1] and AoLP in [0°, 180°) of Stokes luminances s0, s1, s2.
pub fn linear_polarization(s0: f32, s1: f32, s2: f32) -> (f32, f32) {
    if !(s0 > DARK) {
        return (0.0, 0.0);
    }
    let dolp = ((s1 * s1 + s2 * s2).sqrt() / s0).clamp(0.0, 1.0);
    let aolp = (0.5 * s2.atan2(s1).to_degrees()).rem_euclid(180.0);
    (if dolp.is_finite() { dolp } else { 0.0 }, if aolp.is_finite() { aolp } else { 0.0 })
}

/// The display colour (sRGB-encoded, in [0,1]) of hue `h` degrees,
/// saturation 1 and value `v`.
fn hsv(h: f32, v: f32) -> [f32; 3] {
    let h6 = (h / 60.0).rem_euclid(6.0);
    let x = 1.0 - (h6 % 2.0 - 1.0).abs();
    let (r, g, b) = match h6 as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    [r * v, g * v, b * v]
}

/// The AoLP/DoLP picture of a render with layers `S1` and `S2` (as linear
/// RGB, so that writing it as PNG gives the display colours), or `None` if
/// the image has no Stokes layers.
pub fn stokes_view(image: &Image) -> Option<Image> {
    let (s1, s2) = (image.layer("S1")?, image.layer("S2")?);
    let pixels = image
        .pixels
        .iter()
        .zip(&s1.pixels)
        .zip(&s2.pixels)
        .map(|((&s0, &s1), &s2)| {
            let (dolp, aolp) = linear_polarization(luminance(s0), luminance(s1), luminance(s2));
            let c = hsv(2.0 * aolp, dolp);
            Rgb::new(srgb_to_linear(c[0]), srgb_to_linear(c[1]), srgb_to_linear(c[2]))
        })
        .collect();
    Some(Image::new(image.width, image.height, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::Layer;

    #[test]
    fn angle_and_degree_of_linear_polarization() {
        // Horizontal, vertical and ±45° fully polarized light, and half-polarized.
        let cases = [((1.0, 1.0, 0.0), (1.0, 0.0)), ((1.0, -1.0, 0.0), (1.0, 90.0)), ((2.0, 0.0, 2.0), (1.0, 45.0)), ((1.0, 0.0, -1.0), (1.0, 135.0)), ((2.0, 0.6, 0.8), (0.5, 26.565))];
        for ((s0, s1, s2), (dolp, aolp)) in cases {
            let (d, a) = linear_polarization(s0, s1, s2);
            assert!((d - dolp).abs() < 1e-5 && (a - aolp).abs() < 1e-3, "{s0} {s1} {s2}: {d} {a}");
        }
        assert_eq!(linear_polarization(0.0, 0.0, 0.0), (0.0, 0.0));
        assert_eq!(linear_polarization(1.0, f32::NAN, 0.0).0, 0.0);
    }

    fn grey(v: f32) -> Rgb {
        Rgb::new(v, v, v)
    }

    #[test]
    fn view_colours_hue_by_angle_and_brightness_by_degree() {
        let px = |v: f32| vec![grey(v); 3];
        let mut image = Image::new(3, 1, vec![grey(1.0), grey(1.0), grey(0.0)]);
        // Pixel 0: horizontal, fully polarized; 1: vertical, half; 2: dark.
        image.layers.push(Layer { name: "S1".into(), pixels: vec![grey(1.0), grey(-0.5), grey(0.0)] });
        image.layers.push(Layer { name: "S2".into(), pixels: px(0.0) });
        let view = stokes_view(&image).expect("has Stokes layers");
        let red = view.pixels[0];
        assert!((red[0] - 1.0).abs() < 1e-5 && red[1].abs() < 1e-6 && red[2].abs() < 1e-6, "{red:?}");
        let cyan = view.pixels[1];
        assert!(cyan[0].abs() < 1e-6 && (cyan[1] - srgb_to_linear(0.5)).abs() < 1e-5 && (cyan[1] - cyan[2]).abs() < 1e-6, "{cyan:?}");
        assert_eq!(view.pixels[2], Rgb::BLACK);
        assert!(stokes_view(&Image::new(1, 1, vec![Rgb::WHITE])).is_none());
    }
}

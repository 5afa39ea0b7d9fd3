//! Spectral mode (`--mode spectral`): paths carry four sampled wavelengths.
//!
//! - Furnace: dispersive glass (BK7, diamond, water by their Sellmeier
//!   formulas, and an air bubble in dispersive water) in a white constant
//!   environment renders the environment's white everywhere: dispersion
//!   moves light between directions and wavelengths, never creates or
//!   destroys it (this also checks that cutting a path to its hero
//!   wavelength at a dispersive interface stays unbiased).
//! - Against Mitsuba 3.9.1's spectral variant (references in
//!   tests/references/spectral/, made by tools/make_references.py with
//!   `--variant llvm_ad_spectral`): the Cornell box and the caustic box.

mod common;
use common::*;
use snell::film::output::read_exr;
use snell::film::Image;
use snell::spectrum::cie::{cie_xyz, d65_unit, xyz_to_linear_srgb, y_normalization};
use snell::spectrum::{Rgb, Sampled};
use std::path::Path;

/// What a white (RGB 1) emitter looks like through the spectral film: D65
/// of unit luminance in sRGB, (1, 1, 1) up to the tables' rounding.
fn spectral_white() -> Rgb {
    let mut xyz = [0.0f64; 3];
    for i in 0..=4700 {
        let l = 360.0 + i as f32 * 0.1;
        let w = if i == 0 || i == 4700 { 0.05 } else { 0.1 };
        let c = cie_xyz(l);
        for k in 0..3 {
            xyz[k] += (w * d65_unit(l) * c[k] * y_normalization()) as f64;
        }
    }
    xyz_to_linear_srgb(xyz.map(|v| v as f32))
}

#[test]
fn dispersive_glass_furnace_is_white() {
    let text = furnace(
        r#"<shape type="sphere"><point name="center" x="-1.1" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><string name="int_ior" value="sellmeier:bk7"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><string name="int_ior" value="sellmeier:diamond"/><float name="ext_ior" value="1"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="1.1" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.0"/><string name="ext_ior" value="sellmeier:water"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0" y="0.9" z="-0.5"/><float name="radius" value="0.4"/>
            <bsdf type="dielectric"><string name="int_ior" value="sellmeier(1.73759695, 0.313747346, 1.89878101; 0.013188707, 0.0623068142, 155.23629)"/></bsdf></shape>"#,
        64,
        48,
    );
    let white = spectral_white();
    for c in white.0 {
        assert!((c - 1.0).abs() < 3e-3, "spectral white {white:?}");
    }
    let expected = Image { width: 64, height: 48, pixels: vec![white; 64 * 48] };
    let passes = render_passes_as::<Sampled>(Path::new("dispersive-furnace.xml"), Some(&text), Default::default(), 16, 16);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("dispersive glass furnace", 0.005);
}

fn check_against_mitsuba_spectral(scene: &str, reference: &str, spp: u32) {
    let reference = read_exr(&repo(reference)).expect("reference EXR");
    let passes = render_passes_as::<Sampled>(&repo(scene), None, params(&[("res", "64")]), 16, spp);
    // The references' own relative error per pixel is ≈ 0.3 % of the image mean.
    compare(&passes, &reference, 16, 0.004).assert_unbiased(scene, 0.01);
}

#[test]
fn cornell_box_matches_mitsuba_spectral() {
    check_against_mitsuba_spectral("scenes/cornell-box.xml", "tests/references/spectral/cornell-box.exr", 32);
}

#[test]
fn caustic_box_matches_mitsuba_spectral() {
    check_against_mitsuba_spectral("scenes/caustic-cornell-box.xml", "tests/references/spectral/caustic-cornell-box.exr", 64);
}

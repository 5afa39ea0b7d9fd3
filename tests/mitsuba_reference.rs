//! Snell against Mitsuba 3.9.1: the same XML files rendered by both. The
//! references (tests/references/*.exr, 65 536 spp or more, made by
//! tools/make_references.py) are committed, so this test does not need
//! Mitsuba. Snell renders 16 passes × 16 spp (more for caustics); the image
//! means must agree within 1 % per channel and every 16×16 block within its
//! noise.

use crate::common::*;
use snell::film::output::read_exr;

fn check(scene: &str, reference: &str) {
    check_spp(scene, reference, 16);
}

/// As `check`, with `spp` samples per pass (scenes with caustics need more
/// per pass for each pass's block means to be near-normal).
fn check_spp(scene: &str, reference: &str, spp: u32) {
    let reference = read_exr(&repo(reference)).expect("reference EXR");
    let passes = render_passes(&repo(scene), None, params(&[("res", "128")]), 16, spp);
    // The references' own relative error per pixel is ≈ 0.2 % of the image mean.
    compare(&passes, &reference, 16, 0.003).assert_unbiased(scene, 0.01);
}

#[test]
fn cornell_box() {
    check("scenes/cornell-box.xml", "tests/references/cornell-box.exr");
}

#[test]
fn spheres_direct() {
    check("tests/scenes/spheres-direct.xml", "tests/references/spheres-direct.exr");
}

#[test]
fn mesh_env() {
    check("tests/scenes/mesh-env.xml", "tests/references/mesh-env.exr");
}

#[test]
fn ortho_rect_light() {
    check("tests/scenes/ortho-rect-light.xml", "tests/references/ortho-rect-light.exr");
}

// Issue 3: specular materials (conductor, dielectric, thindielectric, plastic).

#[test]
fn cornell_glass_gold() {
    check_spp("tests/scenes/cornell-glass-gold.xml", "tests/references/cornell-glass-gold.exr", 32);
}

#[test]
fn caustics() {
    check_spp("tests/scenes/caustics.xml", "tests/references/caustics.exr", 64);
}

#[test]
fn thin_pane() {
    check("tests/scenes/thin-pane.xml", "tests/references/thin-pane.exr");
}

#[test]
fn plastic() {
    check("tests/scenes/plastic.xml", "tests/references/plastic.exr");
}

// Issue 12: rough surfaces (roughconductor, roughdielectric, roughplastic).

#[test]
fn rough_metals() {
    check("tests/scenes/rough-metals.xml", "tests/references/rough-metals.exr");
}

#[test]
fn rough_glass() {
    check_spp("tests/scenes/rough-glass.xml", "tests/references/rough-glass.exr", 32);
}

#[test]
fn rough_plastic() {
    check("tests/scenes/rough-plastic.xml", "tests/references/rough-plastic.exr");
}

// Issue 12: Mitsuba's principled BSDFs over their parameter ranges (sheen,
// flatness, anisotropic metal, transmission, clearcoat, textured roughness
// and spec_trans).

#[test]
fn principled() {
    check("tests/scenes/principled.xml", "tests/references/principled.exr");
}

#[test]
fn principledthin() {
    check("tests/scenes/principledthin.xml", "tests/references/principledthin.exr");
}

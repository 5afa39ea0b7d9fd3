//! Snell against Mitsuba 3.9.1: the same XML files rendered by both. The
//! references (tests/references/*.exr, 65 536 spp, made by
//! tools/make_references.py) are committed, so this test does not need
//! Mitsuba. Snell renders 16 passes × 16 spp; the image means must agree
//! within 1 % per channel and every 16×16 block within its noise.

mod common;
use common::*;
use snell::film::output::read_exr;

fn check(scene: &str, reference: &str) {
    let reference = read_exr(&repo(reference)).expect("reference EXR");
    let passes = render_passes(&repo(scene), None, params(&[("res", "128")]), 16, 16);
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

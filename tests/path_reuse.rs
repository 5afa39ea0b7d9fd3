//! `path` with path reuse across neighbouring pixels (`reuse_pixels`;
//! src/integrator/path_reuse.rs): the same expected image as the plain
//! estimator (and as Mitsuba's), much less indirect noise per camera ray,
//! and images bit-identical across thread counts and pass splits.

use crate::common::*;
use snell::spectrum::Rgb;
use snell::{RenderOptions, Scene};

fn reuse(n: u32) -> String {
    format!(r#"<integer name="reuse_pixels" value="{n}"/>"#)
}

/// The Cornell box with groups of four against Mitsuba's reference (as
/// tests/mitsuba_reference.rs).
#[test]
fn cornell_box_reuse_matches_mitsuba() {
    let scene = repo("scenes/cornell-box.xml");
    let reference = snell::film::output::read_exr(&repo("tests/references/cornell-box.exr")).expect("reference EXR");
    let passes = render_passes(&scene, Some(&with_path_props(&scene, &reuse(4))), params(&[("res", "128")]), 16, 16);
    compare(&passes, &reference, 16, 0.003).assert_unbiased("cornell box, reuse_pixels 4", 0.01);
}

/// Glass and gold among diffuse walls: first vertices that are not
/// techniques (delta BSDFs) and second vertices that cannot be shared mix
/// with the others; the image is the plain estimator's.
#[test]
fn reuse_with_glass_and_metal_agrees_with_plain_path() {
    let scene = repo("tests/scenes/cornell-glass-gold.xml");
    let p = params(&[("res", "64")]);
    let plain = render_passes(&scene, None, p.clone(), 16, 16);
    let reused = render_passes(&scene, Some(&with_path_props(&scene, &reuse(5))), p, 16, 16);
    assert_agree("cornell glass gold: reuse_pixels 5 vs plain", &reused, &plain, 8, 0.02);
}

/// The relMSE of the same number of camera rays, against a long plain
/// render, with groups of `n`.
fn relmse_with(n: Option<u32>) -> f64 {
    let scene = repo("scenes/cornell-box.xml");
    let p = params(&[("res", "64")]);
    let reference = average(&render_passes(&scene, None, p.clone(), 8, 256));
    let text = n.map(|n| with_path_props(&scene, &reuse(n)));
    relmse_sum(&render_passes(&scene, text.as_deref(), p, 4, 8), &reference)
}

/// Reuse cuts the indirect noise per camera ray: on the Cornell box (most
/// of whose error is indirect light), groups of sixteen bring the relMSE
/// of the same camera rays far below the plain estimator's (0.30x at 64²,
/// 8 spp, measured with the command line against a 4096-spp render).
#[test]
fn reuse_cuts_the_noise_per_camera_ray() {
    let (plain, sixteen) = (relmse_with(None), relmse_with(Some(16)));
    eprintln!("relMSE sum: plain {plain:.4e}, reuse_pixels 16 {sixteen:.4e} ({:.2}x)", sixteen / plain);
    assert!(sixteen < 0.45 * plain, "reuse_pixels 16: relMSE {sixteen:.3e} not well below the plain {plain:.3e}");
}

/// The groups depend on the sample index and the pixel only: the image is
/// the same, bit for bit, for any thread count and pass split; and reuse
/// changed it (it is not silently off).
#[test]
fn reuse_is_exact_across_threads_and_passes() {
    let path = repo("scenes/cornell-box.xml");
    let text = with_path_props(&path, &reuse(3)).replace(r#"<sampler type="independent""#, r#"<sampler type="zsobol""#);
    let p = params(&[("res", "40"), ("spp", "8")]);
    let want = assert_exact_across_threads_and_passes(&path, &text, p.clone());
    let plain: Scene = snell::load_str(&path, &text.replace(&reuse(3), ""), &snell::LoadOptions { params: p, ..Default::default() }).unwrap_or_else(|e| panic!("{e}"));
    let opts = RenderOptions { threads: 1, passes: 1, ..RenderOptions::default() };
    assert!(pixel_bits(&snell::render::render_passes::<Rgb>(&plain, &opts, &mut |_| {}).expect("render").0) != want);
}

/// The parameter is checked like the others.
#[test]
fn reuse_pixels_out_of_range_is_a_located_error() {
    let path = repo("scenes/cornell-box.xml");
    for bad in ["0", "65", "-2"] {
        let err = snell::load_str(&path, &with_path_props(&path, &format!(r#"<integer name="reuse_pixels" value="{bad}"/>"#)), &Default::default()).err().expect("an error");
        let msg = err.to_string();
        assert!(msg.contains("reuse_pixels") && msg.contains("cornell-box.xml:9:"), "{msg}");
    }
}

//! Sensors and reconstruction filters against Mitsuba 3.9.1: the thin-lens
//! camera (depth of field), the perspective camera's default focal length
//! (50 mm) with a shifted principal point, and the Lanczos filter (negative
//! lobes). The references (tests/references/thinlens.exr and
//! focal-lanczos.exr, 64×48, 65 536 spp, tools/make_references.py) are
//! committed; Snell renders 16 passes × 16 spp and must agree within 1 % in
//! the image means and within noise in every 8×8 block.

use crate::common::*;
use snell::LoadOptions;
use snell::film::output::read_exr;
use snell::sensor::Camera;

fn check(scene: &str, reference: &str) {
    let reference = read_exr(&repo(reference)).expect("reference EXR");
    let passes = render_passes(&repo(scene), None, params(&[]), 16, 16);
    compare(&passes, &reference, 8, 0.003).assert_unbiased(scene, 0.01);
}

#[test]
fn thin_lens_depth_of_field_matches_mitsuba() {
    check("tests/scenes/thinlens.xml", "tests/references/thinlens.exr");
}

#[test]
fn default_focal_length_principal_point_and_lanczos_match_mitsuba() {
    check("tests/scenes/focal-lanczos.xml", "tests/references/focal-lanczos.exr");
}

/// tan(fov_x / 2) of the scene's camera.
fn tan_half_x(text: &str) -> f32 {
    let path = repo("tests/scenes/focal.xml");
    let scene = snell::load_str(&path, text, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    match scene.camera {
        Camera::Perspective(c) => c.tan_half_x,
        Camera::ThinLens(c) => c.tan_half_x,
        Camera::Orthographic(_) => panic!("not a perspective camera"),
    }
}

fn camera_scene(kind: &str, params: &str, width: u32, height: u32) -> String {
    format!(
        r#"<scene version="3.0.0">
    <sensor type="{kind}">
        {params}
        <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/></film>
    </sensor>
</scene>"#
    )
}

#[test]
fn focal_length_gives_mitsubas_field_of_view() {
    // Mitsuba 3.9.1's x_fov (mi.traverse(sensor)["x_fov"]) for these films:
    // the default "50mm" on 64×48 and 48×64, "28mm" on 100×100 and "85mm" on
    // a thin lens 300×200 (its diagonal fov turned into the horizontal one).
    for (kind, params, (w, h), mitsuba_x_fov) in [
        ("perspective", "", (64, 48), 38.184_841f32),
        ("perspective", "", (48, 64), 29.105_461),
        ("perspective", r#"<string name="focal_length" value="28mm"/>"#, (100, 100), 57.297_634),
        ("thinlens", r#"<string name="focal_length" value="85mm"/><float name="aperture_radius" value="0.1"/>"#, (300, 200), 23.913_168),
    ] {
        let t = tan_half_x(&camera_scene(kind, params, w, h));
        let expected = (mitsuba_x_fov.to_radians() * 0.5).tan();
        assert!((t - expected).abs() < 2e-5 * expected, "{kind} {params} {w}x{h}: tan {t} vs Mitsuba {expected}");
    }
}

#[test]
fn bad_focal_lengths_and_thin_lens_parameters_are_located_errors() {
    let path = repo("tests/scenes/focal.xml");
    for (params, message) in [
        (r#"<string name="focal_length" value="fifty"/>"#, "focal length \"fifty\""),
        (r#"<string name="focal_length" value="0mm"/>"#, "focal length \"0mm\""),
        (r#"<float name="fov" value="40"/><string name="focal_length" value="50mm"/>"#, "not both"),
    ] {
        let e = match snell::load_str(&path, &camera_scene("perspective", params, 8, 8), &LoadOptions::default()) {
            Ok(_) => panic!("{params} should fail"),
            Err(e) => e,
        };
        assert!(e.message.contains(message), "{e}");
        assert_eq!(e.location.as_ref().map(|l| l.line), Some(3), "{e}");
    }
    // A thin lens needs its aperture radius.
    let e = match snell::load_str(&path, &camera_scene("thinlens", "", 8, 8), &LoadOptions::default()) {
        Ok(_) => panic!("thinlens without aperture_radius should fail"),
        Err(e) => e,
    };
    assert!(e.message.contains("aperture_radius"), "{e}");
}

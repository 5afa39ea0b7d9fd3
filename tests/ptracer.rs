//! Particle tracing (`ptracer`): light paths splatted onto the film must give
//! the same image as camera paths, in expectation.

use crate::common::*;

/// The Cornell box with its integrator swapped for `ptracer`, against
/// Mitsuba's path-traced reference: the same expected image, reached from
/// the other end (including the light seen directly).
#[test]
fn cornell_box_ptracer_matches_mitsuba() {
    let path = repo("scenes/cornell-box.xml");
    let text = std::fs::read_to_string(&path).expect("scene");
    assert!(text.contains(r#"<integrator type="path">"#));
    let text = text.replace(r#"<integrator type="path">"#, r#"<integrator type="ptracer">"#);
    let reference = snell::film::output::read_exr(&repo("tests/references/cornell-box.exr")).expect("reference");
    let passes = render_passes(&path, Some(&text), params(&[("res", "128")]), 16, 16);
    compare(&passes, &reference, 8, 1.2e-3).assert_unbiased("cornell-box ptracer", 0.01);
}

/// `ptracer` with an orthographic camera is a located error, not a black
/// image; emitters at infinity are accepted (their light paths start on
/// the disk of the scene's bounding sphere).
#[test]
fn ptracer_refuses_what_it_cannot_connect() {
    let scene = |sensor: &str, emitter: &str| {
        let fov = if sensor == "perspective" { r#"<float name="fov" value="40"/>"# } else { "" };
        format!(
            r#"<scene version="3.0.0">
    <integrator type="ptracer"/>
    <sensor type="{sensor}">{fov}</sensor>
    {emitter}
    <shape type="sphere"/>
</scene>"#
        )
    };
    let options = snell::LoadOptions::default();
    let err = snell::load_str(std::path::Path::new("ortho.xml"), &scene("orthographic", r#"<emitter type="point"><rgb name="intensity" value="1"/></emitter>"#), &options)
        .err()
        .expect("orthographic + ptracer must fail")
        .to_string();
    assert!(err.contains("ortho.xml:2:5") && err.contains("perspective"), "{err}");
    for emitter in [r#"<emitter type="constant"/>"#, r#"<emitter type="directional"><vector name="direction" x="0" y="-1" z="0"/><rgb name="irradiance" value="1"/></emitter>"#] {
        snell::load_str(std::path::Path::new("env.xml"), &scene("perspective", emitter), &options).unwrap_or_else(|e| panic!("{emitter}: {e}"));
    }
}


/// Light paths from infinity: tests/scenes/sky-sun-glass.xml with its glass
/// sphere made diffuse (a light path cannot reach the camera through a
/// delta surface), lit by its constant sky alone (seen directly too) and by
/// its directional sun alone, agrees with `path`.
#[test]
fn sky_and_sun_ptracer_match_path() {
    let scene = "tests/scenes/sky-sun-glass.xml";
    let text = std::fs::read_to_string(repo(scene)).expect("scene");
    let diffuse = text.replace(r#"<bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf>"#, r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>"#);
    assert_ne!(diffuse, text);
    let ptracer = diffuse.replace(r#"<integrator type="path">"#, r#"<integrator type="ptracer">"#);
    for (name, light) in [("sky", [("sun", "0")]), ("sun", [("sky", "0")])] {
        let list = params(&[("res", "64"), light[0]]);
        let a = render_passes(&repo(scene), Some(&ptracer), list.clone(), 16, 4);
        let b = render_passes(&repo(scene), Some(&diffuse), list, 16, 4);
        assert_agree(&format!("{name} ptracer vs path"), &a, &b, 16, 0.02);
    }
}

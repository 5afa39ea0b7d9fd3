//! Particle tracing (`ptracer`): light paths splatted onto the film must give
//! the same image as camera paths, in expectation.

mod common;
use common::*;

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

/// `ptracer` with an orthographic camera or an environment light is a
/// located error, not a black image.
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
    let err = snell::load_str(std::path::Path::new("env.xml"), &scene("perspective", r#"<emitter type="constant"/>"#), &options)
        .err()
        .expect("constant + ptracer must fail")
        .to_string();
    assert!(err.contains("env.xml:2:5") && err.contains("spot"), "{err}");
}

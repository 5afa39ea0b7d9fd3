//! Emitters against Mitsuba 3.9.1 and closed forms:
//!
//! - `envmap`: diffuse, mirror and glass spheres under a 64×32 EXR
//!   environment map (turned by `to_world`, scaled), path traced, against
//!   Mitsuba's render in RGB and in spectral mode (references in
//!   tests/references/ and tests/references/spectral/, made by
//!   tools/make_references.py); the sampling density's integral and χ² test
//!   are unit tests in src/emitter/envmap.rs;
//! - textured emitters (a `spot` with a `texture`, a `projector`, an `area`
//!   light with a checkerboard `radiance`) against Mitsuba's render, by
//!   camera paths (`direct`) and by light paths (`ptracer`);
//! - `projector`: the uniform irradiance π·scale·E/h² it gives a facing plane;
//! - a missing env map is a located error naming the file.

use crate::common::*;
use snell::film::output::read_exr;
use snell::spectrum::{Polarized, Rgb, Sampled};
use std::path::Path;

#[test]
fn envmap_spheres_match_mitsuba() {
    let reference = read_exr(&repo("tests/references/envmap-spheres.exr")).expect("reference EXR");
    let passes = render_passes(&repo("tests/scenes/envmap-spheres.xml"), None, params(&[("res", "128")]), 16, 16);
    compare(&passes, &reference, 16, 0.002).assert_unbiased("envmap-spheres", 0.01);
}

#[test]
fn envmap_spheres_match_mitsuba_spectral() {
    let reference = read_exr(&repo("tests/references/spectral/envmap-spheres.exr")).expect("reference EXR");
    let passes = render_passes_as::<Sampled>(&repo("tests/scenes/envmap-spheres.xml"), None, params(&[("res", "128")]), 16, 16);
    compare(&passes, &reference, 16, 0.003).assert_unbiased("envmap-spheres spectral", 0.01);
}

#[test]
fn textured_lights_match_mitsuba() {
    let reference = read_exr(&repo("tests/references/textured-lights.exr")).expect("reference EXR");
    let passes = render_passes(&repo("tests/scenes/textured-lights.xml"), None, params(&[("res", "128")]), 16, 16);
    compare(&passes, &reference, 16, 0.002).assert_unbiased("textured-lights", 0.01);
}

/// The same scene by light paths: `ptracer` with two segments (emitter →
/// surface → camera, and the area light seen directly) has the `direct`
/// integrator's expectation, so it must match the same reference. This
/// checks every textured emitter's `sample_ray`.
#[test]
fn textured_lights_by_light_paths_match_mitsuba() {
    let path = repo("tests/scenes/textured-lights.xml");
    let text = std::fs::read_to_string(&path).expect("scene");
    assert!(text.contains(r#"<integrator type="direct"/>"#));
    let text = text.replace(r#"<integrator type="direct"/>"#, r#"<integrator type="ptracer"><integer name="max_depth" value="2"/></integrator>"#);
    let reference = read_exr(&repo("tests/references/textured-lights.exr")).expect("reference EXR");
    let passes = render_passes(&path, Some(&text), params(&[("res", "128")]), 16, 32);
    compare(&passes, &reference, 16, 0.002).assert_unbiased("textured-lights ptracer", 0.01);
}

/// A projector at distance h from a facing diffuse plane (reflectance ρ),
/// constant irradiance E and scale s: the plane receives π·s·E/h² inside
/// the projected rectangle, so it shows ρ·s·E/h² there (a delta light:
/// every sample gives exactly that) and nothing outside.
#[test]
fn projector_gives_uniform_irradiance_on_a_facing_plane() {
    let (h, rho, s, e) = (2.5f32, 0.6f32, 3.0f32, [0.5f32, 1.0, 2.0]);
    let scene = |camera_fov: f32| {
        format!(
            r#"<scene version="3.0.0">
    <integrator type="direct"/>
    <sensor type="perspective">
        <float name="fov" value="{camera_fov}"/>
        <transform name="to_world"><lookat origin="0, 0, {h}" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="40"/><rfilter type="box"/></film>
    </sensor>
    <emitter type="projector">
        <float name="fov" value="40"/>
        <float name="scale" value="{s}"/>
        <rgb name="irradiance" value="{}, {}, {}"/>
        <transform name="to_world"><lookat origin="0, 0, {h}" target="0, 0, 0" up="0, 1, 0"/></transform>
    </emitter>
    <shape type="rectangle"><transform name="to_world"><scale value="10"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="{rho}"/></bsdf></shape>
</scene>"#,
            e[0], e[1], e[2]
        )
    };
    // Camera inside the projected square: every pixel is lit.
    let img = &render_passes(Path::new("projector.xml"), Some(&scene(30.0)), Default::default(), 1, 4)[0];
    for p in &img.pixels {
        for c in 0..3 {
            let expect = rho * s * e[c] / (h * h);
            assert!((p[c] - expect).abs() < 1e-4 * expect, "pixel {:?} vs {expect}", p);
        }
    }
    // A wider camera: only the square of half-width tan 20° / tan 30° is lit.
    let img = &render_passes(Path::new("projector.xml"), Some(&scene(60.0)), Default::default(), 1, 64)[0];
    let lit: f32 = img.pixels.iter().map(|p| p[1] / (rho * s * e[1] / (h * h))).sum::<f32>() / img.pixels.len() as f32;
    let expect = (20f32.to_radians().tan() / 30f32.to_radians().tan()).powi(2);
    assert!((lit - expect).abs() < 0.01, "lit fraction {lit} vs {expect}");
}

/// Env-map emission is unpolarized: with a diffuse and a mirror sphere
/// (light reaches the camera after at most one specular reflection of
/// unpolarized light), S0 of the polarized modes is the unpolarized image,
/// sample for sample.
#[test]
fn envmap_in_polarized_modes_is_unpolarized_light() {
    let path = repo("tests/scenes/envmap-spheres.xml");
    let text = std::fs::read_to_string(&path).expect("scene");
    let glass = text.find("<shape type=\"sphere\">\n        <point name=\"center\" x=\"1.25\"").expect("the glass sphere");
    let text = format!("{}</scene>\n", &text[..glass]);
    let p = params(&[("res", "32"), ("height", "24")]);
    let worst = |a: &snell::film::Image, b: &snell::film::Image| {
        a.pixels.iter().zip(&b.pixels).flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs() / y[c].abs().max(1e-3))).fold(0.0f32, f32::max)
    };
    let a = average(&render_passes_as::<Polarized<Rgb>>(&path, Some(&text), p.clone(), 1, 8));
    let b = average(&render_passes_as::<Rgb>(&path, Some(&text), p.clone(), 1, 8));
    assert!(mean(&b)[0] > 0.1);
    assert!(worst(&a, &b) < 1e-4, "RGB: largest relative difference {}", worst(&a, &b));
    let a = average(&render_passes_as::<Polarized<Sampled>>(&path, Some(&text), p.clone(), 1, 8));
    let b = average(&render_passes_as::<Sampled>(&path, Some(&text), p, 1, 8));
    assert!(worst(&a, &b) < 1e-4, "spectral: largest relative difference {}", worst(&a, &b));
}

/// A missing env map is an error at the `filename` property naming the file.
#[test]
fn missing_envmap_is_a_located_error() {
    let text = r#"<scene version="3.0.0">
    <emitter type="envmap">
        <string name="filename" value="no-such-sky.exr"/>
    </emitter>
</scene>
"#;
    let dir = std::env::temp_dir().join(format!("snell-emitters-{}", std::process::id()));
    let err = match snell::load_str(&dir.join("sky.xml"), text, &snell::LoadOptions::default()) {
        Ok(_) => panic!("a missing env map must fail"),
        Err(e) => e,
    };
    let shown = err.to_string();
    let loc = err.location.as_ref().expect("a location");
    assert_eq!((loc.line, loc.col), (3, 9), "{shown}");
    assert!(err.message.contains("no-such-sky.exr"), "{shown}");
    // A 1-pixel-high image is refused as Mitsuba refuses it.
    std::fs::create_dir_all(&dir).unwrap();
    let pfm = dir.join("thin.pfm");
    let mut bytes = b"PF\n4 1\n-1.0\n".to_vec();
    bytes.extend(std::iter::repeat_n(1.0f32.to_le_bytes(), 12).flatten());
    std::fs::write(&pfm, bytes).unwrap();
    let err = match snell::load_str(&dir.join("sky.xml"), &text.replace("no-such-sky.exr", "thin.pfm"), &snell::LoadOptions::default()) {
        Ok(_) => panic!("a 4x1 env map must fail"),
        Err(e) => e,
    };
    assert!(err.message.contains("thin.pfm") && err.message.contains("2×3"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

//! Sensors and reconstruction filters against Mitsuba 3.9.1: the thin-lens
//! camera (depth of field), the perspective camera's default focal length
//! (50 mm) with a shifted principal point, and the Lanczos filter (negative
//! lobes). The references (tests/references/thinlens.exr and
//! focal-lanczos.exr, 64×48, 65 536 spp, tools/make_references.py) are
//! committed; Snell renders 16 passes × 16 spp and must agree within 1 % in
//! the image means and within noise in every 8×8 block.
//!
//! The radiance meter against closed forms: the sky's radiance seen
//! directly, and ρ·L off a diffuse plane under a uniform sky. The irradiance
//! meter against closed forms: π·L under an open sky, and the shadow of a
//! sphere, π·L·(1 − R²/d²).

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
        _ => panic!("not a perspective camera"),
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

/// A radiancemeter scene: `sensor` (its placement), a 100 × 100 diffuse
/// plane of reflectance (0.2, 0.5, 0.8) at z = 0 and a sky of radiance
/// (2, 1, 0.5); `film` the film's width and height.
fn meter_scene(sensor: &str, film: (u32, u32)) -> String {
    let (w, h) = film;
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="4"/></integrator>
    <sensor type="radiancemeter">
        {sensor}
        <sampler type="independent"><integer name="sample_count" value="256"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/><rfilter type="box"/></film>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world"><scale value="50"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf>
    </shape>
    <emitter type="constant"><rgb name="radiance" value="2, 1, 0.5"/></emitter>
</scene>"#
    )
}

/// Mean and standard error, per channel, of the passes' single pixel.
fn meter_reading(text: &str, passes: u32, spp: u32) -> ([f64; 3], [f64; 3]) {
    let images = render_passes(&repo("tests/scenes/radiancemeter.xml"), Some(text), params(&[]), passes, spp);
    let n = images.len() as f64;
    let mut mean = [0.0; 3];
    let mut stderr = [0.0; 3];
    for c in 0..3 {
        let v: Vec<f64> = images.iter().map(|img| img.pixels[0][c] as f64).collect();
        mean[c] = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean[c]).powi(2)).sum::<f64>() / (n - 1.0);
        stderr[c] = (var / n).sqrt();
    }
    (mean, stderr)
}

#[test]
fn radiancemeter_reads_the_sky_and_a_lit_diffuse_plane() {
    // Looking up: every sample is the sky's radiance, exactly.
    let up = meter_scene(r#"<point name="origin" x="0" y="0" z="1"/><vector name="direction" x="0" y="0.2" z="1"/>"#, (1, 1));
    let (mean, stderr) = meter_reading(&up, 4, 16);
    for (c, want) in [2.0, 1.0, 0.5].into_iter().enumerate() {
        assert!((mean[c] - want).abs() < 1e-6 && stderr[c] < 1e-7, "sky channel {c}: {} ± {}", mean[c], stderr[c]);
    }
    // Looking down at the plane (by origin/direction, and by to_world):
    // irradiance π·L from the sky's upper hemisphere, so radiance ρ·L.
    let want = [0.2 * 2.0, 0.5 * 1.0, 0.8 * 0.5];
    for sensor in [
        r#"<point name="origin" x="0.1" y="0.2" z="1"/><vector name="direction" x="0.3" y="0" z="-1"/>"#,
        r#"<transform name="to_world"><lookat origin="-1, 0.5, 2" target="0.5, 0, 0" up="0, 0, 1"/></transform>"#,
    ] {
        let (mean, stderr) = meter_reading(&meter_scene(sensor, (1, 1)), 16, 256);
        for c in 0..3 {
            // The test must be able to fail: the noise is well below the value.
            assert!(stderr[c] < 0.01 * want[c], "{sensor}: channel {c} too noisy: ± {}", stderr[c]);
            assert!((mean[c] - want[c]).abs() < 4.0 * stderr[c] + 1e-4, "{sensor}: channel {c}: {} ± {} against ρ·L = {}", mean[c], stderr[c], want[c]);
        }
    }
}

/// The error loading `text` (as the file `name`) gives, as text.
#[track_caller]
fn load_error(name: &str, text: &str) -> String {
    match snell::load_str(&repo(name), text, &LoadOptions::default()) {
        Ok(_) => panic!("expected an error:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn radiancemeter_errors_are_located() {
    let path = repo("tests/scenes/radiancemeter.xml");
    let load = |text: &str| load_error("tests/scenes/radiancemeter.xml", text);
    let e = load(&meter_scene("", (2, 3)));
    assert!(e.contains("film must be 1 × 1 pixels, not 2 × 3") && e.contains(":6:"), "{e}");
    let e = load(&meter_scene(r#"<point name="origin" x="0" y="0" z="1"/>"#, (1, 1)));
    assert!(e.contains("needs a direction too") && e.contains(":4:"), "{e}");
    let e = load(&meter_scene(r#"<point name="origin" x="0" y="0" z="1"/><vector name="direction" x="0" y="0" z="0"/>"#, (1, 1)));
    assert!(e.contains("finite, non-zero vector"), "{e}");
    // As Mitsuba, a film one pixel wide (or high) is accepted: each pixel reads the same ray.
    assert!(snell::load_str(&path, &meter_scene("", (1, 4)), &LoadOptions::default()).is_ok());
    // Light paths cannot reach it.
    let e = load(&meter_scene("", (1, 1)).replace(r#"<integrator type="path">"#, r#"<integrator type="ptracer">"#));
    assert!(e.contains("ptracer needs a perspective sensor"), "{e}");
}

/// An irradiance-meter scene: the meter on `meter_shape` (a shape's type
/// and contents), a sky of radiance (2, 1, 0.5) and `others`.
fn irradiance_scene(meter_shape: &str, others: &str) -> String {
    let (kind, inside) = meter_shape.split_once('|').expect("type|contents");
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="4"/></integrator>
    <emitter type="constant"><rgb name="radiance" value="2, 1, 0.5"/></emitter>
    <shape type="{kind}">
        {inside}
        <sensor type="irradiancemeter">
            <sampler type="independent"><integer name="sample_count" value="256"/></sampler>
            <film type="hdrfilm"><integer name="width" value="1"/><integer name="height" value="1"/><rfilter type="box"/></film>
        </sensor>
    </shape>
    {others}
</scene>"#
    )
}

/// The irradiance meter against closed forms. Under an open sky every
/// sample reads π·L exactly, on a rectangle and on a sphere (each point sees
/// its outer hemisphere). A tiny rectangle facing a black sphere of radius
/// R at distance d sees the sky except a cap of solid-angle weight
/// sin²α = R²/d²: E = π·L·(1 − R²/d²).
#[test]
fn irradiancemeter_reads_pi_l_and_the_shadow_of_a_sphere() {
    let pi = std::f64::consts::PI;
    for shape in ["rectangle|<transform name=\"to_world\"><scale value=\"0.5\"/></transform>", "sphere|<float name=\"radius\" value=\"0.3\"/>"] {
        let (mean, stderr) = meter_reading(&irradiance_scene(shape, ""), 4, 16);
        for (c, l) in [2.0, 1.0, 0.5].into_iter().enumerate() {
            assert!((mean[c] - pi * l).abs() < 1e-5 * pi * l && stderr[c] < 1e-5, "{shape}: channel {c}: {} ± {} against πL = {}", mean[c], stderr[c], pi * l);
        }
    }
    let (r, d) = (0.5f64, 1.5f64);
    let occluder = format!(
        r#"<shape type="sphere"><point name="center" x="0" y="0" z="{d}"/><float name="radius" value="{r}"/><bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf></shape>"#
    );
    let text = irradiance_scene("rectangle|<transform name=\"to_world\"><scale value=\"0.001\"/></transform>", &occluder);
    let (mean, stderr) = meter_reading(&text, 16, 1024);
    for (c, l) in [2.0, 1.0, 0.5].into_iter().enumerate() {
        let want = pi * l * (1.0 - r * r / (d * d));
        assert!(stderr[c] < 0.01 * want, "channel {c} too noisy: ± {}", stderr[c]);
        assert!((mean[c] - want).abs() < 4.0 * stderr[c], "channel {c}: {} ± {} against πL(1 − R²/d²) = {want}", mean[c], stderr[c]);
    }
}

#[test]
fn irradiancemeter_errors_are_located() {
    let load = |text: &str| load_error("tests/scenes/irradiancemeter.xml", text);
    let rect = "rectangle|";
    // At the top level, with a to_world, beside a top-level sensor, twice.
    let top = irradiance_scene(rect, "").replace("<shape type=\"rectangle\">", "").replacen("</shape>", "", 1);
    let e = load(&top);
    assert!(e.contains("place it inside a <shape>"), "{e}");
    let e = load(&irradiance_scene(rect, "").replace("<sensor type=\"irradiancemeter\">", "<sensor type=\"irradiancemeter\"><transform name=\"to_world\"><scale value=\"2\"/></transform>"));
    assert!(e.contains("takes no to_world") && e.contains(":6:"), "{e}");
    let e = load(&irradiance_scene(rect, r#"<sensor type="perspective"/>"#));
    assert!(e.contains("more than one <sensor>") && e.contains(":6:"), "{e}");
    let second = r#"<shape type="sphere"><sensor type="irradiancemeter"/></shape>"#;
    let e = load(&irradiance_scene(rect, second));
    assert!(e.contains("more than one irradiancemeter"), "{e}");
    // Another sensor type inside a shape, and a meter in a shapegroup.
    let e = load(&irradiance_scene(rect, "").replace("<sensor type=\"irradiancemeter\">", "<sensor type=\"perspective\">"));
    assert!(e.contains("must be an irradiancemeter, not \"perspective\"") && e.contains(":6:"), "{e}");
    let grouped = irradiance_scene(rect, "").replace("<shape type=\"rectangle\">", "<shape type=\"shapegroup\"><shape type=\"rectangle\">").replacen("</shape>", "</shape></shape>", 1);
    let e = load(&grouped);
    assert!(e.contains("shapegroup cannot carry a sensor"), "{e}");
    // Light paths cannot reach it.
    let e = load(&irradiance_scene(rect, "").replace(r#"<integrator type="path">"#, r#"<integrator type="bdpt">"#));
    assert!(e.contains("bdpt needs a perspective sensor") && e.contains("irradiancemeter"), "{e}");
}

/// A distant-sensor scene: the sensor looking straight down with `target`,
/// over the radiancemeter scene's 100 × 100 diffuse plane (reflectance
/// (0.2, 0.5, 0.8)) under a sky of radiance (2, 1, 0.5).
fn distant_scene(target: &str, film: (u32, u32)) -> String {
    let (w, h) = film;
    meter_scene("", (1, 1)).replace(
        r#"<sensor type="radiancemeter">
        
        <sampler type="independent"><integer name="sample_count" value="256"/></sampler>
        <film type="hdrfilm"><integer name="width" value="1"/><integer name="height" value="1"/><rfilter type="box"/></film>"#,
        &format!(
            r#"<sensor type="distant">
        <vector name="direction" x="0" y="0" z="-1"/>{target}
        <sampler type="independent"><integer name="sample_count" value="256"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/><rfilter type="box"/></film>"#
        ),
    )
}

/// The distant sensor against closed forms. Aimed at a small rectangle or
/// a point on the plane, every ray meets the plane: ρ·L. With no target the
/// rays cross the disk of the scene's bounding sphere (radius a√2 for the
/// plane of half-side a), of which the plane covers 2/π; the others see the
/// sky below: (2/π)·ρ·L + (1 − 2/π)·L.
#[test]
fn distant_sensor_reads_a_lit_plane_and_its_bounding_disk() {
    let (rho, l) = ([0.2, 0.5, 0.8], [2.0, 1.0, 0.5]);
    let frac = 2.0 / std::f64::consts::PI;
    let cases = [
        (r#"<shape type="rectangle" name="target"><transform name="to_world"><scale value="0.5"/></transform></shape>"#, [rho[0] * l[0], rho[1] * l[1], rho[2] * l[2]]),
        (r#"<point name="target" x="0.3" y="-0.2" z="0"/>"#, [rho[0] * l[0], rho[1] * l[1], rho[2] * l[2]]),
        ("", [0, 1, 2].map(|c| frac * rho[c] * l[c] + (1.0 - frac) * l[c])),
    ];
    for (target, want) in cases {
        let text = distant_scene(target, (1, 1));
        assert!(text.contains("type=\"distant\""), "the sensor was replaced");
        let (mean, stderr) = meter_reading(&text, 16, 1024);
        for c in 0..3 {
            assert!(stderr[c] < 0.01 * want[c], "{target}: channel {c} too noisy: ± {}", stderr[c]);
            assert!((mean[c] - want[c]).abs() < 4.0 * stderr[c] + 1e-4, "{target:?}: channel {c}: {} ± {} against {}", mean[c], stderr[c], want[c]);
        }
    }
}

#[test]
fn distant_sensor_errors_are_located() {
    let load = |text: &str| load_error("tests/scenes/distant.xml", text);
    let e = load(&distant_scene("", (1, 4)));
    assert!(e.contains("film must be 1 × 1 pixels, not 1 × 4"), "{e}");
    let e = load(&distant_scene(r#"<transform name="to_world"><scale value="2"/></transform>"#, (1, 1)));
    assert!(e.contains("a direction or a to_world, not both") && e.contains(":4:"), "{e}");
    let e = load(&distant_scene("", (1, 1)).replace(r#"x="0" y="0" z="-1""#, r#"x="0" y="0" z="0""#));
    assert!(e.contains("finite, non-zero vector"), "{e}");
    let e = load(&distant_scene(r#"<bsdf type="diffuse" name="target"/>"#, (1, 1)));
    assert!(e.contains("a point or a <shape>, not a <bsdf>"), "{e}");
    let e = load(&distant_scene(r#"<shape type="sphere" name="target"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#, (1, 1)));
    assert!(e.contains("one plain shape"), "{e}");
}

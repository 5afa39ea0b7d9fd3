//! Participating media under `volpath`: closed forms (Beer–Lambert, a white
//! furnace) and located errors. (Mitsuba's own media test scenes are
//! compared with Mitsuba by `tools/corpus.py`.)

use crate::common::{mean, repo};
use snell::spectrum::Rgb;
use snell::{LoadOptions, RenderOptions};

fn scene(medium: &str, shape: &str, integrator: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
    <integrator type="{integrator}"/>
    <sensor type="orthographic">
        <transform name="to_world"><scale value="0.5"/><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/><rfilter type="box"/></film>
        <sampler type="independent"><integer name="sample_count" value="64"/></sampler>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    {medium}
    <shape type="{shape}"><bsdf type="null"/><ref id="m" name="interior"/></shape>
</scene>"#
    )
}

fn render(text: &str, spp: u32) -> snell::film::Image {
    let options = LoadOptions { params: Default::default(), spp: Some(spp), seed: None };
    let scene = snell::load_str(&repo("tests/scenes/media.xml"), text, &options).unwrap_or_else(|e| panic!("{e}"));
    snell::render::<Rgb>(&scene, &RenderOptions::default()).expect("render").0
}

/// Seen through 2 units of a purely absorbing medium, a uniform sky of
/// radiance 1 has radiance exp(−2σₜ) in each channel (the coloured σₜ
/// makes the tracker take null collisions: ratio tracking in effect).
#[test]
fn an_absorbing_medium_follows_beer_lambert() {
    let sigma = [0.5f64, 1.0, 2.0];
    let medium = r#"<medium id="m" type="homogeneous"><rgb name="sigma_t" value="0.5, 1, 2"/><rgb name="albedo" value="0"/></medium>"#;
    // Each sample's estimate lies in [0, 1] with mean p = exp(−2σ), so its
    // variance is at most p(1 − p): the mean of n samples must fall within
    // four standard errors of it.
    let spp = 1024;
    let within = |m: f64, p: f64, n: f64| (m - p).abs() < 4.0 * (p * (1.0 - p) / n).sqrt();
    let img = render(&scene(medium, "cube", "volpath"), spp);
    let n = (img.width * img.height * spp) as f64;
    let m = mean(&img);
    for c in 0..3 {
        let expected = (-2.0 * sigma[c]).exp();
        assert!(within(m[c], expected, n), "channel {c}: {} against exp(-2σ) = {expected}", m[c]);
    }
    // The same with the medium given as a heterogeneous constvolume box
    // (no extinction outside its box: here the box is the cube).
    let hetero = r#"<medium id="m" type="heterogeneous"><volume name="sigma_t" type="constvolume"><rgb name="value" value="0.5, 1, 2"/>
        <transform name="to_world"><scale value="2"/><translate value="-1, -1, -1"/></transform></volume><rgb name="albedo" value="0"/></medium>"#;
    let m = mean(&render(&scene(hetero, "cube", "volpath"), spp));
    for c in 0..3 {
        let expected = (-2.0 * sigma[c]).exp();
        assert!(within(m[c], expected, n), "heterogeneous, channel {c}: {} against {expected}", m[c]);
    }
    // `path` ignores media (as Mitsuba's does): the sky is seen unattenuated.
    let m = mean(&render(&scene(medium, "cube", "path"), 4));
    assert!(m.iter().all(|v| (v - 1.0).abs() < 1e-4), "{m:?}");
}

/// A white furnace: a non-absorbing medium (albedo 1) lit by a uniform sky
/// of radiance 1 shows radiance 1 everywhere, whatever its density and
/// phase function; no pixel is NaN.
#[test]
fn a_white_medium_in_a_white_furnace_is_invisible() {
    for phase in ["<phase type=\"isotropic\"/>", "<phase type=\"hg\"><float name=\"g\" value=\"0.7\"/></phase>"] {
        let medium = format!(r#"<medium id="m" type="homogeneous"><float name="sigma_t" value="3"/><rgb name="albedo" value="1"/>{phase}</medium>"#);
        let img = render(&scene(&medium, "sphere", "volpath"), 64);
        assert!(img.pixels.iter().all(|p| p.0.iter().all(|v| v.is_finite())));
        let m = mean(&img);
        assert!(m.iter().all(|v| (v - 1.0).abs() < 0.02), "{phase}: mean {m:?}");
    }
}

#[test]
fn medium_errors_are_located_and_list_the_choices() {
    let options = LoadOptions::default();
    let load = |text: &str| snell::load_str(&repo("tests/scenes/media.xml"), text, &options).err().map(|e| e.to_string()).unwrap_or_default();
    let e = load(&scene(r#"<medium id="m" type="fog"/>"#, "sphere", "volpath"));
    assert!(e.contains("fog") && e.contains("homogeneous") && e.contains("heterogeneous"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><phase type="rayleigh"/></medium>"#, "sphere", "volpath"));
    assert!(e.contains("rayleigh") && e.contains("hg"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><volume name="sigma_t" type="gridvolume"><string name="filename" value="missing.vol"/></volume></medium>"#, "sphere", "volpath"));
    assert!(e.contains("missing.vol"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><float name="scale" value="-1"/></medium>"#, "sphere", "volpath"));
    assert!(e.contains("scale") && e.contains("<float name=\"scale\""), "the line is shown: {e}");
}

//! Participating media under `volpath`: closed forms (Beer–Lambert, a white
//! furnace), the phase functions against Mitsuba 3.9.1 (tests/scenes/phases.xml,
//! reference tests/references/phases.exr at 65 536 spp) and located errors.
//! (Mitsuba's own media test scenes are compared with Mitsuba by
//! `tools/corpus.py`.)

use crate::common::{compare, mean, params, render_passes, repo};
use snell::film::output::read_exr;
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

/// Rayleigh, a tabulated lobe and a blend of a backward Henyey–Greenstein
/// lobe with a table, each filling a sphere lit from behind by a spot: the
/// same image as Mitsuba's (means within 1 %, every 8×8 block within noise).
#[test]
fn rayleigh_tabulated_and_blended_phases_match_mitsuba() {
    let reference = read_exr(&repo("tests/references/phases.exr")).expect("reference EXR");
    let passes = render_passes(&repo("tests/scenes/phases.xml"), None, params(&[]), 16, 32);
    // The reference's own error per pixel is ≈ 0.5 % of the image mean.
    compare(&passes, &reference, 8, 0.005).assert_unbiased("tests/scenes/phases.xml", 0.01);
}

#[test]
fn medium_errors_are_located_and_list_the_choices() {
    let options = LoadOptions::default();
    let load = |text: &str| snell::load_str(&repo("tests/scenes/media.xml"), text, &options).err().map(|e| e.to_string()).unwrap_or_default();
    let e = load(&scene(r#"<medium id="m" type="fog"/>"#, "sphere", "volpath"));
    assert!(e.contains("fog") && e.contains("homogeneous") && e.contains("heterogeneous"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><phase type="sggx"/></medium>"#, "sphere", "volpath"));
    assert!(e.contains("sggx") && e.contains("not supported yet"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><phase type="rayleig"/></medium>"#, "sphere", "volpath"));
    assert!(e.contains("rayleig") && e.contains("rayleigh") && e.contains("blendphase"), "{e}");
    // tabphase: a value that is not a number, too few values, a negative one.
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><phase type="tabphase"><string name="values" value="1, x, 2"/></phase></medium>"#, "sphere", "volpath"));
    assert!(e.contains("\"x\"") && e.contains("<string name=\"values\""), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><phase type="tabphase"><string name="values" value="1"/></phase></medium>"#, "sphere", "volpath"));
    assert!(e.contains("at least two"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><phase type="tabphase"><string name="values" value="1, -2"/></phase></medium>"#, "sphere", "volpath"));
    assert!(e.contains("not negative"), "{e}");
    // blendphase: no weight, one nested phase only.
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><phase type="blendphase"><phase type="isotropic"/><phase type="rayleigh"/></phase></medium>"#, "sphere", "volpath"));
    assert!(e.contains("weight") && e.contains("blendphase"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><phase type="blendphase"><float name="weight" value="0.5"/><phase type="isotropic"/></phase></medium>"#, "sphere", "volpath"));
    assert!(e.contains("exactly two") && e.contains("not 1"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><volume name="sigma_t" type="gridvolume"><string name="filename" value="missing.vol"/></volume></medium>"#, "sphere", "volpath"));
    assert!(e.contains("missing.vol"), "{e}");
    let e = load(&scene(r#"<medium id="m" type="homogeneous"><float name="scale" value="-1"/></medium>"#, "sphere", "volpath"));
    assert!(e.contains("scale") && e.contains("<float name=\"scale\""), "the line is shown: {e}");
}

//! Bidirectional path tracing (`bdpt`): unbiased against Mitsuba's
//! path-traced references (the Cornell box, and its caustic variant with a
//! glass and a gold sphere); the MIS-weighted images of the separate (s, t)
//! strategies sum to the full image; light tracing alone (t = 1) agrees with
//! `ptracer`; spectral dispersion on light subpaths (the prism) agrees with
//! `ptracer`; the image is exact across threads and passes; bad parameters
//! are located errors.

use crate::common::*;
use snell::film::Image;
use snell::spectrum::{Rgb, Sampled, Spectrum};
use snell::{LoadOptions, RenderOptions, Scene};
use std::path::Path;

/// `scene`'s text with its `from` integrator opening tag replaced by `to`.
fn swap(scene: &str, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(repo(scene)).expect("scene");
    assert!(text.contains(from), "{scene} has no {from}");
    text.replace(from, to)
}

fn load(scene: &str, text: &str, list: &[(&str, &str)]) -> Scene {
    let options = LoadOptions { params: params(list), ..Default::default() };
    snell::load_str(&repo(scene), text, &options).unwrap_or_else(|e| panic!("{e}"))
}

/// Passes of `text` (a scene at `scene`'s place) rendered in mode `S`,
/// seeds 1..=passes.
fn passes_of<S: Spectrum>(scene: &str, text: &str, list: &[(&str, &str)], passes: u32, spp: u32) -> Vec<Image> {
    render_passes_as::<S>(&repo(scene), Some(text), params(list), passes, spp)
}


const BDPT: &str = r#"<integrator type="bdpt">"#;

/// The Cornell box (max_depth 8) against Mitsuba's path-traced reference.
#[test]
fn cornell_box_matches_mitsuba() {
    let scene = "scenes/cornell-box.xml";
    let text = swap(scene, r#"<integrator type="path">"#, BDPT);
    let reference = snell::film::output::read_exr(&repo("tests/references/cornell-box.exr")).expect("reference");
    let passes = passes_of::<Rgb>(scene, &text, &[("res", "128")], 16, 2);
    compare(&passes, &reference, 16, 0.003).assert_unbiased("cornell-box bdpt", 0.01);
}

/// The caustic Cornell box — a glass sphere (dielectric) and a gold sphere
/// (conductor) casting caustics from a small light — against Mitsuba's
/// path-traced reference: the glass-and-metal scene, where light subpaths
/// and connections through delta vertices carry most of the caustic.
#[test]
fn glass_and_metal_caustic_box_matches_mitsuba() {
    let scene = "tests/scenes/cornell-glass-gold.xml";
    let text = swap(scene, r#"<integrator type="path">"#, BDPT);
    let reference = snell::film::output::read_exr(&repo("tests/references/cornell-glass-gold.exr")).expect("reference");
    let passes = passes_of::<Rgb>(scene, &text, &[("res", "128")], 16, 2);
    compare(&passes, &reference, 16, 0.003).assert_unbiased("cornell-glass-gold bdpt", 0.01);
}

/// The MIS-weighted contributions of each strategy (s, t), rendered alone
/// with the same random numbers, sum to the full image (up to the film's
/// fixed-point rounding), and several strategies carry light of their own.
#[test]
fn weighted_strategies_sum_to_the_full_image() {
    let scene = "tests/scenes/cornell-glass-gold.xml";
    let max_depth = 4usize;
    let with = |extra: &str| {
        let text = swap(scene, r#"<integrator type="path">"#, &format!(r#"<integrator type="bdpt">{extra}"#));
        let scene = load(scene, &text, &[("res", "32"), ("spp", "4"), ("max_depth", &max_depth.to_string())]);
        snell::render::<Rgb>(&scene, &RenderOptions::default()).expect("render").0
    };
    let full = with("");
    let mut sum = vec![[0.0f64; 3]; full.pixels.len()];
    let mut lit = vec![];
    for t in 1..=max_depth + 1 {
        for s in 0..=max_depth + 1 - t {
            if s + t < 2 || (s, t) == (1, 1) {
                continue;
            }
            let image = with(&format!(r#"<integer name="strategy_s" value="{s}"/><integer name="strategy_t" value="{t}"/>"#));
            let m = mean(&image);
            if m.iter().sum::<f64>() > 1e-3 * mean(&full).iter().sum::<f64>() {
                lit.push((s, t));
            }
            for (acc, p) in sum.iter_mut().zip(&image.pixels) {
                for c in 0..3 {
                    acc[c] += p[c] as f64;
                }
            }
        }
    }
    eprintln!("strategies with light: {lit:?}");
    for needed in [(0, 2), (1, 2), (2, 1), (2, 2), (3, 1), (1, 3), (2, 3)] {
        assert!(lit.contains(&needed), "strategy {needed:?} contributes nothing");
    }
    let mut worst = 0.0f64;
    for (a, p) in sum.iter().zip(&full.pixels) {
        for c in 0..3 {
            worst = worst.max((a[c] - p[c] as f64).abs() / (1e-3 + p[c] as f64));
        }
    }
    assert!(worst < 1e-3, "the strategies' sum differs from the full image by {worst:.2e} (relative)");
}

/// Light tracing alone — only the t = 1 strategies, each weighted 1 — is
/// `ptracer` (emitters seen directly hidden: they are no t = 1 strategy).
#[test]
fn light_tracing_alone_matches_ptracer() {
    let scene = "scenes/cornell-box.xml";
    let from = r#"<integrator type="path">"#;
    let light = swap(scene, from, r#"<integrator type="bdpt"><integer name="strategy_t" value="1"/><boolean name="mis" value="false"/>"#);
    let ptracer = swap(scene, from, r#"<integrator type="ptracer"><boolean name="hide_emitters" value="true"/>"#);
    let list = [("res", "64")];
    let a = passes_of::<Rgb>(scene, &light, &list, 16, 4);
    let b = passes_of::<Rgb>(scene, &ptracer, &list, 16, 4);
    assert_agree("light tracing vs ptracer", &a, &b, 16, 0.01);
}

/// Dispersion on light subpaths: the prism's spectrum (a spot beam through
/// SF11 glass onto a screen — a delta light behind a delta surface, which
/// only light subpaths reach) in spectral mode agrees with `ptracer`.
#[test]
fn spectral_prism_matches_ptracer() {
    let scene = "scenes/prism.xml";
    let from = r#"<integrator type="ptracer">"#;
    let bdpt = swap(scene, from, BDPT);
    let ptracer = std::fs::read_to_string(repo(scene)).expect("scene");
    let list = [("res", "64")];
    let a = passes_of::<Sampled>(scene, &bdpt, &list, 16, 8);
    let b = passes_of::<Sampled>(scene, &ptracer, &list, 16, 8);
    assert_agree("prism bdpt vs ptracer (spectral)", &a, &b, 16, 0.03);
}

/// The image is the same, bit for bit, for any thread count and pass split.
#[test]
fn exact_across_threads_and_passes() {
    let scene = "scenes/cornell-box.xml";
    let text = swap(scene, r#"<integrator type="path">"#, BDPT);
    let scene = load(scene, &text, &[("res", "32"), ("spp", "6")]);
    let bits = |image: &Image| image.pixels.iter().flat_map(|p| p.0).map(f32::to_bits).collect::<Vec<u32>>();
    let render = |threads, passes| snell::render::<Rgb>(&scene, &RenderOptions { threads, passes, ..RenderOptions::default() }).expect("render").0;
    let want = bits(&render(1, 1));
    assert!(want.iter().any(|&b| f32::from_bits(b) > 0.0));
    for (threads, passes) in [(2, 1), (3, 2), (2, 3)] {
        assert!(bits(&render(threads, passes)) == want, "{threads} threads, {passes} passes differ");
    }
}

/// Emitters at infinity start light subpaths too (on the disk of the
/// scene's bounding sphere), weighted against s = 0 (the camera subpath
/// leaving the scene) and s = 1: tests/scenes/sky-sun-glass.xml lit by its
/// constant sky alone (the glass sphere's caustic, the sky seen through
/// it), and by its directional sun alone (the glass sphere made diffuse: a
/// path tracer cannot find a delta sun through glass), agrees with `path`;
/// light subpaths carry light of their own (the t = 1 strategies).
#[test]
fn sky_and_sun_match_path() {
    let scene = "tests/scenes/sky-sun-glass.xml";
    let from = r#"<integrator type="path">"#;
    let sky_bdpt = swap(scene, from, BDPT);
    let sky_path = std::fs::read_to_string(repo(scene)).expect("scene");
    let glass = r#"<bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf>"#;
    let diffuse = r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>"#;
    let (sun_bdpt, sun_path) = (sky_bdpt.replace(glass, diffuse), sky_path.replace(glass, diffuse));
    for (name, text_bdpt, text_path, list) in [("sky", &sky_bdpt, &sky_path, [("res", "64"), ("sun", "0")]), ("sun", &sun_bdpt, &sun_path, [("res", "64"), ("sky", "0")])] {
        let a = passes_of::<Rgb>(scene, text_bdpt, &list, 16, 4);
        let b = passes_of::<Rgb>(scene, text_path, &list, 16, 8);
        assert_agree(&format!("{name} bdpt vs path"), &a, &b, 16, 0.02);
        let light = text_bdpt.replace(BDPT, r#"<integrator type="bdpt"><integer name="strategy_t" value="1"/>"#);
        let image = snell::render::<Rgb>(&load(scene, &light, &[("res", "32"), ("spp", "4"), list[1]]), &RenderOptions::default()).expect("render").0;
        let (m, full) = (mean(&image), mean(&average(&a)));
        eprintln!("{name}: light image {m:?} of {full:?}");
        assert!(m[1] > 2e-3 * full[1], "{name}: light subpaths carry no light");
    }
}

fn load_error(text: &str) -> String {
    match snell::load_str(Path::new("bdpt.xml"), text, &LoadOptions::default()) {
        Ok(_) => panic!("should fail:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn small_scene(sensor: &str, emitter: &str, integrator: &str) -> String {
    let fov = if sensor == "perspective" { r#"<float name="fov" value="40"/>"# } else { "" };
    format!(
        r#"<scene version="3.0.0">
    {integrator}
    <sensor type="{sensor}">{fov}</sensor>
    {emitter}
    <shape type="sphere"/>
</scene>"#
    )
}

#[test]
fn bad_parameters_are_located_errors() {
    let point = r#"<emitter type="point"><rgb name="intensity" value="1"/></emitter>"#;
    let cases = [
        (r#"<integrator type="bdpt"><integer name="max_depth" value="-2"/></integrator>"#, "max_depth"),
        (r#"<integrator type="bdpt"><integer name="rr_depth" value="0"/></integrator>"#, "rr_depth"),
        (r#"<integrator type="bdpt"><integer name="strategy_t" value="0"/></integrator>"#, "strategy_t"),
        (r#"<integrator type="bdpt"><boolean name="light_image" value="maybe"/></integrator>"#, "light_image"),
        (r#"<integrator type="bdpt"><float name="radius" value="1"/></integrator>"#, "radius"),
    ];
    for (integrator, what) in cases {
        let e = load_error(&small_scene("perspective", point, integrator));
        assert!(e.contains("bdpt.xml:2:") && e.contains(what), "{e}");
    }
    let bdpt = r#"<integrator type="bdpt"/>"#;
    let e = load_error(&small_scene("orthographic", point, bdpt));
    assert!(e.contains("bdpt.xml:2:5") && e.contains("perspective"), "{e}");
    let projector = r#"<emitter type="projector"><float name="fov" value="30"/><rgb name="irradiance" value="1"/></emitter>"#;
    let e = load_error(&small_scene("perspective", projector, bdpt));
    assert!(e.contains("bdpt.xml:2:5") && e.contains("projector") && e.contains("spot"), "{e}");
    // Nested in an AOV integrator, bdpt is refused too.
    let e = load_error(&small_scene("perspective", point, r#"<integrator type="aov"><string name="aovs" value="dd.y:depth"/><integrator type="bdpt"/></integrator>"#));
    assert!(e.contains("bdpt.xml:2:") && e.contains("cannot be nested"), "{e}");
    // The polarized modes are refused before rendering.
    let scene = snell::load_str(Path::new("bdpt.xml"), &small_scene("perspective", point, bdpt), &LoadOptions::default()).expect("loads");
    let e = snell::session::prepare(&scene, snell::Mode::RgbPolarized, "bdpt.xml").err().expect("polarized bdpt must fail").to_string();
    assert!(e.contains("bdpt") && e.contains("rgb and spectral"), "{e}");
    // An environment light is used (through s = 0 and s = 1).
    let env = snell::load_str(Path::new("env.xml"), &small_scene("perspective", r#"<emitter type="constant"/>"#, bdpt), &LoadOptions::default());
    assert!(env.is_ok());
}

/// Switching strategies off (`light_image`, `sample_direct`) re-weights the
/// others: the image stays the same in expectation. (It did not at the
/// film's border: light-image splats lost the part of the filter's
/// footprint outside the window while camera samples are normalized by the
/// part inside, so the border pixels were up to 12 % dark with
/// `sample_direct` off, 4 % with every strategy on.)
#[test]
fn fewer_strategies_same_image() {
    let scene = "tests/scenes/cornell-glass-gold.xml";
    let from = r#"<integrator type="path">"#;
    let list = [("res", "32"), ("max_depth", "6")];
    let full = passes_of::<Rgb>(scene, &swap(scene, from, BDPT), &list, 16, 64);
    for (name, options) in [
        ("bdpt without t = 1", r#"<boolean name="light_image" value="false"/>"#),
        ("bdpt without s = 1", r#"<boolean name="sample_direct" value="false"/>"#),
        ("bdpt without t = 1 and s = 1", r#"<boolean name="light_image" value="false"/><boolean name="sample_direct" value="false"/>"#),
    ] {
        let fewer = swap(scene, from, &format!(r#"<integrator type="bdpt">{options}"#));
        let a = passes_of::<Rgb>(scene, &fewer, &list, 16, 64);
        assert_agree(&format!("{name} vs all strategies"), &a, &full, 8, 0.02);
    }
}

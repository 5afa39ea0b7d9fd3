//! Vertex connection and merging (`vcm`): with merging off (`mode = bpt`)
//! it is unbiased and agrees with `bdpt` (block z-tests), also under
//! emitters at infinity (against `path`); with merging it converges to
//! Mitsuba's path-traced references of the Cornell box and the caustic box
//! (glass and gold spheres) — the error falls as the iterations grow and the
//! mean ends within 1.5 %; it renders the specular–diffuse–specular light
//! of a floor under water lit by a point light (a closed form) that no
//! connection can sample (`mode = bpt` finds none of it); the image is the
//! same bit for bit for any thread count and pass split; bad parameters
//! and unsupported modes are located or clear errors.

use crate::common::*;
use snell::film::Image;
use snell::film::output::read_exr;
use snell::spectrum::{Rgb, Sampled};
use snell::{LoadOptions, RenderOptions, Scene};
use std::path::Path;

/// `scene`'s text with its `from` integrator opening tag replaced by `to`.
fn swap(scene: &str, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(repo(scene)).expect("scene");
    assert!(text.contains(from), "{scene} has no {from}");
    text.replace(from, to)
}

fn load(scene: &str, text: &str, list: &[(&str, &str)], spp: Option<u32>) -> Scene {
    let options = LoadOptions { params: params(list), spp, ..Default::default() };
    snell::load_str(&repo(scene), text, &options).unwrap_or_else(|e| panic!("{e}"))
}

fn render(scene: &Scene, threads: usize, passes: u32) -> Image {
    snell::render::<Rgb>(scene, &RenderOptions { threads, passes, ..RenderOptions::default() }).expect("render").0
}


const PATH: &str = r#"<integrator type="path">"#;
const BPT: &str = r#"<integrator type="vcm"><string name="mode" value="bpt"/>"#;

/// Connections only: the caustic box (glass and gold spheres, a small
/// light) agrees with `bdpt` block by block.
#[test]
fn bpt_mode_matches_bdpt() {
    let scene = "tests/scenes/cornell-glass-gold.xml";
    let list = [("res", "64")];
    let a = render_passes(&repo(scene), Some(&swap(scene, PATH, BPT)), params(&list), 16, 4);
    let b = render_passes(&repo(scene), Some(&swap(scene, PATH, r#"<integrator type="bdpt">"#)), params(&list), 16, 4);
    assert_agree("vcm (bpt) vs bdpt", &a, &b, 8, 0.02);
}

/// Emitters at infinity are reached by camera subpaths only (leaving the
/// scene, and next-event estimation): tests/scenes/sky-sun-glass.xml under
/// its constant sky alone (the sky seen through the glass sphere), and
/// under its directional sun alone (the sphere made diffuse) agrees with
/// `path`, connections only and with merging (its mean).
#[test]
fn emitters_at_infinity_match_path() {
    let scene = "tests/scenes/sky-sun-glass.xml";
    let sky_vcm = swap(scene, PATH, BPT);
    let sky_path = std::fs::read_to_string(repo(scene)).expect("scene");
    let glass = r#"<bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf>"#;
    let diffuse = r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>"#;
    let (sun_vcm, sun_path) = (sky_vcm.replace(glass, diffuse), sky_path.replace(glass, diffuse));
    for (name, text_vcm, text_path, list) in [("sky", &sky_vcm, &sky_path, [("res", "64"), ("sun", "0")]), ("sun", &sun_vcm, &sun_path, [("res", "64"), ("sky", "0")])] {
        let a = render_passes(&repo(scene), Some(text_vcm), params(&list), 16, 4);
        let b = render_passes(&repo(scene), Some(text_path), params(&list), 16, 8);
        assert_agree(&format!("{name}: vcm (bpt) vs path"), &a, &b, 16, 0.02);
        let merging = text_vcm.replace(r#"value="bpt""#, r#"value="vcm""#);
        let m = mean(&render(&load(scene, &merging, &list, Some(16)), 0, 1));
        let r = mean(&average(&b));
        eprintln!("{name}: vcm mean {m:?}, path {r:?}");
        for c in 0..3 {
            assert!((m[c] / r[c] - 1.0).abs() < 0.02, "{name} vcm channel {c}: {} vs {}", m[c], r[c]);
        }
    }
}

/// Relative mean squared error of the means of `block`² blocks.
fn block_rel_mse(img: &Image, reference: &Image, block: u32) -> f64 {
    let w = img.width;
    let (mut sum, mut n) = (0.0, 0);
    for by in 0..img.height / block {
        for bx in 0..w / block {
            for c in 0..3 {
                let (mut a, mut r) = (0.0f64, 0.0f64);
                for y in by * block..(by + 1) * block {
                    for x in bx * block..(bx + 1) * block {
                        a += img.pixels[(y * w + x) as usize][c] as f64;
                        r += reference.pixels[(y * w + x) as usize][c] as f64;
                    }
                }
                let k = (block * block) as f64;
                let (a, r) = (a / k, r / k);
                sum += (a - r).powi(2) / (r * r + 1e-4);
                n += 1;
            }
        }
    }
    sum / n as f64
}

/// Full vcm on `scene` (128², Mitsuba's reference): the error of 8 × 8
/// block means falls from 4 to 16 to 64 iterations, and the image mean at
/// 64 is within `tol` of the reference's.
fn converges(scene: &str, reference: &str, tol: f64) {
    let reference = read_exr(&repo(reference)).expect("reference");
    let text = swap(scene, PATH, r#"<integrator type="vcm">"#);
    let mut errors = vec![];
    for k in [4u32, 16, 64] {
        let t = std::time::Instant::now();
        let img = render(&load(scene, &text, &[("res", "128")], Some(k)), 0, 1);
        let e = block_rel_mse(&img, &reference, 8);
        let (m, r) = (mean(&img), mean(&reference));
        let ratio = [0, 1, 2].map(|c| m[c] / r[c]);
        eprintln!("{scene} vcm k = {k:3}: block relMSE {e:.3e}, mean ratio {ratio:.4?}, {:.2} s", t.elapsed().as_secs_f64());
        errors.push((k, e, ratio));
    }
    for w in errors.windows(2) {
        assert!(w[1].1 < w[0].1, "{scene}: error did not fall from k = {} to {}: {:.3e} → {:.3e}", w[0].0, w[1].0, w[0].1, w[1].1);
    }
    for c in 0..3 {
        assert!((errors[2].2[c] - 1.0).abs() < tol, "{scene} channel {c}: mean ratio {:.4} at 64 iterations", errors[2].2[c]);
    }
}

#[test]
fn cornell_box_converges_to_the_reference() {
    converges("scenes/cornell-box.xml", "tests/references/cornell-box.exr", 0.015);
}

#[test]
fn caustic_box_converges_to_the_reference() {
    converges("tests/scenes/cornell-glass-gold.xml", "tests/references/cornell-glass-gold.exr", 0.015);
}

/// The pool of tests/common's `pool_scene` (a caustic seen through water):
/// no connection can make its path, only a merge.
fn pool_render(mode: &str, iterations: u32) -> Image {
    let integrator = format!(
        r#"<integrator type="vcm"><integer name="max_depth" value="4"/><integer name="photon_count" value="100000"/><float name="initial_radius" value="0.02"/><string name="mode" value="{mode}"/></integrator>"#
    );
    let options = LoadOptions { spp: Some(iterations), ..LoadOptions::default() };
    let scene = snell::load_str(&std::env::temp_dir().join("snell-vcm-pool.xml"), &pool_scene(&integrator), &options).unwrap_or_else(|e| panic!("{e}"));
    render(&scene, 0, 1)
}

#[test]
fn floor_through_water_matches_the_closed_form() {
    let (eta, h, d, intensity, rho) = (1.333f64, 1.0, 0.5, 10.0, 0.8);
    let t0 = 1.0 - ((eta - 1.0) / (eta + 1.0)).powi(2);
    let expected = t0 * rho * intensity * t0 / (h + d / eta).powi(2) / std::f64::consts::PI / (eta * eta);
    let bpt = mean(&pool_render("bpt", 8));
    eprintln!("pool: vcm (bpt) mean {bpt:?}; expected {expected:.4}");
    assert!(bpt.iter().all(|&v| v < 1e-3 * expected), "connections found the SDS light: {bpt:?}");
    for mode in ["vcm", "ppm"] {
        let m = mean(&pool_render(mode, 32));
        eprintln!("pool: vcm ({mode}) mean {m:.4?}, expected {expected:.4}");
        for c in 0..3 {
            assert!((m[c] / expected - 1.0).abs() < 0.03, "{mode} channel {c}: {:.4} vs {expected:.4}", m[c]);
        }
    }
}

/// The image depends on the seed and the iterations only: the same, bit
/// for bit, for 1, 2 and 3 threads and any pass split.
#[test]
fn exact_across_threads_and_passes() {
    let scene = "scenes/caustic-cornell-box.xml";
    let text = swap(scene, PATH, r#"<integrator type="vcm">"#);
    let scene = load(scene, &text, &[("res", "32")], Some(6));
    let bits = |image: &Image| image.pixels.iter().flat_map(|p| p.0).map(f32::to_bits).collect::<Vec<u32>>();
    let want = bits(&render(&scene, 1, 1));
    assert!(want.iter().any(|&b| f32::from_bits(b) > 0.0));
    for (threads, passes) in [(2, 1), (3, 2), (2, 3)] {
        assert!(bits(&render(&scene, threads, passes)) == want, "{threads} threads, {passes} passes differ");
    }
}

fn load_error(text: &str) -> String {
    match snell::load_str(Path::new("vcm.xml"), text, &LoadOptions::default()) {
        Ok(_) => panic!("should fail:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn small_scene(sensor: &str, emitter: &str, integrator: &str) -> String {
    let fov = if sensor == "perspective" { r#"<float name="fov" value="40"/>"# } else { "" };
    format!(
        r#"<scene version="3.0.0">
    {integrator}
    <sensor type="{sensor}">{fov}<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
    {emitter}
    <shape type="sphere"/>
</scene>"#
    )
}

#[test]
fn bad_parameters_are_located_errors() {
    let point = r#"<emitter type="point"><point name="position" x="0" y="0" z="3"/><rgb name="intensity" value="1"/></emitter>"#;
    let cases = [
        (r#"<integrator type="vcm"><integer name="max_depth" value="0"/></integrator>"#, "max_depth"),
        (r#"<integrator type="vcm"><integer name="rr_depth" value="0"/></integrator>"#, "rr_depth"),
        (r#"<integrator type="vcm"><string name="mode" value="sppm"/></integrator>"#, "ppm"),
        (r#"<integrator type="vcm"><float name="alpha" value="1"/></integrator>"#, "alpha"),
        (r#"<integrator type="vcm"><float name="initial_radius" value="-1"/></integrator>"#, "initial_radius"),
        (r#"<integrator type="vcm"><integer name="photon_count" value="0"/></integrator>"#, "photon_count"),
        (r#"<integrator type="vcm"><float name="radius" value="1"/></integrator>"#, "radius"),
    ];
    for (integrator, what) in cases {
        let e = load_error(&small_scene("perspective", point, integrator));
        assert!(e.contains("vcm.xml:2:") && e.contains(what), "{e}");
    }
    let vcm = r#"<integrator type="vcm"/>"#;
    let e = load_error(&small_scene("orthographic", point, vcm));
    assert!(e.contains("vcm.xml:2:5") && e.contains("perspective"), "{e}");
    let e = load_error(&small_scene("perspective", point, r#"<integrator type="aov"><string name="aovs" value="dd.y:depth"/><integrator type="vcm"/></integrator>"#));
    assert!(e.contains("vcm.xml:2:") && e.contains("cannot be nested"), "{e}");
    // RGB and spectral: the polarized modes are refused with a reason.
    let scene = snell::load_str(Path::new("vcm.xml"), &small_scene("perspective", point, vcm), &LoadOptions::default()).expect("loads");
    let e = snell::session::prepare(&scene, snell::Mode::RgbPolarized, "vcm.xml").err().expect("polarized vcm must fail").to_string();
    assert!(e.contains("vcm") && e.contains("rgb"), "{e}");
    assert!(snell::render::<Sampled>(&scene, &RenderOptions::default()).is_ok());
    assert!(snell::render::<Rgb>(&scene, &RenderOptions::default()).is_ok());
}

/// Spectral mode, dispersion on light subpaths: the prism's spectrum (a
/// spot beam through SF11 glass onto a screen: a delta light behind delta
/// surfaces, which only light subpaths reach, kept for their hero
/// wavelength past the glass) agrees with `ptracer`'s, block by block.
#[test]
fn spectral_prism_matches_ptracer() {
    let scene = "scenes/prism.xml";
    let from = r#"<integrator type="ptracer">"#;
    // Merges of half a pixel footprint (still about 40 % of the weight
    // against the light subpaths' camera connections): the beam on the
    // screen is 2 pixels tall and its spectrum's sRGB values change sign
    // within a few pixels, so the default radius's blur would show in the
    // blocks.
    let vcm = swap(scene, from, r#"<integrator type="vcm"><float name="radius_footprints" value="0.5"/>"#);
    let ptracer = std::fs::read_to_string(repo(scene)).expect("scene");
    // The beam alone (no fill light: the screen's edges would show photon
    // mapping's boundary bias, which merging has in RGB too).
    let list = [("res", "64"), ("fill", "0")];
    let a = render_passes_as::<Sampled>(&repo(scene), Some(&vcm), params(&list), 12, 8);
    let b = render_passes_as::<Sampled>(&repo(scene), Some(&ptracer), params(&list), 12, 8);
    assert_agree("prism vcm vs ptracer (spectral)", &a, &b, 16, 0.03);
}

/// Spectral mode, dispersion on camera subpaths and in merges: the caustic
/// box with its glass sphere made of dispersive SF11 (the caustic on the
/// floor, the walls and the light seen through it) agrees with `path` in
/// spectral mode.
#[test]
fn spectral_dispersive_caustic_box_matches_path() {
    let scene = "tests/scenes/cornell-glass-gold.xml";
    let glass = |t: String| {
        assert!(t.contains(r#"value="bk7""#));
        t.replace(r#"value="bk7""#, r#"value="sellmeier:sf11""#)
    };
    let vcm = glass(swap(scene, PATH, r#"<integrator type="vcm">"#));
    let path = glass(std::fs::read_to_string(repo(scene)).expect("scene"));
    let list = [("res", "48"), ("max_depth", "8")];
    let a = render_passes_as::<Sampled>(&repo(scene), Some(&vcm), params(&list), 8, 8);
    let b = render_passes_as::<Sampled>(&repo(scene), Some(&path), params(&list), 8, 64);
    assert_agree("dispersive caustic box vcm vs path (spectral)", &a, &b, 16, 0.03);
}

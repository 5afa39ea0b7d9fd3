//! Path guiding (`path` with `guiding`; src/integrator/guiding/): the
//! directional distribution's sample and pdf agree, guided `path` converges
//! to the unguided image and to Mitsuba's, images are bit-identical across
//! thread counts and pass splits, and bad parameters are located errors.


use glam::{Vec2, Vec3};
use snell::integrator::guiding::quadtree::{DirTree, dir_to_square, square_to_dir};

/// A small deterministic generator for the tests' random numbers.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
    fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next(), self.next())
    }
}

/// A tree fitted to records peaked around two directions over a floor of
/// uniform ones (so it has several levels and empty-ish cells).
fn peaked_tree() -> DirTree {
    let mut rng = Lcg(7);
    let mut records = vec![];
    for i in 0..20000 {
        let u = rng.next_2d();
        let (p, value) = match i % 4 {
            0 => (Vec2::new(0.8 + 0.05 * u.x, 0.3 + 0.02 * u.y), 5.0),
            1 => (Vec2::new(0.1 + 0.3 * u.x, 0.6 + 0.3 * u.y), 1.0),
            _ => (u, 0.2 + u.x),
        };
        records.push((p.min(Vec2::splat(0.999)), value));
    }
    DirTree::build(&mut records)
}

#[test]
fn direction_map_round_trips() {
    let mut rng = Lcg(3);
    for _ in 0..1000 {
        let p = rng.next_2d() * 0.998 + 0.001;
        let d = square_to_dir(p);
        assert!((d.length() - 1.0).abs() < 1e-5);
        let q = dir_to_square(d);
        assert!((p - q).abs().max_element() < 1e-3, "{p} -> {d} -> {q}");
    }
    assert!(dir_to_square(Vec3::Z).x < 1.0 && dir_to_square(-Vec3::Z).x >= 0.0);
}

#[test]
fn quadtree_pdf_integrates_to_one() {
    let tree = peaked_tree();
    assert!(tree.node_count() > 5, "the tree should refine ({} nodes)", tree.node_count());
    // Midpoint rule on a grid finer than the deepest cells that matter.
    let n = 1024;
    let mut sum = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let p = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            sum += tree.pdf_square(p) as f64;
        }
    }
    let integral = sum / (n * n) as f64;
    assert!((integral - 1.0).abs() < 1e-3, "∫ pdf over the square = {integral}");
    // On the sphere: the map is equal-area, so the solid-angle density is
    // the square's over 4π (and integrates to 1 as well).
    let mut rng = Lcg(11);
    for _ in 0..1000 {
        let p = rng.next_2d();
        let d = square_to_dir(p);
        let a = tree.pdf(d) * 4.0 * std::f32::consts::PI;
        let b = tree.pdf_square(dir_to_square(d));
        assert!((a - b).abs() <= 1e-4 * b.max(1.0), "{a} vs {b}");
    }
}

#[test]
fn quadtree_samples_follow_the_pdf() {
    let tree = peaked_tree();
    // χ² of 16 × 16 cells: expected counts from the pdf integrated per cell.
    let cells = 16usize;
    let n = 200_000usize;
    let mut counts = vec![0f64; cells * cells];
    let mut rng = Lcg(5);
    for _ in 0..n {
        let p = tree.sample_square(rng.next_2d());
        assert!(p.x >= 0.0 && p.x < 1.0 && p.y >= 0.0 && p.y < 1.0);
        assert!(tree.pdf_square(p) > 0.0, "sampled a point of zero density: {p}");
        let (i, j) = ((p.x * cells as f32) as usize, (p.y * cells as f32) as usize);
        counts[j * cells + i] += 1.0;
    }
    let sub = 32;
    let mut chi2 = 0.0;
    let mut dof = 0;
    for j in 0..cells {
        for i in 0..cells {
            let mut mass = 0.0f64;
            for b in 0..sub {
                for a in 0..sub {
                    let p = Vec2::new((i * sub + a) as f32 + 0.5, (j * sub + b) as f32 + 0.5) / (cells * sub) as f32;
                    mass += tree.pdf_square(p) as f64;
                }
            }
            let expected = mass / (cells * cells * sub * sub) as f64 * n as f64;
            if expected > 5.0 {
                chi2 += (counts[j * cells + i] - expected).powi(2) / expected;
                dof += 1;
            } else {
                assert!(counts[j * cells + i] <= expected * 3.0 + 10.0);
            }
        }
    }
    // χ² with ~dof degrees of freedom: mean dof, sd √(2 dof); 5 sd margin.
    let limit = dof as f64 + 5.0 * (2.0 * dof as f64).sqrt();
    assert!(chi2 < limit, "χ² = {chi2:.1} over {dof} cells (limit {limit:.1})");
}

use crate::common::*;
use snell::spectrum::Rgb;
use snell::{RenderOptions, Scene};
use std::path::Path;

/// `scene`'s text with `extra` XML inside its `path` integrator.
fn guided(spp: u32, fraction: &str) -> String {
    format!(r#"<boolean name="guiding" value="true"/><integer name="guiding_spp" value="{spp}"/><float name="bsdf_sampling_fraction" value="{fraction}"/>"#)
}

fn load(path: &Path, text: &str, p: &[(&str, &str)]) -> Scene {
    let options = snell::LoadOptions { params: params(p), ..Default::default() };
    snell::load_str(path, text, &options).unwrap_or_else(|e| panic!("{e}"))
}

/// Guided `path` on the Cornell box against Mitsuba's committed reference
/// (block z-tests as tests/mitsuba_reference.rs).
#[test]
fn guided_cornell_box_matches_mitsuba() {
    let scene = repo("scenes/cornell-box.xml");
    let reference = snell::film::output::read_exr(&repo("tests/references/cornell-box.exr")).expect("reference EXR");
    let passes = render_passes(&scene, Some(&with_path_props(&scene, &guided(4, "0.5"))), params(&[("res", "128")]), 16, 16);
    compare(&passes, &reference, 16, 0.003).assert_unbiased("cornell box, guided", 0.01);
}

/// On the caustic box (light through glass and off metal onto diffuse
/// surfaces, which the guide learns) guided `path` agrees with unguided.
#[test]
fn guided_caustic_box_agrees_with_unguided() {
    let scene = repo("scenes/caustic-cornell-box.xml");
    let p = params(&[("res", "64")]);
    let plain = render_passes(&scene, None, p.clone(), 16, 32);
    let guide = render_passes(&scene, Some(&with_path_props(&scene, &guided(8, "0.5"))), p, 16, 32);
    assert_agree("caustic box: guided vs plain", &guide, &plain, 8, 0.02);
}

/// The guide is trained in a deterministic pre-phase and frozen: the image
/// is the same, bit for bit, for any thread count and pass split.
#[test]
fn guided_is_exact_across_threads_and_passes() {
    let path = repo("scenes/cornell-box.xml");
    let text = with_path_props(&path, &guided(4, "0.5")).replace(r#"<sampler type="independent""#, r#"<sampler type="zsobol""#);
    let render = |threads, passes| {
        // A fresh scene each time: the guide is retrained (as on a resume).
        let scene = load(&path, &text, &[("res", "40"), ("spp", "8")]);
        let opts = RenderOptions { threads, passes, ..RenderOptions::default() };
        snell::render::render_passes::<Rgb>(&scene, &opts, &mut |_| {}).expect("render").0
    };
    let want = pixel_bits(&render(1, 1));
    assert!(want.iter().filter(|&&b| f32::from_bits(b) > 0.0).count() > want.len() / 2);
    for (threads, passes) in [(2, 1), (3, 3), (2, 4)] {
        assert!(pixel_bits(&render(threads, passes)) == want, "{threads} threads, {passes} passes differ");
    }
    // A second render of the same scene object reuses the frozen guide.
    let scene = load(&path, &text, &[("res", "40"), ("spp", "8")]);
    let opts = RenderOptions { threads: 2, ..RenderOptions::default() };
    let a = snell::render::render_passes::<Rgb>(&scene, &opts, &mut |_| {}).expect("render").0;
    let b = snell::render::render_passes::<Rgb>(&scene, &opts, &mut |_| {}).expect("render").0;
    assert!(pixel_bits(&a) == want && pixel_bits(&b) == want);
    // And the guide changes the image (it is used).
    let plain = load(&path, &std::fs::read_to_string(&path).expect("scene").replace(r#"<sampler type="independent""#, r#"<sampler type="zsobol""#), &[("res", "40"), ("spp", "8")]);
    let p = snell::render::render_passes::<Rgb>(&plain, &opts, &mut |_| {}).expect("render").0;
    assert!(pixel_bits(&p) != want, "the guided image equals the unguided one");
}

/// With `bsdf_sampling_fraction` 1 the guide is never sampled and the
/// combined density is the BSDF's: the image is unguided `path`'s (so the
/// guided tracer draws the same sampler dimensions).
#[test]
fn bsdf_fraction_one_is_plain_path() {
    let path = repo("scenes/caustic-cornell-box.xml");
    let p = [("res", "32"), ("spp", "8")];
    let opts = RenderOptions { threads: 2, ..RenderOptions::default() };
    let guided_scene = load(&path, &with_path_props(&path, &guided(2, "1.0")), &p);
    let plain_scene = load(&path, &std::fs::read_to_string(&path).expect("scene"), &p);
    let a = snell::render::render_passes::<Rgb>(&guided_scene, &opts, &mut |_| {}).expect("render").0;
    let b = snell::render::render_passes::<Rgb>(&plain_scene, &opts, &mut |_| {}).expect("render").0;
    // The same paths: equal up to the rounding of f/pdf against the BSDF's
    // own weight (which can flip a rare Russian-roulette decision).
    let n = a.pixels.len() * 3;
    let off = a.pixels.iter().flat_map(|p| p.0).zip(b.pixels.iter().flat_map(|p| p.0)).filter(|(x, y)| (x - y).abs() > 1e-4 * (y.abs() + 1e-3)).count();
    assert!(off * 100 < n, "{off} of {n} values differ");
}

/// Bad values of the guiding parameters are located errors.
#[test]
fn bad_guiding_parameters_are_located_errors() {
    let path = repo("scenes/cornell-box.xml");
    let cases = [
        (r#"<integer name="guiding_spp" value="0"/>"#, "guiding_spp"),
        (r#"<integer name="guiding_spp" value="5000"/>"#, "guiding_spp"),
        (r#"<float name="bsdf_sampling_fraction" value="0"/>"#, "bsdf_sampling_fraction"),
        (r#"<float name="bsdf_sampling_fraction" value="1.5"/>"#, "bsdf_sampling_fraction"),
        (r#"<string name="guiding" value="yes"/>"#, "guiding"),
    ];
    for (extra, name) in cases {
        let err = snell::load_str(&path, &with_path_props(&path, extra), &Default::default()).err().expect("an error");
        let msg = err.to_string();
        assert!(msg.contains(name) && msg.contains("cornell-box.xml:9:"), "{extra}: {msg}");
    }
}

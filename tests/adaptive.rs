//! Adaptive sampling (`RenderOptions::adaptive`, `--noise-threshold`): the
//! image and the per-pixel sample counts are the same for any thread count;
//! a flat region stops at the minimum while a noisy one takes more; the
//! image agrees with a non-adaptive reference within noise; bad options get
//! a clear error.

use crate::common::*;
use snell::film::Image;
use snell::render::Adaptive;
use snell::spectrum::Rgb;
use snell::{RenderOptions, Scene};

fn cornell(res: u32, spp: u32, seed: u64) -> Scene {
    let path = repo("scenes/cornell-box.xml");
    let options = snell::LoadOptions { params: params(&[("res", &res.to_string()), ("spp", &spp.to_string())]), seed: Some(seed), ..Default::default() };
    snell::load_file(&path, &options).unwrap_or_else(|e| panic!("{e}"))
}

fn adaptive(threads: usize, threshold: f64, min_spp: u32) -> RenderOptions {
    RenderOptions { threads, adaptive: Some(Adaptive { threshold, min_spp }), ..RenderOptions::default() }
}

fn bits(image: &Image) -> Vec<u32> {
    let mut out: Vec<u32> = image.pixels.iter().flat_map(|p| p.0).map(f32::to_bits).collect();
    for c in &image.channels {
        out.extend(c.values.iter().map(|v| v.to_bits()));
    }
    out
}

fn counts(image: &Image) -> Vec<u32> {
    image.channel("spp").expect("an adaptive render's image has an spp channel").values.iter().map(|&v| v as u32).collect()
}

#[test]
fn adaptive_images_are_identical_for_any_thread_count() {
    let scene = cornell(40, 64, 0);
    let (reference, stats) = snell::render::<Rgb>(&scene, &adaptive(1, 0.05, 8)).expect("render");
    let n = counts(&reference);
    // The render did adapt: some pixels stopped at the minimum, some took all.
    assert!(n.contains(&8) && n.contains(&64), "{:?}", stats.adaptive);
    assert!(n.iter().all(|c| [8, 16, 32, 64].contains(c)));
    let a = stats.adaptive.as_ref().expect("adaptive stats");
    assert_eq!(stats.samples_taken, n.iter().map(|&c| c as u64).sum::<u64>());
    assert_eq!(a.rounds.iter().map(|r| r.samples).sum::<u64>(), stats.samples_taken);
    assert!(!stats.interrupted && a.least_spp == 8 && a.most_spp == 64);
    for threads in [2, 3] {
        let mut rounds = vec![];
        let (image, _) = snell::render::render_passes::<Rgb>(&scene, &adaptive(threads, 0.05, 8), &mut |r| rounds.push((r.spp_done, r.active_fraction)))
            .expect("render");
        assert!(bits(&image) == bits(&reference), "{threads} threads differ from 1");
        assert_eq!(rounds.len(), 4);
        assert!(rounds[0] == (8, 1.0) && rounds.windows(2).all(|w| w[1].0 == 2 * w[0].0 && w[1].1 <= w[0].1), "{rounds:?}");
    }
    // The wavefront and the one-sample-at-a-time loops agree on which pixels sample.
    let scalar = RenderOptions { wavefront: Some(false), ..adaptive(2, 0.05, 8) };
    let (image, _) = snell::render::<Rgb>(&scene, &scalar).expect("render");
    let differ = counts(&image).iter().zip(&n).filter(|(a, b)| a != b).count();
    assert!(differ < n.len() / 20, "{differ} of {} pixels got other sample counts", n.len());
}

#[test]
fn a_flat_region_stops_at_the_minimum_and_a_noisy_one_samples_on() {
    // A diffuse sphere under a constant sky: the sky is exact with any
    // sample, the sphere is noisy.
    let path = repo("tests/scenes/cli-sphere.xml");
    let options = snell::LoadOptions { params: params(&[("res", "48"), ("height", "36")]), spp: Some(64), ..Default::default() };
    let scene = snell::load_file(&path, &options).unwrap_or_else(|e| panic!("{e}"));
    let (image, stats) = snell::render::<Rgb>(&scene, &adaptive(2, 0.01, 8)).expect("render");
    let n = counts(&image);
    let at = |x: u32, y: u32| n[(y * image.width + x) as usize];
    for (x, y) in [(0, 0), (47, 0), (0, 35), (47, 35), (2, 18)] {
        assert_eq!(at(x, y), 8, "sky pixel ({x}, {y})");
    }
    for (x, y) in [(24, 18), (20, 15), (28, 21)] {
        assert_eq!(at(x, y), 64, "sphere pixel ({x}, {y})");
    }
    let a = stats.adaptive.expect("adaptive stats");
    assert!(a.mean_spp > 8.0 && a.mean_spp < 64.0, "{a:?}");
}

#[test]
fn the_adaptive_image_agrees_with_the_full_render() {
    // 16 adaptive renders (seeds 1..16) against one of 2048 spp everywhere:
    // adaptive stopping is biased only by pixels that stop while they look
    // more converged than they are, which the neighbourhood test makes rare.
    let reference = snell::render::<Rgb>(&cornell(32, 2048, 1000), &RenderOptions { threads: 2, ..RenderOptions::default() }).expect("render").0;
    let mut images = vec![];
    let mut mean_spp = 0.0;
    for seed in 1..=16 {
        let (image, stats) = snell::render::<Rgb>(&cornell(32, 64, seed), &adaptive(2, 0.05, 16)).expect("render");
        mean_spp += stats.adaptive.expect("adaptive stats").mean_spp / 16.0;
        images.push(image);
    }
    assert!(mean_spp < 60.0, "the render did not adapt: {mean_spp} spp on average");
    // The reference's own relative error per 8 × 8 block at 2048 spp, about 0.3 %.
    compare(&images, &reference, 8, 0.003).assert_unbiased("adaptive Cornell box", 0.01);
}

#[test]
fn bad_options_get_a_clear_error() {
    let scene = cornell(16, 64, 0);
    for threshold in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        let e = snell::render::<Rgb>(&scene, &adaptive(1, threshold, 0)).expect_err("a bad threshold").to_string();
        assert!(e.contains("threshold") && e.contains("positive"), "{e}");
    }
    let e = snell::render::<Rgb>(&scene, &adaptive(1, 0.05, 128)).expect_err("min above spp").to_string();
    assert!(e.contains("128") && e.contains("64"), "{e}");
    let passes = RenderOptions { passes: 3, ..adaptive(1, 0.05, 0) };
    let e = snell::render::<Rgb>(&scene, &passes).expect_err("passes").to_string();
    assert!(e.contains("rounds"), "{e}");
    let state = snell::render::render_samples::<Rgb>(&scene, &RenderOptions::default(), 0..8).expect("render");
    let e = snell::render::render_progressive::<Rgb>(&scene, &adaptive(1, 0.05, 0), Some(state), &mut |_| {}).err().expect("resume").to_string();
    assert!(e.contains("resume an adaptive render"), "{e}");
    let path = repo("scenes/cornell-box.xml");
    let text = std::fs::read_to_string(&path).unwrap().replace(r#"<integrator type="path">"#, r#"<integrator type="bdpt">"#);
    let options = snell::LoadOptions { params: params(&[("res", "16")]), ..Default::default() };
    let bdpt = snell::load_str(&path, &text, &options).unwrap_or_else(|e| panic!("{e}"));
    let e = snell::render::<Rgb>(&bdpt, &adaptive(1, 0.05, 0)).expect_err("bdpt").to_string();
    assert!(e.contains("camera-path integrator") && e.contains("bdpt"), "{e}");
}

#[test]
fn the_default_minimum_is_an_eighth_at_least_16() {
    assert_eq!(Adaptive::default_min_spp(1024), 128);
    assert_eq!(Adaptive::default_min_spp(64), 16);
    assert_eq!(Adaptive::default_min_spp(8), 8);
}

//! Tiles of a distributed render: the states of tiles of the crop window
//! (each with the border its reconstruction filter spreads beyond it) add up
//! to exactly the state of one render, bit for bit — with a Gaussian filter
//! (radius 2: borders of 3 pixels), a crop window, light tracing, and over
//! several sample ranges; bad sets of tiles are refused. Also: a render
//! resumes from a state holding any complete sample ranges (what a
//! distributed render's checkpoint holds), not only a prefix.

use crate::common::*;
use snell::film::FilmState;
use snell::{Mode, RenderOptions, Scene};

fn cornell(integrator: &str, extra_film: &str) -> Scene {
    let path = repo("scenes/cornell-box.xml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace(r#"<integrator type="path">"#, &format!(r#"<integrator type="{integrator}">"#))
        .replace(r#"<rfilter type="gaussian"/>"#, &format!(r#"<rfilter type="gaussian"/>{extra_film}"#));
    let options = snell::LoadOptions { params: params(&[("res", "40"), ("spp", "6")]), ..Default::default() };
    snell::load_str(&path, &text, &options).unwrap_or_else(|e| panic!("{e}"))
}

fn options() -> RenderOptions {
    RenderOptions { threads: 2, ..RenderOptions::default() }
}

/// Tiles of at most `tw` × `th` pixels covering a `w` × `h` window.
fn tiling(w: u32, h: u32, tw: u32, th: u32) -> Vec<[u32; 4]> {
    let mut out = vec![];
    for y in (0..h).step_by(th as usize) {
        for x in (0..w).step_by(tw as usize) {
            out.push([x, y, tw.min(w - x), th.min(h - y)]);
        }
    }
    out
}

/// The state of samples `range` merged from tiles of at most `tw` × `th`.
fn tiled(scene: &Scene, range: std::ops::Range<u32>, tw: u32, th: u32, into: &mut FilmState) {
    let [_, _, w, h] = scene.film.crop;
    let tiles: Vec<FilmState> = tiling(w, h, tw, th)
        .into_iter()
        .map(|t| snell::session::render_tile_samples(scene, Mode::Rgb, &options(), range.clone(), t).unwrap())
        .collect();
    into.merge_tiles(&tiles).unwrap();
}

fn assert_tiles_equal_one_render(scene: &Scene, what: &str) {
    let spp = scene.sampler.sample_count;
    let one = snell::session::render_samples(scene, Mode::Rgb, &options(), 0..spp).unwrap();
    let mut merged = snell::session::render_samples(scene, Mode::Rgb, &options(), 0..0).unwrap();
    // Two sample ranges, each in tiles of another shape (odd sizes: tiles
    // that do not line up with the render loop's 16-pixel work tiles).
    tiled(scene, 0..2, 7, 11, &mut merged);
    tiled(scene, 2..spp, 13, 5, &mut merged);
    assert_eq!(merged.ranges(), &[0..spp], "{what}");
    assert!(merged == one, "{what}: tiles differ from one render");
    let (a, b) = (merged.develop(), one.develop());
    assert!(a.pixels.iter().zip(&b.pixels).all(|(p, q)| p.0.map(f32::to_bits) == q.0.map(f32::to_bits)), "{what}");
    assert!(b.pixels.iter().filter(|p| p.0[0] > 0.0).count() > b.pixels.len() / 4, "{what}: image black");
}

#[test]
fn tiles_with_a_wide_filter_merge_into_exactly_one_render() {
    let scene = cornell("path", "");
    assert!(scene.film.filter.radius() > 0.5);
    assert_tiles_equal_one_render(&scene, "cornell, gaussian");
    // The borders matter: without them (the tile's own pixels only) the
    // merged state would differ. A tile's state keeps its border pixels.
    let t = snell::session::render_tile_samples(&scene, Mode::Rgb, &options(), 0..1, [8, 8, 8, 8]).unwrap();
    let region = *t.tile().unwrap();
    assert_eq!(region.pixels, [8, 8, 8, 8]);
    let reach = (scene.film.filter.radius() + 0.5).ceil() as u32;
    assert_eq!(region.window, [8 - reach, 8 - reach, 8 + 2 * reach, 8 + 2 * reach]);
    let image = t.develop();
    assert_eq!(image.width, 8 + 2 * reach);
    // Two pixels left of the tile, mid-height: within the filter's radius
    // (2) of the tile's samples, so its sum is not zero.
    let w = image.width as usize;
    assert!(image.pixels[(reach as usize + 4) * w + reach as usize - 2].0[0] > 0.0, "the border received no filter weight");
    // A tile's state survives serialisation (what a Ray task returns).
    assert_eq!(FilmState::from_bytes(&t.to_bytes()).unwrap(), t);
}

#[test]
fn tiles_of_a_crop_window_and_of_light_tracing_merge_exactly() {
    let crop = r#"<integer name="crop_offset_x" value="5"/><integer name="crop_offset_y" value="9"/><integer name="crop_width" value="23"/><integer name="crop_height" value="17"/>"#;
    let scene = cornell("path", crop);
    assert_eq!(scene.film.crop, [5, 9, 23, 17]);
    assert_tiles_equal_one_render(&scene, "crop window");
    assert_tiles_equal_one_render(&cornell("ptracer", ""), "ptracer");
}

#[test]
fn bad_tilings_are_refused() {
    let scene = cornell("path", "");
    let tile = |r: std::ops::Range<u32>, t: [u32; 4]| snell::session::render_tile_samples(&scene, Mode::Rgb, &options(), r, t).unwrap();
    let empty = || snell::session::render_samples(&scene, Mode::Rgb, &options(), 0..0).unwrap();
    let (left, right) = (tile(0..1, [0, 0, 20, 40]), tile(0..1, [20, 0, 20, 40]));
    let err = |tiles: &[FilmState]| empty().merge_tiles(tiles).unwrap_err().to_string();
    assert!(err(std::slice::from_ref(&left)).contains("cover 800 of"));
    assert!(err(&[left.clone(), tile(0..1, [19, 0, 21, 40])]).contains("overlap"));
    assert!(err(&[left.clone(), tile(1..2, [20, 0, 20, 40])]).contains("same complete ranges"));
    // A tile is not merged as a whole window, nor into a tile.
    assert!(empty().merge(&left).unwrap_err().to_string().contains("tile"));
    assert!(left.clone().merge_tiles(&[right.clone()]).is_err());
    // Samples already held are refused.
    let mut once = empty();
    once.merge_tiles(&[left.clone(), right.clone()]).unwrap();
    assert!(once.merge_tiles(&[left, right]).unwrap_err().to_string().contains("both hold samples"));
    // Tiles outside the film.
    assert!(snell::session::render_tile_samples(&scene, Mode::Rgb, &options(), 0..1, [30, 0, 20, 4]).is_err());
    assert!(snell::session::render_tile_samples(&scene, Mode::Rgb, &options(), 0..1, [0, 0, 0, 4]).is_err());
}

#[test]
fn a_render_resumes_from_any_complete_sample_ranges() {
    let scene = cornell("path", "");
    let spp = scene.sampler.sample_count;
    let one = snell::session::render_samples(&scene, Mode::Rgb, &options(), 0..spp).unwrap();
    // What a distributed checkpoint may hold: chunks finished out of order.
    let mut held = snell::session::render_samples(&scene, Mode::Rgb, &options(), 1..2).unwrap();
    held.merge(&snell::session::render_samples(&scene, Mode::Rgb, &options(), 4..5).unwrap()).unwrap();
    let opts = RenderOptions { threads: 2, passes: 3, ..RenderOptions::default() };
    let mut reports = vec![];
    let (_, stats, state) = snell::session::render_from(&scene, Mode::Rgb, &opts, Some(held), &mut |r| reports.push(r.spp_done)).unwrap();
    assert!(state == one, "resumed state differs from one render");
    assert_eq!(stats.spp_done, spp);
    // Every pass adds the samples it misses; the last holds all of them.
    assert!(reports.windows(2).all(|w| w[0] < w[1]) && reports.last() == Some(&spp), "{reports:?}");
    // 6 spp in 3 passes end at 1, 3, 6: they render [0, 1), [2, 3), then
    // [3, 4) and [5, 6).
    assert_eq!(reports, vec![3, 4, 6]);
}

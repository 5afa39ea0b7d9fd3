//! Birefringence in whole renders: `scenes/calcite.xml`, a calcite slab
//! (1.0 thick, optic axis at 45° to its faces) on a backlit page seen from
//! straight above by an orthographic camera (64 pixels per unit, a box
//! filter), shows a thin line of the page twice: the ordinary image straight
//! through, the extraordinary one displaced by d·tan ρ (the walk-off). The
//! two are polarized at right angles: a polarizer along x (θ = 0, in the
//! plane of the optic axis) keeps only the extraordinary image, one along y
//! only the ordinary one; at 45° each keeps half (Malus).


use crate::common::*;
use snell::bsdf::birefringent::crystal_index;
use snell::film::Image;
use snell::spectrum::{Polarized, Rgb, Spectrum};

const RES: usize = 128;
const SPP: u32 = 32;
/// Slab thickness (world units) and pixels per world unit.
const THICKNESS: f64 = 1.0;
const PIXELS_PER_UNIT: f64 = RES as f64 / 2.0;
/// The line on the page: texel columns 56–57 of 256 across [-1, 1], i.e.
/// x = −0.5547, the centre of pixel column 28.
const LINE_PIXEL: f64 = 28.5;

fn render<S: Spectrum>(extra: &[(&str, &str)]) -> Image {
    let mut p = vec![("res", "128"), ("max_depth", "8")];
    p.extend_from_slice(extra);
    average(&render_passes_as::<S>(&repo("scenes/calcite.xml"), None, params(&p), 1, SPP))
}

/// The walk-off of calcite at the d line (RGB's wavelength), 45° to the axis.
fn walk_off_pixels() -> f64 {
    let (n_o, n_e) = (crystal_index("calcite", false).unwrap().nominal() as f64, crystal_index("calcite", true).unwrap().nominal() as f64);
    let theta = std::f64::consts::FRAC_PI_4;
    let (s, c) = theta.sin_cos();
    let tan_rho = (n_o * n_o - n_e * n_e) * s * c / (n_e * n_e * c * c + n_o * n_o * s * s);
    THICKNESS * tan_rho * PIXELS_PER_UNIT
}

/// Total brightness and centroid (pixel coordinates, centres at i + ½) of
/// the columns [lo, hi) summed over all rows. Left of the word (columns
/// below 35) only the line's copies are lit.
fn copy(img: &Image, lo: usize, hi: usize) -> (f64, f64) {
    let (mut sum, mut moment) = (0.0, 0.0);
    for y in 0..img.height as usize {
        for x in lo..hi {
            let v = img.pixels[y * img.width as usize + x].mean() as f64;
            sum += v;
            moment += v * (x as f64 + 0.5);
        }
    }
    (sum, moment / sum)
}

/// (ordinary, extraordinary) copies: windows of 7 columns around each.
fn copies(img: &Image) -> ((f64, f64), (f64, f64)) {
    let e = (LINE_PIXEL - walk_off_pixels()).floor() as usize;
    (copy(img, 25, 32), copy(img, e - 3, e + 4))
}

#[test]
fn the_double_image_is_displaced_by_the_walk_off() {
    let rho = walk_off_pixels();
    // 6.2° over a thickness of 1: 0.109 units, 6.99 pixels.
    assert!((rho / PIXELS_PER_UNIT - 0.109).abs() < 0.001, "{rho}");
    for (name, img) in [("rgb", render::<Rgb>(&[])), ("rgb-polarized", render::<Polarized<Rgb>>(&[]))] {
        let ((i_o, c_o), (i_e, c_e)) = copies(&img);
        println!("{name}: ordinary copy at {c_o:.3} px ({i_o:.2}), extraordinary at {c_e:.3} px ({i_e:.2}); separation {:.3} px, predicted {rho:.3}", c_o - c_e);
        assert!((c_o - LINE_PIXEL).abs() < 0.1, "{name}: the ordinary image is not displaced: {c_o}");
        assert!((c_o - c_e - rho).abs() < 0.1, "{name}: separation {} px vs d·tan ρ = {rho} px", c_o - c_e);
        // Both copies are bright, each about half the light.
        assert!(i_o > 0.0 && (i_e / i_o - 1.0).abs() < 0.15, "{name}: {i_o} vs {i_e}");
    }
}

#[test]
fn a_polarizer_extinguishes_one_copy_then_the_other() {
    let open = render::<Polarized<Rgb>>(&[]);
    let ((o_open, _), (e_open, _)) = copies(&open);
    let along_x = render::<Polarized<Rgb>>(&[("polarizing", "true"), ("theta", "0")]);
    let along_y = render::<Polarized<Rgb>>(&[("polarizing", "true"), ("theta", "90")]);
    let diagonal = render::<Polarized<Rgb>>(&[("polarizing", "true"), ("theta", "45")]);
    let ((o_x, _), (e_x, _)) = copies(&along_x);
    let ((o_y, _), (e_y, _)) = copies(&along_y);
    let ((o_d, _), (e_d, _)) = copies(&diagonal);
    println!("open: o {o_open:.3} e {e_open:.3}; θ=0: o {o_x:.3e} e {e_x:.3}; θ=90: o {o_y:.3} e {e_y:.3e}; θ=45: o {o_d:.3} e {e_d:.3}");
    // θ = 0 (along x, the plane of the optic axis): the e-ray's polarization passes.
    assert!(o_x < 1e-3 * o_open, "ordinary copy behind a polarizer along x: {o_x} of {o_open}");
    assert!((e_x / e_open - 1.0).abs() < 0.08, "extraordinary copy: {e_x} of {e_open}");
    assert!(e_y < 1e-3 * e_open, "extraordinary copy behind a polarizer along y: {e_y} of {e_open}");
    assert!((o_y / o_open - 1.0).abs() < 0.08, "ordinary copy: {o_y} of {o_open}");
    // Malus: cos² 45° = ½ of each.
    assert!((o_d / o_open - 0.5).abs() < 0.05 && (e_d / e_open - 0.5).abs() < 0.05, "{o_d} {e_d}");
}

/// A white furnace: a calcite sphere (optic axis tilted) alone in a
/// uniform white sky renders 1 — no light created or lost at any interface,
/// and the radiance scaling of each ray (o and e, by the curvature of its
/// wave surface) consistent along every path, however it splits.
#[test]
fn a_birefringent_sphere_in_a_white_furnace_renders_one() {
    let text = furnace(
        r#"<shape type="sphere"><float name="radius" value="1"/>
            <bsdf type="birefringent"><string name="ordinary_ior" value="calcite"/><string name="extraordinary_ior" value="calcite"/>
                <vector name="optic_axis" x="1" y="0.5" z="0.7"/></bsdf></shape>"#,
        32,
        24,
    );
    let path = std::path::Path::new("furnace.xml");
    for polarized in [false, true] {
        let img = if polarized {
            average(&render_passes_as::<Polarized<Rgb>>(path, Some(&text), params(&[]), 1, 256))
        } else {
            average(&render_passes_as::<Rgb>(path, Some(&text), params(&[]), 1, 256))
        };
        let m = mean(&img);
        // Rows of 32 pixels: each row's mean is 1 too (the sphere covers the middle).
        let worst_row = (0..img.height as usize)
            .map(|y| {
                let row = &img.pixels[y * img.width as usize..(y + 1) * img.width as usize];
                (row.iter().map(|p| p.mean() as f64).sum::<f64>() / row.len() as f64 - 1.0).abs()
            })
            .fold(0.0, f64::max);
        println!("furnace, polarized {polarized}: mean {m:?}, worst row off by {worst_row:.4}");
        assert!(m.iter().all(|v| (v - 1.0).abs() < 0.01), "polarized {polarized}: mean {m:?}");
        assert!(worst_row < 0.04, "polarized {polarized}: a row off by {worst_row}");
    }
}

/// Bad parameters are located errors that say what is valid.
#[test]
fn bad_crystal_parameters_are_located_errors() {
    let load = |bsdf: &str| {
        let text = format!("<scene version=\"3.0.0\">\n<shape type=\"sphere\">\n{bsdf}\n</shape>\n</scene>");
        match snell::load_str(std::path::Path::new("crystal.xml"), &text, &snell::LoadOptions::default()) {
            Ok(_) => panic!("{bsdf} loaded"),
            Err(e) => e.to_string(),
        }
    };
    let e = load(r#"<bsdf type="birefringent"><string name="ordinary_ior" value="calcit"/></bsdf>"#);
    assert!(e.contains("crystal.xml:3") && e.contains("calcit") && e.contains("quartz") && e.contains("sapphire"), "{e}");
    let e = load(r#"<bsdf type="birefringent"><vector name="optic_axis" x="0" y="0" z="0"/></bsdf>"#);
    assert!(e.contains("crystal.xml:3") && e.contains("optic_axis"), "{e}");
    let e = load(r#"<bsdf type="birefringent"><string name="extraordinary_ior" value="cauchy(1.5)"/></bsdf>"#);
    assert!(e.contains("2 coefficients"), "{e}");
}

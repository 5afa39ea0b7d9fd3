//! Spectral mode (`--mode spectral`): paths carry four sampled wavelengths.
//!
//! - Furnace: dispersive glass (BK7, diamond, water by their Sellmeier
//!   formulas, and an air bubble in dispersive water) in a white constant
//!   environment renders the environment's white everywhere: dispersion
//!   moves light between directions and wavelengths, never creates or
//!   destroys it (this also checks that cutting a path to its hero
//!   wavelength at a dispersive interface stays unbiased).
//! - Against Mitsuba 3.9.1's spectral variant (references in
//!   tests/references/spectral/, made by tools/make_references.py with
//!   `--variant llvm_ad_spectral`): the Cornell box and the caustic box.
//! - Mitsuba's spectrum plugins (`blackbody`, `d65`, `uniform`, `regular`,
//!   `irregular`, `srgb`) as emission and as reflectance, against Mitsuba
//!   3.9.1's spectral and RGB renders of the same scenes.

use crate::common::*;
use snell::film::output::read_exr;
use snell::film::Image;
use snell::spectrum::cie::{cie_xyz, d65_unit, xyz_to_linear_srgb, y_normalization};
use snell::spectrum::{Rgb, Sampled};
use std::path::Path;

/// What a white (RGB 1) emitter looks like through the spectral film: D65
/// of unit luminance in sRGB, (1, 1, 1) up to the tables' rounding.
fn spectral_white() -> Rgb {
    let mut xyz = [0.0f64; 3];
    for i in 0..=4700 {
        let l = 360.0 + i as f32 * 0.1;
        let w = if i == 0 || i == 4700 { 0.05 } else { 0.1 };
        let c = cie_xyz(l);
        for k in 0..3 {
            xyz[k] += (w * d65_unit(l) * c[k] * y_normalization()) as f64;
        }
    }
    xyz_to_linear_srgb(xyz.map(|v| v as f32))
}

#[test]
fn dispersive_glass_furnace_is_white() {
    let text = furnace(
        r#"<shape type="sphere"><point name="center" x="-1.1" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><string name="int_ior" value="sellmeier:bk7"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><string name="int_ior" value="sellmeier:diamond"/><float name="ext_ior" value="1"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="1.1" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.0"/><string name="ext_ior" value="sellmeier:water"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0" y="0.9" z="-0.5"/><float name="radius" value="0.4"/>
            <bsdf type="dielectric"><string name="int_ior" value="sellmeier(1.73759695, 0.313747346, 1.89878101; 0.013188707, 0.0623068142, 155.23629)"/></bsdf></shape>"#,
        64,
        48,
    );
    let white = spectral_white();
    for c in white.0 {
        assert!((c - 1.0).abs() < 3e-3, "spectral white {white:?}");
    }
    let expected = Image::new(64, 48, vec![white; 64 * 48]);
    let passes = render_passes_as::<Sampled>(Path::new("dispersive-furnace.xml"), Some(&text), Default::default(), 16, 16);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("dispersive glass furnace", 0.005);
}

fn check_against_mitsuba_spectral(scene: &str, reference: &str, spp: u32) {
    let reference = read_exr(&repo(reference)).expect("reference EXR");
    let passes = render_passes_as::<Sampled>(&repo(scene), None, params(&[("res", "64")]), 16, spp);
    // The references' own relative error per pixel is ≈ 0.3 % of the image mean.
    compare(&passes, &reference, 16, 0.004).assert_unbiased(scene, 0.01);
}

#[test]
fn cornell_box_matches_mitsuba_spectral() {
    check_against_mitsuba_spectral("scenes/cornell-box.xml", "tests/references/spectral/cornell-box.exr", 32);
}

#[test]
fn caustic_box_matches_mitsuba_spectral() {
    check_against_mitsuba_spectral("scenes/caustic-cornell-box.xml", "tests/references/spectral/caustic-cornell-box.exr", 64);
}

/// Issue 12: rough conductors (named metals with measured η(λ), k(λ); GGX
/// and Beckmann, anisotropic, textured α; rgb η/k, which Mitsuba's spectral
/// variants clamp to [0, 1] and uplift as a reflectance) in spectral mode
/// against Mitsuba's llvm_ad_spectral.
#[test]
fn rough_metals_match_mitsuba_spectral() {
    check_against_mitsuba_spectral("tests/scenes/rough-metals.xml", "tests/references/spectral/rough-metals.exr", 16);
}

/// A listed `<spectrum>` is used as such in spectral mode. A sphere whose
/// reflectance is a 20 nm band at 550 nm, in a constant environment emitting
/// the same band: a convex diffuse object in a uniform environment reflects
/// ρ(λ)·L(λ) exactly, so the sphere's colour is the spectrum 0.8·L(λ) seen
/// through the CIE observer, the background L(λ)'s. An uplift of the
/// reflectance's RGB colour (a broad green) would give a fraction of that.
#[test]
fn listed_spectra_are_used_at_each_wavelength() {
    let band = "530:0, 540:1, 560:1, 570:0";
    let reflect = "530:0, 540:0.8, 560:0.8, 570:0";
    let text = format!(
        r#"<scene version="3.0.0">
    <integrator type="path"/>
    <sensor type="perspective">
        <float name="fov" value="20"/>
        <transform name="to_world"><lookat origin="0,0,6" target="0,0,0" up="0,1,0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="64"/></sampler>
        <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="48"/><rfilter type="box"/></film>
    </sensor>
    <emitter type="constant"><spectrum name="radiance" value="{band}"/></emitter>
    <shape type="sphere"><float name="radius" value="0.8"/>
        <bsdf type="diffuse"><spectrum name="reflectance" value="{reflect}"/></bsdf></shape>
</scene>"#
    );
    let expect = |pairs: &[(f32, f32)]| snell::spectrum::cie::spectrum_to_linear_srgb(pairs, true);
    let l = [(530.0, 0.0), (540.0, 1.0), (560.0, 1.0), (570.0, 0.0)];
    // ρ(λ)·L(λ), both linear on their ramps: quadratic there, so tabulated finely.
    let (ls, rs) = (snell::spectrum::ListedSpectrum::new(l.to_vec()).unwrap(), snell::spectrum::ListedSpectrum::new(vec![(530.0, 0.0), (540.0, 0.8), (560.0, 0.8), (570.0, 0.0)]).unwrap());
    let rl: Vec<(f32, f32)> = (0..=400).map(|i| 530.0 + i as f32 * 0.1).map(|x| (x, ls.eval(x) * rs.eval(x))).collect();
    let (want_bg, want_sphere) = (expect(&l), expect(&rl));
    let passes = render_passes_as::<Sampled>(Path::new("band.xml"), Some(&text), params(&[]), 4, 64);
    let img = average(&passes);
    // Centre block (on the sphere, which covers the middle ~60 %) and corners (sky).
    let mean_of = |pixels: &mut dyn Iterator<Item = (u32, u32)>| {
        let (mut s, mut n) = ([0.0f64; 3], 0.0);
        for (x, y) in pixels {
            let p = img.pixels[(y * img.width + x) as usize];
            for c in 0..3 {
                s[c] += p[c] as f64;
            }
            n += 1.0;
        }
        s.map(|v| v / n)
    };
    let sphere = mean_of(&mut (18..30).flat_map(|y| (18..30).map(move |x| (x, y))));
    let sky = mean_of(&mut (0..4).flat_map(|y| (0..4).map(move |x| (x, y))));
    eprintln!("sphere {sphere:?} (expected {want_sphere:?}); sky {sky:?} (expected {want_bg:?})");
    for c in 0..3 {
        assert!((sphere[c] - want_sphere[c] as f64).abs() < 0.03 * want_sphere[1] as f64, "sphere channel {c}");
        assert!((sky[c] - want_bg[c] as f64).abs() < 0.03 * want_bg[1] as f64, "sky channel {c}");
    }
}

/// Mitsuba's spectrum plugins (`<spectrum type="…">`), each as an area
/// light's radiance seen head-on and as a diffuse reflectance under a white
/// constant sky (max_depth 2), against Mitsuba 3.9.1: the image means of the
/// same 4×4 scenes rendered by `scalar_spectral` and `scalar_rgb` at 65 536
/// spp (box filter, independent sampler). Mitsuba's RGB variants refuse
/// `blackbody`, `regular` and `irregular`; Snell's RGB mode converts them to
/// colours, which must then agree with the spectral renders.
#[test]
fn spectrum_plugins_match_mitsuba() {
    const CASES: [(&str, &str); 8] = [
        ("blackbody", r#"<spectrum type="blackbody" name="NAME"><float name="temperature" value="3000"/></spectrum>"#),
        (
            "blackbody 500–600 nm",
            r#"<spectrum type="blackbody" name="NAME"><float name="temperature" value="5000"/><float name="wavelength_min" value="500"/><float name="wavelength_max" value="600"/></spectrum>"#,
        ),
        ("d65", r#"<spectrum type="d65" name="NAME"/>"#),
        ("d65 colour", r#"<spectrum type="d65" name="NAME"><rgb name="color" value="0.2,0.4,0.6"/><float name="scale" value="2"/></spectrum>"#),
        ("uniform", r#"<spectrum type="uniform" name="NAME"><float name="value" value="0.5"/></spectrum>"#),
        (
            "regular",
            r#"<spectrum type="regular" name="NAME"><float name="wavelength_min" value="400"/><float name="wavelength_max" value="700"/><string name="values" value="0.1, 0.5, 0.9"/></spectrum>"#,
        ),
        ("irregular", r#"<spectrum type="irregular" name="NAME"><string name="wavelengths" value="400, 500, 700"/><string name="values" value="0.1, 0.5, 0.9"/></spectrum>"#),
        ("srgb", r#"<spectrum type="srgb" name="NAME"><rgb name="color" value="0.2,0.4,0.6"/></spectrum>"#),
    ];
    // Mitsuba's means per case: spectral (emitted, reflected), RGB (emitted,
    // reflected; `None` where Mitsuba refuses the plugin in RGB).
    type Means = ([f64; 3], [f64; 3], Option<([f64; 3], [f64; 3])>);
    let mitsuba: [Means; 8] = [
        ([733.879, 349.900, 112.659], [627.274, 366.849, 130.793], None),
        ([3564.91, 12463.58, -1095.64], [2770.65, 12906.68, -1090.59], None),
        ([0.99982, 0.99991, 0.99864], [0.81234, 1.05311, 1.10776], Some(([1.0, 1.0, 1.0], [0.99991, 0.99991, 0.99991]))),
        ([0.3994, 0.79962, 1.19847], [0.28776, 0.84566, 1.31767], Some(([0.4, 0.8, 1.2], [0.39996, 0.79992, 1.19988]))),
        ([0.60299, 0.47461, 0.45458], [0.49985, 0.49992, 0.49927], Some(([0.5, 0.5, 0.5], [0.49995, 0.49995, 0.49995]))),
        ([0.87312, 0.45917, 0.18125], [0.74351, 0.48157, 0.20824], None),
        ([0.91887, 0.56602, 0.24153], [0.77606, 0.59405, 0.27692], None),
        ([0.25928, 0.37809, 0.5512], [0.19976, 0.39989, 0.59937], Some(([0.2, 0.4, 0.6], [0.19998, 0.39996, 0.59994]))),
    ];
    let scene = |spectrum: &str, emitted: bool| {
        let body = if emitted {
            format!(r#"<shape type="rectangle"><emitter type="area">{}</emitter></shape>"#, spectrum.replace("NAME", "radiance"))
        } else {
            format!(r#"<emitter type="constant"/><shape type="rectangle"><bsdf type="diffuse">{}</bsdf></shape>"#, spectrum.replace("NAME", "reflectance"))
        };
        format!(
            r#"<scene version="3.0.0"><integrator type="path"><integer name="max_depth" value="2"/></integrator>
<sensor type="perspective"><float name="fov" value="10"/><transform name="to_world"><lookat origin="0,0,4" target="0,0,0" up="0,1,0"/></transform>
<film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/><rfilter type="box"/></film></sensor>{body}</scene>"#
        )
    };
    // Within 1.5 % of the case's largest channel (the spectral renders carry
    // wavelength noise: 4 passes of 1024 spp here, about 0.3 %).
    let check = |what: String, got: [f64; 3], want: [f64; 3]| {
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for c in 0..3 {
            assert!((got[c] - want[c]).abs() <= 0.015 * scale, "{what}: channel {c}: Snell {got:?}, Mitsuba {want:?}");
        }
    };
    for ((name, spectrum), (spectral, mitsuba_rgb)) in CASES.iter().zip(mitsuba.iter().map(|m| ((m.0, m.1), m.2))) {
        for (emitted, want) in [(true, spectral.0), (false, spectral.1)] {
            let text = scene(spectrum, emitted);
            let role = if emitted { "emitted" } else { "reflected" };
            let passes = render_passes_as::<Sampled>(Path::new("spectrum-plugin.xml"), Some(&text), Default::default(), 4, 1024);
            check(format!("{name}, {role}, spectral"), mean(&average(&passes)), want);
            let rgb = mean(&average(&render_passes_as::<Rgb>(Path::new("spectrum-plugin.xml"), Some(&text), Default::default(), 2, 256)));
            match mitsuba_rgb {
                // Mitsuba's own RGB value (exact for a light seen head-on).
                Some((e, r)) => check(format!("{name}, {role}, RGB"), rgb, if emitted { e } else { r }),
                // Snell's colour of the spectrum: the spectral render's.
                None => check(format!("{name}, {role}, RGB against spectral"), rgb, want),
            }
        }
    }
}

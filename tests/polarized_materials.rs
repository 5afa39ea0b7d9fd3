//! Thin dielectrics and plastic in the polarized modes (`bsdf/thindielectric.rs`,
//! `bsdf/plastic.rs`): their Mueller matrices keep the unpolarised
//! intensities, so a path that meets one of them between unpolarised light
//! and depolarising surfaces has the unpolarised S0; and a pane reflects the
//! sky s-polarised at Brewster's angle, which a crossed polarizer removes.

use crate::common::*;
use snell::spectrum::{Polarized, Rgb, Sampled};
use std::path::Path;

fn max_relative_difference(a: &snell::film::Image, b: &snell::film::Image) -> f32 {
    a.pixels.iter().zip(&b.pixels).map(|(x, y)| (0..3).map(|c| (x[c] - y[c]).abs() / (y[c].abs() + 1e-3)).fold(0.0f32, f32::max)).fold(0.0f32, f32::max)
}

/// A tilted thindielectric pane (left, with a diffuse sphere behind it) and
/// a plastic sphere (right, tinted coating, `nonlinear`) on a diffuse floor
/// under a white sky and a small area light. A diffuse wall in the plane
/// x = 0, seen edge-on by the camera, keeps the two apart: light polarised
/// by one of them never reaches the other without a diffuse bounce in
/// between, and S0 after two polarising interactions in a row would depend
/// on their relative orientation (the polarized modes are right to differ
/// from the unpolarised ones there).
const PANE_AND_PLASTIC: &str = r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="6"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="50"/>
        <transform name="to_world"><lookat origin="0, 1.2, 4" target="0, 0.5, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/><rfilter type="box"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="0.8, 0.9, 1.0"/></emitter>
    <shape type="rectangle">
        <transform name="to_world"><scale x="0.4" y="0.3" z="1"/><rotate x="1" angle="90"/><translate x="0.9" y="2.2" z="0.8"/></transform>
        <emitter type="area"><rgb name="radiance" value="6, 5.5, 5"/></emitter>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="6"/><rotate x="1" angle="-90"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.45, 0.4"/></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale x="6" y="3" z="1"/><rotate y="1" angle="90"/><translate y="3" z="-4"/></transform>
        <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.5, 0.3"/></bsdf></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale x="0.6" y="0.6" z="1"/><rotate y="1" angle="35"/><translate x="-0.8" y="0.65" z="0.4"/></transform>
        <bsdf type="thindielectric"><float name="int_ior" value="1.5"/><rgb name="specular_transmittance" value="0.9, 0.8, 0.6"/></bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="-0.9" y="0.35" z="-0.6"/>
        <float name="radius" value="0.35"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.2, 0.1"/></bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="0.8" y="0.45" z="0"/>
        <float name="radius" value="0.45"/>
        <bsdf type="plastic">
            <rgb name="diffuse_reflectance" value="0.1, 0.3, 0.7"/>
            <rgb name="specular_reflectance" value="0.9, 0.95, 1"/>
            <float name="int_ior" value="1.6"/>
            <boolean name="nonlinear" value="true"/>
        </bsdf>
    </shape>
</scene>"#;

#[test]
fn pane_and_plastic_intensity_matches_the_unpolarized_render() {
    let path = Path::new("pane-and-plastic.xml");
    let rgb = (average(&render_passes_as::<Polarized<Rgb>>(path, Some(PANE_AND_PLASTIC), params(&[]), 1, 4)), average(&render_passes_as::<Rgb>(path, Some(PANE_AND_PLASTIC), params(&[]), 1, 4)));
    let spectral = (
        average(&render_passes_as::<Polarized<Sampled>>(path, Some(PANE_AND_PLASTIC), params(&[]), 1, 4)),
        average(&render_passes_as::<Sampled>(path, Some(PANE_AND_PLASTIC), params(&[]), 1, 4)),
    );
    for (name, (a, b)) in [("rgb", rgb), ("spectral", spectral)] {
        let worst = max_relative_difference(&a, &b);
        let m = mean(&b);
        eprintln!("{name}: mean {m:.4?}, largest relative difference of S0 from the unpolarised image {worst:e}");
        assert!(m.iter().all(|&v| v > 0.05), "{name}: the scene is lit: {m:?}");
        assert!(worst < 1e-4, "{name}: largest relative difference {worst}");
    }
}

/// A thin pane lying flat (η 1.5, black below) reflects a white sky towards
/// a camera at Brewster's angle atan(1.5): every bounce order reflects s only,
/// so the reflection, of intensity R' = 2R/(1 + R) (R = ½R⊥, the unpolarised
/// single-interface term, as in the unpolarised mode), is s-polarised. A
/// polarizer in front of the camera passes all of it with its axis along s
/// and none crossed; the unpolarised mode sees a 50 % filter either way.
#[test]
fn thin_pane_brewster_reflection_vanishes_behind_a_crossed_polarizer() {
    let eta = 1.5f32;
    let brewster = eta.atan();
    let render = |text: &str, polarized: bool| {
        let path = Path::new("thin-brewster.xml");
        let passes = if polarized {
            render_passes_as::<Polarized<Rgb>>(path, Some(text), params(&[]), 8, 512)
        } else {
            render_passes_as::<Rgb>(path, Some(text), params(&[]), 8, 512)
        };
        mean(&average(&passes))[1]
    };
    let r = 0.5 * snell::bsdf::fresnel::fresnel_dielectric(brewster.cos(), eta).r_perpendicular as f64;
    let slab = 2.0 * r / (1.0 + r);
    let bare = render(&brewster_scene("thindielectric", None), true);
    let along_s = render(&brewster_scene("thindielectric", Some(0.0)), true);
    let crossed = render(&brewster_scene("thindielectric", Some(90.0)), true);
    eprintln!("R' = {slab:.5}: bare {bare:.5}, polarizer along s {along_s:.5}, crossed {crossed:.6}");
    // Reflection is sampled with probability R' ≈ 0.14: 8 × 512 spp × 64 pixels keep the noise near 0.5 %.
    assert!((bare - slab).abs() < 0.03 * slab, "bare {bare} vs {slab}");
    assert!((along_s - slab).abs() < 0.03 * slab, "along s {along_s} vs {slab}");
    assert!(crossed < 1e-3 * slab, "crossed polarizer still passes {crossed}");
    let bare_rgb = render(&brewster_scene("thindielectric", None), false);
    let crossed_rgb = render(&brewster_scene("thindielectric", Some(90.0)), false);
    eprintln!("unpolarised mode: bare {bare_rgb:.5}, crossed {crossed_rgb:.5}");
    assert!((bare_rgb - slab).abs() < 0.03 * slab && (crossed_rgb - 0.5 * slab).abs() < 0.03 * slab, "{bare_rgb} {crossed_rgb}");
}

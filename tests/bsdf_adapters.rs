//! BSDF adapters and cut-outs (issue 11): `mask`, `null`, `blendbsdf`,
//! `normalmap`, `bumpmap`, `twosided` with two BSDFs, `polarizer` angles
//! given as `<spectrum>`. Against committed Mitsuba 3.9.1 references
//! (tests/references/mask-leaf.exr, normal-bump.exr; see
//! tests/references/README.md) and closed forms: a `null` shape or a mask
//! of opacity 0 renders the image of the scene without it, a mask of
//! opacity 1 that of its nested BSDF.

use crate::common::*;
use snell::bsdf::Bsdf;
use snell::film::Image;
use snell::film::output::read_exr;
use std::path::Path;

/// Snell against a Mitsuba reference: 16 passes × `spp`, means within 1 %,
/// every 16×16 block within its noise (`ref_rel_err`: the reference's own
/// relative error per pixel, from tests/references/README.md).
fn check_spp(scene: &str, reference: &str, spp: u32, ref_rel_err: f64) {
    let reference = read_exr(&repo(reference)).expect("reference EXR");
    let passes = render_passes(&repo(scene), None, params(&[("res", "128")]), 16, spp);
    compare(&passes, &reference, 16, ref_rel_err).assert_unbiased(scene, 0.01);
}

#[test]
fn mask_leaf_and_its_shadow_match_mitsuba() {
    check_spp("tests/scenes/mask-leaf.xml", "tests/references/mask-leaf.exr", 16, 0.003);
}

#[test]
fn normal_and_bump_maps_match_mitsuba() {
    check_spp("tests/scenes/normal-bump.xml", "tests/references/normal-bump.exr", 16, 0.003);
}

const LEAF: &str = "tests/scenes/mask-leaf.xml";

fn leaf_text() -> String {
    std::fs::read_to_string(repo(LEAF)).expect("scene")
}

/// The byte range of the leaf's `<bsdf type="mask">…</bsdf>` and of its
/// whole `<shape>`.
fn leaf_ranges(text: &str) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
    let b0 = text.find("<bsdf type=\"mask\">").expect("mask");
    let b1 = b0 + text[b0..].find("</bsdf>\n    </shape>").expect("end of mask") + "</bsdf>".len();
    let s0 = text[..b0].rfind("<shape").expect("shape");
    let s1 = b1 + text[b1..].find("</shape>").expect("end of shape") + "</shape>".len();
    (b0..b1, s0..s1)
}

fn with_leaf_bsdf(bsdf: &str) -> String {
    let text = leaf_text();
    let (b, _) = leaf_ranges(&text);
    format!("{}{bsdf}{}", &text[..b.start], &text[b.end..])
}

fn without_leaf() -> String {
    let text = leaf_text();
    let (_, s) = leaf_ranges(&text);
    format!("{}{}", &text[..s.start], &text[s.end..])
}

fn render_text(text: &str) -> Image {
    render_passes(&repo(LEAF), Some(text), params(&[("res", "48")]), 1, 8).remove(0)
}

/// The two renders agree pixel by pixel (the same random numbers drive both:
/// a fully transparent surface draws none). Rays continued past an
/// invisible surface start from its far side, a rounding-level change of
/// origin that may send a rare path another way, so a few pixels may differ.
fn assert_same_image(a: &Image, b: &Image, what: &str) {
    let (ma, mb) = (mean(a), mean(b));
    let (mut differ, mut worst) = (0, 0.0f32);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        let d = (0..3).map(|c| (p[c] - q[c]).abs() / (0.01 + q[c].abs())).fold(0.0, f32::max);
        worst = worst.max(d);
        if d > 1e-3 {
            differ += 1;
        }
    }
    eprintln!("{what}: means {ma:?} vs {mb:?}, {differ} of {} pixels differ by more than 0.1 %, at most {worst:.2e}", a.pixels.len());
    assert!(differ * 100 <= a.pixels.len() && worst < 1e-2, "{what}: {differ} pixels differ, at most {worst}");
    for c in 0..3 {
        assert!((ma[c] - mb[c]).abs() <= 1e-3 * mb[c], "{what}: channel {c} mean {} vs {}", ma[c], mb[c]);
    }
}

#[test]
fn a_null_shape_is_invisible() {
    let null = render_text(&with_leaf_bsdf(r#"<bsdf type="null"/>"#));
    let none = render_text(&without_leaf());
    assert_same_image(&null, &none, "null leaf vs no leaf");
}

#[test]
fn a_mask_of_opacity_zero_is_invisible_and_of_opacity_one_is_its_nested_bsdf() {
    let nested = r#"<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.25, 0.6, 0.15"/></bsdf></bsdf>"#;
    let mask = |opacity: &str| format!(r#"<bsdf type="mask"><float name="opacity" value="{opacity}"/>{nested}</bsdf>"#);
    let clear = render_text(&with_leaf_bsdf(&mask("0")));
    assert_same_image(&clear, &render_text(&without_leaf()), "opacity 0 vs no leaf");
    let opaque = render_text(&with_leaf_bsdf(&mask("1")));
    let plain = render_text(&with_leaf_bsdf(nested));
    assert_same_image(&opaque, &plain, "opacity 1 vs the nested BSDF");
    // And the cut-out leaf differs from both: its holes let light through.
    let leaf = render_text(&leaf_text());
    let (ml, mo, mc) = (mean(&leaf)[0], mean(&opaque)[0], mean(&clear)[0]);
    assert!(mo < ml && ml < mc, "opaque {mo} < leaf {ml} < clear {mc}");
}

/// A constant white environment over a two-sided rectangle seen from the
/// front and from the back: direct lighting of a plane open to the whole
/// hemisphere is its albedo, 0.8 in front and 0.3 behind.
#[test]
fn twosided_with_two_bsdfs_shows_each_on_its_side() {
    let scene = |z: f32| {
        format!(
            r#"<scene version="3.0.0">
            <integrator type="direct"/>
            <sensor type="perspective">
                <float name="fov" value="20"/>
                <transform name="to_world"><lookat origin="0.3, 0.2, {z}" target="0, 0, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/><rfilter type="box"/></film>
            </sensor>
            <shape type="rectangle">
                <bsdf type="twosided">
                    <bsdf type="diffuse"><rgb name="reflectance" value="0.8"/></bsdf>
                    <bsdf type="diffuse"><rgb name="reflectance" value="0.3"/></bsdf>
                </bsdf>
            </shape>
            <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
        </scene>"#
        )
    };
    for (z, albedo) in [(4.0, 0.8), (-4.0, 0.3)] {
        let passes = render_passes(Path::new("twosided.xml"), Some(&scene(z)), Default::default(), 4, 64);
        let m = mean(&average(&passes));
        for c in 0..3 {
            assert!((m[c] - albedo).abs() < 0.01 * albedo, "camera at z = {z}: {m:?}, expected {albedo}");
        }
    }
}

#[test]
fn polarizer_and_retarder_angles_may_be_spectra_as_in_mitsubas_tutorials() {
    let scene = |theta: &str| {
        format!(
            r#"<scene version="3.0.0">
            <sensor type="perspective"><float name="fov" value="40"/>
                <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
            <shape type="rectangle"><bsdf type="polarizer">{theta}</bsdf></shape>
            <shape type="rectangle"><bsdf type="retarder">{}</bsdf></shape>
        </scene>"#,
            theta.replace("theta", "delta")
        )
    };
    let angles = |text: &str| {
        let s = snell::load_str(Path::new("p.xml"), text, &Default::default()).unwrap_or_else(|e| panic!("{e}"));
        let p = s.bsdfs.iter().find_map(|b| if let Bsdf::Polarizer(p) = b { Some(p.theta) } else { None }).expect("polarizer");
        let r = s.bsdfs.iter().find_map(|b| if let Bsdf::Retarder(r) = b { Some(r.delta) } else { None }).expect("retarder");
        (p, r)
    };
    let spectrum = angles(&scene(r#"<spectrum name="theta" value="45"/>"#));
    let float = angles(&scene(r#"<float name="theta" value="45"/>"#));
    assert_eq!(spectrum, float);
    assert!((spectrum.0 - 45f32.to_radians()).abs() < 1e-6 && (spectrum.1 - 45f32.to_radians()).abs() < 1e-6);
    let e = snell::load_str(Path::new("p.xml"), &scene(r#"<rgb name="theta" value="10, 20, 30"/>"#), &Default::default()).err().expect("an error");
    assert!(e.to_string().contains("one angle in degrees"), "{e}");
}

#[test]
fn adapters_without_their_parts_are_located_errors() {
    let scene = |bsdf: &str| format!("<scene version=\"3.0.0\">\n<shape type=\"sphere\">\n{bsdf}\n</shape>\n</scene>\n");
    for (bsdf, words) in [
        (r#"<bsdf type="mask"><float name="opacity" value="0.5"/></bsdf>"#, "mask takes exactly one nested BSDF"),
        (r#"<bsdf type="blendbsdf"><float name="weight" value="0.5"/><bsdf type="diffuse"/></bsdf>"#, "blendbsdf takes exactly two nested BSDFs"),
        (r#"<bsdf type="blendbsdf"><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#, "blendbsdf needs a \"weight\""),
        (r#"<bsdf type="normalmap"><bsdf type="diffuse"/></bsdf>"#, "normalmap needs a texture named \"normalmap\""),
        (r#"<bsdf type="bumpmap"><bsdf type="diffuse"/></bsdf>"#, "bumpmap takes exactly one nested height texture"),
    ] {
        let e = snell::load_str(Path::new("adapters.xml"), &scene(bsdf), &Default::default()).err().expect("an error");
        let msg = e.to_string();
        assert!(msg.contains(words) && msg.contains("adapters.xml:3"), "{bsdf}: {msg}");
    }
}

/// Shadow rays carry the transmittance of the masks they cross: under a
/// point light (reached only by emitter sampling), a floor shaded by a mask
/// of opacity 0.3 receives 0.7 of its light. (A shadow ray stopped by the
/// mask would leave it black, as Mitsuba 3.9.1's `path` does.)
#[test]
fn shadow_rays_pass_through_a_mask_in_proportion_to_its_transparency() {
    let scene = |mask: bool| {
        let sheet = if mask {
            r#"<shape type="rectangle">
                <transform name="to_world"><rotate x="1" angle="90"/><scale value="4"/><translate y="1.2"/></transform>
                <bsdf type="mask"><float name="opacity" value="0.3"/><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf>
            </shape>"#
        } else {
            ""
        };
        format!(
            r#"<scene version="3.0.0">
            <integrator type="direct"/>
            <sensor type="perspective">
                <float name="fov" value="50"/>
                <transform name="to_world"><lookat origin="0, 0.8, 1.5" target="0, 0, 0" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="24"/><rfilter type="box"/></film>
            </sensor>
            <shape type="rectangle">
                <transform name="to_world"><rotate x="1" angle="-90"/><scale value="3"/></transform>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>
            </shape>
            {sheet}
            <emitter type="point"><point name="position" x="0.2" y="3" z="0"/><rgb name="intensity" value="10"/></emitter>
        </scene>"#
        )
    };
    let render = |mask| mean(&average(&render_passes(Path::new("shadow.xml"), Some(&scene(mask)), Default::default(), 2, 64)));
    let (with, without) = (render(true), render(false));
    for c in 0..3 {
        let ratio = with[c] / without[c];
        assert!((ratio - 0.7).abs() < 0.005, "channel {c}: {ratio}");
    }
}

//! Particle tracing (`ptracer`): light paths splatted onto the film must give
//! the same image as camera paths, in expectation.

mod common;
use common::*;
use snell::film::Image;

/// The Cornell box with its integrator swapped for `ptracer`, against
/// Mitsuba's path-traced reference: the same expected image, reached from
/// the other end (including the light seen directly).
#[test]
fn cornell_box_ptracer_matches_mitsuba() {
    let path = repo("scenes/cornell-box.xml");
    let text = std::fs::read_to_string(&path).expect("scene");
    assert!(text.contains(r#"<integrator type="path">"#));
    let text = text.replace(r#"<integrator type="path">"#, r#"<integrator type="ptracer">"#);
    let reference = snell::film::output::read_exr(&repo("tests/references/cornell-box.exr")).expect("reference");
    let passes = render_passes(&path, Some(&text), params(&[("res", "128")]), 16, 16);
    compare(&passes, &reference, 8, 1.2e-3).assert_unbiased("cornell-box ptracer", 0.01);
}

/// `ptracer` with an orthographic camera is a located error, not a black
/// image; emitters at infinity are accepted (their light paths start on
/// the disk of the scene's bounding sphere).
#[test]
fn ptracer_refuses_what_it_cannot_connect() {
    let scene = |sensor: &str, emitter: &str| {
        let fov = if sensor == "perspective" { r#"<float name="fov" value="40"/>"# } else { "" };
        format!(
            r#"<scene version="3.0.0">
    <integrator type="ptracer"/>
    <sensor type="{sensor}">{fov}</sensor>
    {emitter}
    <shape type="sphere"/>
</scene>"#
        )
    };
    let options = snell::LoadOptions::default();
    let err = snell::load_str(std::path::Path::new("ortho.xml"), &scene("orthographic", r#"<emitter type="point"><rgb name="intensity" value="1"/></emitter>"#), &options)
        .err()
        .expect("orthographic + ptracer must fail")
        .to_string();
    assert!(err.contains("ortho.xml:2:5") && err.contains("perspective"), "{err}");
    for emitter in [r#"<emitter type="constant"/>"#, r#"<emitter type="directional"><vector name="direction" x="0" y="-1" z="0"/><rgb name="irradiance" value="1"/></emitter>"#] {
        snell::load_str(std::path::Path::new("env.xml"), &scene("perspective", emitter), &options).unwrap_or_else(|e| panic!("{emitter}: {e}"));
    }
}

/// Two independent sets of passes agree: image means within `tol` and every
/// `block`² block within its noise (two-sample z over the passes' spread).
fn assert_agree(name: &str, a: &[Image], b: &[Image], block: u32, tol: f64) {
    let (ma, mb) = (mean(&average(a)), mean(&average(b)));
    eprintln!("{name}: means {ma:?} vs {mb:?}");
    for c in 0..3 {
        assert!(mb[c] > 0.0, "{name}: channel {c} is black");
        assert!((ma[c] / mb[c] - 1.0).abs() < tol, "{name}: channel {c} means {} vs {}", ma[c], mb[c]);
    }
    let w = a[0].width;
    let stats = |set: &[Image], bx: u32, by: u32, c: usize| {
        let v: Vec<f64> = set
            .iter()
            .map(|img| {
                let mut s = 0.0f64;
                for y in by * block..(by + 1) * block {
                    for x in bx * block..(bx + 1) * block {
                        s += img.pixels[(y * w + x) as usize][c] as f64;
                    }
                }
                s / (block * block) as f64
            })
            .collect();
        let k = v.len() as f64;
        let m = v.iter().sum::<f64>() / k;
        (m, v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0) / k)
    };
    let (mut sum_z2, mut n, mut max_z) = (0.0, 0, 0.0f64);
    for by in 0..a[0].height / block {
        for bx in 0..w / block {
            for c in 0..3 {
                let ((m1, v1), (m2, v2)) = (stats(a, bx, by, c), stats(b, bx, by, c));
                if v1 + v2 <= 1e-14 {
                    continue;
                }
                let z = (m1 - m2) / (v1 + v2).sqrt();
                sum_z2 += z * z;
                n += 1;
                max_z = max_z.max(z.abs());
            }
        }
    }
    let mean_z2 = sum_z2 / n.max(1) as f64;
    eprintln!("{name}: {n} blocks, mean z² {mean_z2:.2}, max |z| {max_z:.2}");
    assert!(mean_z2 < 2.0, "{name}: mean z² {mean_z2:.2}: a bias larger than the noise");
    assert!(max_z < 6.0, "{name}: a block is {max_z:.1} standard errors off");
}

/// Light paths from infinity: tests/scenes/sky-sun-glass.xml with its glass
/// sphere made diffuse (a light path cannot reach the camera through a
/// delta surface), lit by its constant sky alone (seen directly too) and by
/// its directional sun alone, agrees with `path`.
#[test]
fn sky_and_sun_ptracer_match_path() {
    let scene = "tests/scenes/sky-sun-glass.xml";
    let text = std::fs::read_to_string(repo(scene)).expect("scene");
    let diffuse = text.replace(r#"<bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf>"#, r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>"#);
    assert_ne!(diffuse, text);
    let ptracer = diffuse.replace(r#"<integrator type="path">"#, r#"<integrator type="ptracer">"#);
    for (name, light) in [("sky", [("sun", "0")]), ("sun", [("sky", "0")])] {
        let list = params(&[("res", "64"), light[0]]);
        let a = render_passes(&repo(scene), Some(&ptracer), list.clone(), 16, 4);
        let b = render_passes(&repo(scene), Some(&diffuse), list, 16, 4);
        assert_agree(&format!("{name} ptracer vs path"), &a, &b, 16, 0.02);
    }
}

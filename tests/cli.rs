//! The `snell` command-line tool, run as a separate process on small scenes.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A diffuse sphere lit by a constant environment; 32×24 at 4 spp by default
/// (tests/scenes/cli-sphere.xml, which also has a Mitsuba reference).
const SCENE: &str = include_str!("scenes/cli-sphere.xml");

/// A fresh folder holding `scene.xml`.
fn setup(name: &str) -> (PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("snell-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("scene.xml");
    std::fs::write(&scene, SCENE).unwrap();
    (dir, scene)
}

fn snell(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_snell")).args(args).current_dir(cwd).output().expect("cannot run snell")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[track_caller]
fn assert_success(out: &Output) {
    assert!(
        out.status.success(),
        "snell failed ({}):\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[track_caller]
fn assert_failure(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success(), "snell should have failed:\n{stderr}");
    assert_ne!(out.status.code(), Some(0));
    assert!(!stderr.contains("panicked"), "snell panicked:\n{stderr}");
    stderr
}

#[track_caller]
fn read_exr(path: &Path) -> snell::film::Image {
    snell::film::output::read_exr(path).unwrap_or_else(|e| panic!("cannot read {}: {e:#}", path.display()))
}

#[test]
fn renders_exr_png_and_pfm() {
    let (dir, scene) = setup("formats");
    let (exr, png, pfm) = (dir.join("out.exr"), dir.join("out.png"), dir.join("out.pfm"));
    let out = snell(&["render", s(&scene), "-o", s(&exr), "-o", s(&png), "--output", s(&pfm)], &dir);
    assert_success(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("rendered 32×24 at 4 spp"), "{stderr}");

    let img = read_exr(&exr);
    assert_eq!((img.width, img.height), (32, 24));
    assert_eq!(img.pixels.len(), 32 * 24);
    assert!(img.pixels.iter().all(|p| (0..3).all(|c| p[c].is_finite() && p[c] >= 0.0)), "non-finite or negative pixels");
    // The environment (radiance 1) shows at the corner; the bluish sphere in the middle.
    let corner = img.pixels[0];
    assert!((0..3).all(|c| (corner[c] - 1.0).abs() < 1e-3), "corner {corner:?}");
    let centre = img.pixels[12 * 32 + 16];
    assert!(centre[2] > centre[0] && centre[0] > 0.0, "centre {centre:?}");

    let decoded = image::open(&png).expect("cannot read the PNG");
    assert_eq!((decoded.width(), decoded.height()), (32, 24));
    let rgb = decoded.to_rgb8();
    assert_eq!(rgb.get_pixel(0, 0).0, [255, 255, 255]);

    let bytes = std::fs::read(&pfm).unwrap();
    let header = b"PF\n32 24\n-1.0\n";
    assert!(bytes.starts_with(header), "PFM header {:?}", String::from_utf8_lossy(&bytes[..header.len().min(bytes.len())]));
    assert_eq!(bytes.len(), header.len() + 32 * 24 * 3 * 4);
    // PFM stores the bottom row first.
    let last_row_first = f32::from_le_bytes(bytes[header.len()..header.len() + 4].try_into().unwrap());
    assert_eq!(last_row_first.to_bits(), img.pixels[23 * 32][0].to_bits());
}

#[test]
fn default_output_is_the_scene_name_in_the_current_folder() {
    let (dir, _scene) = setup("default-output");
    let out = snell(&["render", "scene.xml", "-q"], &dir);
    assert_success(&out);
    assert!(out.stderr.is_empty(), "-q should print nothing: {}", String::from_utf8_lossy(&out.stderr));
    let img = read_exr(&dir.join("scene.exr"));
    assert_eq!((img.width, img.height), (32, 24));
}

#[test]
fn stats_json() {
    let (dir, scene) = setup("stats");
    let stats = dir.join("stats.json");
    let out = snell(&["render", s(&scene), "-o", s(&dir.join("o.exr")), "--stats", s(&stats), "--threads", "2", "-q"], &dir);
    assert_success(&out);
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).expect("stats are not JSON");
    assert_eq!(json["width"], 32);
    assert_eq!(json["height"], 24);
    assert_eq!(json["spp"], 4);
    assert_eq!(json["threads"], 2);
    let seconds = json["render_seconds"].as_f64().expect("render_seconds");
    assert!(seconds >= 0.0 && seconds.is_finite(), "{json}");
    let rate = json["samples_per_second"].as_f64().expect("samples_per_second");
    assert!(rate > 0.0 && rate.is_finite(), "{json}");
}

/// Mitsuba 3.9.1's rgb / spectral ratio of the image means of
/// tests/scenes/cli-sphere.xml, 1.00001 ± 0.00008 (scalar_rgb against
/// scalar_spectral, 16 × 1024 spp each): a white environment and a diffuse
/// sphere lose nothing to the spectral uplift.
const MITSUBA_RGB_OVER_SPECTRAL: (f64, f64) = (1.00001, 0.00008);

/// `--mode spectral` renders another image (wavelength noise) and says so in
/// `--stats`; a mode that does not exist is refused with the valid names.
/// Its brightness is checked, not guessed. The spectral path (16 passes ×
/// 64 spp, in-process: the CLI's spectral start-up costs seconds per run)
/// must match Mitsuba's scalar_spectral reference
/// (tests/references/spectral/cli-sphere.exr, 16 384 spp) within noise —
/// means within 1 % per channel, every 8×8 block within its standard error.
/// The CLI's two 4-spp images must have Mitsuba's rgb / spectral ratio of
/// the image means within four standard errors of a 4-spp image mean
/// (computed from the spread of the passes).
#[test]
fn spectral_mode() {
    let (dir, scene) = setup("spectral");
    let (rgb, spectral, stats) = (dir.join("rgb.exr"), dir.join("spectral.exr"), dir.join("stats.json"));
    assert_success(&snell(&["render", s(&scene), "-o", s(&rgb), "-q"], &dir));
    assert_success(&snell(&["render", s(&scene), "-o", s(&spectral), "--mode", "spectral", "--stats", s(&stats), "-q"], &dir));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(json["mode"], "spectral");
    let (a, b) = (read_exr(&rgb), read_exr(&spectral));
    assert_ne!(a.pixels, b.pixels);
    let err = assert_failure(&snell(&["render", s(&scene), "--mode", "polarized"], &dir));
    assert!(err.contains("rgb") && err.contains("spectral"), "{err}");

    let spp = 64;
    let rgb_passes = common::render_passes_as::<snell::spectrum::Rgb>(&scene, None, common::params(&[]), 16, spp);
    let spectral_passes = common::render_passes_as::<snell::spectrum::Sampled>(&scene, None, common::params(&[]), 16, spp);
    let reference = read_exr(&common::repo("tests/references/spectral/cli-sphere.exr"));
    // The reference's per-pixel relative error is 1.5e-3 (its README); an 8×8
    // block's, with the pixel filter sharing samples, at most a quarter of it.
    common::compare(&spectral_passes, &reference, 8, 4e-4).assert_unbiased("cli-sphere spectral", 0.01);

    // The relative standard deviation of one 4-spp image's mean (over pixels
    // and channels): that of a pass, × √(spp / 4).
    let rel_std_4spp = |imgs: &[snell::film::Image]| {
        let m: Vec<f64> = imgs.iter().map(|img| common::mean(img).iter().sum::<f64>() / 3.0).collect();
        let avg = m.iter().sum::<f64>() / m.len() as f64;
        let var = m.iter().map(|x| (x - avg).powi(2)).sum::<f64>() / (m.len() - 1) as f64;
        var.sqrt() / avg * (spp as f64 / 4.0).sqrt()
    };
    let (rel_rgb, rel_spec) = (rel_std_4spp(&rgb_passes), rel_std_4spp(&spectral_passes));
    let mean = |img: &snell::film::Image| common::mean(img).iter().sum::<f64>() / 3.0;
    let ratio = mean(&a) / mean(&b);
    let (expected, expected_err) = MITSUBA_RGB_OVER_SPECTRAL;
    let bound = 4.0 * (ratio * ratio * (rel_rgb * rel_rgb + rel_spec * rel_spec) + expected_err * expected_err).sqrt();
    eprintln!("cli-sphere rgb / spectral {ratio:.5}, Mitsuba's {expected}, bound ± {bound:.5}");
    assert!((ratio - expected).abs() < bound, "rgb {} / spectral {} = {ratio:.5}, Mitsuba's {expected} ± {bound:.5}", mean(&a), mean(&b));
}

#[test]
fn spp_and_defines_take_effect() {
    let (dir, scene) = setup("overrides");
    let (exr, stats) = (dir.join("o.exr"), dir.join("stats.json"));
    let out = snell(&["render", s(&scene), "-o", s(&exr), "--spp", "2", "-D", "res=16", "-D", "height=8", "--stats", s(&stats)], &dir);
    assert_success(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("rendered 16×8 at 2 spp"), "{stderr}");
    let img = read_exr(&exr);
    assert_eq!((img.width, img.height), (16, 8));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!((json["width"].as_u64(), json["height"].as_u64(), json["spp"].as_u64()), (Some(16), Some(8), Some(2)));

    // Just one of the two parameters.
    let out = snell(&["render", s(&scene), "-o", s(&exr), "-q", "-D", "res=16"], &dir);
    assert_success(&out);
    let img = read_exr(&exr);
    assert_eq!((img.width, img.height), (16, 24));
}

#[test]
fn bad_define_and_bad_spp() {
    let (dir, scene) = setup("bad-args");
    let out_exr = dir.join("o.exr");
    let stderr = assert_failure(&snell(&["render", s(&scene), "-o", s(&out_exr), "-D", "res"], &dir));
    assert!(stderr.contains("expected NAME=VALUE"), "{stderr}");
    let stderr = assert_failure(&snell(&["render", s(&scene), "-o", s(&out_exr), "-D", "a b=1"], &dir));
    assert!(stderr.contains("not a valid parameter name"), "{stderr}");
    let stderr = assert_failure(&snell(&["render", s(&scene), "-o", s(&out_exr), "--spp", "0"], &dir));
    assert!(stderr.contains("--spp must be at least 1"), "{stderr}");
    // A define whose value is wrong where it is used: the error is located in the scene.
    let stderr = assert_failure(&snell(&["render", s(&scene), "-o", s(&out_exr), "-D", "res=0"], &dir));
    assert!(stderr.contains(&format!("{}:17:13", scene.display())), "{stderr}");
    assert!(stderr.contains("\"width\" must be between 1 and 65536"), "{stderr}");
    assert!(!out_exr.exists());
}

#[test]
fn bad_scene_reports_file_line_and_column() {
    let (dir, scene) = setup("bad-scene");
    std::fs::write(&scene, SCENE.replace("<bsdf type=\"diffuse\">", "<bsdf type=\"difuse\">")).unwrap();
    let out_exr = dir.join("o.exr");
    let stderr = assert_failure(&snell(&["render", s(&scene), "-o", s(&out_exr)], &dir));
    assert!(stderr.contains(&format!("{}:25:9", scene.display())), "{stderr}");
    assert!(stderr.contains("error: unknown bsdf plugin \"difuse\""), "{stderr}");
    assert!(stderr.contains("25 |         <bsdf type=\"difuse\">"), "{stderr}");
    assert!(stderr.contains("valid choices are: birefringent, blendbsdf, bumpmap, conductor, dielectric, diffuse, mask, normalmap, null, plastic, polarizer, pplastic, principled, principledthin, retarder, roughconductor, roughdielectric, roughplastic, thindielectric, twosided"), "{stderr}");
    assert!(!out_exr.exists());

    // An undefined parameter on the command line's side.
    std::fs::write(&scene, SCENE.replace("<default name=\"height\" value=\"24\"/>", "")).unwrap();
    let stderr = assert_failure(&snell(&["render", s(&scene), "-o", s(&out_exr)], &dir));
    assert!(stderr.contains(&format!("{}:18:36", scene.display())), "{stderr}");
    assert!(stderr.contains("undefined parameter \"$height\""), "{stderr}");
    // ... which -D fixes.
    assert_success(&snell(&["render", s(&scene), "-o", s(&out_exr), "-q", "-D", "height=4"], &dir));
    assert_eq!(read_exr(&out_exr).height, 4);
}

#[test]
fn unknown_output_extension() {
    let (dir, scene) = setup("bad-extension");
    let jpg = dir.join("out.jpg");
    let stderr = assert_failure(&snell(&["render", s(&scene), "-o", s(&dir.join("ok.exr")), "-o", s(&jpg)], &dir));
    assert!(stderr.contains("cannot tell the image format of"), "{stderr}");
    assert!(stderr.contains("out.jpg"), "{stderr}");
    assert!(stderr.contains(".exr, .png, .pfm"), "{stderr}");
    // Checked before rendering: nothing is written.
    assert!(!jpg.exists() && !dir.join("ok.exr").exists());
    let stderr = assert_failure(&snell(&["render", s(&scene), "-o", s(&dir.join("noextension"))], &dir));
    assert!(stderr.contains("cannot tell the image format of"), "{stderr}");
}

#[test]
fn missing_scene_file() {
    let (dir, _) = setup("missing-scene");
    let missing = dir.join("nothere.xml");
    let stderr = assert_failure(&snell(&["render", s(&missing), "-o", s(&dir.join("o.exr"))], &dir));
    assert!(stderr.contains("cannot read scene file"), "{stderr}");
    assert!(stderr.contains(s(&missing)), "{stderr}");
}

#[test]
fn usage_errors() {
    let (dir, scene) = setup("usage");
    let stderr = assert_failure(&snell(&["render"], &dir));
    assert!(stderr.contains("Usage"), "{stderr}");
    let stderr = assert_failure(&snell(&["render", s(&scene), "--spp", "many"], &dir));
    assert!(stderr.contains("--spp"), "{stderr}");
    let stderr = assert_failure(&snell(&["draw", s(&scene)], &dir));
    assert!(stderr.contains("draw"), "{stderr}");
}

#[test]
fn same_seed_is_bit_identical_across_thread_counts() {
    let (dir, scene) = setup("determinism");
    let (one, two, other) = (dir.join("t1.exr"), dir.join("t2.exr"), dir.join("seed.exr"));
    assert_success(&snell(&["render", s(&scene), "-o", s(&one), "--threads", "1", "--seed", "42", "-q"], &dir));
    assert_success(&snell(&["render", s(&scene), "-o", s(&two), "--threads", "2", "--seed", "42", "-q"], &dir));
    let (a, b) = (read_exr(&one), read_exr(&two));
    assert_eq!((a.width, a.height), (b.width, b.height));
    let bits = |img: &snell::film::Image| img.pixels.iter().flat_map(|p| (0..3).map(|c| p[c].to_bits()).collect::<Vec<_>>()).collect::<Vec<u32>>();
    assert!(bits(&a) == bits(&b), "threads 1 and 2 give different images");
    assert_eq!(std::fs::read(&one).unwrap(), std::fs::read(&two).unwrap(), "the EXR files differ");

    // A different seed gives a different (noisy) image.
    assert_success(&snell(&["render", s(&scene), "-o", s(&other), "--threads", "2", "--seed", "43", "-q"], &dir));
    assert!(bits(&a) != bits(&read_exr(&other)), "the seed has no effect");
}

/// A polarized render writes S0–S3 as EXR channels (read back as layers;
/// S0 repeats the RGB image) and the AoLP/DoLP view as a PNG.
#[test]
fn polarized_render_writes_stokes_channels_and_view() {
    let (dir, _) = setup("stokes");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/polarized-glass-metal.xml");
    let (exr, view) = (dir.join("out.exr"), dir.join("view.png"));
    let out = snell(&["render", s(&scene), "-D", "res=16", "--spp", "4", "--mode", "rgb-polarized", "-o", s(&exr), "--stokes-view", s(&view)], &dir);
    assert_success(&out);
    assert!(String::from_utf8_lossy(&out.stderr).contains("view.png"), "the summary names the view");
    let img = read_exr(&exr);
    let names: Vec<&str> = img.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["S0", "S1", "S2", "S3"]);
    assert!(img.layers[0].pixels.iter().zip(&img.pixels).all(|(a, b)| a == b), "S0 is not the RGB image");
    // Half the view is seen through a polarizer: strongly polarized light there.
    let s1_max = img.layers[1].pixels.iter().map(|p| p[1].abs()).fold(0.0f32, f32::max);
    assert!(s1_max > 0.1, "S1 is (nearly) zero everywhere: {s1_max}");
    let png = image::open(&view).unwrap_or_else(|e| panic!("{}: {e}", view.display()));
    assert_eq!((png.width(), png.height()), (16, 16));
}

/// The polarized modes refuse a scene whose BSDF has no Mueller model
/// (principled, principledthin), naming it and the modes that render it;
/// the same scene renders in RGB and spectral mode.
#[test]
fn polarized_modes_refuse_bsdfs_without_a_mueller_model() {
    for plugin in ["principled", "principledthin"] {
        let (dir, _) = setup(&format!("polarized-refusal-{plugin}"));
        let scene = dir.join("principled.xml");
        let text = SCENE.replace(
            "<bsdf type=\"diffuse\">\n            <rgb name=\"reflectance\" value=\"0.2, 0.5, 0.8\"/>",
            &format!("<bsdf type=\"{plugin}\">\n            <rgb name=\"base_color\" value=\"0.2, 0.5, 0.8\"/>"),
        );
        assert!(text.contains(plugin));
        std::fs::write(&scene, text).unwrap();
        for mode in ["rgb-polarized", "spectral-polarized"] {
            let out = dir.join(format!("{mode}.exr"));
            let err = assert_failure(&snell(&["render", s(&scene), "--mode", mode, "-o", s(&out)], &dir));
            assert!(err.contains(&format!("\"{plugin}\" BSDF")) && err.contains("--mode rgb or spectral"), "{err}");
            assert!(!out.exists(), "no image is written");
        }
        for mode in ["rgb", "spectral"] {
            let out = dir.join(format!("{mode}.exr"));
            assert_success(&snell(&["render", s(&scene), "--mode", mode, "-o", s(&out), "-q"], &dir));
            let img = read_exr(&out);
            assert!(img.pixels.iter().all(|p| p.is_finite()) && img.pixels.iter().any(|p| p.mean() > 0.01));
        }
    }
}

/// `--noise-threshold`: the EXR gets each pixel's sample count as the
/// channel `spp`, `--stats` the rounds, stderr a line per round; the options
/// it cannot take are refused with the reason.
#[test]
fn adaptive_sampling() {
    let (dir, scene) = setup("adaptive");
    let (exr, stats) = (dir.join("a.exr"), dir.join("stats.json"));
    let out = snell(&["render", s(&scene), "-o", s(&exr), "--spp", "64", "--min-spp", "8", "--noise-threshold", "0.01", "--stats", s(&stats)], &dir);
    assert_success(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("adaptive round 1/4: 100.0% of the pixels to 8 spp") && stderr.contains("adaptive round 4/4"), "{stderr}");
    let img = read_exr(&exr);
    let n = img.channel("spp").expect("an spp channel").values.clone();
    assert_eq!(n[0], 8.0, "the sky corner stops at the minimum");
    assert_eq!(n[12 * 32 + 16], 64.0, "the sphere's centre takes every sample");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).expect("stats are not JSON");
    assert_eq!(json["adaptive"]["min_spp"], 8);
    assert_eq!(json["adaptive"]["rounds"].as_array().map(Vec::len), Some(4));
    assert_eq!(json["samples_taken"].as_f64(), Some(n.iter().map(|&v| v as f64).sum::<f64>()));
    // Its output holds no resumable state.
    let e = assert_failure(&snell(&["render", s(&scene), "--spp", "64", "--resume", s(&exr), "-o", s(&dir.join("b.exr"))], &dir));
    assert!(e.contains("no resumable state") && e.contains("adaptive"), "{e}");
    for (args, want) in [
        (&["--noise-threshold", "0"][..], "positive"),
        (&["--noise-threshold=-1"], "positive"),
        (&["--noise-threshold", "0.05", "--min-spp", "128"], "above the render's 64"),
        (&["--noise-threshold", "0.05", "--min-spp", "0"], "at least 1"),
        (&["--noise-threshold", "0.05", "--passes", "3"], "leave out --passes"),
        (&["--noise-threshold", "0.05", "--write-every", "1"], "checkpoint"),
        (&["--noise-threshold", "0.05", "--resume", "x.exr"], "checkpoint"),
        (&["--min-spp", "8"], "--noise-threshold"),
    ] {
        let mut all = vec!["render", s(&scene), "-o", "c.exr", "--spp", "64"];
        all.extend_from_slice(args);
        let e = assert_failure(&snell(&all, &dir));
        assert!(e.contains(want), "{args:?}: {e}");
    }
}

/// `reuse_pixels` where it cannot apply (a spectral render) is said, not
/// silently dropped; in RGB it renders without that warning.
#[test]
fn reuse_pixels_where_it_cannot_apply_is_a_warning() {
    let (dir, scene) = setup("reuse-warning");
    let text = SCENE.replacen(r#"<integrator type="path">"#, r#"<integrator type="path"><integer name="reuse_pixels" value="4"/>"#, 1);
    assert_ne!(text, SCENE, "the test scene has no path integrator to extend");
    std::fs::write(&scene, text).unwrap();
    let out_exr = dir.join("out.exr");
    let spectral = snell(&["render", s(&scene), "-o", s(&out_exr), "--mode", "spectral"], &dir);
    assert_success(&spectral);
    assert!(String::from_utf8_lossy(&spectral.stderr).contains("warning: reuse_pixels applies to path in the rgb mode"));
    let rgb = snell(&["render", s(&scene), "-o", s(&out_exr)], &dir);
    assert_success(&rgb);
    assert!(!String::from_utf8_lossy(&rgb.stderr).contains("reuse_pixels"));
}

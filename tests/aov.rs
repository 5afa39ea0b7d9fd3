//! The film's pixel formats and crop window, and the `aov` and `moment`
//! integrators, against Mitsuba 3.9.1 references (tests/references/aov.exr,
//! moment.exr: every channel of Mitsuba's film) and against Snell's own
//! plain renders.


use crate::common::{compare, compare_with_reference_noise, params, render_passes, repo};
use snell::film::output::{read_exr, write_image};
use snell::film::{Image, PixelFormat};
use snell::spectrum::Rgb;
use snell::{LoadOptions, RenderOptions};
use std::path::{Path, PathBuf};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snell-aov-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

/// The channel names of an EXR file, sorted.
fn exr_channels(path: &Path) -> Vec<String> {
    use exr::prelude::{ReadChannels, ReadLayers};
    let file = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .expect("readable EXR");
    let mut names: Vec<String> = file.layer_data.channel_data.list.iter().map(|c| c.name.to_string()).collect();
    names.sort();
    names
}

/// Channels `names` of `img` as the R, G, B of an image (for the block comparison).
fn triple(img: &Image, names: [&str; 3]) -> Image {
    let v = names.map(|n| img.values(n).unwrap_or_else(|| panic!("no channel {n}")));
    let pixels = (0..v[0].len()).map(|i| Rgb::new(v[0][i], v[1][i], v[2][i])).collect();
    Image::new(img.width, img.height, pixels)
}

/// Within the noise of the passes and of the reference (whose per-pixel
/// standard errors `ref_stderr` holds, if given).
#[track_caller]
fn assert_within_noise(passes: &[Image], reference: &Image, ref_stderr: Option<&Image>, names: [&str; 3], positive: bool) {
    let p: Vec<Image> = passes.iter().map(|i| triple(i, names)).collect();
    let c = match ref_stderr {
        Some(e) => compare_with_reference_noise(&p, &triple(reference, names), &triple(e, names), 4),
        None => compare(&p, &triple(reference, names), 4, 0.0),
    };
    let label = names.join(",");
    c.report(&label);
    if positive {
        for k in 0..3 {
            assert!((c.mean_ratio[k] - 1.0).abs() < 0.02, "{label}: channel {k} mean ratio {:.4}", c.mean_ratio[k]);
        }
    }
    assert!(c.mean_z2 < 2.0, "{label}: mean z² = {:.2}", c.mean_z2);
    assert!(c.max_z < 6.0, "{label}: block {:?} is {:.1} standard errors off", c.worst_block, c.max_z);
}

#[test]
fn aov_channels_match_mitsuba() {
    let scene = repo("tests/scenes/aov.xml");
    let passes = render_passes(&scene, None, params(&[("res", "64")]), 16, 64);
    let reference = read_exr(&repo("tests/references/aov.exr")).expect("reference");
    // Its per-pixel standard errors: Snell's default light selection (bvh)
    // is far less noisy than Mitsuba's uniform choice between the point and
    // the sphere light, so the reference's own noise is not negligible.
    let ref_stderr = read_exr(&repo("tests/references/aov.stderr.exr")).expect("reference standard errors");

    // The same channels, by the same names, as Mitsuba writes.
    let out = temp("aov.exr");
    write_image(&passes[0], &out).expect("write");
    assert_eq!(exr_channels(&out), exr_channels(&repo("tests/references/aov.exr")));

    // The main image and alpha are the first nested integrator's.
    for (a, b) in [("R", "my_image.R"), ("B", "my_image.B"), ("A", "my_image.A")] {
        assert_eq!(passes[0].values(a), passes[0].values(b), "{a} vs {b}");
    }
    let alpha = passes[0].values("A").expect("alpha");
    assert!(alpha.iter().any(|&a| a == 0.0) && alpha.iter().any(|&a| a == 1.0) && alpha.iter().any(|&a| a > 0.0 && a < 1.0));

    for (names, positive) in [
        (["R", "G", "B"], true),
        (["_arg_0.R", "_arg_0.G", "_arg_0.B"], true),
        (["A", "my_image.A", "_arg_0.A"], true),
        (["al.R", "al.G", "al.B"], true),
        (["dd.y.T", "uv.U", "uv.V"], true),
        (["nn.X", "nn.Y", "nn.Z"], false),
        (["ng.X", "ng.Y", "ng.Z"], false),
        (["pp.X", "pp.Y", "pp.Z"], false),
    ] {
        assert_within_noise(&passes, &reference, Some(&ref_stderr), names, positive);
    }
    // Triangle indices of the torus (Snell's rectangle is two triangles,
    // Mitsuba's one primitive: indices 0 and 1 left out) are Mitsuba's
    // wherever a pixel sees one triangle only in both.
    let (snell_pi, ref_pi) = (passes[0].values("pi.I").expect("pi"), reference.values("pi.I").expect("pi"));
    let whole: Vec<(f32, f32)> = snell_pi.iter().zip(&ref_pi).filter(|(a, b)| a.fract() == 0.0 && b.fract() == 0.0 && **a > 1.0).map(|(a, b)| (*a, *b)).collect();
    assert!(whole.len() >= 3 && whole.iter().all(|(a, b)| a == b), "prim_index (Snell, Mitsuba) on whole-triangle pixels: {whole:?}");
}

#[test]
fn moment_matches_mitsuba_and_its_variance() {
    let scene = repo("tests/scenes/moment.xml");
    let spp = 64;
    let passes = render_passes(&scene, None, params(&[("res", "64")]), 16, spp);
    let reference = read_exr(&repo("tests/references/moment.exr")).expect("reference");
    let out = temp("moment.exr");
    write_image(&passes[0], &out).expect("write");
    assert_eq!(exr_channels(&out), exr_channels(&repo("tests/references/moment.exr")));

    assert_within_noise(&passes, &reference, None, ["R", "G", "B"], true);
    assert_within_noise(&passes, &reference, None, ["p.X", "p.Y", "p.Z"], true);
    // Squares are heavy-tailed (a small bright light): means only, looser.
    let p: Vec<Image> = passes.iter().map(|i| triple(i, ["m2_p.X", "m2_p.Y", "m2_p.Z"])).collect();
    let c = compare(&p, &triple(&reference, ["m2_p.X", "m2_p.Y", "m2_p.Z"]), 8, 0.0);
    c.report("m2");
    for k in 0..3 {
        assert!((c.mean_ratio[k] - 1.0).abs() < 0.05, "m2 channel {k} mean ratio {:.4}", c.mean_ratio[k]);
    }

    // The first moment is the image in XYZ; the second is at least its square.
    let img = &passes[0];
    let (y, m2) = (img.values("p.Y").expect("p.Y"), img.values("m2_p.Y").expect("m2"));
    for (i, p) in img.pixels.iter().enumerate() {
        let lum = 0.212671 * p[0] + 0.715160 * p[1] + 0.072169 * p[2];
        assert!((y[i] - lum).abs() <= 1e-5 * (1.0 + lum), "pixel {i}: Y {} vs luminance {lum}", y[i]);
        assert!(m2[i] >= y[i] * y[i] * (1.0 - 1e-5), "pixel {i}: m2 {} < m1² {}", m2[i], y[i] * y[i]);
    }
    // m2 − m1² estimates the samples' variance: (n−1)/n σ² per pass, and
    // the pixel means of the passes scatter with σ²/n.
    let (mut scatter, mut predicted) = (0.0f64, 0.0f64);
    let k = passes.len() as f64;
    for i in 0..img.pixels.len() {
        let ys: Vec<f64> = passes.iter().map(|p| p.values("p.Y").expect("p.Y")[i] as f64).collect();
        let mean = ys.iter().sum::<f64>() / k;
        scatter += ys.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (k - 1.0);
        predicted += passes
            .iter()
            .map(|p| {
                let (m1, m2) = (p.values("p.Y").expect("p.Y")[i] as f64, p.values("m2_p.Y").expect("m2")[i] as f64);
                (m2 - m1 * m1) / (spp as f64 - 1.0)
            })
            .sum::<f64>()
            / k;
    }
    eprintln!("pass scatter {scatter:.4e}, predicted from m2 − m1² {predicted:.4e}, ratio {:.3}", scatter / predicted);
    assert!((scatter / predicted - 1.0).abs() < 0.15, "variance from the moments {predicted:.4e} vs the passes' scatter {scatter:.4e}");
}

fn load(text: &str) -> snell::Scene {
    snell::load_str(&repo("tests/scenes/inline.xml"), text, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

fn small_scene(film_extra: &str, filter: &str, integrator: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
    {integrator}
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="0, 1, 4" target="0, 0.3, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="8"/><integer name="seed" value="3"/></sampler>
        <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="36"/>{film_extra}<rfilter type="{filter}"/></film>
    </sensor>
    <emitter type="point"><point name="position" value="1, 3, 2"/><rgb name="intensity" value="10"/></emitter>
    <shape type="sphere"><point name="center" value="-0.5, 0.4, 0"/><float name="radius" value="0.4"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.3, 0.2"/></bsdf></shape>
    <shape type="sphere"><point name="center" value="0.6, 0.5, -0.3"/><float name="radius" value="0.5"/></shape>
</scene>"#
    )
}

fn render(scene: &snell::Scene) -> Image {
    snell::render::<Rgb>(scene, &RenderOptions { threads: 2, progress: false, ..Default::default() }).expect("render").0
}

#[test]
fn crop_renders_that_window_of_the_full_film() {
    let integrator = r#"<integrator type="path"/>"#;
    for filter in ["box", "tent"] {
        let full = render(&load(&small_scene("", filter, integrator)));
        let crop = "<integer name=\"crop_offset_x\" value=\"13\"/><integer name=\"crop_offset_y\" value=\"7\"/>\
                    <integer name=\"crop_width\" value=\"21\"/><integer name=\"crop_height\" value=\"17\"/>";
        let cropped = render(&load(&small_scene(crop, filter, integrator)));
        assert_eq!((cropped.width, cropped.height), (21, 17));
        // Away from the window's edge (where the filter would reach samples
        // outside it) a pixel gets the very samples it gets in the full render.
        let margin = if filter == "box" { 0 } else { 1 };
        let mut lit = 0;
        for y in margin..17 - margin {
            for x in margin..21 - margin {
                let (a, b) = (cropped.pixels[(y * 21 + x) as usize], full.pixels[((y + 7) * 48 + x + 13) as usize]);
                for c in 0..3 {
                    assert!((a[c] - b[c]).abs() <= 1e-5 * (1.0 + b[c].abs()), "{filter} ({x},{y}): {a:?} vs {b:?}");
                }
                lit += (b[0] > 0.0) as u32;
            }
        }
        assert!(lit > 20, "the window should see the spheres");
    }
}

#[test]
fn pixel_formats_write_their_channels() {
    let integrator = r#"<integrator type="direct"/>"#;
    let rgb = render(&load(&small_scene("", "box", integrator)));
    let cases: [(&str, &[&str]); 5] = [
        ("rgba", &["A", "B", "G", "R"]),
        ("luminance", &["Y"]),
        ("luminance_alpha", &["A", "Y"]),
        ("xyz", &["X", "Y", "Z"]),
        ("xyza", &["A", "X", "Y", "Z"]),
    ];
    for (format, channels) in cases {
        let img = render(&load(&small_scene(&format!(r#"<string name="pixel_format" value="{format}"/>"#), "box", integrator)));
        assert_eq!(img.pixel_format, PixelFormat::from_name(format).expect("format"));
        // The same samples: the colour is the RGB render's, converted.
        assert_eq!(img.pixels, rgb.pixels, "{format}");
        let out = temp(&format!("{format}.exr"));
        write_image(&img, &out).expect("write");
        assert_eq!(exr_channels(&out), channels.iter().map(|s| s.to_string()).collect::<Vec<_>>(), "{format}");
        let back = read_exr(&out).expect("read back");
        if format.starts_with("luminance") {
            for (b, p) in back.pixels.iter().zip(&rgb.pixels) {
                let y = 0.212671 * p[0] + 0.715160 * p[1] + 0.072169 * p[2];
                assert!((b[0] - y).abs() <= 1e-6 * (1.0 + y), "Y {} vs {y}", b[0]);
            }
        }
        if let Some(alpha) = img.channel("A") {
            // direct: alpha is whether the camera ray hits a surface; the
            // black background (no environment) is transparent, the spheres opaque.
            assert!(alpha.values.iter().all(|a| (0.0..=1.0).contains(a)));
            for (a, p) in alpha.values.iter().zip(&rgb.pixels) {
                if p[0] > 0.0 {
                    assert!(*a > 0.0);
                }
            }
            assert_eq!(alpha.values[0], 0.0);
            assert!(alpha.values.iter().any(|&a| a == 1.0) && alpha.values.iter().any(|&a| a > 0.0 && a < 1.0));
            let png = temp(&format!("{format}.png"));
            write_image(&img, &png).expect("png");
            let decoded = image::open(&png).expect("png reads back");
            assert!(decoded.color().has_alpha(), "{format}: PNG without alpha");
            let rgba = decoded.to_rgba8();
            assert_eq!(rgba.get_pixel(0, 0)[3], 0);
        }
    }
}

#[test]
fn path_alpha_is_opaque_under_an_environment_unless_emitters_are_hidden() {
    let film = r#"<string name="pixel_format" value="rgba"/>"#;
    let with_env = |integrator: &str| small_scene(film, "box", integrator).replace("</scene>", r#"<emitter type="constant"><rgb name="radiance" value="0.2"/></emitter></scene>"#);
    let a = render(&load(&with_env(r#"<integrator type="path"/>"#)));
    assert!(a.channel("A").expect("A").values.iter().all(|&v| v == 1.0));
    let hidden = render(&load(&with_env(r#"<integrator type="path"><boolean name="hide_emitters" value="true"/></integrator>"#)));
    assert_eq!(hidden.channel("A").expect("A").values[0], 0.0);
    // direct: alpha is coverage even under an environment (as Mitsuba's direct).
    let direct = render(&load(&with_env(r#"<integrator type="direct"/>"#)));
    assert_eq!(direct.channel("A").expect("A").values[0], 0.0);
}

#[track_caller]
fn load_error(text: &str) -> String {
    match snell::load_str(&repo("tests/scenes/inline.xml"), text, &LoadOptions::default()) {
        Ok(_) => panic!("expected an error:\n{text}"),
        Err(e) => {
            assert!(e.location.is_some(), "{e}");
            e.to_string()
        }
    }
}

#[test]
fn bad_aov_moment_and_film_settings_are_located_errors() {
    let aov = |aovs: &str| small_scene("", "box", &format!(r#"<integrator type="aov"><string name="aovs" value="{aovs}"/></integrator>"#));
    let e = load_error(&aov("dd:depth,nn:normal"));
    assert!(e.contains("unknown AOV type \"normal\"") && e.contains("sh_normal"), "{e}");
    let e = load_error(&aov("d:dp_du"));
    assert!(e.contains("\"dp_du\" is not supported yet"), "{e}");
    let e = load_error(&aov("depth"));
    assert!(e.contains("NAME:TYPE"), "{e}");
    let e = load_error(&small_scene("", "box", r#"<integrator type="moment"/>"#));
    assert!(e.contains("at least one nested"), "{e}");
    let e = load_error(&small_scene("", "box", r#"<integrator type="moment"><integrator type="ptracer"/></integrator>"#));
    assert!(e.contains("\"ptracer\" cannot be nested"), "{e}");
    let e = load_error(&small_scene(r#"<string name="pixel_format" value="rgbw"/>"#, "box", ""));
    assert!(e.contains("rgba") && e.contains("luminance"), "{e}");
    let e = load_error(&small_scene(r#"<integer name="crop_offset_x" value="40"/><integer name="crop_width" value="9"/>"#, "box", ""));
    assert!(e.contains("crop_width") && e.contains("between 1 and 8"), "{e}");
    let e = load_error(&small_scene(r#"<integer name="crop_offset_y" value="36"/>"#, "box", ""));
    assert!(e.contains("crop_offset_y") && e.contains("between 0 and 35"), "{e}");
}

#[test]
fn aov_without_nested_integrator_has_a_black_image_and_spaced_names() {
    // As Mitsuba's documentation scene writes it: names separated by ", ".
    let text = small_scene(
        r#"<string name="pixel_format" value="rgba"/>"#,
        "box",
        r#"<integrator type="aov"><string name="aovs" value="nn:sh_normal, position:position, depth.y:depth"/></integrator>"#,
    );
    let img = render(&load(&text));
    assert!(img.pixels.iter().all(|p| *p == Rgb::BLACK));
    assert!(img.channel("A").expect("A").values.iter().all(|&a| a == 0.0));
    let names: Vec<&str> = img.channels.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["A", "nn.X", "nn.Y", "nn.Z", "position.X", "position.Y", "position.Z", "depth.y.T"]);
    // Unit normals where a pixel sees one sphere only.
    let (x, y, z) = (img.values("nn.X").unwrap(), img.values("nn.Y").unwrap(), img.values("nn.Z").unwrap());
    let depth = img.values("depth.y.T").unwrap();
    // The pixel facing the camera most: inside a sphere's disc, not at its
    // edge (where misses would shorten the mean normal).
    let center = (0..z.len()).max_by(|&a, &b| z[a].total_cmp(&z[b])).expect("pixels");
    assert!(((x[center].powi(2) + y[center].powi(2) + z[center].powi(2)).sqrt() - 1.0).abs() < 0.05);
    assert!(depth[center] > 3.0 && depth[center] < 4.5, "{}", depth[center]);
    assert_eq!(depth[0], 0.0);
}

/// Mitsuba's `depth` integrator: each channel is the distance to the first
/// hit (0 on a miss, alpha 0 there), the same as an `aov` depth channel,
/// and on a sphere seen head-on the closed form |c − o| − r − near_clip.
#[test]
fn depth_integrator_gives_the_distance_to_the_first_hit() {
    let text = small_scene(r#"<string name="pixel_format" value="rgba"/>"#, "box", r#"<integrator type="depth"/>"#);
    let depth = render(&load(&text));
    let text = small_scene("", "box", r#"<integrator type="aov"><string name="aovs" value="dd:depth"/></integrator>"#);
    let aov = render(&load(&text));
    let want = aov.values("dd.T").expect("dd.T");
    let alpha = depth.channel("A").expect("A").values.clone();
    for (i, p) in depth.pixels.iter().enumerate() {
        assert!(p.0.iter().all(|&c| (c - want[i]).abs() <= 1e-5 * want[i].max(1.0)), "pixel {i}: {p:?} against the aov's {}", want[i]);
        // The box filter and a pixel half on a sphere: alpha between 0 and 1.
        assert_eq!(alpha[i] == 0.0, want[i] == 0.0, "pixel {i}: alpha {}", alpha[i]);
    }
    assert_eq!(depth.pixels[0], Rgb::BLACK);
    // A 1×1 film with a narrow field of view, aimed at a sphere's centre.
    let text = r#"<scene version="3.0.0"><integrator type="depth"/>
        <sensor type="perspective"><float name="fov" value="0.01"/>
            <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, -1" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="1"/><integer name="height" value="1"/><rfilter type="box"/></film></sensor>
        <shape type="sphere"><point name="center" value="0, 0, -5"/><float name="radius" value="1.5"/></shape></scene>"#;
    // As in Mitsuba 3, camera rays start on the near clipping plane (0.01
    // ahead of the camera by default): the distance is 5 − 1.5 − 0.01
    // (Mitsuba 3.9.1 renders this scene as 3.49 too).
    let d = render(&load(text)).pixels[0];
    assert!(d.0.iter().all(|&c| (c - 3.49).abs() < 1e-4), "{d:?}");
}

#[test]
fn load_at_width_keeps_the_aspect_ratio_and_resets_the_crop() {
    let crop = r#"<integer name="crop_offset_x" value="4"/><integer name="crop_width" value="10"/>"#;
    let path = temp("sized.xml");
    std::fs::write(&path, small_scene(crop, "box", r#"<integrator type="path"/>"#)).expect("write scene");
    let scene = snell::scene::loader::load_file_at_width(&path, &LoadOptions::default(), 20).expect("loads");
    assert_eq!((scene.film.width, scene.film.height), (20, 15));
    assert_eq!(scene.film.crop, [0, 0, 20, 15]);
    let img = render(&scene);
    assert_eq!((img.width, img.height), (20, 15));
    // The same view: the aspect ratio and the field of view are the file's.
    let full = render(&load(&small_scene("", "box", r#"<integrator type="path"/>"#)));
    let lit = |img: &Image| img.pixels.iter().filter(|p| p[0] > 0.0).count() as f64 / img.pixels.len() as f64;
    assert!((lit(&img) - lit(&full)).abs() < 0.05, "{} vs {}", lit(&img), lit(&full));
}

#[test]
fn cli_writes_aov_channels_and_rgba_png_at_a_forced_width() {
    let (exr, png) = (temp("cli.exr"), temp("cli.png"));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(["render", &repo("tests/scenes/aov.xml").display().to_string(), "--spp", "2", "--width", "16", "-q"])
        .args(["-o", &exr.display().to_string(), "-o", &png.display().to_string()])
        .output()
        .expect("runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let img = read_exr(&exr).expect("EXR");
    assert_eq!((img.width, img.height), (16, 12));
    assert_eq!(exr_channels(&exr), exr_channels(&repo("tests/references/aov.exr")));
    let decoded = image::open(&png).expect("PNG");
    assert_eq!((decoded.width(), decoded.height()), (16, 12));
    assert!(decoded.color().has_alpha());
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(["render", &repo("tests/scenes/aov.xml").display().to_string(), "--width", "0", "-q", "-o", &exr.display().to_string()])
        .output()
        .expect("runs");
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--width must be at least 1"));
}

#[test]
fn film_accepts_mitsuba_06_banner_switch() {
    let scene = load(&small_scene(r#"<boolean name="banner" value="false"/><string name="component_format" value="float32"/>"#, "box", ""));
    assert_eq!(scene.film.pixel_format, PixelFormat::Rgb);
    let e = load_error(&small_scene(r#"<string name="banner" value="no"/>"#, "box", ""));
    assert!(e.contains("banner"), "{e}");
}

//! The render loop: images bit-identical across thread counts and splits of
//! the sample range into passes, exact merging of sample ranges in any
//! order, a stop request keeping the last complete pass, and (through the
//! command line) checkpoints that resume to the uninterrupted image and
//! survive a SIGKILL during a write.

use crate::common::*;
use snell::film::{FilmState, Image};
use snell::spectrum::{Polarized, Rgb, Spectrum};
use snell::{Mode, RenderOptions, Scene};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

fn load(path: &Path, text: Option<String>, list: &[(&str, &str)]) -> Scene {
    let options = snell::LoadOptions { params: params(list), ..Default::default() };
    match text {
        Some(t) => snell::load_str(path, &t, &options),
        None => snell::load_file(path, &options),
    }
    .unwrap_or_else(|e| panic!("{e}"))
}

fn cornell(integrator: &str, res: &str, spp: &str) -> Scene {
    let path = repo("scenes/cornell-box.xml");
    let text = std::fs::read_to_string(&path).unwrap().replace(r#"<integrator type="path">"#, &format!(r#"<integrator type="{integrator}">"#));
    load(&path, Some(text), &[("res", res), ("spp", spp)])
}

/// Every value of every channel and layer, as bits.
fn bits(image: &Image) -> Vec<u32> {
    let mut out: Vec<u32> = image.pixels.iter().flat_map(|p| p.0).map(f32::to_bits).collect();
    for l in &image.layers {
        out.extend(l.pixels.iter().flat_map(|p| p.0).map(f32::to_bits));
    }
    for c in &image.channels {
        out.extend(c.values.iter().map(|v| v.to_bits()));
    }
    out
}

fn options(threads: usize, passes: u32) -> RenderOptions {
    RenderOptions { threads, passes, ..RenderOptions::default() }
}

/// The image of `scene` is the same, bit for bit, for 1, 2 and 3 threads
/// and for 1, 2, 3 and 5 passes; and it is not black.
fn assert_exact<S: Spectrum>(what: &str, scene: &Scene, layers: usize, channels: usize) {
    let (reference, stats) = snell::render::<S>(scene, &options(1, 1)).expect("render");
    assert!(!stats.interrupted && stats.spp_done == scene.sampler.sample_count);
    assert_eq!((reference.layers.len(), reference.channels.len()), (layers, channels), "{what}");
    let lit = reference.pixels.iter().filter(|p| p.0.iter().any(|&c| c > 0.0)).count();
    assert!(lit > reference.pixels.len() / 4, "{what}: {lit} pixels lit");
    let want = bits(&reference);
    for (threads, passes) in [(2, 1), (3, 1), (1, 3), (2, 2), (3, 5), (2, 3)] {
        let mut reports = vec![];
        let (image, _) = snell::render::render_passes::<S>(scene, &options(threads, passes), &mut |r| reports.push(r.spp_done)).expect("render");
        assert_eq!(reports, snell::render::pass_schedule(scene.sampler.sample_count, passes), "{what}");
        assert!(bits(&image) == want, "{what}: {threads} threads, {passes} passes differ from 1 thread, 1 pass");
    }
}

#[test]
fn path_tracer_is_exact_across_threads_and_passes() {
    assert_exact::<Rgb>("path", &cornell("path", "48", "6"), 0, 0);
}

#[test]
fn particle_tracer_is_exact_across_threads_and_passes() {
    assert_exact::<Rgb>("ptracer", &cornell("ptracer", "40", "5"), 0, 0);
}

#[test]
fn aov_and_polarized_renders_are_exact_across_threads_and_passes() {
    let path = repo("tests/scenes/aov.xml");
    // A filter wider than a pixel, so samples cross tile borders.
    let text = std::fs::read_to_string(&path).unwrap().replace(r#"<rfilter type="box"/>"#, r#"<rfilter type="gaussian"/>"#);
    let aov = load(&path, Some(text), &[("res", "40"), ("height", "32"), ("spp", "4")]);
    let channels = 1 + aov.integrator.channel_names().len();
    assert!(channels > 10);
    assert_exact::<Rgb>("aov", &aov, 0, channels);
    assert_exact::<Polarized<Rgb>>("rgb-polarized", &cornell("path", "32", "4"), 3, 0);
}

#[test]
fn merged_sample_ranges_equal_the_single_render_in_any_order() {
    for integrator in ["path", "ptracer"] {
        let scene = cornell(integrator, "32", "8");
        let opts = options(2, 1);
        let (whole, _) = snell::render::<Rgb>(&scene, &opts).expect("render");
        let parts: Vec<FilmState> =
            [0..3, 3..4, 4..8].into_iter().map(|r| snell::session::render_samples(&scene, Mode::Rgb, &opts, r).expect("render")).collect();
        for order in [[0, 1, 2], [2, 1, 0], [1, 2, 0]] {
            let mut state = parts[order[0]].clone();
            // Through bytes, as a distributed renderer sends them.
            for &k in &order[1..] {
                state.merge(&FilmState::from_bytes(&parts[k].to_bytes()).expect("bytes")).expect("merge");
            }
            assert_eq!(state.ranges(), &[0..8]);
            assert!(state.is_finished());
            assert!(bits(&state.develop()) == bits(&whole), "{integrator}: merge order {order:?}");
        }
        // Overlapping ranges and ranges past the sample count are refused.
        let mut twice = parts[0].clone();
        assert!(twice.merge(&parts[0]).is_err());
        assert!(snell::render_samples::<Rgb>(&scene, &opts, 4..9).is_err());
        // Another seed is another render.
        let mut other = scene;
        other.sampler.seed += 1;
        let foreign = snell::render_samples::<Rgb>(&other, &opts, 3..4).expect("render");
        let e = parts[0].clone().merge(&foreign).unwrap_err().to_string();
        assert!(e.contains("seed"), "{e}");
    }
}

#[test]
fn short_remaining_passes_are_joined_into_one_with_the_same_image() {
    let scene = cornell("path", "32", "16");
    let want = bits(&snell::render::<Rgb>(&scene, &options(2, 1)).expect("render").0);
    // Any rest is "short" under a huge limit: the first pass, then the rest at once.
    for (limit, expect) in [(1e9, vec![1, 16]), (-1.0, snell::render::pass_schedule(16, 5))] {
        let opts = RenderOptions { join_passes_under: Some(limit), ..options(2, 5) };
        let mut seen = vec![];
        let (image, stats) = snell::render::render_passes::<Rgb>(&scene, &opts, &mut |r| seen.push((r.spp_done, r.passes))).expect("render");
        assert_eq!(seen.iter().map(|s| s.0).collect::<Vec<_>>(), expect, "limit {limit}");
        assert_eq!(seen.last().map(|s| s.1), Some(expect.len() as u32), "limit {limit}: the last report counts the passes made");
        assert_eq!(stats.spp_done, 16);
        assert!(bits(&image) == want, "limit {limit}: joined passes changed the image");
    }
}

#[test]
fn a_stop_request_keeps_the_last_complete_pass() {
    let scene = cornell("path", "32", "16");
    let stop = Arc::new(AtomicBool::new(false));
    let opts = RenderOptions { threads: 2, passes: 4, stop: Some(stop.clone()), ..RenderOptions::default() };
    let mut seen = vec![];
    let (image, stats) = snell::render::render_passes::<Rgb>(&scene, &opts, &mut |r| {
        seen.push(r.spp_done);
        assert_eq!(r.state.prefix(), Some(r.spp_done));
        if r.pass == 2 {
            stop.store(true, Ordering::SeqCst);
        }
    })
    .expect("render");
    assert_eq!(seen, vec![2, 4]);
    assert!(stats.interrupted);
    assert_eq!((stats.spp_done, stats.samples_taken), (4, 32 * 32 * 4));
    let first4 = snell::render_samples::<Rgb>(&scene, &options(1, 1), 0..4).expect("render");
    assert!(bits(&image) == bits(&first4.develop()));
    // Resuming that state finishes the render exactly.
    let (_, _, state) = snell::render::render_progressive::<Rgb>(&scene, &options(2, 4), None, &mut |_| {}).expect("render");
    let (resumed, stats, _) = snell::render::render_progressive::<Rgb>(&scene, &options(3, 2), Some(first4), &mut |_| {}).expect("resume");
    assert!(!stats.interrupted);
    assert!(bits(&resumed) == bits(&state.develop()));
}

// ------------------------------------------------------------ command line

/// A diffuse sphere under a constant environment, 32×24.
const SCENE: &str = r#"<scene version="3.0.0">
    <default name="spp" value="64"/>
    <integrator type="path"><integer name="max_depth" value="4"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="24"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="sphere"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf></shape>
</scene>
"#;

fn setup(name: &str) -> (PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("snell-loop-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("scene.xml");
    std::fs::write(&scene, SCENE).unwrap();
    (dir, scene)
}

fn snell(args: &[&str]) -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_snell"));
    c.args(args).stdout(std::process::Stdio::null());
    c
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run(args: &[&str]) -> (Option<i32>, String) {
    let out = snell(args).output().expect("cannot run snell");
    (out.status.code(), String::from_utf8_lossy(&out.stderr).to_string())
}

fn wait_for(child: &mut std::process::Child, seconds: u64) -> std::process::ExitStatus {
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if start.elapsed().as_secs() > seconds {
            let _ = child.kill();
            panic!("snell did not finish within {seconds} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// The `samples` field of an output's `snell.render` header attribute.
fn samples_of(path: &Path) -> String {
    let meta = snell::film::output::read_exr_metadata(path).unwrap();
    let text = &meta.text.iter().find(|(k, _)| k == snell::cli::RENDER_ATTRIBUTE).expect("snell.render attribute").1;
    let fields = snell::cli::parse_fields(text);
    for key in ["samples", "spp", "seed", "mode", "size", "scene"] {
        assert!(fields.iter().any(|(k, _)| k == key), "{key} missing in {text}");
    }
    fields.into_iter().find(|(k, _)| k == "samples").unwrap().1
}

fn exr_bits(path: &Path) -> Vec<u32> {
    bits(&snell::film::output::read_exr(path).unwrap_or_else(|e| panic!("{e}")))
}

#[cfg(unix)]
#[test]
fn an_interrupted_render_resumes_to_the_uninterrupted_image() {
    let (dir, scene) = setup("resume");
    let (full, part) = (dir.join("full.exr"), dir.join("part.exr"));
    let spp = "-Dspp=4096";
    let (code, err) = run(&["render", s(&scene), spp, "--passes", "1", "--threads", "2", "-o", s(&full), "-q"]);
    assert_eq!(code, Some(0), "{err}");
    // Interrupt once the first checkpoint is on disk (several passes remain).
    let mut child = snell(&["render", s(&scene), spp, "--passes", "9", "--threads", "1", "--write-every", "0", "-o", s(&part)])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    while !part.exists() {
        assert!(child.try_wait().unwrap().is_none(), "the render ended before its first checkpoint");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    std::process::Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    let status = wait_for(&mut child, 60);
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("wrote the last complete pass") && stderr.contains("--resume"), "{stderr}");
    let meta = snell::film::output::read_exr_metadata(&part).unwrap();
    let samples = samples_of(&part);
    assert!(samples.starts_with("0-") && samples != "0-4096" && meta.state.is_some(), "{samples}");
    // Every pixel has the same samples: none is black.
    let img = snell::film::output::read_exr(&part).unwrap();
    assert!(img.pixels.iter().all(|p| p.0.iter().all(|&c| c > 0.0)));
    assert!(exr_bits(&part) != exr_bits(&full));

    // A different scene setting is refused, naming it.
    let (code, err) = run(&["render", s(&scene), "-Dspp=2048", "--resume", s(&part)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("another render") && err.contains("spp"), "{err}");
    let (code, err) = run(&["render", s(&scene), spp, "--seed", "5", "--resume", s(&part)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("another render"), "{err}");

    let (code, err) = run(&["render", s(&scene), spp, "--threads", "2", "--passes", "3", "--resume", s(&part)]);
    assert_eq!(code, Some(0), "{err}");
    assert!(exr_bits(&part) == exr_bits(&full), "the resumed image differs from the uninterrupted one");
    assert_eq!(samples_of(&part), "0-4096");
    assert!(snell::film::output::read_exr_metadata(&part).unwrap().state.is_none(), "a finished render needs no state");
    // Resuming a finished render does nothing.
    let (code, err) = run(&["render", s(&scene), spp, "--resume", s(&part)]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("nothing to do"), "{err}");
}

#[cfg(unix)]
#[test]
fn a_render_killed_while_writing_checkpoints_leaves_a_valid_exr() {
    let (dir, scene) = setup("kill");
    let out = dir.join("out.exr");
    // Many small passes, a checkpoint after each: most of the time is writing.
    for (k, delay_ms) in [37u64, 160, 290, 450, 610, 820].into_iter().enumerate() {
        let mut child = snell(&["render", s(&scene), "-Dspp=16000", "--passes", "2000", "--write-every", "0", "--threads", "2", "-o", s(&out), "-q"])
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = child.kill(); // SIGKILL
        let _ = child.wait();
        if out.exists() {
            let img = snell::film::output::read_exr(&out).unwrap_or_else(|e| panic!("kill {k} at {delay_ms} ms: {e}"));
            assert_eq!((img.width, img.height), (32, 24));
            let meta = snell::film::output::read_exr_metadata(&out).unwrap();
            match meta.state.as_deref() {
                Some(bytes) => {
                    let state = FilmState::from_bytes(bytes).expect("state");
                    assert!(state.header.complete && state.prefix().is_some());
                }
                // Only the finished render's image is written without its state.
                None => assert_eq!(samples_of(&out), "0-16000", "kill {k} at {delay_ms} ms: a checkpoint without its state"),
            }
        }
        // No temporary file is left where the image should be.
        let names: Vec<String> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
        assert!(names.iter().all(|n| n == "scene.xml" || n == "out.exr" || n.starts_with(".out.exr.tmp-")), "{names:?}");
    }
    assert!(out.exists(), "no checkpoint was written in 820 ms");
}

#[test]
fn bad_pass_and_checkpoint_flags_are_clear_errors() {
    let (dir, scene) = setup("flags");
    let exr = dir.join("o.exr");
    let (code, err) = run(&["render", s(&scene), "--passes", "0", "-o", s(&exr)]);
    assert!(code == Some(1) && err.contains("--passes must be at least 1"), "{err}");
    let (code, err) = run(&["render", s(&scene), "--write-every=-1", "-o", s(&exr)]);
    assert!(code == Some(1) && err.contains("--write-every"), "{err}");
    let (code, err) = run(&["render", s(&scene), "--write-every", "5", "-o", s(&dir.join("o.png"))]);
    assert!(code == Some(1) && err.contains("need an .exr output"), "{err}");
    let (code, err) = run(&["render", s(&scene), "--resume", s(&dir.join("missing.exr"))]);
    assert!(code == Some(1) && err.contains("missing.exr"), "{err}");
    // An EXR that is not a checkpoint.
    let plain = dir.join("plain.exr");
    snell::film::output::write_image(&Image::new(2, 2, vec![Rgb::WHITE; 4]), &plain).unwrap();
    let (code, err) = run(&["render", s(&scene), "--resume", s(&plain)]);
    assert!(code == Some(1) && err.contains("not a Snell checkpoint"), "{err}");
    assert!(!exr.exists());
}

/// A checkpoint's digest covers the files the scene reads (included XML, a
/// mesh, a texture): editing one makes `--resume` refuse, naming the file.
#[test]
fn resume_refuses_a_checkpoint_whose_mesh_texture_or_include_changed() {
    let dir = std::env::temp_dir().join(format!("snell-loop-{}-files", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("assets")).unwrap();
    let scene = dir.join("scene.xml");
    std::fs::write(
        &scene,
        r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="12"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <include filename="part.xml"/>
</scene>
"#,
    )
    .unwrap();
    std::fs::write(
        dir.join("part.xml"),
        r#"<scene version="3.0.0">
    <shape type="obj"><string name="filename" value="assets/quad.obj"/>
        <bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="assets/tex.png"/></texture></bsdf>
    </shape>
</scene>
"#,
    )
    .unwrap();
    let quad = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n";
    let mesh = dir.join("assets/quad.obj");
    std::fs::write(&mesh, quad).unwrap();
    let tex = dir.join("assets/tex.png");
    image::RgbImage::from_pixel(4, 4, image::Rgb([200, 120, 40])).save(&tex).unwrap();
    let out = dir.join("out.exr");
    let (code, err) = run(&["render", s(&scene), "-o", s(&out), "-q"]);
    assert_eq!(code, Some(0), "{err}");
    let meta = snell::film::output::read_exr_metadata(&out).unwrap();
    let files = &meta.text.iter().find(|(k, _)| k == "snell.files").expect("snell.files attribute").1;
    let names: Vec<&str> = files.lines().filter_map(|l| l.split_once(' ')).map(|(_, n)| n).collect();
    assert_eq!(names, ["part.xml", "assets/quad.obj", "assets/tex.png"], "{files}");
    let (code, err) = run(&["render", s(&scene), "--resume", s(&out)]);
    assert!(code == Some(0) && err.contains("nothing to do"), "{err}");

    // One vertex moved: refused, naming the mesh; restored: accepted again.
    std::fs::write(&mesh, quad.replace("v 1 1 0", "v 1 1.5 0")).unwrap();
    let (code, err) = run(&["render", s(&scene), "--resume", s(&out)]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("assets/quad.obj") && err.contains("has changed"), "{err}");
    std::fs::write(&mesh, quad).unwrap();
    let (code, err) = run(&["render", s(&scene), "--resume", s(&out)]);
    assert!(code == Some(0) && err.contains("nothing to do"), "{err}");

    // A texture of another colour, and an edited included file.
    image::RgbImage::from_pixel(4, 4, image::Rgb([200, 120, 41])).save(&tex).unwrap();
    let (code, err) = run(&["render", s(&scene), "--resume", s(&out)]);
    assert!(code == Some(1) && err.contains("assets/tex.png") && err.contains("has changed"), "{err}");
    image::RgbImage::from_pixel(4, 4, image::Rgb([200, 120, 40])).save(&tex).unwrap();
    let part = std::fs::read_to_string(dir.join("part.xml")).unwrap();
    std::fs::write(dir.join("part.xml"), part.replace("<shape", "<!-- edited --><shape")).unwrap();
    let (code, err) = run(&["render", s(&scene), "--resume", s(&out)]);
    assert!(code == Some(1) && err.contains("part.xml") && err.contains("has changed"), "{err}");
}

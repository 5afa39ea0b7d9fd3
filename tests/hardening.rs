//! Hostile and broken input (issue 17): each test builds its input, and would
//! crash, hang or silently succeed without the limit or check it exercises.

use snell::spectrum::{Rgb, Sampled};
use snell::{LoadOptions, RenderOptions, SceneError};
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

/// A valid sensor block of 8 lines: a body given to [`scene`] starts at line 9.
const HEAD: &str = r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <film type="hdrfilm">
            <integer name="width" value="8"/>
            <integer name="height" value="6"/>
        </film>
    </sensor>
"#;

fn scene(body: &str) -> String {
    format!("{HEAD}{body}</scene>\n")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snell-hardening-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn path() -> PathBuf {
    std::env::temp_dir().join("snell-hardening").join("test.xml")
}

fn params(list: &[(&str, &str)]) -> HashMap<String, String> {
    list.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect()
}

fn load(text: &str, list: &[(&str, &str)]) -> Result<snell::Scene, SceneError> {
    snell::load_str(&path(), text, &LoadOptions { params: params(list), ..LoadOptions::default() })
}

#[track_caller]
fn load_ok(text: &str) -> snell::Scene {
    load(text, &[]).unwrap_or_else(|e| panic!("{e}"))
}

/// The error's line, and that its message contains `message`.
#[track_caller]
fn err_line(text: &str, list: &[(&str, &str)], message: &str) -> (u32, SceneError) {
    let e = match load(text, list) {
        Ok(_) => panic!("expected an error containing {message:?}"),
        Err(e) => e,
    };
    let shown = e.to_string();
    assert!(shown.contains(message), "expected {message:?} in:\n{shown}");
    (e.location.as_ref().map_or(0, |l| l.line), e)
}

// ------------------------------------------------------------- nesting

#[test]
fn deep_nesting_is_a_located_error_not_a_stack_overflow() {
    let depth = 6000;
    let mut body = String::from("    <shape type=\"sphere\">\n");
    for _ in 0..depth {
        body.push_str("<bsdf type=\"twosided\">\n");
    }
    for _ in 0..depth {
        body.push_str("</bsdf>\n");
    }
    body.push_str("    </shape>\n");
    let text = scene(&body);
    // A thread with a small stack: the reader must not recurse 6000 levels.
    let handle = std::thread::Builder::new().stack_size(1 << 20).spawn(move || load(&text, &[]).err().map(|e| e.to_string())).unwrap();
    let shown = handle.join().expect("loading overflowed the stack").expect("a 6000-deep scene must be refused");
    assert!(shown.contains("nested more than 64 levels deep"), "{shown}");
    // <scene> is level 0, <shape> 1, the first <bsdf> 2: the 64th bsdf (line 9 + 64) is too deep.
    assert!(shown.contains("test.xml:73:1"), "{shown}");
    assert!(shown.contains("SNELL_MAX_XML_DEPTH"), "{shown}");
}

// ------------------------------------------------------------- includes

#[test]
fn fanned_out_includes_stop_at_the_include_count() {
    let dir = temp_dir("fanout");
    // Level k includes level k+1 ten times: 10^16 files without a total limit.
    for level in 0..16 {
        let mut text = String::from("<scene version=\"3.0.0\">\n");
        for _ in 0..10 {
            text.push_str(&format!("    <include filename=\"level{}.xml\"/>\n", level + 1));
        }
        text.push_str("</scene>\n");
        std::fs::write(dir.join(format!("level{level}.xml")), text).unwrap();
    }
    std::fs::write(dir.join("level16.xml"), "<scene version=\"3.0.0\">\n</scene>\n").unwrap();
    let start = Instant::now();
    let e = match snell::load_file(&dir.join("level0.xml"), &LoadOptions::default()) {
        Ok(_) => panic!("a fan-out of 10^16 includes must be refused"),
        Err(e) => e.to_string(),
    };
    assert!(start.elapsed().as_secs_f64() < 10.0, "took {:?}", start.elapsed());
    assert!(e.contains("includes more than 1000 files"), "{e}");
    assert!(e.contains("SNELL_MAX_INCLUDES"), "{e}");
    assert!(e.contains(":5\n"), "the error points at an <include>: {e}");
}

#[test]
fn chained_defaults_cannot_grow_a_value_exponentially() {
    // Each default is its predecessor ten times: 10^30 bytes at the end.
    let mut body = String::from("    <default name=\"p0\" value=\"0123456789\"/>\n");
    for i in 1..30 {
        let v = format!("${}", format!("p{}", i - 1)).repeat(10);
        body.push_str(&format!("    <default name=\"p{i}\" value=\"{v}\"/>\n"));
    }
    let text = format!("<scene version=\"3.0.0\">\n{body}</scene>\n");
    let (line, e) = err_line(&text, &[], "makes this value too long");
    assert!(line >= 2, "{e}");
}

// ------------------------------------------------------------- large scenes

fn spheres(n: usize, error_line: Option<usize>) -> String {
    let mut text = String::with_capacity(n * 200);
    text.push_str(HEAD);
    text.push_str("    <bsdf type=\"diffuse\" id=\"white\"/>\n");
    let mut lines = 9;
    for i in 0..n {
        if Some(lines + 1) == error_line {
            text.push_str("    <shape type=\"sfere\"/>\n");
            lines += 1;
        }
        lines += 5;
        let (x, y, z) = ((i % 100) as f32, ((i / 100) % 100) as f32, (i / 10000) as f32);
        text.push_str(&format!(
            "    <shape type=\"sphere\">\n        <point name=\"center\" x=\"{x}\" y=\"{y}\" z=\"{}\"/>\n        <float name=\"radius\" value=\"0.25\"/>\n        <ref id=\"white\"/>\n    </shape>\n",
            z + 5.0
        ));
    }
    text.push_str("</scene>\n");
    text
}

#[test]
fn loading_is_not_quadratic_in_the_file_size() {
    let text = spheres(100_000, None);
    let start = Instant::now();
    let scene = load_ok(&text);
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(scene.shapes.len(), 100_000);
    eprintln!("100 000 spheres ({} MB) loaded in {seconds:.3} s", text.len() / 1_000_000);
    // Well under a second in release on one core; the bound is generous for a
    // loaded machine, and far below the quadratic behaviour (minutes).
    assert!(seconds < 10.0, "100 000 spheres took {seconds:.1} s to load");

    // An error near the top of a big file is reported at once, with its line.
    let text = spheres(20_000, Some(10));
    let start = Instant::now();
    let (line, _) = err_line(&text, &[], "unknown shape plugin \"sfere\"");
    assert_eq!(line, 10);
    assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
}

// ------------------------------------------------------------- emission

fn lit(emitter: &str) -> String {
    scene(&format!("    <shape type=\"sphere\"><point name=\"center\" value=\"0, 0, 5\"/></shape>\n{emitter}"))
}

#[test]
fn negative_emission_is_a_located_error() {
    let cases = [
        ("<shape type=\"rectangle\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"1, -1, 1\"/></emitter></shape>", "\"radiance\""),
        ("<emitter type=\"point\"><spectrum name=\"intensity\" value=\"-2\"/></emitter>", "\"intensity\""),
        ("<emitter type=\"spot\"><float name=\"intensity\" value=\"-2\"/></emitter>", "\"intensity\""),
        ("<emitter type=\"directional\"><rgb name=\"irradiance\" value=\"-0.5\"/></emitter>", "\"irradiance\""),
        ("<emitter type=\"constant\"><spectrum name=\"radiance\" value=\"400:1, 500:-1, 600:1\"/></emitter>", "\"radiance\""),
    ];
    for (emitter, name) in cases {
        let (line, e) = err_line(&lit(&format!("{emitter}\n")), &[], "is negative");
        assert_eq!(line, 10, "{e}");
        assert!(e.to_string().contains(name), "{e}");
    }
}

#[test]
fn emission_too_large_for_single_precision_is_an_error() {
    let (line, e) = err_line(&lit("<emitter type=\"constant\"><rgb name=\"radiance\" value=\"3e38\"/></emitter>\n"), &[], "above the largest");
    assert_eq!(line, 10, "{e}");
    let (line, _) = err_line(&lit("<emitter type=\"point\"><spectrum name=\"intensity\" value=\"1e25\"/></emitter>\n"), &[], "above the largest");
    assert_eq!(line, 10);
}

/// The largest accepted emission renders to finite, non-black pixels in
/// spectral mode (before the limit, 3e38 silently gave a black image).
#[test]
fn the_largest_accepted_emission_renders_in_spectral_mode() {
    let max = snell::scene::props::MAX_EMISSION;
    for emitter in [
        format!("<emitter type=\"constant\"><rgb name=\"radiance\" value=\"{max:e}, {:e}, {:e}\"/></emitter>", max * 0.5, max * 0.25),
        format!("<emitter type=\"constant\"><spectrum name=\"radiance\" value=\"{max:e}\"/></emitter>"),
    ] {
        let scene = load_ok(&lit(&format!("{emitter}\n")));
        let options = RenderOptions { threads: 1, ..RenderOptions::default() };
        for image in [snell::render::<Sampled>(&scene, &options).unwrap().0, snell::render::<Rgb>(&scene, &options).unwrap().0] {
            for p in &image.pixels {
                assert!(p.is_finite() && p.0.iter().all(|&c| c > 0.0), "{p:?} for {emitter}");
            }
        }
    }
}

// ------------------------------------------------------------- reflectance

#[test]
fn negative_reflectance_is_an_error_and_above_one_a_warning() {
    let (line, e) = err_line(
        &scene("    <shape type=\"sphere\">\n        <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.5, -0.1, 0.5\"/></bsdf>\n    </shape>\n"),
        &[],
        "\"reflectance\" of bsdf \"diffuse\" is negative",
    );
    assert_eq!(line, 10, "{e}");
    let (line, _) = err_line(
        &scene("    <bsdf type=\"plastic\" id=\"p\">\n        <texture type=\"checkerboard\" name=\"diffuse_reflectance\">\n            <rgb name=\"color1\" value=\"-1\"/>\n        </texture>\n    </bsdf>\n"),
        &[],
        "\"diffuse_reflectance\" of bsdf \"plastic\" is negative",
    );
    assert_eq!(line, 10);

    let scene_ok =
        load_ok(&scene("    <shape type=\"sphere\">\n        <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"1.5, 0.5, 0.5\"/></bsdf>\n    </shape>\n"));
    assert_eq!(scene_ok.warnings.len(), 1, "{:?}", scene_ok.warnings);
    let w = &scene_ok.warnings[0];
    assert!(w.starts_with("warning: \"reflectance\" of bsdf \"diffuse\" is above one (1.5)"), "{w}");
    assert!(w.contains("test.xml:10:"), "{w}");
    // Within [0, 1]: no warning.
    assert!(load_ok(&scene("    <shape type=\"sphere\"><bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"1\"/></bsdf></shape>\n")).warnings.is_empty());
}

// ------------------------------------------------------------- parameters

#[test]
fn an_undeclared_override_is_an_error_listing_the_declared_ones() {
    let text = format!(
        "<scene version=\"3.0.0\">\n    <default name=\"res\" value=\"8\"/>\n    <default name=\"spp\" value=\"1\"/>\n{}",
        &HEAD["<scene version=\"3.0.0\">\n".len()..]
    ) + "</scene>\n";
    load(&text, &[("res", "4")]).unwrap_or_else(|e| panic!("{e}"));
    let e = load(&text, &[("rse", "4")]).err().expect("-D rse must be refused").to_string();
    assert!(e.contains("the scene has no parameter \"rse\""), "{e}");
    assert!(e.contains("declared parameters are: res, spp"), "{e}");
    // A parameter the scene uses without a default is declared by its use.
    let used = scene("    <shape type=\"sphere\"><float name=\"radius\" value=\"$r\"/></shape>\n");
    load(&used, &[("r", "2")]).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn a_duplicate_default_is_a_located_error() {
    let text = scene("    <default name=\"r\" value=\"1\"/>\n    <default name=\"r\" value=\"2\"/>\n");
    let (line, e) = err_line(&text, &[], "parameter \"r\" has a second <default> (the first is at line 9)");
    assert_eq!(line, 10, "{e}");
}

#[test]
fn sample_counts_have_one_limit() {
    let text = scene("");
    let too_many = LoadOptions { spp: Some((1 << 24) + 1), ..LoadOptions::default() };
    let e = snell::load_str(&path(), &text, &too_many).err().expect("2^24 + 1 spp must be refused").to_string();
    assert!(e.contains("not between 1 and 16777216"), "{e}");
    let max = LoadOptions { spp: Some(1 << 24), ..LoadOptions::default() };
    assert_eq!(snell::load_str(&path(), &text, &max).unwrap().sampler.sample_count, 1 << 24);
}

#[test]
fn a_huge_max_depth_is_unlimited_with_a_warning() {
    for integrator in ["path", "ptracer"] {
        let text = scene(&format!(
            "    <integrator type=\"{integrator}\"><integer name=\"max_depth\" value=\"1099511627776\"/></integrator>\n    <shape type=\"sphere\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter></shape>\n"
        ));
        let s = load_ok(&text);
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(s.warnings[0].contains("\"max_depth\" = 1099511627776 is beyond 4294967294 and is treated as unlimited (as -1)"), "{:?}", s.warnings);
        assert!(s.warnings[0].contains("test.xml:9:"), "{:?}", s.warnings);
        // -1 and ordinary depths say nothing.
        assert!(load_ok(&text.replace("1099511627776", "-1")).warnings.is_empty());
        assert!(load_ok(&text.replace("1099511627776", "12")).warnings.is_empty());
    }
}

// ================================================================ the command line

/// A diffuse, textured sphere under a constant environment; `$res`×`$res`·¾ at `$spp`.
const CLI_SCENE: &str = r#"<scene version="3.0.0">
    <default name="res" value="32"/>
    <default name="spp" value="4"/>
    <default name="texture" value="tex.png"/>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="$res"/>
            <integer name="height" value="$res"/>
        </film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="sphere">
        <bsdf type="diffuse">
            <texture type="bitmap" name="reflectance"><string name="filename" value="$texture"/></texture>
        </bsdf>
    </shape>
</scene>
"#;

/// A folder with `scene.xml` and a 16×16 `tex.png`.
fn cli_setup(name: &str) -> (PathBuf, PathBuf) {
    let dir = temp_dir(name);
    let scene = dir.join("scene.xml");
    std::fs::write(&scene, CLI_SCENE).unwrap();
    let px: Vec<u8> = (0..16 * 16 * 3).map(|i| (i * 7 % 200) as u8).collect();
    image::save_buffer(dir.join("tex.png"), &px, 16, 16, image::ExtendedColorType::Rgb8).unwrap();
    (dir, scene)
}

fn snell_cmd(args: &[&str], cwd: &std::path::Path) -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_snell"));
    c.args(args).current_dir(cwd);
    c
}

fn run(args: &[&str], cwd: &std::path::Path) -> (Option<i32>, String) {
    let out = snell_cmd(args, cwd).output().expect("cannot run snell");
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!stderr.contains("panicked"), "snell panicked:\n{stderr}");
    (out.status.code(), stderr)
}

fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

#[track_caller]
fn finite_exr(path: &std::path::Path) -> snell::film::Image {
    let img = snell::film::output::read_exr(path).unwrap_or_else(|e| panic!("cannot read {}: {e:#}", path.display()));
    assert!(img.pixels.iter().all(|p| p.is_finite()), "{} has non-finite pixels", path.display());
    img
}

// ---------------------------------------------------------------- images

/// The byte offset of attribute `name` of type `box2i`'s value in an EXR header.
fn box2i_offset(bytes: &[u8], name: &str) -> usize {
    let key = format!("{name}\0box2i\0");
    let at = bytes.windows(key.len()).position(|w| w == key.as_bytes()).unwrap_or_else(|| panic!("no {name}"));
    at + key.len() + 4
}

#[test]
fn an_exr_header_claiming_a_huge_size_is_refused_before_decoding() {
    let (dir, scene) = cli_setup("exr-bomb");
    let tex = dir.join("bomb.exr");
    snell::film::output::write_image(&snell::film::Image::new(4, 4, vec![Rgb::new(0.5, 0.5, 0.5); 16]), &tex).unwrap();
    let mut bytes = std::fs::read(&tex).unwrap();
    // Claim 99 999 × 99 999 pixels in both windows.
    for name in ["dataWindow", "displayWindow"] {
        let o = box2i_offset(&bytes, name);
        bytes[o + 8..o + 12].copy_from_slice(&99_998i32.to_le_bytes());
        bytes[o + 12..o + 16].copy_from_slice(&99_998i32.to_le_bytes());
    }
    std::fs::write(&tex, &bytes).unwrap();
    assert!(bytes.len() < 2000);
    let start = Instant::now();
    let (code, stderr) = run(&["render", s(&scene), "-D", "texture=bomb.exr", "-o", s(&dir.join("out.exr"))], &dir);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("bomb.exr is 99999 × 99999 = 9999800001 pixels, above the budget of 268435456 pixels"), "{stderr}");
    assert!(stderr.contains("--max-image-pixels"), "{stderr}");
    assert!(start.elapsed().as_secs_f64() < 20.0);
}

/// A PNG of only a header (IHDR), a stub of data and an end marker.
fn png_header_only(width: u32, height: u32) -> Vec<u8> {
    fn crc32(data: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32(&body).to_be_bytes());
        out
    };
    let mut ihdr = width.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    // A stub of compressed data: the decoder needs an IDAT to report the size.
    png.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00]));
    png.extend(chunk(b"IEND", &[]));
    png
}

#[test]
fn the_image_pixel_budget_is_checked_from_the_header_and_configurable() {
    let (dir, scene) = cli_setup("png-budget");
    std::fs::write(dir.join("big.png"), png_header_only(20_000, 20_000)).unwrap();
    let out = dir.join("out.exr");
    let (code, stderr) = run(&["render", s(&scene), "-D", "texture=big.png", "-o", s(&out)], &dir);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("big.png is 20000 × 20000 = 400000000 pixels, above the budget"), "{stderr}");

    // The 16×16 texture renders by default, and is refused under a budget of 100 pixels.
    let (code, stderr) = run(&["render", s(&scene), "-q", "-o", s(&out)], &dir);
    assert_eq!(code, Some(0), "{stderr}");
    let (code, stderr) = run(&["render", s(&scene), "-q", "-o", s(&out), "--max-image-pixels", "100"], &dir);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("tex.png is 16 × 16 = 256 pixels, above the budget of 100 pixels"), "{stderr}");
    let (code, stderr) = run(&["render", s(&scene), "-q", "-o", s(&out), "--max-image-pixels", "16*16"], &dir);
    assert_eq!(code, Some(0), "{stderr}");
    let child = snell_cmd(&["render", s(&scene), "-q", "-o", s(&out)], &dir).env("SNELL_MAX_IMAGE_PIXELS", "255").output().unwrap();
    assert_eq!(child.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&child.stderr).contains("above the budget of 255 pixels"));
}

// ---------------------------------------------------------------- OBJ

#[test]
fn obj_errors_name_the_line() {
    let dir = temp_dir("obj");
    let cases = [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/3\n", 5, "texture coordinate 2, but the file has 1"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n# no normals\nf 1//1 2//1 3//1\n", 5, "normal 1, but the file has no normals"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\n", 5, "a face has 2 vertices; a face needs at least three"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", 4, "vertex 7, but the file has 3"),
        ("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n", 2, "\"zero\" in a vertex is not a number"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", 4, "index 0"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", 4, "vertex -4, but the file has 3"),
    ];
    for (i, (obj, line, message)) in cases.iter().enumerate() {
        let p = dir.join(format!("m{i}.obj"));
        std::fs::write(&p, obj).unwrap();
        let e = snell::geometry::mesh_io::read_obj(&p).err().unwrap_or_else(|| panic!("{obj} must be refused"));
        assert!(e.contains(&format!("m{i}.obj:{line}: ")), "expected line {line}: {e}");
        assert!(e.contains(message), "expected {message:?}: {e}");
        // Through a scene: the error points at the shape's filename and carries the OBJ line.
        let text = scene(&format!("    <shape type=\"obj\"><string name=\"filename\" value=\"m{i}.obj\"/></shape>\n"));
        let err = snell::load_str(&dir.join("scene.xml"), &text, &LoadOptions::default()).err().expect("must fail").to_string();
        assert!(err.contains(&format!("m{i}.obj:{line}: ")) && err.contains("scene.xml:9:"), "{err}");
    }
    // Negative indices, polygons, uv and normals, comments.
    let p = dir.join("good.obj");
    std::fs::write(&p, "# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf -4/1/1 -3/1/1 -2/1/1 -1/1/1 # fan\n").unwrap();
    let m = snell::geometry::mesh_io::read_obj(&p).unwrap();
    assert_eq!(m.triangles.len(), 2);
    assert_eq!(m.positions.len(), 4);
    assert_eq!(m.normals.as_ref().map(Vec::len), Some(4));
}

// ---------------------------------------------------------------- film and output

#[test]
fn a_film_too_large_for_the_memory_budget_is_refused_before_allocating() {
    let text = HEAD.replace("\"8\"", "\"65536\"").replace("\"6\"", "\"65536\"") + "</scene>\n";
    let scene = load_ok(&text);
    let estimate = snell::render::estimate_memory(&scene, false);
    assert!(estimate > 300 << 30, "{estimate}");
    // The budget is process-wide, and the fuzz tests of this binary lower it
    // (at any moment, so the message may name the budget before or after).
    let budget_before = snell::limits::max_film_bytes() >> 20;
    let start = Instant::now();
    let e = snell::render::<Rgb>(&scene, &RenderOptions::default()).err().expect("a 65536² film must be refused").to_string();
    assert!(start.elapsed().as_secs_f64() < 1.0);
    assert!(e.contains("the film of 65536 × 65536 pixels needs about"), "{e}");
    let budget_after = snell::limits::max_film_bytes() >> 20;
    assert!(
        [budget_before, budget_after].iter().any(|mb| e.contains(&format!("above the budget of {mb} MB"))),
        "{e}"
    );

    // A fresh process has the default budget, 8 GiB.
    let (dir, scene_file) = cli_setup("film-budget");
    let (code, stderr) = run(&["render", s(&scene_file), "-D", "res=65536", "-o", s(&dir.join("o.exr"))], &dir);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("the film of 65536 × 65536 pixels needs about") && stderr.contains("above the budget of 8192 MB"), "{stderr}");
    let (code, stderr) = run(&["render", s(&scene_file), "-D", "res=2048", "--max-film-mb", "64", "-o", s(&dir.join("o.exr"))], &dir);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("the film of 2048 × 2048 pixels needs about") && stderr.contains("above the budget of 64 MB"), "{stderr}");
}

#[test]
fn output_paths_are_checked_before_rendering() {
    let (dir, scene) = cli_setup("outputs");
    // 2^20 spp would take minutes: the checks must come first.
    for args in [
        vec!["-o", "missing/folder/out.exr"],
        vec!["-o", "a.exr", "-o", "missing/b.png"],
        vec!["-o", "a.exr", "-o", "b.png", "-o", "./a.exr"],
        vec!["-o", "a.exr", "--stats", "nowhere/stats.json"],
    ] {
        let start = Instant::now();
        let mut all = vec!["render", s(&scene), "-D", "spp=1048576"];
        all.extend(args.iter().copied());
        let (code, stderr) = run(&all, &dir);
        assert_eq!(code, Some(1), "{stderr}");
        assert!(start.elapsed().as_secs_f64() < 10.0, "{args:?} took {:?}", start.elapsed());
        assert!(stderr.contains("does not exist") || stderr.contains("is given twice"), "{stderr}");
        assert!(!dir.join("a.exr").exists(), "nothing may be written: {args:?}");
    }
}

/// Runs snell under a file-size limit (writes past 512 bytes fail with
/// EFBIG, as on a full disk), with SIGXFSZ ignored so the write reports it.
#[cfg(unix)]
#[test]
fn a_failed_write_is_an_error_naming_the_file_and_leaves_no_partial_file() {
    let (dir, scene) = cli_setup("full-disk");
    for name in ["out.exr", "out.png", "out.pfm"] {
        let out = dir.join(name);
        let script = format!("trap '' XFSZ; ulimit -f 1; exec \"$0\" render {} -q -D res=64 -o {}", s(&scene), s(&out));
        let child = std::process::Command::new("sh").arg("-c").arg(&script).arg(env!("CARGO_BIN_EXE_snell")).current_dir(&dir).output().unwrap();
        let stderr = String::from_utf8_lossy(&child.stderr);
        assert_eq!(child.status.code(), Some(1), "{name}: {stderr}");
        assert!(stderr.contains(&format!("cannot write {}", s(&out))), "{name}: {stderr}");
        assert!(!out.exists(), "{name}: a partial file was left");
        let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().filter_map(|e| e.ok()).filter(|e| e.file_name().to_string_lossy().starts_with('.')).collect();
        assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
        // Without the limit the same render succeeds.
        let (code, stderr) = run(&["render", s(&scene), "-q", "-D", "res=64", "-o", s(&out)], &dir);
        assert_eq!(code, Some(0), "{stderr}");
        assert!(out.exists());
        std::fs::remove_file(&out).unwrap();
    }
}

#[test]
fn a_closed_stderr_does_not_panic() {
    let (dir, scene) = cli_setup("stderr");
    let out = dir.join("out.exr");
    // The warning (reflectance above one is not it: texture is in [0, 1]) and
    // the summary line go to a pipe whose reader is gone.
    let mut child = snell_cmd(&["render", s(&scene), "-o", s(&out)], &dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0), "{status}");
    finite_exr(&out);
}

#[test]
fn too_many_threads_is_a_clear_error() {
    let (dir, scene) = cli_setup("threads");
    let start = Instant::now();
    let (code, stderr) = run(&["render", s(&scene), "--threads", "100000", "-o", s(&dir.join("o.exr"))], &dir);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("--threads 100000 is more than the 4096 worker threads"), "{stderr}");
    assert!(start.elapsed().as_secs_f64() < 10.0);
}

// ---------------------------------------------------------------- signals

#[cfg(unix)]
#[test]
fn sigterm_writes_the_partial_image_and_exits_130() {
    let (dir, scene) = cli_setup("sigterm");
    let (exr, png, stats) = (dir.join("out.exr"), dir.join("out.png"), dir.join("stats.json"));
    // 32 × 32 at 2^18 spp: minutes of work; one tile row is a fraction of a second.
    let mut child = snell_cmd(
        // One pass: an interruption leaves the partial image (with passes,
        // the last complete pass; tests/render_loop.rs).
        &["render", s(&scene), "-D", "spp=262144", "--threads", "2", "--passes", "1", "-o", s(&exr), "-o", s(&png), "--stats", s(&stats)],
        &dir,
    )
    .stderr(std::process::Stdio::piped())
    .spawn()
    .unwrap();
    std::thread::sleep(std::time::Duration::from_secs(3));
    assert!(child.try_wait().unwrap().is_none(), "the render finished before the signal");
    let killed = std::process::Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    assert!(killed.success());
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed().as_secs() > 60 {
            let _ = child.kill();
            panic!("snell did not stop within 60 s of SIGTERM");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert_eq!(status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted: wrote the partial image"), "{stderr}");
    let img = finite_exr(&exr);
    assert!(png.exists());
    // Some pixels were rendered (the sphere is lit), not all (it stopped early).
    let lit = img.pixels.iter().filter(|p| p.0.iter().any(|&c| c > 0.0)).count();
    assert!(lit > 0 && lit < img.pixels.len(), "{lit} of {} pixels rendered", img.pixels.len());
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(json["interrupted"], true, "{json}");
    let (taken, planned) = (json["samples_taken"].as_u64().unwrap(), json["samples_planned"].as_u64().unwrap());
    assert!(taken > 0 && taken < planned && taken % 262144 == 0, "{json}");
    assert_eq!(planned, 32 * 32 * 262144);
}

//! A seeded mutation fuzzer for everything Snell reads: scenes (loaded and,
//! when they load, rendered at 8×8 and 1 spp in RGB and spectral mode), OBJ
//! and PLY meshes and PNG, JPEG and EXR textures (each read directly and
//! through a scene that renders it).
//!
//! Every case must not panic, must finish within `SNELL_FUZZ_CASE_SECONDS`
//! (default 10), and, when it renders, must give finite pixels. A failure
//! prints the kind, seed and case index, and the input is saved under the
//! system temp folder (`snell-fuzz-failures/`).
//!
//! Bounded by default (a few thousand cases, well under a minute in
//! `cargo test --release`); `tools/fuzz.sh` runs the same tests for as long
//! as asked, through `SNELL_FUZZ_SEED` (first seed) and `SNELL_FUZZ_CASES`
//! (cases per kind and seed).

use snell::spectrum::{Rgb, Sampled};
use snell::{LoadOptions, RenderOptions};
use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// SplitMix64.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next() % n as u64) as usize }
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

/// (first seed, cases per kind, seconds per case).
fn settings(default_cases: u64) -> (u64, u64, f64) {
    (env_u64("SNELL_FUZZ_SEED", 17), env_u64("SNELL_FUZZ_CASES", default_cases), env_u64("SNELL_FUZZ_CASE_SECONDS", 10) as f64)
}

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn work_dir(kind: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snell-fuzz-{}-{kind}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Keeps fuzzed images small (a header claiming more is refused cheaply),
/// and fits the spectral uplift table once before any case is timed (a
/// one-off cost of seconds, as `snell render` also pays before rendering).
fn small_budgets() {
    snell::limits::set_max_image_pixels(1 << 20);
    snell::limits::set_max_film_bytes(256 << 20);
    snell::spectrum::uplift::RgbUplift::get();
}

const TROUBLE: [&str; 24] = [
    "", " ", "0", "-1", "-0", "1e40", "-1e40", "1e-45", "nan", "inf", "-inf", "abc", "$", "$res", "3e38", "-3e38",
    "9223372036854775807", "99999999999999999999", "0, 0, 0", "1 2", "1,2,3,4", "//", "/", "-999999",
];

/// One to four mutations of `input`: byte changes, deletions, duplications,
/// insertions of troublesome text, truncation.
fn mutate(rng: &mut Rng, input: &[u8], specials: &[u8]) -> Vec<u8> {
    let mut b = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        if b.is_empty() {
            break;
        }
        let i = rng.below(b.len());
        match rng.below(8) {
            0 => b[i] = rng.next() as u8,
            1 => b[i] = *rng.pick(specials),
            2 => {
                let n = 1 + rng.below(16);
                b.drain(i..(i + n).min(b.len()));
            }
            3 => {
                let n = 1 + rng.below(64);
                let chunk: Vec<u8> = b[i..(i + n).min(b.len())].to_vec();
                let at = rng.below(b.len());
                b.splice(at..at, chunk);
            }
            4 => {
                let t = rng.pick(&TROUBLE).as_bytes().to_vec();
                b.splice(i..i, t);
            }
            5 => b.truncate(i),
            6 => {
                // Replace a token (up to the next separator) with trouble.
                let end = b[i..].iter().position(|c| b" \t\n\"',/<>".contains(c)).map_or(b.len(), |p| i + p);
                let t = rng.pick(&TROUBLE).as_bytes().to_vec();
                b.splice(i..end, t);
            }
            _ => {
                // Header bytes matter most in binary formats.
                let j = rng.below(b.len().min(128));
                b[j] = b[j].wrapping_add(1 + rng.below(255) as u8);
            }
        }
    }
    b
}

/// Saves a failing input and panics with where it is.
fn fail(kind: &str, seed: u64, case: u64, ext: &str, bytes: &[u8], why: &str) -> ! {
    let dir = std::env::temp_dir().join("snell-fuzz-failures");
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join(format!("{kind}-{seed}-{case}.{ext}"));
    let _ = std::fs::write(&path, bytes);
    panic!("fuzz {kind} seed {seed} case {case}: {why} (input saved to {})", path.display());
}

/// Renders `scene` at 8×8 and 1 spp in RGB or spectral mode; `Err` names a
/// non-finite pixel. Rendering errors (e.g. a budget) are fine.
fn render_tiny(mut scene: snell::Scene, spectral: bool) -> Result<(), String> {
    scene.film.width = 8;
    scene.film.height = 8;
    scene.sampler.sample_count = 1;
    let options = RenderOptions { threads: 1, ..RenderOptions::default() };
    let result = if spectral { snell::render::<Sampled>(&scene, &options) } else { snell::render::<Rgb>(&scene, &options) };
    if let Ok((image, _)) = result {
        if let Some(p) = image.pixels.iter().find(|p| !p.is_finite()) {
            return Err(format!("non-finite pixel {p:?}"));
        }
    }
    Ok(())
}

#[derive(Default, Debug)]
struct Tally {
    cases: u64,
    loaded: u64,
    errors: u64,
    slowest: f64,
}

/// Loads scene text (as if at `path`) and renders it if it loads.
fn scene_case(kind: &str, seed: u64, case: u64, path: &Path, bytes: &[u8], params: &HashMap<String, String>, limit: f64, tally: &mut Tally) {
    tally.cases += 1;
    let text = String::from_utf8_lossy(bytes).to_string();
    let options = LoadOptions { params: params.clone(), spp: None, seed: None };
    let start = Instant::now();
    let outcome = catch_unwind(AssertUnwindSafe(|| match snell::load_str(path, &text, &options) {
        Ok(scene) => render_tiny(scene, case % 2 == 1).map(|_| true),
        Err(e) => {
            let shown = e.to_string();
            assert!(shown.starts_with("error: "), "{shown}");
            Ok(false)
        }
    }));
    let seconds = start.elapsed().as_secs_f64();
    tally.slowest = tally.slowest.max(seconds);
    match outcome {
        Err(_) => fail(kind, seed, case, "xml", bytes, "panicked"),
        Ok(Err(why)) => fail(kind, seed, case, "xml", bytes, &why),
        Ok(Ok(true)) => tally.loaded += 1,
        Ok(Ok(false)) => tally.errors += 1,
    }
    if seconds > limit {
        fail(kind, seed, case, "xml", bytes, &format!("took {seconds:.1} s"));
    }
}

fn report(kind: &str, seed: u64, t: &Tally) {
    eprintln!(
        "fuzz {kind}: seed {seed}: {} cases, {} loaded and rendered, {} clean errors, 0 panics, slowest {:.3} s",
        t.cases, t.loaded, t.errors, t.slowest
    );
}

#[test]
fn fuzz_scenes() {
    small_budgets();
    let (seed, cases, limit) = settings(1200);
    let seeds: Vec<PathBuf> = [
        "scenes/cornell-box.xml",
        "tests/scenes/mesh-env.xml",
        "tests/scenes/plastic.xml",
        "tests/scenes/ortho-rect-light.xml",
        "tests/scenes/caustics.xml",
        "tests/scenes/polarized-glass-metal.xml",
        "tests/scenes/thin-pane.xml",
        "tests/scenes/spheres-direct.xml",
    ]
    .iter()
    .map(|p| repo(p))
    .filter(|p| p.exists())
    .collect();
    let originals: Vec<Vec<u8>> = seeds.iter().map(|p| std::fs::read(p).unwrap()).collect();
    let mut tally = Tally::default();
    let mut rng = Rng(seed);
    let specials = b"<>/\"'=&$-.0 9eE\n\tx";
    for case in 0..cases {
        let k = rng.below(seeds.len());
        let bytes = mutate(&mut rng, &originals[k], specials);
        // The scenes' own parameters, small, and now and then a hostile one.
        let mut params: HashMap<String, String> = HashMap::new();
        let text = String::from_utf8_lossy(&originals[k]);
        for name in ["res", "spp"] {
            if text.contains(&format!("<default name=\"{name}\"")) {
                params.insert(name.to_string(), if name == "res" { "8" } else { "1" }.to_string());
            }
        }
        if rng.below(8) == 0 {
            if let Some((_, v)) = params.iter_mut().next() {
                *v = rng.pick(&TROUBLE).to_string();
            }
        }
        scene_case("scene", seed, case, &seeds[k], &bytes, &params, limit, &mut tally);
    }
    report("scene", seed, &tally);
    assert!(cases < 300 || (tally.loaded > 0 && tally.errors > 0), "{tally:?}");
}

/// A scene around a mesh or texture file: the mesh itself with a diffuse
/// BSDF, or a sphere textured with the image, under a constant light.
fn wrapper_scene(shape: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="60"/>
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    {shape}
</scene>
"#
    )
}

/// Writes each mutated file to `dir/name`, then reads it through `read` and
/// through a scene that renders it.
#[allow(clippy::too_many_arguments)]
fn file_cases(
    kind: &str,
    originals: &[(Vec<u8>, &str)],
    shape_for: impl Fn(&str) -> String,
    read: impl Fn(&Path) -> Result<(), String>,
    specials: &[u8],
) {
    small_budgets();
    let (seed, cases, limit) = settings(300);
    let dir = work_dir(kind);
    let mut tally = Tally::default();
    let mut rng = Rng(seed ^ 0x0bad_f00d);
    for case in 0..cases {
        let (original, ext) = &originals[rng.below(originals.len())];
        let bytes = mutate(&mut rng, original, specials);
        let name = format!("input.{ext}");
        let path = dir.join(&name);
        std::fs::write(&path, &bytes).unwrap();
        let start = Instant::now();
        let direct = catch_unwind(AssertUnwindSafe(|| read(&path)));
        match direct {
            Err(_) => fail(kind, seed, case, ext, &bytes, "the reader panicked"),
            Ok(Err(why)) if why.starts_with("BUG") => fail(kind, seed, case, ext, &bytes, &why),
            Ok(_) => {}
        }
        let scene_text = wrapper_scene(&shape_for(&name));
        scene_case(kind, seed, case, &dir.join("scene.xml"), scene_text.as_bytes(), &HashMap::new(), limit, &mut tally);
        let seconds = start.elapsed().as_secs_f64();
        if seconds > limit {
            fail(kind, seed, case, ext, &bytes, &format!("took {seconds:.1} s"));
        }
    }
    report(kind, seed, &tally);
    // The default run must exercise both outcomes; a small campaign batch
    // may by chance break every input (e.g. 200 PLY mutations, none loads).
    assert!(cases < 300 || (tally.loaded > 0 && tally.errors > 0), "{tally:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

fn check_mesh(m: snell::geometry::mesh_io::RawMesh) -> Result<(), String> {
    let n = m.positions.len();
    if m.triangles.iter().flatten().any(|&i| i as usize >= n) || m.positions.iter().any(|p| !p.is_finite()) {
        return Err("BUG: the reader returned an invalid mesh".into());
    }
    Ok(())
}

fn mesh_shape(kind: &str) -> impl Fn(&str) -> String {
    let kind = kind.to_string();
    move |name: &str| format!("<shape type=\"{kind}\"><string name=\"filename\" value=\"{name}\"/></shape>")
}

#[test]
fn fuzz_obj() {
    let cube = "# cube\nv -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 -1\nvn 0 0 1\nvn 0 -1 0\nvn 0 1 0\nvn -1 0 0\nvn 1 0 0\n\
f 1/1/1 4/4/1 3/3/1 2/2/1\nf 5/1/2 6/2/2 7/3/2 8/4/2\nf 1/1/3 2/2/3 6/3/3 5/4/3\nf 4/1/4 8/2/4 7/3/4 3/4/4\nf 1/1/5 5/2/5 8/3/5 4/4/5\nf 2/1/6 3/2/6 7/3/6 6/4/6\n";
    let tris = "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ng g1\nf 1 2 3\nf -3 -1 -2\nusemtl x\nf 1//1 2//1 3//1\nvn 0 0 1\n";
    let torus = std::fs::read(repo("tests/scenes/assets/torus.obj")).unwrap_or_default();
    let mut originals = vec![(cube.as_bytes().to_vec(), "obj"), (tris.as_bytes().to_vec(), "obj")];
    if !torus.is_empty() && torus.len() < 200_000 {
        originals.push((torus, "obj"));
    }
    file_cases(
        "obj",
        &originals,
        mesh_shape("obj"),
        |p| snell::geometry::mesh_io::read_obj(p).map_or(Ok(()), check_mesh),
        b"vfn/ -.0123456789e#\n",
    );
}

fn ply_ascii() -> Vec<u8> {
    b"ply\nformat ascii 1.0\ncomment fuzz seed\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n-1 -1 0 0 0 1 0 0\n1 -1 0 0 0 1 1 0\n1 1 0 0 0 1 1 1\n-1 1 0 0 0 1 0 1\n3 0 1 2\n4 0 2 3 1\n".to_vec()
}

fn ply_binary(big_endian: bool) -> Vec<u8> {
    let format = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
    let mut out = format!("ply\nformat {format} 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar uint vertex_indices\nend_header\n").into_bytes();
    let f = |v: f32| if big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
    let u = |v: u32| if big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
    for p in [[-1.0f32, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]] {
        for c in p {
            out.extend_from_slice(&f(c));
        }
    }
    for face in [[0u32, 1, 2], [0, 2, 3]] {
        out.push(3);
        for i in face {
            out.extend_from_slice(&u(i));
        }
    }
    out
}

#[test]
fn fuzz_ply() {
    let mut originals = vec![(ply_ascii(), "ply"), (ply_binary(false), "ply"), (ply_binary(true), "ply")];
    let bowl = std::fs::read(repo("tests/scenes/assets/bowl.ply")).unwrap_or_default();
    if !bowl.is_empty() && bowl.len() < 200_000 {
        originals.push((bowl, "ply"));
    }
    file_cases(
        "ply",
        &originals,
        mesh_shape("ply"),
        |p| snell::geometry::mesh_io::read_ply(p).map_or(Ok(()), check_mesh),
        b" 0123456789\n-.e\xff\x00",
    );
}

#[test]
fn fuzz_bitmaps() {
    let dir = work_dir("bitmap-seeds");
    let px: Vec<u8> = (0..16 * 16 * 3).map(|i| (i * 37 % 251) as u8).collect();
    let mut originals = vec![];
    for (ext, color) in [("png", image::ExtendedColorType::Rgb8), ("jpg", image::ExtendedColorType::Rgb8)] {
        let p = dir.join(format!("seed.{ext}"));
        image::save_buffer(&p, &px, 16, 16, color).unwrap();
        originals.push((std::fs::read(&p).unwrap(), ext));
    }
    // 16-bit grey, as native-endian bytes (what save_buffer expects for L16).
    let gray: Vec<u8> = (0..64u16).flat_map(|i| (i * 1000).to_ne_bytes()).collect();
    let p = dir.join("seed16.png");
    image::save_buffer(&p, &gray, 8, 8, image::ExtendedColorType::L16).unwrap();
    originals.push((std::fs::read(&p).unwrap(), "png"));
    let exr = dir.join("seed.exr");
    let texels: Vec<Rgb> = (0..64).map(|i| Rgb::new(i as f32 / 64.0, 0.5, 1.0 - i as f32 / 64.0)).collect();
    snell::film::output::write_image(&snell::film::Image::new(8, 8, texels), &exr).unwrap();
    originals.push((std::fs::read(&exr).unwrap(), "exr"));
    let grid = std::fs::read(repo("tests/scenes/assets/grid.png")).unwrap_or_default();
    if !grid.is_empty() && grid.len() < 100_000 {
        originals.push((grid, "png"));
    }
    file_cases(
        "bitmap",
        &originals,
        |name| {
            format!(
                "<shape type=\"sphere\"><bsdf type=\"diffuse\"><texture type=\"bitmap\" name=\"reflectance\"><string name=\"filename\" value=\"{name}\"/></texture></bsdf></shape>"
            )
        },
        |p| match snell::texture::bitmap::read_image(p, false) {
            Ok((w, h, texels)) if texels.len() != w * h || texels.iter().any(|t| !t.is_finite()) => {
                Err("BUG: the image reader returned a bad image".into())
            }
            _ => Ok(()),
        },
        b"\x00\xff\x01\x7f\x80",
    );
    let _ = std::fs::remove_dir_all(&dir);
}

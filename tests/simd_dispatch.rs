//! Runtime CPU dispatch: the `snell` command renders the same image with
//! every instruction-set level of the BVH traversal this CPU runs, forced
//! with `SNELL_SIMD=baseline|avx2|avx512` (the level used is read back from
//! `--stats`). AVX2 and AVX-512 run the same 8-wide code and must agree bit
//! for bit; the baseline path does not fuse multiply-adds on x86-64, so a
//! ray grazing an edge may rarely hit the other triangle: its image must
//! agree within that float noise.

use snell::geometry::accel::SimdLevel;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Renders `scene` with the level forced; returns the image and the level
/// the stats report.
fn render(scene: &Path, defines: &[&str], level: SimdLevel, dir: &Path) -> (snell::film::Image, String) {
    let out = dir.join(format!("{}.exr", level.name()));
    let stats = dir.join(format!("{}.json", level.name()));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_snell"));
    cmd.arg("render").arg(scene).arg("-o").arg(&out).arg("--stats").arg(&stats).args(["--threads", "2", "--quiet"]);
    for d in defines {
        cmd.args(["-D", d]);
    }
    let o = cmd.env("SNELL_SIMD", level.name()).output().expect("cannot run snell");
    assert!(o.status.success(), "snell failed: {}", String::from_utf8_lossy(&o.stderr));
    let st: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let img = snell::film::output::read_exr(&out).unwrap();
    (img, st["simd"].as_str().unwrap_or("").to_string())
}

fn check_scene(name: &str, scene: &str, defines: &[&str]) {
    let dir = std::env::temp_dir().join(format!("snell-simd-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let levels: Vec<SimdLevel> = SimdLevel::ALL.into_iter().filter(|l| l.supported()).collect();
    let missing: Vec<&str> = SimdLevel::ALL.into_iter().filter(|l| !l.supported()).map(SimdLevel::name).collect();
    eprintln!("{name}: testing levels {:?}; this CPU cannot run {missing:?}", levels.iter().map(|l| l.name()).collect::<Vec<_>>());
    let images: Vec<_> = levels
        .iter()
        .map(|&l| {
            let (img, used) = render(&repo(scene), defines, l, &dir);
            assert_eq!(used, l.name(), "{name}: SNELL_SIMD={} ran {used}", l.name());
            img
        })
        .collect();
    let best = images.last().unwrap();
    let m = best.pixels.iter().map(|p| p.0.iter().map(|&c| c as f64).sum::<f64>()).sum::<f64>() / best.pixels.len() as f64;
    assert!(m > 0.01, "{name}: the image is black");
    for (l, img) in levels.iter().zip(&images) {
        let pairs = || img.pixels.iter().zip(&best.pixels);
        if *l >= SimdLevel::Avx2 {
            assert!(pairs().all(|(a, b)| a.0.map(f32::to_bits) == b.0.map(f32::to_bits)), "{name}: {} and {} differ", l.name(), levels.last().unwrap().name());
            continue;
        }
        // Rounding differences move hit points by an ulp or so (most pixels
        // then differ in their last bits); a rare path takes another turn.
        let d = |a: &snell::spectrum::Rgb, b: &snell::spectrum::Rgb| (0..3).map(|c| (a.0[c] as f64 - b.0[c] as f64).abs()).sum::<f64>();
        let s = |b: &snell::spectrum::Rgb| b.0.iter().map(|&c| c.abs() as f64).sum::<f64>();
        let n = best.pixels.len() as f64;
        let close = pairs().filter(|(a, b)| d(a, b) <= 1e-4 * (s(b) + 1e-3)).count() as f64 / n;
        let diff = pairs().map(|(a, b)| d(a, b)).sum::<f64>() / n;
        eprintln!("{name}: {} vs best: {:.2} % of pixels within 1e-4, mean |difference| {:.2e} (mean {m:.3})", l.name(), 100.0 * close, diff);
        assert!(close > 0.95 && diff < 1e-3 * m, "{name}: {} differs from the best level beyond float noise ({close}, {diff})", l.name());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_level_renders_the_cornell_box_alike() {
    check_scene("cornell", "scenes/cornell-box.xml", &["res=64", "spp=16"]);
}

#[test]
fn every_level_renders_ply_and_obj_meshes_alike() {
    check_scene("mesh-env", "tests/scenes/mesh-env.xml", &["res=64", "height=48", "spp=16"]);
}

/// `scene` rendered at 64², 16 spp into `out` with the environment
/// variables `env` set (they choose the BVH's storage).
fn render_with_env(scene: &str, out: &Path, env: &[(&str, &str)]) -> snell::film::Image {
    let o = Command::new(env!("CARGO_BIN_EXE_snell"))
        .arg("render")
        .arg(repo(scene))
        .arg("-o")
        .arg(out)
        .args(["--threads", "2", "--quiet", "-D", "res=64", "-D", "spp=16"])
        .envs(env.iter().copied())
        .output()
        .expect("cannot run snell");
    assert!(o.status.success(), "snell failed: {}", String::from_utf8_lossy(&o.stderr));
    snell::film::output::read_exr(out).unwrap()
}

/// The BVH's triangle storages (lanes stored ready for small BVHs,
/// gathered from the mesh as loaded or, as above `PACKED_MAX_TRIANGLES`,
/// renumbered in leaf order), forced with `SNELL_TRIANGLES`, give the same
/// image bit for bit at the best level.
#[test]
fn stored_and_gathered_triangles_render_alike() {
    let dir = std::env::temp_dir().join(format!("snell-triangles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // `ordered` renumbers the meshes in leaf order: the same hits, but an
    // emitting mesh's triangles (the Cornell box's light) would be drawn
    // in another order, so it is compared on the scene without one.
    for (scene, storages) in [("scenes/cornell-box.xml", &["packed", "indexed"][..]), ("tests/scenes/mesh-env.xml", &["packed", "indexed", "ordered"][..])] {
        let images: Vec<snell::film::Image> = storages
            .iter()
            .map(|storage| {
                render_with_env(scene, &dir.join(format!("{storage}.exr")), &[("SNELL_TRIANGLES", storage)])
            })
            .collect();
        let m = images[0].pixels.iter().map(|p| p.0.iter().sum::<f32>()).sum::<f32>() / images[0].pixels.len() as f32;
        assert!(m > 0.01, "{scene}: black image");
        for (storage, image) in storages.iter().zip(&images).skip(1) {
            let same = images[0].pixels.iter().zip(&image.pixels).all(|(a, b)| a.0.map(f32::to_bits) == b.0.map(f32::to_bits));
            assert!(same, "{scene}: stored and gathered ({storage}) triangles render differently");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Quantized BVH nodes (`SNELL_NODES=quantized`: child boxes grown to 8-bit
/// planes) give the same image bit for bit as full ones, with the
/// triangles stored as lanes and gathered from the mesh in leaf order.
#[test]
fn full_and_quantized_nodes_render_alike() {
    let dir = std::env::temp_dir().join(format!("snell-nodes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for storage in ["packed", "ordered"] {
        let images: Vec<snell::film::Image> = ["full", "quantized"]
            .iter()
            .map(|nodes| {
                render_with_env("tests/scenes/mesh-env.xml", &dir.join(format!("{storage}-{nodes}.exr")), &[("SNELL_TRIANGLES", storage), ("SNELL_NODES", nodes)])
            })
            .collect();
        let m = images[0].pixels.iter().map(|p| p.0.iter().sum::<f32>()).sum::<f32>() / images[0].pixels.len() as f32;
        assert!(m > 0.01, "{storage}: black image");
        let same = images[0].pixels.iter().zip(&images[1].pixels).all(|(a, b)| a.0.map(f32::to_bits) == b.0.map(f32::to_bits));
        assert!(same, "{storage}: full and quantized nodes render differently");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

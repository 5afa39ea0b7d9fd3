//! Snell's integration tests, one module per area, built as a single test
//! binary: under `cargo test --release` every test binary is a fat-LTO link of
//! the whole renderer, so one binary instead of one per file cuts the build of
//! the suite by several minutes. `autotests = false` in Cargo.toml stops Cargo
//! from also building each file alone; a new `tests/NAME.rs` is declared here
//! (the last test below checks that none is forgotten). Run one area with
//! `cargo test --release --test integration sppm::`.

mod common;

mod adaptive;
mod analytic;
mod aov;
mod bdpt;
mod birefringence;
mod bsdf_adapters;
mod cli;
mod documents;
mod emitters;
mod fuzz;
mod gallery_scenes;
mod guiding;
mod hardening;
mod light_selection;
mod media;
mod mitsuba_reference;
mod path_reuse;
mod path_split;
mod polarization;
mod polarized_materials;
mod preview;
mod prism;
mod ptracer;
mod rainbow;
mod render_loop;
mod samplers;
mod scene_errors;
mod sensors;
mod shapes;
mod simd_dispatch;
mod spectral;
mod specular;
mod sphere_connection;
mod sppm;
mod tiles;
mod vcm;
mod wavefront;

/// Every `tests/*.rs` file is a module of this binary: a file left out would
/// silently never run.
#[test]
fn every_test_file_is_declared() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let this = std::fs::read_to_string(dir.join("main.rs")).expect("tests/main.rs");
    let mut missing = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("tests/") {
        let path = entry.expect("tests/ entry").path();
        let Some(stem) = path.file_stem().and_then(|s| s.to_str()) else { continue };
        if path.extension().is_some_and(|e| e == "rs") && stem != "main" && !this.contains(&format!("\nmod {stem};\n")) {
            missing.push(stem.to_string());
        }
    }
    assert!(missing.is_empty(), "tests/main.rs does not declare: {missing:?}");
}

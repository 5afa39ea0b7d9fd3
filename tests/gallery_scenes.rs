//! Every scene shipped in `scenes/` loads and renders (tiny, a few samples):
//! a bundled scene can never rot unnoticed. Their agreement with Mitsuba 3 is
//! checked by hand when they change (numbers in the commit messages); the
//! physics is tested on purpose-built scenes in the other test files.

use snell::spectrum::Rgb;
use snell::{LoadOptions, RenderOptions};
use std::collections::HashMap;
use std::path::PathBuf;

#[test]
fn every_bundled_scene_loads_and_renders() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "xml"))
        .collect();
    scenes.sort();
    // The README's gallery: these must stay.
    for name in ["cornell-box", "caustic-cornell-box", "snells-window", "glass-of-water", "metal-showcase", "prism", "diamond", "pool", "pool-polarizer", "calcite"] {
        assert!(scenes.iter().any(|p| p.file_stem().is_some_and(|s| s == name)), "scenes/{name}.xml is missing");
    }
    for path in &scenes {
        let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        // Shrink the film through the scene's own parameters.
        let mut params = HashMap::new();
        for (name, value) in [("res", "16"), ("height", "8")] {
            if text.contains(&format!("<default name=\"{name}\"")) {
                params.insert(name.to_string(), value.to_string());
            }
        }
        assert!(params.contains_key("res"), "{}: declare <default name=\"res\"> for the film size", path.display());
        let options = LoadOptions { params, spp: Some(4), seed: None };
        let scene = snell::load_file(path, &options).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let (image, stats) =
            snell::render::<Rgb>(&scene, &RenderOptions { threads: 1, ..RenderOptions::default() }).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(stats.invalid_samples, 0, "{}", path.display());
        assert!(image.pixels.iter().all(|p| p.is_finite()), "{}", path.display());
        let mean = image.pixels.iter().map(|p| p.mean()).sum::<f32>() / image.pixels.len() as f32;
        assert!(mean > 0.01, "{}: black image (mean {mean})", path.display());
    }
}

//! Scene documents as Mitsuba 3.9 reads them: `<path>` search folders,
//! `<include>` resolution, the in-memory upgrade of version 0.x files, and
//! features that are named as "not supported yet".

use crate::common::*;
use snell::film::Image;
use snell::{LoadOptions, RenderOptions, SceneError};
use std::path::{Path, PathBuf};

/// A fresh folder for scenes that refer to files.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snell-documents-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const SENSOR: &str = r#"<sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
    </sensor>"#;

/// One triangle facing +z.
const TRIANGLE_OBJ: &str = "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n";

fn load(path: &Path) -> Result<snell::Scene, SceneError> {
    snell::load_file(path, &LoadOptions::default())
}

#[track_caller]
fn load_err(path: &Path) -> SceneError {
    match load(path) {
        Ok(_) => panic!("expected {} to fail", path.display()),
        Err(e) => e,
    }
}

fn triangle_count(scene: &snell::Scene) -> usize {
    scene.shapes.len()
}

#[test]
fn path_adds_search_folders_tried_last_declared_first() {
    // scenes/s.xml finds meshes in ../common (a <path>), the later <path> first.
    let dir = temp_dir("path");
    for d in ["scenes", "common/meshes", "other/meshes"] {
        std::fs::create_dir_all(dir.join(d)).unwrap();
    }
    std::fs::write(dir.join("common/meshes/tri.obj"), TRIANGLE_OBJ).unwrap();
    // A broken copy in the folder declared first: it must not be the one read.
    std::fs::write(dir.join("other/meshes/tri.obj"), "this is not an OBJ file\nf 7 8 9\n").unwrap();
    let scene = dir.join("scenes/s.xml");
    let text = |paths: &str| {
        format!(
            "<scene version=\"3.0.0\">\n    {paths}\n    {SENSOR}\n    <shape type=\"obj\"><string name=\"filename\" value=\"meshes/tri.obj\"/></shape>\n</scene>\n"
        )
    };
    std::fs::write(&scene, text(r#"<path value="../other"/><path value="../common"/>"#)).unwrap();
    let loaded = load(&scene).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(triangle_count(&loaded), 1);
    // Declared the other way round, the broken copy is found first.
    std::fs::write(&scene, text(r#"<path value="../common"/><path value="../other"/>"#)).unwrap();
    let e = load_err(&scene);
    assert!(e.message.contains("OBJ"), "{e}");
    // Without a <path>, the mesh is not found; the error lists the folders searched.
    std::fs::write(&scene, text("")).unwrap();
    let e = load_err(&scene);
    let shown = e.to_string();
    assert_eq!(e.location.as_ref().map(|l| l.line), Some(8), "{shown}");
    let help = e.help.as_deref().unwrap_or_else(|| panic!("no help: {shown}"));
    assert!(help.contains("meshes/tri.obj") && help.contains(&dir.join("scenes").display().to_string()), "{shown}");
    // With the <path>, its folder is listed first.
    std::fs::write(&scene, text(r#"<path value="../common"/>"#).replace("tri.obj", "missing.obj")).unwrap();
    let e = load_err(&scene);
    let help = e.help.as_deref().unwrap_or_default();
    let (common, scenes) =
        (format!("\"{}\"", dir.join("scenes/../common").display()), format!("\"{}\"", dir.join("scenes").display()));
    let (i, j) = (help.find(&common), help.find(&scenes));
    assert!(i.is_some() && j.is_some() && i < j, "{e}");
}

#[test]
fn path_to_a_missing_folder_is_a_located_error() {
    let dir = temp_dir("path-missing");
    let scene = dir.join("s.xml");
    std::fs::write(&scene, format!("<scene version=\"3.0.0\">\n    <path value=\"../nowhere\"/>\n    {SENSOR}\n</scene>\n")).unwrap();
    let e = load_err(&scene);
    let loc = e.location.as_ref().expect("located");
    assert_eq!((loc.line, loc.col), (2, 11), "{e}");
    assert!(e.message.contains("folder \"../nowhere\" not found"), "{e}");
    // <path> belongs to the scene, not inside an object.
    std::fs::write(&scene, format!("<scene version=\"3.0.0\">\n    {SENSOR}\n    <shape type=\"sphere\"><path value=\".\"/></shape>\n</scene>\n")).unwrap();
    let e = load_err(&scene);
    assert!(e.message.contains("<path> may only appear directly inside <scene>"), "{e}");
}

#[test]
fn includes_resolve_from_the_including_files_folder_first() {
    // As Mitsuba 3.9.1 (checked with it): include/a.xml includes "b.xml",
    // which exists both beside it and beside the scene: the one beside a.xml
    // wins; "c.xml", only beside the scene, is found there.
    let dir = temp_dir("include");
    std::fs::create_dir_all(dir.join("include")).unwrap();
    let sphere = "<scene version=\"3.0.0\">\n    <shape type=\"sphere\"/>\n</scene>\n";
    let two = "<scene version=\"3.0.0\">\n    <shape type=\"sphere\"/>\n    <shape type=\"sphere\"/>\n</scene>\n";
    std::fs::write(dir.join("include/b.xml"), sphere).unwrap();
    std::fs::write(dir.join("b.xml"), two).unwrap();
    std::fs::write(dir.join("c.xml"), two).unwrap();
    std::fs::write(
        dir.join("include/a.xml"),
        "<scene version=\"3.0.0\">\n    <include filename=\"b.xml\"/>\n    <include filename=\"c.xml\"/>\n</scene>\n",
    )
    .unwrap();
    let scene = dir.join("s.xml");
    std::fs::write(&scene, format!("<scene version=\"3.0.0\">\n    {SENSOR}\n    <include filename=\"include/a.xml\"/>\n</scene>\n")).unwrap();
    let loaded = load(&scene).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(triangle_count(&loaded), 1 + 2);
    // An include that is nowhere: located in the including file, its folders listed.
    std::fs::write(dir.join("include/b.xml"), "<scene version=\"3.0.0\">\n    <include filename=\"d.xml\"/>\n</scene>\n").unwrap();
    let e = load_err(&scene);
    let loc = e.location.as_ref().expect("located");
    assert_eq!((loc.file.path.clone(), loc.line, loc.col), (dir.join("include/b.xml"), 2, 14), "{e}");
    assert!(e.message.contains("cannot read included file \"d.xml\""), "{e}");
    let help = e.help.as_deref().unwrap_or_default();
    let (inner, outer) = (help.find(&format!("\"{}\"", dir.join("include").display())), help.find(&format!("\"{}\"", dir.display())));
    assert!(inner.is_some() && outer.is_some() && inner < outer, "{e}");
}

#[test]
fn a_path_in_an_included_file_applies_to_its_includes_not_to_meshes() {
    // Mitsuba 3.9.1 opens meshes and textures with the top-level file's
    // folders only (checked with it: the mesh below is "not found" there too).
    let dir = temp_dir("include-path");
    for d in ["include", "assets"] {
        std::fs::create_dir_all(dir.join(d)).unwrap();
    }
    std::fs::write(dir.join("assets/tri.obj"), TRIANGLE_OBJ).unwrap();
    std::fs::write(
        dir.join("assets/part.xml"),
        "<scene version=\"3.0.0\">\n    <shape type=\"obj\"><string name=\"filename\" value=\"tri.obj\"/></shape>\n</scene>\n",
    )
    .unwrap();
    // a.xml's <path> (relative to a.xml) finds part.xml ...
    std::fs::write(
        dir.join("include/a.xml"),
        "<scene version=\"3.0.0\">\n    <path value=\"../assets\"/>\n    <include filename=\"part.xml\"/>\n</scene>\n",
    )
    .unwrap();
    let scene = dir.join("s.xml");
    std::fs::write(&scene, format!("<scene version=\"3.0.0\">\n    {SENSOR}\n    <include filename=\"include/a.xml\"/>\n</scene>\n")).unwrap();
    // ... but not part.xml's mesh, which is looked for in the scene's folders.
    let e = load_err(&scene);
    let loc = e.location.as_ref().expect("located");
    assert_eq!(loc.file.path.canonicalize().ok(), dir.join("assets/part.xml").canonicalize().ok(), "{e}");
    assert_eq!(loc.line, 2, "{e}");
    assert!(e.help.as_deref().unwrap_or_default().contains("tri.obj"), "{e}");
    // The same <path> in the top-level file applies to every mesh.
    std::fs::write(
        &scene,
        format!("<scene version=\"3.0.0\">\n    <path value=\"assets\"/>\n    {SENSOR}\n    <include filename=\"include/a.xml\"/>\n</scene>\n"),
    )
    .unwrap();
    assert_eq!(triangle_count(&load(&scene).unwrap_or_else(|e| panic!("{e}"))), 1);
}

fn render(path: &Path, seed: u64) -> Image {
    let scene = snell::load_file(path, &LoadOptions { seed: Some(seed), ..LoadOptions::default() }).unwrap_or_else(|e| panic!("{e}"));
    snell::render::<snell::spectrum::Rgb>(&scene, &RenderOptions::default()).expect("render").0
}

#[test]
fn version_0_6_scene_renders_as_its_3_0_form() {
    // The same samples through the upgraded scene and the hand-written 3.0
    // form: identical images (any parameter the upgrade missed would fail
    // to load, or change the image).
    let old = render(&repo("tests/scenes/legacy-0.6.xml"), 5);
    let new = render(&repo("tests/scenes/legacy-3.0.xml"), 5);
    assert_eq!((old.width, old.height), (48, 32));
    let m = mean(&new);
    assert!(m.iter().all(|&c| c > 0.01), "{m:?}");
    for (a, b) in old.pixels.iter().zip(&new.pixels) {
        assert_eq!(a.0, b.0);
    }
}

#[test]
fn legacy_names_are_upgraded_as_mitsuba_does() {
    use snell::scene::xml::legacy_snake_case;
    for (old, new) in [
        ("toWorld", "to_world"),
        ("intIOR", "int_ior"),
        ("sampleCount", "sample_count"),
        ("maxDepth", "max_depth"),
        ("diffuseReflectance", "diffuse_reflectance"),
        ("uvscale", "uvscale"),
        ("fovAxis", "fov_axis"),
        ("to_world", "to_world"),
        ("alphaUV", "alpha_uv"),
        ("aBcD", "a_bc_d"),
        ("specularTransmittance", "specular_transmittance"),
    ] {
        assert_eq!(legacy_snake_case(old), new, "{old}");
    }
    // A 3.0 file is not upgraded: camelCase stays and is an unused parameter.
    let dir = temp_dir("legacy");
    let scene = dir.join("s.xml");
    let body = |version: &str| {
        format!(
            "<scene version=\"{version}\">\n    {SENSOR}\n    <shape type=\"sphere\"><transform name=\"toWorld\"><translate x=\"1\"/></transform></shape>\n</scene>\n"
        )
    };
    std::fs::write(&scene, body("3.0.0")).unwrap();
    let e = load_err(&scene);
    assert!(e.message.contains("toWorld"), "{e}");
    for version in ["0.5.0", "0.6.0", "1.0.0"] {
        std::fs::write(&scene, body(version)).unwrap();
        load(&scene).unwrap_or_else(|e| panic!("{version}: {e}"));
    }
}

#[track_caller]
fn assert_unsupported(body: &str, line: u32, col: u32, words: &[&str]) {
    let path = std::env::temp_dir().join("snell-documents-unsupported.xml");
    let text = format!("<scene version=\"3.0.0\">\n    {SENSOR}\n{body}</scene>\n");
    let e = match snell::load_str(&path, &text, &LoadOptions::default()) {
        Ok(_) => panic!("expected an error for\n{body}"),
        Err(e) => e,
    };
    let shown = e.to_string();
    let loc = e.location.as_ref().unwrap_or_else(|| panic!("not located: {shown}"));
    assert_eq!((loc.line, loc.col), (line, col), "{shown}");
    assert!(e.message.contains("is not supported yet") || e.message.contains("are not supported yet"), "{shown}");
    for w in words {
        assert!(e.message.contains(w), "expected {w:?} in {shown}");
    }
    assert!(!e.message.contains("unknown"), "{shown}");
}

#[test]
fn unsupported_features_are_named() {
    // SENSOR is 5 lines: the body starts on line 7.
    // Participating media, once named here, are supported now
    // (`tests/media.rs`): the same elements load.
    for body in [
        "    <medium type=\"homogeneous\" id=\"fog\"/>\n",
        "    <shape type=\"sphere\">\n        <bsdf type=\"null\"/>\n        <medium type=\"heterogeneous\" name=\"interior\"/>\n    </shape>\n",
        "    <integrator type=\"volpath\"/>\n",
        "    <integrator type=\"volpathmis\"/>\n",
        "    <integrator type=\"prbvolpath\"/>\n",
    ] {
        let text = format!("<scene version=\"3.0.0\">\n    {SENSOR}\n{body}</scene>\n");
        if let Err(e) = snell::load_str(&repo("tests/scenes/unsupported.xml"), &text, &LoadOptions::default()) {
            panic!("{body}: {e}");
        }
    }
    // A <phase> belongs inside a <medium>, not a shape.
    let text = format!("<scene version=\"3.0.0\">\n    {SENSOR}\n    <shape type=\"sphere\">\n        <phase type=\"hg\"/>\n    </shape>\n</scene>\n");
    let e = snell::load_str(&repo("tests/scenes/unsupported.xml"), &text, &LoadOptions::default()).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("<phase>") && e.contains(":8:9"), "{e}");
    // Curves and SDF grids are read now: without their file, the error is the missing parameter's.
    for shape in ["bsplinecurve", "linearcurve", "sdfgrid"] {
        let text = format!("<scene version=\"3.0.0\">\n    {SENSOR}\n    <shape type=\"{shape}\"/>\n</scene>\n");
        let e = snell::load_str(&repo("tests/scenes/unsupported.xml"), &text, &LoadOptions::default()).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("filename") && !e.contains("not supported"), "{e}");
    }
    assert_unsupported("    <alias id=\"a\" as=\"b\"/>\n", 7, 5, &["<alias>", "aliases"]);
}

/// Mitsuba's differentiable integrators render their primal image as the
/// path tracers do, with the default depth of Mitsuba's ADIntegrator base
/// (6) where `path` and `volpath` have none.
#[test]
fn differentiable_integrators_read_as_path_tracers_with_depth_six() {
    use snell::integrator::Integrator;
    let cornell = std::fs::read_to_string(repo("scenes/cornell-box.xml")).expect("cornell-box.xml");
    let block = "<integrator type=\"path\">\n        <integer name=\"max_depth\" value=\"$max_depth\"/>\n    </integrator>";
    assert!(cornell.contains(block), "the Cornell box's integrator block changed");
    let load = |integrator: &str| {
        let text = cornell.replace(block, integrator);
        snell::load_str(&repo("scenes/cornell-box.xml"), &text, &LoadOptions::default()).unwrap_or_else(|e| panic!("{integrator}: {e}"))
    };
    for plugin in ["prb", "prb_basic"] {
        let scene = load(&format!("<integrator type=\"{plugin}\"/>"));
        let Integrator::Path(p) = &scene.integrator else { panic!("{plugin} is not read as path") };
        assert_eq!((p.max_depth, p.rr_depth, p.hide_emitters), (6, 5, false), "{plugin}");
        let scene = load(&format!(
            "<integrator type=\"{plugin}\"><integer name=\"max_depth\" value=\"-1\"/><integer name=\"rr_depth\" value=\"3\"/><boolean name=\"hide_emitters\" value=\"true\"/></integrator>"
        ));
        let Integrator::Path(p) = &scene.integrator else { panic!("{plugin} is not read as path") };
        assert_eq!((p.max_depth, p.rr_depth, p.hide_emitters), (u32::MAX, 3, true), "{plugin}");
    }
    let Integrator::VolPath(v) = &load("<integrator type=\"prbvolpath\"/>").integrator else { panic!("prbvolpath is not read as volpath") };
    assert_eq!(v.max_depth, 6);
    let Integrator::VolPath(v) = &load("<integrator type=\"volpath\"/>").integrator else { panic!("volpath") };
    assert_eq!(v.max_depth, u32::MAX);
    // And a misspelt parameter is still an error.
    let text = cornell.replace(block, "<integrator type=\"prb\"><integer name=\"max_dept\" value=\"3\"/></integrator>");
    assert!(snell::load_str(&repo("scenes/cornell-box.xml"), &text, &LoadOptions::default()).is_err());
}

#[test]
fn objects_declared_at_the_top_level_for_reference() {
    // Mitsuba's documentation scenes declare an area emitter and a sampler
    // at the top level with an id and <ref> them from a shape and a sensor.
    let text = r#"<scene version="3.0.0">
    <sampler type="independent" id="my_sampler"><integer name="sample_count" value="7"/></sampler>
    <emitter type="area" id="light"><rgb name="radiance" value="2"/></emitter>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <ref id="my_sampler"/>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
    </sensor>
    <shape type="sphere"><ref id="light"/></shape>
    <shape type="sphere"><float name="radius" value="0.5"/><ref id="light"/></shape>
</scene>
"#;
    let path = std::env::temp_dir().join("snell-documents-declared.xml");
    let scene = snell::load_str(&path, text, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.sampler.sample_count, 7);
    assert_eq!(scene.emitters.len(), 2);
    assert!(scene.shapes.iter().all(|s| s.emitter.is_some()));
    // A sensor takes only films and samplers by reference.
    let bad = text.replace(r#"<ref id="my_sampler"/>"#, r#"<ref id="light"/>"#);
    let e = match snell::load_str(&path, &bad, &LoadOptions::default()) {
        Ok(_) => panic!("a sensor must not take an emitter"),
        Err(e) => e,
    };
    assert_eq!(e.location.as_ref().map(|l| (l.line, l.col)), Some((6, 9)), "{e}");
    assert!(e.message.contains("a sensor cannot take a reference to a <emitter>"), "{e}");
}

#[test]
fn plugins_mitsuba_3_removed_say_what_to_use() {
    let path = std::env::temp_dir().join("snell-documents-removed.xml");
    for (body, line, instead) in [
        ("    <integrator type=\"mlt\"/>\n", 7, "use path"),
        ("    <shape type=\"sphere\"><bsdf type=\"phong\"/></shape>\n", 7, "Mitsuba 3 has no such BSDF"),
    ] {
        let text = format!("<scene version=\"0.6.0\">\n    {SENSOR}\n{body}</scene>\n");
        let e = match snell::load_str(&path, &text, &LoadOptions::default()) {
            Ok(_) => panic!("{body} should fail"),
            Err(e) => e,
        };
        assert_eq!(e.location.as_ref().map(|l| l.line), Some(line), "{e}");
        assert!(e.message.contains("Mitsuba 3 removed"), "{e}");
        assert!(e.help.as_deref().unwrap_or_default().contains(instead), "{e}");
    }
    let text = format!("<scene version=\"0.6.0\">\n    {SENSOR}\n</scene>\n").replace("hdrfilm", "ldrfilm");
    let e = snell::load_str(&path, &text, &LoadOptions::default()).err().expect("ldrfilm fails");
    assert!(e.help.as_deref().unwrap_or_default().contains("use hdrfilm"), "{e}");
}

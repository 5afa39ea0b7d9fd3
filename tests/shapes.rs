//! Shapes from real Mitsuba scenes: `serialized` meshes (against the same
//! mesh as PLY; corrupt files), `shapegroup` + `instance` (against the
//! flattened copy; memory of many instances; error cases), `merge` (the
//! image of its shapes on their own) and `cylinder` (an area light against
//! a closed form).
//!
//! `tests/scenes/assets/rectangle_normals_uv.serialized` is Mitsuba's test
//! file `tests/serialized/rectangle_normals_uv.serialized` from the
//! mitsuba-data repository.

use crate::common;

use crate::common::{mean, render_passes};
use glam::{Vec2, Vec3};
use snell::geometry::mesh_io::RawMesh;
use snell::geometry::serialized;
use snell::{LoadOptions, SceneError};
use std::path::{Path, PathBuf};

pub(crate) fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snell-shapes-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A bumpy grid of (n+1)² vertices and 2n² triangles over [-1, 1]².
pub(crate) fn bumpy_grid(n: u32) -> RawMesh {
    let mut positions = vec![];
    let mut uvs = vec![];
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            let (x, y) = (2.0 * u - 1.0, 2.0 * v - 1.0);
            positions.push(Vec3::new(x, y, 0.2 * (3.0 * x).sin() * (2.0 * y).cos()));
            uvs.push(Vec2::new(u, v));
        }
    }
    let mut triangles = vec![];
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            triangles.push([a, a + 1, a + n + 2]);
            triangles.push([a, a + n + 2, a + n + 1]);
        }
    }
    RawMesh { positions, normals: None, uvs: Some(uvs), triangles, attributes: vec![] }
}

pub(crate) fn write_ply(path: &Path, m: &RawMesh) {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    );
    let uvs = m.uvs.as_ref().unwrap();
    for (p, uv) in m.positions.iter().zip(uvs) {
        s += &format!("{} {} {} {} {}\n", p.x, p.y, p.z, uv.x, uv.y);
    }
    for t in &m.triangles {
        s += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    std::fs::write(path, s).unwrap();
}

/// A small scene around `shapes`: a point light and a camera looking down -z.
fn scene(shapes: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="3"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="0.5, -3, 4" target="0, 0, 0" up="0, 0, 1"/></transform>
        <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="48"/><rfilter type="box"/></film>
    </sensor>
    <emitter type="point"><point name="position" x="2" y="-2" z="5"/><rgb name="intensity" value="30"/></emitter>
    <emitter type="constant"><rgb name="radiance" value="0.2"/></emitter>
{shapes}</scene>
"#
    )
}

fn load(path: &Path, text: &str) -> Result<snell::Scene, SceneError> {
    snell::load_str(path, text, &LoadOptions::default())
}

#[track_caller]
fn load_err(path: &Path, text: &str) -> SceneError {
    match load(path, text) {
        Ok(_) => panic!("expected loading to fail:\n{text}"),
        Err(e) => e,
    }
}

/// The error is located at `line` (1-based) of the scene text and its
/// message contains every one of `words`.
#[track_caller]
fn assert_located(e: &SceneError, text: &str, line: u32, words: &[&str]) {
    let loc = e.location.as_ref().unwrap_or_else(|| panic!("no location:\n{e}"));
    assert_eq!(loc.line, line, "wrong line (expected {:?}):\n{e}", text.lines().nth(line as usize - 1));
    for w in words {
        assert!(e.message.contains(w), "expected {w:?} in the message:\n{e}");
    }
}

/// Line number (1-based) of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> u32 {
    text.lines().position(|l| l.contains(needle)).unwrap_or_else(|| panic!("{needle} not in scene")) as u32 + 1
}

fn max_abs_diff(a: &snell::film::Image, b: &snell::film::Image) -> f32 {
    a.pixels.iter().zip(&b.pixels).map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs()).fold(0.0, f32::max)).fold(0.0, f32::max)
}

// ------------------------------------------------------------- serialized

#[test]
fn serialized_renders_the_same_as_ply() {
    let dir = temp_dir("ser-vs-ply");
    let mesh = bumpy_grid(12);
    write_ply(&dir.join("grid.ply"), &mesh);
    // Two meshes in the file; the grid is the second one.
    let other = bumpy_grid(2);
    std::fs::write(dir.join("grid.serialized"), serialized::write(&[(&other, None), (&mesh, None)])).unwrap();
    let transform = r#"<transform name="to_world"><rotate z="1" angle="20"/><translate x="0.1"/></transform>"#;
    let ply = scene(&format!("    <shape type=\"ply\"><string name=\"filename\" value=\"grid.ply\"/>{transform}</shape>\n"));
    let ser = scene(&format!(
        "    <shape type=\"serialized\"><string name=\"filename\" value=\"grid.serialized\"/><integer name=\"shape_index\" value=\"1\"/>{transform}</shape>\n"
    ));
    let path = dir.join("scene.xml");
    let a = render_passes(&path, Some(&ply), Default::default(), 1, 4);
    let b = render_passes(&path, Some(&ser), Default::default(), 1, 4);
    let m = mean(&a[0]);
    assert!(m[0] > 0.01, "the mesh should be visible: {m:?}");
    // The same triangles, normals and uvs: the same image, sample for sample.
    assert!(max_abs_diff(&a[0], &b[0]) < 1e-5, "serialized and PLY differ by {}", max_abs_diff(&a[0], &b[0]));
    // shape_index 0 is the other (coarser) mesh: a different image.
    let c = render_passes(&path, Some(&ser.replace("value=\"1\"/>", "value=\"0\"/>")), Default::default(), 1, 4);
    assert!(max_abs_diff(&a[0], &c[0]) > 1e-3);
}

#[test]
fn mitsubas_serialized_test_file_loads() {
    let path = common::repo("tests/scenes/scene.xml");
    let text = scene(
        "    <shape type=\"serialized\"><string name=\"filename\" value=\"assets/rectangle_normals_uv.serialized\"/>\
         <transform name=\"to_world\"><rotate x=\"1\" angle=\"90\"/><scale value=\"0.2\"/></transform></shape>\n",
    );
    let s = load(&path, &text).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.shapes.len(), 1);
    // 5.7 × 8.2 scaled by 0.2.
    assert!((s.shapes[0].area() - 5.7 * 8.2 * 0.04).abs() < 1e-3, "{}", s.shapes[0].area());
}

#[test]
fn corrupt_serialized_files_are_located_errors() {
    let dir = temp_dir("ser-errors");
    let mesh = bumpy_grid(3);
    let good = serialized::write(&[(&mesh, None), (&mesh, None)]);
    std::fs::write(dir.join("good.serialized"), &good).unwrap();
    std::fs::write(dir.join("truncated.serialized"), &good[..good.len() / 3]).unwrap();
    std::fs::write(dir.join("badmagic.serialized"), b"PK\x03\x04 not a mesh at all").unwrap();
    let mut corrupt = good.clone();
    for b in &mut corrupt[8..40] {
        *b ^= 0xA5;
    }
    std::fs::write(dir.join("corrupt.serialized"), &corrupt).unwrap();
    let path = dir.join("scene.xml");
    for (file, index, words) in [
        ("truncated.serialized", 0, &["truncated.serialized", "truncated"][..]),
        ("truncated.serialized", 1, &["truncated.serialized"][..]),
        ("badmagic.serialized", 0, &["not a Mitsuba serialized mesh"][..]),
        ("corrupt.serialized", 0, &["corrupt"][..]),
        ("good.serialized", 2, &["shape_index 2 is out of range", "2 meshes", "0 to 1"][..]),
        ("missing.serialized", 0, &["cannot read serialized mesh", "missing.serialized"][..]),
    ] {
        let text = scene(&format!(
            "    <shape type=\"serialized\">\n        <string name=\"filename\" value=\"{file}\"/>\n        <integer name=\"shape_index\" value=\"{index}\"/>\n    </shape>\n"
        ));
        let e = load_err(&path, &text);
        assert_located(&e, &text, line_of(&text, "name=\"filename\""), words);
        assert_eq!(e.location.as_ref().unwrap().col, 9, "{e}");
    }
    let text = scene("    <shape type=\"serialized\">\n        <string name=\"filename\" value=\"good.serialized\"/>\n        <integer name=\"shape_index\" value=\"-1\"/>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "shape_index"), &["shape_index"]);
}

// ------------------------------------------------------------- instancing

/// Group members and instance transforms used by the instancing tests.
const MEMBERS: &str = r#"<shape type="ply"><string name="filename" value="grid.ply"/><transform name="to_world"><scale value="0.5"/><rotate x="1" angle="30"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.5, 0.3"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0.2" y="0" z="0.5"/><float name="radius" value="0.3"/><bsdf type="conductor"/></shape>
        <shape type="cylinder"><float name="radius" value="0.15"/><point name="p1" x="0" y="0.3" z="0.8"/></shape>"#;
const PLACEMENTS: [&str; 3] = [
    r#"<rotate z="1" angle="25"/><translate x="-0.9" y="0.2"/>"#,
    r#"<scale value="0.7"/><rotate y="1" angle="-15"/><translate x="0.8" y="-0.3" z="0.1"/>"#,
    r#"<rotate x="1" angle="10"/><scale value="1.3"/><translate x="0.1" y="1.2" z="-0.4"/>"#,
];

fn instanced_scene(placements: &[&str]) -> String {
    let mut s = format!("    <shape type=\"shapegroup\" id=\"group\">\n        {MEMBERS}\n    </shape>\n");
    for p in placements {
        s += &format!("    <shape type=\"instance\"><ref id=\"group\"/><transform name=\"to_world\">{p}</transform></shape>\n");
    }
    s += "    <shape type=\"rectangle\"><transform name=\"to_world\"><scale value=\"4\"/><translate z=\"-1\"/></transform></shape>\n";
    scene(&s)
}

/// The same scene with every instance written out: each member's
/// transform followed by the instance's.
fn flattened_scene() -> String {
    let mut s = String::new();
    for p in PLACEMENTS {
        for member in MEMBERS.split("<shape ").filter(|m| !m.trim().is_empty()) {
            let member = format!("<shape {member}");
            let member = if member.contains("name=\"to_world\">") {
                member.replace("</transform>", &format!("{p}</transform>"))
            } else {
                member.replace("</shape>", &format!("<transform name=\"to_world\">{p}</transform></shape>"))
            };
            s += &format!("    {}\n", member.trim());
        }
    }
    s += "    <shape type=\"rectangle\"><transform name=\"to_world\"><scale value=\"4\"/><translate z=\"-1\"/></transform></shape>\n";
    scene(&s)
}

#[test]
fn instances_render_like_their_flattened_copy() {
    let dir = temp_dir("instancing");
    write_ply(&dir.join("grid.ply"), &bumpy_grid(10));
    let path = dir.join("scene.xml");
    let inst = load(&path, &instanced_scene(&PLACEMENTS)).unwrap_or_else(|e| panic!("{e}"));
    // One copy of the group's three shapes plus the floor.
    assert_eq!(inst.shapes.len(), 4);
    let a = render_passes(&path, Some(&instanced_scene(&PLACEMENTS)), Default::default(), 1, 16);
    let b = render_passes(&path, Some(&flattened_scene()), Default::default(), 1, 16);
    let (ma, mb) = (mean(&a[0]), mean(&b[0]));
    for c in 0..3 {
        assert!((ma[c] / mb[c] - 1.0).abs() < 0.01, "means differ: instanced {ma:?}, flattened {mb:?}");
    }
    // Same seed: every pixel agrees up to float rounding, except the few
    // where a path's rounding sends it another way.
    let close = a[0]
        .pixels
        .iter()
        .zip(&b[0].pixels)
        .filter(|(p, q)| (0..3).all(|c| (p[c] - q[c]).abs() <= 1e-3 * (1.0 + q[c].abs())))
        .count();
    let n = a[0].pixels.len();
    assert!(close as f64 >= 0.97 * n as f64, "only {close} of {n} pixels agree");
    // Removing an instance changes the image (the instances are seen).
    let c = render_passes(&path, Some(&instanced_scene(&PLACEMENTS[1..])), Default::default(), 1, 16);
    assert!(max_abs_diff(&a[0], &c[0]) > 0.05);
}

/// A `merge` renders as its shapes do on their own, whatever they are
/// (meshes, an emitting sphere, a nested merge), bit for bit with the same
/// seed; it takes shapes only and no `to_world`, with located errors.
#[test]
fn merge_renders_like_its_shapes() {
    let dir = temp_dir("merge");
    write_ply(&dir.join("grid.ply"), &bumpy_grid(10));
    let path = dir.join("scene.xml");
    let shapes = "<shape type=\"ply\"><string name=\"filename\" value=\"grid.ply\"/><bsdf type=\"diffuse\"/></shape>
        <shape type=\"rectangle\"><transform name=\"to_world\"><scale value=\"4\"/><translate z=\"-1\"/></transform></shape>
        <shape type=\"sphere\"><point name=\"center\" x=\"0.7\" y=\"0.5\" z=\"0.6\"/><float name=\"radius\" value=\"0.2\"/><emitter type=\"area\"><rgb name=\"radiance\" value=\"4\"/></emitter></shape>";
    let plain = scene(&format!("    {shapes}\n"));
    let (first, rest) = shapes.split_once('\n').expect("two lines");
    let merged = scene(&format!("    <shape type=\"merge\" id=\"all\">{first}<shape type=\"merge\">{rest}</shape></shape>\n"));
    let a = render_passes(&path, Some(&plain), Default::default(), 1, 8);
    let b = render_passes(&path, Some(&merged), Default::default(), 1, 8);
    assert_eq!(max_abs_diff(&a[0], &b[0]), 0.0, "a merge changed the image");
    assert!(mean(&a[0])[0] > 0.01, "the scene is lit");

    let text = scene("    <shape type=\"merge\">\n        <transform name=\"to_world\"><scale value=\"2\"/></transform>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "<scale value=\"2\"/>"), &["to_world"]);
    let text = scene("    <bsdf type=\"diffuse\" id=\"white\"/>\n    <shape type=\"merge\">\n        <ref id=\"white\"/>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "id=\"white\"/>"), &["a merge holds shapes", "bsdf"]);
}

/// 10 000 instances of a 100 000-triangle mesh take the memory of one copy
/// plus a small record per instance.
#[test]
fn many_instances_share_one_copy() {
    let dir = temp_dir("many-instances");
    let mesh = bumpy_grid(224); // 100 352 triangles
    assert!(mesh.triangles.len() >= 100_000);
    std::fs::write(dir.join("big.serialized"), serialized::write(&[(&mesh, None)])).unwrap();
    let group = "    <shape type=\"shapegroup\" id=\"g\"><shape type=\"serialized\"><string name=\"filename\" value=\"big.serialized\"/></shape></shape>\n";
    let instances = |n: usize| -> String {
        (0..n)
            .map(|i| {
                let (x, y) = ((i % 100) as f32 * 2.5, (i / 100) as f32 * 2.5);
                format!("    <shape type=\"instance\"><ref id=\"g\"/><transform name=\"to_world\"><rotate z=\"1\" angle=\"{}\"/><translate x=\"{x}\" y=\"{y}\"/></transform></shape>\n", i % 360)
            })
            .collect()
    };
    let path = dir.join("scene.xml");
    let one = load(&path, &scene(&format!("{group}{}", instances(1)))).unwrap_or_else(|e| panic!("{e}"));
    let many = load(&path, &scene(&format!("{group}{}", instances(10_000)))).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(many.shapes.len(), 1, "the mesh is stored once");
    let (m1, m2) = (one.accel.memory_bytes(), many.accel.memory_bytes());
    let per_instance = (m2 - m1) as f64 / 9_999.0;
    eprintln!("accel: 1 instance {m1} B, 10 000 instances {m2} B ({per_instance:.0} B per instance)");
    // One copy: the mesh's vertices and indices (about 18 B per triangle)
    // that the BVH reads, and the BVH's nodes and triangle references.
    assert!(m1 > 100_000 * 30, "one copy holds the triangles ({m1} B)");
    assert!(per_instance < 600.0, "{per_instance} bytes per instance");
    // Rays find the instances: one straight down onto instance (10, 10).
    let ray = snell::geometry::Ray::new(Vec3::new(25.0 + 0.1, 25.0 + 0.05, 5.0), -Vec3::Z);
    let si = many.intersect(&ray).expect("hits the instance");
    assert!((si.p.x - 25.1).abs() < 1e-3 && si.p.z.abs() <= 0.21, "{:?}", si.p);
}

#[test]
fn instancing_errors_are_located() {
    let dir = temp_dir("instancing-errors");
    let path = dir.join("scene.xml");
    let cases = [
        (
            "    <shape type=\"shapegroup\" id=\"g\">\n        <shape type=\"sphere\">\n            <emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter>\n        </shape>\n    </shape>\n",
            "<emitter type=\"area\"",
            &["cannot emit", "instancing of emitters"][..],
        ),
        (
            "    <shape type=\"sphere\" id=\"s\"/>\n    <shape type=\"instance\">\n        <ref id=\"s\"/>\n    </shape>\n",
            "<ref id=\"s\"/>",
            &["must refer to a shapegroup", "\"sphere\""][..],
        ),
        (
            "    <bsdf type=\"diffuse\" id=\"b\"/>\n    <shape type=\"instance\">\n        <ref id=\"b\"/>\n    </shape>\n",
            "<ref id=\"b\"/>",
            &["must refer to a shapegroup", "<bsdf>"][..],
        ),
        (
            "    <shape type=\"shapegroup\" id=\"g\">\n        <shape type=\"sphere\"/>\n        <shape type=\"instance\">\n            <ref id=\"g\"/>\n        </shape>\n    </shape>\n",
            "<shape type=\"instance\">",
            &["cannot contain an instance"][..],
        ),
        (
            "    <shape type=\"shapegroup\" id=\"g\">\n        <shape type=\"shapegroup\" id=\"h\">\n            <shape type=\"sphere\"/>\n        </shape>\n    </shape>\n",
            "<shape type=\"shapegroup\" id=\"h\">",
            &["cannot contain another shapegroup"][..],
        ),
        ("    <shape type=\"instance\"/>\n", "<shape type=\"instance\"/>", &["exactly one shapegroup", "found 0"][..]),
        (
            "    <shape type=\"instance\">\n        <ref id=\"nothere\"/>\n    </shape>\n",
            "<ref id=\"nothere\"/>",
            &["unknown id \"nothere\""][..],
        ),
    ];
    for (body, at, words) in cases {
        let text = scene(body);
        let e = load_err(&path, &text);
        assert_located(&e, &text, line_of(&text, at), words);
    }
}

// ------------------------------------------------------------- cylinder

/// A diffuse patch (albedo ρ) at the centre of an open tube of radius R and
/// length 2H whose inside emits radiance L (flip_normals), facing along the
/// axis: it sees the tube's upper half between polar angles θ₀ = atan(R/H)
/// and π/2, so its irradiance is E = Lπ cos²θ₀ and its radiance ρ E / π =
/// ρ L H² / (H² + R²). Checked with emitter and BSDF sampling (MIS) and
/// with BSDF sampling alone.
#[test]
fn cylinder_area_light_against_closed_form() {
    let (r, h, l, rho) = (1.0f64, 1.5f64, 2.0f64, 0.8f64);
    let expected = rho * l * h * h / (h * h + r * r);
    for (integrator, spp) in [("<integrator type=\"direct\"/>", 64), ("<integrator type=\"direct\"><integer name=\"emitter_samples\" value=\"0\"/></integrator>", 256)] {
        let text = format!(
            r#"<scene version="3.0.0">
    {integrator}
    <sensor type="perspective">
        <float name="fov" value="2"/>
        <transform name="to_world"><lookat origin="0, 0, 6" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/><rfilter type="box"/></film>
    </sensor>
    <shape type="cylinder">
        <point name="p0" x="0" y="0" z="-{h}"/><point name="p1" x="0" y="0" z="{h}"/>
        <float name="radius" value="{r}"/>
        <boolean name="flip_normals" value="true"/>
        <emitter type="area"><rgb name="radiance" value="{l}"/></emitter>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="0.2"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="{rho}"/></bsdf>
    </shape>
</scene>
"#
        );
        let path = std::env::temp_dir().join("snell-cylinder.xml");
        let images = render_passes(&path, Some(&text), Default::default(), 4, spp);
        let avg = common::average(&images);
        let m = mean(&avg);
        // Per-pass means give the noise of the estimate.
        let per: Vec<f64> = images.iter().map(|i| mean(i)[0]).collect();
        let mu = per.iter().sum::<f64>() / per.len() as f64;
        let sd = (per.iter().map(|v| (v - mu).powi(2)).sum::<f64>() / (per.len() - 1) as f64).sqrt() / (per.len() as f64).sqrt();
        for c in 0..3 {
            assert!(
                (m[c] - expected).abs() < 0.01 * expected + 4.0 * sd,
                "{integrator}: patch radiance {m:?}, closed form {expected} (σ {sd})"
            );
        }
    }
}

#[test]
fn cylinder_shape_errors() {
    let path = std::env::temp_dir().join("snell-cylinder-errors.xml");
    let text = scene("    <shape type=\"cylinder\">\n        <transform name=\"to_world\"><scale x=\"1\" y=\"2\" z=\"1\"/></transform>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "y=\"2\""), &["similarity"]);
    let text = scene("    <shape type=\"cylinder\">\n        <float name=\"radius\" value=\"-1\"/>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "radius"), &["radius"]);
}

// ------------------------------------------------------------- mesh_attribute

/// A furnace: an orthographic camera looking straight at the square
/// [-1, 1]² (the PLY `ply`) under a white constant environment, lit by BSDF
/// sampling alone. Every sample leaves the square into the environment
/// with weight equal to the albedo at the hit, so a pixel is the albedo
/// averaged over its footprint, without noise.
fn attribute_furnace(dir: &Path, ply: &str, texture_name: &str, scale: f32) -> String {
    std::fs::write(dir.join("quad.ply"), ply).unwrap();
    format!(
        r#"<scene version="3.0.0">
    <integrator type="direct"><integer name="emitter_samples" value="0"/></integrator>
    <sensor type="orthographic">
        <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/><rfilter type="box"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="ply">
        <string name="filename" value="quad.ply"/>
        <bsdf type="diffuse">
            <texture type="mesh_attribute" name="reflectance">
                <string name="name" value="{texture_name}"/>
                <float name="scale" value="{scale}"/>
            </texture>
        </bsdf>
    </shape>
</scene>
"#
    )
}

#[test]
fn vertex_colours_interpolate_linearly() {
    let dir = temp_dir("vertex-colours");
    // 8-bit colours (divided by 255): (0.2, 0.4, 0.8) at x = -1, (0.8, 0.6, 0.2) at x = 1.
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n-1 -1 0 51 102 204\n1 -1 0 204 153 51\n1 1 0 204 153 51\n-1 1 0 51 102 204\n4 0 1 2 3\n";
    let text = attribute_furnace(&dir, ply, "vertex_color", 1.0);
    let img = &render_passes(&dir.join("scene.xml"), Some(&text), Default::default(), 1, 64)[0];
    let (c0, c1) = ([0.2f32, 0.4, 0.8], [0.8f32, 0.6, 0.2]);
    // Column means: the albedo's mean over the column's footprint, i.e. at
    // its centre (the only noise: where in the pixel samples fall, σ ≈ 3e-4).
    let column = |x: usize, c: usize| (0..16).map(|y| img.pixels[y * 16 + x][c]).sum::<f32>() / 16.0;
    // Whichever way the image's x runs along the world's x.
    let err = |flip: bool| {
        let mut worst = 0.0f32;
        for x in 0..16 {
            let wx = -1.0 + (x as f32 + 0.5) / 8.0;
            let s = (if flip { -wx } else { wx } + 1.0) / 2.0;
            for c in 0..3 {
                worst = worst.max((column(x, c) - (c0[c] + (c1[c] - c0[c]) * s)).abs());
            }
        }
        worst
    };
    let worst = err(false).min(err(true));
    assert!(worst < 2e-3, "columns differ from the interpolated vertex colour by up to {worst}");
}

#[test]
fn face_attributes_are_constant_per_face_and_scaled() {
    let dir = temp_dir("face-weights");
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nproperty float weight\nend_header\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2 0.25\n3 0 2 3 0.75\n";
    let text = attribute_furnace(&dir, ply, "face_weight", 0.8);
    let img = &render_passes(&dir.join("scene.xml"), Some(&text), Default::default(), 1, 16)[0];
    let m = mean(img);
    // The diagonal splits the square in halves: mean 0.8 · (0.25 + 0.75) / 2.
    assert!((m[0] - 0.4).abs() < 2e-3 && (m[1] - m[0]).abs() < 1e-6, "{m:?}");
    let (lo, hi) = (img.pixels.iter().filter(|p| (p[0] - 0.2).abs() < 1e-5).count(), img.pixels.iter().filter(|p| (p[0] - 0.6).abs() < 1e-5).count());
    assert!(lo >= 100 && hi >= 100, "{lo} pixels at 0.8·0.25 and {hi} at 0.8·0.75");
    // An attribute no mesh has: located at its name, the known ones listed.
    let text = attribute_furnace(&dir, ply, "vertex_color", 1.0);
    let e = load_err(&dir.join("scene.xml"), &text);
    assert_located(&e, &text, line_of(&text, "value=\"vertex_color\""), &["no mesh in the scene has the attribute \"vertex_color\""]);
    assert!(e.help.as_deref().is_some_and(|h| h.contains("face_weight")), "{e}");
    let text = attribute_furnace(&dir, ply, "color", 1.0);
    assert_located(&load_err(&dir.join("scene.xml"), &text), &text, line_of(&text, "value=\"color\""), &["\"vertex_\" or \"face_\""]);
}

/// A scalar input read from a mesh attribute: a `blendbsdf` between black
/// and white `diffuse` weighted by a one-component face attribute has albedo
/// equal to the weight (Mitsuba's tests/scenes/mesh_attributes
/// `test_mesh_attributes_1_face_direct.xml` does this; scalar inputs once
/// dropped the hit's mesh and read 0 everywhere).
#[test]
fn face_attribute_as_a_blend_weight() {
    let dir = temp_dir("face-blend");
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nproperty float weight_0\nend_header\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2 0.25\n3 0 2 3 0.75\n";
    let text = attribute_furnace(&dir, ply, "face_weight", 1.0).replace(
        r#"<bsdf type="diffuse">
            <texture type="mesh_attribute" name="reflectance">
                <string name="name" value="face_weight"/>
                <float name="scale" value="1"/>
            </texture>
        </bsdf>"#,
        r#"<bsdf type="blendbsdf">
            <texture type="mesh_attribute" name="weight"><string name="name" value="face_weight"/></texture>
            <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
            <bsdf type="diffuse"><rgb name="reflectance" value="1"/></bsdf>
        </bsdf>"#,
    );
    assert!(text.contains("blendbsdf"), "the furnace's BSDF was not replaced");
    let img = &render_passes(&dir.join("scene.xml"), Some(&text), Default::default(), 1, 16)[0];
    let (lo, hi) = (img.pixels.iter().filter(|p| (p[0] - 0.25).abs() < 1e-5).count(), img.pixels.iter().filter(|p| (p[0] - 0.75).abs() < 1e-5).count());
    assert!(lo >= 100 && hi >= 100, "{lo} pixels at weight 0.25 and {hi} at 0.75 (mean {:?})", mean(img));
}

/// Mitsuba's `rawconstant` texture: its value as given, a vector or a float.
#[test]
fn rawconstant_texture() {
    let dir = temp_dir("rawconstant");
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n4 0 1 2 3\n";
    let furnace = attribute_furnace(&dir, ply, "face_weight", 1.0);
    let old = r#"<texture type="mesh_attribute" name="reflectance">
                <string name="name" value="face_weight"/>
                <float name="scale" value="1"/>
            </texture>"#;
    for (value, expected) in [(r#"<vector name="value" value="0.2, 0.4, 0.6"/>"#, [0.2f32, 0.4, 0.6]), (r#"<float name="value" value="0.3"/>"#, [0.3; 3])] {
        let text = furnace.replace(old, &format!(r#"<texture type="rawconstant" name="reflectance">{value}</texture>"#));
        assert!(text != furnace);
        let img = &render_passes(&dir.join("scene.xml"), Some(&text), Default::default(), 1, 4)[0];
        for p in &img.pixels {
            for c in 0..3 {
                assert!((p[c] - expected[c]).abs() < 1e-6, "{value}: pixel {p:?}, expected {expected:?}");
            }
        }
    }
}

/// Mitsuba 3.9.1's checkerboard gives `eval_1` (every scalar input: blend
/// weights, opacities, roughness) the other square than `eval` (colours);
/// Snell follows it so that such scenes render as in Mitsuba. Here a
/// checkerboard is both a blend weight (black/white diffuse) and, on a
/// second copy of the quad, the reflectance: where one is 1 the other is 0.
#[test]
fn checkerboard_scalar_inputs_take_the_other_square() {
    let dir = temp_dir("checker-eval1");
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n-1 -1 0 0 0\n1 -1 0 1 0\n1 1 0 1 1\n-1 1 0 0 1\n4 0 1 2 3\n";
    let checker = r#"<texture type="checkerboard" name="NAME"><rgb name="color0" value="1"/><rgb name="color1" value="0"/></texture>"#;
    let furnace = attribute_furnace(&dir, ply, "face_weight", 1.0);
    let old = r#"<bsdf type="diffuse">
            <texture type="mesh_attribute" name="reflectance">
                <string name="name" value="face_weight"/>
                <float name="scale" value="1"/>
            </texture>
        </bsdf>"#;
    let colour = furnace.replace(old, &format!("<bsdf type=\"diffuse\">{}</bsdf>", checker.replace("NAME", "reflectance")));
    let blend = furnace.replace(
        old,
        &format!(
            "<bsdf type=\"blendbsdf\">{}<bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0\"/></bsdf><bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"1\"/></bsdf></bsdf>",
            checker.replace("NAME", "weight")
        ),
    );
    assert!(colour != furnace && blend != furnace, "the furnace's BSDF was not replaced");
    let a = &render_passes(&dir.join("colour.xml"), Some(&colour), Default::default(), 1, 16)[0];
    let b = &render_passes(&dir.join("blend.xml"), Some(&blend), Default::default(), 1, 16)[0];
    // Pixels wholly inside one square (the 4×4 squares are 4 pixels wide).
    let (mut both, mut inside) = (0, 0);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        if p[0] == 0.0 || p[0] == 1.0 {
            inside += 1;
            both += usize::from((p[0] + q[0] - 1.0).abs() < 1e-6);
        }
    }
    assert!(inside >= 128 && both == inside, "{both} of {inside} whole-square pixels have blend weight = 1 − colour");
}

/// `<ref name="bsdf" id="…"/>` inside a shape, as Mitsuba's documentation
/// scenes (e.g. `docs/scenes/include/shape_scene.xml`) write it.
#[test]
fn named_bsdf_reference_in_a_shape() {
    let path = std::env::temp_dir().join("snell-named-ref.xml");
    let text = scene("    <bsdf type=\"conductor\" id=\"metal\"/>\n    <shape type=\"cylinder\">\n        <ref name=\"bsdf\" id=\"metal\"/>\n    </shape>\n");
    let s = load(&path, &text).unwrap_or_else(|e| panic!("{e}"));
    assert!(matches!(s.bsdfs[s.shapes[0].bsdf as usize], snell::bsdf::Bsdf::Conductor(_)));
    let text = scene("    <bsdf type=\"conductor\" id=\"metal\"/>\n    <shape type=\"cylinder\">\n        <ref name=\"bsdf\" id=\"metal\"/>\n        <bsdf type=\"diffuse\"/>\n    </shape>\n");
    // Located, as for an unnamed reference, at the second BSDF's definition.
    assert_located(&load_err(&path, &text), &text, line_of(&text, "id=\"metal\"/>"), &["at most one BSDF"]);
}

/// PLY and serialized texture coordinates are used as stored (Mitsuba 3.9
/// reads `u v` = (0.1, 0.2) as uv (0.1, 0.2), checked with its Python
/// bindings); only OBJ flips v (`flip_tex_coords`, default true).
#[test]
fn ply_and_serialized_uvs_are_not_flipped() {
    let dir = temp_dir("uvs");
    let mesh = bumpy_grid(2);
    write_ply(&dir.join("grid.ply"), &mesh);
    std::fs::write(dir.join("grid.serialized"), serialized::write(&[(&mesh, None)])).unwrap();
    std::fs::write(dir.join("grid.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.1 0.2\nvt 0.3 0.4\nvt 0.5 0.6\nf 1/1 2/2 3/3\n").unwrap();
    for (plugin, file) in [("ply", "grid.ply"), ("serialized", "grid.serialized")] {
        let text = scene(&format!("    <shape type=\"{plugin}\"><string name=\"filename\" value=\"{file}\"/></shape>\n"));
        let s = load(&dir.join("scene.xml"), &text).unwrap_or_else(|e| panic!("{e}"));
        let snell::geometry::ShapeGeometry::Mesh(m) = &s.shapes[0].geometry else { panic!("not a mesh") };
        assert_eq!(m.uvs.as_ref(), mesh.uvs.as_ref(), "{plugin}");
    }
    let text = scene("    <shape type=\"obj\"><string name=\"filename\" value=\"grid.obj\"/></shape>\n");
    let s = load(&dir.join("scene.xml"), &text).unwrap_or_else(|e| panic!("{e}"));
    let snell::geometry::ShapeGeometry::Mesh(m) = &s.shapes[0].geometry else { panic!("not a mesh") };
    let uv0 = m.uvs.as_ref().unwrap()[m.positions.iter().position(|p| *p == Vec3::ZERO).unwrap()];
    assert!((uv0 - Vec2::new(0.1, 0.8)).length() < 1e-6, "OBJ v is flipped by default: {uv0}");
}

/// A mesh big enough to compute its vertex normals on a thread of its own
/// while the rest loads (and the BVH builds) gets the same normals, bit for
/// bit, as computing them in place, flipped or not, next to a small mesh
/// that computes them at once.
#[test]
fn overlapped_vertex_normals_are_the_same_bits() {
    let dir = temp_dir("overlapped-normals");
    let big = bumpy_grid(190); // 72 200 triangles: over the overlap threshold
    assert!(big.triangles.len() >= 1 << 16);
    write_ply(&dir.join("big.ply"), &big);
    write_ply(&dir.join("small.ply"), &bumpy_grid(8));
    let transform = r#"<transform name="to_world"><rotate z="1" angle="20"/><scale x="1.5" y="0.8" z="1.1"/><translate x="0.3"/></transform>"#;
    let text = scene(&format!(
        "    <shape type=\"ply\"><string name=\"filename\" value=\"big.ply\"/>{transform}</shape>\n\
         <shape type=\"ply\"><string name=\"filename\" value=\"small.ply\"/></shape>\n\
         <shape type=\"ply\"><string name=\"filename\" value=\"big.ply\"/><boolean name=\"flip_normals\" value=\"true\"/></shape>\n"
    ));
    let scene = load(&dir.join("scene.xml"), &text).unwrap();
    assert_eq!(scene.shapes.len(), 3);
    for (k, flip) in [(0, false), (1, false), (2, true)] {
        let snell::geometry::shape::ShapeGeometry::Mesh(m) = &scene.shapes[k].geometry else { panic!("shape {k} is not a mesh") };
        let mut expected = snell::geometry::mesh::Mesh::compute_vertex_normals(&m.positions, &m.triangles);
        for n in &mut expected {
            *n = n.normalize_or_zero();
            if flip {
                *n = -*n;
            }
        }
        let got = m.normals.as_ref().expect("vertex normals");
        assert_eq!(got.len(), expected.len());
        let same = got.iter().zip(&expected).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits));
        assert!(same, "shape {k}: normals differ");
        assert!(got.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ------------------------------------------------------------- curves

/// Tubes seen from above (orthographic, down −z), lit by a point light and
/// a dim sky; `shapes` as XML.
fn tube_scene(shapes: &str, floor: bool) -> String {
    let floor = if floor { r#"<shape type="rectangle"><transform name="to_world"><scale value="10"/><translate z="-1"/></transform></shape>"# } else { "" };
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="3"/></integrator>
    <sensor type="orthographic">
        <transform name="to_world"><scale value="2.2"/><lookat origin="2, 0, 5" target="2, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="32"/><rfilter type="box"/></film>
        <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
    </sensor>
    <emitter type="point"><point name="position" x="1" y="-2" z="5"/><rgb name="intensity" value="30"/></emitter>
    <emitter type="constant"><rgb name="radiance" value="0.2"/></emitter>
    {floor}
{shapes}</scene>
"#
    )
}

/// Fraction of pixels where two images differ by more than `tol` in some channel.
fn fraction_differing(a: &snell::film::Image, b: &snell::film::Image, tol: f32) -> f64 {
    let n = a.pixels.iter().zip(&b.pixels).filter(|(p, q)| (0..3).any(|c| (p[c] - q[c]).abs() > tol)).count();
    n as f64 / a.pixels.len() as f64
}

/// A linear curve of two control points of equal radius is a capsule: it
/// renders as a cylinder between two spheres (same rays, same samples:
/// the images agree but for pixels on the outline). A B-spline of five
/// evenly spaced collinear points of equal radius is the open tube from
/// c(0) of its first segment to c(1) of its last, x = 1 to 3 here: a
/// `cylinder` (seen from the side, where its open ends are edge-on).
#[test]
fn straight_curves_render_as_capsules_and_tubes() {
    let dir = temp_dir("curves");
    let bsdf = "<bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.7, 0.5, 0.3\"/></bsdf>";
    std::fs::write(dir.join("capsule.txt"), "0.5 0 0 0.4\n3.5 0 0 0.4\n").unwrap();
    std::fs::write(dir.join("straight.txt"), "0 0 0 0.4\n1 0 0 0.4\n2 0 0 0.4\n3 0 0 0.4\n4 0 0 0.4\n").unwrap();
    let path = dir.join("scene.xml");
    let render_on = |shapes: &str, floor: bool| render_passes(&path, Some(&tube_scene(shapes, floor)), Default::default(), 1, 16).remove(0);
    let render = |shapes: &str| render_on(shapes, true);
    let curve = render(&format!("<shape type=\"linearcurve\"><string name=\"filename\" value=\"capsule.txt\"/>{bsdf}</shape>"));
    let capsule = render(&format!(
        "<shape type=\"cylinder\"><point name=\"p0\" x=\"0.5\" y=\"0\" z=\"0\"/><point name=\"p1\" x=\"3.5\" y=\"0\" z=\"0\"/><float name=\"radius\" value=\"0.4\"/>{bsdf}</shape>
         <shape type=\"sphere\"><point name=\"center\" x=\"0.5\" y=\"0\" z=\"0\"/><float name=\"radius\" value=\"0.4\"/>{bsdf}</shape>
         <shape type=\"sphere\"><point name=\"center\" x=\"3.5\" y=\"0\" z=\"0\"/><float name=\"radius\" value=\"0.4\"/>{bsdf}</shape>"
    ));
    // No floor under the tube: light reaching the floor through its open
    // ends would pass through the curve's inside (curves, like Mitsuba's,
    // are hit from outside only) but be stopped by the cylinder's inner wall.
    let spline = render_on(&format!("<shape type=\"bsplinecurve\"><string name=\"filename\" value=\"straight.txt\"/>{bsdf}</shape>"), false);
    let tube = render_on(&format!(
        "<shape type=\"cylinder\"><point name=\"p0\" x=\"1\" y=\"0\" z=\"0\"/><point name=\"p1\" x=\"3\" y=\"0\" z=\"0\"/><float name=\"radius\" value=\"0.4\"/>{bsdf}</shape>"
    ), false);
    for (name, a, b) in [("linear curve vs capsule", &curve, &capsule), ("B-spline vs cylinder", &spline, &tube)] {
        let (ma, mb) = (mean(a), mean(b));
        for c in 0..3 {
            assert!((ma[c] / mb[c] - 1.0).abs() < 0.01, "{name}: means {ma:?} vs {mb:?}");
        }
        let f = fraction_differing(a, b, 0.02);
        assert!(f < 0.06, "{name}: {:.1} % of pixels differ", 100.0 * f);
        assert!(a.pixels.iter().all(|p| p.0.iter().all(|v| v.is_finite())));
    }
    // And the tube is really there: it differs from the empty floor.
    let empty = render_on("", false);
    assert!(fraction_differing(&spline, &empty, 0.02) > 0.1);
}

#[test]
fn curve_errors_are_located() {
    let dir = temp_dir("curve-errors");
    std::fs::write(dir.join("bad.txt"), "0 0 0 0.1\n1 0 zero 0.1\n").unwrap();
    std::fs::write(dir.join("short.txt"), "0 0 0 0.1\n1 0 0 0.1\n2 0 0 0.1\n").unwrap();
    std::fs::write(dir.join("ok.txt"), "0 0 0 0.1\n1 0 0 0.1\n").unwrap();
    let path = dir.join("scene.xml");
    let text = scene("    <shape type=\"linearcurve\">\n        <string name=\"filename\" value=\"bad.txt\"/>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "bad.txt"), &["line 2", "x y z radius"]);
    let text = scene("    <shape type=\"bsplinecurve\">\n        <string name=\"filename\" value=\"short.txt\"/>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "short.txt"), &["at least 4"]);
    let text = scene("    <shape type=\"linearcurve\">\n        <string name=\"filename\" value=\"missing.txt\"/>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "missing.txt"), &["missing.txt"]);
    let text = scene("    <shape type=\"linearcurve\">\n        <string name=\"filename\" value=\"ok.txt\"/>\n        <emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter>\n    </shape>\n");
    assert_located(&load_err(&path, &text), &text, line_of(&text, "type=\"area\""), &["cannot emit"]);
    assert!(load(&path, &scene("    <shape type=\"linearcurve\">\n        <string name=\"filename\" value=\"ok.txt\"/>\n    </shape>\n")).is_ok());
}

/// Mitsuba's `.vol` grid of one float channel (x fastest), as `sdfgrid` reads it.
fn write_vol(path: &std::path::Path, res: [usize; 3], value: impl Fn([usize; 3]) -> f32) {
    let mut bytes = b"VOL\x03".to_vec();
    bytes.extend(1i32.to_le_bytes());
    for n in res {
        bytes.extend((n as i32).to_le_bytes());
    }
    bytes.extend(1i32.to_le_bytes());
    for b in [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
        bytes.extend(b.to_le_bytes());
    }
    for k in 0..res[2] {
        for j in 0..res[1] {
            for i in 0..res[0] {
                bytes.extend(value([i, j, k]).to_le_bytes());
            }
        }
    }
    std::fs::write(path, bytes).unwrap();
}

/// The distance field of a sphere, sampled on a 48³ grid and placed by
/// `to_world`, renders as the analytic sphere: trilinear interpolation of
/// an exact distance is off the sphere by about h²/8r (3·10⁻⁴ here), far
/// below a pixel. Both normal modes; the grid is hit from either side.
#[test]
fn sdf_grid_of_a_sphere_renders_as_the_sphere() {
    let dir = temp_dir("sdfgrid");
    let n = 48;
    write_vol(&dir.join("ball.vol"), [n; 3], |ijk| {
        let p = glam::Vec3::from_array(ijk.map(|i| i as f32 / (n - 1) as f32));
        (p - glam::Vec3::splat(0.5)).length() - 0.35
    });
    let bsdf = "<bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.7, 0.5, 0.3\"/></bsdf>";
    let path = dir.join("scene.xml");
    let render = |shapes: &str| render_passes(&path, Some(&tube_scene(shapes, true)), Default::default(), 1, 16).remove(0);
    let sphere = render(&format!("<shape type=\"sphere\"><point name=\"center\" x=\"2\" y=\"0\" z=\"0\"/><float name=\"radius\" value=\"0.7\"/>{bsdf}</shape>"));
    let place = "<transform name=\"to_world\"><translate value=\"-0.5, -0.5, -0.5\"/><scale value=\"2\"/><translate x=\"2\"/></transform>";
    for normals in ["smooth", "analytic"] {
        let grid = render(&format!(
            "<shape type=\"sdfgrid\"><string name=\"filename\" value=\"ball.vol\"/><string name=\"normals\" value=\"{normals}\"/>{place}{bsdf}</shape>"
        ));
        let (ma, mb) = (mean(&grid), mean(&sphere));
        for c in 0..3 {
            assert!((ma[c] / mb[c] - 1.0).abs() < 0.01, "{normals}: means {ma:?} vs {mb:?}");
        }
        let f = fraction_differing(&grid, &sphere, 0.02);
        assert!(f < 0.06, "{normals}: {:.1} % of pixels differ", 100.0 * f);
        assert!(grid.pixels.iter().all(|p| p.0.iter().all(|v| v.is_finite())));
    }
    let empty = render("");
    assert!(fraction_differing(&sphere, &empty, 0.02) > 0.1);
}

#[test]
fn sdf_grid_errors_are_located() {
    let dir = temp_dir("sdfgrid-errors");
    write_vol(&dir.join("ball.vol"), [4; 3], |ijk| ijk.iter().map(|&i| (i as f32 - 1.5).powi(2)).sum::<f32>().sqrt() - 1.0);
    let path = dir.join("scene.xml");
    let load = |shape: &str| {
        let text = format!("<scene version=\"3.0.0\">\n{shape}\n</scene>\n");
        snell::load_str(&path, &text, &Default::default()).err().map(|e| e.to_string()).unwrap_or_default()
    };
    let e = load("<shape type=\"sdfgrid\">\n<string name=\"filename\" value=\"ball.vol\"/>\n<string name=\"normals\" value=\"flat\"/>\n</shape>");
    assert!(e.contains(":4:") && e.contains("flat") && e.contains("smooth") && e.contains("analytic"), "{e}");
    let e = load("<shape type=\"sdfgrid\">\n<string name=\"filename\" value=\"ball.vol\"/>\n<emitter type=\"area\"/>\n</shape>");
    assert!(e.contains(":4:") && e.contains("cannot emit"), "{e}");
    let e = load("<shape type=\"sdfgrid\">\n<string name=\"filename\" value=\"nowhere.vol\"/>\n</shape>");
    assert!(e.contains(":3:") && e.contains("nowhere.vol"), "{e}");
    std::fs::write(dir.join("short.vol"), b"VOL\x03").unwrap();
    let e = load("<shape type=\"sdfgrid\">\n<string name=\"filename\" value=\"short.vol\"/>\n</shape>");
    assert!(e.contains(":3:") && e.contains("short.vol") && e.contains("header"), "{e}");
}

/// A sphere's and a disk's texture coordinates (two arc tangents a sphere
/// hit) are computed only where something reads them: a bitmap or
/// checkerboard texture anywhere in the scene, or a `uv` AOV. Where one
/// does, the hit's uv is Mitsuba's parameterisation; where none does, zero.
#[test]
fn sphere_and_disk_uv_only_where_something_reads_them() {
    let dir = temp_dir("reads-uv");
    let shapes = r#"<shape type="sphere"><float name="radius" value="1"/></shape>
    <shape type="disk"><transform name="to_world"><translate z="-1.5"/></transform></shape>
"#;
    let plain = scene(shapes);
    let textured = plain.replace(
        r#"<float name="radius" value="1"/></shape>"#,
        r#"<float name="radius" value="1"/><bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf></shape>"#,
    );
    let uv_aov = plain.replace(
        r#"<integrator type="path"><integer name="max_depth" value="3"/></integrator>"#,
        r#"<integrator type="aov"><string name="aovs" value="uv:uv"/><integrator type="path"/></integrator>"#,
    );
    assert!(textured != plain && uv_aov != plain, "the scene was not changed");
    // Straight down onto the sphere at (x, y) and onto the disk at (x, y).
    let (x, y) = (0.3f32, 0.2f32);
    let z = (1.0 - x * x - y * y).sqrt();
    let d = Vec3::new(0.0, 0.0, -1.0);
    let mut phi = y.atan2(x);
    if phi < 0.0 {
        phi += std::f32::consts::TAU;
    }
    let sphere_uv = Vec2::new(phi / std::f32::consts::TAU, z.acos() / std::f32::consts::PI);
    let disk_uv = Vec2::new((x * x + y * y).sqrt(), phi / std::f32::consts::TAU);
    for (name, text, reads) in [("plain", &plain, false), ("textured", &textured, true), ("uv-aov", &uv_aov, true)] {
        let s = load(&dir.join(format!("{name}.xml")), text).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(s.shapes.len(), 2, "{name}");
        assert!(s.shapes.iter().all(|sh| sh.reads_uv == reads), "{name}: reads_uv should be {reads}");
        let o = Vec3::new(x, y, 5.0);
        let on_sphere = s.shapes[0].interaction(0, 0, o, d, 5.0 - z, (0.0, 0.0));
        let on_disk = s.shapes[1].interaction(1, 0, o, d, 6.5, (0.0, 0.0));
        assert!((on_sphere.p - Vec3::new(x, y, z)).length() < 1e-5, "{name}: sphere hit at {}", on_sphere.p);
        let (want_sphere, want_disk) = if reads { (sphere_uv, disk_uv) } else { (Vec2::ZERO, Vec2::ZERO) };
        assert!((on_sphere.uv - want_sphere).abs().max_element() < 1e-4, "{name}: sphere uv {} against {want_sphere}", on_sphere.uv);
        assert!((on_disk.uv - want_disk).abs().max_element() < 1e-4, "{name}: disk uv {} against {want_disk}", on_disk.uv);
    }
}

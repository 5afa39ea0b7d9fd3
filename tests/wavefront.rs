//! The wavefront (batched) path tracer (`snell::integrator::wavefront`)
//! against the scalar `path`: the same image bit for bit, on scenes that
//! take each of its branches (stream tracing and packets of shadow rays,
//! pass-through shapes, `hide_emitters`, an environment, delta and rough
//! BSDFs, several lights, Russian roulette from the first bounce,
//! `max_depth` 1 and 2, the spectral mode with a dispersive prism, a mesh
//! too big for the cache), and the same image for any thread count and pass
//! split.

use crate::common::*;
use snell::film::Image;
use snell::spectrum::{Rgb, Sampled, Spectrum};
use snell::{RenderOptions, Scene};

fn load(path: &str, replace: &[(&str, &str)], list: &[(&str, &str)]) -> Scene {
    let path = repo(path);
    let mut text = std::fs::read_to_string(&path).unwrap();
    for (from, to) in replace {
        assert!(text.contains(from), "{from} not in {}", path.display());
        text = text.replace(from, to);
    }
    let options = snell::LoadOptions { params: params(list), ..Default::default() };
    snell::load_str(&path, &text, &options).unwrap_or_else(|e| panic!("{e}"))
}

fn render<S: Spectrum>(scene: &Scene, wavefront: bool, threads: usize, passes: u32) -> Image {
    let options = RenderOptions { threads, passes, wavefront: Some(wavefront), ..RenderOptions::default() };
    snell::render::render_passes::<S>(scene, &options, &mut |_| {}).expect("render").0
}

/// Wavefront and scalar images of `scene` are identical, and not black.
fn assert_same<S: Spectrum>(what: &str, scene: &Scene) {
    let scalar = render::<S>(scene, false, 2, 1);
    let batched = render::<S>(scene, true, 2, 1);
    let lit = scalar.pixels.iter().filter(|p| p.0.iter().any(|&c| c > 0.0)).count();
    assert!(lit > scalar.pixels.len() / 100, "{what}: only {lit} pixels lit");
    let (a, b) = (pixel_bits(&scalar), pixel_bits(&batched));
    let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert!(differ == 0, "{what}: {differ} of {} values differ from the scalar path tracer", a.len());
}

#[test]
fn cornell_box_is_bit_identical_to_path() {
    assert_same::<Rgb>("cornell", &load("scenes/cornell-box.xml", &[], &[("res", "64"), ("spp", "16")]));
}

#[test]
fn caustic_box_is_bit_identical_to_path() {
    assert_same::<Rgb>("caustic", &load("scenes/caustic-cornell-box.xml", &[], &[("res", "64"), ("spp", "16")]));
}

#[test]
fn depth_limits_roulette_and_hidden_emitters_are_bit_identical_to_path() {
    for depth in ["1", "2", "-1"] {
        assert_same::<Rgb>(&format!("max_depth {depth}"), &load("scenes/cornell-box.xml", &[], &[("res", "40"), ("spp", "8"), ("max_depth", depth)]));
    }
    let rr = [(r#"<integer name="max_depth" value="$max_depth"/>"#, r#"<integer name="max_depth" value="$max_depth"/><integer name="rr_depth" value="1"/>"#)];
    assert_same::<Rgb>("rr_depth 1", &load("scenes/cornell-box.xml", &rr, &[("res", "40"), ("spp", "8")]));
    let hide = [(r#"<integer name="max_depth" value="$max_depth"/>"#, r#"<integer name="max_depth" value="$max_depth"/><boolean name="hide_emitters" value="true"/>"#)];
    assert_same::<Rgb>("hide_emitters", &load("scenes/cornell-box.xml", &hide, &[("res", "40"), ("spp", "8")]));
}

#[test]
fn pass_through_environment_and_materials_are_bit_identical_to_path() {
    let small = [("res", "48"), ("spp", "8"), ("height", "36")];
    for (scene, n) in [("tests/scenes/mask-leaf.xml", 2), ("tests/scenes/envmap-spheres.xml", 3), ("tests/scenes/rough-glass.xml", 3), ("tests/scenes/principled.xml", 3), ("tests/scenes/light-mix.xml", 2)] {
        assert_same::<Rgb>(scene, &load(scene, &[], &small[..n]));
    }
}

/// A `constant` environment lighting `diffuse` surfaces (textured among
/// them) takes the environment's kernels; its `twosided` bowl and the
/// directional light take the scalar route. Both modes, every SIMD level.
#[test]
fn constant_environment_kernels_are_bit_identical_to_path() {
    let mut scene = load("tests/scenes/mesh-env.xml", &[], &[("res", "48"), ("height", "36"), ("spp", "8")]);
    assert_same::<Sampled>("mesh-env spectral", &scene);
    for level in snell::geometry::accel::SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
        scene.accel.set_simd_level(level);
        assert_same::<Rgb>(&format!("mesh-env {level:?}"), &scene);
    }
}

#[test]
fn spectral_mode_and_dispersion_are_bit_identical_to_path() {
    assert_same::<Sampled>("cornell spectral", &load("scenes/cornell-box.xml", &[], &[("res", "32"), ("spp", "8")]));
    let path = [(r#"<integrator type="ptracer">"#, r#"<integrator type="path">"#)];
    assert_same::<Sampled>("prism spectral", &load("scenes/prism.xml", &path, &[("res", "48"), ("spp", "8")]));
}

#[test]
fn wavefront_images_are_exact_across_threads_and_passes() {
    let scene = load("scenes/caustic-cornell-box.xml", &[], &[("res", "40"), ("spp", "6")]);
    let want = pixel_bits(&render::<Rgb>(&scene, true, 1, 1));
    for (threads, passes) in [(2, 1), (3, 3), (2, 2)] {
        assert!(pixel_bits(&render::<Rgb>(&scene, true, threads, passes)) == want, "{threads} threads, {passes} passes");
    }
}

#[test]
fn wavefront_matches_path_at_every_simd_level() {
    let mut scene = load("scenes/caustic-cornell-box.xml", &[], &[("res", "32"), ("spp", "4")]);
    for level in snell::geometry::accel::SimdLevel::ALL.into_iter().filter(|l| l.supported()) {
        scene.accel.set_simd_level(level);
        assert_same::<Rgb>(&format!("{level:?}"), &scene);
    }
}

/// A mesh big enough that the BVH prefetches (and with it the hit records'
/// triangle indices and corners, a few hits ahead): the same image as the
/// scalar path tracer, with and without shading normals.
#[test]
fn big_mesh_with_prefetched_hits_is_bit_identical_to_path() {
    let dir = crate::shapes::temp_dir("wavefront-big-mesh");
    crate::shapes::write_ply(&dir.join("grid.ply"), &crate::shapes::bumpy_grid(160));
    for face_normals in ["false", "true"] {
        let text = format!(
            r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="4"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0.3, -2.5, 2" target="0, 0, 0" up="0, 0, 1"/></transform>
        <film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="40"/></film>
        <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
    </sensor>
    <shape type="ply">
        <string name="filename" value="grid.ply"/>
        <boolean name="face_normals" value="{face_normals}"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>
    </shape>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <emitter type="point"><point name="position" x="1" y="-1" z="3"/><rgb name="intensity" value="5"/></emitter>
</scene>"#
        );
        let scene = snell::load_str(&dir.join("scene.xml"), &text, &snell::LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.accel.prefetches(), "51 200 triangles should make a BVH that prefetches");
        assert_same::<Rgb>(&format!("big mesh, face_normals {face_normals}"), &scene);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

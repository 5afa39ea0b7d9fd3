//! Rendered images against closed forms: Lambert's polygon irradiance, the
//! inverse-square law of a point light, and the furnace (energy
//! conservation). The expected images are computed here, from the formulas,
//! at each pixel's footprint (found through the scene's own camera, whose
//! conventions the Mitsuba comparison tests pin down).

use crate::common::*;
use glam::{Vec2, Vec3};
use snell::film::Image;
use snell::spectrum::Rgb;
use std::path::Path;

const PI: f64 = std::f64::consts::PI;

/// Irradiance at `x` (normal `n`) from a uniformly emitting polygon of
/// radiance 1, by Lambert's formula: E = ½ |Σᵢ Θᵢ (n · Γᵢ)|, Θᵢ the angle
/// subtended by edge i, Γᵢ the unit normal of the plane through x and edge i.
fn lambert_polygon(x: Vec3, n: Vec3, polygon: &[Vec3]) -> f64 {
    let mut sum = 0.0f64;
    for i in 0..polygon.len() {
        let a = (polygon[i] - x).as_dvec3().normalize();
        let b = (polygon[(i + 1) % polygon.len()] - x).as_dvec3().normalize();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        let gamma = a.cross(b).normalize();
        sum += theta * n.as_dvec3().dot(gamma);
    }
    0.5 * sum.abs()
}

/// The expected image: `radiance(x)` for the floor point x seen by each
/// pixel, averaged over a 4×4 grid in the pixel (box filter).
fn expected_floor_image(scene_path: &Path, text: &str, radiance: impl Fn(Vec3) -> Rgb) -> Image {
    let scene = snell::load_str(scene_path, text, &Default::default()).unwrap();
    let (w, h) = (scene.film.width, scene.film.height);
    let mut pixels = vec![];
    for y in 0..h {
        for x in 0..w {
            let mut acc = Rgb::BLACK;
            for j in 0..4 {
                for i in 0..4 {
                    let film = Vec2::new((x as f32 + (i as f32 + 0.5) / 4.0) / w as f32, (y as f32 + (j as f32 + 0.5) / 4.0) / h as f32);
                    let ray = scene.camera.generate_ray(film);
                    let t = -ray.o.z / ray.d.z; // the floor is the plane z = 0
                    acc += radiance(ray.o + ray.d * t);
                }
            }
            pixels.push(acc / 16.0);
        }
    }
    Image::new(w, h, pixels)
}

const FLOOR_CAMERA: &str = r#"
    <sensor type="orthographic">
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/><rfilter type="box"/></film>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world"><scale value="1.5"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.5, 0.3"/></bsdf>
    </shape>"#;

const ALBEDO: [f32; 3] = [0.8, 0.5, 0.3];

#[test]
fn lambert_polygon_irradiance_under_a_rectangular_light() {
    // A 0.6 × 1.0 light at height 0.6, facing down; the camera looks straight
    // down through it (hidden emitters let camera rays pass).
    let text = format!(
        r#"<scene version="3.0.0">
        <integrator type="direct"><boolean name="hide_emitters" value="true"/></integrator>
        {FLOOR_CAMERA}
        <shape type="rectangle">
            <transform name="to_world">
                <scale x="0.3" y="0.5" z="1"/> <rotate x="1" angle="180"/> <translate x="0.2" y="-0.1" z="0.6"/>
            </transform>
            <emitter type="area"><rgb name="radiance" value="4, 4, 4"/></emitter>
        </shape>
    </scene>"#
    );
    let corners: Vec<Vec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|&(x, y)| Vec3::new(0.2 + 0.3 * x, -0.1 - 0.5 * y, 0.6))
        .collect();
    let path = Path::new("lambert.xml");
    let expected = expected_floor_image(path, &text, |x| {
        if x.x.abs() > 1.5 || x.y.abs() > 1.5 {
            return Rgb::BLACK;
        }
        let e = 4.0 * lambert_polygon(x, Vec3::Z, &corners);
        Rgb::new(ALBEDO[0], ALBEDO[1], ALBEDO[2]) * (e / PI) as f32
    });
    let passes = render_passes(path, Some(&text), Default::default(), 16, 16);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("lambert polygon", 0.005);
}

#[test]
fn point_light_follows_the_inverse_square_law_with_several_emitter_samples() {
    let text = format!(
        r#"<scene version="3.0.0">
        <integrator type="direct"><integer name="emitter_samples" value="4"/></integrator>
        {FLOOR_CAMERA}
        <emitter type="point">
            <point name="position" x="0.1" y="0.2" z="0.8"/>
            <rgb name="intensity" value="2, 3, 4"/>
        </emitter>
    </scene>"#
    );
    let light = Vec3::new(0.1, 0.2, 0.8);
    let path = Path::new("point.xml");
    let expected = expected_floor_image(path, &text, |x| {
        if x.x.abs() > 1.5 || x.y.abs() > 1.5 {
            return Rgb::BLACK;
        }
        let v = light - x;
        let cos = v.z / v.length();
        let e = cos / v.length_squared();
        Rgb::new(2.0 * ALBEDO[0], 3.0 * ALBEDO[1], 4.0 * ALBEDO[2]) * (e / std::f32::consts::PI)
    });
    let passes = render_passes(path, Some(&text), Default::default(), 16, 16);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("point light", 0.005);
}

/// A furnace: a `constant` environment of radiance 1 around `shapes`,
/// rendered by the path tracer with unlimited depth.
fn furnace(shapes: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
        <integrator type="path"><integer name="max_depth" value="-1"/></integrator>
        <sensor type="perspective">
            <float name="fov" value="45"/>
            <transform name="to_world"><lookat origin="0, 0.5, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
            <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
            <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="48"/><rfilter type="box"/></film>
        </sensor>
        <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
        {shapes}
    </scene>"#
    )
}

#[test]
fn white_furnace_is_one_everywhere() {
    // Albedo 1 everywhere: nothing absorbs, so every pixel sees radiance 1,
    // however many times light bounces between the (non-convex) objects.
    let text = furnace(
        r#"<bsdf type="diffuse" id="white"><rgb name="reflectance" value="1"/></bsdf>
        <shape type="sphere"><float name="radius" value="0.7"/><ref id="white"/></shape>
        <shape type="cube"><transform name="to_world"><scale value="0.4"/><translate x="0.9" y="-0.5"/></transform><ref id="white"/></shape>
        <shape type="rectangle"><transform name="to_world"><scale value="2"/><rotate x="1" angle="-90"/><translate y="-0.9"/></transform>
            <bsdf type="twosided"><ref id="white"/></bsdf></shape>"#,
    );
    let path = Path::new("white-furnace.xml");
    let passes = render_passes(path, Some(&text), Default::default(), 16, 16);
    let ones = Image::new(64, 48, vec![Rgb::WHITE; 64 * 48]);
    compare(&passes, &ones, 8, 0.0).assert_unbiased("white furnace", 0.005);
}

#[test]
fn furnace_convex_object_renders_its_albedo() {
    let rho = Rgb::new(0.2, 0.5, 0.8);
    let text = furnace(r#"<shape type="sphere"><float name="radius" value="1"/><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf></shape>"#);
    let path = Path::new("furnace.xml");
    let scene = snell::load_str(path, &text, &Default::default()).unwrap();
    // Expected: ρ where the pixel sees the sphere, 1 elsewhere (coverage of
    // silhouette pixels from a 16×16 grid of camera rays).
    let (w, h) = (scene.film.width, scene.film.height);
    let mut pixels = vec![];
    for y in 0..h {
        for x in 0..w {
            let mut hits = 0;
            for j in 0..16 {
                for i in 0..16 {
                    let film = Vec2::new((x as f32 + (i as f32 + 0.5) / 16.0) / w as f32, (y as f32 + (j as f32 + 0.5) / 16.0) / h as f32);
                    let ray = scene.camera.generate_ray(film);
                    let b = ray.o.dot(ray.d);
                    if b * b - (ray.o.length_squared() - 1.0) >= 0.0 && b < 0.0 {
                        hits += 1;
                    }
                }
            }
            let f = hits as f32 / 256.0;
            pixels.push(rho * f + Rgb::WHITE * (1.0 - f));
        }
    }
    let expected = Image::new(w, h, pixels);
    let passes = render_passes(path, Some(&text), Default::default(), 16, 16);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("coloured furnace", 0.005);
}

//! Ideal specular materials rendered against closed forms: furnaces of glass
//! and mirrors (nothing absorbs, so everything renders 1), spheres whose
//! every pixel has a closed-form value from the Fresnel equations (gold,
//! glass with a transmittance scale), a thin pane, and Snell's window seen
//! from under water (its radius is the critical angle, its brightness
//! carries the η² radiance factor).
//!
//! The expected images are computed here at each pixel's footprint (a grid
//! of camera rays per pixel through the scene's own camera).

use crate::common::*;
use glam::{Vec2, Vec3};
use snell::bsdf::fresnel::{fresnel_conductor, fresnel_dielectric};
use snell::film::Image;
use snell::geometry::Ray;
use snell::spectrum::Rgb;
use std::path::Path;

/// The expected image: `value(ray)` averaged over an n×n grid of camera rays per pixel.
fn expected_image(path: &Path, text: &str, n: u32, value: impl Fn(&Ray) -> Rgb) -> Image {
    let scene = snell::load_str(path, text, &Default::default()).unwrap_or_else(|e| panic!("{e}"));
    let (w, h) = (scene.film.width, scene.film.height);
    let mut pixels = vec![];
    for y in 0..h {
        for x in 0..w {
            let mut acc = Rgb::BLACK;
            for j in 0..n {
                for i in 0..n {
                    let film = Vec2::new(
                        (x as f32 + (i as f32 + 0.5) / n as f32) / w as f32,
                        (y as f32 + (j as f32 + 0.5) / n as f32) / h as f32,
                    );
                    acc += value(&scene.camera.generate_ray(film));
                }
            }
            pixels.push(acc / (n * n) as f32);
        }
    }
    Image::new(w, h, pixels)
}

/// Cosine of the angle at which `ray` meets the unit sphere at the origin, if it does.
fn unit_sphere_cos(ray: &Ray) -> Option<f32> {
    let d = ray.d.normalize();
    let b = ray.o.dot(d);
    let disc = b * b - (ray.o.length_squared() - 1.0);
    if disc < 0.0 || b > 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    let n = (ray.o + d * t).normalize();
    Some((-d.dot(n)).clamp(0.0, 1.0))
}

/// `shapes` in a `constant` environment of radiance 1, path tracer, unlimited depth.
fn ones(w: u32, h: u32) -> Image {
    Image::new(w, h, vec![Rgb::WHITE; (w * h) as usize])
}

#[test]
fn glass_and_mirror_furnace_is_one_everywhere() {
    // Glass of several indices (also a bubble: a sphere of lower index than
    // outside), a perfect mirror, a thin pane, and a mirror floor facing them:
    // nothing absorbs, so however light is bent or trapped, every pixel is 1.
    let text = furnace(
        r#"<shape type="sphere"><point name="center" x="-1.1" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><string name="int_ior" value="diamond"/><string name="ext_ior" value="vacuum"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="1.1" y="0" z="0"/><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.0"/><string name="ext_ior" value="water"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="-0.55" y="0.9" z="-0.5"/><float name="radius" value="0.4"/>
            <bsdf type="conductor"/></shape>
        <shape type="rectangle"><transform name="to_world"><scale value="0.5"/><rotate y="1" angle="30"/><translate x="0.6" y="0.9" z="0.3"/></transform>
            <bsdf type="thindielectric"/></shape>
        <shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/><translate y="-0.6"/></transform>
            <bsdf type="twosided"><bsdf type="conductor"><string name="material" value="none"/></bsdf></bsdf></shape>"#,
        64,
        48,
    );
    let path = Path::new("glass-furnace.xml");
    let passes = render_passes(path, Some(&text), Default::default(), 16, 16);
    compare(&passes, &ones(64, 48), 8, 0.0).assert_unbiased("glass and mirror furnace", 0.005);
}

#[test]
fn gold_sphere_reflects_the_conductor_fresnel_term() {
    // Each camera ray reflects once off the sphere into the environment:
    // the pixel is F(θ) per channel, with F from the complex-index formula.
    let (eta, k) = ([0.2f32, 0.45, 1.4], [3.6f32, 2.5, 1.9]);
    let text = furnace(
        r#"<shape type="sphere"><float name="radius" value="1"/>
            <bsdf type="conductor"><rgb name="eta" value="0.2, 0.45, 1.4"/><rgb name="k" value="3.6, 2.5, 1.9"/></bsdf></shape>"#,
        48,
        48,
    );
    let path = Path::new("gold.xml");
    let expected = expected_image(path, &text, 8, |ray| match unit_sphere_cos(ray) {
        Some(c) => Rgb::new(fresnel_conductor(c, eta[0], k[0]), fresnel_conductor(c, eta[1], k[1]), fresnel_conductor(c, eta[2], k[2])),
        None => Rgb::WHITE,
    });
    let passes = render_passes(path, Some(&text), Default::default(), 8, 4);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("gold sphere", 0.002);
}

#[test]
fn glass_sphere_with_transmittance_darkens_by_the_closed_form() {
    // A glass sphere whose surface passes only t of the transmitted light.
    // Every internal hit of a sphere meets the surface at the same angle, so
    // with F = F(θ) at the entry the pixel is
    //   F + (1−F) t · (1−F) t · Σ F^k = F + t² (1 − F),
    // the η² factors of entering and leaving cancelling (t = 1 gives 1).
    let t = 0.6f32;
    let text = furnace(
        r#"<shape type="sphere"><float name="radius" value="1"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.7"/><float name="ext_ior" value="1.0"/>
                <float name="specular_transmittance" value="0.6"/></bsdf></shape>"#,
        48,
        48,
    );
    let path = Path::new("tinted-glass.xml");
    let expected = expected_image(path, &text, 8, |ray| match unit_sphere_cos(ray) {
        Some(c) => {
            let f = fresnel_dielectric(c, 1.7).r;
            Rgb::WHITE * (f + t * t * (1.0 - f))
        }
        None => Rgb::WHITE,
    });
    let passes = render_passes(path, Some(&text), Default::default(), 16, 64);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("tinted glass sphere", 0.005);
}

#[test]
fn thin_pane_reflects_and_transmits_its_slab_terms() {
    // A tilted pane filling the view in front of a dim emitting backdrop:
    // pixel = R_slab(θ) · L(mirror direction) + (1 − R_slab(θ)) · t · L(straight on),
    // L being the sky (1) or the backdrop (0.25), with the slab reflectance
    // R_slab = R + T²R/(1 − R²) of the exact Fresnel R.
    let text = r#"<scene version="3.0.0">
        <integrator type="path"><integer name="max_depth" value="-1"/></integrator>
        <sensor type="perspective">
            <float name="fov" value="50"/>
            <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
            <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
            <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="48"/><rfilter type="box"/></film>
        </sensor>
        <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
        <shape type="rectangle">
            <transform name="to_world"><scale value="10"/><rotate y="1" angle="35"/></transform>
            <bsdf type="thindielectric"><float name="int_ior" value="1.8"/><float name="specular_transmittance" value="0.5"/></bsdf>
        </shape>
        <shape type="rectangle">
            <transform name="to_world"><scale value="100"/><translate z="-5"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
            <emitter type="area"><rgb name="radiance" value="0.25"/></emitter>
        </shape>
    </scene>"#;
    let normal = Vec3::new(35f32.to_radians().sin(), 0.0, 35f32.to_radians().cos());
    let path = Path::new("pane.xml");
    // What a ray leaving the pane point p in direction d sees: the backdrop
    // (the 200 × 200 square at z = −5) or the sky.
    let sees = |p: Vec3, d: Vec3| -> f32 {
        if d.z < 0.0 {
            let q = p + d * ((-5.0 - p.z) / d.z);
            if q.x.abs() <= 100.0 && q.y.abs() <= 100.0 {
                return 0.25;
            }
        }
        1.0
    };
    let expected = expected_image(path, text, 8, |ray| {
        let d = ray.d.normalize();
        let p = ray.o + d * (-ray.o.dot(normal) / d.dot(normal));
        let cos = d.dot(normal).abs();
        let r = fresnel_dielectric(cos, 1.8).r;
        let tt = 1.0 - r;
        let slab_r = r + tt * tt * r / (1.0 - r * r);
        let mirrored = d - 2.0 * d.dot(normal) * normal;
        Rgb::WHITE * (slab_r * sees(p, mirrored) + (1.0 - slab_r) * 0.5 * sees(p, d))
    });
    let passes = render_passes(path, Some(text), Default::default(), 16, 8);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("thin pane", 0.005);
}

const WATER: f32 = 1.333;

fn snells_window_scene() -> &'static str {
    // The camera 1 m under a flat water surface looks straight up, with a
    // 130° field of view; the sky (and everything else) is a constant 1.
    r#"<scene version="3.0.0">
        <integrator type="path"><integer name="max_depth" value="-1"/></integrator>
        <sensor type="perspective">
            <float name="fov" value="130"/>
            <transform name="to_world"><lookat origin="0, 0, -1" target="0, 0, 0" up="0, 1, 0"/></transform>
            <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
            <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/><rfilter type="box"/></film>
        </sensor>
        <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
        <shape type="rectangle">
            <transform name="to_world"><scale value="50"/></transform>
            <bsdf type="dielectric"><float name="int_ior" value="1.333"/><float name="ext_ior" value="1.0"/></bsdf>
        </shape>
    </scene>"#
}

#[test]
fn snells_window_has_the_critical_angle_radius_and_the_eta_squared_brightness() {
    // The rectangle faces +z, so the water below is its interior (int_ior
    // 1.333) and the air above its exterior. A ray going up at angle θ from the vertical is
    // reflected with F(θ) back into the water (where it sees radiance 1) and
    // refracted with 1 − F into the air, where the sky's radiance 1 becomes
    // η² · 1 inside the denser water. Beyond the critical angle
    // asin(1/1.333) = 48.6° everything is reflected: the pixel is exactly 1.
    let text = snells_window_scene();
    let path = Path::new("snells-window.xml");
    let up = Vec3::Z;
    let value_at = |d: Vec3| -> f32 {
        let cos = d.normalize().dot(up);
        // Seen from the water side (outside of the interface, relative index 1/η).
        let f = fresnel_dielectric(cos, 1.0 / WATER).r;
        f + (1.0 - f) * WATER * WATER
    };
    let expected = expected_image(path, text, 8, |ray| Rgb::WHITE * value_at(ray.d));
    let passes = render_passes(path, Some(text), Default::default(), 16, 16);
    compare(&passes, &expected, 8, 0.0).assert_unbiased("snell's window", 0.005);

    // The window's radius read off the rendered image: along the middle row,
    // the first pixel from the centre that is not brighter than the TIR
    // region (1) marks the critical angle.
    let avg = average(&passes);
    let scene = snell::load_str(path, text, &Default::default()).expect("scene");
    let w = avg.width as usize;
    let row = avg.height as usize / 2;
    let mut edge = None;
    for x in w / 2..w {
        if avg.pixels[row * w + x][1] < 1.01 {
            edge = Some(x);
            break;
        }
    }
    let edge = edge.expect("the window has an edge inside the image");
    let angle_of = |x: f32| -> f32 {
        let ray = scene.camera.generate_ray(Vec2::new(x / w as f32, (row as f32 + 0.5) / avg.height as f32));
        ray.d.normalize().dot(up).acos().to_degrees()
    };
    let critical = (1.0 / WATER).asin().to_degrees();
    // The edge lies within the last bright pixel or the first dark one.
    let (inner, outer) = (angle_of(edge as f32 - 1.0), angle_of(edge as f32 + 1.0));
    assert!(inner <= critical && critical <= outer, "window edge between {inner:.2}° and {outer:.2}°, critical angle {critical:.2}°");
    assert!((critical - 48.6).abs() < 0.05);
    // Inside, the centre is brighter than the sky by nearly η² (less the reflected part).
    let centre = avg.pixels[row * w + w / 2][1];
    let f0 = ((WATER - 1.0) / (WATER + 1.0)).powi(2);
    let expected_centre = f0 + (1.0 - f0) * WATER * WATER;
    assert!((centre - expected_centre).abs() < 0.01, "centre {centre} vs {expected_centre}");
    assert!(centre > 1.7, "the η² factor is missing: centre {centre}");
}

#[test]
fn an_emitter_seen_in_a_mirror_counts_once() {
    // Looking straight down through a hidden area light at a metal mirror:
    // where the mirrored ray meets the light the pixel is F(0) · L_e, else 0.
    // No emitter sampling happens at the delta vertex and the emitter hit
    // after it is counted in full, in `direct` and in `path` alike. The
    // light's edges lie on pixel edges, so every pixel is exact.
    let (eta, k) = ([1.5f32, 0.9, 0.4], [3.0f32, 2.6, 2.2]);
    for integrator in ["direct", "path"] {
        let text = format!(
            r#"<scene version="3.0.0">
            <integrator type="{integrator}"><boolean name="hide_emitters" value="true"/></integrator>
            <sensor type="orthographic">
                <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
                <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
                <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/><rfilter type="box"/></film>
            </sensor>
            <shape type="rectangle">
                <transform name="to_world"><scale value="2"/></transform>
                <bsdf type="conductor"><rgb name="eta" value="1.5, 0.9, 0.4"/><rgb name="k" value="3.0, 2.6, 2.2"/></bsdf>
            </shape>
            <shape type="rectangle">
                <transform name="to_world"><scale x="0.375" y="0.25" z="1"/><rotate x="1" angle="180"/><translate x="0.125" z="1"/></transform>
                <emitter type="area"><rgb name="radiance" value="2"/></emitter>
            </shape>
        </scene>"#
        );
        let path = Path::new("mirror-light.xml");
        let expected = expected_image(path, &text, 4, |ray| {
            let p = ray.o + ray.d * (-ray.o.z / ray.d.z);
            if (p.x - 0.125).abs() <= 0.375 && p.y.abs() <= 0.25 {
                Rgb::new(fresnel_conductor(1.0, eta[0], k[0]), fresnel_conductor(1.0, eta[1], k[1]), fresnel_conductor(1.0, eta[2], k[2])) * 2.0
            } else {
                Rgb::BLACK
            }
        });
        let passes = render_passes(path, Some(&text), Default::default(), 8, 4);
        compare(&passes, &expected, 4, 0.0).assert_unbiased(&format!("light in a mirror ({integrator})"), 0.005);
    }
}

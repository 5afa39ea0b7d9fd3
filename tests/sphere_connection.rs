//! `ptracer`'s `sphere_connection`: light paths joined to the pinhole
//! through smooth dielectric spheres in closed form
//! (`src/integrator/sphere_connection.rs`).

mod common;
use common::*;

/// A 7 × 7 grid of water drops (radius 0.3, non-dispersive η = 1.333) at
/// depth 10 in front of a pinhole, lit by a large one-sided disk light
/// (radius 8, 20 away from the drops: 22° seen from them) behind the camera,
/// nothing else. A camera path finds the light through the drops' specular
/// chains (the light is large); a light path is joined to the pinhole through
/// them only by the closed-form connection. Both count the same paths (up
/// to `max_depth` segments), so the images agree; the connection's one
/// approximation, a beam uniform over each drop, is off by the drop's size
/// over the light's distance (1.5 %).
fn drops_scene(integrator: &str) -> String {
    let mut drops = String::new();
    for j in 0..7 {
        for i in 0..7 {
            let (x, y) = (-2.4 + 0.8 * i as f32, -2.4 + 0.8 * j as f32);
            drops.push_str(&format!(
                r#"<shape type="sphere"><point name="center" x="{x}" y="{y}" z="{}"/><float name="radius" value="0.3"/><ref id="water"/></shape>"#,
                10.0 + 0.3 * ((i + j) % 3) as f32
            ));
        }
    }
    format!(
        r#"<scene version="3.0.0">
        {integrator}
        <sensor type="perspective">
            <float name="fov" value="34"/>
            <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/></transform>
            <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
            <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/><rfilter type="box"/></film>
        </sensor>
        <bsdf type="dielectric" id="water"><float name="int_ior" value="1.333"/><float name="ext_ior" value="1"/></bsdf>
        <shape type="disk">
            <transform name="to_world"><scale value="8"/><translate z="-10"/></transform>
            <emitter type="area"><rgb name="radiance" value="1, 0.8, 0.6"/></emitter>
        </shape>
        {drops}
    </scene>"#
    )
}

/// Drops lit by the disk light, reflections only (`max_depth` 3: light →
/// drop surface → camera, and the same through a second drop): the image
/// means agree within 1 % and every 8² block within its noise.
#[test]
fn reflections_off_drops_match_path_tracing() {
    let dir = repo("tests/scenes");
    let ptracer = r#"<integrator type="ptracer"><integer name="max_depth" value="3"/><boolean name="sphere_connection" value="true"/></integrator>"#;
    let path = r#"<integrator type="path"><integer name="max_depth" value="3"/></integrator>"#;
    let a = render_passes(&dir.join("drops.xml"), Some(&drops_scene(ptracer)), params(&[]), 8, 32);
    let b = render_passes(&dir.join("drops.xml"), Some(&drops_scene(path)), params(&[]), 8, 256);
    assert_agree("drops, reflections", &a, &b, 8, 0.01);
    // Without the connection the drops stay black to the light paths.
    let off = render_passes(&dir.join("drops.xml"), Some(&drops_scene(&ptracer.replace("true", "false"))), params(&[]), 1, 8);
    assert_eq!(mean(&off[0]), [0.0; 3]);
}

//! Mitsuba features that Snell knows by name but does not render yet, so a
//! scene using them fails with a located error that names the feature
//! ("… is not supported yet") instead of "unknown element" or "unknown plugin".
//!
//! | what | Mitsuba names |
//! |---|---|
//! | id aliases | `<alias id="…" as="…"/>` |
//!
//! [`removed`] names Mitsuba 0.6 plugins that Mitsuba 3 no longer has, so
//! that an old scene's "unknown plugin" error says what to use instead.

use super::xml::Kind;

/// The feature an unsupported element tag belongs to.
pub fn element(tag: &str) -> Option<&'static str> {
    match tag {
        "alias" => Some("aliases of object ids"),
        _ => None,
    }
}

/// What to write instead of a Mitsuba 0.6 plugin that Mitsuba 3 removed.
pub fn removed(kind: Kind, name: &str) -> Option<&'static str> {
    match (kind, name) {
        (Kind::Film, "ldrfilm") => Some("use hdrfilm (Snell writes 8-bit sRGB with -o image.png)"),
        (Kind::Sampler, "halton" | "hammersley") => Some("use sobol or zsobol (Owen-scrambled Sobol points)"),
        (Kind::Integrator, "mlt" | "pssmlt" | "erpt" | "photonmapper" | "ppm" | "vpl") => Some("use path, bdpt or sppm"),
        (Kind::Bsdf, "phong" | "ward" | "roughcoating" | "coating" | "irawan" | "hk" | "difftrans" | "roughdiffuse") => {
            Some("Mitsuba 3 has no such BSDF; diffuse, plastic, conductor or dielectric are the closest")
        }
        (Kind::Texture, "scale" | "vertexcolors" | "wireframe" | "gridtexture" | "curvature") => Some("Mitsuba 3 has no such texture"),
        (Kind::Emitter, "sunsky" | "sun" | "sky") => Some("Mitsuba 3 has no sky model; an environment map image is the closest"),
        _ => None,
    }
}

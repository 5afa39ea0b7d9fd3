//! Mitsuba features that Snell knows by name but does not render yet, so a
//! scene using them fails with a located error that names the feature
//! ("… is not supported yet") instead of "unknown element" or "unknown plugin".
//!
//! | what | Mitsuba names |
//! |---|---|
//! | id aliases | `<alias id="…" as="…"/>` |
//!
//! [`mitsuba3_plugin`] names the plugins of Mitsuba 3.9.1 that Snell does
//! not render yet, so that their error says so instead of suggesting a typo.
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

/// What a Mitsuba 3.9.1 plugin that Snell does not render yet is.
pub fn mitsuba3_plugin(kind: Kind, name: &str) -> Option<&'static str> {
    match (kind, name) {
        (Kind::Emitter, "sunsky" | "timed_sunsky") => Some("Hosek–Wilkie sky and sun"),
        (Kind::Emitter, "directionalarea") => Some("an area light emitting in one direction"),
        (Kind::Bsdf, "hair") => Some("a hair fibre BSDF"),
        (Kind::Bsdf, "measured" | "measured_polarized") => Some("a measured (tabulated) BSDF"),
        (Kind::Film, "specfilm") => Some("a film of spectral sensitivities"),
        (Kind::Integrator, "direct_projective" | "prb_projective") => Some("a differentiable integrator; path renders the same image"),
        (Kind::Sensor, "batch") => Some("a multi-view sensor"),
        (Kind::Shape, "ellipsoids" | "ellipsoidsmesh") => Some("ellipsoid (Gaussian splat) primitives"),
        (Kind::Phase, "sggx") => Some("a microflake (SGGX) phase function"),
        (Kind::Texture, "volume") => Some("a 3-D texture read from a volume"),
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
        (Kind::Emitter, "sun" | "sky") => {
            Some("Mitsuba 3 replaced sun and sky by sunsky (Hosek–Wilkie), which Snell does not render yet; an environment map image of a sky is the closest")
        }
        _ => None,
    }
}

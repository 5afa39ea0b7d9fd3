//! Mitsuba features that Snell knows by name but does not render yet, so a
//! scene using them fails with a located error that names the feature
//! ("… is not supported yet") instead of "unknown element" or "unknown plugin".
//!
//! | what | Mitsuba names |
//! |---|---|
//! | participating media | `<medium>`, `<phase>`, `<volume>` elements; `homogeneous`, `heterogeneous` media; `volpath`, `volpathmis`, `prbvolpath` integrators; `gridvolume`/`constvolume` volumes |
//! | curves | `bsplinecurve`, `linearcurve` shapes |
//! | signed distance fields | `sdfgrid` shape |
//! | id aliases | `<alias id="…" as="…"/>` |

use super::xml::Kind;

/// The feature an unsupported element tag belongs to.
pub fn element(tag: &str) -> Option<&'static str> {
    match tag {
        "medium" => Some("participating media"),
        "phase" => Some("phase functions of participating media"),
        "volume" => Some("volume data of participating media"),
        "alias" => Some("aliases of object ids"),
        _ => None,
    }
}

/// The feature an unsupported plugin of `kind` belongs to.
pub fn plugin(kind: Kind, name: &str) -> Option<&'static str> {
    match (kind, name) {
        (Kind::Integrator, "volpath" | "volpathmis" | "prbvolpath") => Some("participating media"),
        (Kind::Shape, "bsplinecurve" | "linearcurve") => Some("curves"),
        (Kind::Shape, "sdfgrid") => Some("signed distance fields"),
        (Kind::Texture, "gridvolume" | "constvolume") => Some("participating media"),
        _ => None,
    }
}

//! Typed access to a node's properties. Every getter marks what it read; a
//! property or nested object nobody read is an error (Mitsuba: "unreferenced
//! property"), so a misspelt parameter never silently falls back to a default.

use super::error::{Result, SceneError};
use super::xml::{Child, Kind, Node, Value};
use crate::bsdf::dispersion::IorSpectrum;
use crate::math::Transform;
use crate::spectrum::{Emission, ListedSpectrum, Rgb};
use crate::spectrum::cie::spectrum_to_linear_srgb;
use glam::Vec3;
use std::cell::Cell;

/// Linear sRGB of the equal-energy spectrum of unit value (CIE 1931 2°
/// observer, XYZ → sRGB; Mitsuba 3 gives the same triple).
/// The largest emitted radiance, intensity or irradiance accepted: far above
/// any physical light (the sun's radiance is about 10⁷ W m⁻² sr⁻¹ nm⁻¹),
/// and far enough below f32::MAX (3.4·10³⁸) that spectral uplift, path
/// throughput and film sums stay finite.
pub const MAX_EMISSION: f32 = 1e20;

pub const EQUAL_ENERGY_WHITE: Rgb = Rgb::new(1.204_794, 0.948_291, 0.908_916);

pub struct Props<'a> {
    pub node: &'a Node,
    used: Vec<Cell<bool>>,
    child_used: Vec<Cell<bool>>,
}

impl<'a> Props<'a> {
    pub fn new(node: &'a Node) -> Props<'a> {
        Props {
            node,
            used: node.props.iter().map(|_| Cell::new(false)).collect(),
            child_used: node.children.iter().map(|_| Cell::new(false)).collect(),
        }
    }

    fn find(&self, name: &str) -> Option<(usize, &'a Value)> {
        let i = self.node.props.iter().position(|p| p.name == name)?;
        self.used[i].set(true);
        Some((i, &self.node.props[i].value))
    }

    pub fn has(&self, name: &str) -> bool {
        self.node.props.iter().any(|p| p.name == name)
    }

    /// Whether a nested object (or reference) is called `name`.
    pub fn has_child(&self, name: &str) -> bool {
        self.node.children.iter().any(|c| c.name.as_deref() == Some(name))
    }

    /// An error located at property `name` (or at the object, if absent).
    pub fn error_at(&self, name: &str, message: impl Into<String>) -> SceneError {
        match self.node.props.iter().find(|p| p.name == name) {
            Some(p) => SceneError::at(&p.loc, message),
            None => SceneError::at(&self.node.loc, message),
        }
    }

    fn type_error(&self, i: usize, expected: &str) -> SceneError {
        let p = &self.node.props[i];
        SceneError::at(
            &p.loc,
            format!(
                "property \"{}\" of {} \"{}\" has type {}, expected {expected}",
                p.name,
                self.node.kind.tag(),
                self.node.plugin,
                p.value.type_name()
            ),
        )
    }

    fn range_error(&self, i: usize, what: &str) -> SceneError {
        let p = &self.node.props[i];
        SceneError::at(&p.loc, format!("property \"{}\" must be {what}", p.name))
    }

    fn missing(&self, name: &str, ty: &str) -> SceneError {
        SceneError::at(
            &self.node.loc,
            format!("{} \"{}\" needs the {ty} property \"{name}\"", self.node.kind.tag(), self.node.plugin),
        )
    }

    pub fn float_opt(&self, name: &str) -> Result<Option<f32>> {
        match self.find(name) {
            None => Ok(None),
            Some((_, Value::Float(f))) => Ok(Some(*f as f32)),
            Some((_, Value::Integer(v))) => Ok(Some(*v as f32)),
            Some((i, _)) => Err(self.type_error(i, "float")),
        }
    }

    pub fn float(&self, name: &str, default: f32) -> Result<f32> {
        Ok(self.float_opt(name)?.unwrap_or(default))
    }

    pub fn float_req(&self, name: &str) -> Result<f32> {
        self.float_opt(name)?.ok_or_else(|| self.missing(name, "float"))
    }

    /// A float with a check (e.g. positivity) reported at the property.
    pub fn float_checked(&self, name: &str, default: f32, ok: impl Fn(f32) -> bool, what: &str) -> Result<f32> {
        let v = self.float(name, default)?;
        if !ok(v) {
            return Err(match self.node.props.iter().position(|p| p.name == name) {
                Some(i) => self.range_error(i, what),
                None => self.missing(name, "float"),
            });
        }
        Ok(v)
    }

    pub fn int(&self, name: &str, default: i64) -> Result<i64> {
        match self.find(name) {
            None => Ok(default),
            Some((_, Value::Integer(v))) => Ok(*v),
            Some((i, _)) => Err(self.type_error(i, "integer")),
        }
    }

    pub fn int_checked(&self, name: &str, default: i64, ok: impl Fn(i64) -> bool, what: &str) -> Result<i64> {
        let v = self.int(name, default)?;
        if !ok(v) {
            return Err(match self.node.props.iter().position(|p| p.name == name) {
                Some(i) => self.range_error(i, what),
                None => self.missing(name, "integer"),
            });
        }
        Ok(v)
    }

    pub fn bool(&self, name: &str, default: bool) -> Result<bool> {
        match self.find(name) {
            None => Ok(default),
            Some((_, Value::Boolean(b))) => Ok(*b),
            Some((i, _)) => Err(self.type_error(i, "boolean")),
        }
    }

    pub fn string_opt(&self, name: &str) -> Result<Option<&'a str>> {
        match self.find(name) {
            None => Ok(None),
            Some((_, Value::String(s))) => Ok(Some(s.as_str())),
            Some((i, _)) => Err(self.type_error(i, "string")),
        }
    }

    pub fn string_req(&self, name: &str) -> Result<&'a str> {
        self.string_opt(name)?.ok_or_else(|| self.missing(name, "string"))
    }

    /// A string that must be one of `choices`.
    pub fn choice(&self, name: &str, default: &'a str, choices: &[&str]) -> Result<&'a str> {
        let v = self.string_opt(name)?.unwrap_or(default);
        if !choices.contains(&v) {
            let loc = self.node.props.iter().find(|p| p.name == name).map_or(&self.node.loc, |p| &p.loc);
            return Err(SceneError::at(loc, format!("\"{v}\" is not a valid value of \"{name}\"")).with_choices(choices));
        }
        Ok(v)
    }

    /// An index of refraction given as a positive number or a name from
    /// [`crate::bsdf::ior`] (Mitsuba's `lookup_ior`); `default` if absent.
    /// An index of refraction that may depend on the wavelength: a number,
    /// a constant's name, or a dispersive form (`sellmeier:bk7`, see
    /// `bsdf/dispersion.rs`).
    pub fn ior_spectrum(&self, name: &str, default: f32) -> Result<IorSpectrum> {
        if let Some((i, Value::String(s))) = self.find(name) {
            if let Some(parsed) = crate::bsdf::dispersion::parse_ior_expr(s) {
                let loc = &self.node.props[i].loc;
                return parsed.map_err(|e| SceneError::at(loc, format!("bad dispersive index of refraction for \"{name}\": {e}")));
            }
        }
        self.ior(name, default).map(IorSpectrum::Constant)
    }

    pub fn ior(&self, name: &str, default: f32) -> Result<f32> {
        let Some((i, value)) = self.find(name) else { return Ok(default) };
        let loc = &self.node.props[i].loc;
        let v = match value {
            Value::Float(f) => *f as f32,
            Value::Integer(v) => *v as f32,
            Value::String(s) => {
                return crate::bsdf::ior::lookup_ior(s).ok_or_else(|| {
                    SceneError::at(loc, format!("unknown index of refraction \"{s}\" for \"{name}\" (give a number or a name)"))
                        .with_choices(&crate::bsdf::ior::ior_names())
                });
            }
            _ => return Err(self.type_error(i, "float or string")),
        };
        if !(v > 0.0 && v.is_finite()) {
            return Err(SceneError::at(loc, format!("index of refraction \"{name}\" must be a positive number, not {v}")));
        }
        Ok(v)
    }

    /// A point or vector (Mitsuba accepts either where a 3-vector is meant).
    pub fn vec3_opt(&self, name: &str) -> Result<Option<Vec3>> {
        match self.find(name) {
            None => Ok(None),
            Some((_, Value::Point(p) | Value::Vector(p))) => Ok(Some(*p)),
            Some((i, _)) => Err(self.type_error(i, "point or vector")),
        }
    }

    pub fn vec3(&self, name: &str, default: Vec3) -> Result<Vec3> {
        Ok(self.vec3_opt(name)?.unwrap_or(default))
    }

    pub fn transform(&self, name: &str) -> Result<Transform> {
        match self.find(name) {
            None => Ok(Transform::IDENTITY),
            Some((_, Value::Transform(t))) => Ok(*t),
            Some((i, _)) => Err(self.type_error(i, "transform")),
        }
    }

    /// A colour given as `rgb`, a constant `spectrum` or a `float`.
    /// `Ok(None)` when absent; an error for other types.
    pub fn color_opt(&self, name: &str) -> Result<Option<Rgb>> {
        match self.find(name) {
            None => Ok(None),
            Some((_, Value::Rgb(c))) => Ok(Some(Rgb(*c))),
            Some((_, Value::Spectrum(s))) => Ok(Some(Rgb([*s; 3]))),
            Some((_, Value::SpectrumList(v))) => Ok(Some(spectrum_to_linear_srgb(v, false))),
            Some((_, Value::SpectrumPlugin(p))) => Ok(Some(p.reflectance().0)),
            Some((_, Value::Float(f))) => Ok(Some(Rgb([*f as f32; 3]))),
            Some((_, Value::Integer(v))) => Ok(Some(Rgb([*v as f32; 3]))),
            Some((i, _)) => Err(self.type_error(i, "rgb, spectrum or float")),
        }
    }

    /// A `<spectrum>` of `wavelength:value` pairs or a spectrum plugin, if
    /// that is what `name` is (other types are left for the other getters).
    pub fn listed_opt(&self, name: &str) -> Option<ListedSpectrum> {
        self.spectrum_opt(name).map(|(_, spectrum)| spectrum)
    }

    /// A `<spectrum>` of pairs or a spectrum plugin read as a reflectance:
    /// its RGB-mode colour and the spectrum spectral mode evaluates. `None`
    /// for other types.
    pub fn spectrum_opt(&self, name: &str) -> Option<(Rgb, ListedSpectrum)> {
        let i = self.node.props.iter().position(|p| p.name == name)?;
        let out = match &self.node.props[i].value {
            Value::SpectrumList(v) => {
                let listed = ListedSpectrum::new(v.clone())?;
                (listed.to_rgb(false), listed)
            }
            Value::SpectrumPlugin(p) => p.reflectance(),
            _ => return None,
        };
        self.used[i].set(true);
        Some(out)
    }

    /// Emission (radiance, intensity, irradiance): a colour, or a spectrum
    /// kept as such for spectral mode (a constant `<spectrum>` is flat).
    /// Negative emission is an error, and so is emission so large that
    /// arithmetic along a path would overflow single precision (above
    /// [`MAX_EMISSION`]), which would otherwise give a black image.
    pub fn emission_opt(&self, name: &str) -> Result<Option<Emission>> {
        let plugin = match self.find(name) {
            Some((_, Value::SpectrumPlugin(p))) => Some(p.emission()),
            _ => None,
        };
        let emission = if let Some(e) = plugin {
            e
        } else if let Some(listed) = self.listed_opt(name) {
            Emission::listed(listed)
        } else if let Some((_, Value::Spectrum(v))) = self.find(name) {
            Emission::flat(EQUAL_ENERGY_WHITE * *v, *v)
        } else {
            match self.color_opt(name)? {
                Some(c) => Emission::rgb(c),
                None => return Ok(None),
            }
        };
        let values: Vec<f32> = match &emission.spectrum {
            // The values given (the RGB of a spectrum is derived from them).
            Some(s) => s.samples().iter().map(|&(_, v)| v).collect(),
            None => emission.rgb.0.to_vec(),
        };
        if let Some(v) = values.iter().find(|&&v| v < 0.0) {
            return Err(self.error_at(
                name,
                format!("emission \"{name}\" of {} \"{}\" is negative ({v}); light sources emit zero or more", self.node.kind.tag(), self.node.plugin),
            ));
        }
        if let Some(v) = values.iter().find(|&&v| v > MAX_EMISSION) {
            return Err(self.error_at(
                name,
                format!("emission \"{name}\" of {} \"{}\" is {v:e}, above the largest Snell renders ({MAX_EMISSION:e})", self.node.kind.tag(), self.node.plugin),
            )
            .with_help("larger values overflow single-precision arithmetic along a path and give a black image; scale the scene's units"));
        }
        Ok(Some(emission))
    }

    pub fn color(&self, name: &str, default: Rgb) -> Result<Rgb> {
        Ok(self.color_opt(name)?.unwrap_or(default))
    }

    /// Marks the nested objects of `kind` as used and returns them, in document order.
    pub fn children_of(&self, kind: Kind) -> Vec<&'a Child> {
        let mut out = vec![];
        for (i, c) in self.node.children.iter().enumerate() {
            if c.kind_hint() == Some(kind) {
                self.child_used[i].set(true);
                out.push(c);
            }
        }
        out
    }

    /// A nested object by its `name` attribute (inline or `<ref name=…>`).
    pub fn child_named(&self, name: &str) -> Option<&'a Child> {
        let i = self.node.children.iter().position(|c| c.name.as_deref() == Some(name))?;
        self.child_used[i].set(true);
        Some(&self.node.children[i])
    }

    /// References (`<ref id>`) without a name: their kind is known only after
    /// resolution, so the loader hands them out through this.
    pub fn unnamed_refs(&self) -> Vec<&'a Child> {
        let mut out = vec![];
        for (i, c) in self.node.children.iter().enumerate() {
            if c.kind_hint().is_none() && c.name.is_none() {
                self.child_used[i].set(true);
                out.push(c);
            }
        }
        out
    }

    /// Errors on the first property or nested object nobody read.
    pub fn finish(&self) -> Result<()> {
        for (i, p) in self.node.props.iter().enumerate() {
            if !self.used[i].get() {
                return Err(SceneError::at(
                    &p.loc,
                    format!("unused parameter \"{}\": {} \"{}\" does not take it", p.name, self.node.kind.tag(), self.node.plugin),
                ));
            }
        }
        for (i, c) in self.node.children.iter().enumerate() {
            if !self.child_used[i].get() {
                let what = match c.kind_hint() {
                    Some(k) => format!("<{}>", k.tag()),
                    None => "reference".to_string(),
                };
                return Err(SceneError::at(
                    &c.loc,
                    format!("unexpected nested {what}: {} \"{}\" does not take it here", self.node.kind.tag(), self.node.plugin),
                ));
            }
        }
        Ok(())
    }
}

impl Child {
    /// The kind of an inline child; `None` for a reference.
    pub fn kind_hint(&self) -> Option<Kind> {
        match &self.target {
            super::xml::ChildTarget::Inline(n) => Some(n.kind),
            super::xml::ChildTarget::Ref(_) => None,
        }
    }
}

//! Stage 1 of scene loading: Mitsuba 3 XML text → a tree of [`Node`]s with
//! typed, located properties. `<default>` parameters and `$name` substitution,
//! `<include>` and transforms are resolved here; references (`<ref id>`) are
//! kept by name and resolved by the loader. `<path value>` adds a search
//! folder (see [`super::search`]) that every [`SourceFile`] of the document
//! shares, so the loader resolves file names against it.
//!
//! Scene files older than version 2.0.0 (Mitsuba 0.5/0.6) are upgraded in
//! memory as Mitsuba 3.9 upgrades them (its parser's `upgrade_from_v1`):
//! property and object names from camelCase to snake_case (`toWorld` →
//! `to_world`, `intIOR` → `int_ior`, `sampleCount` → `sample_count`), the
//! `diffuse` BSDF's `diffuseReflectance` → `reflectance`, and
//! `uoffset`/`voffset`/`uscale`/`vscale` turned into a `to_uv` transform
//! (scale · translate). Nothing else is renamed (Mitsuba 3.9 does not either):
//! a plugin Mitsuba 3 removed fails as an unknown plugin, and `<lookAt>` as
//! an unknown transform operation (Mitsuba 3 spells it `<lookat>`).

use super::error::{Location, Result, SceneError, SourceFile};
use super::search::{SearchPaths, folder_of};
use crate::math::Transform;
use crate::spectrum::Rgb;
use crate::spectrum::plugins::SpectrumPlugin;
use glam::{Mat4, Vec3, Vec4};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The kinds of scene object, named as Mitsuba's XML tags.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    Scene,
    Shape,
    Bsdf,
    Texture,
    Emitter,
    Sensor,
    Film,
    Sampler,
    Integrator,
    Rfilter,
    Medium,
    Phase,
    Volume,
}

impl Kind {
    pub const ALL: [Kind; 13] = [
        Kind::Scene,
        Kind::Shape,
        Kind::Bsdf,
        Kind::Texture,
        Kind::Emitter,
        Kind::Sensor,
        Kind::Film,
        Kind::Sampler,
        Kind::Integrator,
        Kind::Rfilter,
        Kind::Medium,
        Kind::Phase,
        Kind::Volume,
    ];

    pub fn tag(self) -> &'static str {
        match self {
            Kind::Scene => "scene",
            Kind::Shape => "shape",
            Kind::Bsdf => "bsdf",
            Kind::Texture => "texture",
            Kind::Emitter => "emitter",
            Kind::Sensor => "sensor",
            Kind::Film => "film",
            Kind::Sampler => "sampler",
            Kind::Integrator => "integrator",
            Kind::Rfilter => "rfilter",
            Kind::Medium => "medium",
            Kind::Phase => "phase",
            Kind::Volume => "volume",
        }
    }

    fn from_tag(tag: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.tag() == tag)
    }
}

#[derive(Clone, Debug)]
pub enum Value {
    Integer(i64),
    Float(f64),
    Boolean(bool),
    String(String),
    Rgb([f32; 3]),
    /// A `<spectrum>` with one constant value.
    Spectrum(f32),
    /// A `<spectrum>` given as `wavelength:value` pairs (nm), increasing.
    SpectrumList(Vec<(f32, f32)>),
    /// A `<spectrum type="…">`: one of Mitsuba's spectrum plugins.
    SpectrumPlugin(Arc<SpectrumPlugin>),
    Point(Vec3),
    Vector(Vec3),
    Transform(Transform),
}

impl Value {
    pub fn type_name(&self) -> &'static str {
        match self {
            Value::Integer(_) => "integer",
            Value::Float(_) => "float",
            Value::Boolean(_) => "boolean",
            Value::String(_) => "string",
            Value::Rgb(_) => "rgb",
            Value::Spectrum(_) | Value::SpectrumList(_) | Value::SpectrumPlugin(_) => "spectrum",
            Value::Point(_) => "point",
            Value::Vector(_) => "vector",
            Value::Transform(_) => "transform",
        }
    }
}

#[derive(Clone, Debug)]
pub struct Prop {
    pub name: String,
    pub value: Value,
    pub loc: Location,
}

/// A nested object: written inline, or a `<ref id="..."/>` to one declared elsewhere.
#[derive(Clone, Debug)]
pub enum ChildTarget {
    Inline(Arc<Node>),
    Ref(String),
}

#[derive(Clone, Debug)]
pub struct Child {
    pub name: Option<String>,
    pub target: ChildTarget,
    pub loc: Location,
}

#[derive(Clone, Debug)]
pub struct Node {
    pub kind: Kind,
    /// The plugin name (`type` attribute); empty for `<scene>`.
    pub plugin: String,
    pub id: Option<String>,
    pub loc: Location,
    pub props: Vec<Prop>,
    pub children: Vec<Child>,
}

/// Reads a scene file. `params` are the `-D name=value` overrides; a
/// `<default>` only sets a parameter that is not given there.
pub fn parse_file(path: &Path, params: &HashMap<String, String>) -> Result<Node> {
    let mut parser = Parser::new(params, path);
    let root = parser.parse_root(path)?;
    parser.check_overrides(&root)?;
    Ok(root)
}

/// Parses scene text as if it were read from `path` (used by tests and the API).
pub fn parse_str(path: &Path, text: &str, params: &HashMap<String, String>) -> Result<Node> {
    let mut parser = Parser::new(params, path);
    let file = Arc::new(SourceFile::with_search(path.to_path_buf(), text.to_string(), parser.search.clone()));
    let root = parser.parse_document(file)?;
    parser.check_overrides(&root)?;
    Ok(root)
}

/// Longest attribute value after `$name` substitution, and the most bytes
/// that substitution may produce in one document (chained `<default>`s can
/// otherwise grow a value exponentially).
const MAX_EXPANDED_VALUE: usize = 1 << 20;
const MAX_EXPANDED_TOTAL: usize = 256 << 20;

struct Parser {
    params: HashMap<String, String>,
    include_depth: u32,
    /// The top-level file's search folders, which the loader resolves file
    /// names with (shared by every [`SourceFile`] of the document).
    search: Arc<SearchPaths>,
    /// The folders the file being parsed resolves `<include>` and `<path>`
    /// values with (Mitsuba 3.9's per-file resolver): its own `<path>`s
    /// (last first), its folder, then those of the file that included it as
    /// they were at the `<include>`. The working directory comes last.
    folders: Vec<PathBuf>,
    /// Whether the file being parsed is older than version 2.0.0 and is
    /// upgraded as Mitsuba 3 upgrades it.
    legacy: bool,
    /// `-D` names, which must be declared by a `<default>` or used as `$name`.
    overrides: Vec<String>,
    /// Names declared by `<default>`, and names used as `$name`.
    declared: HashSet<String>,
    used: std::cell::RefCell<HashSet<String>>,
    /// `<default>`s of each file (by path), to refuse a duplicate.
    defaults_seen: HashMap<(std::path::PathBuf, String), u32>,
    /// Current element depth, included files so far, elements so far.
    depth: u64,
    includes: u64,
    elements: u64,
    expanded_bytes: std::cell::Cell<usize>,
}

type XNode<'a, 'i> = roxmltree::Node<'a, 'i>;

fn loc_of(file: &Arc<SourceFile>, node: &XNode) -> Location {
    let r = node.range();
    // Text starts with the white space after the previous tag: point at the text itself.
    let skip = if node.is_text() { file.text.get(r.clone()).map_or(0, |s| s.len() - s.trim_start().len()) } else { 0 };
    Location::at_byte(file, r.start + skip)
}

fn attr_loc(file: &Arc<SourceFile>, node: &XNode, name: &str) -> Location {
    match node.attribute_node(name) {
        Some(a) => Location::at_byte(file, a.range().start),
        None => loc_of(file, node),
    }
}

impl Parser {
    fn new(params: &HashMap<String, String>, scene_file: &Path) -> Parser {
        let mut overrides: Vec<String> = params.keys().cloned().collect();
        overrides.sort();
        Parser {
            params: params.clone(),
            include_depth: 0,
            search: Arc::new(SearchPaths::for_scene(scene_file)),
            folders: vec![folder_of(scene_file)],
            legacy: false,
            overrides,
            declared: HashSet::new(),
            used: std::cell::RefCell::new(HashSet::new()),
            defaults_seen: HashMap::new(),
            depth: 0,
            includes: 0,
            elements: 0,
            expanded_bytes: std::cell::Cell::new(0),
        }
    }

    /// Every `-D name=value` must name a parameter the scene declares with
    /// `<default>` or uses as `$name`; otherwise it would be silently ignored.
    fn check_overrides(&self, root: &Node) -> Result<()> {
        let used = self.used.borrow();
        for name in &self.overrides {
            if self.declared.contains(name) || used.contains(name) {
                continue;
            }
            let mut known: Vec<&str> = self.declared.iter().chain(used.iter()).map(|s| s.as_str()).collect();
            known.sort();
            known.dedup();
            let e = SceneError::file(&root.loc.file.path, format!("-D {name}=…: the scene has no parameter \"{name}\""));
            return Err(if known.is_empty() {
                e.with_help("the scene declares no parameters (<default name=\"…\" value=\"…\"/>)")
            } else {
                e.with_help(format!("declared parameters are: {}", known.join(", ")))
            });
        }
        Ok(())
    }

    fn parse_root(&mut self, path: &Path) -> Result<Node> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::file(path, format!("cannot read scene file: {e}")))?;
        let file = Arc::new(SourceFile::with_search(path.to_path_buf(), text, self.search.clone()));
        self.parse_document(file)
    }

    fn parse_document(&mut self, file: Arc<SourceFile>) -> Result<Node> {
        // A UTF-8 byte-order mark is not part of the first line's columns.
        let file = match file.text.strip_prefix('\u{feff}') {
            Some(text) => Arc::new(SourceFile::with_search(file.path.clone(), text.to_string(), file.search.clone())),
            None => file,
        };
        let doc = roxmltree::Document::parse(&file.text).map_err(|e| {
            let p = e.pos();
            SceneError::at(&Location::new(&file, p.row, p.col), format!("malformed XML: {e}"))
        })?;
        let root = doc.root_element();
        let loc = loc_of(&file, &root);
        if root.tag_name().name() != "scene" {
            return Err(SceneError::at(&loc, format!("the root element is <{}>, expected <scene>", root.tag_name().name())));
        }
        // An included file may omit its version (Mitsuba then upgrades nothing).
        let legacy = match root.attribute("version") {
            None if self.include_depth > 0 => false,
            None => {
                return Err(SceneError::at(&loc, "<scene> has no version attribute").with_help("write <scene version=\"3.0.0\">"));
            }
            Some(version) => match parse_version(version) {
                Some(major) => major < 2,
                None => {
                    return Err(SceneError::at(&attr_loc(&file, &root, "version"), format!("unsupported scene version \"{version}\""))
                        .with_help("a version is three numbers, e.g. version=\"3.0.0\" (files older than 2.0.0 are upgraded as Mitsuba 3 upgrades them)"));
                }
            },
        };
        self.check_attrs(&file, &root, &["version"])?;
        let mut node = Node { kind: Kind::Scene, plugin: String::new(), id: None, loc, props: vec![], children: vec![] };
        let outer = std::mem::replace(&mut self.legacy, legacy);
        let parsed = self.parse_children(&file, &root, &mut node);
        self.legacy = outer;
        parsed?;
        Ok(node)
    }

    /// `$name` substitution in an attribute value.
    fn attr(&self, file: &Arc<SourceFile>, node: &XNode, name: &str) -> Result<Option<String>> {
        let Some(raw) = node.attribute(name) else { return Ok(None) };
        self.substitute(file, node, name, raw).map(Some)
    }

    /// The `name` attribute of an object, reference or property inside
    /// `parent`, upgraded (after `$` substitution, as Mitsuba 3.9 does) in a
    /// legacy file.
    fn name_attr(&self, file: &Arc<SourceFile>, node: &XNode, parent: &Node) -> Result<Option<String>> {
        let Some(name) = self.attr(file, node, "name")? else { return Ok(None) };
        if !self.legacy {
            return Ok(Some(name));
        }
        let name = legacy_snake_case(&name);
        if parent.kind == Kind::Bsdf && parent.plugin == "diffuse" && name == "diffuse_reflectance" {
            return Ok(Some("reflectance".to_string()));
        }
        Ok(Some(name))
    }

    /// `name` through this file's folders, then the working directory.
    fn resolve_here(&self, name: &str) -> Result<PathBuf, Vec<PathBuf>> {
        let p = Path::new(name);
        if p.is_absolute() {
            return if p.exists() { Ok(p.to_path_buf()) } else { Err(vec![]) };
        }
        for f in &self.folders {
            if f.join(p).exists() {
                return Ok(f.join(p));
            }
        }
        if p.exists() {
            return Ok(p.to_path_buf());
        }
        let mut searched = self.folders.clone();
        searched.push(PathBuf::from("."));
        Err(searched)
    }

    fn substitute(&self, file: &Arc<SourceFile>, node: &XNode, name: &str, raw: &str) -> Result<String> {
        if !raw.contains('$') {
            return Ok(raw.to_string());
        }
        let mut out = String::new();
        let mut rest = raw;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let after = &rest[i + 1..];
            let end = after.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(after.len());
            let key = &after[..end];
            match self.params.get(key) {
                Some(v) if !key.is_empty() => {
                    self.used.borrow_mut().insert(key.to_string());
                    out.push_str(v);
                    let total = self.expanded_bytes.get() + v.len();
                    self.expanded_bytes.set(total);
                    if out.len() > MAX_EXPANDED_VALUE || total > MAX_EXPANDED_TOTAL {
                        return Err(SceneError::at(
                            &attr_loc(file, node, name),
                            format!("substituting \"${key}\" makes this value too long ({} bytes so far)", out.len()),
                        )
                        .with_help(format!(
                            "one value may grow to {MAX_EXPANDED_VALUE} bytes and a document's substitutions to {MAX_EXPANDED_TOTAL} bytes"
                        )));
                    }
                }
                _ => {
                    let mut known: Vec<&str> = self.params.keys().map(|s| s.as_str()).collect();
                    known.sort();
                    let help = if known.is_empty() {
                        "declare it with <default name=\"…\" value=\"…\"/> or pass -D name=value".to_string()
                    } else {
                        format!("declare it with <default> or pass -D; defined parameters are: {}", known.join(", "))
                    };
                    return Err(SceneError::at(&attr_loc(file, node, name), format!("undefined parameter \"${key}\"")).with_help(help));
                }
            }
            rest = &after[end..];
        }
        out.push_str(rest);
        Ok(out)
    }

    fn req_attr(&self, file: &Arc<SourceFile>, node: &XNode, name: &str) -> Result<String> {
        self.attr(file, node, name)?.ok_or_else(|| {
            SceneError::at(&loc_of(file, node), format!("<{}> needs a \"{name}\" attribute", node.tag_name().name()))
        })
    }

    fn check_attrs(&self, file: &Arc<SourceFile>, node: &XNode, allowed: &[&str]) -> Result<()> {
        for a in node.attributes() {
            if !allowed.contains(&a.name()) {
                return Err(SceneError::at(
                    &Location::at_byte(file, a.range().start),
                    format!("unexpected attribute \"{}\" on <{}>", a.name(), node.tag_name().name()),
                )
                .with_choices(allowed));
            }
        }
        Ok(())
    }

    fn parse_children(&mut self, file: &Arc<SourceFile>, xml: &XNode, out: &mut Node) -> Result<()> {
        for child in xml.children() {
            if child.is_element() {
                self.elements += 1;
                if self.elements > crate::limits::max_xml_nodes() {
                    return Err(SceneError::at(
                        &loc_of(file, &child),
                        format!("the scene has more than {} XML elements (includes expanded)", crate::limits::max_xml_nodes()),
                    )
                    .with_help("raise the limit with the environment variable SNELL_MAX_XML_NODES"));
                }
                if self.depth >= crate::limits::max_xml_depth() {
                    return Err(SceneError::at(
                        &loc_of(file, &child),
                        format!("elements are nested more than {} levels deep", crate::limits::max_xml_depth()),
                    )
                    .with_help(format!(
                        "raise the limit with the environment variable SNELL_MAX_XML_DEPTH (at most {})",
                        crate::limits::XML_DEPTH_CEILING
                    )));
                }
                self.depth += 1;
                let r = self.parse_element(file, &child, out);
                self.depth -= 1;
                r?;
            } else if child.is_text() && !child.text().unwrap_or("").trim().is_empty() {
                return Err(SceneError::at(&loc_of(file, &child), "unexpected text inside an element"));
            }
        }
        Ok(())
    }

    fn parse_element(&mut self, file: &Arc<SourceFile>, x: &XNode, out: &mut Node) -> Result<()> {
        let tag = x.tag_name().name();
        let loc = loc_of(file, x);
        if let Some(kind) = Kind::from_tag(tag).filter(|k| *k != Kind::Scene) {
            self.check_attrs(file, x, &["type", "id", "name"])?;
            let plugin = self.req_attr(file, x, "type")?;
            let id = self.attr(file, x, "id")?;
            let name = self.name_attr(file, x, out)?;
            let mut node = Node { kind, plugin, id, loc: loc.clone(), props: vec![], children: vec![] };
            self.parse_children(file, x, &mut node)?;
            if self.legacy {
                upgrade_uv_floats(&mut node);
            }
            out.children.push(Child { name, target: ChildTarget::Inline(Arc::new(node)), loc });
            return Ok(());
        }
        match tag {
            "default" => {
                if out.kind != Kind::Scene {
                    return Err(SceneError::at(&loc, "<default> may only appear directly inside <scene>"));
                }
                self.check_attrs(file, x, &["name", "value"])?;
                let name = self.req_attr(file, x, "name")?;
                let value = self.req_attr(file, x, "value")?;
                if let Some(first) = self.defaults_seen.insert((file.path.clone(), name.clone()), loc.line) {
                    return Err(SceneError::at(
                        &attr_loc(file, x, "name"),
                        format!("parameter \"{name}\" has a second <default> (the first is at line {first})"),
                    ));
                }
                self.declared.insert(name.clone());
                self.params.entry(name).or_insert(value);
            }
            "ref" => {
                self.check_attrs(file, x, &["id", "name"])?;
                let id = self.req_attr(file, x, "id")?;
                let name = self.name_attr(file, x, out)?;
                out.children.push(Child { name, target: ChildTarget::Ref(id), loc });
            }
            "include" => {
                if out.kind != Kind::Scene {
                    return Err(SceneError::at(&loc, "<include> may only appear directly inside <scene>"));
                }
                self.check_attrs(file, x, &["filename"])?;
                let name = self.req_attr(file, x, "filename")?;
                // As Mitsuba 3.9: through this file's folders (its <path>s so
                // far, its own folder, then the including files' folders).
                let path = self.resolve_here(&name).map_err(|searched| {
                    SceneError::at(&attr_loc(file, x, "filename"), format!("cannot read included file \"{name}\": not found"))
                        .with_help(searched_help(&name, &searched))
                })?;
                if self.include_depth > 16 {
                    return Err(SceneError::at(&loc, "includes nested too deeply (a cycle?)"));
                }
                self.includes += 1;
                if self.includes > crate::limits::max_includes() {
                    return Err(SceneError::at(
                        &loc,
                        format!("the scene includes more than {} files in all", crate::limits::max_includes()),
                    )
                    .with_help("raise the limit with the environment variable SNELL_MAX_INCLUDES"));
                }
                let text = std::fs::read_to_string(&path).map_err(|e| {
                    SceneError::at(&attr_loc(file, x, "filename"), format!("cannot read included file {}: {e}", path.display()))
                })?;
                self.include_depth += 1;
                // The included file resolves names from its own folder first;
                // its <path>s apply to itself and the files it includes.
                let mut inner = vec![folder_of(&path)];
                inner.extend(self.folders.iter().cloned());
                let outer = std::mem::replace(&mut self.folders, inner);
                let sub = self.parse_document(Arc::new(SourceFile::with_search(path, text, self.search.clone())));
                self.folders = outer;
                self.include_depth -= 1;
                let sub = sub?;
                out.props.extend(sub.props);
                out.children.extend(sub.children);
            }
            "path" => {
                if out.kind != Kind::Scene {
                    return Err(SceneError::at(&loc, "<path> may only appear directly inside <scene>"));
                }
                self.check_attrs(file, x, &["value"])?;
                let value = self.req_attr(file, x, "value")?;
                // Resolved as an <include> is (so first from the file's
                // earlier <path>s, then its own folder).
                let folder = self.resolve_here(&value).ok().filter(|f| f.is_dir()).ok_or_else(|| {
                    let mut searched = self.folders.clone();
                    searched.push(PathBuf::from("."));
                    SceneError::at(&attr_loc(file, x, "value"), format!("<path>: folder \"{value}\" not found"))
                        .with_help(searched_help(&value, &searched))
                })?;
                self.folders.insert(0, folder.clone());
                // Mitsuba 3.9 resolves meshes and textures with the top-level
                // file's folders only: an included file's <path> does not apply.
                if self.include_depth == 0 {
                    self.search.prepend(folder);
                }
            }
            tag if super::unsupported::element(tag).is_some() => {
                let what = super::unsupported::element(tag).unwrap_or_default();
                return Err(SceneError::at(&loc, format!("<{tag}> elements ({what}) are not supported yet")));
            }
            "integer" | "float" | "boolean" | "string" | "rgb" | "spectrum" | "point" | "vector" | "transform" => {
                let prop = self.parse_property(file, x, out)?;
                if out.kind == Kind::Scene {
                    return Err(SceneError::at(&prop.loc, format!("<{tag}> properties are not allowed directly inside <scene>")));
                }
                if let Some(prev) = out.props.iter().find(|p| p.name == prop.name) {
                    return Err(SceneError::at(
                        &prop.loc,
                        format!("property \"{}\" is given twice (first at line {})", prop.name, prev.loc.line),
                    ));
                }
                out.props.push(prop);
            }
            _ => {
                let mut valid: Vec<&str> = Kind::ALL.iter().filter(|k| **k != Kind::Scene).map(|k| k.tag()).collect();
                valid.extend([
                    "ref", "default", "include", "path", "integer", "float", "boolean", "string", "rgb", "spectrum", "point", "vector",
                    "transform",
                ]);
                return Err(SceneError::at(&loc, format!("unknown element <{tag}>")).with_choices(&valid));
            }
        }
        Ok(())
    }

    fn parse_property(&self, file: &Arc<SourceFile>, x: &XNode, parent: &Node) -> Result<Prop> {
        let tag = x.tag_name().name();
        let loc = loc_of(file, x);
        let name = self.name_attr(file, x, parent)?.ok_or_else(|| SceneError::at(&loc, format!("<{tag}> needs a \"name\" attribute")))?;
        let num = |attr: &str| -> Result<f64> {
            let s = self.req_attr(file, x, attr)?;
            parse_f64(&s).ok_or_else(|| {
                SceneError::at(&attr_loc(file, x, attr), format!("\"{s}\" is not a number (in <{tag} name=\"{name}\">)"))
            })
        };
        let value = match tag {
            "integer" => {
                self.check_attrs(file, x, &["name", "value"])?;
                let s = self.req_attr(file, x, "value")?;
                let v = s.trim().parse::<i64>().map_err(|_| {
                    SceneError::at(&attr_loc(file, x, "value"), format!("\"{s}\" is not an integer (in <integer name=\"{name}\">)"))
                })?;
                Value::Integer(v)
            }
            "float" => {
                self.check_attrs(file, x, &["name", "value"])?;
                Value::Float(num("value")?)
            }
            "boolean" => {
                self.check_attrs(file, x, &["name", "value"])?;
                let s = self.req_attr(file, x, "value")?;
                match s.trim().to_ascii_lowercase().as_str() {
                    "true" => Value::Boolean(true),
                    "false" => Value::Boolean(false),
                    _ => {
                        return Err(SceneError::at(&attr_loc(file, x, "value"), format!("\"{s}\" is not a boolean"))
                            .with_choices(&["true", "false"]));
                    }
                }
            }
            "string" => {
                self.check_attrs(file, x, &["name", "value"])?;
                Value::String(self.req_attr(file, x, "value")?)
            }
            "rgb" => {
                self.check_attrs(file, x, &["name", "value"])?;
                let s = self.req_attr(file, x, "value")?;
                let v = parse_list(&s).filter(|v| v.len() == 3 || v.len() == 1).ok_or_else(|| {
                    SceneError::at(&attr_loc(file, x, "value"), format!("\"{s}\" is not an RGB value (three numbers, or one)"))
                })?;
                let c = if v.len() == 1 { [v[0] as f32; 3] } else { [v[0] as f32, v[1] as f32, v[2] as f32] };
                Value::Rgb(c)
            }
            "spectrum" if x.attribute("type").is_some() => {
                self.check_attrs(file, x, &["name", "type"])?;
                let plugin = self.req_attr(file, x, "type")?;
                Value::SpectrumPlugin(Arc::new(self.parse_spectrum_plugin(file, x, &plugin, parent)?))
            }
            "spectrum" => {
                self.check_attrs(file, x, &["name", "value"])?;
                let s = self.req_attr(file, x, "value")?;
                match parse_list(&s) {
                    Some(v) if v.len() == 1 => Value::Spectrum(v[0] as f32),
                    _ => match parse_spectrum_pairs(&s) {
                        Some(pairs) => Value::SpectrumList(pairs),
                        None => {
                            return Err(SceneError::at(
                                &attr_loc(file, x, "value"),
                                format!("spectrum \"{s}\" is neither a constant nor a list of wavelength:value pairs"),
                            )
                            .with_help("e.g. value=\"0.5\" or value=\"400:0.1, 500:0.4, 600:0.8\" (wavelengths in nm, increasing)"));
                        }
                    },
                }
            }
            "point" | "vector" => {
                self.check_attrs(file, x, &["name", "value", "x", "y", "z"])?;
                let v = self.parse_xyz(file, x, 0.0)?;
                if tag == "point" { Value::Point(v) } else { Value::Vector(v) }
            }
            "transform" => {
                self.check_attrs(file, x, &["name"])?;
                Value::Transform(self.parse_transform(file, x)?)
            }
            _ => return Err(SceneError::at(&loc, format!("<{tag}> is not a property type"))),
        };
        if !value_is_finite(&value) {
            return Err(SceneError::at(&loc, format!("property \"{name}\" is not finite")));
        }
        Ok(Prop { name, value, loc })
    }

    /// `<spectrum type="…">`: one of Mitsuba's spectrum plugins, its
    /// parameters nested as properties (see `spectrum/plugins.rs`).
    fn parse_spectrum_plugin(&self, file: &Arc<SourceFile>, x: &XNode, plugin: &str, parent: &Node) -> Result<SpectrumPlugin> {
        let loc = loc_of(file, x);
        let params = crate::spectrum::plugins::parameters(plugin).ok_or_else(|| {
            SceneError::at(&attr_loc(file, x, "type"), format!("unknown spectrum plugin \"{plugin}\"")).with_choices(&crate::spectrum::plugins::NAMES)
        })?;
        let mut props: Vec<Prop> = vec![];
        for c in x.children() {
            if c.is_comment() || c.is_text() && c.text().unwrap_or("").trim().is_empty() {
                continue;
            }
            let at = loc_of(file, &c);
            if !c.is_element() {
                return Err(SceneError::at(&at, "unexpected text inside <spectrum>"));
            }
            let tag = c.tag_name().name();
            if !matches!(tag, "float" | "integer" | "string" | "rgb" | "boolean") {
                return Err(SceneError::at(&at, format!("<{tag}> cannot be a parameter of <spectrum type=\"{plugin}\">"))
                    .with_choices(&["float", "integer", "string", "rgb", "boolean"]));
            }
            let prop = self.parse_property(file, &c, parent)?;
            if !params.contains(&prop.name.as_str()) {
                return Err(SceneError::at(&prop.loc, format!("unknown parameter \"{}\" of <spectrum type=\"{plugin}\">", prop.name))
                    .with_choices(params));
            }
            if let Some(prev) = props.iter().find(|p| p.name == prop.name) {
                return Err(SceneError::at(&prop.loc, format!("parameter \"{}\" is given twice (first at line {})", prop.name, prev.loc.line)));
            }
            props.push(prop);
        }
        let find = |name: &str| props.iter().find(|p| p.name == name);
        let missing = |name: &str| SceneError::at(&loc, format!("<spectrum type=\"{plugin}\"> needs the parameter \"{name}\""));
        let wrong = |p: &Prop, what: &str| {
            SceneError::at(&p.loc, format!("parameter \"{}\" of <spectrum type=\"{plugin}\"> must be {what}, not {}", p.name, p.value.type_name()))
        };
        let float = |name: &str, default: Option<f32>| -> Result<f32> {
            match find(name) {
                Some(Prop { value: Value::Float(v), .. }) => Ok(*v as f32),
                Some(Prop { value: Value::Integer(v), .. }) => Ok(*v as f32),
                Some(p) => Err(wrong(p, "a float")),
                None => default.ok_or_else(|| missing(name)),
            }
        };
        let list = |name: &str| -> Result<Vec<f32>> {
            match find(name) {
                Some(p @ Prop { value: Value::String(s), .. }) => parse_list(s)
                    .map(|v| v.into_iter().map(|x| x as f32).collect::<Vec<f32>>())
                    .filter(|v| v.iter().all(|x| x.is_finite()))
                    .ok_or_else(|| SceneError::at(&p.loc, format!("\"{s}\" is not a list of numbers (in \"{name}\")"))),
                Some(p) => Err(wrong(p, "a string of numbers")),
                None => Err(missing(name)),
            }
        };
        let color = |name: &str| -> Result<Option<Rgb>> {
            match find(name) {
                Some(Prop { value: Value::Rgb(c), .. }) => Ok(Some(Rgb(*c))),
                Some(Prop { value: Value::Float(v), .. }) => Ok(Some(Rgb([*v as f32; 3]))),
                Some(p) => Err(wrong(p, "an rgb colour")),
                None => Ok(None),
            }
        };
        let range = |name_min: &str, name_max: &str| -> Result<(f32, f32)> {
            let (lo, hi) = (float(name_min, Some(360.0))?, float(name_max, Some(830.0))?);
            if !(lo > 0.0 && lo < hi) {
                let at = find(name_min).or(find(name_max)).map_or(&loc, |p| &p.loc);
                return Err(SceneError::at(at, format!("<spectrum type=\"{plugin}\">: wavelength range [{lo}, {hi}] nm is empty or not positive")));
            }
            Ok((lo, hi))
        };
        let bad = |what: String| SceneError::at(&loc, what);
        Ok(match plugin {
            "uniform" => {
                // Mitsuba reads the range; it bounds only its wavelength sampling.
                range("wavelength_min", "wavelength_max")?;
                SpectrumPlugin::Uniform { value: float("value", None)? }
            }
            "regular" => {
                let (lo, hi) = (float("wavelength_min", None)?, float("wavelength_max", None)?);
                let values = list("values")?;
                SpectrumPlugin::regular(lo, hi, &values).ok_or_else(|| {
                    bad(format!("<spectrum type=\"regular\"> needs 0 < wavelength_min < wavelength_max (here {lo}, {hi}) and two or more values (here {})", values.len()))
                })?
            }
            "irregular" => {
                let (wavelengths, values) = (list("wavelengths")?, list("values")?);
                SpectrumPlugin::irregular(&wavelengths, &values).ok_or_else(|| {
                    bad(format!(
                        "<spectrum type=\"irregular\"> needs as many values as wavelengths (here {} and {}), at least two, wavelengths positive and increasing",
                        values.len(),
                        wavelengths.len()
                    ))
                })?
            }
            "blackbody" => {
                let temperature = float("temperature", None)?;
                let (lo, hi) = range("wavelength_min", "wavelength_max")?;
                SpectrumPlugin::blackbody(temperature, lo, hi)
                    .ok_or_else(|| bad(format!("<spectrum type=\"blackbody\">: temperature must be positive (kelvin), not {temperature}")))?
            }
            "d65" => {
                let scale = float("scale", Some(1.0))?;
                let color = color("color")?.unwrap_or(Rgb::WHITE);
                if scale < 0.0 || color.0.iter().any(|&c| c < 0.0) {
                    return Err(bad("<spectrum type=\"d65\">: colour and scale must not be negative".to_string()));
                }
                SpectrumPlugin::D65 { color, scale }
            }
            _ => {
                let color = color("color")?.ok_or_else(|| missing("color"))?;
                let unbounded = match find("unbounded") {
                    Some(Prop { value: Value::Boolean(b), .. }) => *b,
                    Some(p) => return Err(wrong(p, "a boolean")),
                    None => false,
                };
                let (lo, hi) = if unbounded { (0.0, f32::INFINITY) } else { (0.0, 1.0) };
                if color.0.iter().any(|&c| !(c >= lo && c <= hi)) {
                    let at = find("color").map_or(&loc, |p| &p.loc);
                    return Err(SceneError::at(at, format!("<spectrum type=\"srgb\">: colour {:?} must lie in [0, 1]", color.0))
                        .with_help("add <boolean name=\"unbounded\" value=\"true\"/> for a colour above one"));
                }
                SpectrumPlugin::Srgb { color, unbounded }
            }
        })
    }

    /// A 3-vector from `value="x, y, z"` or from x/y/z attributes (missing ones
    /// take `default`).
    fn parse_xyz(&self, file: &Arc<SourceFile>, x: &XNode, default: f32) -> Result<Vec3> {
        if let Some(s) = self.attr(file, x, "value")? {
            let v = parse_list(&s).filter(|v| v.len() == 3 || v.len() == 1).ok_or_else(|| {
                SceneError::at(&attr_loc(file, x, "value"), format!("\"{s}\" is not a 3-vector (three numbers)"))
            })?;
            return Ok(if v.len() == 1 { Vec3::splat(v[0] as f32) } else { Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32) });
        }
        let mut out = [default; 3];
        for (i, a) in ["x", "y", "z"].iter().enumerate() {
            if let Some(s) = self.attr(file, x, a)? {
                out[i] = parse_f64(&s)
                    .ok_or_else(|| SceneError::at(&attr_loc(file, x, a), format!("\"{s}\" is not a number")))?
                    as f32;
            }
        }
        Ok(Vec3::from_array(out))
    }

    fn vec_attr(&self, file: &Arc<SourceFile>, x: &XNode, name: &str) -> Result<Vec3> {
        let s = self.req_attr(file, x, name)?;
        parse_list(&s)
            .filter(|v| v.len() == 3)
            .map(|v| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32))
            .ok_or_else(|| SceneError::at(&attr_loc(file, x, name), format!("\"{s}\" is not a 3-vector (three numbers)")))
    }

    /// Transform operations, each applied after the ones before it
    /// (Mitsuba: `M = op · M` in document order).
    fn parse_transform(&self, file: &Arc<SourceFile>, x: &XNode) -> Result<Transform> {
        let mut m = Transform::IDENTITY;
        for op in x.children() {
            if op.is_text() && op.text().unwrap_or("").trim().is_empty() || op.is_comment() {
                continue;
            }
            let loc = loc_of(file, &op);
            if !op.is_element() {
                return Err(SceneError::at(&loc, "unexpected text inside <transform>"));
            }
            let tag = op.tag_name().name();
            let degenerate = || SceneError::at(&loc, format!("<{tag}> gives a degenerate (non-invertible) transform"));
            let t = match tag {
                "translate" => {
                    self.check_attrs(file, &op, &["value", "x", "y", "z"])?;
                    Transform::from_matrix(Mat4::from_translation(self.parse_xyz(file, &op, 0.0)?)).ok_or_else(degenerate)?
                }
                "scale" => {
                    self.check_attrs(file, &op, &["value", "x", "y", "z"])?;
                    Transform::from_matrix(Mat4::from_scale(self.parse_xyz(file, &op, 1.0)?)).ok_or_else(degenerate)?
                }
                "rotate" => {
                    self.check_attrs(file, &op, &["value", "x", "y", "z", "angle"])?;
                    let axis = self.parse_xyz(file, &op, 0.0)?;
                    let s = self.req_attr(file, &op, "angle")?;
                    let angle = parse_f64(&s)
                        .ok_or_else(|| SceneError::at(&attr_loc(file, &op, "angle"), format!("\"{s}\" is not a number")))?;
                    Transform::rotate(axis, angle as f32)
                        .ok_or_else(|| SceneError::at(&loc, "<rotate> needs a non-zero axis (x, y, z or value)"))?
                }
                "matrix" => {
                    self.check_attrs(file, &op, &["value"])?;
                    let s = self.req_attr(file, &op, "value")?;
                    let v = parse_list(&s).filter(|v| v.len() == 16 || v.len() == 9).ok_or_else(|| {
                        SceneError::at(&attr_loc(file, &op, "value"), "a matrix needs 16 numbers (row-major 4×4) or 9 (3×3)")
                    })?;
                    let f: Vec<f32> = v.iter().map(|&x| x as f32).collect();
                    let mat = if f.len() == 16 {
                        Mat4::from_cols_array(&[
                            f[0], f[4], f[8], f[12], f[1], f[5], f[9], f[13], f[2], f[6], f[10], f[14], f[3], f[7], f[11], f[15],
                        ])
                    } else {
                        Mat4::from_cols(
                            Vec4::new(f[0], f[3], f[6], 0.0),
                            Vec4::new(f[1], f[4], f[7], 0.0),
                            Vec4::new(f[2], f[5], f[8], 0.0),
                            Vec4::W,
                        )
                    };
                    Transform::from_matrix(mat).ok_or_else(degenerate)?
                }
                "lookat" => {
                    self.check_attrs(file, &op, &["origin", "target", "up"])?;
                    let origin = self.vec_attr(file, &op, "origin")?;
                    let target = self.vec_attr(file, &op, "target")?;
                    let up = if op.attribute("up").is_some() { self.vec_attr(file, &op, "up")? } else { Vec3::Y };
                    Transform::look_at(origin, target, up).ok_or_else(|| {
                        SceneError::at(&loc, "<lookat> is degenerate: origin equals target, or up is parallel to the view direction")
                    })?
                }
                _ => {
                    return Err(SceneError::at(&loc, format!("unknown transform operation <{tag}>"))
                        .with_choices(&["translate", "rotate", "scale", "matrix", "lookat"]));
                }
            };
            m = t.compose(&m);
        }
        Ok(m)
    }
}

/// A version attribute's major number: one to three numbers separated by
/// periods (Mitsuba writes three).
fn parse_version(version: &str) -> Option<u32> {
    let parts: Vec<&str> = version.trim().split('.').collect();
    if parts.is_empty() || parts.len() > 3 || parts.iter().any(|p| p.trim().parse::<u32>().is_err()) {
        return None;
    }
    parts[0].trim().parse().ok()
}

/// "looked for NAME in: …" help for a file not found in `searched`.
fn searched_help(name: &str, searched: &[PathBuf]) -> String {
    let list: Vec<String> = searched.iter().map(|f| format!("\"{}\"", f.display())).collect();
    format!("looked for \"{name}\" in these folders, in order: {}", list.join(", "))
}

/// Mitsuba 3.9's upgrade of a legacy parameter name (`camel_to_underscore_case`):
/// an upper-case letter after a lower-case one becomes `_` and its lower
/// case, and so do the upper-case letters right after it (`toWorld` →
/// `to_world`, `intIOR` → `int_ior`).
pub fn legacy_snake_case(name: &str) -> String {
    let b = name.as_bytes();
    let mut out: Vec<u8> = Vec::with_capacity(b.len() + 4);
    let mut i = 0;
    while i < b.len() {
        if i > 0 && b[i - 1].is_ascii_lowercase() && b[i].is_ascii_uppercase() {
            out.push(b'_');
            out.push(b[i].to_ascii_lowercase());
            while i + 1 < b.len() && b[i + 1].is_ascii_uppercase() {
                i += 1;
                out.push(b[i].to_ascii_lowercase());
            }
        } else {
            out.push(b[i]);
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Mitsuba 3's upgrade of legacy texture offsets and scales: `uoffset`,
/// `voffset`, `uscale`, `vscale` become a `to_uv` transform that translates
/// by the offset, then scales.
fn upgrade_uv_floats(node: &mut Node) {
    const NAMES: [&str; 4] = ["uoffset", "voffset", "uscale", "vscale"];
    let is_uv = |p: &Prop| NAMES.contains(&p.name.as_str()) && matches!(p.value, Value::Float(_) | Value::Integer(_));
    let Some(first) = node.props.iter().find(|p| is_uv(p)).map(|p| p.loc.clone()) else { return };
    let (mut offset, mut scale) = ([0.0f32; 2], [1.0f32; 2]);
    for p in node.props.iter().filter(|p| is_uv(p)) {
        let v = match p.value {
            Value::Float(v) => v,
            Value::Integer(v) => v as f64,
            _ => continue,
        };
        {
            match p.name.as_str() {
                "uoffset" => offset[0] = v as f32,
                "voffset" => offset[1] = v as f32,
                "uscale" => scale[0] = v as f32,
                _ => scale[1] = v as f32,
            }
        }
    }
    node.props.retain(|p| !is_uv(p));
    let m = Mat4::from_scale(Vec3::new(scale[0], scale[1], 1.0)) * Mat4::from_translation(Vec3::new(offset[0], offset[1], 0.0));
    // A zero scale has no inverse; keep the matrix, with the identity as its (unused) inverse.
    let t = Transform::from_matrix(m).unwrap_or(Transform { matrix: m, inverse: Mat4::IDENTITY });
    node.props.push(Prop { name: "to_uv".to_string(), value: Value::Transform(t), loc: first });
}

fn value_is_finite(v: &Value) -> bool {
    match v {
        Value::Float(f) => f.is_finite(),
        Value::Rgb(c) => c.iter().all(|x| x.is_finite()),
        Value::Spectrum(s) => s.is_finite(),
        Value::SpectrumList(v) => v.iter().all(|(l, x)| l.is_finite() && x.is_finite()),
        Value::Point(p) | Value::Vector(p) => p.is_finite(),
        Value::Transform(t) => t.matrix.is_finite(),
        _ => true,
    }
}

fn parse_f64(s: &str) -> Option<f64> {
    s.trim().parse::<f64>().ok()
}

/// Numbers separated by commas and/or white space.
fn parse_list(s: &str) -> Option<Vec<f64>> {
    let v: Option<Vec<f64>> =
        s.split(|c: char| c == ',' || c.is_whitespace()).filter(|t| !t.is_empty()).map(parse_f64).collect();
    v.filter(|v| !v.is_empty())
}

/// `"400:0.1, 500:0.4, …"`: at least two pairs, wavelengths strictly increasing.
fn parse_spectrum_pairs(text: &str) -> Option<Vec<(f32, f32)>> {
    let mut pairs = vec![];
    for item in text.split(',') {
        let (l, v) = item.trim().split_once(':')?;
        let (l, v) = (l.trim().parse::<f32>().ok()?, v.trim().parse::<f32>().ok()?);
        if !(l.is_finite() && v.is_finite() && l > 0.0) || pairs.last().is_some_and(|&(prev, _)| l <= prev) {
            return None;
        }
        pairs.push((l, v));
    }
    (pairs.len() >= 2).then_some(pairs)
}

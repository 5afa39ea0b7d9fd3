//! Stage 3 of scene loading: nodes → a renderable [`Scene`]. One factory per
//! kind of object (`shape`, `bsdf`, `texture`, `emitter`, `sensor`, `film`,
//! `rfilter`, `sampler`, `integrator`), each matching on the plugin name and
//! listing the valid names when it does not know one.

use super::error::{Result, SceneError};
use super::props::Props;
use super::xml::{self, Child, ChildTarget, Kind, Node};
use super::Scene;
use crate::bsdf::{BlendBsdf, Bsdf, BumpMap, Conductor, Dielectric, Diffuse, Mask, NormalMap, Null, Plastic, Polarizer, Retarder, ThinDielectric, TwoSided};
use crate::emitter::{AreaLight, ConstantLight, DirectionalLight, Emitter, EnvironmentMap, PointLight, Projector, SpotLight};
use crate::film::{FilmSpec, Filter, FilterKind, PixelFormat};
use crate::geometry::accel::Accel;
use crate::geometry::curve::{CurveKind, Curves};
use crate::geometry::cylinder::Cylinder;
use crate::geometry::disk::Disk;
use crate::geometry::mesh::Mesh;
use crate::geometry::sdfgrid::{SdfGrid, SdfNormals};
use crate::geometry::mesh_io;
use crate::geometry::serialized;
use crate::geometry::sphere::Sphere;
use crate::geometry::{Shape, ShapeGeometry};
use crate::emitter::{LightSampling, LightSelector};
use crate::integrator::{Aov, AovKind, Bdpt, Direct, Integrator, Moment, ParticleTracer, PathTracer, Sppm, Vcm, VcmMode};
use crate::integrator::sppm::Photons as SppmPhotons;
use crate::math::Transform;
use crate::sampler::SamplerSpec;
use crate::sensor::perspective::{focal_length_fov, horizontal_fov, parse_focal_length};
use crate::sensor::{Camera, Distant, DistantTarget, IrradianceMeter, Orthographic, Perspective, RadianceMeter, ThinLens};
use crate::spectrum::{Emission, Rgb};
use crate::texture::bitmap::{self, Bitmap};
use crate::texture::{Checkerboard, MeshAttributeTexture, Texture, uv_transform};
use glam::{Mat4, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub const SHAPES: [&str; 14] = [
    "rectangle", "cube", "disk", "sphere", "cylinder", "obj", "ply", "serialized", "linearcurve", "bsplinecurve", "sdfgrid", "shapegroup", "instance", "merge",
];
pub const BSDFS: [&str; 20] = [
    "birefringent", "blendbsdf", "bumpmap", "conductor", "dielectric", "diffuse", "mask", "normalmap", "null", "plastic", "polarizer", "pplastic",
    "principled", "principledthin", "retarder",
    "roughconductor", "roughdielectric", "roughplastic", "thindielectric", "twosided",
];
pub const TEXTURES: [&str; 4] = ["bitmap", "checkerboard", "mesh_attribute", "rawconstant"];
pub const EMITTERS: [&str; 7] = ["area", "point", "spot", "constant", "directional", "envmap", "projector"];
pub const SENSORS: [&str; 6] = ["perspective", "orthographic", "thinlens", "radiancemeter", "irradiancemeter", "distant"];
pub const FILMS: [&str; 1] = ["hdrfilm"];
pub const RFILTERS: [&str; 6] = ["box", "tent", "gaussian", "mitchell", "catmullrom", "lanczos"];
pub const SAMPLERS: [&str; 7] = crate::sampler::NAMES;
pub const INTEGRATORS: [&str; 15] =
    ["direct", "path", "ptracer", "bdpt", "sppm", "stokes", "aov", "moment", "vcm", "volpath", "volpathmis", "prbvolpath", "prb", "prb_basic", "depth"];
pub const MEDIA: [&str; 2] = ["homogeneous", "heterogeneous"];
pub const PHASES: [&str; 5] = ["isotropic", "hg", "rayleigh", "tabphase", "blendphase"];
pub const VOLUMES: [&str; 2] = ["constvolume", "gridvolume"];

/// The most samples per pixel, from the scene or from `--spp` (Mitsuba's
/// sample counts are 32-bit; 2^24 keeps per-pixel sums exact in f32 weights).
pub const MAX_SPP: u32 = 1 << 24;

/// A warning located at `loc`: "warning: MESSAGE (at FILE:LINE:COL)".
fn located_warning(loc: &super::Location, message: &str) -> String {
    format!("warning: {message} (at {}:{}:{})", loc.file.path.display(), loc.line, loc.col)
}

/// The smallest and largest value a texture takes (over texels, colours and
/// listed spectrum samples).
fn texture_range(t: &Texture) -> (f32, f32) {
    let fold = |vals: &mut dyn Iterator<Item = f32>| vals.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    match t {
        Texture::Constant(c, _) => fold(&mut c.0.into_iter()),
        Texture::Spectral { spectrum, .. } => fold(&mut spectrum.samples().iter().map(|&(_, v)| v)),
        Texture::Bitmap(b) => fold(&mut b.texels.iter().flat_map(|t| t.0)),
        Texture::Checkerboard(c) => fold(&mut c.color0.0.into_iter().chain(c.color1.0)),
        // Its values come from a mesh resolved after the material: not
        // checked here.
        Texture::MeshAttribute(_) => (0.0, 0.0),
    }
}

/// What the command line can override.
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// `-D name=value` parameters.
    pub params: HashMap<String, String>,
    /// Samples per pixel, overriding the scene's sampler.
    pub spp: Option<u32>,
    /// Seed, overriding the scene's sampler.
    pub seed: Option<u64>,
}

pub fn load_file(path: &Path, options: &LoadOptions) -> Result<Scene> {
    let root = xml::parse_file(path, &options.params)?;
    Loader::new(&root)?.build(&root, options)
}

/// As [`load_file`], with the film made `width` pixels wide and its height
/// scaled to keep the aspect ratio (rounded, at least 1; any crop window
/// reset to the whole film): quick low-resolution renders of scenes whose
/// film size is fixed in the file.
pub fn load_file_at_width(path: &Path, options: &LoadOptions, width: u32) -> Result<Scene> {
    let root = xml::parse_file(path, &options.params)?;
    let mut loader = Loader::new(&root)?;
    loader.film_width = Some(width.max(1));
    loader.build(&root, options)
}

/// Loads scene text; relative file names resolve against `path`'s folder.
pub fn load_str(path: &Path, text: &str, options: &LoadOptions) -> Result<Scene> {
    let root = xml::parse_str(path, text, &options.params)?;
    Loader::new(&root)?.build(&root, options)
}

/// What a plugin's `from_props` may ask of the loader: its texture
/// parameters and its nested BSDFs (which need the scene's ids).
pub trait PluginLoader {
    /// A colour parameter: `rgb`/`spectrum`/`float`, or a nested (or
    /// referenced) texture; `default` if absent.
    fn texture(&self, props: &Props, name: &str, default: Rgb) -> Result<Texture>;
    /// As [`PluginLoader::texture`], for a reflectance or transmittance: a
    /// negative value is an error, a value above one a warning naming the
    /// parameter.
    fn reflectance(&self, props: &Props, name: &str, default: Rgb) -> Result<Texture>;
    /// The nested (inline or referenced, unnamed) BSDFs of `props`' node, built.
    fn nested_bsdfs(&self, props: &Props) -> Result<Vec<(Arc<Node>, Bsdf)>>;
    /// The nested inline textures of `props`' node, whatever their names, built.
    fn nested_textures(&self, props: &Props) -> Result<Vec<(Arc<Node>, Texture)>>;
}

impl PluginLoader for Loader {
    fn texture(&self, props: &Props, name: &str, default: Rgb) -> Result<Texture> {
        self.texture_input(props, name, default)
    }

    fn reflectance(&self, props: &Props, name: &str, default: Rgb) -> Result<Texture> {
        self.reflectance_input(props, name, default)
    }

    fn nested_bsdfs(&self, props: &Props) -> Result<Vec<(Arc<Node>, Bsdf)>> {
        let mut nested = self.nested(props, Kind::Bsdf)?;
        for r in props.unnamed_refs() {
            let t = self.resolve(r)?;
            if t.kind != Kind::Bsdf {
                return Err(SceneError::at(&r.loc, format!("{} takes BSDFs, not a <{}>", props.node.plugin, t.kind.tag())));
            }
            nested.push(t);
        }
        nested.into_iter().map(|n| self.make_bsdf(&n).map(|b| (n, b))).collect()
    }

    fn nested_textures(&self, props: &Props) -> Result<Vec<(Arc<Node>, Texture)>> {
        let nested = self.nested(props, Kind::Texture)?;
        nested.into_iter().map(|n| self.texture(&n).map(|t| (n, t))).collect()
    }
}

struct Loader {
    /// Warnings for the user (reflectance above one, clamped values), each
    /// naming the parameter and where it is.
    warnings: std::cell::RefCell<Vec<String>>,
    ids: HashMap<String, Arc<Node>>,
    bsdf_cache: HashMap<*const Node, u32>,
    bsdfs: Vec<Bsdf>,
    /// Participating media, each built once however many shapes name it.
    media: Vec<crate::medium::Medium>,
    medium_cache: HashMap<*const Node, u32>,
    shapes: Vec<Shape>,
    emitters: Vec<Emitter>,
    environment: Option<u32>,
    /// Shapes traced directly (the others belong to shape groups).
    top_shapes: Vec<u32>,
    /// Members (shape indices) of each `shapegroup`, its index by node.
    groups: Vec<Vec<u32>>,
    group_index: HashMap<*const Node, u32>,
    /// `instance`s: group-to-world transform and group.
    instances: Vec<(Transform, u32)>,
    /// Building the members of a shape group.
    in_group: bool,
    /// A sensor nested in a shape (an irradiance meter) and the shape's index.
    shape_sensor: Option<(Arc<Node>, u32)>,
    /// `mesh_attribute` textures, resolved against the meshes once all
    /// are loaded, with the location of their `name`.
    mesh_attribute_textures: std::cell::RefCell<Vec<(Arc<MeshAttributeTexture>, super::Location)>>,
    /// Film width forced by [`load_file_at_width`].
    film_width: Option<u32>,
    /// The `light_sampling` an integrator named explicitly (the default
    /// depends on the integrator).
    light_sampling: std::cell::Cell<Option<LightSampling>>,
    /// Something reads texture coordinates: a bitmap or checkerboard
    /// texture, or a `uv` AOV ([`Shape::reads_uv`]).
    reads_uv: std::cell::Cell<bool>,
    /// The files read besides the scene's XML (meshes, images), in the
    /// order first read: [`Scene::files`].
    files: std::cell::RefCell<Vec<PathBuf>>,
    /// Vertex normals of big meshes computed on their own thread while the
    /// following shapes load and the BVH builds: (shape index, normals).
    pending_normals: std::cell::RefCell<Vec<(usize, std::thread::JoinHandle<Vec<Vec3>>)>>,
}

/// Meshes of at least this many triangles compute their vertex normals on
/// a thread of their own, overlapped with the rest of the load and the
/// BVH build (`Loader::pending_normals`); smaller ones at once.
const OVERLAPPED_NORMALS_MIN: usize = 1 << 16;

fn collect_ids(node: &Node, ids: &mut HashMap<String, Arc<Node>>) -> Result<()> {
    for c in &node.children {
        if let ChildTarget::Inline(n) = &c.target {
            if let Some(id) = &n.id {
                if let Some(prev) = ids.get(id) {
                    return Err(SceneError::at(&n.loc, format!("id \"{id}\" is used twice (first at line {})", prev.loc.line)));
                }
                ids.insert(id.clone(), n.clone());
            }
            collect_ids(n, ids)?;
        }
    }
    Ok(())
}

/// Where a file name written in the scene is read from: the first of the
/// document's search folders that holds it (`<path>` folders, the scene's
/// folder, the working directory; see [`super::search`]).
fn resolve_path(node: &Node, name: &str) -> PathBuf {
    node.loc.file.search.resolve_or_default(name)
}

/// The XML files other than `top` that elements of `node` come from.
fn included_files(node: &Node, top: &Path, out: &mut Vec<PathBuf>) {
    let path = &node.loc.file.path;
    if path.as_path() != top && !out.contains(path) {
        out.push(path.clone());
    }
    for c in &node.children {
        if let ChildTarget::Inline(n) = &c.target {
            included_files(n, top, out);
        }
    }
}

/// `e` with the folders searched for `name` as help, if no such file exists.
fn with_search_help(e: SceneError, node: &Node, name: &str) -> SceneError {
    match node.loc.file.search.not_found_help(name) {
        Some(help) if e.help.is_none() => e.with_help(help),
        _ => e,
    }
}

/// The horizontal field of view (degrees) of a perspective or thin-lens
/// sensor, as Mitsuba's `parse_fov`: `fov` along `fov_axis`, or else
/// `focal_length` (default `50mm`, 35 mm film equivalent, on the diagonal).
fn sensor_fov(props: &Props, aspect: f32) -> Result<f32> {
    if props.has("fov") && props.has("focal_length") {
        return Err(props.error_at("focal_length", "give either a field of view (\"fov\") or a focal length (\"focal_length\"), not both"));
    }
    if props.has("fov") {
        let fov = props.float_checked("fov", f32::NAN, |f| f > 0.0 && f < 180.0, "an angle in (0, 180) degrees")?;
        let axis = props.choice("fov_axis", "x", &["x", "y", "smaller", "larger", "diagonal"])?;
        return Ok(horizontal_fov(fov, axis, aspect));
    }
    let given = props.node.props.iter().find(|p| p.name == "focal_length").map(|p| &p.value);
    let mm = match given {
        None => 50.0,
        Some(xml::Value::String(_)) => {
            let text = props.string_req("focal_length")?;
            parse_focal_length(text).ok_or_else(|| {
                props.error_at("focal_length", format!("focal length \"{text}\" is not of the form <x>mm with a positive number x"))
            })?
        }
        Some(_) => props.float_checked("focal_length", 50.0, |f| f > 0.0 && f.is_finite(), "positive (millimetres)")? as f64,
    };
    let fov_x = horizontal_fov(focal_length_fov(mm) as f32, "diagonal", aspect);
    if !(fov_x > 0.0 && fov_x < 180.0) {
        return Err(props.error_at("focal_length", "this focal length gives no valid field of view"));
    }
    Ok(fov_x)
}

fn unknown_plugin(node: &Node, choices: &[&str]) -> SceneError {
    if let Some(what) = super::unsupported::mitsuba3_plugin(node.kind, &node.plugin) {
        return SceneError::at(&node.loc, format!("Mitsuba 3's {} plugin \"{}\" ({what}) is not supported yet", node.kind.tag(), node.plugin))
            .with_choices(choices);
    }
    if let Some(instead) = super::unsupported::removed(node.kind, &node.plugin) {
        return SceneError::at(&node.loc, format!("unknown {} plugin \"{}\" (a Mitsuba 0.6 plugin that Mitsuba 3 removed)", node.kind.tag(), node.plugin))
            .with_help(format!("{instead}; valid choices are: {}", choices.join(", ")));
    }
    SceneError::at(&node.loc, format!("unknown {} plugin \"{}\"", node.kind.tag(), node.plugin)).with_choices(choices)
}

impl Loader {
    fn new(root: &Node) -> Result<Loader> {
        let mut ids = HashMap::new();
        collect_ids(root, &mut ids)?;
        Ok(Loader {
            warnings: Default::default(),
            ids,
            bsdf_cache: HashMap::new(),
            bsdfs: vec![],
            media: vec![],
            medium_cache: HashMap::new(),
            shapes: vec![],
            emitters: vec![],
            environment: None,
            top_shapes: vec![],
            groups: vec![],
            group_index: HashMap::new(),
            instances: vec![],
            in_group: false,
            shape_sensor: None,
            mesh_attribute_textures: Default::default(),
            reads_uv: Default::default(),
            film_width: None,
            light_sampling: Default::default(),
            files: Default::default(),
            pending_normals: Default::default(),
        })
    }

    /// Where a file name written in `node` is read from ([`resolve_path`]),
    /// noted in [`Scene::files`].
    fn input_file(&self, node: &Node, name: &str) -> PathBuf {
        let path = resolve_path(node, name);
        let mut files = self.files.borrow_mut();
        if !files.contains(&path) {
            files.push(path.clone());
        }
        path
    }

    fn resolve(&self, child: &Child) -> Result<Arc<Node>> {
        match &child.target {
            ChildTarget::Inline(n) => Ok(n.clone()),
            ChildTarget::Ref(id) => self.ids.get(id).cloned().ok_or_else(|| {
                let mut known: Vec<&str> = self.ids.keys().map(|s| s.as_str()).collect();
                known.sort();
                let e = SceneError::at(&child.loc, format!("reference to unknown id \"{id}\""));
                if known.is_empty() { e.with_help("no object in this scene has an id") } else { e.with_choices(&known) }
            }),
        }
    }

    /// Nested objects of `kind`: inline ones and unnamed references to that kind.
    fn nested(&self, props: &Props, kind: Kind) -> Result<Vec<Arc<Node>>> {
        let mut out = vec![];
        for c in &props.node.children {
            match &c.target {
                ChildTarget::Inline(n) if n.kind == kind => out.push(n.clone()),
                _ => {}
            }
        }
        props.children_of(kind);
        Ok(out)
    }

    fn build(mut self, root: &Node, options: &LoadOptions) -> Result<Scene> {
        let mut sensor: Option<(Camera, FilmSpec, SamplerSpec)> = None;
        let mut integrator: Option<Integrator> = None;
        let mut integrator_loc: Option<super::Location> = None;
        let mut stokes_requested = false;
        for child in &root.children {
            let node = match &child.target {
                ChildTarget::Inline(n) => n.clone(),
                ChildTarget::Ref(_) => {
                    return Err(SceneError::at(&child.loc, "a <ref> may not appear directly inside <scene>"));
                }
            };
            // Declared at the top level only to be referenced by id (as
            // Mitsuba allows): an area emitter that shapes <ref>, a film,
            // sampler or filter that a sensor <ref>s.
            let for_reference = matches!(node.kind, Kind::Film | Kind::Sampler | Kind::Rfilter)
                || (node.kind == Kind::Emitter && node.plugin == "area")
                || node.kind == Kind::Medium;
            if for_reference && node.id.is_some() {
                continue;
            }
            match node.kind {
                Kind::Shape => self.shape(&node)?,
                Kind::Bsdf => {
                    self.bsdf(&node)?;
                }
                Kind::Texture => {
                    self.texture(&node)?;
                }
                Kind::Emitter => self.top_level_emitter(&node)?,
                Kind::Sensor => {
                    if sensor.is_some() {
                        return Err(SceneError::at(&node.loc, "the scene has more than one <sensor>; Snell renders exactly one"));
                    }
                    sensor = Some(self.sensor(&node, None)?);
                }
                Kind::Integrator => {
                    if integrator.is_some() {
                        return Err(SceneError::at(&node.loc, "the scene has more than one <integrator>"));
                    }
                    let (inner, stokes) = self.integrator(&node)?;
                    integrator = Some(inner);
                    stokes_requested = stokes;
                    integrator_loc = Some(node.loc.clone());
                }
                Kind::Film | Kind::Sampler | Kind::Rfilter => {
                    return Err(SceneError::at(&node.loc, format!("<{}> belongs inside a <sensor>", node.kind.tag())));
                }
                Kind::Medium => {
                    // Unnamed and so unused; built for its errors.
                    self.medium(&node)?;
                }
                Kind::Phase | Kind::Volume => {
                    return Err(SceneError::at(&node.loc, format!("<{}> belongs inside a <medium>", node.kind.tag())));
                }
                Kind::Scene => return Err(SceneError::at(&node.loc, "nested <scene> elements are not allowed")),
            }
        }
        let sensor = match (sensor, self.shape_sensor.clone()) {
            (Some(_), Some((meter, _))) => {
                return Err(SceneError::at(&meter.loc, "the scene has more than one <sensor> (this one in a shape, and one at the top); Snell renders exactly one"));
            }
            (None, Some((meter, shape))) => {
                let shape = self.shapes[shape as usize].clone();
                Some(self.sensor(&meter, Some(&shape))?)
            }
            (sensor, None) => sensor,
        };
        let (mut camera, film, mut sampler) =
            sensor.ok_or_else(|| SceneError::at(&root.loc, "the scene has no <sensor>").with_help("add e.g. <sensor type=\"perspective\">…</sensor>"))?;
        if let Some(spp) = options.spp {
            if !(1..=MAX_SPP).contains(&spp) {
                return Err(SceneError::file(&root.loc.file.path, format!("the sample count {spp} is not between 1 and {MAX_SPP} (2^24)")));
            }
            sampler.set_sample_count(spp);
        }
        if let Some(seed) = options.seed {
            sampler.seed = seed;
        }
        let integrator =
            integrator.unwrap_or(Integrator::Path(PathTracer { max_depth: u32::MAX, rr_depth: 5, hide_emitters: false, emitter_samples: 1, bsdf_samples: 1, guiding: None, reuse_pixels: 1 }));
        if let Integrator::Sppm(sppm) = &integrator {
            if sppm.max_passes > 0 && options.spp.is_none() {
                sampler.set_sample_count(sppm.max_passes);
            }
        }
        if let (Integrator::Particle(_), Some(loc)) = (&integrator, &integrator_loc) {
            // A light path must start somewhere finite and end in a pinhole.
            if !matches!(camera, Camera::Perspective(_)) {
                return Err(SceneError::at(loc, "ptracer needs a perspective sensor (light paths cannot be connected to an orthographic, thin-lens, radiancemeter, irradiancemeter or distant sensor)")
                    .with_choices(&["perspective"]));
            }
        }
        if let (Integrator::Vcm(_), Some(loc)) = (&integrator, &integrator_loc) {
            if !matches!(camera, Camera::Perspective(_)) {
                return Err(SceneError::at(loc, "vcm needs a perspective sensor (light subpaths cannot be connected to an orthographic, thin-lens, radiancemeter, irradiancemeter or distant sensor)")
                    .with_choices(&["perspective"]));
            }
            if self.emitters.iter().any(|e| matches!(e, Emitter::Projector(_))) {
                return Err(SceneError::at(loc, "vcm cannot use a \"projector\" emitter (no density for its emitted directions); use path or ptracer")
                    .with_choices(&["area", "point", "spot", "constant", "envmap", "directional"]));
            }
        }
        if let (Integrator::Bdpt(_), Some(loc)) = (&integrator, &integrator_loc) {
            // Light subpaths end in a pinhole.
            if !matches!(camera, Camera::Perspective(_)) {
                return Err(SceneError::at(loc, "bdpt needs a perspective sensor (light subpaths cannot be connected to an orthographic, thin-lens, radiancemeter, irradiancemeter or distant sensor)")
                    .with_choices(&["perspective"]));
            }
            if self.emitters.iter().any(|e| matches!(e, Emitter::Projector(_))) {
                return Err(SceneError::at(loc, "bdpt cannot use a \"projector\" emitter (no density for its emitted directions); use path or ptracer")
                    .with_choices(&["area", "point", "spot", "constant", "envmap", "directional"]));
            }
        }
        let reads_uv = self.reads_uv.get();
        for s in &mut self.shapes {
            s.reads_uv = reads_uv;
        }
        let mut accel = Accel::build_instanced(&self.shapes, &self.top_shapes, &self.groups, &self.instances);
        // The vertex normals computed meanwhile, before the meshes are
        // renumbered below.
        for (si, job) in self.pending_normals.take() {
            let normals = job.join().map_err(|_| SceneError::file(&root.loc.file.path, "computing a mesh's vertex normals failed"))?;
            if let ShapeGeometry::Mesh(m) = &mut self.shapes[si].geometry {
                m.set_vertex_normals(normals);
            }
        }
        // Big meshes renumbered in the BVH's leaf order, before the mesh
        // attribute tables and the emitters' samplers read them.
        accel.store_meshes_in_leaf_order(&mut self.shapes);
        self.resolve_mesh_attributes()?;
        if let Camera::Distant(d) = &mut camera {
            let (lo, hi) = accel.bounds(&self.shapes);
            d.set_bounds(lo, hi);
        }
        // The meter samples its shape as rendered (vertex normals computed).
        if let (Camera::IrradianceMeter(meter), Some((_, shape))) = (&mut camera, &self.shape_sensor) {
            meter.shape = Arc::new(self.shapes[*shape as usize].clone());
        }
        // Unless the integrator names one: bvh, or for light paths (which
        // start with no shading point to weigh emitters by) power.
        let light_sampling = self.light_sampling.get().unwrap_or(match integrator {
            Integrator::Particle(_) => LightSampling::DEFAULT_LIGHT_PATHS,
            _ => LightSampling::DEFAULT,
        });
        for e in &mut self.emitters {
            if let Emitter::Area(a) = e {
                a.find_rectangle(&self.shapes);
            }
        }
        let lights = LightSelector::new(light_sampling, &self.emitters, &self.shapes);
        if !self.media.is_empty() && !integrator.renders_media() {
            let named = self.shapes.iter().any(|s| s.interior.is_some() || s.exterior.is_some());
            if named {
                self.warnings.borrow_mut().push(format!(
                    "warning: {}: the scene has participating media, which only the volpath integrator renders; this integrator renders as if space were empty (as Mitsuba's does)",
                    root.loc.file.path.display()
                ));
            }
        }
        // Included XML files first (every file some element comes from),
        // then the meshes and images in the order read.
        let mut files = vec![];
        included_files(root, &root.loc.file.path, &mut files);
        for f in self.files.take() {
            if !files.contains(&f) {
                files.push(f);
            }
        }
        Ok(Scene {
            bsdfs: self.bsdfs,
            media: self.media,
            camera_medium: None,
            emitters: self.emitters,
            accel,
            camera,
            film,
            sampler,
            integrator,
            stokes_requested,
            environment: self.environment,
            warnings: self.warnings.into_inner(),
            pass_through: self.shapes.iter().any(|s| s.pass_through),
            lights,
            shapes: self.shapes,
            files,
            folder: root.loc.file.path.parent().map(Path::to_path_buf).unwrap_or_default(),
        })
    }

    // ---------------------------------------------------------------- shapes

    fn shape(&mut self, node: &Arc<Node>) -> Result<()> {
        match node.plugin.as_str() {
            "shapegroup" if self.in_group => {
                return Err(SceneError::at(&node.loc, "a shapegroup cannot contain another shapegroup (Mitsuba does not nest them)"));
            }
            "instance" if self.in_group => {
                return Err(SceneError::at(&node.loc, "a shapegroup cannot contain an instance (Mitsuba does not nest instancing)"));
            }
            "shapegroup" => return self.shapegroup(node).map(|_| ()),
            "instance" => return self.instance(node),
            "merge" => return self.merge(node),
            _ => {}
        }
        let props = Props::new(node);
        let to_world = props.transform("to_world")?;
        let flip = props.bool("flip_normals", false)?;
        let geometry = match node.plugin.as_str() {
            "rectangle" => ShapeGeometry::Mesh(Mesh::rectangle(&to_world, flip)),
            "cube" => ShapeGeometry::Mesh(Mesh::cube(&to_world, flip)),
            "disk" => ShapeGeometry::Disk(Disk::new(to_world, flip)),
            "sphere" => ShapeGeometry::Sphere(self.sphere(&props, &to_world, flip)?),
            "cylinder" => {
                let p0 = props.vec3("p0", Vec3::ZERO)?;
                let p1 = props.vec3("p1", Vec3::Z)?;
                let radius = props.float_checked("radius", 1.0, |r| r > 0.0 && r.is_finite(), "positive")?;
                let cylinder = Cylinder::new(&to_world, p0, p1, radius, flip).ok_or_else(|| {
                    let loc = node.props.iter().find(|p| p.name == "to_world").map_or(&node.loc, |p| &p.loc);
                    SceneError::at(loc, "a cylinder needs p0 ≠ p1 and a to_world that keeps it circular (rotation, translation, a scale uniform across its axis — similarity or a stretch along the axis — no shear, no mirror)")
                })?;
                ShapeGeometry::Cylinder(cylinder)
            }
            "obj" | "ply" | "serialized" => ShapeGeometry::Mesh(self.mesh_file(&props, &to_world, flip)?),
            "linearcurve" | "bsplinecurve" => {
                let kind = if node.plugin == "linearcurve" { CurveKind::Linear } else { CurveKind::BSpline };
                let filename = props.string_req("filename")?;
                let path = self.input_file(node, filename);
                let file_loc = node.props.iter().find(|p| p.name == "filename").map_or(&node.loc, |p| &p.loc);
                let curves = Curves::load(&path, &to_world, kind).map_err(|e| with_search_help(SceneError::at(file_loc, e), node, filename))?;
                ShapeGeometry::Curves(curves)
            }
            "sdfgrid" => {
                let normals = props.choice("normals", "smooth", &["smooth", "analytic"])?;
                let normals = SdfNormals::parse(normals).unwrap_or(SdfNormals::Smooth);
                let filename = props.string_req("filename")?;
                let path = self.input_file(node, filename);
                let file_loc = node.props.iter().find(|p| p.name == "filename").map_or(&node.loc, |p| &p.loc);
                let grid = SdfGrid::load(&path, &to_world, normals).map_err(|e| with_search_help(SceneError::at(file_loc, e), node, filename))?;
                ShapeGeometry::SdfGrid(grid)
            }
            _ => return Err(unknown_plugin(node, &SHAPES)),
        };
        let shape_index = self.shapes.len() as u32;

        let mut bsdf_nodes = self.nested(&props, Kind::Bsdf)?;
        let mut emitter_nodes = self.nested(&props, Kind::Emitter)?;
        let sensor_nodes = self.nested(&props, Kind::Sensor)?;
        // `<ref name="bsdf" id="…"/>` (as Blender's exporter and Mitsuba's
        // own scenes write it) is the same as an unnamed reference.
        let named_refs = ["bsdf", "emitter"].into_iter().filter_map(|n| props.child_named(n)).filter(|c| matches!(c.target, ChildTarget::Ref(_)));
        for r in props.unnamed_refs().into_iter().chain(named_refs.collect::<Vec<_>>()) {
            let target = self.resolve(r)?;
            match target.kind {
                Kind::Bsdf => bsdf_nodes.push(target),
                Kind::Emitter => emitter_nodes.push(target),
                k => {
                    return Err(SceneError::at(&r.loc, format!("a shape cannot take a reference to a <{}>", k.tag()))
                        .with_help("a shape takes one <bsdf> and at most one area <emitter>"));
                }
            }
        }
        if bsdf_nodes.len() > 1 {
            return Err(SceneError::at(&bsdf_nodes[1].loc, "a shape takes at most one BSDF"));
        }
        if emitter_nodes.len() > 1 {
            return Err(SceneError::at(&emitter_nodes[1].loc, "a shape takes at most one emitter"));
        }
        if let Some(sensor) = sensor_nodes.first() {
            if sensor.plugin != "irradiancemeter" {
                return Err(SceneError::at(&sensor.loc, format!("a sensor inside a shape must be an irradiancemeter, not \"{}\"", sensor.plugin))
                    .with_choices(&["irradiancemeter"]));
            }
            // The second meter, in this shape or after one in an earlier shape.
            let second = if sensor_nodes.len() > 1 { Some(&sensor_nodes[1]) } else { self.shape_sensor.as_ref().map(|_| sensor) };
            if let Some(second) = second {
                return Err(SceneError::at(&second.loc, "the scene has more than one irradiancemeter; Snell renders exactly one sensor"));
            }
            if self.in_group {
                return Err(SceneError::at(&sensor.loc, "a shape inside a shapegroup cannot carry a sensor (as in Mitsuba)"));
            }
            if matches!(geometry, ShapeGeometry::Curves(_) | ShapeGeometry::SdfGrid(_)) {
                return Err(SceneError::at(&sensor.loc, format!("an irradiancemeter cannot sit on a {}: its surface cannot be sampled by area", node.plugin))
                    .with_help("place the meter on a mesh, sphere, disk, rectangle or cylinder"));
            }
            self.shape_sensor = Some((sensor.clone(), shape_index));
        }
        if let (ShapeGeometry::Curves(_) | ShapeGeometry::SdfGrid(_), Some(e)) = (&geometry, emitter_nodes.first()) {
            return Err(SceneError::at(&e.loc, format!("a {} cannot emit: its surface cannot be sampled by area (nor can Mitsuba's)", node.plugin))
                .with_help("make the light a mesh, sphere, disk, rectangle or cylinder"));
        }
        if let (true, Some(e)) = (self.in_group, emitter_nodes.first()) {
            return Err(SceneError::at(&e.loc, "a shape inside a shapegroup cannot emit: Mitsuba does not support instancing of emitters")
                .with_help("place the emitting shape outside the shapegroup, once per copy"));
        }
        let bsdf = match bsdf_nodes.first() {
            Some(b) => self.bsdf(b)?,
            None => {
                // Mitsuba's default material: diffuse 0.5, but black on an
                // emitter (a light source reflects nothing unless told to).
                let albedo = if emitter_nodes.is_empty() { 0.5 } else { 0.0 };
                self.bsdfs.push(Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(Rgb::new(albedo, albedo, albedo)) }));
                self.bsdfs.len() as u32 - 1
            }
        };
        // A crystal's optic axis is given in the shape's frame: each shape gets its own copy.
        let bsdf = match self.bsdfs[bsdf as usize].placed_on(&to_world) {
            Some(placed) => {
                self.bsdfs.push(placed);
                self.bsdfs.len() as u32 - 1
            }
            None => bsdf,
        };
        let emitter = match emitter_nodes.first() {
            Some(e) => Some(self.area_emitter(e, shape_index)?),
            None => None,
        };
        let tangent_frame = self.bsdfs[bsdf as usize].needs_tangent_frame();
        let pass_through = self.bsdfs[bsdf as usize].passes_through() && emitter.is_none();
        let interior = self.shape_medium(&props, "interior")?;
        let exterior = self.shape_medium(&props, "exterior")?;
        if let (true, Some(_)) = (self.in_group, interior.or(exterior)) {
            return Err(SceneError::at(&node.loc, "a shape inside a shapegroup cannot bound a medium (instances of one medium boundary would share it)"));
        }
        props.finish()?;
        let shape = Shape { geometry, bsdf, emitter, tangent_frame, pass_through, reads_uv: true, interior, exterior };
        let has_area = !matches!(shape.geometry, ShapeGeometry::SdfGrid(_));
        if has_area && (shape.area() <= 0.0 || !shape.area().is_finite()) {
            return Err(SceneError::at(&node.loc, format!("this {} has zero or non-finite surface area", node.plugin)));
        }
        if !self.in_group {
            self.top_shapes.push(self.shapes.len() as u32);
        }
        self.shapes.push(shape);
        Ok(())
    }

    // ----------------------------------------------------------------- media

    /// The medium a shape names as `interior` or `exterior` (inline or by reference).
    fn shape_medium(&mut self, props: &Props, side: &str) -> Result<Option<u32>> {
        let Some(child) = props.child_named(side) else { return Ok(None) };
        let node = self.resolve(child)?;
        if node.kind != Kind::Medium {
            return Err(SceneError::at(&child.loc, format!("a shape's \"{side}\" must be a <medium>, not a <{}>", node.kind.tag())).with_choices(&MEDIA));
        }
        self.medium(&node).map(Some)
    }

    fn medium(&mut self, node: &Arc<Node>) -> Result<u32> {
        let key = Arc::as_ptr(node);
        if let Some(&i) = self.medium_cache.get(&key) {
            return Ok(i);
        }
        let props = Props::new(node);
        if !MEDIA.contains(&node.plugin.as_str()) {
            return Err(unknown_plugin(node, &MEDIA));
        }
        let homogeneous = node.plugin == "homogeneous";
        let sigma_t = self.volume_input(&props, "sigma_t", 1.0)?;
        if homogeneous && !sigma_t.is_constant() {
            let loc = props.child_named("sigma_t").map_or(&node.loc, |c| &c.loc);
            return Err(SceneError::at(loc, "a homogeneous medium's sigma_t is a constant; a grid of densities needs a heterogeneous medium").with_choices(&MEDIA));
        }
        let albedo = self.volume_input(&props, "albedo", 0.75)?;
        if albedo.max > 1.0 {
            self.warnings.borrow_mut().push(located_warning(&node.loc, &format!("the medium's albedo reaches {} (above 1, it creates energy)", albedo.max)));
        }
        let scale = props.float_checked("scale", 1.0, |v| v >= 0.0 && v.is_finite(), "finite and not negative")?;
        let sample_emitters = props.bool("sample_emitters", true)?;
        // Speed hints of Mitsuba's that do not change the image.
        props.bool("has_spectral_extinction", true)?;
        if !homogeneous {
            props.int_checked("majorant_resolution_factor", 0, |v| v >= 0, "not negative")?;
            props.float_checked("majorant_factor", 1.01, |v| v > 0.0, "positive")?;
        }
        let phases = props.children_of(Kind::Phase);
        if phases.len() > 1 {
            return Err(SceneError::at(&phases[1].loc, "a medium takes at most one <phase>"));
        }
        let phase = match phases.first() {
            Some(c) => self.phase(&self.resolve(c)?)?,
            None => crate::medium::PhaseFunction::Isotropic,
        };
        props.finish()?;
        self.media.push(crate::medium::Medium { sigma_t, albedo, scale, phase, sample_emitters, homogeneous });
        let i = self.media.len() as u32 - 1;
        self.medium_cache.insert(key, i);
        Ok(i)
    }

    fn phase(&self, node: &Arc<Node>) -> Result<crate::medium::PhaseFunction> {
        use crate::medium::PhaseFunction;
        let props = Props::new(node);
        let phase = match node.plugin.as_str() {
            "isotropic" => PhaseFunction::Isotropic,
            "hg" => PhaseFunction::HenyeyGreenstein { g: props.float_checked("g", 0.8, |g| g > -1.0 && g < 1.0, "in (-1, 1)")? },
            "rayleigh" => PhaseFunction::Rayleigh,
            "tabphase" => {
                let text = props.string_req("values")?;
                let mut values = vec![];
                for token in text.split([',', ' ', '\t', '\n']).filter(|t| !t.is_empty()) {
                    let v = token.parse::<f32>().map_err(|_| props.error_at("values", format!("\"values\" holds \"{token}\", which is not a number")))?;
                    values.push(v);
                }
                let table = crate::medium::phase::Tabulated::new(&values).map_err(|e| props.error_at("values", format!("tabphase's \"values\": {e}")))?;
                PhaseFunction::Tabulated(Arc::new(table))
            }
            "blendphase" => {
                // Mitsuba requires the weight (no default).
                if props.child_named("weight").is_none() && !props.has("weight") {
                    return Err(SceneError::at(&node.loc, "blendphase needs a \"weight\" (a float in [0, 1] or a volume)"));
                }
                let weight = self.volume_input(&props, "weight", 0.5)?;
                let nested = props.children_of(Kind::Phase);
                if nested.len() != 2 {
                    let loc = nested.get(2).map_or(&node.loc, |c| &c.loc);
                    return Err(SceneError::at(loc, format!("blendphase takes exactly two nested <phase>s, not {}", nested.len())).with_choices(&PHASES));
                }
                let a = self.phase(&self.resolve(nested[0])?)?;
                let b = self.phase(&self.resolve(nested[1])?)?;
                PhaseFunction::Blend { weight: Arc::new(weight), phases: Arc::new([a, b]) }
            }
            _ => return Err(unknown_plugin(node, &PHASES)),
        };
        props.finish()?;
        Ok(phase)
    }

    /// A medium's input `name`: a nested `<volume>` or a constant.
    fn volume_input(&self, props: &Props, name: &str, default: f32) -> Result<crate::medium::Volume> {
        if let Some(child) = props.child_named(name) {
            let node = self.resolve(child)?;
            if node.kind != Kind::Volume {
                return Err(SceneError::at(&child.loc, format!("\"{name}\" must be a <volume> or a value, not a <{}>", node.kind.tag())).with_choices(&VOLUMES));
            }
            return self.volume(&node);
        }
        let value = props.color(name, Rgb::new(default, default, default))?;
        if value.0.iter().any(|v| !(*v >= 0.0) || !v.is_finite()) {
            return Err(props.error_at(name, format!("\"{name}\" must be finite and not negative")));
        }
        Ok(crate::medium::Volume::constant(value, Transform::IDENTITY))
    }

    fn volume(&self, node: &Arc<Node>) -> Result<crate::medium::Volume> {
        use crate::medium::{Grid, Volume, WrapMode};
        let props = Props::new(node);
        let to_world = props.transform("to_world")?;
        let volume = match node.plugin.as_str() {
            "constvolume" => {
                let value = props.color("value", Rgb::new(1.0, 1.0, 1.0))?;
                if value.0.iter().any(|v| !(*v >= 0.0) || !v.is_finite()) {
                    return Err(props.error_at("value", "a volume's value must be finite and not negative"));
                }
                Volume::constant(value, to_world)
            }
            "gridvolume" | "grid" => {
                let file = props.string_req("filename")?;
                let nearest = props.choice("filter_type", "trilinear", &["trilinear", "nearest"])? == "nearest";
                let wrap = match props.choice("wrap_mode", "clamp", &["clamp", "repeat", "mirror"])? {
                    "repeat" => WrapMode::Repeat,
                    "mirror" => WrapMode::Mirror,
                    _ => WrapMode::Clamp,
                };
                let use_grid_bbox = props.bool("use_grid_bbox", false)?;
                let max_value = props.float_opt("max_value")?;
                // Colour conversion switch and GPU hint: no effect here.
                props.bool("raw", false)?;
                props.bool("accel", true)?;
                let path = self.input_file(node, file);
                let grid = Grid::read(&path, nearest, wrap).map_err(|e| with_search_help(props.error_at("filename", e), node, file))?;
                let to_world = if use_grid_bbox {
                    let placed = grid.bounds_transform().ok_or_else(|| props.error_at("use_grid_bbox", "the grid file's bounds are empty or not finite"))?;
                    to_world.compose(&placed)
                } else {
                    to_world
                };
                Volume::grid(grid, to_world, max_value)
            }
            _ => return Err(unknown_plugin(node, &VOLUMES)),
        };
        props.finish()?;
        Ok(volume)
    }

    /// Points every `mesh_attribute` texture at its attribute on each mesh;
    /// an attribute no mesh has, or of 2 or more than 3 components, is an error.
    fn resolve_mesh_attributes(&self) -> Result<()> {
        for (tex, loc) in self.mesh_attribute_textures.borrow().iter() {
            let mut known = vec![];
            let table: Vec<_> = self
                .shapes
                .iter()
                .map(|s| match &s.geometry {
                    ShapeGeometry::Mesh(m) => {
                        known.extend(m.attributes.iter().map(|(n, _)| n.as_str()));
                        m.attributes.iter().find(|(n, _)| *n == tex.name).map(|(_, a)| a.clone())
                    }
                    _ => None,
                })
                .collect();
            if let Some(a) = table.iter().flatten().find(|a| a.dims != 1 && a.dims != 3) {
                return Err(SceneError::at(loc, format!("mesh attribute \"{}\" has {} components; a texture reads 1 or 3", tex.name, a.dims)));
            }
            if table.iter().all(Option::is_none) {
                known.sort();
                known.dedup();
                let e = SceneError::at(loc, format!("no mesh in the scene has the attribute \"{}\"", tex.name));
                return Err(if known.is_empty() { e.with_help("no mesh in this scene has attributes (PLY vertex or face properties)") } else { e.with_choices(&known) });
            }
            let _ = tex.table.set(table);
        }
        Ok(())
    }

    /// Mitsuba's `shapegroup`: shapes that are not rendered themselves but
    /// placed by `instance`s; built once however many instances use it.
    fn shapegroup(&mut self, node: &Arc<Node>) -> Result<u32> {
        let key = Arc::as_ptr(node);
        if let Some(&g) = self.group_index.get(&key) {
            return Ok(g);
        }
        let props = Props::new(node);
        let mut members = vec![];
        self.in_group = true;
        let mut built = || -> Result<()> {
            for c in props.children_of(Kind::Shape) {
                let member = self.resolve(c)?;
                let first = self.shapes.len() as u32;
                self.shape(&member)?;
                members.extend(first..self.shapes.len() as u32);
            }
            props.finish()
        };
        let result = built();
        self.in_group = false;
        result?;
        self.groups.push(members);
        let g = self.groups.len() as u32 - 1;
        self.group_index.insert(key, g);
        Ok(g)
    }

    /// A shape that only aims a sensor's rays (a distant sensor's target):
    /// built as any shape, then taken out of the scene.
    fn detached_shape(&mut self, node: &Arc<Node>) -> Result<Shape> {
        let first = self.shapes.len();
        let (emitters, sensor) = (self.emitters.len(), self.shape_sensor.is_some());
        self.shape(node)?;
        if self.shapes.len() != first + 1 || self.emitters.len() != emitters || self.shape_sensor.is_some() != sensor {
            return Err(SceneError::at(&node.loc, "a sensor's target must be one plain shape (no emitter, sensor, group or merge)")
                .with_choices(&["rectangle", "cube", "disk", "sphere", "cylinder", "obj", "ply", "serialized"]));
        }
        let Some(mut shape) = self.shapes.pop() else {
            return Err(SceneError::at(&node.loc, "the target shape was not built"));
        };
        self.top_shapes.retain(|&i| i as usize != first);
        // Its vertex normals (if any were being computed) are not needed to aim rays.
        let pending: Vec<_> = self.pending_normals.take().into_iter().filter(|(i, _)| *i != first).collect();
        self.pending_normals.replace(pending);
        if let ShapeGeometry::SdfGrid(_) | ShapeGeometry::Curves(_) = shape.geometry {
            return Err(SceneError::at(&node.loc, format!("a {} cannot be a target: its surface cannot be sampled by area", node.plugin)));
        }
        shape.emitter = None;
        Ok(shape)
    }

    /// Mitsuba's `merge`: shapes that Mitsuba joins into fewer meshes to
    /// save memory in its ray tracer. The image is that of the shapes on
    /// their own, so Snell loads them as if they stood outside it (it takes
    /// no `to_world`, as Mitsuba's does not).
    fn merge(&mut self, node: &Arc<Node>) -> Result<()> {
        let props = Props::new(node);
        let children = props.children_of(Kind::Shape);
        let mut members = vec![];
        for c in children.iter().copied().chain(props.unnamed_refs()) {
            members.push(self.resolve(c)?);
        }
        props.finish()?;
        for member in members {
            if member.kind != Kind::Shape {
                return Err(SceneError::at(&member.loc, format!("a merge holds shapes, not a <{}>", member.kind.tag())));
            }
            self.shape(&member)?;
        }
        Ok(())
    }

    /// Mitsuba's `instance`: a `<ref>` to a shapegroup placed by `to_world`.
    fn instance(&mut self, node: &Arc<Node>) -> Result<()> {
        let props = Props::new(node);
        let to_world = props.transform("to_world")?;
        let children = props.children_of(Kind::Shape);
        let mut targets = vec![];
        for c in children.iter().copied().chain(props.unnamed_refs()) {
            targets.push((c, self.resolve(c)?));
        }
        let [(child, group)] = targets.as_slice() else {
            return Err(SceneError::at(&node.loc, format!("an instance takes exactly one shapegroup (a <ref id=\"…\"/> to it), found {}", targets.len())));
        };
        if group.kind != Kind::Shape || group.plugin != "shapegroup" {
            let what = if group.kind == Kind::Shape { format!("a \"{}\" shape", group.plugin) } else { format!("a <{}>", group.kind.tag()) };
            return Err(SceneError::at(&child.loc, format!("an instance must refer to a shapegroup, not to {what}")).with_choices(&["shapegroup"]));
        }
        props.finish()?;
        let g = self.shapegroup(group)?;
        self.instances.push((to_world, g));
        Ok(())
    }

    fn sphere(&self, props: &Props, to_world: &Transform, flip: bool) -> Result<Sphere> {
        let center = props.vec3("center", Vec3::ZERO)?;
        let radius = props.float_checked("radius", 1.0, |r| r > 0.0, "positive")?;
        // Mitsuba allows translation, rotation and uniform scale here.
        let axes = [to_world.vector(Vec3::X), to_world.vector(Vec3::Y), to_world.vector(Vec3::Z)];
        let s = axes[0].length();
        let uniform = axes.iter().all(|a| (a.length() - s).abs() <= 1e-4 * s)
            && axes[0].dot(axes[1]).abs() <= 1e-4 * s * s
            && axes[1].dot(axes[2]).abs() <= 1e-4 * s * s
            && axes[0].dot(axes[2]).abs() <= 1e-4 * s * s;
        if !uniform {
            let loc = props.node.props.iter().find(|p| p.name == "to_world").map_or(&props.node.loc, |p| &p.loc);
            return Err(SceneError::at(loc, "a sphere's to_world must be a similarity (rotation, translation, uniform scale)")
                .with_help("use a mesh (obj/ply) for an ellipsoid"));
        }
        let object_to_world =
            to_world.compose(&Transform::from_matrix(Mat4::from_translation(center) * Mat4::from_scale(Vec3::splat(radius))).ok_or_else(|| {
                SceneError::at(&props.node.loc, "degenerate sphere transform")
            })?);
        Ok(Sphere {
            center: to_world.point(center),
            radius: radius * s,
            to_object: Transform { matrix: object_to_world.inverse, inverse: object_to_world.matrix },
            flip_normals: flip,
        })
    }

    fn mesh_file(&self, props: &Props, to_world: &Transform, flip: bool) -> Result<Mesh> {
        let node = props.node;
        let filename = props.string_req("filename")?;
        let mut face_normals = props.bool("face_normals", false)?;
        let flip_tex = if node.plugin == "obj" { props.bool("flip_tex_coords", true)? } else { false };
        let path = self.input_file(node, filename);
        let file_loc = node.props.iter().find(|p| p.name == "filename").map_or(&node.loc, |p| &p.loc);
        let raw = match node.plugin.as_str() {
            "obj" => mesh_io::read_obj(&path),
            "serialized" => {
                let index = props.int_checked("shape_index", 0, |v| (0..=u32::MAX as i64).contains(&v), "a non-negative integer")?;
                serialized::read_serialized(&path, index as u32).map(|s| {
                    face_normals |= s.face_normals;
                    s.mesh
                })
            }
            _ => mesh_io::read_ply(&path),
        }
        .map_err(|e| with_search_help(SceneError::at(file_loc, e), node, filename))?;
        let positions: Vec<Vec3> = {
            use rayon::prelude::*;
            raw.positions.par_iter().map(|&p| to_world.point(p)).collect()
        };
        // A big mesh's vertex normals are computed on a thread of their own
        // (`pending_normals`), the same bits as here.
        let overlapped = !face_normals && raw.normals.is_none() && raw.triangles.len() >= OVERLAPPED_NORMALS_MIN;
        let normals = if face_normals || overlapped {
            None
        } else {
            Some(match raw.normals {
                Some(ns) => ns.iter().map(|&n| to_world.normal(n)).collect(),
                None => Mesh::compute_vertex_normals(&positions, &raw.triangles),
            })
        };
        // The OBJ reader applied Mitsuba's default flip already; undo it if asked.
        // PLY and serialized texture coordinates are used as stored (as Mitsuba does).
        let undo_flip = node.plugin == "obj" && !flip_tex;
        let uvs = raw.uvs.map(|uvs| if !undo_flip { uvs } else { uvs.into_iter().map(|uv| glam::Vec2::new(uv.x, 1.0 - uv.y)).collect() });
        let attributes = raw.attributes.iter().map(|(n, a)| (n.clone(), Arc::new(a.to_corners(&raw.triangles)))).collect();
        let mut mesh = Mesh::new(positions, normals, uvs, raw.triangles, flip);
        mesh.attributes = attributes;
        if overlapped {
            let (positions, triangles) = (mesh.positions.clone(), mesh.triangles.clone());
            let job = std::thread::Builder::new()
                .name("snell-normals".into())
                .spawn(move || Mesh::compute_vertex_normals(&positions, &triangles))
                .map_err(|e| SceneError::at(file_loc, format!("cannot start a thread for the vertex normals: {e}")))?;
            // `shape` pushes this mesh's shape next.
            self.pending_normals.borrow_mut().push((self.shapes.len(), job));
        }
        Ok(mesh)
    }

    // ------------------------------------------------------------ materials

    fn bsdf(&mut self, node: &Arc<Node>) -> Result<u32> {
        let key = Arc::as_ptr(node);
        if let Some(&i) = self.bsdf_cache.get(&key) {
            return Ok(i);
        }
        let bsdf = self.make_bsdf(node)?;
        self.bsdfs.push(bsdf);
        let i = self.bsdfs.len() as u32 - 1;
        self.bsdf_cache.insert(key, i);
        Ok(i)
    }

    fn make_bsdf(&self, node: &Arc<Node>) -> Result<Bsdf> {
        let props = Props::new(node);
        let bsdf = match node.plugin.as_str() {
            "diffuse" => Bsdf::Diffuse(Diffuse::from_props(&props, self)?),
            "polarizer" => Bsdf::Polarizer(Polarizer::from_props(&props, self)?),
            "retarder" => Bsdf::Retarder(Retarder::from_props(&props, self)?),
            "conductor" => Bsdf::Conductor(Conductor::from_props(&props, self)?),
            "dielectric" => Bsdf::Dielectric(Dielectric::from_props(&props, self)?),
            "thindielectric" => Bsdf::ThinDielectric(ThinDielectric::from_props(&props, self)?),
            "plastic" => Bsdf::Plastic(Plastic::from_props(&props, self)?),
            "twosided" => Bsdf::TwoSided(TwoSided::from_props(&props, self)?),
            "null" => Bsdf::Null(Null),
            "mask" => Bsdf::Mask(Mask::from_props(&props, self)?),
            "blendbsdf" => Bsdf::BlendBsdf(BlendBsdf::from_props(&props, self)?),
            "normalmap" => Bsdf::NormalMap(NormalMap::from_props(&props, self)?),
            "bumpmap" => Bsdf::BumpMap(BumpMap::from_props(&props, self)?),
            "roughconductor" => Bsdf::RoughConductor(crate::bsdf::RoughConductor::from_props(&props, self)?),
            "roughdielectric" => Bsdf::RoughDielectric(crate::bsdf::RoughDielectric::from_props(&props, self)?),
            "roughplastic" => Bsdf::RoughPlastic(crate::bsdf::RoughPlastic::from_props(&props, self)?),
            "pplastic" => Bsdf::PolarizedPlastic(crate::bsdf::PolarizedPlastic::from_props(&props, self)?),
            "principled" => Bsdf::Principled(crate::bsdf::Principled::from_props(&props, self)?),
            "principledthin" => Bsdf::PrincipledThin(crate::bsdf::PrincipledThin::from_props(&props, self)?),
            "birefringent" => Bsdf::Birefringent(crate::bsdf::Birefringent::from_props(&props, self)?),
            _ => return Err(unknown_plugin(node, &BSDFS)),
        };
        props.finish()?;
        Ok(bsdf)
    }

    /// A colour or scalar parameter: `rgb`/`spectrum`/`float`, or a nested
    /// (or referenced) texture, and where it was given; `None` if absent.
    fn texture_input_at(&self, props: &Props, name: &str) -> Result<Option<(Texture, super::Location)>> {
        let at_prop = || props.node.props.iter().find(|p| p.name == name).map_or(&props.node.loc, |p| &p.loc).clone();
        if let Some((rgb, listed)) = props.spectrum_opt(name) {
            return Ok(Some((Texture::Spectral { rgb, spectrum: Arc::new(listed) }, at_prop())));
        }
        if let Some(c) = props.color_opt(name)? {
            return Ok(Some((Texture::constant(c), at_prop())));
        }
        match props.child_named(name) {
            Some(child) => {
                let node = self.resolve(child)?;
                if node.kind != Kind::Texture {
                    return Err(SceneError::at(&child.loc, format!("\"{name}\" must be a colour or a <texture>, not a <{}>", node.kind.tag())));
                }
                Ok(Some((self.texture(&node)?, node.loc.clone())))
            }
            None => Ok(None),
        }
    }

    /// A colour or scalar parameter with no range (emission, weights,
    /// opacities, normal and height maps); `default` if absent.
    fn texture_input(&self, props: &Props, name: &str, default: Rgb) -> Result<Texture> {
        Ok(self.texture_input_at(props, name)?.map_or_else(|| Texture::constant(default), |(t, _)| t))
    }

    /// A reflectance or transmittance (all colour inputs of BSDFs are):
    /// `rgb`/`spectrum`/`float`, or a nested (or referenced) texture. A
    /// negative value is an error; a value above one (more light out than
    /// in) a warning naming the parameter.
    fn reflectance_input(&self, props: &Props, name: &str, default: Rgb) -> Result<Texture> {
        let Some((texture, loc)) = self.texture_input_at(props, name)? else { return Ok(Texture::constant(default)) };
        let (lo, hi) = texture_range(&texture);
        let what = format!("\"{name}\" of {} \"{}\"", props.node.kind.tag(), props.node.plugin);
        if lo < 0.0 {
            return Err(SceneError::at(&loc, format!("{what} is negative ({lo}); a reflectance or transmittance lies in [0, 1]")));
        }
        if hi > 1.0 {
            self.warnings.borrow_mut().push(located_warning(
                &loc,
                &format!("{what} is above one ({hi}): the surface gives back more light than it receives"),
            ));
        }
        Ok(texture)
    }

    fn texture(&self, node: &Arc<Node>) -> Result<Texture> {
        let props = Props::new(node);
        let to_uv = uv_transform(&props.transform("to_uv")?.matrix);
        if matches!(node.plugin.as_str(), "checkerboard" | "bitmap") {
            self.reads_uv.set(true);
        }
        let tex = match node.plugin.as_str() {
            "checkerboard" => Texture::Checkerboard(Checkerboard {
                color0: props.color("color0", Rgb::new(0.4, 0.4, 0.4))?,
                color1: props.color("color1", Rgb::new(0.2, 0.2, 0.2))?,
                to_uv,
            }),
            "bitmap" => {
                let filename = props.string_req("filename")?;
                let filter = match props.choice("filter_type", "bilinear", &["bilinear", "nearest"])? {
                    "nearest" => bitmap::Filter::Nearest,
                    _ => bitmap::Filter::Bilinear,
                };
                let wrap = match props.choice("wrap_mode", "repeat", &["repeat", "mirror", "clamp"])? {
                    "mirror" => bitmap::Wrap::Mirror,
                    "clamp" => bitmap::Wrap::Clamp,
                    _ => bitmap::Wrap::Repeat,
                };
                let raw = props.bool("raw", false)?;
                // Mitsuba's storage precision: `uint8` and `float16` round the
                // texels as Mitsuba stores them; `auto`/`variant` keep floats.
                let format = props.choice("format", "auto", &["auto", "variant", "float16", "uint8"])?;
                let path = self.input_file(node, filename);
                let loc = node.props.iter().find(|p| p.name == "filename").map_or(&node.loc, |p| &p.loc);
                let (width, height, texels) =
                    bitmap::read_image(&path, raw).map_err(|e| with_search_help(SceneError::at(loc, e), node, filename))?;
                if width == 0 || height == 0 {
                    return Err(SceneError::at(loc, format!("image {} is empty", path.display())));
                }
                let texels = match format {
                    "uint8" => texels.into_iter().map(|c| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() / 255.0)).collect(),
                    "float16" => texels.into_iter().map(|c| c.map(round_to_half)).collect(),
                    _ => texels,
                };
                Texture::Bitmap(Arc::new(Bitmap { width, height, texels, filter, wrap, to_uv }))
            }
            // A constant stored as given: no colour conversion (Mitsuba uses
            // it for raw data such as a normal map's vector). Snell's
            // constant textures are linear already; in spectral mode a
            // rawconstant read as a colour is uplifted like an `rgb`.
            "rawconstant" => {
                let value = match props.vec3_opt("value") {
                    Ok(Some(v)) => Rgb::new(v.x, v.y, v.z),
                    Ok(None) => props.color("value", Rgb::new(1.0, 1.0, 1.0))?,
                    Err(_) => props.color_opt("value")?.unwrap_or(Rgb::new(1.0, 1.0, 1.0)),
                };
                Texture::constant(value)
            }
            "mesh_attribute" => {
                let name = props.string_req("name")?;
                let loc = node.props.iter().find(|p| p.name == "name").map_or(&node.loc, |p| &p.loc);
                if !(name.starts_with("vertex_") || name.starts_with("face_")) {
                    return Err(SceneError::at(loc, format!("mesh attribute name \"{name}\" must start with \"vertex_\" or \"face_\""))
                        .with_help("e.g. \"vertex_color\" or \"face_color\""));
                }
                let scale = props.float_checked("scale", 1.0, f32::is_finite, "a finite number")?;
                let tex = Arc::new(MeshAttributeTexture { name: name.to_string(), scale, table: Default::default() });
                self.mesh_attribute_textures.borrow_mut().push((tex.clone(), loc.clone()));
                Texture::MeshAttribute(tex)
            }
            _ => return Err(unknown_plugin(node, &TEXTURES)),
        };
        props.finish()?;
        Ok(tex)
    }

    // ------------------------------------------------------------- emitters

    fn area_emitter(&mut self, node: &Arc<Node>, shape: u32) -> Result<u32> {
        if node.plugin != "area" {
            return Err(SceneError::at(&node.loc, format!("a shape can only carry an \"area\" emitter, not \"{}\"", node.plugin))
                .with_choices(&["area"]));
        }
        let props = Props::new(node);
        let (radiance, texture) = match props.emission_opt("radiance")? {
            Some(e) => (e, None),
            None if props.child_named("radiance").is_some() => {
                (Emission::rgb(Rgb::BLACK), Some(self.texture_input(&props, "radiance", Rgb::BLACK)?))
            }
            None => return Err(SceneError::at(&node.loc, "area emitter needs \"radiance\"")),
        };
        props.finish()?;
        self.emitters.push(Emitter::Area(AreaLight { shape, radiance, texture, rect: None }));
        Ok(self.emitters.len() as u32 - 1)
    }

    fn top_level_emitter(&mut self, node: &Arc<Node>) -> Result<()> {
        let props = Props::new(node);
        let emitter = match node.plugin.as_str() {
            "area" => {
                return Err(SceneError::at(&node.loc, "an area emitter must be nested inside the <shape> that emits"));
            }
            "point" => {
                let to_world = props.transform("to_world")?;
                let position = props.vec3_opt("position")?.unwrap_or_else(|| to_world.point(Vec3::ZERO));
                let intensity =
                    props.emission_opt("intensity")?.ok_or_else(|| SceneError::at(&node.loc, "point emitter needs \"intensity\""))?;
                Emitter::Point(PointLight { position, intensity })
            }
            "spot" => {
                let to_world = props.transform("to_world")?;
                let axis = to_world.vector(Vec3::Z).normalize_or_zero();
                if axis == Vec3::ZERO {
                    return Err(SceneError::at(&node.loc, "spot emitter's to_world collapses its axis"));
                }
                let intensity =
                    props.emission_opt("intensity")?.ok_or_else(|| SceneError::at(&node.loc, "spot emitter needs \"intensity\""))?;
                let cutoff = props.float_checked("cutoff_angle", 20.0, |a| a > 0.0 && a <= 90.0, "an angle in (0, 90] degrees")?;
                let beam = props.float_checked("beam_width", cutoff * 0.75, |b| b > 0.0 && b <= cutoff, "an angle in (0, cutoff_angle] degrees")?;
                let spot = SpotLight::new(to_world.point(Vec3::ZERO), axis, intensity, cutoff, beam);
                match props.child_named("texture") {
                    Some(_) => Emitter::Spot(spot.with_texture(self.texture_input(&props, "texture", Rgb::WHITE)?, to_world)),
                    None => Emitter::Spot(spot),
                }
            }
            "constant" => Emitter::Constant(ConstantLight { radiance: props.emission_opt("radiance")?.unwrap_or(Emission::rgb(Rgb::WHITE)) }),
            "directional" => {
                let to_world = props.transform("to_world")?;
                let direction = props.vec3_opt("direction")?.unwrap_or_else(|| to_world.vector(Vec3::Z)).normalize_or_zero();
                if direction == Vec3::ZERO {
                    return Err(SceneError::at(&node.loc, "directional emitter has a zero direction"));
                }
                let irradiance = props
                    .emission_opt("irradiance")?
                    .ok_or_else(|| SceneError::at(&node.loc, "directional emitter needs \"irradiance\""))?;
                Emitter::Directional(DirectionalLight { direction, irradiance })
            }
            "projector" => {
                let to_world = props.transform("to_world")?;
                if to_world.vector(Vec3::Z).normalize_or_zero() == Vec3::ZERO {
                    return Err(SceneError::at(&node.loc, "projector's to_world collapses its axis"));
                }
                let irradiance = self.texture_input(&props, "irradiance", Rgb::WHITE)?;
                let scale = props.float_checked("scale", 1.0, |s| s.is_finite() && s >= 0.0, "a non-negative number")?;
                let aspect = match &irradiance {
                    Texture::Bitmap(b) => b.width as f32 / b.height as f32,
                    _ => 1.0,
                };
                let fov_x = match props.float_opt("fov")? {
                    Some(_) => {
                        let fov = props.float_checked("fov", f32::NAN, |f| f > 0.0 && f < 180.0, "an angle in (0, 180) degrees")?;
                        let axis = props.choice("fov_axis", "x", &["x", "y", "smaller", "larger", "diagonal"])?;
                        horizontal_fov(fov, axis, aspect)
                    }
                    None => {
                        // Mitsuba's default: a 50 mm lens on 35 mm film, measured on the diagonal.
                        let text = props.string_opt("focal_length")?.unwrap_or("50mm");
                        let mm = text.trim().trim_end_matches("mm").trim().parse::<f32>().ok().filter(|f| *f > 0.0 && f.is_finite());
                        let Some(mm) = mm else {
                            return Err(props.error_at("focal_length", format!("focal_length must be a length like \"50mm\", not \"{text}\"")));
                        };
                        let diagonal = 2.0 * ((36.0f32 * 36.0 + 24.0 * 24.0).sqrt() / (2.0 * mm)).atan().to_degrees();
                        horizontal_fov(diagonal, "diagonal", aspect)
                    }
                };
                Emitter::Projector(Box::new(Projector::new(to_world, irradiance, scale, fov_x, aspect)))
            }
            "envmap" => {
                let filename = props.string_req("filename")?;
                let scale = props.float_checked("scale", 1.0, |s| s.is_finite() && s >= 0.0, "a non-negative number")?;
                let to_world = props.transform("to_world")?;
                props.bool("mis_compensation", false)?;
                let path = self.input_file(node, filename);
                let loc = node.props.iter().find(|p| p.name == "filename").map_or(&node.loc, |p| &p.loc);
                let (width, height, texels) = bitmap::read_image(&path, false).map_err(|e| SceneError::at(loc, e))?;
                let map = EnvironmentMap::new(width, height, texels, scale, to_world)
                    .map_err(|e| SceneError::at(loc, format!("{}: {e}", path.display())))?;
                Emitter::EnvMap(Box::new(map))
            }
            _ => return Err(unknown_plugin(node, &EMITTERS)),
        };
        props.finish()?;
        if emitter.is_environment() {
            if self.environment.is_some() {
                return Err(SceneError::at(&node.loc, "only one environment emitter is allowed per scene"));
            }
            self.environment = Some(self.emitters.len() as u32);
        }
        self.emitters.push(emitter);
        Ok(())
    }

    // -------------------------------------------------------------- sensors

    /// A sensor; `on_shape` is the shape it is nested in (an irradiance meter's).
    fn sensor(&mut self, node: &Arc<Node>, on_shape: Option<&Shape>) -> Result<(Camera, FilmSpec, SamplerSpec)> {
        let props = Props::new(node);
        if !SENSORS.contains(&node.plugin.as_str()) {
            return Err(unknown_plugin(node, &SENSORS));
        }
        let mut films = self.nested(&props, Kind::Film)?;
        let mut samplers = self.nested(&props, Kind::Sampler)?;
        for r in props.unnamed_refs() {
            let target = self.resolve(r)?;
            match target.kind {
                Kind::Film => films.push(target),
                Kind::Sampler => samplers.push(target),
                k => {
                    return Err(SceneError::at(&r.loc, format!("a sensor cannot take a reference to a <{}>", k.tag()))
                        .with_help("a sensor takes one <film> and one <sampler>"));
                }
            }
        }
        if films.len() > 1 || samplers.len() > 1 {
            return Err(SceneError::at(&node.loc, "a sensor takes at most one <film> and one <sampler>"));
        }
        let film = match films.first() {
            Some(f) => self.film(f)?,
            None => match self.film_width {
                Some(w) => FilmSpec::new(w, ((576.0 * w as f64 / 768.0).round() as u32).max(1), Filter::gaussian(0.5)),
                None => FilmSpec::new(768, 576, Filter::gaussian(0.5)),
            },
        };
        let sampler = match samplers.first() {
            Some(s) => self.sampler(s)?,
            None => SamplerSpec::default(),
        };
        let mut sampler = sampler;
        sampler.fit_film(film.width, film.height);
        let aspect = film.width as f32 / film.height as f32;
        let to_world = props.transform("to_world")?;
        let near_clip = props.float_checked("near_clip", 0.01, |v| v >= 0.0, "non-negative")?;
        let far_clip = props.float_checked("far_clip", 10000.0, |v| v > near_clip, "greater than near_clip")?;
        let camera = match node.plugin.as_str() {
            "perspective" | "thinlens" => {
                let tan_half_x = (sensor_fov(&props, aspect)?.to_radians() * 0.5).tan();
                let offset = glam::Vec2::new(
                    props.float_checked("principal_point_offset_x", 0.0, f32::is_finite, "finite")?,
                    props.float_checked("principal_point_offset_y", 0.0, f32::is_finite, "finite")?,
                );
                // Mitsuba's default focus distance is the far clip distance.
                let focus_distance = props.float_checked("focus_distance", far_clip, |v| v > 0.0 && v.is_finite(), "positive")?;
                if node.plugin == "perspective" {
                    // A pinhole has everything in focus; the distance is accepted for Mitsuba compatibility.
                    Camera::Perspective(Perspective::new(to_world, tan_half_x, aspect, near_clip, far_clip).with_principal_offset(offset))
                } else {
                    let radius = props.float_checked("aperture_radius", f32::NAN, |r| r >= 0.0 && r.is_finite(), "a non-negative radius")?;
                    Camera::ThinLens(ThinLens {
                        to_world,
                        tan_half_x,
                        aspect,
                        near_clip,
                        far_clip,
                        // Mitsuba replaces a zero radius by the float epsilon.
                        aperture_radius: if radius == 0.0 { f32::EPSILON / 2.0 } else { radius },
                        focus_distance,
                        principal_offset: offset,
                    })
                }
            }
            "radiancemeter" => {
                // As Mitsuba: a film with neither side 1 is refused.
                if film.width != 1 && film.height != 1 {
                    let at = films.first().map_or(&node.loc, |f| &f.loc);
                    return Err(SceneError::at(at, format!("a radiancemeter measures one ray: its film must be 1 × 1 pixels, not {} × {}", film.width, film.height))
                        .with_help("<film type=\"hdrfilm\"><integer name=\"width\" value=\"1\"/><integer name=\"height\" value=\"1\"/></film>"));
                }
                // `to_world` (the identity where absent) wins over origin and
                // direction, which are read either way (Mitsuba).
                let meter = match (props.has("to_world"), props.vec3_opt("origin")?, props.vec3_opt("direction")?) {
                    (true, _, _) | (false, None, None) => RadianceMeter::from_transform(&to_world)
                        .ok_or_else(|| props.error_at("to_world", "to_world maps +z to a zero vector: the radiancemeter has no direction"))?,
                    (false, Some(o), Some(d)) => RadianceMeter::from_ray(o, d)
                        .ok_or_else(|| props.error_at("direction", "the radiancemeter's direction must be a finite, non-zero vector"))?,
                    (false, Some(_), None) => return Err(props.error_at("origin", "a radiancemeter given an origin needs a direction too (or a to_world instead)")),
                    (false, None, Some(_)) => return Err(props.error_at("direction", "a radiancemeter given a direction needs an origin too (or a to_world instead)")),
                };
                Camera::RadianceMeter(meter)
            }
            "irradiancemeter" => {
                let Some(shape) = on_shape else {
                    return Err(SceneError::at(&node.loc, "an irradiancemeter measures the shape it is nested in: place it inside a <shape>")
                        .with_help("<shape type=\"rectangle\"><sensor type=\"irradiancemeter\">…</sensor></shape>"));
                };
                if props.has("to_world") {
                    return Err(props.error_at("to_world", "an irradiancemeter takes no to_world: it sits on its shape (transform the shape instead)"));
                }
                Camera::IrradianceMeter(IrradianceMeter { shape: Arc::new(shape.clone()) })
            }
            "distant" => {
                // As Mitsuba: one pixel exactly.
                if (film.width, film.height) != (1, 1) {
                    let at = films.first().map_or(&node.loc, |f| &f.loc);
                    return Err(SceneError::at(at, format!("a distant sensor measures one value: its film must be 1 × 1 pixels, not {} × {}", film.width, film.height))
                        .with_help("<film type=\"hdrfilm\"><integer name=\"width\" value=\"1\"/><integer name=\"height\" value=\"1\"/></film>"));
                }
                let frame = match props.vec3_opt("direction")? {
                    Some(_) if props.has("to_world") => {
                        return Err(props.error_at("direction", "a distant sensor takes a direction or a to_world, not both"));
                    }
                    Some(d) => {
                        let d = d.normalize_or_zero();
                        if d == Vec3::ZERO || !d.is_finite() {
                            return Err(props.error_at("direction", "the distant sensor's direction must be a finite, non-zero vector"));
                        }
                        // Mitsuba's frame: up is the direction's second tangent.
                        Transform::look_at(Vec3::ZERO, d, crate::math::Frame::from_normal(d).t)
                            .ok_or_else(|| props.error_at("direction", "the distant sensor's direction gives no frame"))?
                    }
                    None => to_world,
                };
                let direction = frame.vector(Vec3::Z).normalize_or_zero();
                if direction == Vec3::ZERO || !direction.is_finite() {
                    return Err(props.error_at("to_world", "to_world maps +z to a zero vector: the distant sensor has no direction"));
                }
                let target = match (props.vec3_opt("target"), props.child_named("target")) {
                    (Ok(Some(p)), _) => DistantTarget::Point(p),
                    (_, Some(child)) => {
                        let target = self.resolve(child)?;
                        if target.kind != Kind::Shape {
                            return Err(SceneError::at(&child.loc, format!("a distant sensor's target is a point or a <shape>, not a <{}>", target.kind.tag())));
                        }
                        DistantTarget::Shape(Arc::new(self.detached_shape(&target)?))
                    }
                    (Err(e), None) => return Err(e),
                    (Ok(None), None) => DistantTarget::BoundingDisk,
                };
                Camera::Distant(Distant {
                    direction,
                    x_axis: frame.vector(Vec3::X),
                    y_axis: frame.vector(Vec3::Y),
                    target,
                    center: Vec3::ZERO,
                    radius: 1.0,
                })
            }
            _ => Camera::Orthographic(Orthographic { to_world, aspect, near_clip, far_clip }),
        };
        props.finish()?;
        Ok((camera, film, sampler))
    }

    fn film(&self, node: &Arc<Node>) -> Result<FilmSpec> {
        if !FILMS.contains(&node.plugin.as_str()) {
            return Err(unknown_plugin(node, &FILMS));
        }
        let props = Props::new(node);
        let width = props.int_checked("width", 768, |v| (1..=65536).contains(&v), "between 1 and 65536")? as u32;
        let height = props.int_checked("height", 576, |v| (1..=65536).contains(&v), "between 1 and 65536")? as u32;
        let pixel_format = props.choice("pixel_format", "rgb", &PixelFormat::NAMES)?;
        let pixel_format = PixelFormat::from_name(pixel_format).unwrap_or(PixelFormat::Rgb);
        // The crop window: offset inside the film, size at least one pixel and within the film.
        let crop_x = props.int_checked("crop_offset_x", 0, |v| (0..width as i64).contains(&v), &format!("between 0 and {} (width − 1)", width - 1))? as u32;
        let crop_y = props.int_checked("crop_offset_y", 0, |v| (0..height as i64).contains(&v), &format!("between 0 and {} (height − 1)", height - 1))? as u32;
        let crop_w = props.int_checked("crop_width", (width - crop_x) as i64, |v| v >= 1 && v <= (width - crop_x) as i64, &format!("between 1 and {} (width − crop_offset_x)", width - crop_x))? as u32;
        let crop_h = props.int_checked("crop_height", (height - crop_y) as i64, |v| v >= 1 && v <= (height - crop_y) as i64, &format!("between 1 and {} (height − crop_offset_y)", height - crop_y))? as u32;
        props.choice("component_format", "float32", &["float16", "float32"])?;
        // Mitsuba 0.6's film banner switch, still in many scene files (Mitsuba 3 ignores it).
        props.bool("banner", false)?;
        props.choice("file_format", "openexr", &["openexr", "exr"])?;
        let filters = self.nested(&props, Kind::Rfilter)?;
        let filter = match filters.as_slice() {
            [] => Filter::gaussian(0.5),
            [f] => self.rfilter(f)?,
            _ => return Err(SceneError::at(&filters[1].loc, "a film takes at most one <rfilter>")),
        };
        props.finish()?;
        if let Some(w) = self.film_width {
            let h = ((height as f64 * w as f64 / width as f64).round() as u32).max(1);
            return Ok(FilmSpec { pixel_format, ..FilmSpec::new(w, h, filter) });
        }
        Ok(FilmSpec { crop: [crop_x, crop_y, crop_w, crop_h], pixel_format, ..FilmSpec::new(width, height, filter) })
    }

    fn rfilter(&self, node: &Arc<Node>) -> Result<Filter> {
        let props = Props::new(node);
        let filter = match node.plugin.as_str() {
            "box" => Filter::new(FilterKind::Box),
            "tent" => Filter::new(FilterKind::Tent { radius: props.float_checked("radius", 1.0, |r| r > 0.0 && r <= 4.0, "in (0, 4]")? }),
            "gaussian" => Filter::gaussian(props.float_checked("stddev", 0.5, |s| s > 0.0 && s <= 1.0, "in (0, 1]")?),
            "mitchell" => Filter::new(FilterKind::Mitchell {
                b: props.float_checked("B", 1.0 / 3.0, f32::is_finite, "finite")?,
                c: props.float_checked("C", 1.0 / 3.0, f32::is_finite, "finite")?,
            }),
            "catmullrom" => Filter::catmull_rom(),
            "lanczos" => Filter::new(FilterKind::Lanczos {
                lobes: props.int_checked("lobes", 3, |l| (1..=4).contains(&l), "between 1 and 4 (the film splats at most 4 pixels away)")? as u32,
            }),
            _ => return Err(unknown_plugin(node, &RFILTERS)),
        };
        props.finish()?;
        Ok(filter)
    }

    fn sampler(&self, node: &Arc<Node>) -> Result<SamplerSpec> {
        if !SAMPLERS.contains(&node.plugin.as_str()) {
            return Err(unknown_plugin(node, &SAMPLERS));
        }
        let props = Props::new(node);
        let spec = SamplerSpec::from_props(&node.plugin, &props)?;
        props.finish()?;
        Ok(spec)
    }

    /// A path depth: -1 is unlimited; values from 2^32 − 1 up are treated as
    /// unlimited too (no path gets that long), with a warning that says so.
    fn depth_limit(&self, props: &Props, name: &str, v: i64) -> u32 {
        if v < 0 {
            return u32::MAX;
        }
        if v >= u32::MAX as i64 {
            let loc = props.node.props.iter().find(|p| p.name == name).map_or(&props.node.loc, |p| &p.loc);
            self.warnings.borrow_mut().push(located_warning(
                loc,
                &format!("\"{name}\" = {v} is beyond {} and is treated as unlimited (as -1)", u32::MAX - 1),
            ));
            return u32::MAX;
        }
        v as u32
    }

    /// The integrator, and whether it asked for Stokes output (Mitsuba's
    /// `stokes`, which wraps the integrator that does the work).
    fn integrator(&self, node: &Arc<Node>) -> Result<(Integrator, bool)> {
        let props = Props::new(node);
        if node.plugin == "stokes" {
            let nested = props.children_of(Kind::Integrator);
            let inner = match nested.as_slice() {
                [child] => match &child.target {
                    ChildTarget::Inline(n) if n.plugin != "stokes" => self.integrator(n)?.0,
                    ChildTarget::Inline(n) => return Err(SceneError::at(&n.loc, "a stokes integrator cannot wrap another stokes integrator")),
                    ChildTarget::Ref(_) => return Err(SceneError::at(&child.loc, "the stokes integrator needs its integrator inline, not by <ref>")),
                },
                _ => {
                    return Err(SceneError::at(&node.loc, "the stokes integrator wraps exactly one nested <integrator> that renders the image")
                        .with_choices(&INTEGRATORS[..3]))
                }
            };
            props.finish()?;
            return Ok((inner, true));
        }
        if node.plugin == "aov" || node.plugin == "moment" {
            let integrators = self.nested_integrators(node, &props)?;
            let integrator = if node.plugin == "aov" {
                Integrator::Aov(Aov { aovs: self.aov_list(node, &props)?, integrators })
            } else {
                if integrators.is_empty() {
                    return Err(SceneError::at(&node.loc, "the moment integrator needs at least one nested <integrator> whose moments it records")
                        .with_choices(&["direct", "path", "aov", "moment"]));
                }
                Integrator::Moment(Moment { integrators })
            };
            props.finish()?;
            return Ok((integrator, false));
        }
        let integrator = match node.plugin.as_str() {
            "direct" => {
                let shading = props.int_checked("shading_samples", 1, |v| (0..=1024).contains(&v), "between 0 and 1024")?;
                let emitter_samples = props.int_checked("emitter_samples", shading, |v| (0..=1024).contains(&v), "between 0 and 1024")?;
                let bsdf_samples = props.int_checked("bsdf_samples", shading, |v| (0..=1024).contains(&v), "between 0 and 1024")?;
                self.light_sampling(&props, &LightSampling::NAMES)?;
                Integrator::Direct(Direct {
                    emitter_samples: emitter_samples as u32,
                    bsdf_samples: bsdf_samples as u32,
                    hide_emitters: props.bool("hide_emitters", false)?,
                })
            }
            "path" | "prb" | "prb_basic" => {
                // prb and prb_basic, Mitsuba's differentiable path tracers,
                // render path's image; their default depth is that of
                // Mitsuba's ADIntegrator base, 6, not path's unlimited.
                let default_depth = if node.plugin == "path" { -1 } else { 6 };
                let max_depth = props.int_checked("max_depth", default_depth, |v| v >= -1, "-1 (unlimited) or a non-negative integer")?;
                let rr_depth = props.int_checked("rr_depth", 5, |v| v > 0, "positive")?;
                self.light_sampling(&props, &LightSampling::NAMES)?;
                Integrator::Path(PathTracer {
                    max_depth: self.depth_limit(&props, "max_depth", max_depth),
                    rr_depth: self.depth_limit(&props, "rr_depth", rr_depth),
                    hide_emitters: props.bool("hide_emitters", false)?,
                    emitter_samples: props.int_checked("emitter_samples", 1, |v| (0..=1024).contains(&v), "between 0 and 1024")? as u32,
                    bsdf_samples: props.int_checked("bsdf_samples", 1, |v| (1..=1024).contains(&v), "between 1 and 1024")? as u32,
                    guiding: {
                        let spp = props.int_checked("guiding_spp", 16, |v| (1..=4096).contains(&v), "between 1 and 4096")? as u32;
                        let fraction = props.float_checked("bsdf_sampling_fraction", 0.5, |v| v > 0.0 && v <= 1.0, "in (0, 1]")?;
                        props.bool("guiding", false)?.then(|| crate::integrator::guiding::Guiding::new(spp, fraction))
                    },
                    reuse_pixels: props.int_checked("reuse_pixels", 1, |v| (1..=crate::integrator::path_reuse::MAX_GROUP as i64).contains(&v), "between 1 and 64")? as u32,
                })
            }
            "ptracer" => {
                let max_depth = props.int_checked("max_depth", -1, |v| v >= -1, "-1 (unlimited) or a non-negative integer")?;
                let rr_depth = props.int_checked("rr_depth", 5, |v| v > 0, "positive")?;
                // Mitsuba's work-splitting knob: no effect on the image.
                props.int_checked("samples_per_pass", 1, |v| v > 0, "positive")?;
                // Light paths start before there is a shading point to weigh
                // emitters by: no bvh.
                self.light_sampling(&props, &["uniform", "power"])?;
                Integrator::Particle(ParticleTracer {
                    max_depth: self.depth_limit(&props, "max_depth", max_depth),
                    rr_depth: self.depth_limit(&props, "rr_depth", rr_depth),
                    hide_emitters: props.bool("hide_emitters", false)?,
                    sphere_connection: props.bool("sphere_connection", false)?,
                })
            }
            "bdpt" => {
                let max_depth = props.int_checked("max_depth", -1, |v| v >= -1, "-1 (unlimited) or a non-negative integer")?;
                let rr_depth = props.int_checked("rr_depth", 5, |v| v > 0, "positive")?;
                let strategy_s = props.int_checked("strategy_s", -1, |v| (-1..=1 << 20).contains(&v), "-1 (every strategy) or a non-negative integer")?;
                let strategy_t = props.int_checked("strategy_t", -1, |v| v == -1 || (1..=1 << 20).contains(&v), "-1 (every strategy) or a positive integer")?;
                self.light_sampling(&props, &LightSampling::NAMES)?;
                Integrator::Bdpt(Bdpt {
                    max_depth: self.depth_limit(&props, "max_depth", max_depth),
                    rr_depth: self.depth_limit(&props, "rr_depth", rr_depth),
                    light_image: props.bool("light_image", true)?,
                    sample_direct: props.bool("sample_direct", true)?,
                    hide_emitters: props.bool("hide_emitters", false)?,
                    strategy_s: u32::try_from(strategy_s).ok(),
                    strategy_t: u32::try_from(strategy_t).ok(),
                    mis: props.bool("mis", true)?,
                })
            }
            "sppm" => {
                let max_depth = props.int_checked("max_depth", -1, |v| v == -1 || v >= 1, "-1 (unlimited) or a positive integer")?;
                let rr_depth = props.int_checked("rr_depth", 5, |v| v > 0, "positive")?;
                let photon_count = props.int_checked("photon_count", -1, |v| v == -1 || (1..=1 << 24).contains(&v), "-1 (automatic: one per pixel) or between 1 and 16777216 (2^24)")?;
                let initial_radius = props.float_checked("initial_radius", 0.0, |r| r >= 0.0 && r.is_finite(), "0 (automatic) or a positive length")?;
                let alpha = props.float_checked("alpha", 2.0 / 3.0, |a| a > 0.0 && a < 1.0, "between 0 and 1 (exclusive)")?;
                let granularity = props.int_checked("granularity", 0, |v| (0..=1 << 24).contains(&v), "0 (automatic) or a positive integer up to 2^24")?;
                let passes = props.int_checked("max_passes", -1, |v| v == -1 || (1..=MAX_SPP as i64).contains(&v), "-1 (the sampler's sample count) or between 1 and 2^24")?;
                let photons = props.choice("photons", "caustics", &SppmPhotons::NAMES)?;
                let radius_footprints = props.float_checked("radius_footprints", 1.5, |r| r > 0.0 && r <= 1e4, "a positive number of pixel footprints up to 10^4")?;
                let photons = SppmPhotons::from_name(photons).unwrap_or(SppmPhotons::Caustics);
                let vertex_radius_scale = props.float_checked("vertex_radius_scale", photons.default_vertex_radius_scale(), |r| r > 0.0 && r <= 1e4, "a positive multiple of the visible points' radius up to 10^4")?;
                let camera_paths = props.int_checked("camera_paths", 1, |v| (1..=64).contains(&v), "between 1 and 64")? as u32;
                Integrator::Sppm(Sppm {
                    camera_paths,
                    vertex_radius_scale,
                    photons,
                    radius_footprints,
                    photon_count: photon_count.max(0) as u32,
                    initial_radius,
                    alpha,
                    max_depth: self.depth_limit(&props, "max_depth", max_depth),
                    rr_depth: self.depth_limit(&props, "rr_depth", rr_depth),
                    granularity: granularity as u32,
                    max_passes: passes.max(0) as u32,
                })
            }
            "vcm" => {
                let max_depth = props.int_checked("max_depth", -1, |v| v == -1 || v >= 1, "-1 (unlimited) or a positive integer")?;
                let rr_depth = props.int_checked("rr_depth", 5, |v| v > 0, "positive")?;
                let mode = props.choice("mode", "vcm", &VcmMode::NAMES)?;
                let photon_count = props.int_checked("photon_count", -1, |v| v == -1 || (1..=1 << 24).contains(&v), "-1 (automatic: one per pixel) or between 1 and 16777216 (2^24)")?;
                let initial_radius = props.float_checked("initial_radius", 0.0, |r| r >= 0.0 && r.is_finite(), "0 (automatic) or a positive length")?;
                let radius_footprints = props.float_checked("radius_footprints", 1.5, |r| r > 0.0 && r <= 1e4, "a positive number of pixel footprints up to 10^4")?;
                let alpha = props.float_checked("alpha", 0.75, |a| a > 0.0 && a < 1.0, "between 0 and 1 (exclusive)")?;
                self.light_sampling(&props, &LightSampling::NAMES)?;
                Integrator::Vcm(Vcm {
                    max_depth: self.depth_limit(&props, "max_depth", max_depth),
                    rr_depth: self.depth_limit(&props, "rr_depth", rr_depth),
                    mode: VcmMode::from_name(mode).unwrap_or(VcmMode::Vcm),
                    photon_count: photon_count.max(0) as u32,
                    initial_radius,
                    radius_footprints,
                    alpha,
                })
            }
            "volpath" | "volpathmis" | "prbvolpath" => {
                // prbvolpath, a differentiable integrator, defaults to depth 6
                // as Mitsuba's ADIntegrator base does.
                let default_depth = if node.plugin == "prbvolpath" { 6 } else { -1 };
                let max_depth = props.int_checked("max_depth", default_depth, |v| v >= -1, "-1 (unlimited) or a non-negative integer")?;
                let rr_depth = props.int_checked("rr_depth", 5, |v| v > 0, "positive")?;
                self.light_sampling(&props, &LightSampling::NAMES)?;
                if node.plugin == "volpathmis" {
                    // Which of its estimators are on; the image converges to the same.
                    props.bool("use_spectral_mis", true)?;
                }
                Integrator::VolPath(crate::integrator::VolPath {
                    max_depth: self.depth_limit(&props, "max_depth", max_depth),
                    rr_depth: self.depth_limit(&props, "rr_depth", rr_depth),
                    hide_emitters: props.bool("hide_emitters", false)?,
                })
            }
            "depth" => Integrator::Depth(crate::integrator::Depth),
            _ => return Err(unknown_plugin(node, &INTEGRATORS)),
        };
        props.finish()?;
        Ok((integrator, false))
    }

    /// Reads an integrator's `light_sampling` (one of `choices`) if given;
    /// integrators nested in one scene must not ask for different ones.
    fn light_sampling(&self, props: &Props, choices: &[&str]) -> Result<()> {
        let Some(_) = props.string_opt("light_sampling")? else { return Ok(()) };
        let name = props.choice("light_sampling", "", choices)?;
        let Some(strategy) = LightSampling::from_name(name) else { return Ok(()) };
        match self.light_sampling.get() {
            Some(previous) if previous != strategy => Err(props.error_at(
                "light_sampling",
                format!("light_sampling \"{name}\" differs from the \"{}\" another integrator of this scene asks for", previous.name()),
            )),
            _ => {
                self.light_sampling.set(Some(strategy));
                Ok(())
            }
        }
    }

    /// The integrators nested in an `aov` or `moment` integrator, with their
    /// names (`name` attribute, else `_arg_0`, `_arg_1`, … as Mitsuba names them).
    fn nested_integrators(&self, node: &Arc<Node>, props: &Props) -> Result<Vec<(String, Integrator)>> {
        let mut out = vec![];
        let mut unnamed = 0;
        for child in props.children_of(Kind::Integrator) {
            let n = self.resolve(child)?;
            if matches!(n.plugin.as_str(), "ptracer" | "bdpt" | "stokes" | "sppm" | "vcm") {
                return Err(SceneError::at(&n.loc, format!("the {} integrator nests camera-path integrators; \"{}\" cannot be nested", node.plugin, n.plugin))
                    .with_choices(&["direct", "path", "aov", "moment"]));
            }
            let name = child.name.clone().unwrap_or_else(|| {
                unnamed += 1;
                format!("_arg_{}", unnamed - 1)
            });
            out.push((name, self.integrator(&n)?.0));
        }
        Ok(out)
    }

    /// The `aovs` string of an `aov` integrator: `NAME:TYPE` pairs separated
    /// by commas or spaces.
    fn aov_list(&self, node: &Arc<Node>, props: &Props) -> Result<Vec<(String, AovKind)>> {
        let text = props.string_req("aovs")?;
        let loc = props.node.props.iter().find(|p| p.name == "aovs").map_or(&node.loc, |p| &p.loc);
        let mut out = vec![];
        for token in text.split([',', ' ', '\t', '\n']).filter(|t| !t.is_empty()) {
            let (name, kind) = match token.split_once(':') {
                Some((n, k)) if !n.is_empty() && !k.is_empty() && !k.contains(':') => (n, k),
                _ => return Err(SceneError::at(loc, format!("\"{token}\" in \"aovs\" is not a NAME:TYPE pair (e.g. \"dd.y:depth\")")).with_choices(&AovKind::NAMES)),
            };
            let Some(kind) = AovKind::from_name(kind) else {
                let msg = if AovKind::UNSUPPORTED.contains(&kind) {
                    format!("the AOV type \"{kind}\" is not supported yet")
                } else {
                    format!("unknown AOV type \"{kind}\"")
                };
                return Err(SceneError::at(loc, msg).with_choices(&AovKind::NAMES));
            };
            if kind == AovKind::Uv {
                self.reads_uv.set(true);
            }
            out.push((name.to_string(), kind));
        }
        Ok(out)
    }
}

/// `v` rounded to the nearest IEEE half-precision value (as Mitsuba stores
/// a `float16` bitmap); out-of-range values become ±65504.
fn round_to_half(v: f32) -> f32 {
    if !v.is_finite() || v == 0.0 {
        return v;
    }
    let a = v.abs().min(65504.0);
    // Halves have 10 fraction bits; below 2⁻¹⁴ they are subnormal with a
    // fixed step of 2⁻²⁴.
    let exp = a.log2().floor().max(-14.0);
    let step = (exp - 10.0).exp2();
    ((a / step).round() * step).min(65504.0).copysign(v)
}

#[cfg(test)]
mod half_tests {
    use super::round_to_half;

    #[test]
    fn rounds_as_ieee_half() {
        assert_eq!(round_to_half(1.0), 1.0);
        assert_eq!(round_to_half(-2.5), -2.5);
        // 0.1 in half precision is 1638/16384.
        assert_eq!(round_to_half(0.1), 1638.0 / 16384.0);
        assert_eq!(round_to_half(1.0 + 1.0 / 4096.0), 1.0); // below half a step (2⁻¹⁰) rounds down
        assert_eq!(round_to_half(70000.0), 65504.0);
        assert_eq!(round_to_half(1e-8), 0.0); // under half the smallest subnormal, 2⁻²⁴
        assert_eq!(round_to_half(3.0 * (-24.0f32).exp2()), 3.0 * (-24.0f32).exp2());
    }
}

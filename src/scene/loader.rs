//! Stage 3 of scene loading: nodes → a renderable [`Scene`]. One factory per
//! kind of object (`shape`, `bsdf`, `texture`, `emitter`, `sensor`, `film`,
//! `rfilter`, `sampler`, `integrator`), each matching on the plugin name and
//! listing the valid names when it does not know one.

use super::error::{Result, SceneError};
use super::props::Props;
use super::xml::{self, Child, ChildTarget, Kind, Node};
use super::Scene;
use crate::bsdf::dispersion::DispersiveInterface;
use crate::bsdf::{Bsdf, Conductor, Lobe, Dielectric, Diffuse, Plastic, Polarizer, Retarder, ThinDielectric, TwoSided};
use crate::emitter::{AreaLight, ConstantLight, DirectionalLight, Emitter, PointLight, SpotLight};
use crate::film::{FilmSpec, Filter, FilterKind};
use crate::geometry::accel::Accel;
use crate::geometry::cylinder::Cylinder;
use crate::geometry::disk::Disk;
use crate::geometry::mesh::Mesh;
use crate::geometry::mesh_io;
use crate::geometry::serialized;
use crate::geometry::sphere::Sphere;
use crate::geometry::{Shape, ShapeGeometry};
use crate::integrator::{Direct, Integrator, ParticleTracer, PathTracer};
use crate::math::Transform;
use crate::sampler::SamplerSpec;
use crate::sensor::perspective::horizontal_fov;
use crate::sensor::{Camera, Orthographic, Perspective};
use crate::spectrum::{Emission, Rgb};
use crate::texture::bitmap::{self, Bitmap};
use crate::texture::{Checkerboard, MeshAttributeTexture, Texture, uv_transform};
use glam::{Mat4, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub const SHAPES: [&str; 10] = ["rectangle", "cube", "disk", "sphere", "cylinder", "obj", "ply", "serialized", "shapegroup", "instance"];
pub const BSDFS: [&str; 8] = ["conductor", "dielectric", "diffuse", "plastic", "polarizer", "retarder", "thindielectric", "twosided"];
pub const TEXTURES: [&str; 3] = ["bitmap", "checkerboard", "mesh_attribute"];
pub const EMITTERS: [&str; 5] = ["area", "point", "spot", "constant", "directional"];
pub const SENSORS: [&str; 2] = ["perspective", "orthographic"];
pub const FILMS: [&str; 1] = ["hdrfilm"];
pub const RFILTERS: [&str; 3] = ["box", "tent", "gaussian"];
pub const SAMPLERS: [&str; 1] = ["independent"];
pub const INTEGRATORS: [&str; 4] = ["direct", "path", "ptracer", "stokes"];

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

/// Loads scene text; relative file names resolve against `path`'s folder.
pub fn load_str(path: &Path, text: &str, options: &LoadOptions) -> Result<Scene> {
    let root = xml::parse_str(path, text, &options.params)?;
    Loader::new(&root)?.build(&root, options)
}

struct Loader {
    ids: HashMap<String, Arc<Node>>,
    bsdf_cache: HashMap<*const Node, u32>,
    bsdfs: Vec<Bsdf>,
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
    /// `mesh_attribute` textures, resolved against the meshes once all
    /// are loaded, with the location of their `name`.
    mesh_attribute_textures: std::cell::RefCell<Vec<(Arc<MeshAttributeTexture>, super::Location)>>,
}

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

/// A file name relative to the scene file that mentions it.
fn resolve_path(node: &Node, name: &str) -> PathBuf {
    let p = Path::new(name);
    if p.is_absolute() { p.to_path_buf() } else { node.loc.file.path.parent().unwrap_or(Path::new(".")).join(p) }
}

/// Default indices of refraction (Mitsuba's defaults by name).
const BK7: f32 = 1.5046;
const AIR: f32 = 1.000_277;
const POLYPROPYLENE: f32 = 1.49;

fn unknown_plugin(node: &Node, choices: &[&str]) -> SceneError {
    SceneError::at(&node.loc, format!("unknown {} plugin \"{}\"", node.kind.tag(), node.plugin)).with_choices(choices)
}

impl Loader {
    fn new(root: &Node) -> Result<Loader> {
        let mut ids = HashMap::new();
        collect_ids(root, &mut ids)?;
        Ok(Loader {
            ids,
            bsdf_cache: HashMap::new(),
            bsdfs: vec![],
            shapes: vec![],
            emitters: vec![],
            environment: None,
            top_shapes: vec![],
            groups: vec![],
            group_index: HashMap::new(),
            instances: vec![],
            in_group: false,
            mesh_attribute_textures: Default::default(),
        })
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
                    sensor = Some(self.sensor(&node)?);
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
                Kind::Scene => return Err(SceneError::at(&node.loc, "nested <scene> elements are not allowed")),
            }
        }
        let (camera, film, mut sampler) =
            sensor.ok_or_else(|| SceneError::at(&root.loc, "the scene has no <sensor>").with_help("add e.g. <sensor type=\"perspective\">…</sensor>"))?;
        if let Some(spp) = options.spp {
            sampler.sample_count = spp;
        }
        if let Some(seed) = options.seed {
            sampler.seed = seed;
        }
        let integrator =
            integrator.unwrap_or(Integrator::Path(PathTracer { max_depth: u32::MAX, rr_depth: 5, hide_emitters: false }));
        if let (Integrator::Particle(_), Some(loc)) = (&integrator, &integrator_loc) {
            // A light path must start somewhere finite and end in a pinhole.
            if !matches!(camera, Camera::Perspective(_)) {
                return Err(SceneError::at(loc, "ptracer needs a perspective sensor (light paths cannot be connected to an orthographic camera)")
                    .with_choices(&["perspective"]));
            }
            if let Some(e) = self.emitters.iter().find(|e| matches!(e, Emitter::Constant(_) | Emitter::Directional(_))) {
                let kind = if matches!(e, Emitter::Constant(_)) { "constant" } else { "directional" };
                return Err(SceneError::at(loc, format!("ptracer cannot start light paths on a \"{kind}\" emitter; use the path integrator"))
                    .with_choices(&["area", "point", "spot"]));
            }
        }
        self.resolve_mesh_attributes()?;
        let accel = Accel::build_instanced(&self.shapes, &self.top_shapes, &self.groups, &self.instances);
        Ok(Scene {
            shapes: self.shapes,
            bsdfs: self.bsdfs,
            emitters: self.emitters,
            accel,
            camera,
            film,
            sampler,
            integrator,
            stokes_requested,
            environment: self.environment,
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
                    SceneError::at(loc, "a cylinder needs p0 ≠ p1 and a to_world that is a similarity (rotation, translation, uniform scale, no mirror)")
                })?;
                ShapeGeometry::Cylinder(cylinder)
            }
            "obj" | "ply" | "serialized" => ShapeGeometry::Mesh(self.mesh_file(&props, &to_world, flip)?),
            _ => return Err(unknown_plugin(node, &SHAPES)),
        };
        let shape_index = self.shapes.len() as u32;

        let mut bsdf_nodes = self.nested(&props, Kind::Bsdf)?;
        let mut emitter_nodes = self.nested(&props, Kind::Emitter)?;
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
        let emitter = match emitter_nodes.first() {
            Some(e) => Some(self.area_emitter(e, shape_index)?),
            None => None,
        };
        props.finish()?;
        let tangent_frame = self.bsdfs[bsdf as usize].needs_tangent_frame();
        let shape = Shape { geometry, bsdf, emitter, tangent_frame };
        if shape.area() <= 0.0 || !shape.area().is_finite() {
            return Err(SceneError::at(&node.loc, format!("this {} has zero or non-finite surface area", node.plugin)));
        }
        if !self.in_group {
            self.top_shapes.push(self.shapes.len() as u32);
        }
        self.shapes.push(shape);
        Ok(())
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
        let path = resolve_path(node, filename);
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
        .map_err(|e| SceneError::at(file_loc, e))?;
        let positions: Vec<Vec3> = raw.positions.iter().map(|&p| to_world.point(p)).collect();
        let normals = if face_normals {
            None
        } else {
            Some(match raw.normals {
                Some(ns) => ns.iter().map(|&n| to_world.normal(n)).collect(),
                None => Mesh::compute_vertex_normals(&positions, &raw.triangles),
            })
        };
        // tobj applied Mitsuba's default flip already; undo it if asked.
        // PLY and serialized texture coordinates are used as stored (as Mitsuba does).
        let undo_flip = node.plugin == "obj" && !flip_tex;
        let uvs = raw.uvs.map(|uvs| if !undo_flip { uvs } else { uvs.into_iter().map(|uv| glam::Vec2::new(uv.x, 1.0 - uv.y)).collect() });
        let attributes = raw.attributes.iter().map(|(n, a)| (n.clone(), Arc::new(a.to_corners(&raw.triangles)))).collect();
        let mut mesh = Mesh::new(positions, normals, uvs, raw.triangles, flip);
        mesh.attributes = attributes;
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

    fn make_bsdf(&mut self, node: &Arc<Node>) -> Result<Bsdf> {
        let props = Props::new(node);
        let bsdf = match node.plugin.as_str() {
            "diffuse" => Bsdf::Diffuse(Diffuse { reflectance: self.texture_input(&props, "reflectance", Rgb::new(0.5, 0.5, 0.5))? }),
            "polarizer" => Bsdf::Polarizer(Polarizer {
                theta: props.float_checked("theta", 0.0, f32::is_finite, "an angle in degrees")?.to_radians(),
                transmittance: self.texture_input(&props, "transmittance", Rgb::WHITE)?,
                polarizing: props.bool("polarizing", true)?,
            }),
            "retarder" => Bsdf::Retarder(Retarder {
                theta: props.float_checked("theta", 0.0, f32::is_finite, "an angle in degrees")?.to_radians(),
                delta: props.float_checked("delta", 90.0, f32::is_finite, "an angle in degrees")?.to_radians(),
                transmittance: self.texture_input(&props, "transmittance", Rgb::WHITE)?,
            }),
            "conductor" => self.conductor(node, &props)?,
            "dielectric" | "thindielectric" => {
                let int_ior = props.ior_spectrum("int_ior", BK7)?;
                let ext_ior = props.ior_spectrum("ext_ior", AIR)?;
                let specular_reflectance = self.texture_input(&props, "specular_reflectance", Rgb::WHITE)?;
                let specular_transmittance = self.texture_input(&props, "specular_transmittance", Rgb::WHITE)?;
                let eta = int_ior.nominal() / ext_ior.nominal();
                let dispersive = int_ior.is_dispersive() || ext_ior.is_dispersive();
                if node.plugin == "dielectric" {
                    let dispersion = dispersive.then(|| Box::new(DispersiveInterface { int_ior, ext_ior }));
                    Bsdf::Dielectric(Dielectric { eta, dispersion, specular_reflectance, specular_transmittance })
                } else {
                    if dispersive {
                        let which = if int_ior.is_dispersive() { "int_ior" } else { "ext_ior" };
                        return Err(props.error_at(which, "thindielectric does not bend light, so it cannot disperse it: give a constant index"));
                    }
                    Bsdf::ThinDielectric(ThinDielectric { eta, specular_reflectance, specular_transmittance })
                }
            }
            "plastic" => {
                let int_ior = props.ior("int_ior", POLYPROPYLENE)?;
                let ext_ior = props.ior("ext_ior", AIR)?;
                let diffuse = self.texture_input(&props, "diffuse_reflectance", Rgb::new(0.5, 0.5, 0.5))?;
                let specular = if props.has("specular_reflectance") || props.has_child("specular_reflectance") {
                    Some(self.texture_input(&props, "specular_reflectance", Rgb::WHITE)?)
                } else {
                    None
                };
                let nonlinear = props.bool("nonlinear", false)?;
                Bsdf::Plastic(Plastic::new(diffuse, specular, int_ior / ext_ior, nonlinear))
            }
            "twosided" => {
                let mut nested = self.nested(&props, Kind::Bsdf)?;
                for r in props.unnamed_refs() {
                    let t = self.resolve(r)?;
                    if t.kind != Kind::Bsdf {
                        return Err(SceneError::at(&r.loc, format!("twosided takes BSDFs, not a <{}>", t.kind.tag())));
                    }
                    nested.push(t);
                }
                if nested.is_empty() || nested.len() > 2 {
                    return Err(SceneError::at(&node.loc, "twosided takes one nested BSDF (or two: front and back)"));
                }
                let mut sides = vec![];
                for n in &nested {
                    let b = self.make_bsdf(n)?;
                    if let Bsdf::TwoSided(_) = b {
                        return Err(SceneError::at(&n.loc, "twosided cannot nest another twosided"));
                    }
                    if b.lobes().intersects(Lobe::DIFFUSE_TRANSMISSION | Lobe::GLOSSY_TRANSMISSION | Lobe::DELTA_TRANSMISSION) {
                        return Err(SceneError::at(&n.loc, format!("twosided cannot nest a transmitting BSDF (\"{}\"); it already scatters on both sides", n.plugin)));
                    }
                    sides.push(b);
                }
                let front = sides.remove(0);
                let back = sides.pop().unwrap_or_else(|| front.clone());
                Bsdf::TwoSided(TwoSided { front: Box::new(front), back: Box::new(back) })
            }
            _ => return Err(unknown_plugin(node, &BSDFS)),
        };
        props.finish()?;
        Ok(bsdf)
    }

    /// `conductor`: η and k given directly, or a named metal (or `none`).
    fn conductor(&self, node: &Arc<Node>, props: &Props) -> Result<Bsdf> {
        let specular_reflectance = self.texture_input(props, "specular_reflectance", Rgb::WHITE)?;
        let material = props.string_opt("material")?;
        let given = props.has("eta") || props.has("k");
        let mut spectra = None;
        let (eta, k) = match material {
            Some(name) if name != "none" => {
                let loc = node.props.iter().find(|p| p.name == "material").map_or(&node.loc, |p| &p.loc);
                if given {
                    return Err(SceneError::at(loc, "give either \"material\" or \"eta\"/\"k\", not both"));
                }
                let metal = crate::bsdf::metals::METALS.iter().find(|m| m.name == name).ok_or_else(|| {
                    let mut names: Vec<&str> = crate::bsdf::metals::METALS.iter().map(|m| m.name).collect();
                    names.push("none");
                    SceneError::at(loc, format!("unknown conductor material \"{name}\"")).with_choices(&names)
                })?;
                spectra = crate::bsdf::metal_spectra::METAL_SPECTRA.iter().find(|m| m.name == name);
                (Rgb(metal.eta), Rgb(metal.k))
            }
            _ => (props.color("eta", Rgb::BLACK)?, props.color("k", Rgb::WHITE)?),
        };
        if !(eta.is_finite() && k.is_finite() && eta.0.iter().chain(&k.0).all(|&v| v >= 0.0)) {
            return Err(SceneError::at(&node.loc, "conductor \"eta\" and \"k\" must be finite and not negative"));
        }
        Ok(Bsdf::Conductor(Conductor { eta, k, spectra, specular_reflectance }))
    }

    /// A colour parameter: `rgb`/`spectrum`/`float`, or a nested (or referenced) texture.
    fn texture_input(&self, props: &Props, name: &str, default: Rgb) -> Result<Texture> {
        if let Some(listed) = props.listed_opt(name) {
            return Ok(Texture::Spectral { rgb: listed.to_rgb(false), spectrum: Arc::new(listed) });
        }
        if let Some(c) = props.color_opt(name)? {
            return Ok(Texture::constant(c));
        }
        match props.child_named(name) {
            Some(child) => {
                let node = self.resolve(child)?;
                if node.kind != Kind::Texture {
                    return Err(SceneError::at(&child.loc, format!("\"{name}\" must be a colour or a <texture>, not a <{}>", node.kind.tag())));
                }
                self.texture(&node)
            }
            None => Ok(Texture::constant(default)),
        }
    }

    fn texture(&self, node: &Arc<Node>) -> Result<Texture> {
        let props = Props::new(node);
        let to_uv = uv_transform(&props.transform("to_uv")?.matrix);
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
                let path = resolve_path(node, filename);
                let loc = node.props.iter().find(|p| p.name == "filename").map_or(&node.loc, |p| &p.loc);
                let (width, height, texels) = bitmap::read_image(&path, raw).map_err(|e| SceneError::at(loc, e))?;
                if width == 0 || height == 0 {
                    return Err(SceneError::at(loc, format!("image {} is empty", path.display())));
                }
                Texture::Bitmap(Arc::new(Bitmap { width, height, texels, filter, wrap, to_uv }))
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
        let radiance = props.emission_opt("radiance")?.ok_or_else(|| SceneError::at(&node.loc, "area emitter needs \"radiance\""))?;
        props.finish()?;
        self.emitters.push(Emitter::Area(AreaLight { shape, radiance }));
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
                Emitter::Spot(SpotLight::new(to_world.point(Vec3::ZERO), axis, intensity, cutoff, beam))
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

    fn sensor(&self, node: &Arc<Node>) -> Result<(Camera, FilmSpec, SamplerSpec)> {
        let props = Props::new(node);
        if !SENSORS.contains(&node.plugin.as_str()) {
            return Err(unknown_plugin(node, &SENSORS));
        }
        let films = self.nested(&props, Kind::Film)?;
        let samplers = self.nested(&props, Kind::Sampler)?;
        if films.len() > 1 || samplers.len() > 1 {
            return Err(SceneError::at(&node.loc, "a sensor takes at most one <film> and one <sampler>"));
        }
        let film = match films.first() {
            Some(f) => self.film(f)?,
            None => FilmSpec { width: 768, height: 576, filter: Filter::gaussian(0.5) },
        };
        let sampler = match samplers.first() {
            Some(s) => self.sampler(s)?,
            None => SamplerSpec { sample_count: 4, seed: 0 },
        };
        let aspect = film.width as f32 / film.height as f32;
        let to_world = props.transform("to_world")?;
        let near_clip = props.float_checked("near_clip", 0.01, |v| v >= 0.0, "non-negative")?;
        let far_clip = props.float_checked("far_clip", 10000.0, |v| v > near_clip, "greater than near_clip")?;
        let camera = match node.plugin.as_str() {
            "perspective" => {
                let fov = props.float_checked("fov", f32::NAN, |f| f > 0.0 && f < 180.0, "an angle in (0, 180) degrees")?;
                let axis = props.choice("fov_axis", "x", &["x", "y", "smaller", "larger", "diagonal"])?;
                // A pinhole has everything in focus; the distance is accepted for Mitsuba compatibility.
                props.float_checked("focus_distance", 1.0, |v| v > 0.0, "positive")?;
                let fov_x = horizontal_fov(fov, axis, aspect);
                Camera::Perspective(Perspective::new(to_world, (fov_x.to_radians() * 0.5).tan(), aspect, near_clip, far_clip))
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
        props.choice("pixel_format", "rgb", &["rgb"])?;
        props.choice("component_format", "float32", &["float16", "float32"])?;
        props.choice("file_format", "openexr", &["openexr", "exr"])?;
        let filters = self.nested(&props, Kind::Rfilter)?;
        let filter = match filters.as_slice() {
            [] => Filter::gaussian(0.5),
            [f] => self.rfilter(f)?,
            _ => return Err(SceneError::at(&filters[1].loc, "a film takes at most one <rfilter>")),
        };
        props.finish()?;
        Ok(FilmSpec { width, height, filter })
    }

    fn rfilter(&self, node: &Arc<Node>) -> Result<Filter> {
        let props = Props::new(node);
        let filter = match node.plugin.as_str() {
            "box" => Filter::new(FilterKind::Box),
            "tent" => Filter::new(FilterKind::Tent { radius: props.float_checked("radius", 1.0, |r| r > 0.0 && r <= 4.0, "in (0, 4]")? }),
            "gaussian" => Filter::gaussian(props.float_checked("stddev", 0.5, |s| s > 0.0 && s <= 1.0, "in (0, 1]")?),
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
        let sample_count = props.int_checked("sample_count", 4, |v| (1..=1 << 24).contains(&v), "between 1 and 16777216")? as u32;
        let seed = props.int_checked("seed", 0, |v| v >= 0, "non-negative")? as u64;
        props.finish()?;
        Ok(SamplerSpec { sample_count, seed })
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
        let integrator = match node.plugin.as_str() {
            "direct" => {
                let shading = props.int_checked("shading_samples", 1, |v| (0..=1024).contains(&v), "between 0 and 1024")?;
                let emitter_samples = props.int_checked("emitter_samples", shading, |v| (0..=1024).contains(&v), "between 0 and 1024")?;
                let bsdf_samples = props.int_checked("bsdf_samples", shading, |v| (0..=1024).contains(&v), "between 0 and 1024")?;
                Integrator::Direct(Direct {
                    emitter_samples: emitter_samples as u32,
                    bsdf_samples: bsdf_samples as u32,
                    hide_emitters: props.bool("hide_emitters", false)?,
                })
            }
            "path" => {
                let max_depth = props.int_checked("max_depth", -1, |v| v >= -1, "-1 (unlimited) or a non-negative integer")?;
                let rr_depth = props.int_checked("rr_depth", 5, |v| v > 0, "positive")?;
                Integrator::Path(PathTracer {
                    max_depth: if max_depth < 0 { u32::MAX } else { max_depth.min(u32::MAX as i64) as u32 },
                    rr_depth: rr_depth.min(u32::MAX as i64) as u32,
                    hide_emitters: props.bool("hide_emitters", false)?,
                })
            }
            "ptracer" => {
                let max_depth = props.int_checked("max_depth", -1, |v| v >= -1, "-1 (unlimited) or a non-negative integer")?;
                let rr_depth = props.int_checked("rr_depth", 5, |v| v > 0, "positive")?;
                // Mitsuba's work-splitting knob: no effect on the image.
                props.int_checked("samples_per_pass", 1, |v| v > 0, "positive")?;
                Integrator::Particle(ParticleTracer {
                    max_depth: if max_depth < 0 { u32::MAX } else { max_depth.min(u32::MAX as i64) as u32 },
                    rr_depth: rr_depth.min(u32::MAX as i64) as u32,
                    hide_emitters: props.bool("hide_emitters", false)?,
                })
            }
            _ => return Err(unknown_plugin(node, &INTEGRATORS)),
        };
        props.finish()?;
        Ok((integrator, false))
    }
}

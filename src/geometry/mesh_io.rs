//! Reading triangle meshes from OBJ (a strict reader of its own, which
//! reports the line of each problem) and PLY (via `ply-rs-bw`)
//! files, into object space. Errors are plain messages; the scene loader adds
//! the location of the `<shape>` that named the file.

use glam::{Vec2, Vec3};
use std::path::Path;

/// A mesh as read from a file, before `to_world`.
#[derive(Debug, Default)]
pub struct RawMesh {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
    pub triangles: Vec<[u32; 3]>,
    /// Other per-vertex or per-face data (PLY properties beyond positions,
    /// normals and uvs), by Mitsuba's name: `vertex_color`, `face_weight`, …
    pub attributes: Vec<(String, Attribute)>,
}

/// A mesh attribute: `dims` values per vertex or per triangle.
#[derive(Clone, Debug)]
pub struct Attribute {
    pub per_face: bool,
    pub dims: usize,
    pub data: Vec<f32>,
}

impl Attribute {
    /// A per-vertex attribute as values per triangle corner (3 × dims per
    /// triangle), so a hit reads its triangle's values directly.
    pub fn to_corners(&self, triangles: &[[u32; 3]]) -> Attribute {
        if self.per_face {
            return self.clone();
        }
        let d = self.dims;
        let mut data = Vec::with_capacity(triangles.len() * 3 * d);
        for t in triangles {
            for &v in t {
                data.extend_from_slice(&self.data[v as usize * d..(v as usize + 1) * d]);
            }
        }
        Attribute { per_face: false, dims: d, data }
    }
}

/// Groups a PLY element's extra properties into attributes as Mitsuba
/// does: `r g b` / `red green blue` become `color` (8-bit values divided
/// by 255), `name_0, name_1, …` become `name` with that many components,
/// any other property `name` a one-component attribute. Returns (name,
/// property names in component order, divide by 255).
fn attribute_groups(keys: &[String], skip: &[&str]) -> Vec<(String, Vec<String>)> {
    let keys: Vec<&String> = keys.iter().filter(|k| !skip.contains(&k.as_str())).collect();
    let mut groups: Vec<(String, Vec<String>)> = vec![];
    let mut used = vec![false; keys.len()];
    for colour in [["r", "g", "b"], ["red", "green", "blue"]] {
        if colour.iter().all(|c| keys.iter().any(|k| k.as_str() == *c)) {
            for (i, k) in keys.iter().enumerate() {
                used[i] |= colour.contains(&k.as_str());
            }
            groups.push(("color".into(), colour.iter().map(|c| c.to_string()).collect()));
        }
    }
    for (i, k) in keys.iter().enumerate() {
        if used[i] {
            continue;
        }
        let (prefix, index) = match k.rsplit_once('_') {
            Some((p, n)) if !p.is_empty() && n.parse::<usize>().is_ok_and(|i| i < 16) => (p.to_string(), n.parse::<usize>().unwrap_or(0)),
            _ => (k.to_string(), 0),
        };
        match groups.iter_mut().find(|(name, _)| *name == prefix) {
            Some((_, members)) => {
                if members.len() <= index {
                    members.resize(index + 1, String::new());
                }
                members[index] = k.to_string();
            }
            None => {
                let mut members = vec![String::new(); index + 1];
                members[index] = k.to_string();
                groups.push((prefix, members));
            }
        }
    }
    groups
}

impl RawMesh {
    pub(crate) fn validate(self) -> Result<RawMesh, String> {
        let n = self.positions.len() as u32;
        if self.triangles.is_empty() {
            return Err("the mesh has no faces".into());
        }
        if let Some(bad) = self.triangles.iter().flatten().find(|&&i| i >= n) {
            return Err(format!("a face refers to vertex {bad}, but the mesh has {n} vertices"));
        }
        if self.positions.iter().any(|p| !p.is_finite()) {
            return Err("the mesh has a vertex position that is not a finite number".into());
        }
        if self.normals.as_ref().is_some_and(|ns| ns.len() != n as usize || ns.iter().any(|v| !v.is_finite())) {
            return Err("the mesh's vertex normals do not match its vertices".into());
        }
        if self.uvs.as_ref().is_some_and(|uv| uv.len() != n as usize || uv.iter().any(|v| !v.is_finite())) {
            return Err("the mesh's texture coordinates do not match its vertices".into());
        }
        for (name, a) in &self.attributes {
            let count = if a.per_face { self.triangles.len() } else { n as usize };
            if a.dims == 0 || a.data.len() != count * a.dims || a.data.iter().any(|v| !v.is_finite()) {
                return Err(format!("the mesh attribute \"{name}\" does not match its {}", if a.per_face { "faces" } else { "vertices" }));
            }
        }
        Ok(self)
    }
}

/// Reads an OBJ file; all its objects become one mesh. Texture v is flipped
/// (v ↦ 1 − v) as Mitsuba's OBJ loader does by default.
///
/// Strict, with the line of each problem: a number that does not parse, a
/// face with fewer than three vertices, or a face naming a position,
/// texture coordinate or normal the file does not have is an error.
/// Indices are 1-based, or negative (relative to the end of the list so
/// far); polygons are fanned into triangles. Statements other than `v`,
/// `vt`, `vn` and `f` (groups, materials, lines, points) are ignored.
pub fn read_obj(path: &Path) -> Result<RawMesh, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read OBJ file {}: {e}", path.display()))?;
    let text = String::from_utf8_lossy(&bytes);
    parse_obj(&text).map_err(|(line, e)| format!("cannot read OBJ file {}:{line}: {e}", path.display()))
}

/// One face corner: indices (0-based, already resolved) of position,
/// texture coordinate and normal.
type Corner = (u32, Option<u32>, Option<u32>);

/// [`read_obj`] on text; errors carry the 1-based line.
pub fn parse_obj(text: &str) -> Result<RawMesh, (usize, String)> {
    let mut positions: Vec<Vec3> = vec![];
    let mut texcoords: Vec<Vec2> = vec![];
    let mut vnormals: Vec<Vec3> = vec![];
    // Faces as (line, corners), resolved once the whole file is read (a
    // positive index may name a vertex given later).
    let mut faces: Vec<(usize, Vec<(i64, Option<i64>, Option<i64>)>)> = vec![];
    let mut counts_at_face: Vec<[usize; 3]> = vec![];
    let number = |tok: Option<&str>, what: &str, line: usize| -> Result<f32, (usize, String)> {
        let t = tok.ok_or_else(|| (line, format!("{what} is missing a number")))?;
        let v: f32 = t.parse().map_err(|_| (line, format!("\"{t}\" in {what} is not a number")))?;
        if !v.is_finite() {
            return Err((line, format!("{what} has a value that is not a finite number ({t})")));
        }
        Ok(v)
    };
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else { continue };
        match keyword {
            "v" => {
                let p = Vec3::new(number(tokens.next(), "a vertex", line)?, number(tokens.next(), "a vertex", line)?, number(tokens.next(), "a vertex", line)?);
                positions.push(p);
            }
            "vt" => {
                let u = number(tokens.next(), "a texture coordinate", line)?;
                let v = match tokens.next() {
                    Some(t) => number(Some(t), "a texture coordinate", line)?,
                    None => 0.0,
                };
                texcoords.push(Vec2::new(u, 1.0 - v));
            }
            "vn" => {
                let n = Vec3::new(number(tokens.next(), "a normal", line)?, number(tokens.next(), "a normal", line)?, number(tokens.next(), "a normal", line)?);
                vnormals.push(n);
            }
            "f" => {
                let mut corners = vec![];
                for tok in tokens {
                    let mut parts = tok.split('/');
                    let index = |s: Option<&str>, what: &str| -> Result<Option<i64>, (usize, String)> {
                        match s {
                            None | Some("") => Ok(None),
                            Some(t) => match t.parse::<i64>() {
                                Ok(0) => Err((line, format!("face vertex index out of bounds: {what} index 0 in \"{tok}\" (OBJ indices start at 1)"))),
                                Ok(v) => Ok(Some(v)),
                                Err(_) => Err((line, format!("\"{tok}\" is not a face vertex (v, v/vt, v//vn or v/vt/vn)"))),
                            },
                        }
                    };
                    let v = index(parts.next(), "vertex")?
                        .ok_or_else(|| (line, format!("\"{tok}\" has no vertex index")))?;
                    let vt = index(parts.next(), "texture coordinate")?;
                    let vn = index(parts.next(), "normal")?;
                    if parts.next().is_some() {
                        return Err((line, format!("\"{tok}\" is not a face vertex (v, v/vt, v//vn or v/vt/vn)")));
                    }
                    corners.push((v, vt, vn));
                }
                if corners.len() < 3 {
                    return Err((line, format!("a face has {} vertices; a face needs at least three", corners.len())));
                }
                faces.push((line, corners));
                counts_at_face.push([positions.len(), texcoords.len(), vnormals.len()]);
            }
            _ => {}
        }
    }
    if faces.is_empty() {
        return Err((text.lines().count().max(1), "the mesh has no faces".into()));
    }
    // Resolve: positive indices against the whole file, negative ones
    // against the lists as they were at the face.
    let resolve = |i: i64, total: usize, so_far: usize, what: &str, line: usize| -> Result<u32, (usize, String)> {
        let r = if i > 0 { i - 1 } else { so_far as i64 + i };
        if r < 0 || r >= total as i64 {
            let have = if total == 0 { format!("the file has no {what}s") } else { format!("the file has {total}") };
            return Err((line, format!("face vertex index out of bounds: a face names {what} {i}, but {have}")));
        }
        Ok(r as u32)
    };
    let mut corners_all: Vec<(usize, Vec<Corner>)> = Vec::with_capacity(faces.len());
    let (mut all_uv, mut all_n) = (true, true);
    for ((line, corners), counts) in faces.iter().zip(&counts_at_face) {
        let mut out = Vec::with_capacity(corners.len());
        for &(v, vt, vn) in corners {
            let v = resolve(v, positions.len(), counts[0], "vertex", *line)?;
            let vt = vt.map(|i| resolve(i, texcoords.len(), counts[1], "texture coordinate", *line)).transpose()?;
            let vn = vn.map(|i| resolve(i, vnormals.len(), counts[2], "normal", *line)).transpose()?;
            all_uv &= vt.is_some();
            all_n &= vn.is_some();
            out.push((v, vt, vn));
        }
        corners_all.push((*line, out));
    }
    // One vertex per distinct (position, uv, normal) in use.
    let mut out = RawMesh::default();
    let mut uvs = vec![];
    let mut normals = vec![];
    let mut map: std::collections::HashMap<Corner, u32> = std::collections::HashMap::new();
    for (_, corners) in &corners_all {
        let mut ids = Vec::with_capacity(corners.len());
        for &(v, vt, vn) in corners {
            let key = (v, vt.filter(|_| all_uv), vn.filter(|_| all_n));
            let id = *map.entry(key).or_insert_with(|| {
                out.positions.push(positions[v as usize]);
                if all_uv {
                    uvs.push(texcoords[vt.unwrap_or(0) as usize]);
                }
                if all_n {
                    normals.push(vnormals[vn.unwrap_or(0) as usize]);
                }
                out.positions.len() as u32 - 1
            });
            ids.push(id);
        }
        for k in 1..ids.len() - 1 {
            out.triangles.push([ids[0], ids[k], ids[k + 1]]);
        }
    }
    out.normals = all_n.then_some(normals);
    out.uvs = all_uv.then_some(uvs);
    out.validate().map_err(|e| (1, e))
}

/// Reads an ASCII or binary PLY file with `vertex` (x, y, z and optionally
/// nx, ny, nz and u, v / s, t / texture_u, texture_v) and `face`
/// (`vertex_indices` or `vertex_index` lists; polygons are fanned).
pub fn read_ply(path: &Path) -> Result<RawMesh, String> {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};
    let file = std::fs::File::open(path).map_err(|e| format!("cannot open PLY file {}: {e}", path.display()))?;
    let mut reader = std::io::BufReader::new(file);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut reader)
        .map_err(|e| format!("cannot read PLY file {}: {e}", path.display()))?;

    fn scalar(p: Option<&Property>) -> Option<f32> {
        Some(match p? {
            Property::Char(v) => *v as f32,
            Property::UChar(v) => *v as f32,
            Property::Short(v) => *v as f32,
            Property::UShort(v) => *v as f32,
            Property::Int(v) => *v as f32,
            Property::UInt(v) => *v as f32,
            Property::Float(v) => *v,
            Property::Double(v) => *v as f32,
            _ => return None,
        })
    }
    fn index_list(p: Option<&Property>) -> Option<Vec<i64>> {
        Some(match p? {
            Property::ListChar(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListUChar(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListShort(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListUShort(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListInt(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListUInt(v) => v.iter().map(|&x| x as i64).collect(),
            _ => return None,
        })
    }

    let err = |m: &str| format!("{}: {m}", path.display());
    let vertices = ply.payload.get("vertex").ok_or_else(|| err("no \"vertex\" element"))?;
    let faces = ply.payload.get("face").ok_or_else(|| err("no \"face\" element"))?;
    let mut out = RawMesh::default();
    let first = vertices.first();
    let has = |k: &str| first.is_some_and(|v| v.contains_key(k));
    let uv_keys = [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")]
        .into_iter()
        .find(|(a, b)| has(a) && has(b));
    let has_normals = has("nx") && has("ny") && has("nz");
    let mut skip = vec!["x", "y", "z"];
    if has_normals {
        skip.extend(["nx", "ny", "nz"]);
    }
    if let Some((a, b)) = uv_keys {
        skip.extend([a, b]);
    }
    let vertex_keys: Vec<String> = first.map(|v| v.keys().cloned().collect()).unwrap_or_default();
    let face_keys: Vec<String> = faces.first().map(|f| f.keys().cloned().collect()).unwrap_or_default();
    let vertex_groups = attribute_groups(&vertex_keys, &skip);
    let face_groups = attribute_groups(&face_keys, &["vertex_indices", "vertex_index"]);
    let mut vertex_data: Vec<Vec<f32>> = vec![vec![]; vertex_groups.len()];
    let mut face_data: Vec<Vec<f32>> = vec![vec![]; face_groups.len()];
    // A group's values for one element; None if one is missing or not a number.
    fn values(e: &DefaultElement, members: &[String], out: &mut Vec<f32>) -> Option<()> {
        for m in members {
            let p = e.get(m)?;
            let v = scalar(Some(p))?;
            out.push(if matches!(p, Property::UChar(_)) && members.len() >= 3 && (m == "r" || m == "g" || m == "b" || m == "red" || m == "green" || m == "blue") { v / 255.0 } else { v });
        }
        Some(())
    }
    let mut normals = vec![];
    let mut uvs = vec![];
    for v in vertices {
        let p = Vec3::new(
            scalar(v.get("x")).ok_or_else(|| err("a vertex has no numeric x"))?,
            scalar(v.get("y")).ok_or_else(|| err("a vertex has no numeric y"))?,
            scalar(v.get("z")).ok_or_else(|| err("a vertex has no numeric z"))?,
        );
        out.positions.push(p);
        if has_normals {
            let n = (scalar(v.get("nx")), scalar(v.get("ny")), scalar(v.get("nz")));
            match n {
                (Some(x), Some(y), Some(z)) => normals.push(Vec3::new(x, y, z)),
                _ => return Err(err("a vertex normal is not numeric")),
            }
        }
        if let Some((ku, kv)) = uv_keys {
            match (scalar(v.get(ku)), scalar(v.get(kv))) {
                (Some(u), Some(w)) => uvs.push(Vec2::new(u, w)),
                _ => return Err(err("a texture coordinate is not numeric")),
            }
        }
        for ((name, members), out) in vertex_groups.iter().zip(&mut vertex_data) {
            values(v, members, out).ok_or_else(|| err(&format!("vertex attribute \"{name}\" is missing or not numeric on a vertex")))?;
        }
    }
    for f in faces {
        let idx = index_list(f.get("vertex_indices").or_else(|| f.get("vertex_index")))
            .ok_or_else(|| err("a face has no integer list \"vertex_indices\""))?;
        if idx.len() < 3 {
            return Err(err("a face has fewer than three vertices"));
        }
        if idx.iter().any(|&i| i < 0 || i > u32::MAX as i64) {
            return Err(err("a face has a vertex index that is negative or too large"));
        }
        let mut face_values = vec![];
        for ((name, members), out) in face_groups.iter().zip(&mut face_data) {
            face_values.clear();
            values(f, members, &mut face_values).ok_or_else(|| err(&format!("face attribute \"{name}\" is missing or not numeric on a face")))?;
            // A polygon is fanned into triangles that share its values.
            for _ in 1..idx.len() - 1 {
                out.extend_from_slice(&face_values);
            }
        }
        for k in 1..idx.len() - 1 {
            out.triangles.push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
        }
    }
    for ((name, members), data) in vertex_groups.into_iter().zip(vertex_data) {
        out.attributes.push((format!("vertex_{name}"), Attribute { per_face: false, dims: members.len(), data }));
    }
    for ((name, members), data) in face_groups.into_iter().zip(face_data) {
        out.attributes.push((format!("face_{name}"), Attribute { per_face: true, dims: members.len(), data }));
    }
    out.normals = has_normals.then_some(normals);
    out.uvs = uv_keys.is_some().then_some(uvs);
    out.validate().map_err(|e| err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_with_quads_and_uvs() {
        let dir = std::env::temp_dir().join(format!("snell-obj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("quad.obj");
        std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n").unwrap();
        let m = read_obj(&p).unwrap();
        assert_eq!(m.triangles.len(), 2);
        assert!(m.normals.is_none());
        let uvs = m.uvs.unwrap();
        // v is flipped: the vertex with vt 0 0 gets uv (0, 1).
        let i0 = m.positions.iter().position(|p| *p == Vec3::ZERO).unwrap();
        assert_eq!(uvs[i0], Vec2::new(0.0, 1.0));
    }

    #[test]
    fn ply_ascii_with_normals() {
        let dir = std::env::temp_dir().join(format!("snell-ply-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("tri.ply");
        std::fs::write(
            &p,
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n",
        )
        .unwrap();
        let m = read_ply(&p).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(m.normals.unwrap()[2], Vec3::Z);
        let bad = dir.join("bad.ply");
        std::fs::write(&bad, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 2\n").unwrap();
        assert!(read_ply(&bad).unwrap_err().contains("vertex"));
    }
}

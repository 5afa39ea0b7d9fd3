//! Reading triangle meshes from OBJ (via `tobj`) and PLY (via `ply-rs-bw`)
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
        Ok(self)
    }
}

/// Reads an OBJ file; all its objects become one mesh. Texture v is flipped
/// (v ↦ 1 − v) as Mitsuba's OBJ loader does by default.
pub fn read_obj(path: &Path) -> Result<RawMesh, String> {
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, _) = tobj::load_obj(path, &options).map_err(|e| format!("cannot read OBJ file {}: {e}", path.display()))?;
    let mut out = RawMesh::default();
    let mut all_have_normals = true;
    let mut all_have_uvs = true;
    let mut normals = vec![];
    let mut uvs = vec![];
    for m in &models {
        let mesh = &m.mesh;
        let base = out.positions.len() as u32;
        let nv = mesh.positions.len() / 3;
        out.positions.extend(mesh.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
        if mesh.normals.len() == nv * 3 && nv > 0 {
            normals.extend(mesh.normals.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
        } else {
            all_have_normals = false;
        }
        if mesh.texcoords.len() == nv * 2 && nv > 0 {
            uvs.extend(mesh.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], 1.0 - c[1])));
        } else {
            all_have_uvs = false;
        }
        out.triangles.extend(mesh.indices.chunks_exact(3).map(|c| [c[0] + base, c[1] + base, c[2] + base]));
    }
    out.normals = all_have_normals.then_some(normals);
    out.uvs = all_have_uvs.then_some(uvs);
    out.validate().map_err(|e| format!("{}: {e}", path.display()))
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
        for k in 1..idx.len() - 1 {
            out.triangles.push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
        }
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

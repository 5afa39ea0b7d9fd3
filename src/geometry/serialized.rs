//! Mitsuba's `serialized` mesh format: one or more zlib-compressed indexed
//! triangle meshes in one file.
//!
//! | parameter      | type      | default  | meaning                                                |
//! |----------------|-----------|----------|--------------------------------------------------------|
//! | `filename`     | string    | required | the `.serialized` file                                 |
//! | `shape_index`  | integer   | 0        | which mesh of the file to load (the first is 0)        |
//! | `face_normals` | boolean   | false    | discard vertex normals, shade with the face normals    |
//! | `flip_normals` | boolean   | false    | negate all normals                                     |
//! | `to_world`     | transform | identity | object-to-world transform                              |
//!
//! ```xml
//! <shape type="serialized">
//!     <string name="filename" value="meshes/matpreview.serialized"/>
//!     <integer name="shape_index" value="1"/>
//! </shape>
//! ```
//!
//! Layout (little endian). Each mesh: `u16` magic `0x041C`, `u16` version
//! (3 or 4), then a zlib stream holding `u32` flags (`0x1` normals, `0x2`
//! texture coordinates, `0x8` vertex colours, `0x10` face normals, `0x1000`
//! single, `0x2000` double precision), in version 4 a NUL-terminated name,
//! `u64` vertex count, `u64` triangle count, positions, [normals], [uvs],
//! [colours] (3, 3, 2, 3 reals per vertex) and the `u32` vertex indices (3
//! per triangle). Meshes are concatenated; the file ends with the byte
//! offset of every mesh (`u64` in version 4, `u32` in version 3) and the
//! `u32` mesh count, which `shape_index` > 0 reads to find its mesh.
//!
//! Every count read from the file is checked against what the file can
//! hold before anything is allocated: a corrupt or truncated file is an
//! error message, never a panic or a huge allocation.

use super::mesh_io::RawMesh;
use glam::{Vec2, Vec3};
use std::io::Read;
use std::path::Path;

const MAGIC: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_TEXCOORDS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const FACE_NORMALS: u32 = 0x0010;
const DOUBLE_PRECISION: u32 = 0x2000;
/// DEFLATE expands at most about 1032:1; a stream claiming more data than
/// that is corrupt.
const MAX_RATIO: u64 = 1032;
/// The longest mesh name accepted.
const MAX_NAME: usize = 1 << 16;

/// One mesh of a `.serialized` file, in object space.
#[derive(Debug)]
pub struct SerializedMesh {
    pub mesh: RawMesh,
    /// Per-vertex colours stored in the file (read by `mesh_attribute`).
    pub colors: Option<Vec<Vec3>>,
    /// The file asks for face normals (flag `0x10`).
    pub face_normals: bool,
    pub name: String,
}

/// Reads mesh `shape_index` of the file at `path`.
pub fn read_serialized(path: &Path, shape_index: u32) -> Result<SerializedMesh, String> {
    let data = std::fs::read(path).map_err(|e| format!("cannot read serialized mesh {}: {e}", path.display()))?;
    parse(&data, shape_index).map_err(|e| format!("serialized mesh {}: {e}", path.display()))
}

fn u16_at(data: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(data.get(at..at.checked_add(2)?)?.try_into().ok()?))
}
fn u32_at(data: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(data.get(at..at.checked_add(4)?)?.try_into().ok()?))
}
fn u64_at(data: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(data.get(at..at.checked_add(8)?)?.try_into().ok()?))
}

/// Parses mesh `shape_index` of a whole `.serialized` file held in `data`.
pub fn parse(data: &[u8], shape_index: u32) -> Result<SerializedMesh, String> {
    let truncated = "the file is truncated";
    let magic = u16_at(data, 0).ok_or(truncated)?;
    if magic != MAGIC {
        return Err(format!("not a Mitsuba serialized mesh (the file starts with 0x{magic:04X}, expected 0x{MAGIC:04X})"));
    }
    let version = u16_at(data, 2).ok_or(truncated)?;
    if version != 3 && version != 4 {
        return Err(format!("unsupported serialized format version {version} (Mitsuba writes versions 3 and 4)"));
    }
    let start = if shape_index == 0 { 0 } else { mesh_offset(data, version, shape_index)? };
    // Every mesh starts with its own uncompressed header.
    if u16_at(data, start) != Some(MAGIC) || u16_at(data, start + 2) != Some(version) {
        return Err(format!("mesh {shape_index} does not start with a serialized-mesh header at byte {start}: the file is corrupt"));
    }
    let compressed = &data[start + 4..];
    let budget = (compressed.len() as u64).saturating_mul(MAX_RATIO).saturating_add(1024);
    let mut z = Stream { inner: flate2::read::ZlibDecoder::new(compressed), read: 0, budget };

    let flags = z.u32()?;
    let mut name = String::new();
    if version == 4 {
        let mut bytes = vec![];
        loop {
            let b = z.bytes(1)?[0];
            if b == 0 {
                break;
            }
            if bytes.len() >= MAX_NAME {
                return Err("the mesh name is not terminated: the file is corrupt".into());
            }
            bytes.push(b);
        }
        name = String::from_utf8_lossy(&bytes).into_owned();
    }
    let vertex_count = z.u64()?;
    let face_count = z.u64()?;
    if vertex_count > u32::MAX as u64 {
        return Err(format!("the mesh claims {vertex_count} vertices, more than 32-bit indices can address"));
    }
    let real = if flags & DOUBLE_PRECISION != 0 { 8u64 } else { 4 };
    let per_vertex = 3
        + if flags & HAS_NORMALS != 0 { 3 } else { 0 }
        + if flags & HAS_TEXCOORDS != 0 { 2 } else { 0 }
        + if flags & HAS_COLORS != 0 { 3 } else { 0 };
    let needed = vertex_count
        .checked_mul(per_vertex * real)
        .and_then(|v| face_count.checked_mul(12).and_then(|f| v.checked_add(f)));
    match needed {
        Some(n) if n <= z.budget.saturating_sub(z.read) => {}
        _ => {
            return Err(format!(
                "the mesh claims {vertex_count} vertices and {face_count} triangles, more than the file's {} compressed bytes can hold: the file is corrupt",
                compressed.len()
            ));
        }
    }
    let vc = vertex_count as usize;
    let positions = z.vec3s(vc, real)?;
    let normals = if flags & HAS_NORMALS != 0 { Some(z.vec3s(vc, real)?) } else { None };
    let uvs = if flags & HAS_TEXCOORDS != 0 {
        let v = z.reals(vc * 2, real)?;
        Some(v.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect())
    } else {
        None
    };
    let colors = if flags & HAS_COLORS != 0 { Some(z.vec3s(vc, real)?) } else { None };
    let idx = z.bytes(face_count as usize * 12)?;
    let triangles = idx
        .chunks_exact(12)
        .map(|c| {
            let i = |k: usize| u32::from_le_bytes([c[k], c[k + 1], c[k + 2], c[k + 3]]);
            [i(0), i(4), i(8)]
        })
        .collect();
    let mesh = RawMesh { positions, normals, uvs, triangles, attributes: vec![] }.validate()?;
    if colors.as_ref().is_some_and(|c| c.iter().any(|v| !v.is_finite())) {
        return Err("a vertex colour is not a finite number".into());
    }
    Ok(SerializedMesh { mesh, colors, face_normals: flags & FACE_NORMALS != 0, name })
}

/// Byte offset of mesh `shape_index` from the end-of-file dictionary.
fn mesh_offset(data: &[u8], version: u16, shape_index: u32) -> Result<usize, String> {
    let len = data.len();
    let count = len.checked_sub(4).and_then(|at| u32_at(data, at)).ok_or("the file is truncated")?;
    let entry = if version == 4 { 8 } else { 4 };
    // The dictionary must fit in the file after the first mesh's header.
    if count == 0 || (count as u64) * entry as u64 + 8 > len as u64 {
        return Err(format!(
            "its end-of-file table of meshes is missing or corrupt (it claims {count} meshes), so shape_index {shape_index} cannot be found"
        ));
    }
    if shape_index >= count {
        return Err(format!("shape_index {shape_index} is out of range: the file holds {count} meshes (valid: 0 to {})", count - 1));
    }
    let at = len - 4 - entry * (count - shape_index) as usize;
    let offset = if version == 4 { u64_at(data, at) } else { u32_at(data, at).map(u64::from) }.ok_or("the file is truncated")?;
    if offset.saturating_add(4) > (len - 4 - entry * count as usize) as u64 {
        return Err(format!("the offset {offset} of mesh {shape_index} lies outside the file ({len} bytes): the file is corrupt"));
    }
    Ok(offset as usize)
}

/// The decompressed stream, with reads that report truncation.
struct Stream<R: Read> {
    inner: R,
    read: u64,
    budget: u64,
}

impl<R: Read> Stream<R> {
    /// Reads exactly `n` bytes. The buffer grows with the data actually
    /// decompressed, so a count that lies costs no more than the file holds.
    fn bytes(&mut self, n: usize) -> Result<Vec<u8>, String> {
        let mut out = Vec::with_capacity(n.min(1 << 20));
        let got = (&mut self.inner)
            .take(n as u64)
            .read_to_end(&mut out)
            .map_err(|e| format!("the compressed data is corrupt ({e})"))?;
        self.read += got as u64;
        if got < n {
            return Err("the compressed mesh data ends early: the file is truncated or corrupt".into());
        }
        Ok(out)
    }
    fn u32(&mut self) -> Result<u32, String> {
        let b = self.bytes(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn u64(&mut self) -> Result<u64, String> {
        let b = self.bytes(8)?;
        Ok(u64::from_le_bytes(b[..8].try_into().unwrap_or([0; 8])))
    }
    fn reals(&mut self, n: usize, size: u64) -> Result<Vec<f32>, String> {
        let b = self.bytes(n * size as usize)?;
        Ok(if size == 8 {
            b.chunks_exact(8).map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]) as f32).collect()
        } else {
            b.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
        })
    }
    fn vec3s(&mut self, n: usize, size: u64) -> Result<Vec<Vec3>, String> {
        Ok(self.reals(n * 3, size)?.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
    }
}

/// Writes meshes as a version-4 `.serialized` file (single precision), with
/// the end-of-file table. For tests and tools.
pub fn write(meshes: &[(&RawMesh, Option<&[Vec3]>)]) -> Vec<u8> {
    use std::io::Write;
    let mut out = vec![];
    let mut offsets = vec![];
    for (m, colors) in meshes {
        offsets.push(out.len() as u64);
        out.extend_from_slice(&MAGIC.to_le_bytes());
        out.extend_from_slice(&4u16.to_le_bytes());
        let mut body = vec![];
        let flags = 0x1000
            | if m.normals.is_some() { HAS_NORMALS } else { 0 }
            | if m.uvs.is_some() { HAS_TEXCOORDS } else { 0 }
            | if colors.is_some() { HAS_COLORS } else { 0 };
        body.extend_from_slice(&(flags as u32).to_le_bytes());
        body.extend_from_slice(b"mesh\0");
        body.extend_from_slice(&(m.positions.len() as u64).to_le_bytes());
        body.extend_from_slice(&(m.triangles.len() as u64).to_le_bytes());
        let mut put = |v: &[f32]| v.iter().for_each(|x| body.extend_from_slice(&x.to_le_bytes()));
        m.positions.iter().for_each(|p| put(&p.to_array()));
        if let Some(ns) = &m.normals {
            ns.iter().for_each(|p| put(&p.to_array()));
        }
        if let Some(uvs) = &m.uvs {
            uvs.iter().for_each(|p| put(&p.to_array()));
        }
        if let Some(cs) = colors {
            cs.iter().for_each(|p| put(&p.to_array()));
        }
        m.triangles.iter().flatten().for_each(|i| body.extend_from_slice(&i.to_le_bytes()));
        let mut enc = flate2::write::ZlibEncoder::new(vec![], flate2::Compression::default());
        // Writing to a Vec cannot fail.
        let _ = enc.write_all(&body);
        out.extend(enc.finish().unwrap_or_default());
    }
    for o in &offsets {
        out.extend_from_slice(&o.to_le_bytes());
    }
    out.extend_from_slice(&(meshes.len() as u32).to_le_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(z: f32) -> RawMesh {
        RawMesh {
            positions: vec![Vec3::new(0.0, 0.0, z), Vec3::new(1.0, 0.0, z), Vec3::new(1.0, 1.0, z), Vec3::new(0.0, 1.0, z)],
            normals: Some(vec![Vec3::Z; 4]),
            uvs: Some(vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)]),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            attributes: vec![],
        }
    }

    #[test]
    fn round_trip_with_several_meshes() {
        let (a, b, c) = (quad(0.0), quad(1.0), quad(2.0));
        let colors = [Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
        let data = write(&[(&a, None), (&b, Some(&colors)), (&c, None)]);
        for (i, m) in [&a, &b, &c].into_iter().enumerate() {
            let s = parse(&data, i as u32).unwrap();
            assert_eq!(s.mesh.positions, m.positions);
            assert_eq!(s.mesh.triangles, m.triangles);
            assert_eq!(s.mesh.uvs, m.uvs);
            assert_eq!(s.name, "mesh");
            assert_eq!(s.colors.is_some(), i == 1);
        }
        let e = parse(&data, 3).unwrap_err();
        assert!(e.contains("out of range") && e.contains("3 meshes") && e.contains("0 to 2"), "{e}");
    }

    /// Mitsuba's own test file (version 4, one quad with normals and uvs).
    #[test]
    fn reads_mitsubas_rectangle() {
        let data = include_bytes!("../../tests/scenes/assets/rectangle_normals_uv.serialized");
        let s = parse(data, 0).unwrap();
        assert_eq!(s.mesh.positions.len(), 4);
        assert_eq!(s.mesh.triangles.len(), 2);
        assert!(s.mesh.normals.is_some() && s.mesh.uvs.is_some());
        // A 5.7 × 8.2 rectangle in the y = 0 plane, normals along +y.
        assert!(s.mesh.positions.iter().all(|p| p.y == 0.0 && (p.x.abs() - 2.85).abs() < 1e-6));
        assert!(s.mesh.normals.as_ref().unwrap().iter().all(|n| (*n - Vec3::Y).length() < 1e-6));
    }

    #[test]
    fn every_truncation_and_corruption_is_an_error() {
        let m = quad(0.0);
        let data = write(&[(&m, None), (&m, None)]);
        for len in 0..data.len() {
            for index in 0..2 {
                let _ = parse(&data[..len], index); // must not panic
            }
            assert!(parse(&data[..len], 1).is_err(), "truncated to {len}");
        }
        // Flip every byte in turn: an error or a valid mesh, never a panic.
        for i in 0..data.len() {
            let mut d = data.clone();
            d[i] ^= 0x5A;
            for index in 0..3 {
                if let Ok(s) = parse(&d, index) {
                    assert!(s.mesh.triangles.iter().flatten().all(|&v| (v as usize) < s.mesh.positions.len()));
                }
            }
        }
        assert!(parse(b"ply\nformat", 0).unwrap_err().contains("not a Mitsuba serialized mesh"));
    }

    #[test]
    fn lying_counts_do_not_allocate() {
        // A valid stream claiming 2⁶⁰ vertices must fail before allocating.
        use std::io::Write;
        let mut body = vec![];
        body.extend_from_slice(&0x1000u32.to_le_bytes());
        body.push(0);
        body.extend_from_slice(&(1u64 << 31).to_le_bytes());
        body.extend_from_slice(&(1u64 << 60).to_le_bytes());
        let mut enc = flate2::write::ZlibEncoder::new(vec![], flate2::Compression::default());
        enc.write_all(&body).unwrap();
        let mut data = vec![0x1C, 0x04, 4, 0];
        data.extend(enc.finish().unwrap());
        assert!(parse(&data, 0).unwrap_err().contains("corrupt"));
    }
}

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
    let chunks = parse_obj_chunks(&bytes);
    // The file's bytes are not needed past the parse: free them before
    // the mesh is assembled (lower peak memory).
    drop(bytes);
    chunks.and_then(assemble_obj).map_err(|(line, e)| format!("cannot read OBJ file {}:{line}: {e}", path.display()))
}

/// What one chunk of an OBJ file holds: its vertex data, its face corners
/// as written, one `u32` per corner and index kind (see [`ObjIndex`];
/// resolved in place later to 0-based indices), where each face ends and
/// its line (in the chunk). A chunk is about 1 MiB of text, so `u32`
/// counts suffice (checked). Texture coordinate and normal indices are
/// kept only while every corner so far has them (a mesh uses them only if
/// every face does): a file of positions only costs 4 bytes per corner.
#[derive(Default)]
struct ObjChunk {
    positions: Vec<Vec3>,
    texcoords: Vec<Vec2>,
    normals: Vec<Vec3>,
    /// Per corner, by kind: position, texture coordinate, normal.
    corners: [Vec<u32>; 3],
    /// Indices that fit neither form of `ObjIndex` (always out of bounds,
    /// or naming an earlier piece of the file), in corner order.
    far: Vec<FarIndex>,
    face_end: Vec<u32>,
    face_line: Vec<u32>,
    all_uv: bool,
    all_n: bool,
    lines: usize,
}

/// How a face corner's index is stored while the pieces are parsed
/// independently: `1..=ABS_MAX` as written (1-based, absolute), `REL |
/// r` for a negative index that names element `r` (0-based) of the
/// chunk's own list, `FAR` for one kept in `ObjChunk::far`.
struct ObjIndex;

impl ObjIndex {
    const REL: u32 = 1 << 31;
    const FAR: u32 = u32::MAX;
    const ABS_MAX: u32 = i32::MAX as u32;
}

/// A face corner's index kept aside: corner `corner`, kind `slot`, the
/// index as written, and for a negative one the 0-based position it names
/// counted from the start of its chunk (negative: an earlier chunk).
struct FarIndex {
    corner: u32,
    slot: u8,
    written: i64,
    rel: Option<i64>,
}

/// The tokens of an OBJ line up to a `#` comment, separated by whitespace.
/// Lines of ASCII (nearly all) are split byte by byte on the six ASCII
/// characters `char::is_whitespace` accepts; others go through `str`'s
/// Unicode-aware split, so every line gives the same tokens either way.
enum Tokens<'a> {
    Ascii { line: &'a str, at: usize },
    Unicode(std::str::SplitWhitespace<'a>),
}

impl<'a> Tokens<'a> {
    fn of(line: &'a str) -> Self {
        if line.is_ascii() {
            Tokens::Ascii { line, at: 0 }
        } else {
            Tokens::Unicode(line.split('#').next().unwrap_or("").split_whitespace())
        }
    }
}

impl<'a> Iterator for Tokens<'a> {
    type Item = &'a str;

    #[inline]
    fn next(&mut self) -> Option<&'a str> {
        match self {
            Tokens::Unicode(split) => split.next(),
            Tokens::Ascii { line, at } => {
                let b = line.as_bytes();
                let space = |c: u8| matches!(c, b' ' | b'\t' | b'\n' | b'\x0b' | b'\x0c' | b'\r');
                let mut i = *at;
                while i < b.len() && space(b[i]) {
                    i += 1;
                }
                let first = i;
                while i < b.len() && !space(b[i]) && b[i] != b'#' {
                    i += 1;
                }
                // At a comment the line ends.
                *at = if i < b.len() && b[i] == b'#' { b.len() } else { i };
                // ASCII: every byte is a char boundary.
                (i > first).then(|| &line[first..i])
            }
        }
    }
}

/// A face corner's parts, as `str::split('/')` gives them (the separator
/// is one byte, so the cuts are char boundaries in any text).
struct Slashes<'a>(Option<&'a str>);

impl<'a> Iterator for Slashes<'a> {
    type Item = &'a str;

    #[inline]
    fn next(&mut self) -> Option<&'a str> {
        let s = self.0?;
        match s.as_bytes().iter().position(|&b| b == b'/') {
            Some(k) => {
                self.0 = Some(&s[k + 1..]);
                Some(&s[..k])
            }
            None => {
                self.0 = None;
                Some(s)
            }
        }
    }
}

/// Parses `text` (whole lines); errors carry the line within it (1-based).
fn parse_obj_chunk(text: &str) -> Result<ObjChunk, (usize, String)> {
    let mut c = ObjChunk { all_uv: true, all_n: true, ..Default::default() };
    let number = |tok: Option<&str>, what: &str, line: usize| -> Result<f32, (usize, String)> {
        let t = tok.ok_or_else(|| (line, format!("{what} is missing a number")))?;
        let v: f32 = t.parse().map_err(|_| (line, format!("\"{t}\" in {what} is not a number")))?;
        if !v.is_finite() {
            return Err((line, format!("{what} has a value that is not a finite number ({t})")));
        }
        Ok(v)
    };
    let bytes = text.as_bytes();
    let mut start = 0;
    while start < bytes.len() {
        let end = memchr::memchr(b'\n', &bytes[start..]).map_or(bytes.len(), |k| start + k);
        // A '\n' ends no multi-byte character: both cuts are char boundaries.
        let raw = &text[start..end];
        start = end + 1;
        c.lines += 1;
        let line = c.lines;
        let mut tokens = Tokens::of(raw);
        let Some(keyword) = tokens.next() else { continue };
        match keyword {
            "v" => {
                let p = Vec3::new(number(tokens.next(), "a vertex", line)?, number(tokens.next(), "a vertex", line)?, number(tokens.next(), "a vertex", line)?);
                c.positions.push(p);
            }
            "vt" => {
                let u = number(tokens.next(), "a texture coordinate", line)?;
                let v = match tokens.next() {
                    Some(t) => number(Some(t), "a texture coordinate", line)?,
                    None => 0.0,
                };
                c.texcoords.push(Vec2::new(u, 1.0 - v));
            }
            "vn" => {
                let n = Vec3::new(number(tokens.next(), "a normal", line)?, number(tokens.next(), "a normal", line)?, number(tokens.next(), "a normal", line)?);
                c.normals.push(n);
            }
            "f" => {
                let first = c.corners[0].len();
                for tok in tokens {
                    let mut parts = Slashes(Some(tok));
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
                    let k = c.corners[0].len() as u32;
                    let counts = [c.positions.len(), c.texcoords.len(), c.normals.len()];
                    let encode = |slot: usize, i: i64, far: &mut Vec<FarIndex>| -> u32 {
                        if i > 0 && i <= ObjIndex::ABS_MAX as i64 {
                            return i as u32;
                        }
                        let rel = (i < 0).then(|| counts[slot] as i64 + i);
                        match rel {
                            Some(r) if (0..ObjIndex::REL as i64 - 1).contains(&r) => ObjIndex::REL | r as u32,
                            _ => {
                                far.push(FarIndex { corner: k, slot: slot as u8, written: i, rel });
                                ObjIndex::FAR
                            }
                        }
                    };
                    let x = encode(0, v, &mut c.far);
                    c.corners[0].push(x);
                    for (slot, index) in [(1, vt), (2, vn)] {
                        let all = if slot == 1 { &mut c.all_uv } else { &mut c.all_n };
                        match index {
                            Some(i) if *all => {
                                let x = encode(slot, i, &mut c.far);
                                c.corners[slot].push(x);
                            }
                            Some(_) => {}
                            None => {
                                *all = false;
                                c.corners[slot] = vec![];
                            }
                        }
                    }
                }
                let n = c.corners[0].len() - first;
                if n < 3 {
                    return Err((line, format!("a face has {n} vertices; a face needs at least three")));
                }
                let narrow = |x: usize| u32::try_from(x).map_err(|_| (line, "too much data in one line of the OBJ file".to_string()));
                c.face_end.push(narrow(c.corners[0].len())?);
                c.face_line.push(narrow(line)?);
                narrow(c.positions.len().max(c.texcoords.len()).max(c.normals.len()))?;
            }
            _ => {}
        }
    }
    Ok(c)
}

/// [`read_obj`] on text; errors carry the 1-based line.
///
/// Large files are cut at line ends into pieces parsed in parallel; the
/// result (and the first error, by line) is the same as reading it in one go.
pub fn parse_obj(text: &str) -> Result<RawMesh, (usize, String)> {
    parse_obj_chunks(text.as_bytes()).and_then(assemble_obj)
}

/// The first half of [`parse_obj`]: the file's pieces parsed (in parallel),
/// each with the number of lines before it. Text that is not UTF-8 is read
/// as `String::from_utf8_lossy` gives it (piece by piece: cut after a
/// newline, the pieces convert as the whole would).
fn parse_obj_chunks(bytes: &[u8]) -> Result<Vec<(usize, ObjChunk)>, (usize, String)> {
    use rayon::prelude::*;
    // Pieces of about 1 MiB, cut after a newline.
    const PIECE: usize = 1 << 20;
    let mut cuts = vec![0];
    while let Some(&last) = cuts.last() {
        if last >= bytes.len() {
            break;
        }
        let target = (last + PIECE).min(bytes.len());
        let cut = bytes[target..].iter().position(|&b| b == b'\n').map_or(bytes.len(), |i| target + i + 1);
        cuts.push(cut);
    }
    let pieces: Vec<&[u8]> = cuts.windows(2).map(|w| &bytes[w[0]..w[1]]).collect();
    let parsed: Vec<Result<ObjChunk, (usize, String)>> = pieces
        .par_iter()
        .map(|p| match std::str::from_utf8(p) {
            Ok(text) => parse_obj_chunk(text),
            Err(_) => parse_obj_chunk(&String::from_utf8_lossy(p)),
        })
        .collect();
    // Lines before each piece: a piece that ends with a newline has exactly
    // `lines` lines (the last one may end without; nothing follows it).
    let mut chunks = Vec::with_capacity(parsed.len());
    let mut line0 = 0;
    for r in parsed {
        match r {
            Ok(c) => {
                let n = c.lines;
                chunks.push((line0, c));
                line0 += n;
            }
            Err((line, e)) => return Err((line0 + line, e)),
        }
    }
    if chunks.iter().all(|(_, c)| c.face_end.is_empty()) {
        return Err((String::from_utf8_lossy(bytes).lines().count().max(1), "the mesh has no faces".into()));
    }
    Ok(chunks)
}

/// The second half of [`parse_obj`]: indices resolved, vertices made
/// distinct per (position, uv, normal) in use, polygons fanned.
fn assemble_obj(mut chunks: Vec<(usize, ObjChunk)>) -> Result<RawMesh, (usize, String)> {
    use rayon::prelude::*;
    let total = |f: fn(&ObjChunk) -> usize| chunks.iter().map(|(_, c)| f(c)).sum::<usize>();
    let (n_pos, n_tex, n_nrm) = (total(|c| c.positions.len()), total(|c| c.texcoords.len()), total(|c| c.normals.len()));
    let n_tris = total(|c| c.corners[0].len()) - 2 * total(|c| c.face_end.len());
    let all_uv = chunks.iter().all(|(_, c)| c.all_uv);
    let all_n = chunks.iter().all(|(_, c)| c.all_n);
    // Resolve: positive indices against the whole file, negative ones
    // against the lists as they were at the face. Absent: u32::MAX.
    let resolve = |i: i64, total: usize, so_far: usize, what: &str, line: usize| -> Result<u32, (usize, String)> {
        let r = if i > 0 { i - 1 } else { so_far as i64 + i };
        if r < 0 || r >= total as i64 {
            let have = if total == 0 { format!("the file has no {what}s") } else { format!("the file has {total}") };
            return Err((line, format!("face vertex index out of bounds: a face names {what} {i}, but {have}")));
        }
        Ok(r as u32)
    };
    let mut before = vec![[0usize; 3]; chunks.len()];
    for k in 1..chunks.len() {
        let c = &chunks[k - 1].1;
        before[k] = [before[k - 1][0] + c.positions.len(), before[k - 1][1] + c.texcoords.len(), before[k - 1][2] + c.normals.len()];
    }
    let totals = [n_pos, n_tex, n_nrm];
    let names = ["vertex", "texture coordinate", "normal"];
    let used = [true, all_uv, all_n];
    // Resolved in place: each corner's indices become 0-based. Per chunk,
    // the first error by line: the stored indices face by face, then the
    // ones kept aside (whose line comes from their face).
    let resolved: Vec<Result<(), (usize, String)>> = chunks
        .par_iter_mut()
        .zip(&before)
        .map(|((line0, c), b)| {
            let ObjChunk { corners, far, face_end, face_line, .. } = c;
            let line_of = |corner: usize| *line0 + face_line[face_end.partition_point(|&e| e as usize <= corner)] as usize;
            let mut first: Option<(usize, String)> = None;
            for slot in (0..3).filter(|&s| used[s]) {
                let list = &mut corners[slot];
                for (k, x) in list.iter_mut().enumerate() {
                    *x = match *x {
                        ObjIndex::FAR => continue,
                        x if x & ObjIndex::REL != 0 => (b[slot] + (x & !ObjIndex::REL) as usize) as u32,
                        x => match resolve(x as i64, totals[slot], 0, names[slot], 0) {
                            Ok(r) => r,
                            Err((_, e)) => {
                                let line = line_of(k);
                                if first.as_ref().is_none_or(|f| line < f.0) {
                                    first = Some((line, e));
                                }
                                break;
                            }
                        },
                    };
                }
            }
            for f in far.iter().filter(|f| used[f.slot as usize]) {
                let slot = f.slot as usize;
                // A negative index counts back from the list's length at its face.
                let so_far = f.rel.map_or(0, |rel| (b[slot] as i64 + rel - f.written) as usize);
                match resolve(f.written, totals[slot], so_far, names[slot], 0) {
                    Ok(r) => corners[slot][f.corner as usize] = r,
                    Err((_, e)) => {
                        let line = line_of(f.corner as usize);
                        if first.as_ref().is_none_or(|g| line < g.0) {
                            first = Some((line, e));
                        }
                        break;
                    }
                }
            }
            *face_line = vec![];
            *far = vec![];
            first.map_or(Ok(()), Err)
        })
        .collect();
    for r in resolved {
        r?;
    }
    // Each chunk's lists are freed as they are copied out.
    let positions: Vec<Vec3> = chunks.iter_mut().flat_map(|(_, c)| std::mem::take(&mut c.positions)).collect();
    let texcoords: Vec<Vec2> = if all_uv { chunks.iter_mut().flat_map(|(_, c)| std::mem::take(&mut c.texcoords)).collect() } else { vec![] };
    let vnormals: Vec<Vec3> = if all_n { chunks.iter_mut().flat_map(|(_, c)| std::mem::take(&mut c.normals)).collect() } else { vec![] };
    // One vertex per distinct (position, uv, normal) in use, in order of first use.
    let mut out = RawMesh::default();
    out.triangles.reserve_exact(n_tris);
    let mut uvs = vec![];
    let mut normals = vec![];
    let mut by_position = if all_uv || all_n { vec![] } else { vec![u32::MAX; n_pos] };
    let mut map: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let mut ids = vec![];
    for (_, c) in chunks.iter_mut() {
        let [cv, ct, cn] = std::mem::take(&mut c.corners);
        let mut start = 0;
        for &end in &c.face_end {
            let end = end as usize;
            ids.clear();
            for k in start..end {
                let (v, vt, vn) = (cv[k], if all_uv { ct[k] } else { u32::MAX }, if all_n { cn[k] } else { u32::MAX });
                let key = [v, vt, vn];
                let new = out.positions.len() as u32;
                let id = if by_position.is_empty() {
                    *map.entry(key).or_insert(new)
                } else {
                    let slot = &mut by_position[v as usize];
                    if *slot == u32::MAX {
                        *slot = new;
                    }
                    *slot
                };
                if id == new {
                    out.positions.push(positions[v as usize]);
                    if all_uv {
                        uvs.push(texcoords[vt as usize]);
                    }
                    if all_n {
                        normals.push(vnormals[vn as usize]);
                    }
                }
                ids.push(id);
            }
            for k in 1..ids.len() - 1 {
                out.triangles.push([ids[0], ids[k], ids[k + 1]]);
            }
            start = end;
        }
    }
    out.normals = all_n.then_some(normals);
    out.uvs = all_uv.then_some(uvs);
    out.validate().map_err(|e| (1, e))
}

/// Reads an ASCII or binary PLY file with `vertex` (x, y, z and optionally
/// nx, ny, nz and u, v / s, t / texture_u, texture_v) and `face`
/// (`vertex_indices` or `vertex_index` lists; polygons are fanned).
///
/// Binary files whose vertices have only those properties and whose faces
/// have only the index list (the usual layout) are read straight into the
/// mesh buffers ([`read_binary_ply`]); any other file goes through
/// `ply-rs-bw`, which also reads the extra properties as attributes.
pub fn read_ply(path: &Path) -> Result<RawMesh, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot open PLY file {}: {e}", path.display()))?;
    if let Some(mesh) = read_binary_ply(&bytes).map_err(|e| format!("cannot read PLY file {}: {e}", path.display()))? {
        return mesh.validate().map_err(|e| format!("{}: {e}", path.display()));
    }
    read_ply_generic(&bytes, path)
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq)]
enum PlyType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl PlyType {
    fn parse(s: &str) -> Option<PlyType> {
        Some(match s {
            "char" | "int8" => PlyType::I8,
            "uchar" | "uint8" => PlyType::U8,
            "short" | "int16" => PlyType::I16,
            "ushort" | "uint16" => PlyType::U16,
            "int" | "int32" => PlyType::I32,
            "uint" | "uint32" => PlyType::U32,
            "float" | "float32" => PlyType::F32,
            "double" | "float64" => PlyType::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            PlyType::I8 | PlyType::U8 => 1,
            PlyType::I16 | PlyType::U16 => 2,
            PlyType::I32 | PlyType::U32 | PlyType::F32 => 4,
            PlyType::F64 => 8,
        }
    }

    fn is_int(self) -> bool {
        !matches!(self, PlyType::F32 | PlyType::F64)
    }

    /// The value at the start of `b` (which holds at least `size()` bytes).
    #[inline(always)]
    fn float(self, b: &[u8], big: bool) -> f32 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().unwrap_or([0; $n]);
                if big { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) }
            }};
        }
        match self {
            PlyType::F32 => get!(f32, 4),
            PlyType::F64 => get!(f64, 8) as f32,
            _ => self.int(b, big) as f32,
        }
    }

    /// The integer at the start of `b`; floats are truncated (callers check `is_int`).
    #[inline(always)]
    fn int(self, b: &[u8], big: bool) -> i64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().unwrap_or([0; $n]);
                (if big { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) }) as i64
            }};
        }
        match self {
            PlyType::I8 => b[0] as i8 as i64,
            PlyType::U8 => b[0] as i64,
            PlyType::I16 => get!(i16, 2),
            PlyType::U16 => get!(u16, 2),
            PlyType::I32 => get!(i32, 4),
            PlyType::U32 => get!(u32, 4),
            PlyType::F32 => get!(f32, 4),
            PlyType::F64 => get!(f64, 8),
        }
    }
}

/// A PLY element of the header: name, count, and its properties as (name,
/// list count type if a list, value type).
struct PlyElement {
    name: String,
    count: usize,
    props: Vec<(String, Option<PlyType>, PlyType)>,
}

/// The binary PLY reader: `Ok(None)` when the file is ASCII, its header
/// does not parse, or its layout is not the plain one (vertices with
/// positions, optional normals and uvs only; faces with the index list
/// only; no other elements), which [`read_ply_generic`] then reads.
/// Errors: data that ends early or a face with fewer than three
/// vertices or an index out of range; counts are checked against the file
/// size before anything is allocated.
pub(crate) fn read_binary_ply(bytes: &[u8]) -> Result<Option<RawMesh>, String> {
    let Some(end) = bytes.windows(11).position(|w| w == b"end_header\n").map(|i| i + 11) else { return Ok(None) };
    let Ok(header) = std::str::from_utf8(&bytes[..end]) else { return Ok(None) };
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Ok(None);
    }
    let mut big = None;
    let mut elements: Vec<PlyElement> = vec![];
    for line in lines {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            ["format", "binary_little_endian", _] => big = Some(false),
            ["format", "binary_big_endian", _] => big = Some(true),
            ["format", ..] => return Ok(None),
            ["element", name, count] => match count.parse() {
                Ok(count) => elements.push(PlyElement { name: name.to_string(), count, props: vec![] }),
                Err(_) => return Ok(None),
            },
            ["property", "list", ct, it, name] => match (elements.last_mut(), PlyType::parse(ct), PlyType::parse(it)) {
                (Some(e), Some(ct), Some(it)) => e.props.push((name.to_string(), Some(ct), it)),
                _ => return Ok(None),
            },
            ["property", ty, name] => match (elements.last_mut(), PlyType::parse(ty)) {
                (Some(e), Some(ty)) => e.props.push((name.to_string(), None, ty)),
                _ => return Ok(None),
            },
            ["comment", ..] | ["obj_info", ..] | ["end_header"] | [] => {}
            _ => return Ok(None),
        }
    }
    let Some(big) = big else { return Ok(None) };
    let [vertex, face] = elements.as_slice() else { return Ok(None) };
    if vertex.name != "vertex" || face.name != "face" {
        return Ok(None);
    }
    // Vertex layout: offsets of the properties we use, all scalars.
    let find = |k: &str| vertex.props.iter().position(|p| p.0 == k);
    let uv_keys = [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")]
        .into_iter()
        .find(|(a, b)| find(a).is_some() && find(b).is_some());
    let has_normals = ["nx", "ny", "nz"].iter().all(|k| find(k).is_some());
    let mut used = vec!["x", "y", "z"];
    if has_normals {
        used.extend(["nx", "ny", "nz"]);
    }
    if let Some((a, b)) = uv_keys {
        used.extend([a, b]);
    }
    if vertex.props.iter().any(|p| p.1.is_some() || !used.contains(&p.0.as_str())) || used.iter().any(|k| find(k).is_none()) {
        return Ok(None);
    }
    let mut offsets = vec![];
    let mut stride = 0;
    for p in &vertex.props {
        offsets.push(stride);
        stride += p.2.size();
    }
    let field = |k: &str| find(k).map(|i| (offsets[i], vertex.props[i].2));
    let xyz = ["x", "y", "z"].map(|k| field(k).unwrap_or((0, PlyType::F32)));
    let nxyz = ["nx", "ny", "nz"].map(|k| field(k).unwrap_or((0, PlyType::F32)));
    let uv = uv_keys.map(|(a, b)| [a, b].map(|k| field(k).unwrap_or((0, PlyType::F32))));
    let [(ref fname, Some(count_ty), index_ty)] = face.props[..] else { return Ok(None) };
    if !(fname == "vertex_indices" || fname == "vertex_index") || !count_ty.is_int() || !index_ty.is_int() {
        return Ok(None);
    }

    let mut data = &bytes[end..];
    let n_v = vertex.count;
    if n_v.checked_mul(stride).is_none_or(|len| len > data.len()) {
        return Err(format!("the file ends before its {n_v} vertices"));
    }
    // Each face takes at least a count and three indices.
    let min_face = count_ty.size() + 3 * index_ty.size();
    if face.count.checked_mul(min_face).is_none_or(|len| len > data.len() - n_v * stride) {
        return Err(format!("the file ends before its {} faces", face.count));
    }
    let vdata = &data[..n_v * stride];
    let point = |rec: &[u8], f: &[(usize, PlyType); 3]| Vec3::new(f[0].1.float(&rec[f[0].0..], big), f[1].1.float(&rec[f[1].0..], big), f[2].1.float(&rec[f[2].0..], big));
    let mut out = RawMesh::default();
    let plain = !big && stride == 12 && xyz.iter().enumerate().all(|(k, &(o, t))| o == 4 * k && t == PlyType::F32);
    if plain && cfg!(target_endian = "little") {
        // x, y, z floats and nothing else: the data is the array itself.
        out.positions = vdata.chunks_exact(12).map(|r| Vec3::new(f32::from_le_bytes([r[0], r[1], r[2], r[3]]), f32::from_le_bytes([r[4], r[5], r[6], r[7]]), f32::from_le_bytes([r[8], r[9], r[10], r[11]]))).collect();
    } else {
        out.positions = vdata.chunks_exact(stride).map(|r| point(r, &xyz)).collect();
    }
    if has_normals {
        out.normals = Some(vdata.chunks_exact(stride).map(|r| point(r, &nxyz)).collect());
    }
    if let Some([(ou, tu), (ov, tv)]) = uv {
        out.uvs = Some(vdata.chunks_exact(stride).map(|r| Vec2::new(tu.float(&r[ou..], big), tv.float(&r[ov..], big))).collect());
    }
    data = &data[n_v * stride..];
    let (cs, is) = (count_ty.size(), index_ty.size());
    out.triangles.reserve(face.count);
    let mut poly: Vec<u32> = vec![];
    for f in 0..face.count {
        let Some(c) = data.get(..cs) else { return Err(format!("the file ends inside face {f}")) };
        let n = count_ty.int(c, big);
        if n < 3 {
            return Err(format!("face {f} has {n} vertices; a face needs at least three"));
        }
        let n = n as usize;
        let Some(list) = data.get(cs..cs + n * is) else { return Err(format!("the file ends inside face {f}")) };
        poly.clear();
        for k in 0..n {
            let i = index_ty.int(&list[k * is..], big);
            if i < 0 || i > u32::MAX as i64 {
                return Err(format!("face {f} has a vertex index that is negative or too large ({i})"));
            }
            poly.push(i as u32);
        }
        for k in 1..n - 1 {
            out.triangles.push([poly[0], poly[k], poly[k + 1]]);
        }
        data = &data[cs + n * is..];
    }
    Ok(Some(out))
}

/// Any PLY file, by `ply-rs-bw`, with extra properties as attributes.
fn read_ply_generic(bytes: &[u8], path: &Path) -> Result<RawMesh, String> {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::{DefaultElement, Property};
    let mut reader = std::io::Cursor::new(bytes);
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

    /// A PLY file of `n` vertices with normals and uvs and faces of 3 to 5
    /// vertices, in the given format, with positions as `pos_ty` and
    /// indices as `idx_ty` (list counts as uchar).
    fn ply_bytes(format: &str, pos_ty: &str, idx_ty: &str, n: usize) -> Vec<u8> {
        let mut out = format!(
            "ply\nformat {format} 1.0\ncomment test\nelement vertex {n}\nproperty {pos_ty} x\nproperty {pos_ty} y\nproperty {pos_ty} z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\nelement face {}\nproperty list uchar {idx_ty} vertex_indices\nend_header\n",
            n - 4
        )
        .into_bytes();
        let big = format == "binary_big_endian";
        let vertex = |k: usize| {
            let f = k as f32;
            ([f * 0.5, (f * 0.37).sin(), 1.0 / (f + 1.0)], [0.0, (f * 0.1).cos(), (f * 0.1).sin()], [f / n as f32, 1.0 - f / n as f32])
        };
        let face = |k: usize| (0..3 + k % 3).map(|j| ((k + 2 * j) % n) as u32).collect::<Vec<u32>>();
        macro_rules! put {
            ($v:expr) => {
                out.extend(if big { $v.to_be_bytes().to_vec() } else { $v.to_le_bytes().to_vec() })
            };
        }
        for k in 0..n {
            let (p, nn, uv) = vertex(k);
            if format == "ascii" {
                out.extend(format!("{} {} {} {} {} {} {} {}\n", p[0], p[1], p[2], nn[0], nn[1], nn[2], uv[0], uv[1]).bytes());
                continue;
            }
            for x in p {
                if pos_ty == "double" { put!(x as f64) } else { put!(x) }
            }
            for x in nn.into_iter().chain(uv) {
                put!(x);
            }
        }
        for k in 0..n - 4 {
            let f = face(k);
            if format == "ascii" {
                out.extend(format!("{} {}\n", f.len(), f.iter().map(|i| i.to_string()).collect::<Vec<_>>().join(" ")).bytes());
                continue;
            }
            out.push(f.len() as u8);
            for i in f {
                match idx_ty {
                    "ushort" => put!(i as u16),
                    "uint" => put!(i),
                    _ => put!(i as i32),
                }
            }
        }
        out
    }

    fn same_mesh(a: &RawMesh, b: &RawMesh) {
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.normals, b.normals);
        assert_eq!(a.uvs, b.uvs);
        assert_eq!(a.triangles, b.triangles);
        assert_eq!(a.attributes.len(), b.attributes.len());
    }

    /// Binary little and big endian PLY (float and double positions, int,
    /// uint and ushort indices, polygons) read by the direct reader give the
    /// same mesh as the general reader, and as the same data in ASCII.
    #[test]
    fn binary_ply_reader_matches_the_general_one() {
        let dir = std::env::temp_dir().join(format!("snell-plyb-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let n = 300;
        let ascii = ply_bytes("ascii", "float", "int", n);
        assert!(read_binary_ply(&ascii).unwrap().is_none(), "ASCII goes to the general reader");
        let reference = read_ply_generic(&ascii, Path::new("a.ply")).unwrap();
        assert_eq!(reference.triangles.len(), (0..n - 4).map(|k| 1 + k % 3).sum::<usize>());
        for format in ["binary_little_endian", "binary_big_endian"] {
            for (pos_ty, idx_ty) in [("float", "int"), ("double", "uint"), ("float", "ushort")] {
                let bytes = ply_bytes(format, pos_ty, idx_ty, n);
                let direct = read_binary_ply(&bytes).unwrap().expect("the direct reader takes this layout");
                let general = read_ply_generic(&bytes, Path::new("b.ply")).unwrap();
                same_mesh(&direct, &general);
                // ASCII prints floats exactly (shortest round trip), so the meshes agree.
                same_mesh(&direct, &reference);
                let p = dir.join(format!("{format}-{pos_ty}-{idx_ty}.ply"));
                std::fs::write(&p, &bytes).unwrap();
                same_mesh(&read_ply(&p).unwrap(), &reference);
            }
        }
        // Plain x y z floats (the copy fast path), little endian.
        let head = "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";
        let mut plain = head.as_bytes().to_vec();
        for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.5]] {
            v.iter().for_each(|x| plain.extend(x.to_le_bytes()));
        }
        for f in [[0i32, 1, 2], [0, 2, 3]] {
            plain.push(3);
            f.iter().for_each(|x| plain.extend(x.to_le_bytes()));
        }
        let m = read_binary_ply(&plain).unwrap().unwrap();
        same_mesh(&m, &read_ply_generic(&plain, Path::new("c.ply")).unwrap());
        assert_eq!(m.positions[3], Vec3::new(0.0, 1.0, 0.5));
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        // Truncated data, a lying count, a bad index and a two-vertex face are errors.
        assert!(read_binary_ply(&plain[..plain.len() - 3]).unwrap_err().contains("ends"));
        let with_head = |h: String| [h.as_bytes(), &plain[head.len()..]].concat();
        assert!(read_binary_ply(&with_head(head.replace("vertex 4", "vertex 4000000000"))).unwrap_err().contains("ends"));
        assert!(read_binary_ply(&with_head(head.replace("face 2", "face 2000000000"))).unwrap_err().contains("ends"));
        let mut bad = plain.clone();
        let at = bad.len() - 4;
        bad[at..].copy_from_slice(&(-3i32).to_le_bytes());
        assert!(read_binary_ply(&bad).unwrap_err().contains("negative"));
        let mut short = plain.clone();
        let at = short.len() - 13;
        short[at] = 2;
        assert!(read_binary_ply(&short).is_err());
        // Extra vertex properties (attributes) go to the general reader.
        let extra = with_head(head.replacen("property float z\n", "property float z\nproperty float quality\n", 1));
        assert!(read_binary_ply(&extra).unwrap().is_none());
    }

    /// An OBJ big enough to be parsed in several pieces (quads, negative
    /// indices, uvs, normals) gives the same mesh as its faces say, and
    /// an error on a late line names that line.
    #[test]
    fn obj_in_parallel_pieces() {
        let (nu, nv) = (300, 200);
        let mut text = String::from("# grid\n");
        let mut expected_tris = 0;
        for j in 0..nv {
            for i in 0..nu {
                text += &format!("v {} {} {}\nvt {} {}\nvn 0 0 1\n", i as f32 * 0.1, j as f32 * 0.1, ((i * j) % 7) as f32 * 0.01, i as f32 / nu as f32, j as f32 / nv as f32);
            }
            if j > 0 {
                for i in 0..nu - 1 {
                    // Row j-1 by absolute index, row j relative to the end.
                    let a = (j - 1) * nu + i + 1;
                    let (c, d) = (i as i64 - nu as i64, i as i64 - nu as i64 + 1);
                    if i % 2 == 0 {
                        text += &format!("f {a}/{a}/{a} {}/{}/{} {d}/{d}/{d} {c}/{c}/{c}\n", a + 1, a + 1, a + 1);
                        expected_tris += 2;
                    } else {
                        text += &format!("f {a}/{a}/{a} {}/{}/{} {d}/{d}/{d}\n", a + 1, a + 1, a + 1);
                        expected_tris += 1;
                    }
                }
            }
        }
        assert!(text.len() > 3 << 20, "several pieces ({} bytes)", text.len());
        let m = parse_obj(&text).unwrap();
        assert_eq!(m.triangles.len(), expected_tris);
        // Every vertex is used (the top-right one of each row is not: nv of them).
        assert!(m.positions.len() >= nu * nv - nv);
        // Triangles reproduce their faces' positions: the first face's corners.
        assert_eq!(m.positions[m.triangles[0][0] as usize], Vec3::new(0.0, 0.0, 0.0));
        assert_eq!(m.positions[m.triangles[0][2] as usize], Vec3::new(0.1, 0.1, 0.01));
        let uvs = m.uvs.as_ref().unwrap();
        assert_eq!(uvs[m.triangles[0][1] as usize], Vec2::new(1.0 / nu as f32, 1.0));
        // A bad line near the end is reported with its line number.
        let lines = text.lines().count();
        let bad = text.clone() + "v 1 2 oops\n";
        assert_eq!(parse_obj(&bad).unwrap_err().0, lines + 1);
        let bad = text.clone() + "f 1 2 999999999\n";
        let e = parse_obj(&bad).unwrap_err();
        assert_eq!(e.0, lines + 1);
        assert!(e.1.contains("out of bounds"), "{}", e.1);
        // A bad line in the middle wins over a later one.
        let mut mid = String::new();
        for (k, l) in text.lines().enumerate() {
            mid += l;
            mid += "\n";
            if k == lines / 2 {
                mid += "vn 1 x 2\n";
            }
        }
        assert_eq!(parse_obj(&(mid + "v 1 2 oops\n")).unwrap_err().0, lines / 2 + 2);
    }

    /// Lines are split as `str::split_whitespace` splits them, whether of
    /// ASCII (the byte-wise split: tabs, vertical tabs, form feeds, `\r`)
    /// or not (a no-break space separates too); a `#` ends a line even
    /// inside a token; bytes that are not UTF-8 read as U+FFFD, in a
    /// comment harmlessly, in a number as an error naming the line.
    #[test]
    fn obj_tokens_as_str_splits_them() {
        let text = "v 0 0 0\nv\t1\x0b0\x0c0\r\nv\u{a0}0 1 0 # apex\nv 1 1 0#x\nf 1 2 3 4\n";
        let m = parse_obj(text).unwrap();
        assert_eq!(m.positions, vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)]);
        assert_eq!(m.triangles.len(), 2);
        let read = |b: &[u8]| parse_obj_chunks(b).and_then(assemble_obj);
        let mut bytes = b"# caf\xe9 \xff\n".to_vec();
        bytes.extend_from_slice(text.as_bytes());
        assert_eq!(read(&bytes).unwrap().positions.len(), 4);
        let e = read(b"v 0 0 0\nv 1 0 0\nv 0 1\xe9 0\nf 1 2 3\n").unwrap_err();
        assert_eq!(e.0, 3);
        assert!(e.1.contains('\u{fffd}'), "{}", e.1);
    }

    /// Every form a face index is kept in while the pieces are parsed:
    /// absolute, negative within the piece, negative reaching back into an
    /// earlier piece, too large; texture coordinates some faces lack are
    /// dropped; errors name their line and the index as written.
    #[test]
    fn obj_index_forms_across_pieces() {
        let n = 120_000usize;
        let mut text = String::new();
        for k in 0..n {
            text += &format!("v {k} {} 0.25\n", k % 17);
        }
        text += "vt 0.5 0.5\nvt 0.25 0.75\n";
        assert!(text.len() > 3 << 19, "several pieces ({} bytes)", text.len());
        let faces = ["f 1/1 2/2 3/1", "f -1 -2 -3", &format!("f -{n} -{} {}", n - 1, n / 2), "f 5 -7 9"];
        let head_lines = text.lines().count();
        for f in faces {
            text += f;
            text += "\n";
        }
        let m = parse_obj(&text).unwrap();
        assert!(m.uvs.is_none(), "not every face has texture coordinates");
        let p = |t: usize, k: usize| m.positions[m.triangles[t][k] as usize].x as usize;
        let expect = [[0, 1, 2], [n - 1, n - 2, n - 3], [0, 1, n / 2 - 1], [4, n - 7, 8]];
        for (t, e) in expect.iter().enumerate() {
            assert_eq!([p(t, 0), p(t, 1), p(t, 2)], *e, "face {t}");
        }
        for (bad, what) in [(format!("f 1 2 -{}", n + 1), format!("-{}", n + 1)), ("f 1 4000000000 2".to_string(), "4000000000".into()), (format!("f 1 2 {}", n + 1), format!("{}", n + 1))] {
            let e = parse_obj(&(text.clone() + &bad + "\n" + "f 1 2 3\n")).unwrap_err();
            assert_eq!(e.0, head_lines + faces.len() + 1, "{bad}: {}", e.1);
            assert!(e.1.contains("out of bounds") && e.1.contains(&format!("vertex {what},")), "{bad}: {}", e.1);
        }
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

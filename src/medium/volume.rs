//! Volume data: a value (a density, an albedo) at every point of space.
//!
//! | plugin | parameters |
//! |---|---|
//! | `constvolume` | `value` (float, rgb or spectrum; default 1), `to_world` (places its box) |
//! | `gridvolume` | `filename` (Mitsuba's binary `.vol` grid, 1 or 3 channels of float32), `filter_type` (`trilinear` default, `nearest`), `wrap_mode` (`clamp` default, `repeat`, `mirror`), `use_grid_bbox` (false: the grid fills the unit cube), `max_value`, `raw`, `to_world` |
//!
//! A volume occupies the box `to_world` makes of the unit cube (its axis-
//! aligned bounds in world space, as Mitsuba's `bbox`); a `heterogeneous`
//! medium has no extinction outside the box of its `sigma_t`. Grid cells
//! are sampled at their centres, as Mitsuba's 3-D textures are.
//!
//! The `.vol` format (Mitsuba 0.6 and 3): "VOL", version byte 3, then
//! little-endian int32 encoding (1 = float32), x, y, z resolution and
//! channel count, six float32 bounds (xmin ymin zmin xmax ymax zmax), then
//! the values with x varying fastest and the channels interleaved.

use crate::math::Transform;
use crate::spectrum::Rgb;
use glam::Vec3;
use std::path::Path;
use std::sync::Arc;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WrapMode {
    Clamp,
    Repeat,
    Mirror,
}

#[derive(Debug)]
pub struct Grid {
    pub res: [usize; 3],
    pub channels: usize,
    pub data: Vec<f32>,
    /// The bounds written in the file (used with `use_grid_bbox`).
    pub file_bounds: (Vec3, Vec3),
    pub nearest: bool,
    pub wrap: WrapMode,
}

#[derive(Clone, Debug)]
pub enum VolumeData {
    Constant(Rgb),
    Grid(Arc<Grid>),
}

#[derive(Clone, Debug)]
pub struct Volume {
    pub data: VolumeData,
    /// Unit cube → world.
    pub to_world: Transform,
    /// World-space bounds of the placed unit cube.
    pub bounds: (Vec3, Vec3),
    /// The largest value of any channel (or `max_value` when given).
    pub max: f32,
}

impl Volume {
    pub fn constant(value: Rgb, to_world: Transform) -> Volume {
        let max = value.0[0].max(value.0[1]).max(value.0[2]);
        Volume { bounds: to_world.unit_cube_bounds(), data: VolumeData::Constant(value), to_world, max }
    }

    pub fn grid(grid: Grid, to_world: Transform, max_value: Option<f32>) -> Volume {
        let max = max_value.unwrap_or_else(|| grid.data.iter().copied().fold(0.0f32, f32::max));
        Volume { bounds: to_world.unit_cube_bounds(), data: VolumeData::Grid(Arc::new(grid)), to_world, max }
    }

    pub fn is_constant(&self) -> bool {
        matches!(self.data, VolumeData::Constant(_))
    }

    /// The value at the world-space point `p` (a one-channel grid gives grey).
    #[inline]
    pub fn eval(&self, p: Vec3) -> Rgb {
        match &self.data {
            VolumeData::Constant(c) => *c,
            VolumeData::Grid(g) => g.eval(self.to_world.inverse_point(p)),
        }
    }

    /// The parameter range [t0, t1] of the ray `o + t d` inside the
    /// volume's box, if it meets it.
    #[inline]
    pub fn clip(&self, o: Vec3, d: Vec3) -> Option<(f32, f32)> {
        let (lo, hi) = self.bounds;
        let inv = d.recip();
        let a = (lo - o) * inv;
        let b = (hi - o) * inv;
        // NaN (0 · ∞ for a ray in a face's plane) is dropped by min/max.
        let t0 = a.min(b).max_element();
        let t1 = a.max(b).min_element();
        (t0 <= t1).then_some((t0, t1))
    }
}

/// The contents of a `.vol` file (format in the module's documentation),
/// read by volume grids and by the `sdfgrid` shape.
pub struct VolFile {
    pub res: [usize; 3],
    pub channels: usize,
    /// x fastest, channels interleaved.
    pub data: Vec<f32>,
    /// The bounds the file gives (lo, hi).
    pub bounds: (Vec3, Vec3),
}

impl VolFile {
    /// Parses the bytes of a `.vol` file; an error says what is wrong.
    pub fn parse(bytes: &[u8]) -> Result<VolFile, String> {
        if bytes.len() < 48 || &bytes[..3] != b"VOL" {
            return Err("not a Mitsuba volume grid (it must start with \"VOL\" and a 48-byte header)".into());
        }
        if bytes[3] != 3 {
            return Err(format!("format version {} (only version 3 is read)", bytes[3]));
        }
        let int = |at: usize| i32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
        let float = |at: usize| f32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
        if int(4) != 1 {
            return Err(format!("encoding {} (only 1, float32, is read)", int(4)));
        }
        let dims = [int(8), int(12), int(16)];
        let channels = int(20);
        if dims.iter().any(|&d| d <= 0) {
            return Err(format!("resolution {}×{}×{} is not positive", dims[0], dims[1], dims[2]));
        }
        if channels <= 0 {
            return Err(format!("{channels} channels"));
        }
        let count = dims.iter().try_fold(channels as usize, |acc, &d| acc.checked_mul(d as usize));
        let expected = count.and_then(|c| c.checked_mul(4)).and_then(|c| c.checked_add(48));
        if expected != Some(bytes.len()) {
            return Err(format!(
                "{} bytes, but a {}×{}×{} grid of {channels} float32 channels takes {}",
                bytes.len(),
                dims[0],
                dims[1],
                dims[2],
                expected.map_or("more than fits in memory".to_string(), |e| e.to_string())
            ));
        }
        Ok(VolFile {
            res: [dims[0] as usize, dims[1] as usize, dims[2] as usize],
            channels: channels as usize,
            data: bytes[48..].chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect(),
            bounds: (Vec3::new(float(24), float(28), float(32)), Vec3::new(float(36), float(40), float(44))),
        })
    }
}

/// A `.vol` file's bytes (bounds the unit cube), for tests.
#[cfg(test)]
pub fn vol_bytes(res: [i32; 3], channels: i32, values: &[f32]) -> Vec<u8> {
    let mut b = b"VOL\x03".to_vec();
    for v in [1, res[0], res[1], res[2], channels] {
        b.extend(v.to_le_bytes());
    }
    for v in [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
        b.extend(v.to_le_bytes());
    }
    for v in values {
        b.extend(v.to_le_bytes());
    }
    b
}

impl Grid {
    /// Reads a `.vol` file; an error message says what is wrong with it.
    pub fn read(path: &Path, nearest: bool, wrap: WrapMode) -> Result<Grid, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot read the volume file \"{}\": {e}", path.display()))?;
        Grid::parse(&bytes, nearest, wrap).map_err(|e| format!("volume file \"{}\": {e}", path.display()))
    }

    pub fn parse(bytes: &[u8], nearest: bool, wrap: WrapMode) -> Result<Grid, String> {
        let vol = VolFile::parse(bytes)?;
        if vol.channels != 1 && vol.channels != 3 {
            return Err(format!("{} channels (1 or 3 are read)", vol.channels));
        }
        if let Some(v) = vol.data.iter().find(|v| !v.is_finite() || **v < 0.0) {
            return Err(format!("a value is {v}; volume values must be finite and not negative"));
        }
        Ok(Grid { res: vol.res, channels: vol.channels, data: vol.data, file_bounds: vol.bounds, nearest, wrap })
    }

    /// The transform that maps the unit cube to the bounds the file gives.
    pub fn bounds_transform(&self) -> Option<Transform> {
        let (lo, hi) = self.file_bounds;
        let size = hi - lo;
        if !(size.min_element() > 0.0) || !size.is_finite() || !lo.is_finite() {
            return None;
        }
        Transform::from_matrix(glam::Mat4::from_translation(lo) * glam::Mat4::from_scale(size))
    }

    fn index(&self, i: i64, axis: usize) -> usize {
        let n = self.res[axis] as i64;
        let i = match self.wrap {
            WrapMode::Clamp => i.clamp(0, n - 1),
            WrapMode::Repeat => i.rem_euclid(n),
            WrapMode::Mirror => {
                let m = i.rem_euclid(2 * n);
                if m < n { m } else { 2 * n - 1 - m }
            }
        };
        i as usize
    }

    fn texel(&self, x: usize, y: usize, z: usize) -> Rgb {
        let at = ((z * self.res[1] + y) * self.res[0] + x) * self.channels;
        if self.channels == 1 {
            Rgb([self.data[at]; 3])
        } else {
            Rgb([self.data[at], self.data[at + 1], self.data[at + 2]])
        }
    }

    /// The value at `q` in the grid's unit cube.
    pub fn eval(&self, q: Vec3) -> Rgb {
        let q = [q.x, q.y, q.z];
        if self.nearest {
            let i = |a: usize| self.index((q[a] * self.res[a] as f32).floor() as i64, a);
            return self.texel(i(0), i(1), i(2));
        }
        // Cell centres at (i + ½) / res.
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        let mut f = [0f32; 3];
        for a in 0..3 {
            let x = q[a] * self.res[a] as f32 - 0.5;
            let x = if x.is_finite() { x.clamp(-1e7, 1e7) } else { 0.0 };
            let base = x.floor();
            f[a] = x - base;
            lo[a] = self.index(base as i64, a);
            hi[a] = self.index(base as i64 + 1, a);
        }
        let mut out = Rgb([0.0; 3]);
        for corner in 0..8 {
            let pick = |a: usize| corner >> a & 1 == 1;
            let w = (0..3).map(|a| if pick(a) { f[a] } else { 1.0 - f[a] }).product::<f32>();
            if w == 0.0 {
                continue;
            }
            let t = self.texel(if pick(0) { hi[0] } else { lo[0] }, if pick(1) { hi[1] } else { lo[1] }, if pick(2) { hi[2] } else { lo[2] });
            for c in 0..3 {
                out.0[c] += w * t.0[c];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trilinear_lookup_hits_cell_centres_and_interpolates_between() {
        // 2×1×1 grid: 1 at x-cell 0, 3 at x-cell 1.
        let g = Grid::parse(&vol_bytes([2, 1, 1], 1, &[1.0, 3.0]), false, WrapMode::Clamp).unwrap();
        let at = |x: f32| g.eval(Vec3::new(x, 0.5, 0.5)).0[0];
        assert!((at(0.25) - 1.0).abs() < 1e-6);
        assert!((at(0.75) - 3.0).abs() < 1e-6);
        assert!((at(0.5) - 2.0).abs() < 1e-6);
        assert!((at(0.0) - 1.0).abs() < 1e-6, "clamped below the first centre");
        assert!((at(1.0) - 3.0).abs() < 1e-6, "clamped above the last centre");
        let r = Grid::parse(&vol_bytes([2, 1, 1], 1, &[1.0, 3.0]), false, WrapMode::Repeat).unwrap();
        assert!((r.eval(Vec3::new(1.0, 0.5, 0.5)).0[0] - 2.0).abs() < 1e-6, "repeat wraps the last cell onto the first");
        let n = Grid::parse(&vol_bytes([2, 1, 1], 1, &[1.0, 3.0]), true, WrapMode::Clamp).unwrap();
        assert_eq!(n.eval(Vec3::new(0.49, 0.5, 0.5)).0[0], 1.0);
        assert_eq!(n.eval(Vec3::new(0.51, 0.5, 0.5)).0[0], 3.0);
    }

    #[test]
    fn bad_volume_files_are_errors_that_say_why() {
        let good = vol_bytes([2, 2, 2], 3, &[0.5; 24]);
        assert!(Grid::parse(&good, false, WrapMode::Clamp).is_ok());
        for (bytes, says) in [
            (good[..40].to_vec(), "48-byte header"),
            (good[..good.len() - 4].to_vec(), "bytes"),
            (vol_bytes([2, 2, 2], 2, &[0.5; 16]), "channels"),
            (vol_bytes([0, 2, 2], 1, &[]), "not positive"),
            (vol_bytes([1, 1, 1], 1, &[f32::NAN]), "finite"),
            (vol_bytes([1, 1, 1], 1, &[-1.0]), "negative"),
            (vol_bytes([i32::MAX, i32::MAX, i32::MAX], 3, &[]), "bytes"),
        ] {
            let e = Grid::parse(&bytes, false, WrapMode::Clamp).unwrap_err();
            assert!(e.contains(says), "{e}");
        }
    }

    #[test]
    fn a_volume_box_clips_rays() {
        let v = Volume::constant(Rgb([1.0; 3]), Transform::from_matrix(glam::Mat4::from_translation(Vec3::splat(-0.5))).unwrap());
        let (t0, t1) = v.clip(Vec3::new(0.0, 0.0, -2.0), Vec3::Z).unwrap();
        assert!((t0 - 1.5).abs() < 1e-6 && (t1 - 2.5).abs() < 1e-6);
        assert!(v.clip(Vec3::new(2.0, 0.0, -2.0), Vec3::Z).is_none());
    }
}

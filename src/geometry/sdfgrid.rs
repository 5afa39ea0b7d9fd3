//! Mitsuba's `sdfgrid`: the zero level set of a signed distance field
//! sampled on a regular grid. The samples sit on the grid's vertices, which
//! span the unit cube [0, 1]³ in object space (sample (i, j, k) of an
//! nx × ny × nz grid is at (i/(nx−1), j/(ny−1), k/(nz−1))), and the field
//! between them is the trilinear interpolant of each voxel's eight corners.
//! Negative values are inside, so normals (the field's gradient) point out.
//!
//! | parameter  | type      | default  | meaning                                                        |
//! |------------|-----------|----------|----------------------------------------------------------------|
//! | `filename` | string    | —        | Mitsuba's binary `.vol` grid, one float32 channel (required)   |
//! | `normals`  | string    | `smooth` | shading normals: `smooth` (blended across voxels) or `analytic` |
//! | `to_world` | transform | identity | places the unit cube (any invertible affine map)               |
//!
//! ```xml
//! <shape type="sdfgrid">
//!     <string name="filename" value="sdfgrid/torus_sdfgrid.vol"/>
//!     <string name="normals" value="analytic"/>
//!     <bsdf type="diffuse"/>
//! </shape>
//! ```
//!
//! As in Mitsuba:
//! - a ray meets the first zero of the trilinear interpolant along it
//!   (within a voxel, a cubic in t); both sides are surface (no culling);
//! - the geometric normal is the gradient of the hit voxel's interpolant;
//!   `analytic` shades with it, `smooth` blends the gradients of the eight
//!   voxels around the nearest grid vertex (Hansson-Söderlund, Evans and
//!   Akenine-Möller, "Ray Tracing of Signed Distance Function Grids", JCGT
//!   2022), which hides the voxel-to-voxel creases;
//! - there is no parameterisation: uv is (0, 0) everywhere, so textures see
//!   a constant; the hit point is not projected onto the level set;
//! - the shape has no area and no position sampling, so it cannot carry an
//!   `area` emitter; the grid's own bounds in the file are ignored;
//! - the bounding box is the placed unit cube.
//!
//! Differences: Mitsuba asks for a `to_world` without rotation (it warns,
//! and its per-voxel boxes are then wrong, so hits go missing); here any
//! invertible affine `to_world` works, and gives what Mitsuba gives for the
//! same grid placed by an `instance`. The `grid` tensor parameter (Python
//! only in Mitsuba) has no XML form and is not read. Roots are found to
//! double precision (Mitsuba stops within 1e-5 in t), and hits closer than
//! a small relative epsilon to the ray's origin are ignored, as for the
//! other shapes, so that a ray leaving the surface does not find it again.
//!
//! The intersection walks the voxels along the ray (3-D DDA, clipped to the
//! box of the voxels that can hold the surface), skips voxels whose corners
//! all have the same strict sign (a trilinear interpolant stays within its
//! corners' range), and finds the first root of the cubic by splitting it
//! into monotonic pieces at the roots of its derivative, then safeguarded
//! Newton steps, all in double precision.

use crate::math::Transform;
use crate::medium::volume::VolFile;
use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};
use std::path::Path;
use std::sync::Arc;

/// How shading normals are computed (Mitsuba's `normals` parameter).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdfNormals {
    /// The gradient of the hit voxel's interpolant (the geometric normal).
    Analytic,
    /// Gradients of the eight voxels around the nearest vertex, blended.
    Smooth,
}

impl SdfNormals {
    /// The value of Mitsuba's `normals` string, if it is one.
    pub fn parse(s: &str) -> Option<SdfNormals> {
        match s {
            "analytic" => Some(SdfNormals::Analytic),
            "smooth" => Some(SdfNormals::Smooth),
            _ => None,
        }
    }
}

#[derive(Clone)]
pub struct SdfGrid {
    pub to_world: Transform,
    pub normals: SdfNormals,
    /// Samples along x, y, z (each at least 2).
    res: [usize; 3],
    /// The samples, x fastest (shared: instances clone shapes).
    values: Arc<[f32]>,
    /// One bit per voxel (x fastest over the (nx−1)(ny−1)(nz−1) voxels):
    /// its corners are not all of one strict sign, so it may hold surface.
    occupied: Arc<[u64]>,
    /// Voxel index range [lo, hi) of the occupied voxels along each axis.
    occ_lo: [i64; 3],
    occ_hi: [i64; 3],
    /// World → voxel coordinates (object space scaled by res − 1, so the
    /// voxel (i, j, k) is [i, i+1] × [j, j+1] × [k, k+1]).
    to_voxel: DMat4,
    /// Voxel-space gradient → world-space normal (the transpose of
    /// `to_voxel`'s linear part: normals transform by the inverse transpose).
    normal_to_world: DMat3,
}

impl std::fmt::Debug for SdfGrid {
    // The grid itself would print millions of numbers.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SdfGrid").field("res", &self.res).field("normals", &self.normals).field("to_world", &self.to_world).finish_non_exhaustive()
    }
}

/// Hits closer than this fraction of (1 + the origin's largest coordinate),
/// in world units along the ray, are ignored: a ray started on the surface
/// (from a hit point rounded to single precision) must not find that same
/// surface again at t ≈ 0.
const T_EPSILON: f64 = 32.0 * f32::EPSILON as f64;

impl SdfGrid {
    /// Reads Mitsuba's `.vol` file (version 3, float32, one channel).
    pub fn load(path: &Path, to_world: &Transform, normals: SdfNormals) -> Result<SdfGrid, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot read the SDF grid file \"{}\": {e}", path.display()))?;
        let (values, res) = parse_vol(&bytes).map_err(|e| format!("SDF grid file \"{}\": {e}", path.display()))?;
        SdfGrid::from_values(values, res, to_world, normals).map_err(|e| format!("SDF grid file \"{}\": {e}", path.display()))
    }

    /// The shape from samples in x-fastest order at resolution (nx, ny, nz).
    pub fn from_values(values: Vec<f32>, res: [usize; 3], to_world: &Transform, normals: SdfNormals) -> Result<SdfGrid, String> {
        if res.iter().any(|&n| n < 2) {
            return Err(format!("resolution {}×{}×{}: an SDF grid needs at least 2 samples along each axis", res[0], res[1], res[2]));
        }
        let count = res[0].checked_mul(res[1]).and_then(|c| c.checked_mul(res[2]));
        if count != Some(values.len()) {
            return Err(format!("{} values for a {}×{}×{} grid", values.len(), res[0], res[1], res[2]));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(format!("a value is {v}; SDF values must be finite"));
        }
        let m = to_world.matrix.as_dmat4();
        let det = m.determinant();
        if !m.is_finite() || !det.is_finite() || det.abs() < 1e-30 {
            return Err("to_world cannot be inverted".into());
        }
        let to_object = m.inverse();
        let scale = DVec3::new((res[0] - 1) as f64, (res[1] - 1) as f64, (res[2] - 1) as f64);
        let to_voxel = DMat4::from_scale(scale) * to_object;
        let normal_to_world = DMat3::from_mat4(to_voxel).transpose();

        // Which voxels may hold surface: some corner ≥ 0 and some ≤ 0 (as
        // Mitsuba, which builds a box only for those).
        let nv = [res[0] - 1, res[1] - 1, res[2] - 1];
        let mut occupied = vec![0u64; (nv[0] * nv[1] * nv[2]).div_ceil(64)];
        let (mut occ_lo, mut occ_hi) = ([i64::MAX; 3], [i64::MIN; 3]);
        for z in 0..nv[2] {
            for y in 0..nv[1] {
                for x in 0..nv[0] {
                    let (mut any_pos, mut any_neg) = (false, false);
                    for c in 0..8 {
                        let v = values[((z + (c >> 2)) * res[1] + y + ((c >> 1) & 1)) * res[0] + x + (c & 1)];
                        any_pos |= v >= 0.0;
                        any_neg |= v <= 0.0;
                    }
                    if any_pos && any_neg {
                        let i = (z * nv[1] + y) * nv[0] + x;
                        occupied[i / 64] |= 1 << (i % 64);
                        for (a, c) in [x, y, z].into_iter().enumerate() {
                            occ_lo[a] = occ_lo[a].min(c as i64);
                            occ_hi[a] = occ_hi[a].max(c as i64 + 1);
                        }
                    }
                }
            }
        }
        if occ_lo[0] == i64::MAX {
            return Err("no voxel holds any surface (the values never change sign)".into());
        }

        Ok(SdfGrid {
            to_world: *to_world,
            normals,
            res,
            values: values.into(),
            occupied: occupied.into(),
            occ_lo,
            occ_hi,
            to_voxel,
            normal_to_world,
        })
    }

    /// Samples along x, y and z.
    pub fn resolution(&self) -> [usize; 3] {
        self.res
    }

    /// World-space bounding box (lo, hi): the placed unit cube.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        // As Mitsuba's `bbox()`.
        self.to_world.unit_cube_bounds()
    }

    /// Nearest t in (0, tmax) where the world-space ray o + t·d meets the
    /// surface, or infinity.
    pub fn intersect(&self, o: Vec3, d: Vec3, tmax: f32) -> f32 {
        let len = d.length();
        if !(len > 0.0) || !o.is_finite() || !d.is_finite() || !(tmax > 0.0) {
            return f32::INFINITY;
        }
        let x = self.to_voxel.transform_point3(o.as_dvec3());
        let dv = self.to_voxel.transform_vector3(d.as_dvec3());
        let t_min = T_EPSILON * (1.0 + o.abs().max_element() as f64) / len as f64;
        match self.walk(x, dv, t_min, tmax as f64) {
            Some((t, _)) => {
                let t = t as f32;
                if t > 0.0 && t < tmax { t } else { f32::INFINITY }
            }
            None => f32::INFINITY,
        }
    }

    /// At a hit point `p` of a ray with direction `d` (from
    /// [`SdfGrid::intersect`]): the point (unchanged, as Mitsuba does not
    /// project it), the geometric normal, the shading normal (world, unit)
    /// and uv (always zero: the shape has no parameterisation).
    pub fn surface(&self, p: Vec3, d: Vec3) -> (Vec3, Vec3, Vec3, Vec2) {
        let x = self.to_voxel.transform_point3(p.as_dvec3());
        let dv = self.to_voxel.transform_vector3(d.as_dvec3());
        let fallback = (-d).normalize_or(Vec3::Z);
        if !x.is_finite() {
            return (p, fallback, fallback, Vec2::ZERO);
        }
        // Hits are inside the grid; this only keeps stray points' indices small.
        let x = x.clamp(DVec3::splat(-1.0), self.voxel_scale() + 1.0);
        let voxel = self.hit_voxel(x, dv);
        let grad = self.voxel_gradient(voxel, x);
        let n = (self.normal_to_world * grad).normalize_or_zero();
        let n = if n == DVec3::ZERO { fallback } else { n.as_vec3() };
        let sh = match self.normals {
            SdfNormals::Analytic => n,
            SdfNormals::Smooth => {
                let s = (self.normal_to_world * self.smooth_gradient(x)).normalize_or_zero();
                if s == DVec3::ZERO { n } else { s.as_vec3() }
            }
        };
        (p, n, sh, Vec2::ZERO)
    }

    #[inline]
    fn sample(&self, x: usize, y: usize, z: usize) -> f64 {
        self.values[(z * self.res[1] + y) * self.res[0] + x] as f64
    }

    /// The eight corner values of voxel `v`, indexed x + 2y + 4z.
    #[inline]
    fn corners(&self, v: [usize; 3]) -> [f64; 8] {
        let mut s = [0.0; 8];
        for (c, s) in s.iter_mut().enumerate() {
            *s = self.sample(v[0] + (c & 1), v[1] + ((c >> 1) & 1), v[2] + (c >> 2));
        }
        s
    }

    #[inline]
    fn is_occupied(&self, v: [i64; 3]) -> bool {
        let nv = [self.res[0] - 1, self.res[1] - 1, self.res[2] - 1];
        let i = (v[2] as usize * nv[1] + v[1] as usize) * nv[0] + v[0] as usize;
        self.occupied[i / 64] >> (i % 64) & 1 == 1
    }

    /// The first zero of the interpolant along x + t·dv (voxel space) with
    /// t in [t0, t1], and the voxel it lies in.
    fn walk(&self, x: DVec3, dv: DVec3, t0: f64, t1: f64) -> Option<(f64, [usize; 3])> {
        let (xa, da) = (x.to_array(), dv.to_array());
        if !x.is_finite() || !dv.is_finite() || dv == DVec3::ZERO {
            return None;
        }
        // Clip to the box of the occupied voxels; remember the face the ray
        // enters through (its coordinate is then exact, see `voxel_root`).
        let (mut tn, mut tf) = (t0, t1);
        let mut entry_axis = None;
        for a in 0..3 {
            let (lo, hi) = (self.occ_lo[a] as f64, self.occ_hi[a] as f64);
            if da[a] == 0.0 {
                if xa[a] < lo || xa[a] > hi {
                    return None;
                }
                continue;
            }
            let (ta, tb) = ((lo - xa[a]) / da[a], (hi - xa[a]) / da[a]);
            let (ta, tb) = if ta < tb { (ta, tb) } else { (tb, ta) };
            if ta > tn {
                tn = ta;
                entry_axis = Some(a);
            }
            tf = tf.min(tb);
        }
        if !(tn <= tf) {
            return None;
        }

        // The voxel the ray is in just after tn: on a grid plane, the one
        // on the side it moves to.
        let mut v = [0i64; 3];
        let mut step = [0i64; 3];
        let mut t_next = [f64::INFINITY; 3];
        for a in 0..3 {
            let c = xa[a] + da[a] * tn;
            let i = match entry_axis {
                Some(e) if e == a => {
                    if da[a] > 0.0 {
                        self.occ_lo[a]
                    } else {
                        self.occ_hi[a] - 1
                    }
                }
                _ if da[a] < 0.0 => c.ceil() as i64 - 1,
                _ => c.floor() as i64,
            };
            v[a] = i.clamp(self.occ_lo[a], self.occ_hi[a] - 1);
            step[a] = if da[a] > 0.0 {
                1
            } else if da[a] < 0.0 {
                -1
            } else {
                0
            };
            t_next[a] = self.plane_t(xa[a], da[a], v[a]);
        }

        let mut t_enter = tn;
        loop {
            let a = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
                0
            } else if t_next[1] <= t_next[2] {
                1
            } else {
                2
            };
            let (t_exit, exit_axis) = if t_next[a] < tf { (t_next[a].max(t_enter), Some(a)) } else { (tf, None) };
            if self.is_occupied(v) {
                let vu = [v[0] as usize, v[1] as usize, v[2] as usize];
                if let Some(t) = self.voxel_root(vu, x, dv, t_enter, t_exit, entry_axis, exit_axis) {
                    return Some((t, vu));
                }
            }
            exit_axis?; // left through the far end of the range
            v[a] += step[a];
            if v[a] < self.occ_lo[a] || v[a] >= self.occ_hi[a] {
                return None;
            }
            t_next[a] = self.plane_t(xa[a], da[a], v[a]);
            entry_axis = Some(a);
            t_enter = t_exit;
        }
    }

    /// Where the ray leaves voxel index `v` along one axis.
    #[inline]
    fn plane_t(&self, x: f64, d: f64, v: i64) -> f64 {
        if d > 0.0 {
            ((v + 1) as f64 - x) / d
        } else if d < 0.0 {
            (v as f64 - x) / d
        } else {
            f64::INFINITY
        }
    }

    /// The first zero of voxel `v`'s interpolant along the ray for t in
    /// [t_enter, t_exit].
    #[allow(clippy::too_many_arguments)]
    fn voxel_root(&self, v: [usize; 3], x: DVec3, dv: DVec3, t_enter: f64, t_exit: f64, entry: Option<usize>, exit: Option<usize>) -> Option<f64> {
        let s = self.corners(v);
        let base = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        // Local coordinates where the ray enters and leaves. On the face it
        // crosses, a coordinate is set to exactly 0 or 1: the neighbouring
        // voxel then computes bit for bit the same value there (the face's
        // bilinear interpolant of the same four samples at the same point),
        // so a surface passing through the face is found by one of them
        // rather than missed by both through rounding.
        let local = |t: f64, face: Option<usize>, leaving: bool| {
            let mut q = (x + dv * t - base).clamp(DVec3::ZERO, DVec3::ONE);
            if let Some(a) = face {
                q[a] = if (dv[a] > 0.0) == leaving { 1.0 } else { 0.0 };
            }
            q
        };
        let q0 = local(t_enter, entry, false);
        let f0 = trilerp(&s, q0);
        let f1 = trilerp(&s, local(t_exit, exit, true));
        let len = t_exit - t_enter;

        // The interpolant along the ray, u = t − t_enter:
        // f = k0 + k1 x + k2 y + k4 z + k3 xy + k5 xz + k6 yz + k7 xyz.
        let k0 = s[0];
        let k1 = s[1] - s[0];
        let k2 = s[2] - s[0];
        let k4 = s[4] - s[0];
        let k3 = s[3] - s[2] - k1;
        let k5 = s[5] - s[4] - k1;
        let k6 = s[6] - s[4] - k2;
        let k7 = (s[7] - s[6]) - (s[5] - s[4]) - k3;
        let (p, d) = (q0, dv);
        let c0 = k0 + k1 * p.x + k2 * p.y + k4 * p.z + k3 * p.x * p.y + k5 * p.x * p.z + k6 * p.y * p.z + k7 * p.x * p.y * p.z;
        let gx = k1 + k3 * p.y + k5 * p.z + k7 * p.y * p.z;
        let gy = k2 + k3 * p.x + k6 * p.z + k7 * p.x * p.z;
        let gz = k4 + k5 * p.x + k6 * p.y + k7 * p.x * p.y;
        let c1 = gx * d.x + gy * d.y + gz * d.z;
        let c2 = k3 * d.x * d.y + k5 * d.x * d.z + k6 * d.y * d.z + k7 * (d.x * d.y * p.z + d.x * p.y * d.z + p.x * d.y * d.z);
        let c3 = k7 * d.x * d.y * d.z;
        let cubic = Cubic([c0, c1, c2, c3]);

        // Split [0, len] at the derivative's zeros into monotonic pieces
        // and take the first piece whose ends differ in sign.
        let mut ends = [len; 3];
        let mut n = 0;
        for r in cubic.turning_points() {
            if r > 0.0 && r < len {
                ends[n] = r;
                n += 1;
            }
        }
        ends[n] = len;
        let (mut a, mut fa) = (0.0, f0);
        for (i, &b) in ends[..=n].iter().enumerate() {
            let fb = if i == n { f1 } else { cubic.eval(b) };
            if fa == 0.0 {
                return Some(t_enter + a);
            }
            if fb == 0.0 {
                return Some(t_enter + b);
            }
            if (fa < 0.0) != (fb < 0.0) {
                return Some(t_enter + cubic.root_in(a, b, fa, fb, t_enter.abs() + len));
            }
            (a, fa) = (b, fb);
        }
        None
    }

    /// The voxel a hit at `x` (voxel space) of a ray along `dv` was found
    /// in: a short walk from just before the point to just after it. (On a
    /// face between voxels, flooring the point could pick the neighbour,
    /// whose gradient differs.)
    fn hit_voxel(&self, x: DVec3, dv: DVec3) -> [usize; 3] {
        let reach = 1e-3 / dv.abs().max_element();
        if reach.is_finite()
            && let Some((_, v)) = self.walk(x, dv, -reach, reach)
        {
            return v;
        }
        let mut v = [0; 3];
        for a in 0..3 {
            v[a] = (x[a].floor().max(0.0) as usize).min(self.res[a] - 2);
        }
        v
    }

    /// Voxel-space gradient of voxel `v`'s interpolant at `x` (clamped into
    /// the voxel).
    fn voxel_gradient(&self, v: [usize; 3], x: DVec3) -> DVec3 {
        let s = self.corners(v);
        let q = (x - DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)).clamp(DVec3::ZERO, DVec3::ONE);
        DVec3::new(
            bilerp([s[1] - s[0], s[3] - s[2], s[5] - s[4], s[7] - s[6]], q.y, q.z),
            bilerp([s[2] - s[0], s[3] - s[1], s[6] - s[4], s[7] - s[5]], q.x, q.z),
            bilerp([s[4] - s[0], s[5] - s[1], s[6] - s[2], s[7] - s[3]], q.x, q.y),
        )
    }

    /// The smooth normal at `x` (voxel space), unnormalised and in the form
    /// `normal_to_world` takes (an object-space vector divided by the voxel
    /// scale).
    ///
    /// The eight voxels around the grid vertex nearest to `x` each give a
    /// gradient: along each axis, the difference of the global interpolant
    /// between the voxel's two grid planes, taken at `x`'s position along
    /// the other two axes. Their unit vectors are blended trilinearly by
    /// `x`'s position relative to the voxels' centres. Voxels below the
    /// grid get weight zero; above it, the sample index is clamped so the
    /// difference along that axis vanishes. (Mitsuba's definition.)
    fn smooth_gradient(&self, x: DVec3) -> DVec3 {
        let (res, scale) = (self.res, self.voxel_scale());
        let xa = x.to_array();
        let mut v = [0i64; 3];
        let mut uvw = [0.0; 3];
        let mut cell = [0usize; 3];
        let mut w = [0.0; 3];
        for a in 0..3 {
            // `round_ties_even` as Mitsuba's rounding (rint) does.
            let r = xa[a].round_ties_even();
            v[a] = r as i64 - 1;
            uvw[a] = if v[a] >= 0 { xa[a] - v[a] as f64 - 0.5 } else { 1.0 };
            cell[a] = (xa[a].floor().max(0.0) as usize).min(res[a] - 2);
            w[a] = xa[a] - cell[a] as f64;
        }
        // The interpolant on grid plane `q` (clamped) across axis `a`, at
        // x's position along the other two axes.
        let plane = |a: usize, q: i64| {
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            let mut f = [0.0; 4];
            for (i, f) in f.iter_mut().enumerate() {
                let mut idx = [0usize; 3];
                idx[a] = q.clamp(0, res[a] as i64 - 1) as usize;
                idx[b] = cell[b] + (i & 1);
                idx[c] = cell[c] + (i >> 1);
                *f = self.sample(idx[0], idx[1], idx[2]);
            }
            bilerp(f, w[b], w[c])
        };
        // Differences across the lower (v) and upper (v + 1) voxels per axis.
        let mut d_lo = [0.0; 3];
        let mut d_hi = [0.0; 3];
        for a in 0..3 {
            let (g0, g1, g2) = (plane(a, v[a]), plane(a, v[a] + 1), plane(a, v[a] + 2));
            d_lo[a] = g1 - g0;
            d_hi[a] = g2 - g1;
        }
        let mut n = [DVec3::ZERO; 8];
        for (i, n) in n.iter_mut().enumerate() {
            let hi = [i & 1 != 0, i & 2 != 0, i & 4 != 0];
            if (0..3).all(|a| hi[a] || v[a] >= 0) {
                let g = DVec3::from_array(std::array::from_fn(|a| if hi[a] { d_hi[a] } else { d_lo[a] }));
                // Mitsuba normalises in object space (voxel gradient · scale).
                *n = (g * scale).normalize_or_zero();
            }
        }
        let lerp = |a: DVec3, b: DVec3, t: f64| a * (1.0 - t) + b * t;
        lerp(lerp(lerp(n[0], n[1], uvw[0]), lerp(n[2], n[3], uvw[0]), uvw[1]), lerp(lerp(n[4], n[5], uvw[0]), lerp(n[6], n[7], uvw[0]), uvw[1]), uvw[2]) / scale // back to voxel-space form, which `normal_to_world` takes
    }

    /// Res − 1 per axis: voxel-space gradient · this = object-space gradient.
    #[inline]
    fn voxel_scale(&self) -> DVec3 {
        DVec3::new((self.res[0] - 1) as f64, (self.res[1] - 1) as f64, (self.res[2] - 1) as f64)
    }
}

/// c0 + c1 u + c2 u² + c3 u³.
struct Cubic([f64; 4]);

impl Cubic {
    #[inline]
    fn eval(&self, u: f64) -> f64 {
        let c = &self.0;
        ((c[3] * u + c[2]) * u + c[1]) * u + c[0]
    }

    #[inline]
    fn slope(&self, u: f64) -> f64 {
        let c = &self.0;
        (3.0 * c[3] * u + 2.0 * c[2]) * u + c[1]
    }

    /// Real zeros of the derivative, ascending (NaN when absent, which
    /// fails every range test).
    fn turning_points(&self) -> [f64; 2] {
        let (a, b, c) = (3.0 * self.0[3], 2.0 * self.0[2], self.0[1]);
        if a == 0.0 {
            return [if b != 0.0 { -c / b } else { f64::NAN }, f64::NAN];
        }
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            return [f64::NAN; 2];
        }
        // The form without cancellation.
        let q = -0.5 * (b + disc.sqrt().copysign(b));
        let r0 = q / a;
        let r1 = if q != 0.0 { c / q } else { r0 };
        if r0 < r1 { [r0, r1] } else { [r1, r0] }
    }

    /// The zero in [a, b], where the cubic is monotonic and fa, fb (its
    /// values at the ends, nonzero) differ in sign: Newton steps from the
    /// secant estimate, kept inside the shrinking bracket by bisection.
    /// `scale` sets the convergence tolerance (t's magnitude).
    fn root_in(&self, a: f64, b: f64, fa: f64, fb: f64, scale: f64) -> f64 {
        let neg_at_a = fa < 0.0;
        let (mut lo, mut hi) = (a, b);
        let mut u = a + (b - a) * (fa / (fa - fb));
        if !(u >= a && u <= b) {
            u = 0.5 * (a + b);
        }
        let tol = 4.0 * f64::EPSILON * scale;
        for _ in 0..100 {
            let f = self.eval(u);
            if f == 0.0 {
                return u;
            }
            if (f < 0.0) == neg_at_a {
                lo = u;
            } else {
                hi = u;
            }
            let mut next = u - f / self.slope(u);
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            if (next - u).abs() <= tol || hi - lo <= tol {
                return next;
            }
            u = next;
        }
        u
    }
}

/// Bilinear interpolant of f (indexed u + 2v). The (1 − t)·a + t·b form
/// gives exactly a at t = 0 and b at t = 1 (face values must agree
/// between neighbouring voxels).
#[inline]
fn bilerp(f: [f64; 4], u: f64, v: f64) -> f64 {
    let lerp = |a: f64, b: f64, t: f64| a * (1.0 - t) + b * t;
    lerp(lerp(f[0], f[1], u), lerp(f[2], f[3], u), v)
}

/// Trilinear interpolant of a voxel's corners (indexed x + 2y + 4z).
#[inline]
fn trilerp(s: &[f64; 8], q: DVec3) -> f64 {
    let lo = bilerp([s[0], s[1], s[2], s[3]], q.x, q.y);
    let hi = bilerp([s[4], s[5], s[6], s[7]], q.x, q.y);
    lo * (1.0 - q.z) + hi * q.z
}

/// The samples and resolution of a `.vol` file with one float32 channel
/// (negative values allowed, unlike a medium's grid: every SDF has them).
fn parse_vol(bytes: &[u8]) -> Result<(Vec<f32>, [usize; 3]), String> {
    let vol = VolFile::parse(bytes)?;
    if vol.channels != 1 {
        return Err(format!("{} channels, but an SDF grid has exactly 1", vol.channels));
    }
    Ok((vol.data, vol.res))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Pcg32;
    use crate::medium::volume::vol_bytes;
    use glam::Mat4;

    fn random_unit(rng: &mut Pcg32) -> Vec3 {
        loop {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            let l = v.length();
            if l > 0.1 && l <= 1.0 {
                return v / l;
            }
        }
    }

    /// Samples of `f` at the vertices of an n × n × n grid over the unit cube.
    fn sampled(n: usize, f: impl Fn(DVec3) -> f64) -> Vec<f32> {
        let mut v = Vec::with_capacity(n * n * n);
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    v.push(f(DVec3::new(x as f64, y as f64, z as f64) / (n - 1) as f64) as f32);
                }
            }
        }
        v
    }

    const CENTRE: Vec3 = Vec3::splat(0.5);
    const RADIUS: f32 = 0.3;

    fn sphere_grid(to_world: &Transform, normals: SdfNormals) -> SdfGrid {
        let values = sampled(32, |p| (p - DVec3::splat(0.5)).length() - RADIUS as f64);
        SdfGrid::from_values(values, [32; 3], to_world, normals).unwrap()
    }

    /// Nearest t > 0 on the exact sphere (unit d), or None.
    fn exact_sphere(o: Vec3, d: Vec3) -> Option<f32> {
        let oc = (o - CENTRE).as_dvec3();
        let b = oc.dot(d.as_dvec3());
        let disc = b * b - (oc.length_squared() - (RADIUS * RADIUS) as f64);
        if disc < 0.0 {
            return None;
        }
        [-b - disc.sqrt(), -b + disc.sqrt()].into_iter().find(|&t| t > 0.0).map(|t| t as f32)
    }

    /// A 32³ grid of the sphere |p − (½, ½, ½)| − 0.3. Trilinear
    /// interpolation of a distance field errs by at most h²/8 · tr(Hessian)
    /// = h²/8 · 2/ρ: with h = 1/31 and ρ ≈ 0.3 that is 9e-4, so the level set
    /// lies within 1e-3 of the sphere along its normal, and a ray meeting
    /// it at cos θ to the normal sees t off by at most 1e-3 / cos θ. The
    /// gradient of a voxel's interpolant errs by up to about h/2 · 1/ρ per
    /// axis (3° for one axis; measured: 4.1° at worst), so normals are
    /// allowed 6°.
    #[test]
    fn a_sampled_sphere_is_hit_where_the_sphere_is() {
        for normals in [SdfNormals::Analytic, SdfNormals::Smooth] {
            let g = sphere_grid(&Transform::IDENTITY, normals);
            let mut rng = Pcg32::new(5, 3);
            let (mut hits, mut misses) = (0, 0);
            let (mut worst_n, mut worst_sh) = (0.0f32, 0.0f32);
            for i in 0..4000 {
                let (o, d) = if i % 5 == 4 {
                    // From inside (the centre region) outwards.
                    (CENTRE + random_unit(&mut rng) * 0.2 * rng.next_f32(), random_unit(&mut rng))
                } else {
                    let o = CENTRE + random_unit(&mut rng) * 2.0;
                    let target = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.8 + 0.1;
                    (o, (target - o).normalize())
                };
                let t = g.intersect(o, d, f32::INFINITY);
                assert!(!t.is_nan());
                let to_c = CENTRE - o;
                let closest = (to_c - d * to_c.dot(d)).length();
                match exact_sphere(o, d) {
                    Some(te) if closest < RADIUS - 0.01 => {
                        hits += 1;
                        let pe = o + d * te;
                        let ne = (pe - CENTRE).normalize();
                        let cos = ne.dot(d).abs();
                        assert!((t - te).abs() * cos <= 1e-3, "{normals:?} o {o} d {d}: t {t} vs {te}");
                        let (p, n, sh, uv) = g.surface(o + d * t, d);
                        assert_eq!(uv, Vec2::ZERO);
                        assert!((p - (o + d * t)).length() < 1e-6);
                        worst_n = worst_n.max(n.dot(ne).clamp(-1.0, 1.0).acos().to_degrees());
                        worst_sh = worst_sh.max(sh.dot(ne).clamp(-1.0, 1.0).acos().to_degrees());
                        if normals == SdfNormals::Analytic {
                            assert_eq!(n, sh);
                        }
                    }
                    None if closest > RADIUS + 0.01 => {
                        misses += 1;
                        assert!(t.is_infinite(), "{normals:?} o {o} d {d}: hit at {t}, the sphere is missed by {}", closest - RADIUS);
                    }
                    _ => {} // near the silhouette either answer is right
                }
            }
            assert!(hits > 1500 && misses > 500, "{hits} hits, {misses} misses");
            println!("{normals:?}: geometric normals up to {worst_n}°, shading normals up to {worst_sh}° off the sphere's");
            assert!(worst_n < 6.0, "{normals:?}: geometric normals up to {worst_n}° off");
            assert!(worst_sh < 6.0, "{normals:?}: shading normals up to {worst_sh}° off");
        }
    }

    /// Mitsuba's `docs/scenes/sdfgrid/torus_sdfgrid.vol` (40³): a torus
    /// around the y axis through the grid's centre sample (20, 20, 20),
    /// radii 10 and 4 in sample units. Computed here, it is within 2e-6 of
    /// the file's values (the file rounded a different evaluation).
    fn torus() -> Vec<f32> {
        sampled(40, |p| {
            let q = p * 39.0 - DVec3::splat(20.0);
            let ring = (q.x * q.x + q.z * q.z).sqrt() - 10.0;
            (ring * ring + q.y * q.y).sqrt() - 4.0
        })
    }

    /// Fixture: Mitsuba 3.9.1 (scalar_rgb) measured on torus_sdfgrid.vol.
    /// Generated by a script that loads
    /// `{'type': 'scene', 's': {'type': 'sdfgrid', 'filename': …, 'normals': mode, 'to_world': T}}`
    /// for mode in (smooth, analytic) and T in (identity, translate(1, −2, 0.5)
    /// · scale(2, 0.5, 1.5)), fires `scene.ray_intersect(mi.Ray3f(T·o, T·d))`
    /// with o on a sphere of radius 2 around the cube's centre aimed at a
    /// point of [0.15, 0.85]³ (every third d scaled to a length in [0.3, 3])
    /// or o inside the cube with a random unit d (numpy seed 7), and prints
    /// si.t, si.n, si.sh_frame.n, si.uv. Rows: (transformed, world o,
    /// world d, t, n, smooth shading normal). In analytic mode Mitsuba gives
    /// the same t and n and a shading normal equal to n; uv is always (0, 0).
    /// Over all 400 rays × 4 cases: no hit/miss disagreement, |Δt|·|d| ≤
    /// 6e-7, |Δn| ≤ 3e-6, |Δ shading n| ≤ 1.1e-5.
    type Row = (bool, [f32; 3], [f32; 3], f32, [f32; 3], [f32; 3]);
    #[rustfmt::skip]
    const MITSUBA_TORUS: [Row; 28] = [
        (false, [0.5060679, 1.973594, -0.8522142], [-0.08662593, -0.7043998, 0.7044976], 1.977175, [0.7612404, 0.6302989, -0.1524347], [0.734839, 0.6684588, -0.1147799]),
        (false, [0.5841753, 2.375729, -0.188879], [-0.05111554, -0.9653509, 0.2559001], 1.826163, [0.01181387, 0.9929469, 0.1179691], [0.01824108, 0.9803405, 0.1964677]),
        (false, [0.7250333, -1.486318, 0.4375546], [-0.1576446, 1.960771, 0.2246435], 1.003034, [-0.358526, -0.3584921, -0.8619412], [-0.3192981, -0.3139457, -0.8941403]),
        (false, [-0.2044154, -0.9427612, -0.6925766], [0.2964872, 0.8097234, 0.5064023], 1.781806, [-0.5336009, -0.1278864, -0.8360114], [-0.5247604, -0.1274755, -0.8416511]),
        (false, [2.160104, -0.5954866, 0.2903223], [-1.540872, 1.218596, 0.5004239], 0.8889852, [0.7725811, -0.1335919, 0.6207025], [0.7579284, -0.2371062, 0.6077213]),
        (false, [0.4161793, 1.340821, 2.312731], [0.0849407, -0.4017211, -0.9118142], 2.119232, [-0.5427622, -0.1280266, 0.8300714], [-0.5178643, -0.2228072, 0.825938]),
        (false, [-0.7633452, 1.966811, -0.002418881], [0.6778454, -0.7054974, 0.2068794], 2.071045, [-0.805864, -0.1268987, 0.5783423], [-0.8253399, -0.07021219, 0.5602538]),
        (false, [-0.1299791, 2.156148, 1.427524], [0.4973216, -0.9345593, -0.497793], 1.664612, [-0.427702, 0.8762038, -0.2221216], [-0.4589877, 0.861854, -0.2157262]),
        (false, [-0.1316291, -1.366876, 0.8403232], [0.4483501, 0.8829532, -0.1391969], 2.013154, [0.1601263, -0.9870737, 0.006706483], [0.05791231, -0.9982464, 0.01225829]),
        (false, [1.230365, 2.253031, -0.1272555], [-0.3381737, -0.9105472, 0.2377864], 1.801016, [-0.0729178, 0.9906881, 0.114979], [-0.07952312, 0.984693, 0.1550989]),
        (false, [-0.0342459, 0.1881957, -1.401936], [0.368783, 0.1626077, 1.352677], 1.55064, [-0.05336432, -0.7154663, -0.6966063], [-0.0939309, -0.7102314, -0.6976736]),
        (false, [0.8804836, 0.1118438, 0.4369972], [-0.1575174, 0.9874223, 0.01362119], 0.3285273, [0.6896032, -0.7119132, -0.1327669], [0.6447316, -0.7502323, -0.1465354]),
        (false, [0.1309212, -1.196451, -0.4928914], [0.07173048, 0.8479239, 0.5252426], 1.896367, [0.1209128, -0.9926488, 0.005315042], [0.09855513, -0.9951236, 0.004003532]),
        (false, [0.8288684, 1.871987, -0.9175671], [-0.146417, -1.015283, 1.17235], 1.305422, [-0.73234, 0.3798402, -0.5651544], [-0.7378548, 0.3292488, -0.5892075]),
        (false, [0.2275543, 0.5662771, 0.6248749], [-0.4919831, -0.8321065, 0.25603], 0.08985986, [-0.9109449, -0.1302708, 0.3914191], [-0.9060406, -0.2031962, 0.3712165]),
        (false, [2.489673, 0.2994692, 0.4685612], [-1.302621, 0.2002836, -0.1597824], 1.347578, [0.5109704, 0.5811991, -0.6333379], [0.5442951, 0.5486566, -0.6346012]),
        (false, [0.9400641, 0.2437778, 0.1941908], [-0.9707814, 0.2077708, 0.1200611], f32::INFINITY, [0.0; 3], [0.0; 3]),
        (false, [0.3551229, -1.450565, 0.08249681], [0.116634, 0.9716117, 0.2058329], f32::INFINITY, [0.0; 3], [0.0; 3]),
        (false, [0.7175938, 0.132346, 0.5370294], [0.05672348, -0.3048614, 0.9507061], f32::INFINITY, [0.0; 3], [0.0; 3]),
        (false, [1.571353, -1.185596, 0.6047323], [-0.6372478, 0.768143, 0.06222214], f32::INFINITY, [0.0; 3], [0.0; 3]),
        (true, [2.012136, -1.013203, -0.7783213], [-0.1732519, -0.3521999, 1.056746], 1.977175, [0.2881912, 0.9544764, -0.07694523], [0.2645981, 0.962783, -0.05510634]),
        (true, [2.168351, -0.8121353, 0.2166815], [-0.1022311, -0.4826755, 0.3838501], 1.826163, [0.00297209, 0.9992123, 0.03957108], [0.004641304, 0.9977655, 0.06665299]),
        (true, [2.450067, -2.743159, 1.156332], [-0.3152893, 0.9803856, 0.3369653], 1.003035, [-0.1914874, -0.7658763, -0.6138127], [-0.181342, -0.7132058, -0.6770913]),
        (true, [0.5911692, -2.471381, -0.538865], [0.5929744, 0.4048617, 0.7596035], 1.781806, [-0.3989519, -0.3824621, -0.8334028], [-0.3917074, -0.3806294, -0.8376673]),
        (true, [5.320208, -2.297743, 0.9354835], [-3.081745, 0.6092979, 0.7506359], 0.888985, [0.6171066, -0.4268307, 0.661056], [0.5192549, -0.6497725, 0.5551308]),
        (true, [1.832359, -1.329589, 3.969097], [0.1698814, -0.2008606, -1.367721], 2.119232, [-0.4066155, -0.3836504, 0.8291419], [-0.343323, -0.5908517, 0.7300847]),
        (true, [2.880128, -1.878111, 0.7912862], [-1.941563, 0.1038854, 0.1800917], f32::INFINITY, [0.0; 3], [0.0; 3]),
        (true, [1.710246, -2.725282, 0.6237452], [0.233268, 0.4858059, 0.3087494], f32::INFINITY, [0.0; 3], [0.0; 3]),
    ];

    fn fixture_transform() -> Transform {
        Transform::from_matrix(Mat4::from_translation(Vec3::new(1.0, -2.0, 0.5)) * Mat4::from_scale(Vec3::new(2.0, 0.5, 1.5))).unwrap()
    }

    #[test]
    fn matches_mitsuba_on_its_torus() {
        for normals in [SdfNormals::Smooth, SdfNormals::Analytic] {
            let plain = SdfGrid::from_values(torus(), [40; 3], &Transform::IDENTITY, normals).unwrap();
            let placed = SdfGrid::from_values(torus(), [40; 3], &fixture_transform(), normals).unwrap();
            for (transformed, o, d, t_ref, n_ref, sh_ref) in MITSUBA_TORUS {
                let g = if transformed { &placed } else { &plain };
                let (o, d) = (Vec3::from(o), Vec3::from(d));
                let t = g.intersect(o, d, f32::INFINITY);
                if t_ref.is_infinite() {
                    assert!(t.is_infinite(), "o {o} d {d}: Mitsuba misses, t {t}");
                    continue;
                }
                assert!((t - t_ref).abs() * d.length() < 1e-5, "{normals:?} o {o} d {d}: t {t} vs {t_ref}");
                let (_, n, sh, uv) = g.surface(o + d * t, d);
                let sh_ref = if normals == SdfNormals::Smooth { Vec3::from(sh_ref) } else { Vec3::from(n_ref) };
                assert!((n - Vec3::from(n_ref)).length() < 1e-4, "{normals:?} o {o} d {d}: n {n} vs {n_ref:?}");
                assert!((sh - sh_ref).length() < 1e-4, "{normals:?} o {o} d {d}: shading n {sh} vs {sh_ref}");
                assert_eq!(uv, Vec2::ZERO);
            }
        }
    }

    /// A placed grid: t is the same as for the object-space ray (the map is
    /// affine and t is not renormalised), normals follow the inverse
    /// transpose, and the bounds are the placed cube's.
    #[test]
    fn to_world_places_the_grid() {
        let m = Mat4::from_translation(Vec3::new(1.0, -2.0, 0.5))
            * Mat4::from_axis_angle(Vec3::new(0.3, 1.0, 0.2).normalize(), 0.6)
            * Mat4::from_scale(Vec3::new(2.0, 0.5, 1.5));
        let to_world = Transform::from_matrix(m).unwrap();
        for normals in [SdfNormals::Analytic, SdfNormals::Smooth] {
            let local = sphere_grid(&Transform::IDENTITY, normals);
            let placed = sphere_grid(&to_world, normals);
            let mut rng = Pcg32::new(11, 2);
            let mut hits = 0;
            for _ in 0..500 {
                let o = CENTRE + random_unit(&mut rng) * 1.5;
                let d = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.6 + 0.2 - o).normalize();
                let t = local.intersect(o, d, f32::INFINITY);
                let (wo, wd) = (to_world.point(o), to_world.vector(d));
                let tw = placed.intersect(wo, wd, f32::INFINITY);
                assert_eq!(t.is_finite(), tw.is_finite(), "o {o} d {d}: {t} vs {tw}");
                if t.is_finite() {
                    hits += 1;
                    assert!((t - tw).abs() < 1e-4 * t, "{t} vs {tw}");
                    let (_, n, sh, _) = local.surface(o + d * t, d);
                    let (pw, nw, shw, _) = placed.surface(wo + wd * tw, wd);
                    assert!((pw - to_world.point(o + d * t)).length() < 1e-4);
                    assert!((nw - to_world.normal(n).normalize()).length() < 1e-3, "{nw} vs {n}");
                    assert!((shw - to_world.normal(sh).normalize()).length() < 1e-3, "{shw} vs {sh}");
                    // The world-space tmax cuts in the same place.
                    assert!(placed.intersect(wo, wd, tw * 0.999).is_infinite());
                }
            }
            assert!(hits > 200, "{hits}");
            let (lo, hi) = placed.bounds();
            for i in 0..8 {
                let c = to_world.point(Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, (i >> 2) as f32));
                assert!(c.cmpge(lo - 1e-5).all() && c.cmple(hi + 1e-5).all());
            }
            assert!((hi - lo).min_element() > 0.5);
        }
    }

    /// A ray leaving a hit point (not offset from the surface) must not meet
    /// the surface again at t ≈ 0; into the object it finds the far side.
    #[test]
    fn rays_from_the_surface_do_not_hit_it_again() {
        let g = sphere_grid(&Transform::IDENTITY, SdfNormals::Analytic);
        let torus = SdfGrid::from_values(torus(), [40; 3], &Transform::IDENTITY, SdfNormals::Smooth).unwrap();
        let mut rng = Pcg32::new(3, 9);
        let mut checked = 0;
        for g in [&g, &torus] {
            for _ in 0..2000 {
                let o = CENTRE + random_unit(&mut rng) * 2.0;
                let d = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.6 + 0.2 - o).normalize();
                let t = g.intersect(o, d, f32::INFINITY);
                if !t.is_finite() {
                    continue;
                }
                let p = o + d * t;
                let (_, n, _, _) = g.surface(p, d);
                // Away from the surface (a reflection), and into the object.
                let away = (d - 2.0 * d.dot(n) * n).normalize();
                for dir in [away, d] {
                    let t2 = g.intersect(p, dir, f32::INFINITY);
                    assert!(t2 > 1e-3, "from {p} along {dir}: hit again at {t2}");
                }
                assert!(g.intersect(p, d, f32::INFINITY).is_finite(), "into the object the far side is found");
                checked += 1;
            }
        }
        assert!(checked > 1000, "{checked}");
    }

    /// A surface lying exactly on a grid plane (the samples there are 0) is
    /// found from either side, also by rays along grid lines and planes.
    #[test]
    fn a_surface_on_a_grid_plane_is_not_missed() {
        let values = sampled(5, |p| p.x - 0.5);
        let g = SdfGrid::from_values(values, [5; 3], &Transform::IDENTITY, SdfNormals::Smooth).unwrap();
        let mut rng = Pcg32::new(1, 1);
        for i in 0..2000 {
            let mut o = Vec3::new(-1.0, rng.next_f32(), rng.next_f32());
            if i % 4 == 0 {
                // Exactly on grid lines.
                o.y = (rng.next_u32() % 5) as f32 / 4.0;
                o.z = (rng.next_u32() % 5) as f32 / 4.0;
            }
            let target = Vec3::new(0.5, rng.next_f32(), rng.next_f32());
            let mut d = if i % 2 == 0 { Vec3::X } else { target - o };
            if i % 3 == 0 {
                o.x = 2.0; // from the other side
                d.x = -d.x;
            }
            // The ray reaches the plane within the cube (at the target's y, z).
            let t = g.intersect(o, d, f32::INFINITY);
            let x = o.x + d.x * t;
            assert!((x - 0.5).abs() < 1e-5, "o {o} d {d}: t {t}, x {x}");
            let (_, n, sh, _) = g.surface(o + d * t, d);
            assert!((n - Vec3::X).length() < 1e-5 && (sh - Vec3::X).length() < 1e-5, "{n} {sh}");
        }
        // In the plane itself (f = 0 all along): the start counts as the
        // hit only beyond the self-intersection epsilon, never NaN.
        let t = g.intersect(Vec3::new(0.5, -1.0, 0.5), Vec3::Y, f32::INFINITY);
        assert!(!t.is_nan());
    }

    #[test]
    fn tmax_degenerate_rays_and_no_nan() {
        let g = sphere_grid(&Transform::IDENTITY, SdfNormals::Smooth);
        let (o, d) = (Vec3::new(0.5, 0.5, -1.0), Vec3::Z);
        let t = g.intersect(o, d, f32::INFINITY);
        assert!((t - 1.2).abs() < 1e-3, "{t}");
        assert!(g.intersect(o, d, t * 0.999).is_infinite());
        assert_eq!(g.intersect(o, d, t * 1.001), t);
        assert!((g.intersect(o, d * 4.0, f32::INFINITY) - t / 4.0).abs() < 1e-5, "t in units of d");
        assert!(g.intersect(o, -d, f32::INFINITY).is_infinite(), "behind the origin");
        assert!(g.intersect(o, Vec3::ZERO, f32::INFINITY).is_infinite());
        assert!(g.intersect(Vec3::new(f32::NAN, 0.0, 0.0), d, f32::INFINITY).is_infinite());
        assert!(g.intersect(o, Vec3::new(f32::INFINITY, 0.0, 1.0), f32::INFINITY).is_infinite());
        assert!(g.intersect(o, d, 0.0).is_infinite());
        let (_, n, sh, _) = g.surface(Vec3::new(f32::NAN, 0.0, 0.0), d);
        assert!(n.is_finite() && sh.is_finite());
        let (_, n, sh, _) = g.surface(Vec3::splat(50.0), d); // far outside the grid
        assert!(n.is_finite() && sh.is_finite());
        // Axis-aligned rays through grid vertices (every third grid line).
        for i in (0..32).step_by(3) {
            for j in (0..32).step_by(3) {
                let (a, b) = (i as f32 / 31.0, j as f32 / 31.0);
                for (o, d) in [(Vec3::new(a, b, -1.0), Vec3::Z), (Vec3::new(-1.0, a, b), Vec3::X), (Vec3::new(a, 2.0, b), -Vec3::Y)] {
                    let t = g.intersect(o, d, f32::INFINITY);
                    let exact = exact_sphere(o, d);
                    let closest = Vec2::new(a - 0.5, b - 0.5).length(); // from the sphere's centre line
                    assert!(!t.is_nan());
                    if closest < RADIUS - 0.01 {
                        assert!((t - exact.unwrap()).abs() < 0.02, "{o} {d}: {t} vs {exact:?}");
                        let (_, n, sh, _) = g.surface(o + d * t, d);
                        assert!(n.is_finite() && sh.is_finite() && n.dot(d) < 0.0);
                    }
                }
            }
        }
    }

    #[test]
    fn bad_input_is_an_error_that_says_why() {
        let id = Transform::IDENTITY;
        let ok = sampled(3, |p| p.x - 0.4);
        assert!(SdfGrid::from_values(ok.clone(), [3; 3], &id, SdfNormals::Smooth).is_ok());
        let mut nan = ok.clone();
        nan[5] = f32::NAN;
        let mut inf = ok.clone();
        inf[0] = f32::NEG_INFINITY;
        let singular = Transform { matrix: Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0)), inverse: Mat4::IDENTITY };
        for (values, res, to_world, says) in [
            (nan, [3; 3], id, "finite"),
            (inf, [3; 3], id, "finite"),
            (ok.clone(), [3, 3, 2], id, "values"),
            (ok.clone(), [27, 1, 1], id, "at least 2"),
            (vec![], [0, 0, 0], id, "at least 2"),
            (vec![1.0; 27], [3; 3], id, "change sign"),
            (vec![-1.0; 8], [2; 3], id, "change sign"),
            (ok.clone(), [3; 3], singular, "inverted"),
            (ok.clone(), [usize::MAX, 2, 2], id, "values"),
        ] {
            let e = SdfGrid::from_values(values, res, &to_world, SdfNormals::Analytic).unwrap_err();
            assert!(e.contains(says), "{e}");
        }
        // A corner exactly 0 with the others positive still holds surface (Mitsuba's ≤ / ≥).
        let mut touch = vec![1.0; 8];
        touch[0] = 0.0;
        assert!(SdfGrid::from_values(touch, [2; 3], &id, SdfNormals::Smooth).is_ok());

        let good = vol_bytes([3, 3, 3], 1, &ok);
        assert!(parse_vol(&good).is_ok());
        let mut version = good.clone();
        version[3] = 2;
        let mut encoding = good.clone();
        encoding[4] = 2;
        for (bytes, says) in [
            (good[..40].to_vec(), "48-byte header"),
            (b"VAL\x03".repeat(20), "48-byte header"),
            (version, "version"),
            (encoding, "encoding"),
            (good[..good.len() - 4].to_vec(), "bytes"),
            (vol_bytes([3, 3, 1], 3, &ok), "3 channels"),
            (vol_bytes([0, 3, 3], 1, &[]), "not positive"),
            (vol_bytes([-3, 3, 3], 1, &[]), "not positive"),
            (vol_bytes([i32::MAX, i32::MAX, i32::MAX], 1, &[]), "bytes"),
        ] {
            let e = parse_vol(&bytes).unwrap_err();
            assert!(e.contains(says), "{e}");
        }

        // Through files: the error names the file; a good file loads.
        let dir = std::env::temp_dir().join(format!("snell-sdfgrid-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plane.vol");
        std::fs::write(&path, &good).unwrap();
        let g = SdfGrid::load(&path, &id, SdfNormals::Smooth).unwrap();
        assert_eq!(g.resolution(), [3; 3]);
        assert!((g.intersect(Vec3::new(-1.0, 0.3, 0.6), Vec3::X, f32::INFINITY) - 1.4).abs() < 1e-5);
        std::fs::write(&path, vol_bytes([3, 3, 3], 1, &[2.0; 27])).unwrap();
        let e = SdfGrid::load(&path, &id, SdfNormals::Smooth).unwrap_err();
        assert!(e.contains("plane.vol") && e.contains("change sign"), "{e}");
        let e = SdfGrid::load(&dir.join("missing.vol"), &id, SdfNormals::Smooth).unwrap_err();
        assert!(e.contains("missing.vol"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(SdfNormals::parse("analytic"), Some(SdfNormals::Analytic));
        assert_eq!(SdfNormals::parse("smooth"), Some(SdfNormals::Smooth));
        assert_eq!(SdfNormals::parse("flat"), None);
    }
}

//! Mitsuba's `mesh_attribute` texture: a per-vertex or per-face attribute
//! of the mesh that was hit (e.g. the colours of a PLY file), vertex values
//! interpolated with the hit's barycentrics, face values constant.
//!
//! | parameter | type   | default  | meaning                                                   |
//! |-----------|--------|----------|-----------------------------------------------------------|
//! | `name`    | string | required | `vertex_…` or `face_…`: the attribute (`vertex_color`, `face_weight`) |
//! | `scale`   | float  | 1        | factor applied to the values                              |
//!
//! ```xml
//! <bsdf type="diffuse">
//!     <texture type="mesh_attribute" name="reflectance">
//!         <string name="name" value="vertex_color"/>
//!     </texture>
//! </bsdf>
//! ```
//!
//! A one-component attribute is grey; a three-component one a linear RGB
//! colour. A PLY file's `r g b` (or `red green blue`) vertex properties
//! are `vertex_color`, properties `name_0, name_1, …` are `vertex_name` (or
//! `face_name` on faces). On a shape without the attribute the texture is
//! black.

use super::TexPoint;
use crate::geometry::mesh_io::Attribute;
use crate::spectrum::Rgb;
use std::sync::{Arc, OnceLock};

#[derive(Debug)]
pub struct MeshAttributeTexture {
    pub name: String,
    pub scale: f32,
    /// Per shape index: the attribute (vertex ones stored per triangle
    /// corner), set once every shape is loaded.
    pub table: OnceLock<Vec<Option<Arc<Attribute>>>>,
}

impl MeshAttributeTexture {
    #[inline]
    pub fn eval(&self, p: &TexPoint) -> Rgb {
        let Some(Some(a)) = self.table.get().and_then(|t| t.get(p.shape as usize)) else {
            return Rgb::BLACK;
        };
        let d = a.dims;
        let fetch = |i: usize| -> Rgb {
            match a.data.get(i * d..(i + 1) * d) {
                Some([v]) => Rgb::new(*v, *v, *v),
                Some([r, g, b, ..]) => Rgb::new(*r, *g, *b),
                _ => Rgb::BLACK,
            }
        };
        let i = p.prim as usize;
        let v = if a.per_face {
            fetch(i)
        } else {
            let (b1, b2) = (p.bary.x, p.bary.y);
            fetch(3 * i) * (1.0 - b1 - b2) + fetch(3 * i + 1) * b1 + fetch(3 * i + 2) * b2
        };
        v * self.scale
    }

    /// Mean and largest value over every shape's attribute.
    pub fn stats(&self) -> (f32, f32) {
        let (mut sum, mut n, mut max) = (0.0f64, 0usize, 0.0f32);
        for a in self.table.get().into_iter().flatten().flatten() {
            let d = a.dims.min(3);
            for chunk in a.data.chunks_exact(a.dims) {
                for &v in &chunk[..d] {
                    sum += v as f64;
                    n += 1;
                    max = max.max(v);
                }
            }
        }
        (if n > 0 { (sum / n as f64) as f32 * self.scale } else { 0.0 }, max * self.scale)
    }
}

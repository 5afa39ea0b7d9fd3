//! `bumpmap` — perturbs the shading frame of a nested BSDF by a height field.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | (nested) | texture | — (required) | the height field h(u, v) (any name; a colour texture counts by its luminance; give a bitmap `raw="true"` to use its 8-bit values as they are) |
//! | `scale` | float | 1 | multiplier on the height's gradient |
//! | (nested) | bsdf | — | the BSDF seen in the perturbed frame (exactly one) |
//! | `flip_invalid_normals` | boolean | true | as for `normalmap` |
//! | `use_shadowing_function` | boolean | true | as for `normalmap` |
//!
//! As in Mitsuba 3.9: the gradient (∂h/∂u, ∂h/∂v) · `scale` of the texture
//! (for a bilinear bitmap, that of its bilinear interpolation; zero for
//! piecewise-constant textures) displaces the surface along its shading
//! normal n, ignoring the change of n itself:
//! ∂p'/∂u = ∂p/∂u + n (∂h/∂u − n·∂p/∂u), the same for v, and the
//! perturbed normal is ∂p'/∂u × ∂p'/∂v, turned to the side of the geometric
//! normal. ∂p/∂u, ∂p/∂v are those of Mitsuba's parametrisation of the shape
//! (their length matters: a sphere's ∂p/∂u is 2πr long at the equator). The
//! nested BSDF is then used in that frame with the rules of `normalmap`
//! (mirrored normals, side rule, shadowing term), as Mitsuba 3.9.1's
//! shared `PerturbedBSDF` does. Only height variations matter; a constant
//! offset does not.
//!
//! ```xml
//! <bsdf type="bumpmap">
//!     <texture name="arbitrary" type="bitmap">
//!         <boolean name="raw" value="true"/>
//!         <string name="filename" value="textures/bumpmap.jpg"/>
//!     </texture>
//!     <float name="scale" value="0.5"/>
//!     <bsdf type="diffuse"/>
//! </bsdf>
//! ```

use super::normalmap::{PerturbOptions, perturbed_bsdf_model, single_nested};
use super::Bsdf;
use crate::geometry::SurfaceInteraction;
use crate::scene::error::{Result, SceneError};
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::texture::Texture;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct BumpMap {
    pub height: Texture,
    pub scale: f32,
    pub nested: Box<Bsdf>,
    pub options: PerturbOptions,
}

impl BumpMap {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<BumpMap> {
        let scale = props.float_checked("scale", 1.0, f32::is_finite, "a finite number")?;
        let mut textures = loader.nested_textures(props)?;
        if textures.len() != 1 {
            let loc = textures.get(1).map_or(&props.node.loc, |(n, _)| &n.loc);
            return Err(SceneError::at(loc, format!("bumpmap takes exactly one nested height texture, found {}", textures.len())));
        }
        let height = textures.remove(0).1;
        let nested = single_nested(props, loader, "bumpmap")?;
        Ok(BumpMap { height, scale, nested: Box::new(nested), options: PerturbOptions::from_props(props)? })
    }

    /// The perturbed normal (unnormalised), in `si`'s shading frame.
    fn perturbation(&self, si: &SurfaceInteraction) -> Vec3 {
        let g = self.height.eval_1_grad(si.uv) * self.scale;
        let n = si.frame.n;
        let dp_du = si.dp_du + n * (g.x - n.dot(si.dp_du));
        let dp_dv = si.dp_dv + n * (g.y - n.dot(si.dp_dv));
        let mut cr = dp_du.cross(dp_dv);
        if si.n.dot(cr) < 0.0 {
            cr = -cr;
        }
        if cr.is_finite() { si.to_local(cr) } else { Vec3::Z }
    }
}

perturbed_bsdf_model!(BumpMap);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{BsdfContext, Diffuse};
    use crate::bsdf::testing::*;
    use crate::spectrum::Rgb;
    use crate::texture::bitmap::{Bitmap, Filter, Wrap};
    use std::f32::consts::PI;
    use std::sync::Arc;

    #[test]
    fn a_linear_ramp_tilts_the_normal_by_its_slope() {
        // Height c·i at texel i (8 texels across): ∂h/∂u = 8c between texel
        // centres. On a plane with ∂p/∂u = (2,0,0), ∂p/∂v = (0,2,0) the bumped
        // normal is (2,0,s∂h/∂u) × (0,2,0) ∝ (-s∂h/∂u / 2, 0, 1).
        let c = 0.05;
        let texels = (0..4).flat_map(|_| (0..8).map(|i| Rgb::new(c * i as f32, c * i as f32, c * i as f32))).collect();
        let height = Texture::Bitmap(Arc::new(Bitmap { width: 8, height: 4, texels, filter: Filter::Bilinear, wrap: Wrap::Clamp, to_uv: glam::Affine2::IDENTITY }));
        let scale = 1.5;
        let b = Bsdf::BumpMap(BumpMap {
            height,
            scale,
            nested: Box::new(Bsdf::Diffuse(Diffuse { reflectance: Texture::constant(Rgb::new(0.5, 0.5, 0.5)) })),
            options: PerturbOptions { flip_invalid_normals: true, use_shadowing_function: false },
        });
        let wi = incident(0.1, 0.0);
        let si = SurfaceInteraction { wi, uv: glam::Vec2::new(0.47, 0.5), dp_du: Vec3::new(2.0, 0.0, 0.0), dp_dv: Vec3::new(0.0, 2.0, 0.0), ..dummy_interaction() };
        let n = Vec3::new(-scale * 8.0 * c / 2.0, 0.0, 1.0).normalize();
        for wo in [Vec3::Z, incident(0.6, 0.0), incident(0.6, PI), incident(1.2, 1.0)] {
            let f: Rgb = b.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
            assert!((f[0] - 0.5 / PI * n.dot(wo).max(0.0)).abs() < 1e-5, "wo {wo}: {} vs {}", f[0], 0.5 / PI * n.dot(wo));
        }
        // A constant offset changes nothing: no gradient, no tilt.
        let flat = Bsdf::BumpMap(BumpMap { height: Texture::constant(Rgb::new(0.7, 0.7, 0.7)), ..match &b { Bsdf::BumpMap(m) => m.clone(), _ => unreachable!() } });
        let f: Rgb = flat.eval(&BsdfContext::RADIANCE, &si, wi, incident(0.6, 0.0), &());
        assert!((f[0] - 0.5 / PI * incident(0.6, 0.0).z).abs() < 1e-6);
        check_sample_consistency(&b, wi, 3);
    }
}

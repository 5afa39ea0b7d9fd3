//! `thindielectric` — a thin slab of dielectric (a window pane, a soap film
//! without interference) seen as one surface: both of its parallel
//! interfaces, with every internal bounce summed, and no refraction offset.
//!
//! A ray meeting the slab at cos θ is reflected at the first interface with
//! the exact Fresnel reflectance R and transmitted with T = 1 − R; inside,
//! light bounces between the two interfaces (each reflecting R), so the
//! slab reflects R + T²R + T²R³ + … = R + T²R / (1 − R²) in total and
//! transmits the rest. Transmitted light leaves parallel to the incident
//! ray (the two refractions undo each other) and, since it enters and
//! leaves the same medium, unscaled. Both sides behave alike. Both lobes
//! are deltas.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `int_ior` | float / string | `bk7` | index of the slab, or a name |
//! | `ext_ior` | float / string | `air` | index around it, or a name |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale of reflection |
//! | `specular_transmittance` | rgb / spectrum / float / texture | 1 | scale of transmission |
//!
//! ```xml
//! <bsdf type="thindielectric"><string name="int_ior" value="bk7"/></bsdf>
//! ```

use super::fresnel::{fresnel_dielectric, reflect};
use super::{BsdfSample, Lobe};
use crate::geometry::SurfaceInteraction;
use crate::spectrum::Spectrum;
use crate::texture::Texture;
use glam::Vec3;

#[derive(Clone, Debug)]
pub struct ThinDielectric {
    pub eta: f32,
    pub specular_reflectance: Texture,
    pub specular_transmittance: Texture,
}

impl ThinDielectric {
    /// Total reflectance of the slab, all internal bounces included.
    pub fn slab_reflectance(&self, cos_i: f32) -> f32 {
        let r = fresnel_dielectric(cos_i.abs(), self.eta).r;
        if r >= 1.0 {
            return 1.0;
        }
        let t = 1.0 - r;
        r + t * t * r / (1.0 - r * r)
    }

    #[inline]
    pub fn sample<S: Spectrum>(&self, si: &SurfaceInteraction, wi: Vec3, u: f32, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        let r = self.slab_reflectance(wi.z);
        if u < r {
            Some(BsdfSample {
                wo: reflect(wi),
                weight: self.specular_reflectance.eval_spectrum::<S>(si.uv, wl),
                pdf: r,
                eta: 1.0,
                lobe: Lobe::DELTA_REFLECTION,
            })
        } else {
            Some(BsdfSample {
                wo: -wi,
                weight: self.specular_transmittance.eval_spectrum::<S>(si.uv, wl),
                pdf: 1.0 - r,
                eta: 1.0,
                lobe: Lobe::DELTA_TRANSMISSION,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectrum::Rgb;

    #[test]
    fn slab_reflectance_sums_the_internal_bounces() {
        let pane = ThinDielectric {
            eta: 1.5,
            specular_reflectance: Texture::constant(Rgb::WHITE),
            specular_transmittance: Texture::constant(Rgb::WHITE),
        };
        for cos in [1.0f32, 0.8, 0.3, 0.05] {
            let r = fresnel_dielectric(cos, 1.5).r as f64;
            // Sum the geometric series bounce by bounce.
            let (mut total, mut inside) = (r, (1.0 - r) * (1.0 - r) * r);
            for _ in 0..200 {
                total += inside;
                inside *= r * r;
            }
            assert!((pane.slab_reflectance(cos) as f64 - total).abs() < 1e-6);
            // Both sides are the same, and the slab reflects more than one interface.
            assert_eq!(pane.slab_reflectance(cos), pane.slab_reflectance(-cos));
            assert!(pane.slab_reflectance(cos) as f64 >= r);
        }
        // A 1.5 pane at normal incidence: 2R/(1+R) with R = 0.04 → 0.0769.
        assert!((pane.slab_reflectance(1.0) - 0.08 / 1.04).abs() < 1e-6);
    }
}

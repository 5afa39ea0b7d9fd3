//! Path guiding for `path`: Practical Path Guiding (Müller, Gross, Novák
//! 2017, "Practical Path Guiding for Efficient Light-Transport
//! Simulation").
//!
//! Why this method: it learns the incident radiance (direct and indirect,
//! caustics included) as a piecewise-constant density per region of space,
//! with no parameters to tune per scene, a closed-form pdf (needed for MIS
//! with next-event estimation) and a cheap sample; the error measured on
//! the Cornell box lies in indirect light (96 %) and on the caustic box in
//! light through glass and off metal onto diffuse surfaces (64 %), both of
//! which a learned incident-radiance distribution targets and BSDF
//! sampling does not. A von Mises–Fisher mixture (Vorba et al.) fits fewer,
//! smoother lobes and needs an EM fit per region; the SD-tree is simpler to
//! build deterministically.
//!
//! - [`sdtree`]: the spatial binary tree over the scene's bounding box;
//! - [`quadtree`]: the directional quadtrees in each of its leaves;
//! - [`trace`]: the guided path tracer (one-sample MIS of BSDF and guide,
//!   next-event estimation weighed against the combined density), which
//!   also gathers the training records;
//! - [`train`]: the training pre-phase.
//!
//! **Training** runs before the render, in iterations of 1, 2, 4, … samples
//! per pixel (the last one taking what is left of `guiding_spp`), each
//! sampling with the guide fitted to the previous iteration's records
//! (the first with the BSDF alone); the render uses the guide fitted to the
//! last iteration. Training paths draw from their own sampler (`independent`
//! with a seed derived from the scene's), so they never share a sample with
//! the image. Records are gathered per image row in parallel and
//! concatenated in row order before the trees are fitted: the guide is a
//! pure function of the scene, whatever the thread count. The guide is then
//! frozen and kept with the integrator (one per spectral mode): every pass
//! of a progressive render and every sample range uses the same guide, so
//! the image stays a pure function of (scene, seed, pixel, sample index),
//! bit-identical for any thread count and pass split. A resumed render (or
//! a tile of a distributed one) retrains in its own process and obtains the
//! same guide. The training time is part of the render time.
//!
//! Guiding applies to the top-level `path` integrator in the RGB and
//! spectral modes (in the polarized modes, and nested in `aov`/`moment`,
//! `path` renders unguided); with guiding on, `path` does not use the
//! batched (wavefront) tracer nor first-vertex splitting.
//!
//! **Measured** (`tools/bench.py --efficiency --cpu-time --runs 3 --ref-spp
//! 4096`, 64 spp, `zsobol`, max_depth 8, 2 threads on a loaded machine;
//! relMSE / CPU seconds per thread / efficiency 1/(relMSE·s)):
//!
//! | scene | res | unguided | guiding (16 training spp) | guiding_spp 64 |
//! |---|---|---|---|---|
//! | Cornell box | 128² | 8.12e-4 / 0.655 / 1881 | 9.20e-4 / 1.485 / 732 | 8.29e-4 / 2.615 / 461 |
//! | Cornell box | 64² | 8.58e-4 / 0.165 / 7064 | 1.20e-3 / 0.340 / 2459 | 9.90e-4 / 0.585 / 1726 |
//! | caustic box | 128² | 9.89e-3 / 0.630 / 161 | 1.50e-2 / 1.480 / 45 | 1.40e-2 / 2.470 / 29 |
//! | caustic box | 64² | 1.05e-2 / 0.160 / 597 | 1.28e-2 / 0.340 / 230 | 1.24e-2 / 0.565 / 143 |
//!
//! At these sizes and budgets the guide does not pay: the error per sample
//! is not lower than BSDF sampling's (at best −11 % on the Cornell box with
//! 64 training spp) and a guided sample costs about twice as much (no
//! batched tracer, one more BSDF evaluation and a tree lookup per bounce,
//! plus training). Hence `guiding` is off by default.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `guiding` | boolean | false | learn and sample the incident radiance |
//! | `guiding_spp` | integer | 16 | training samples per pixel (1–4096), spent before the render |
//! | `bsdf_sampling_fraction` | float | 0.5 | probability α of sampling the BSDF at a guided vertex, in (0, 1] |
//!
//! ```xml
//! <integrator type="path">
//!     <integer name="max_depth" value="8"/>
//!     <boolean name="guiding" value="true"/>
//!     <integer name="guiding_spp" value="16"/>
//!     <float name="bsdf_sampling_fraction" value="0.5"/>
//! </integrator>
//! ```

pub mod quadtree;
pub mod sdtree;
pub mod trace;
pub mod train;

use sdtree::SdTree;
use std::sync::{Arc, OnceLock};

/// Guiding parameters of a `path` integrator, and its trained guides.
#[derive(Clone)]
pub struct Guiding {
    pub guiding_spp: u32,
    pub bsdf_sampling_fraction: f32,
    /// The frozen guides: [RGB, spectral]. Shared by clones of the
    /// integrator; not part of its identity (`Debug` leaves it out, so the
    /// scene fingerprint does not change after training).
    pub trained: Arc<[OnceLock<Arc<SdTree>>; 2]>,
}

impl std::fmt::Debug for Guiding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Guiding").field("guiding_spp", &self.guiding_spp).field("bsdf_sampling_fraction", &self.bsdf_sampling_fraction).finish()
    }
}

impl Guiding {
    pub fn new(guiding_spp: u32, bsdf_sampling_fraction: f32) -> Guiding {
        Guiding { guiding_spp, bsdf_sampling_fraction, trained: Arc::new([OnceLock::new(), OnceLock::new()]) }
    }

    /// Which slot of [`Guiding::trained`] the spectrum type uses; None for
    /// the polarized modes (not guided).
    #[inline]
    pub fn slot<S: crate::spectrum::Spectrum>() -> Option<usize> {
        if S::POLARIZED { None } else { Some(S::SPECTRAL as usize) }
    }

    /// The trained guide for the spectrum type, if training has run.
    #[inline]
    pub fn guide<S: crate::spectrum::Spectrum>(&self) -> Option<&SdTree> {
        Self::slot::<S>().and_then(|i| self.trained[i].get()).map(|g| &**g)
    }
}

impl crate::integrator::PathTracer {
    /// Whether this path tracer guides (its guide is trained before a render).
    #[inline]
    pub fn guides(&self) -> bool {
        self.guiding.is_some()
    }

    /// Radiance along `ray` by whichever estimator the parameters select:
    /// guided (once trained, in the RGB and spectral modes), split at the
    /// first vertex, or plain.
    #[inline]
    pub fn li_any<S: crate::spectrum::Spectrum>(
        &self,
        scene: &crate::scene::Scene,
        ray: crate::geometry::Ray,
        sampler: &mut crate::sampler::Sampler,
        wl: &mut S::Wavelengths,
    ) -> S {
        if let Some(g) = &self.guiding {
            if let Some(tree) = g.guide::<S>() {
                return trace::li::<S>(self, g, Some(tree), scene, ray, sampler, wl, None);
            }
        }
        if self.splits() { self.li_split(scene, ray, sampler, wl) } else { self.li(scene, ray, sampler, wl) }
    }
}

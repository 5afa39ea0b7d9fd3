//! Snell: a physically based renderer for Mitsuba 3 XML scenes.
//!
//! The crate is laid out as the renderer is: [`scene`] loading, [`geometry`]
//! (shapes, rays, the BVH), [`bsdf`] materials and their [`texture`]s,
//! [`emitter`]s, [`sensor`]s (cameras), the [`sampler`], [`integrator`]s,
//! the [`film`] and the [`render`] driver; [`spectrum`] defines what a path
//! carries and [`math`] the shared numerics.

pub mod bsdf;
pub mod cli;
pub mod emitter;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod limits;
pub mod math;
pub mod medium;
pub mod preview;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod sensor;
pub mod session;
pub mod spectrum;
pub mod texture;

pub use film::FilmState;
pub use render::{PassReport, RenderOptions, RenderStats, render, render_samples};
pub use session::Mode;
pub use scene::{LoadOptions, Scene, SceneError, load_file, load_str};

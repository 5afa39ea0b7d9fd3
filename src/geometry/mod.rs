//! Geometry: rays, shapes (triangle meshes, spheres, disks, cylinders, curves, SDF grids), surface
//! interactions and the acceleration structure over all of them.

pub mod accel;
pub mod curve;
pub mod cylinder;
pub mod disk;
pub mod interaction;
pub mod mesh;
pub mod mesh_io;
pub mod ray;
pub mod sdfgrid;
pub mod serialized;
pub mod shape;
pub mod sphere;

pub use interaction::SurfaceInteraction;
pub use ray::Ray;
pub use shape::{Shape, ShapeGeometry};

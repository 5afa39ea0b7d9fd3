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

/// Asks the memory system for the cache line holding `value`, to be read
/// soon; the caller goes on without waiting. A no-op off x86-64.
#[inline(always)]
pub(crate) fn prefetch<T>(value: Option<&T>) {
    #[cfg(target_arch = "x86_64")]
    if let Some(value) = value {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: a prefetch never faults, and this address is a live value's.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(value as *const T as *const i8) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

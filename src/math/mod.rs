//! Small numeric building blocks shared by every part of the renderer: the
//! local shading frame, sample warps, the random number generator and affine
//! transforms.

pub mod frame;
pub mod rng;
pub mod rounding;
pub mod sampling;
pub mod transform;
pub mod trig;

pub use frame::Frame;
pub use rng::Pcg32;
pub use transform::Transform;

pub const PI: f32 = std::f32::consts::PI;
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
pub const INV_TWO_PI: f32 = 0.5 * std::f32::consts::FRAC_1_PI;
pub const INV_FOUR_PI: f32 = 0.25 * std::f32::consts::FRAC_1_PI;

/// Relative offset used when spawning rays off a surface (Mitsuba uses
/// 1500 ulp of 1.0 in single precision).
pub const RAY_EPSILON: f32 = 1500.0 * f32::EPSILON * 0.5;
/// Shadow rays stop this fraction short of their target.
pub const SHADOW_EPSILON: f32 = RAY_EPSILON * 10.0;

/// Power heuristic (β = 2) for multiple importance sampling.
#[inline]
pub fn mis_power(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b > 0.0 && a.is_finite() { a / (a + b) } else if a.is_infinite() { 1.0 } else { 0.0 }
}

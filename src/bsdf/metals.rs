//! PLACEHOLDER until tools/derive_metal_rgb.py generates this file.
pub struct Metal {
    pub name: &'static str,
    pub eta: [f32; 3],
    pub k: [f32; 3],
}
pub const METALS: &[Metal] = &[Metal { name: "Au", eta: [0.143, 0.374, 1.442], k: [3.983, 2.385, 1.603] }];

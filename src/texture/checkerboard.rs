//! `checkerboard` — a two-colour checkerboard in uv space.
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `color0` | rgb / spectrum / float | 0.4 | colour of the squares where ⌊2u⌋ and ⌊2v⌋ agree |
//! | `color1` | rgb / spectrum / float | 0.2 | the other squares |
//! | `to_uv` | transform | identity | uv transform |
//!
//! ```xml
//! <texture type="checkerboard" name="reflectance">
//!     <rgb name="color0" value="0.8"/>  <rgb name="color1" value="0.1"/>
//!     <transform name="to_uv"><scale x="8" y="8"/></transform>
//! </texture>
//! ```

use crate::spectrum::Rgb;
use glam::{Affine2, Vec2};

#[derive(Clone, Debug)]
pub struct Checkerboard {
    pub color0: Rgb,
    pub color1: Rgb,
    pub to_uv: Affine2,
}

impl Checkerboard {
    #[inline]
    pub fn eval(&self, uv: Vec2) -> Rgb {
        let uv = self.to_uv.transform_point2(uv);
        let f = uv - uv.floor();
        let (mx, my) = (f.x > 0.5, f.y > 0.5);
        if mx == my { self.color0 } else { self.color1 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadrants() {
        let c = Checkerboard { color0: Rgb::WHITE, color1: Rgb::BLACK, to_uv: Affine2::IDENTITY };
        assert_eq!(c.eval(Vec2::new(0.25, 0.25)), Rgb::WHITE);
        assert_eq!(c.eval(Vec2::new(0.75, 0.25)), Rgb::BLACK);
        assert_eq!(c.eval(Vec2::new(0.75, 0.75)), Rgb::WHITE);
        assert_eq!(c.eval(Vec2::new(1.25, 0.75)), Rgb::BLACK);
    }
}

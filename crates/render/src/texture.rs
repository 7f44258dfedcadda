//! Bilinear texture lookup with wrap modes.

use glam::{Vec2, Vec4};
use lucent_scene::{Texture, Wrap};

fn wrap(i: i64, n: u32, w: Wrap) -> usize {
    let n = n as i64;
    (match w {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            if m < n {
                m
            } else {
                2 * n - 1 - m
            }
        }
    }) as usize
}

/// Bilinearly filtered RGBA at `uv` (v = 0 at the bottom of the image).
#[must_use]
pub fn sample(t: &Texture, uv: Vec2) -> Vec4 {
    if t.width == 0 || t.height == 0 || !uv.is_finite() {
        return Vec4::ONE;
    }
    let x = uv.x * t.width as f32 - 0.5;
    let y = (1.0 - uv.y) * t.height as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let texel = |xi: i64, yi: i64| {
        let c = t.texels[wrap(yi, t.height, t.wrap_v) * t.width as usize + wrap(xi, t.width, t.wrap_u)];
        Vec4::from(c)
    };
    let (xi, yi) = (x0 as i64, y0 as i64);
    let top = texel(xi, yi).lerp(texel(xi + 1, yi), fx);
    let bottom = texel(xi, yi + 1).lerp(texel(xi + 1, yi + 1), fx);
    top.lerp(bottom, fy)
}

//! Texture lookup (bilinear, or the nearest texel) with wrap modes.

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

/// The two texel indices a bilinear lookup blends along one axis, wrapped.
///
/// PERF: the common case, both inside the image, takes no division (`rem_euclid` on i64,
/// eight per lookup, made texturing a fifth of a BART kitchen frame).
#[inline(always)]
fn pair(i: i64, n: u32, w: Wrap) -> (usize, usize) {
    if i >= 0 && i + 1 < i64::from(n) {
        (i as usize, i as usize + 1)
    } else {
        (wrap(i, n, w), wrap(i + 1, n, w))
    }
}

/// Where `uv` falls among the texels: the upper-left texel of the bilinear footprint
/// (unwrapped, row 0 at the top) and the blend weights toward its right and lower
/// neighbours. `None` for an empty texture or a non-finite `uv` (the lookup is white).
fn footprint(t: &Texture, uv: Vec2) -> Option<(i64, i64, f32, f32)> {
    if t.width == 0 || t.height == 0 || !uv.is_finite() {
        return None;
    }
    let x = uv.x * t.width as f32 - 0.5;
    let y = (1.0 - uv.y) * t.height as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    Some((x0 as i64, y0 as i64, x - x0, y - y0))
}

/// The texel `uv` falls in (nearest lookups), wrapped; `None` as [`footprint`].
fn nearest(t: &Texture, uv: Vec2) -> Option<Vec4> {
    if t.width == 0 || t.height == 0 || !uv.is_finite() {
        return None;
    }
    let x = (uv.x * t.width as f32).floor() as i64;
    let y = ((1.0 - uv.y) * t.height as f32).floor() as i64;
    Some(t.texel_at(wrap(x, t.width, t.wrap_u), wrap(y, t.height, t.wrap_v)))
}

/// Bilinearly filtered RGBA at `uv` (v = 0 at the bottom of the image), or the nearest
/// texel's for a texture of nearest lookups.
#[must_use]
pub fn sample(t: &Texture, uv: Vec2) -> Vec4 {
    if t.nearest {
        return nearest(t, uv).unwrap_or(Vec4::ONE);
    }
    let Some((x0, y0, fx, fy)) = footprint(t, uv) else { return Vec4::ONE };
    let (xa, xb) = pair(x0, t.width, t.wrap_u);
    let (ya, yb) = pair(y0, t.height, t.wrap_v);
    let texel = |xi: usize, yi: usize| t.texel_at(xi, yi);
    let top = texel(xa, ya).lerp(texel(xb, ya), fx);
    let bottom = texel(xa, yb).lerp(texel(xb, yb), fx);
    top.lerp(bottom, fy)
}

/// The gradient (∂/∂u, ∂/∂v) of a bilinear lookup's luminance at `uv` (Mitsuba's
/// `eval_1_grad` of a bitmap: zero for nearest lookups, and within a texel cell the
/// bilinear patch's slope). Zero for an empty texture or a non-finite `uv`.
#[must_use]
pub fn sample_gradient(t: &Texture, uv: Vec2) -> Vec2 {
    if t.nearest {
        return Vec2::ZERO;
    }
    let Some((x0, y0, fx, fy)) = footprint(t, uv) else { return Vec2::ZERO };
    let (xa, xb) = pair(x0, t.width, t.wrap_u);
    let (ya, yb) = pair(y0, t.height, t.wrap_v);
    let lum = |xi: usize, yi: usize| {
        let c = t.texel_at(xi, yi);
        0.212_671 * c.x + 0.715_160 * c.y + 0.072_169 * c.z
    };
    let (f00, f10, f01, f11) = (lum(xa, ya), lum(xb, ya), lum(xa, yb), lum(xb, yb));
    let dx = (1.0 - fy) * (f10 - f00) + fy * (f11 - f01);
    let dy = (1.0 - fx) * (f01 - f00) + fx * (f11 - f10);
    // (Rows run down the image as v falls.)
    Vec2::new(dx * t.width as f32, -dy * t.height as f32)
}

/// The plain form of [`sample`] (every texel wrapped on its own): the reference it is
/// tested against.
#[must_use]
pub fn sample_reference(t: &Texture, uv: Vec2) -> Vec4 {
    if t.nearest {
        return nearest(t, uv).unwrap_or(Vec4::ONE);
    }
    let Some((xi, yi, fx, fy)) = footprint(t, uv) else { return Vec4::ONE };
    let texel = |xi: i64, yi: i64| t.texel_at(wrap(xi, t.width, t.wrap_u), wrap(yi, t.height, t.wrap_v));
    let top = texel(xi, yi).lerp(texel(xi + 1, yi), fx);
    let bottom = texel(xi, yi + 1).lerp(texel(xi + 1, yi + 1), fx);
    top.lerp(bottom, fy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texels_read_back_where_the_image_put_them() {
        // Sizes that do and do not fill whole 4×4 blocks.
        for (w, h) in [(1u32, 1u32), (4, 4), (5, 3), (9, 6), (17, 33)] {
            let texels: Vec<[u8; 4]> =
                (0..w * h).map(|i| [(i % 251) as u8, (i / 251) as u8, (i * 7 % 256) as u8, (255 - i % 200) as u8]).collect();
            let t = Texture::new(String::new(), w, h, texels.clone(), false, Wrap::Repeat, Wrap::Repeat);
            for y in 0..h as usize {
                for x in 0..w as usize {
                    let c = texels[y * w as usize + x];
                    let want = Vec4::new(f32::from(c[0]), f32::from(c[1]), f32::from(c[2]), f32::from(c[3])) / 255.0;
                    assert_eq!(t.texel_at(x, y), want, "{w}x{h} at ({x}, {y})");
                }
            }
            assert_eq!(t.texel_at(w as usize, 0), Vec4::ONE);
            assert_eq!(t.texel_at(0, h as usize), Vec4::ONE);
        }
    }

    #[test]
    fn sample_matches_the_reference_in_every_wrap_mode() {
        let mut h = 12345u32;
        let mut rnd = || {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            h as f32 / u32::MAX as f32
        };
        for (wu, wv) in [(Wrap::Repeat, Wrap::Repeat), (Wrap::Clamp, Wrap::Mirror), (Wrap::Mirror, Wrap::Clamp)] {
            for (width, height) in [(1u32, 1u32), (2, 3), (7, 5), (64, 33)] {
                let texels = (0..width * height).map(|i| [i as u8, (i * 7 % 11) as u8, (rnd() * 255.0) as u8, 200]).collect();
                let t = Texture::new(String::new(), width, height, texels, true, wu, wv);
                for _ in 0..2000 {
                    // Inside, near the edges, and far outside the unit square.
                    let uv = Vec2::new(rnd() * 6.0 - 3.0, rnd() * 6.0 - 3.0) * if rnd() < 0.2 { 1000.0 } else { 1.0 };
                    assert_eq!(sample(&t, uv), sample_reference(&t, uv), "{wu:?}/{wv:?} {width}x{height} at {uv}");
                }
            }
        }
    }
}

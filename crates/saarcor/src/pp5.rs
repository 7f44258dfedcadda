//! Pixel-Planes 5's ray tracer's arithmetic ("Real Time Ray Tracer", UNC, 1994): every
//! pixel's processor traces its ray through a few spheres in integers, the ray, the
//! model and most intermediate values in 12 or 24 bits, screen-sized coordinates (a
//! 1280x1024 display), the quadratic's discriminant needing far more (the paper: "on the
//! order of 2^36"), and 6 fraction bits on the ray parameter t, added after reflections
//! off normals "kept as the length of the sphere's radius" (about 200) truncated t to 0,
//! 1 or 2 on spheres some 400 units away. Quarter resolution (640x512) while moving.
//!
//! [`study`] traces a sphere scene in that arithmetic, with and without t's fraction
//! bits, at both resolutions, against the same algorithm in f64: which sphere each
//! primary and each reflected ray hits, and the shaded images' PSNR.

/// A sphere in screen units: centre and radius (12-bit integers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sphere {
    /// Centre (x right, y down, z into the screen).
    pub c: [i64; 3],
    /// Radius.
    pub r: i64,
}

/// The study's scene, in the 1280x1024 display's units: eight spheres in a ring over a
/// large one, all within 12-bit coordinates (-2048..2047).
#[must_use]
pub fn scene() -> Vec<Sphere> {
    let mut s = vec![Sphere { c: [640, 1750, 600], r: 1100 }];
    for k in 0..8i64 {
        let a = k as f64 * std::f64::consts::TAU / 8.0;
        let r = 110 + 30 * (k % 3);
        s.push(Sphere { c: [640 + (520.0 * a.cos()) as i64, 640 - r, 500 + (300.0 * a.sin()) as i64], r });
    }
    s.push(Sphere { c: [640, 430, 500], r: 190 });
    s
}

/// The eye, in display units (perspective: the ray's tail is the eye, its direction
/// varies by pixel).
const EYE: [i64; 3] = [640, 512, -1024];
/// The light's direction (towards the light), length 256.
const LIGHT: [i64; 3] = [-128, -192, -110];

/// How the tracer computes: PP5's integers with `t_bits` fraction bits on t, or f64.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arith {
    /// Integers, t with this many fraction bits.
    Int {
        /// Fraction bits of t (the paper: 6).
        t_bits: u32,
    },
    /// The same algorithm in f64 (the reference).
    Float,
}

/// One pixel's answers: the sphere its ray hits and the sphere its reflection hits
/// (`u8::MAX`: none), its grey value 0..1.
type Pixel = (u8, u8, f32);

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Bits of a signed magnitude.
fn bits(x: i128) -> u32 {
    128 - x.unsigned_abs().leading_zeros()
}

/// The nearest sphere along `o + t d` (t > 0, skipping `skip`): (sphere, t). In
/// integers, t comes back scaled by 2^t_bits; the largest discriminant's bits go to
/// `disc_bits`.
fn nearest(spheres: &[Sphere], o: [f64; 3], d: [f64; 3], skip: usize, ar: Arith, disc_bits: &mut u32) -> Option<(usize, f64)> {
    let mut best: Option<(usize, f64)> = None;
    for (i, s) in spheres.iter().enumerate().filter(|(i, _)| *i != skip) {
        let c = s.c.map(|x| x as f64);
        let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
        let t = match ar {
            Arith::Float => {
                let (a, b, cc) = (dot(d, d), dot(d, oc), dot(oc, oc) - (s.r * s.r) as f64);
                let disc = b * b - a * cc;
                if disc < 0.0 {
                    continue;
                }
                (-b - disc.sqrt()) / a
            }
            Arith::Int { t_bits } => {
                // Integer inputs: o, d and oc are whole display units here.
                let (d, oc) = (d.map(|x| x as i128), oc.map(|x| x as i128));
                let a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                let b = d[0] * oc[0] + d[1] * oc[1] + d[2] * oc[2];
                let cc = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - i128::from(s.r * s.r);
                let disc = b * b - a * cc;
                *disc_bits = (*disc_bits).max(bits(disc));
                if disc < 0 || a == 0 {
                    continue;
                }
                // t scaled by 2^t_bits, truncated as an integer division does.
                let q = ((-b - isqrt(disc)) << t_bits) / a;
                q as f64
            }
        };
        if t > 0.0 && best.is_none_or(|(_, bt)| t < bt) {
            best = Some((i, t));
        }
    }
    best
}

/// The integer square root (floor).
fn isqrt(x: i128) -> i128 {
    if x <= 0 {
        return 0;
    }
    let mut r = (x as f64).sqrt() as i128;
    while r * r > x {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= x {
        r += 1;
    }
    r
}

/// One pixel at display position (x, y): the primary ray, its shade, its reflection (its
/// direction as long as the normal, the sphere's radius, as the paper keeps it) and the
/// reflected sphere's shade.
fn pixel(spheres: &[Sphere], x: f64, y: f64, ar: Arith, disc_bits: &mut u32) -> Pixel {
    let int = matches!(ar, Arith::Int { .. });
    let round = |v: [f64; 3]| if int { v.map(f64::round) } else { v };
    let scale = match ar {
        Arith::Int { t_bits } => f64::from(1u32 << t_bits),
        Arith::Float => 1.0,
    };
    let eye = EYE.map(|v| v as f64);
    let d = round([x - eye[0], y - eye[1], -eye[2]]);
    let Some((i, t)) = nearest(spheres, eye, d, usize::MAX, ar, disc_bits) else { return (u8::MAX, u8::MAX, 0.0) };
    // The hit point (t's scale taken off after multiplying), the normal p - c.
    let p = round([eye[0] + d[0] * t / scale, eye[1] + d[1] * t / scale, eye[2] + d[2] * t / scale]);
    let s = spheres[i];
    let n = round([p[0] - s.c[0] as f64, p[1] - s.c[1] as f64, p[2] - s.c[2] as f64]);
    let light = LIGHT.map(|v| v as f64);
    let shade = |n: [f64; 3], r: i64| (dot(n, light) / (r as f64 * 256.0)).clamp(0.0, 1.0);
    let lit = shade(n, s.r);
    // Reflection: d - 2 (d.n) n / (n.n), made as long as the normal.
    let nn = dot(n, n).max(1.0);
    let rf = [d[0] - 2.0 * dot(d, n) * n[0] / nn, d[1] - 2.0 * dot(d, n) * n[1] / nn, d[2] - 2.0 * dot(d, n) * n[2] / nn];
    let len = dot(rf, rf).sqrt().max(1e-9);
    let rf = round(rf.map(|v| v * s.r as f64 / len));
    let (j, second) = match nearest(spheres, p, rf, i, ar, disc_bits) {
        Some((jt, t2)) => {
            let q = round([p[0] + rf[0] * t2 / scale, p[1] + rf[1] * t2 / scale, p[2] + rf[2] * t2 / scale]);
            let sj = spheres[jt];
            let nj = round([q[0] - sj.c[0] as f64, q[1] - sj.c[1] as f64, q[2] - sj.c[2] as f64]);
            (jt as u8, shade(nj, sj.r))
        }
        None => (u8::MAX, 0.0),
    };
    (i as u8, j, (0.15 + 0.6 * lit + 0.25 * second) as f32)
}

/// One row of the study.
#[derive(Clone, Debug, PartialEq)]
pub struct Pp5Row {
    /// What was computed ("integers, t with 6 fraction bits", ...).
    pub arith: String,
    /// Image size.
    pub size: (u32, u32),
    /// Pixels whose primary ray hits another sphere than f64's, percent.
    pub primary_changed_pct: f64,
    /// Pixels whose reflection hits another sphere than f64's, percent of those where
    /// f64's primary ray hit a sphere.
    pub reflection_changed_pct: f64,
    /// PSNR of the shaded image against f64's, dB.
    pub psnr: f64,
    /// Bits of the largest discriminant b^2 - ac (sign included).
    pub disc_bits: u32,
}

fn trace(spheres: &[Sphere], size: (u32, u32), ar: Arith) -> (Vec<Pixel>, u32) {
    use rayon::prelude::*;
    // Pixel centres in display units: the quarter-resolution image covers the same
    // display with pixels twice as large.
    let (sx, sy) = (1280.0 / f64::from(size.0), 1024.0 / f64::from(size.1));
    let rows: Vec<(Vec<Pixel>, u32)> = (0..size.1)
        .into_par_iter()
        .map(|y| {
            let mut bits = 0;
            let row = (0..size.0).map(|x| pixel(spheres, (f64::from(x) + 0.5) * sx, (f64::from(y) + 0.5) * sy, ar, &mut bits)).collect();
            (row, bits)
        })
        .collect();
    let bits = rows.iter().map(|r| r.1).max().unwrap_or(0);
    (rows.into_iter().flat_map(|r| r.0).collect(), bits)
}

/// The study: at 640x512 (while moving) and 1280x1024 (still), PP5's integers with 6
/// fraction bits on t and with none, against f64.
#[must_use]
pub fn study() -> Vec<Pp5Row> {
    let spheres = scene();
    let mut rows = Vec::new();
    for size in [(640, 512), (1280, 1024)] {
        let (reference, _) = trace(&spheres, size, Arith::Float);
        for t_bits in [6, 0] {
            let (img, disc_bits) = trace(&spheres, size, Arith::Int { t_bits });
            let n = img.len().max(1) as f64;
            let primary = img.iter().zip(&reference).filter(|(a, b)| a.0 != b.0).count() as f64;
            let hit_ref: Vec<(&Pixel, &Pixel)> = img.iter().zip(&reference).filter(|(_, b)| b.0 != u8::MAX).collect();
            let refl = hit_ref.iter().filter(|(a, b)| a.1 != b.1).count() as f64;
            let a: Vec<f32> = img.iter().map(|p| p.2).collect();
            let b: Vec<f32> = reference.iter().map(|p| p.2).collect();
            rows.push(Pp5Row {
                arith: format!("integers, t with {t_bits} fraction bits"),
                size,
                primary_changed_pct: 100.0 * primary / n,
                reflection_changed_pct: 100.0 * refl / hit_ref.len().max(1) as f64,
                psnr: crate::precision::psnr(&a, &b),
                disc_bits,
            });
        }
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scene fits PP5's 12-bit coordinates; isqrt is the floor; and the paper's
    /// story holds: without fraction bits on t, far more reflections go astray than with
    /// its 6, and the discriminant needs well over 24 bits.
    #[test]
    fn pp5_arithmetic() {
        for s in scene() {
            assert!(s.c.iter().all(|&v| (-2048..2048).contains(&v)) && (1..2048).contains(&s.r), "{s:?}");
        }
        for x in [0i128, 1, 2, 3, 4, 15, 16, 17, 1 << 40, (1 << 40) + 1, (1 << 40) - 1] {
            let r = isqrt(x);
            assert!(r * r <= x && (r + 1) * (r + 1) > x, "{x}");
        }
        let spheres = scene();
        let size = (160, 128);
        let (reference, _) = trace(&spheres, size, Arith::Float);
        let (six, bits) = trace(&spheres, size, Arith::Int { t_bits: 6 });
        let (none, _) = trace(&spheres, size, Arith::Int { t_bits: 0 });
        let astray = |img: &[Pixel]| img.iter().zip(&reference).filter(|(a, b)| b.0 != u8::MAX && a.1 != b.1).count();
        assert!(reference.iter().filter(|p| p.0 != u8::MAX).count() > 160 * 128 / 3, "the spheres fill the view");
        assert!(reference.iter().filter(|p| p.1 != u8::MAX).count() > 100, "reflections meet other spheres");
        assert!(astray(&none) > 3 * astray(&six).max(1), "t bits: {} astray without, {} with 6", astray(&none), astray(&six));
        assert!(bits > 30, "discriminant bits {bits}");
    }
}

//! The Whitted integrator (Whitted, "An Improved Illumination Model for Shaded Display",
//! CACM 1980): Phong-like local shading (ambient, Lambert diffuse, Phong specular) from
//! every light with a hard shadow ray, plus recursive mirror reflection and refraction
//! (Snell's law, exact dielectric Fresnel, total internal reflection) up to a depth limit.

use crate::texture::sample;
use crate::world::{Surface, World};
use glam::Vec3;
use lucent_accel::Ray;
use lucent_scene::{Light, LightKind, Material};

/// Integrator settings.
#[derive(Clone, Copy, Debug)]
pub struct WhittedSettings {
    /// Most bounces (reflection or refraction generations).
    pub max_depth: u32,
    /// Trace shadow rays.
    pub shadows: bool,
    /// Trace primary and shadow rays in packets of 8×8 pixels (the default; the same image
    /// as ray by ray, only faster).
    pub packets: bool,
}

impl Default for WhittedSettings {
    fn default() -> Self {
        Self { max_depth: 6, shadows: true, packets: true }
    }
}

/// Unpolarized Fresnel reflectance of a dielectric; `cos_i` > 0 on the incident side,
/// `eta` = n_incident / n_transmitted. Returns 1 on total internal reflection.
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Refracts unit `d` through unit normal `n` (facing against `d`) with ratio `eta`;
/// `None` on total internal reflection.
#[must_use]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalize())
}

fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - n * (2.0 * d.dot(n))
}

/// What a pixel shows: the viewer cycles through these.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Integrator {
    /// Whitted ray tracing: lights, shadows, reflection, refraction ([`li`]).
    #[default]
    Whitted,
    /// A light at the eye, no shadows, no secondary rays: the fastest preview.
    EyeLight,
    /// Shading normals as colours (0.5 + 0.5 n), for inspecting geometry.
    Normals,
}

impl Integrator {
    /// The next one in the cycle.
    #[must_use]
    pub fn next(self) -> Self {
        match self {
            Self::Whitted => Self::EyeLight,
            Self::EyeLight => Self::Normals,
            Self::Normals => Self::Whitted,
        }
    }
    /// Name for the heads-up line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Whitted => "whitted",
            Self::EyeLight => "eye light",
            Self::Normals => "normals",
        }
    }
}

/// Radiance along `ray` with the chosen integrator.
#[must_use]
pub fn radiance(w: &World, ray: &Ray, s: &WhittedSettings, integrator: Integrator) -> Vec3 {
    match integrator {
        Integrator::Whitted => li(w, ray, s, 0),
        Integrator::EyeLight | Integrator::Normals => {
            let Some(hit) = w.intersect(ray) else {
                return w.scene.background;
            };
            let surf = w.surface(ray, &hit);
            let d = ray.dir.normalize();
            let ns = if d.dot(surf.ng) < 0.0 { surf.ns } else { -surf.ns };
            if integrator == Integrator::Normals {
                return ns * 0.5 + Vec3::splat(0.5);
            }
            static DEFAULT: std::sync::OnceLock<Material> = std::sync::OnceLock::new();
            let mat = w.scene.materials.get(surf.material as usize).unwrap_or_else(|| DEFAULT.get_or_init(Material::default));
            let mut kd = mat.diffuse;
            if let Some(t) = mat.diffuse_tex.and_then(|t| w.scene.textures.get(t as usize)) {
                kd *= sample(t, surf.uv).truncate();
            }
            let base = if kd.max_element() > 0.0 { kd } else { mat.specular.max(mat.reflect).max(mat.transmit) };
            base * (0.15 + 0.85 * (-d).dot(ns).max(0.0)) + mat.emission.min(Vec3::ONE)
        }
    }
}

/// Radiance along `ray`.
#[must_use]
pub fn li(w: &World, ray: &Ray, s: &WhittedSettings, depth: u32) -> Vec3 {
    let Some(hit) = w.intersect(ray) else {
        return w.scene.background;
    };
    let surf = w.surface(ray, &hit);
    // PERF: borrowed, not cloned (a clone allocates the name on every hit).
    static DEFAULT: std::sync::OnceLock<Material> = std::sync::OnceLock::new();
    let mat = w.scene.materials.get(surf.material as usize).unwrap_or_else(|| DEFAULT.get_or_init(Material::default));
    shade(w, ray, &surf, mat, s, depth)
}

fn offset(w: &World, p: Vec3, n: Vec3) -> Vec3 {
    // Scaled to the magnitude of the coordinates (float spacing) and a hair of the scene size.
    p + n * (p.abs().max_element() * 4e-6 + w.scale * 1e-6)
}

/// What shading one hit needs, found before any light is asked.
#[derive(Clone, Copy)]
struct Local<'a> {
    surf: Surface,
    mat: &'a Material,
    d: Vec3,
    front: bool,
    ng: Vec3,
    ns: Vec3,
    kd: Vec3,
    transmit: f32,
    opaque: f32,
    p_out: Vec3,
}

#[inline(always)]
fn local<'a>(w: &World, ray: &Ray, surf: Surface, mat: &'a Material) -> (Local<'a>, Vec3) {
    let d = ray.dir.normalize();
    let front = d.dot(surf.ng) < 0.0;
    // Normals facing the viewer.
    let ng = if front { surf.ng } else { -surf.ng };
    let ns = if front { surf.ns } else { -surf.ns };
    let mut kd = mat.diffuse;
    if let Some(t) = mat.diffuse_tex.and_then(|t| w.scene.textures.get(t as usize)) {
        kd *= sample(t, surf.uv).truncate();
    }
    let transmit = mat.transmit.max_element().clamp(0.0, 1.0);
    let opaque = 1.0 - transmit;
    let ka = if mat.ambient != Vec3::ZERO { mat.ambient } else { kd };
    let c = mat.emission.min(Vec3::ONE) + w.scene.ambient * ka * opaque;
    let p_out = offset(w, surf.p, ng);
    (Local { surf, mat, d, front, ng, ns, kd, transmit, opaque, p_out }, c)
}

/// A packet's ray buffer before its rays are made (PERF: a constant copied in; filling it
/// ray by ray showed in profiles of sparse REND3R frames).
pub(crate) const NO_RAYS: [Ray; lucent_accel::MAX_PACKET] =
    [Ray { org: Vec3::ZERO, dir: Vec3::X, tmin: 0.0, tmax: f32::INFINITY }; lucent_accel::MAX_PACKET];

/// Light `l`'s contribution at a hit, and the shadow ray that must be clear for it to count
/// (`None` when shadows are off); `None` when the light cannot reach the surface anyway.
#[inline(always)]
fn light_term(l: &Light, h: &Local, s: &WhittedSettings) -> Option<(Vec3, Option<Ray>)> {
    let p = h.surf.p;
    let (ldir, dist, mut rad) = match l.kind {
        LightKind::Point { position } => {
            let to = position - p;
            let dist = to.length();
            (to / dist, dist, l.color)
        }
        LightKind::Directional { direction } => (-direction.normalize(), f32::INFINITY, l.color),
        LightKind::Spot { position, direction, inner, outer } => {
            let to = position - p;
            let dist = to.length();
            let ldir = to / dist;
            let cos = (-ldir).dot(direction.normalize());
            let (ci, co) = (inner.cos(), outer.cos());
            let f = if ci > co { ((cos - co) / (ci - co)).clamp(0.0, 1.0) } else { (cos >= co) as u8 as f32 };
            (ldir, dist, l.color * f * f)
        }
    };
    if l.inverse_square && dist.is_finite() {
        rad /= (dist * dist).max(1e-12);
    }
    let cos = h.ns.dot(ldir);
    if cos <= 0.0 || h.ng.dot(ldir) <= 0.0 || rad.max_element() <= 0.0 || !cos.is_finite() {
        return None;
    }
    let shadow = s.shadows.then(|| {
        let tmax = if dist.is_finite() { (dist - (h.p_out - p).length()) * (1.0 - 1e-4) } else { f32::INFINITY };
        Ray::new(h.p_out, ldir).with_range(0.0, tmax)
    });
    let v = -h.d;
    let r = reflect(-ldir, h.ns);
    let mat = h.mat;
    // PERF: 0^shininess is 0 for a positive exponent; `powf` is skipped for the half of
    // the lit points whose mirror direction faces away from the eye.
    let rv = r.dot(v);
    let spec = if mat.specular.max_element() > 0.0 && (rv > 0.0 || mat.shininess <= 0.0) {
        mat.specular * pow_unit(rv.max(0.0), mat.shininess)
    } else {
        Vec3::ZERO
    };
    Some((rad * (h.kd * cos * h.opaque + spec), shadow))
}

/// `x^y` for the Phong term: `x` in `(0, 1]` and `y` in `(0, 4096]` by `exp2(y·log2 x)`
/// with short series (relative error below 2e-5 for these arguments, against `powf`'s
/// exactly rounded result; PERF: `powf` was 5–7% of a shaded frame of the BART kitchen and
/// of the sunflowers); anything else goes to `powf`.
#[inline]
fn pow_unit(x: f32, y: f32) -> f32 {
    if !(x > 0.0 && x <= 1.0 && y > 0.0 && y <= 4096.0) {
        return x.powf(y);
    }
    // log2 x = e + log2 m with m in [√½, √2): log2 m = 2/ln 2 · atanh((m − 1)/(m + 1)),
    // an odd series in s = (m − 1)/(m + 1), |s| ≤ 0.172 (next term below 2e-8).
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    if e == -127 {
        // Subnormal x: x^y underflows for every y this path takes unless y is tiny.
        return x.powf(y);
    }
    if m > std::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    // PERF: the series in Estrin's form (two short chains rather than one long one).
    let atanh = s * ((1.0 + s2 * (1.0 / 3.0)) + (s2 * s2) * (1.0 / 5.0 + s2 * (1.0 / 7.0)));
    let z = y * (e as f32 + 2.0 * std::f32::consts::LOG2_E * atanh);
    // 2^z = 2^n · 2^f with n = z rounded to nearest (adding and taking away 1.5·2^23 rounds
    // in one step where `round` is a libm call on the baseline target), so f is in
    // [−½, ½]: e^(f ln 2) by its Taylor series to the 5th power (next term below 2.5e-6),
    // in Estrin's form.
    if z < -126.0 {
        return 0.0;
    }
    const ROUND: f32 = 12_582_912.0;
    let r = (z + ROUND) - ROUND;
    let n = r as i32;
    let g = (z - r) * std::f32::consts::LN_2;
    let g2 = g * g;
    let p = (1.0 + g) + g2 * ((0.5 + g * (1.0 / 6.0)) + g2 * (1.0 / 24.0 + g * (1.0 / 120.0)));
    p * f32::from_bits(((n + 127) as u32) << 23)
}

/// The refracted and the reflected ray of a hit, each with its weight (either may be
/// absent), in the order their light is added.
fn secondary_rays(w: &World, h: &Local) -> [Option<(Vec3, Ray)>; 2] {
    let (d, mat) = (h.d, h.mat);
    let mut out = [None, None];
    let mut kr = mat.reflect;
    if h.transmit > 0.0 {
        // Entering when the ray meets the front side.
        let eta = if h.front { 1.0 / mat.ior.max(1e-3) } else { mat.ior.max(1e-3) };
        let cos_i = -d.dot(h.ns).clamp(-1.0, 1.0);
        let f = if mat.fresnel { fresnel_dielectric(cos_i.abs(), eta) } else { 0.0 };
        match refract(d, h.ns, eta) {
            Some(t) if f < 1.0 => {
                let p_in = offset(w, h.surf.p, -h.ng);
                out[0] = Some((mat.transmit * (1.0 - f), Ray::new(p_in, t)));
                if mat.fresnel {
                    kr = kr.max(Vec3::splat(f));
                }
            }
            _ => kr = Vec3::ONE, // total internal reflection
        }
    }
    if kr.max_element() > 0.0 {
        out[1] = Some((kr, Ray::new(h.p_out, reflect(d, h.ns))));
    }
    out
}

/// Adds the refracted and reflected light (traced ray by ray) to `c`.
fn secondary(w: &World, h: &Local, s: &WhittedSettings, depth: u32, c: &mut Vec3) {
    if depth >= s.max_depth {
        return;
    }
    for (k, r) in secondary_rays(w, h).into_iter().flatten() {
        *c += k * li(w, &r, s, depth + 1);
    }
}

fn shade(w: &World, ray: &Ray, surf: &Surface, mat: &Material, s: &WhittedSettings, depth: u32) -> Vec3 {
    let (h, mut c) = local(w, ray, *surf, mat);
    for l in &w.lights {
        let Some((term, shadow)) = light_term(l, &h, s) else { continue };
        if shadow.is_some_and(|r| w.occluded(&r)) {
            continue;
        }
        c += term;
    }
    secondary(w, &h, s, depth, &mut c);
    c
}

/// [`li`] for up to [`lucent_accel::MAX_PACKET`] coherent rays (e.g. an 8×8 tile of primary
/// rays): the closest hits and then each light's shadow rays are traced as packets, the
/// reflected and refracted rays one by one. The same radiance as [`li`] on each ray (only
/// which of two surfaces at exactly the same distance is seen may differ).
pub fn li_packet(w: &World, rays: &[Ray], s: &WhittedSettings, out: &mut [Vec3]) {
    li_packet_at(w, rays, s, 0, out);
}

/// [`li_packet`] at recursion depth `depth`: the refracted rays of the block, then its
/// reflected rays, are traced as packets of their own (a flat mirror's or a window's rays
/// stay coherent; scattered ones fall back to single rays inside the kernels).
fn li_packet_at(w: &World, rays: &[Ray], s: &WhittedSettings, depth: u32, out: &mut [Vec3]) {
    const N: usize = lucent_accel::MAX_PACKET;
    static DEFAULT: std::sync::OnceLock<Material> = std::sync::OnceLock::new();
    for (rays, out) in rays.chunks(N).zip(out.chunks_mut(N)) {
        let n = rays.len();
        let mut hits = [None; N];
        w.intersect_packet(rays, &mut hits[..n]);
        // PERF: a block that met nothing shows the background; the per-hit arrays below
        // (about 20 KB to initialise) are skipped.
        if hits[..n].iter().all(Option::is_none) {
            out.fill(w.scene.background);
            continue;
        }
        // PERF: a fixed array, not a Vec (one allocation per block showed in profiles).
        let mut locals: [Option<Local>; N] = [None; N];
        let locals = &mut locals[..n];
        for i in 0..n {
            match hits[i] {
                Some(hit) => {
                    let surf = w.surface(&rays[i], &hit);
                    let mat = w.scene.materials.get(surf.material as usize).unwrap_or_else(|| DEFAULT.get_or_init(Material::default));
                    let (h, c) = local(w, &rays[i], surf, mat);
                    out[i] = c;
                    locals[i] = Some(h);
                }
                None => out[i] = w.scene.background,
            }
        }
        let mut shadow = NO_RAYS;
        let mut who = [0usize; N];
        let mut terms = [Vec3::ZERO; N];
        let mut blocked = [false; N];
        for l in &w.lights {
            let mut k = 0;
            for (i, h) in locals.iter().enumerate() {
                let Some(h) = h else { continue };
                let Some((term, ray)) = light_term(l, h, s) else { continue };
                match ray {
                    Some(r) => {
                        shadow[k] = r;
                        who[k] = i;
                        terms[k] = term;
                        k += 1;
                    }
                    None => out[i] += term,
                }
            }
            if k > 0 {
                w.occluded_packet(&shadow[..k], &mut blocked[..k]);
                for j in 0..k {
                    if !blocked[j] {
                        out[who[j]] += terms[j];
                    }
                }
            }
        }
        // PERF: blocks where nothing reflects or transmits (REND3R's matte spheres) skip
        // the secondary stage and its buffers (a tenth of a 256-sphere frame).
        if depth >= s.max_depth || !locals.iter().flatten().any(|h| h.transmit > 0.0 || h.mat.reflect.max_element() > 0.0) {
            continue;
        }
        // Transmitted light first, then reflected, as `secondary` adds them.
        // PERF: a fixed array, as `locals` (no allocation per block and depth).
        let mut sec = [[None; 2]; N];
        for (slot, h) in sec.iter_mut().zip(locals.iter()) {
            if let Some(h) = h {
                *slot = secondary_rays(w, h);
            }
        }
        let sec = &sec[..n];
        let mut res = [Vec3::ZERO; N];
        for pass in 0..2 {
            let mut k = 0;
            for (i, r) in sec.iter().enumerate() {
                if let Some((_, ray)) = r[pass] {
                    shadow[k] = ray;
                    who[k] = i;
                    k += 1;
                }
            }
            if k == 0 {
                continue;
            }
            li_packet_at(w, &shadow[..k], s, depth + 1, &mut res[..k]);
            for j in 0..k {
                if let Some((weight, _)) = sec[who[j]][pass] {
                    out[who[j]] += weight * res[j];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::pow_unit;

    /// The Phong power against `powf` over the range it serves (relative error, with an
    /// absolute floor far below one 8-bit step), and `powf`'s answers outside it.
    #[test]
    fn pow_unit_matches_powf() {
        let mut worst = 0.0f64;
        for i in 1..=2000 {
            let x = i as f32 / 2000.0;
            for y in [0.01f32, 0.5, 1.0, 2.0, 5.0, 10.0, 32.0, 64.0, 96.078, 128.0, 500.0, 1000.0, 4096.0] {
                let (got, want) = (pow_unit(x, y) as f64, (x as f64).powf(y as f64));
                let err = (got - want).abs() / want.max(1e-30);
                if want > 1e-30 {
                    worst = worst.max(err);
                }
                assert!(err < 2e-5 || (got - want).abs() < 1e-12, "{x}^{y}: {got} against {want}");
            }
        }
        assert!(worst > 0.0, "the series is not exact");
        for (x, y) in [(0.0f32, 2.0f32), (0.5, 0.0), (0.5, -1.0), (1.5, 2.0), (0.5, 1e5), (1e-40, 0.5), (f32::NAN, 2.0)] {
            let (got, want) = (pow_unit(x, y), x.powf(y));
            assert!(got == want || (got.is_nan() && want.is_nan()), "{x}^{y}: {got} against {want}");
        }
    }
}

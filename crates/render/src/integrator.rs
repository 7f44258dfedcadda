//! The Whitted integrator (Whitted, "An Improved Illumination Model for Shaded Display",
//! CACM 1980): Phong-like local shading (ambient, Lambert diffuse, Phong specular) from
//! every light with a hard shadow ray, plus recursive mirror reflection and refraction
//! (Snell's law, exact dielectric Fresnel, total internal reflection) up to a depth limit.

use crate::texture::sample;
use crate::world::{Surface, World};
use glam::Vec3;
use lucent_accel::Ray;
use lucent_scene::{LightKind, Material};

/// Integrator settings.
#[derive(Clone, Copy, Debug)]
pub struct WhittedSettings {
    /// Most bounces (reflection or refraction generations).
    pub max_depth: u32,
    /// Trace shadow rays.
    pub shadows: bool,
}

impl Default for WhittedSettings {
    fn default() -> Self {
        Self { max_depth: 6, shadows: true }
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

fn shade(w: &World, ray: &Ray, surf: &Surface, mat: &Material, s: &WhittedSettings, depth: u32) -> Vec3 {
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
    let mut c = mat.emission.min(Vec3::ONE) + w.scene.ambient * ka * opaque;
    let v = -d;
    let p_out = offset(w, surf.p, ng);
    for l in &w.lights {
        let (ldir, dist, mut rad) = match l.kind {
            LightKind::Point { position } => {
                let to = position - surf.p;
                let dist = to.length();
                (to / dist, dist, l.color)
            }
            LightKind::Directional { direction } => (-direction.normalize(), f32::INFINITY, l.color),
            LightKind::Spot { position, direction, inner, outer } => {
                let to = position - surf.p;
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
        let cos = ns.dot(ldir);
        if cos <= 0.0 || ng.dot(ldir) <= 0.0 || rad.max_element() <= 0.0 || !cos.is_finite() {
            continue;
        }
        if s.shadows {
            let tmax = if dist.is_finite() { (dist - (p_out - surf.p).length()) * (1.0 - 1e-4) } else { f32::INFINITY };
            if w.occluded(&Ray::new(p_out, ldir).with_range(0.0, tmax)) {
                continue;
            }
        }
        let r = reflect(-ldir, ns);
        let spec = if mat.specular.max_element() > 0.0 { mat.specular * r.dot(v).max(0.0).powf(mat.shininess) } else { Vec3::ZERO };
        c += rad * (kd * cos * opaque + spec);
    }
    if depth >= s.max_depth {
        return c;
    }
    let mut kr = mat.reflect;
    if transmit > 0.0 {
        // Entering when the ray meets the front side.
        let eta = if front { 1.0 / mat.ior.max(1e-3) } else { mat.ior.max(1e-3) };
        let cos_i = -d.dot(ns).clamp(-1.0, 1.0);
        let f = if mat.fresnel { fresnel_dielectric(cos_i.abs(), eta) } else { 0.0 };
        match refract(d, ns, eta) {
            Some(t) if f < 1.0 => {
                let p_in = offset(w, surf.p, -ng);
                c += mat.transmit * (1.0 - f) * li(w, &Ray::new(p_in, t), s, depth + 1);
                if mat.fresnel {
                    kr = kr.max(Vec3::splat(f));
                }
            }
            _ => kr = Vec3::ONE, // total internal reflection
        }
    }
    if kr.max_element() > 0.0 {
        let r = reflect(d, ns);
        c += kr * li(w, &Ray::new(p_out, r), s, depth + 1);
    }
    c
}

//! The path tracer: unidirectional path tracing (Kajiya, "The Rendering Equation", 1986)
//! with next-event estimation and BSDF sampling combined by multiple importance sampling,
//! the power heuristic (Veach and Guibas, "Optimally Combining Sampling Techniques for
//! Monte Carlo Rendering", 1995), and Russian roulette, with Mitsuba 3's conventions for
//! its `path` integrator's parameters: `max_depth` counts path segments (1: emitters seen
//! directly, 2: direct light, unlimited by default), roulette starts at `rr_depth` (5)
//! with survival probability `min(max(throughput) · η², 0.95)`, and `hide_emitters`
//! hides emitters seen directly from the camera.
//!
//! Random numbers come from the [`Sampler`] (Owen-scrambled Sobol' pairs), a pure function
//! of pixel, sample index and dimension: pair 0 places the sample in its pixel, and each
//! bounce takes two pairs (a point on the light; the BSDF's direction) and four hashed
//! numbers for its discrete choices (which light, which lobe, reflection or refraction,
//! roulette: `PixelSampler::get1_hashed`, a third of a scrambled pair's cost).
//!
//! Lights: emitting triangles (a mesh material's emission: one-sided, toward the side the
//! triangle's winding makes its normal point, as Mitsuba's `area` emitter), chosen in
//! proportion to power, a point uniformly on the chosen one; the scene's point,
//! directional and spot lights (always falling off with the squared distance, as physical
//! point lights do); the background, a constant environment met by rays that leave the
//! scene (not sampled by next-event estimation yet).
//!
//! Materials, until the BSDFs of issue 34's second part: the diffuse reflectance
//! (textured) as a Lambertian lobe, the mirror reflectance as a smooth conductor of that
//! colour, and the transmittance as a smooth dielectric of the material's index (Fresnel
//! weighted when the material says so); one lobe is chosen per bounce, in proportion to
//! its weight. Phong highlights are not part of the path tracer.

use super::{material, textured_kd, whitted::fresnel_dielectric, whitted::refract};
use crate::sampler::Sampler;
use crate::world::{luminance, World};
use glam::Vec3;
use lucent_accel::{Hit, Ray};
use lucent_scene::LightKind;

/// Which strategies estimate the light arriving at a surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LightSampling {
    /// Both, weighted by the power heuristic (the default).
    #[default]
    Mis,
    /// Next-event estimation only: a sampled point on a light, and emitters met by BSDF
    /// rays ignored (except through delta lobes, which next-event estimation cannot see).
    Nee,
    /// BSDF sampling only: light comes from emitters the rays happen to meet (point lights
    /// are then invisible).
    Bsdf,
}

/// The path tracer's settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathSettings {
    /// Most path segments (`u32::MAX`: unlimited; Mitsuba's `max_depth = -1`).
    pub max_depth: u32,
    /// Path depth from which Russian roulette may end paths.
    pub rr_depth: u32,
    /// Emitters seen directly from the camera show the background instead.
    pub hide_emitters: bool,
    /// The light-sampling strategy.
    pub sampling: LightSampling,
}

impl Default for PathSettings {
    fn default() -> Self {
        Self { max_depth: u32::MAX, rr_depth: 5, hide_emitters: false, sampling: LightSampling::Mis }
    }
}

/// The sampler the path tracer draws from.
pub(crate) const SAMPLER: Sampler = Sampler::new(0x1ce7_0001);

/// Sampler pairs per bounce, after pair 0 (the pixel position).
const PAIRS: u32 = 2;

/// Hashed numbers per bounce.
const CHOICES: u32 = 4;

/// The power heuristic with β = 2 for `a` against `b` (pdfs of one sample each).
#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// A unit vector's orthonormal frame: tangent, bitangent (Duff et al., "Building an
/// Orthonormal Basis, Revisited", JCGT 2017).
#[inline]
fn frame(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// A cosine-weighted direction about `n` for `u` in [0, 1)² (Malley's method over a
/// concentric disk, Shirley and Chiu 1997).
#[inline]
fn cosine_hemisphere(n: Vec3, u: (f32, f32)) -> Vec3 {
    let (a, b) = (2.0 * u.0 - 1.0, 2.0 * u.1 - 1.0);
    let (r, phi) = if a == 0.0 && b == 0.0 {
        (0.0, 0.0)
    } else if a.abs() > b.abs() {
        (a, std::f32::consts::FRAC_PI_4 * (b / a))
    } else {
        (b, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a / b))
    };
    let (x, y) = (r * phi.cos(), r * phi.sin());
    let z = (1.0 - x * x - y * y).max(0.0).sqrt();
    let (t, bt) = frame(n);
    (t * x + bt * y + n * z).normalize()
}

/// A uniformly distributed point on a triangle for `u` in [0, 1)² (the square folded onto
/// the triangle).
#[inline]
fn triangle_point(p0: Vec3, e1: Vec3, e2: Vec3, u: (f32, f32)) -> Vec3 {
    let (mut a, mut b) = u;
    if a + b > 1.0 {
        (a, b) = (1.0 - a, 1.0 - b);
    }
    p0 + e1 * a + e2 * b
}

/// The lobes of a hit's material, with their weights (albedos).
struct Lobes {
    diffuse: Vec3,
    mirror: Vec3,
    transmit: Vec3,
    ior: f32,
    fresnel: bool,
}

impl Lobes {
    /// The probability of choosing each lobe (diffuse, mirror, transmission).
    fn choice(&self) -> [f32; 3] {
        let w = [luminance(self.diffuse), luminance(self.mirror), luminance(self.transmit)].map(|x| x.max(0.0));
        let sum = w[0] + w[1] + w[2];
        if sum > 0.0 && sum.is_finite() {
            w.map(|x| x / sum)
        } else {
            [0.0; 3]
        }
    }
}

/// Radiance along a camera ray through pixel (x, y), sample `index`; `first`, when given,
/// is the camera ray's closest hit, already found (by a packet of the block's camera rays).
pub(crate) fn li(w: &World, camera_ray: &Ray, s: &PathSettings, x: u32, y: u32, index: u32, first: Option<Option<Hit>>) -> Vec3 {
    let px = SAMPLER.pixel(x, y);
    let dims = |pair: u32| px.get2(index, pair);
    let choice_at = |depth: u32, k: u32| px.get1_hashed(index, depth.saturating_mul(CHOICES) + k);
    let bg = w.scene.background;
    let delta_lights = w.scene.lights.len();
    let area = !w.emitters.is_empty();
    let n_lights = delta_lights + usize::from(area);
    let mut radiance = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut ray = *camera_ray;
    // The previous bounce: its BSDF pdf (solid angle) and whether it was a delta lobe.
    let (mut prev_pdf, mut prev_delta) = (0.0f32, true);
    let mut prev_p = ray.org;
    let mut depth = 0u32;
    // The relative index of refraction along the path so far (for roulette).
    let mut eta = 1.0f32;
    let mut first = first;
    loop {
        let found = match first.take() {
            Some(h) => h,
            None => w.intersect(&ray),
        };
        let Some(hit) = found else {
            if !(depth == 0 && s.hide_emitters) {
                radiance += beta * bg;
            }
            break;
        };
        let surf = w.surface(&ray, &hit);
        let d = ray.dir.normalize();
        let mat = material(w, surf.material);
        // Emission, on the side the triangle's normal points to.
        if mat.emission.max_element() > 0.0 && d.dot(surf.ng) < 0.0 && !(depth == 0 && s.hide_emitters) {
            let weight = if prev_delta {
                1.0
            } else {
                match s.sampling {
                    LightSampling::Bsdf => 1.0,
                    // (Emitters next-event estimation cannot sample count as they are met.)
                    LightSampling::Nee => match w.emitters.find(hit.inst, hit.prim) {
                        Some(_) => 0.0,
                        None => 1.0,
                    },
                    LightSampling::Mis => match w.emitters.find(hit.inst, hit.prim) {
                        Some(i) => {
                            let cos_l = w.emitters.tris[i].n.dot(-d).abs().max(1e-12);
                            let light_pdf = w.emitters.pdf(i, (surf.p - prev_p).length_squared(), cos_l) / n_lights as f32;
                            power_heuristic(prev_pdf, light_pdf)
                        }
                        None => 1.0,
                    },
                }
            };
            radiance += beta * mat.emission * weight;
        }
        if depth.saturating_add(1) >= s.max_depth {
            break;
        }
        let base = 1 + depth.saturating_mul(PAIRS);
        let (u_light, u_lobe) = (choice_at(depth, 0), choice_at(depth, 1));
        let lobes = Lobes {
            diffuse: textured_kd(w, mat, surf.uv),
            mirror: mat.reflect,
            transmit: mat.transmit,
            ior: mat.ior.max(1e-3),
            fresnel: mat.fresnel,
        };
        let choice = lobes.choice();
        if choice == [0.0; 3] {
            break;
        }
        // Normals facing the incoming ray.
        let front = d.dot(surf.ng) < 0.0;
        let ng = if front { surf.ng } else { -surf.ng };
        let ns = if d.dot(surf.ns) < 0.0 { surf.ns } else { -surf.ns };
        let p_diffuse = choice[0];
        // Next-event estimation, for the diffuse lobe.
        if p_diffuse > 0.0 && n_lights > 0 && s.sampling != LightSampling::Bsdf {
            let f = lobes.diffuse * std::f32::consts::FRAC_1_PI;
            let pick = ((u_light * n_lights as f32) as usize).min(n_lights - 1);
            let u_pos = dims(base);
            let sample = if pick < delta_lights {
                delta_light(w, pick, surf.p).map(|(dir, dist, li)| (dir, dist, li, f32::INFINITY))
            } else {
                // Reuse u_light's fraction within the area lights' share to choose a
                // triangle.
                let u = (u_light * n_lights as f32 - delta_lights as f32).clamp(0.0, 1.0 - f32::EPSILON);
                w.emitters.choose(u).and_then(|i| {
                    let t = &w.emitters.tris[i];
                    let q = triangle_point(t.p0, t.e1, t.e2, u_pos);
                    let to = q - surf.p;
                    let dist = to.length();
                    let dir = to / dist;
                    let cos_l = t.n.dot(-dir);
                    if !(cos_l > 0.0 && dist > 0.0 && dist.is_finite()) {
                        return None;
                    }
                    let pdf = w.emitters.pdf(i, dist * dist, cos_l);
                    Some((dir, dist, t.le / pdf, pdf))
                })
            };
            if let Some((dir, dist, li, light_pdf)) = sample {
                let cos_s = ns.dot(dir);
                if cos_s > 0.0 && ng.dot(dir) > 0.0 {
                    let shadow = surf.spawn(dir);
                    let tmax = if dist.is_finite() { dist * (1.0 - 1e-4) } else { f32::INFINITY };
                    if !w.occluded(&shadow.with_range(0.0, tmax)) {
                        let bsdf_pdf = p_diffuse * cos_s * std::f32::consts::FRAC_1_PI;
                        let weight = if light_pdf.is_infinite() || s.sampling == LightSampling::Nee {
                            1.0
                        } else {
                            // The light's pdf with the choice among the lights.
                            power_heuristic(light_pdf / n_lights as f32, bsdf_pdf)
                        };
                        radiance += beta * f * li * cos_s * (n_lights as f32) * weight;
                    }
                }
            }
        }
        // The next direction: one lobe, chosen in proportion to its weight.
        let u_dir = dims(base + 1);
        let (dir, weight, pdf, delta) = if u_lobe < choice[0] {
            let dir = cosine_hemisphere(ns, u_dir);
            if ng.dot(dir) <= 0.0 {
                break;
            }
            // f cos / pdf = (kd / π) cos / (p cos / π).
            (dir, lobes.diffuse / choice[0], choice[0] * ns.dot(dir).max(0.0) * std::f32::consts::FRAC_1_PI, false)
        } else if u_lobe < choice[0] + choice[1] {
            (d - ns * (2.0 * d.dot(ns)), lobes.mirror / choice[1], f32::INFINITY, true)
        } else {
            // A smooth dielectric: reflect with the Fresnel reflectance's probability.
            let eta_rel = if front { 1.0 / lobes.ior } else { lobes.ior };
            let cos_i = (-d.dot(ns)).clamp(0.0, 1.0);
            let fr = if lobes.fresnel { fresnel_dielectric(cos_i, eta_rel) } else { 0.0 };
            let u_fr = choice_at(depth, 2);
            match refract(d, ns, eta_rel) {
                Some(t) if u_fr >= fr => {
                    eta *= 1.0 / eta_rel;
                    (t, lobes.transmit / choice[2], f32::INFINITY, true)
                }
                _ => (d - ns * (2.0 * d.dot(ns)), lobes.transmit / choice[2], f32::INFINITY, true),
            }
        };
        beta *= weight;
        if !beta.is_finite() || beta.max_element() <= 0.0 {
            break;
        }
        prev_pdf = pdf;
        prev_delta = delta;
        prev_p = surf.p;
        ray = surf.spawn(dir);
        depth += 1;
        // Russian roulette.
        if depth >= s.rr_depth {
            let q = (beta.max_element() * eta * eta).min(0.95);
            // (The bounce's own numbers: `depth` has moved on.)
            let u_rr = choice_at(depth - 1, 3);
            if u_rr >= q {
                break;
            }
            beta /= q;
        }
    }
    if radiance.is_finite() {
        radiance
    } else {
        Vec3::ZERO
    }
}

/// Scene light `i` seen from `p`: the unit direction toward it, its distance (infinite for
/// a directional light) and the radiance it brings (irradiance at normal incidence).
fn delta_light(w: &World, i: usize, p: Vec3) -> Option<(Vec3, f32, Vec3)> {
    let l = w.scene.lights.get(i)?;
    match l.kind {
        LightKind::Directional { direction } => {
            let dir = -direction.normalize_or_zero();
            (dir != Vec3::ZERO).then_some((dir, f32::INFINITY, l.color))
        }
        LightKind::Point { position } | LightKind::Spot { position, .. } => {
            let to = position - p;
            let dist = to.length();
            if !(dist > 0.0 && dist.is_finite()) {
                return None;
            }
            let dir = to / dist;
            let falloff = match l.kind {
                LightKind::Spot { direction, inner, outer, .. } => {
                    // Mitsuba's spot falloff: full inside `inner`, a linear ramp of the
                    // angle to zero at `outer`.
                    let angle = (-dir).dot(direction.normalize_or_zero()).clamp(-1.0, 1.0).acos();
                    if angle <= inner {
                        1.0
                    } else if angle >= outer || outer <= inner {
                        0.0
                    } else {
                        (outer - angle) / (outer - inner)
                    }
                }
                _ => 1.0,
            };
            (falloff > 0.0).then(|| (dir, dist, l.color * falloff / (dist * dist)))
        }
    }
}

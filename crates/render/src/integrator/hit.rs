//! What the integrators read at a hit: its material, the light it emits, its shading
//! normal (bent by normal maps), its BSDF and shading frame; and the first hits of a
//! block's camera rays, traced as one packet where that pays.

use crate::bsdf::Bsdf;
use crate::sampling::ShadingFrame;
use crate::texture::sample;
use crate::world::surface::Surface;
use crate::world::World;
use glam::Vec3;
use lucent_accel::{Hit, Ray};
use lucent_scene::{Material, Sides};

/// Whether a block's camera rays are narrow enough for a packet to pay: their unit
/// directions differ by at most [`PACKET_SPREAD`] in every component. Measured on the
/// bunny reference scene, path traced (median of two runs, 2 threads): at 64 × 64 pixels
/// (8-pixel blocks span 0.065) single rays took 0.90 s where packets took 1.13 s; at
/// 256 × 256 (0.016) packets took 0.67 s against 0.71, at 512 × 512 2.46 s against 2.62.
const PACKET_SPREAD: f32 = 0.03;

/// Traces a block's camera rays (at most [`lucent_accel::MAX_PACKET`]) as one packet, their
/// closest hits into `hits`, when `packets` is on, no surface has an alpha mask (a packet
/// stops at cut-out parts) and the rays are [`coherent`]; returns whether it did. The
/// camera paths then start from those hits ([`World::first_hit`]), else they trace alone.
pub(crate) fn packet_first_hits(w: &World, rays: &[Ray], among: Option<&[u32]>, packets: bool, hits: &mut [Option<Hit>]) -> bool {
    if !packets || w.has_alpha() || !coherent(rays) {
        return false;
    }
    match among {
        Some(ids) => w.intersect_packet_among(rays, ids, hits),
        None => w.intersect_packet(rays, hits),
    }
    true
}

pub(crate) fn coherent(rays: &[Ray]) -> bool {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for r in rays {
        let d = r.dir.normalize_or_zero();
        lo = lo.min(d);
        hi = hi.max(d);
    }
    (hi - lo).max_element() <= PACKET_SPREAD
}

/// The radiance `mat` emits at texture coordinates `uv` (its emission times its emission
/// texture, when it has one), on the side its normal points to.
pub(crate) fn emitted(w: &World, mat: &Material, uv: glam::Vec2) -> Vec3 {
    match mat.emission_tex.and_then(|t| w.scene.textures.get(t as usize)) {
        Some(t) => mat.emission * sample(t, uv).truncate(),
        None => mat.emission,
    }
}

/// Material `index` of the scene, or the default one for an index out of range (PERF:
/// borrowed, not cloned: a clone allocates the name on every hit).
pub(crate) fn material(w: &World, index: u32) -> &Material {
    w.scene.materials.get(index as usize).unwrap_or_else(|| default_material())
}

/// `Material::default()`, made once.
pub(crate) fn default_material() -> &'static Material {
    static DEFAULT: std::sync::OnceLock<Material> = std::sync::OnceLock::new();
    DEFAULT.get_or_init(Material::default)
}

/// The material's diffuse reflectance at `uv`, textured.
#[inline(always)]
pub(crate) fn textured_kd(w: &World, mat: &Material, uv: glam::Vec2) -> Vec3 {
    let mut kd = mat.diffuse;
    if let Some(t) = mat.diffuse_tex.and_then(|t| w.scene.textures.get(t as usize)) {
        kd *= sample(t, uv).truncate();
    }
    kd
}
/// The shading normal at a surface point: the interpolated one, bent by the material's
/// tangent-space normal map when it has one (tangents from the triangle's texture
/// coordinates: x along ∂p/∂u, y along ∂p/∂v, as glTF's maps are authored, or along
/// n × x with a bent normal facing the viewer, as Mitsuba's: see
/// [`lucent_scene::NormalMap`]).
pub(crate) fn shading_normal(w: &World, ray: &Ray, hit: &Hit, surf: &Surface) -> Vec3 {
    let mat = material(w, surf.material);
    let Some(nm) = mat.normal_map else { return surf.ns };
    let Some(tex) = w.scene.textures.get(nm.tex as usize) else { return surf.ns };
    let Some((dpdu, dpdv)) = w.uv_tangents(ray, hit) else { return surf.ns };
    let n = surf.ns;
    if nm.height {
        return bumped_normal(tex, &nm, surf, n, dpdu, dpdv, -ray.dir);
    }
    let c = sample(tex, nm.to_uv.transform_point2(surf.uv)).truncate() * 2.0 - Vec3::ONE;
    let t = (dpdu - n * n.dot(dpdu)).normalize_or_zero();
    let b = if nm.mitsuba { n.cross(t) } else { (dpdv - n * n.dot(dpdv) - t * t.dot(dpdv)).normalize_or_zero() };
    if t == Vec3::ZERO || b == Vec3::ZERO {
        return n;
    }
    let mut bent = (t * (c.x * nm.scale) + b * (c.y * nm.scale) + n * c.z).normalize_or_zero();
    if nm.mitsuba {
        // (The viewer below the bent normal: its tangent part reversed.)
        let wi = -ray.dir;
        if wi.dot(n) * wi.dot(bent) <= 0.0 {
            bent = 2.0 * bent.dot(n) * n - bent;
        }
    }
    if bent == Vec3::ZERO || !bent.is_finite() {
        n
    } else {
        bent
    }
}

/// The normal of a height field (Mitsuba's `bumpmap`): ∂p/∂u and ∂p/∂v moved along `n` to
/// the height's slopes (the texture's gradient through its transform, times the scale),
/// their cross product turned to the geometric side, and its tangent part reversed where
/// it turns the surface away from the viewer along `wi`.
fn bumped_normal(
    tex: &lucent_scene::Texture,
    nm: &lucent_scene::NormalMap,
    surf: &Surface,
    n: Vec3,
    dpdu: Vec3,
    dpdv: Vec3,
    wi: Vec3,
) -> Vec3 {
    let g = crate::texture::sample_gradient(tex, nm.to_uv.transform_point2(surf.uv));
    // (The chain rule through the texture's transform: its transpose.)
    let m = nm.to_uv.matrix2;
    let g = glam::Vec2::new(m.x_axis.dot(g), m.y_axis.dot(g)) * nm.scale;
    let du = dpdu + n * (g.x - n.dot(dpdu));
    let dv = dpdv + n * (g.y - n.dot(dpdv));
    let mut bent = du.cross(dv).normalize_or_zero();
    if bent == Vec3::ZERO || !bent.is_finite() {
        return n;
    }
    if bent.dot(surf.ng) < 0.0 {
        bent = -bent;
    }
    if wi.dot(n) * wi.dot(bent) <= 0.0 {
        bent = 2.0 * bent.dot(n) * n - bent;
    }
    bent.normalize_or(n)
}

/// What Mitsuba's `normalmap` adapter adds to its BSDF (a material whose normal map has
/// [`lucent_scene::NormalMap::mitsuba`]): light must lie on the same side of the
/// unperturbed and the bent normal, and the BSDF's value is damped toward grazing light by
/// the microfacet shadowing term of Conty Estevez, Lecocq and Stein ("A Microfacet-Based
/// Shadowing Function to Solve the Bump Terminator Problem", Ray Tracing Gems, 2019),
/// whose roughness grows with the bend: α² = min(tan²θ_bend / 8, 1), G = 2 / (1 +
/// √(1 + α² tan²θ_light)). Sampling densities are unchanged (as Mitsuba's).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bend {
    n0: Vec3,
    n: Vec3,
    /// α², or below zero: no bend (the weight is one).
    alpha2: f32,
}

impl Bend {
    pub(crate) const NONE: Self = Self { n0: Vec3::ZERO, n: Vec3::ZERO, alpha2: -1.0 };

    /// The bend of shading normal `ns` at `surf` (none without a Mitsuba normal map).
    pub(crate) fn of(w: &World, surf: &Surface, ns: Vec3) -> Self {
        match material(w, surf.material).normal_map {
            Some(nm) if nm.mitsuba && ns != surf.ns => {
                let c = ns.dot(surf.ns).clamp(-1.0, 1.0);
                let tan2 = ((1.0 - c * c) / (c * c)).max(0.0);
                Self { n0: surf.ns, n: ns, alpha2: (0.125 * tan2).min(1.0) }
            }
            _ => Self::NONE,
        }
    }

    /// The factor on the BSDF's value for light from world direction `wi`.
    #[inline]
    pub(crate) fn weight(self, wi: Vec3) -> f32 {
        if self.alpha2 < 0.0 {
            return 1.0;
        }
        let c0 = wi.dot(self.n0);
        if c0 * wi.dot(self.n) <= 0.0 {
            return 0.0;
        }
        let tan2 = ((1.0 - c0 * c0) / (c0 * c0)).max(0.0);
        2.0 / (1.0 + (1.0 + self.alpha2 * tan2).sqrt())
    }
}

/// The BSDF of a surface point for a viewer along `-d`, and the frame to evaluate it in
/// (sided as Mitsuba's: see the module's notes).
pub(crate) fn bsdf_frame<'w>(w: &'w World, ray: &Ray, hit: &Hit, surf: &Surface, ns: Vec3, d: Vec3) -> (Bsdf<'w>, ShadingFrame) {
    let prep = w.prepared(surf.material);
    let mat = material(w, surf.material);
    let textures = &w.scene.textures;
    let back = -d.dot(ns) < 0.0;
    let bsdf = prep.bsdf_at(textures, surf.uv);
    // (Anisotropic roughness is along ∂p/∂u, as Mitsuba's frame: its tangent is then the
    // surface's, else any.)
    let frame = |n: Vec3| match prep.anisotropic.then(|| w.uv_tangents(ray, hit)).flatten() {
        Some((dpdu, _)) => ShadingFrame::with_tangent(n, dpdu),
        None => ShadingFrame::new(n),
    };
    if !back {
        return (bsdf, frame(ns));
    }
    match &mat.sides {
        Sides::Back(_) => match &prep.back {
            Some(b) => (b.bsdf_at(textures, surf.uv), ShadingFrame::new(-ns)),
            None => (bsdf, frame(-ns)),
        },
        // (A dielectric's inside is told by the frame: never turned.)
        // (A mask's holes pass light either way: its two-sided surface turns as any.)
        Sides::Both if !bsdf.transmits() || bsdf.symmetric() || matches!(bsdf, Bsdf::Mask(_)) => (bsdf, frame(-ns)),
        _ if bsdf.symmetric() => (bsdf, frame(-ns)),
        _ => (bsdf, frame(ns)),
    }
}

/// The normal a light sample is weighed and drawn by at a surface with `bsdf` in `frame`
/// (see `lights::reach` and the environment's sampling): the frame's for a BSDF that only
/// reflects (it sends nothing below it), none (zero) for one that transmits or that the
/// user wrote, whose light may come from either side.
#[inline]
pub(crate) fn light_normal(bsdf: &Bsdf, frame: &ShadingFrame) -> Vec3 {
    if bsdf.transmits() {
        Vec3::ZERO
    } else {
        frame.n
    }
}

/// What `surf`, met by `r`, emits back along it.
pub(crate) fn emission_at(w: &World, r: &Ray, surf: &Surface) -> Vec3 {
    let mat = material(w, surf.material);
    if mat.emission.max_element() > 0.0 && r.dir.dot(surf.ng) < 0.0 {
        emitted(w, mat, surf.uv)
    } else {
        Vec3::ZERO
    }
}

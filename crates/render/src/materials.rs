//! The scene's materials prepared for the path tracer: what can be computed once per
//! material (rough plastic's coating tables, plastics' sampling weights and diffuse Fresnel
//! reflectance, the user's BSDFs) kept beside it, and [`PreparedMaterial::bsdf_at`] resolving the
//! textures of a surface point into a [`Bsdf`].

use crate::bsdf::microfacet::{fresnel_diffuse_reflectance, Microfacet};
use crate::bsdf::{
    plastic_spec_weight, Blend, Bsdf, BsdfModel, Conductor, Dielectric, Diffuse, DiffuseGlossy, Mask, MetallicRoughness, Plastic,
    Principled, RoughPlastic, RoughPlasticTables, ThinDielectric,
};
use crate::texture::sample;
use glam::{Vec2, Vec3, Vec4};
use lucent_scene::{Bsdf as Desc, ColorTex, FloatTex, Material, Scene, Texture};
use std::sync::Arc;

/// One material, prepared.
#[derive(Debug, Clone)]
pub struct PreparedMaterial {
    /// The model (the scene's, or its Phong terms read as one).
    pub desc: Desc,
    /// The back's model, for `Sides::Back`.
    pub back: Option<Box<PreparedMaterial>>,
    /// Rough plastic's tables.
    tables: Option<std::sync::Arc<RoughPlasticTables>>,
    /// Plastics' specular sampling weight.
    spec_weight: f32,
    /// Smooth plastic's diffuse Fresnel reflectance from inside.
    fdr_int: f32,
    /// A BSDF of the user's own, replacing `desc`.
    pub custom: Option<Arc<dyn BsdfModel>>,
    /// A blend's two BSDFs, prepared.
    blend: Option<Box<(PreparedMaterial, PreparedMaterial)>>,
    /// A mask's BSDF, prepared.
    masked: Option<Box<PreparedMaterial>>,
    /// The material reads texture coordinates (a texture anywhere in it: see
    /// [`lucent_scene::Material::uses_uv`]); analytic shapes compute them only then.
    pub(crate) uses_uv: bool,
    /// A layer has anisotropic roughness: the shading frame's tangent is then ∂p/∂u.
    pub(crate) anisotropic: bool,
}

/// The mean of a texture's texels (linear), for Mitsuba's `mean()` of a bitmap.
fn texture_mean(t: &Texture) -> Vec4 {
    let (w, h) = (t.width as usize, t.height as usize);
    if w == 0 || h == 0 {
        return Vec4::ONE;
    }
    let mut sum = glam::DVec4::ZERO;
    for y in 0..h {
        for x in 0..w {
            sum += t.texel_at(x, y).as_dvec4();
        }
    }
    (sum / (w * h) as f64).as_vec4()
}

/// A colour parameter's mean over the surface.
fn color_mean(c: &ColorTex, textures: &[Texture]) -> Vec3 {
    match c {
        ColorTex::Image { tex, scale, .. } => textures.get(*tex as usize).map_or(Vec3::ONE, |t| texture_mean(t).truncate()) * *scale,
        _ => c.mean_guess(),
    }
}

impl PreparedMaterial {
    /// Prepares one BSDF (`scene` for its textures).
    #[must_use]
    pub fn new(desc: Desc, scene: &Scene) -> Self {
        let mut p = Self {
            desc,
            back: None,
            tables: None,
            spec_weight: 0.5,
            fdr_int: 0.0,
            custom: None,
            blend: None,
            masked: None,
            uses_uv: false,
            anisotropic: false,
        };
        p.anisotropic = p.desc.anisotropic();
        if let Desc::Blend { first, second, .. } = &p.desc {
            p.blend = Some(Box::new((Self::new((**first).clone(), scene), Self::new((**second).clone(), scene))));
        }
        if let Desc::Mask { inner, .. } = &p.desc {
            p.masked = Some(Box::new(Self::new((**inner).clone(), scene)));
        }
        if let Desc::Plastic { diffuse, specular, eta, rough, .. } = &p.desc {
            p.spec_weight = plastic_spec_weight(color_mean(diffuse, &scene.textures), color_mean(specular, &scene.textures));
            p.fdr_int = fresnel_diffuse_reflectance(1.0 / eta);
            if let Some((dist, alpha)) = rough {
                p.tables = Some(RoughPlasticTables::new(&Microfacet::new(*dist, *alpha), *eta));
            }
        }
        p
    }

    /// Prepares a scene material (its back too).
    #[must_use]
    pub fn of(m: &Material, scene: &Scene) -> Self {
        let mut p = Self::new(m.bsdf().into_owned(), scene);
        p.uses_uv = m.uses_uv();
        if let lucent_scene::Sides::Back(b) = &m.sides {
            p.back = Some(Box::new(Self::new((**b).clone(), scene)));
        }
        p
    }

    /// The BSDF at texture coordinates `uv` (`textures`: the scene's).
    #[must_use]
    pub fn bsdf_at<'a>(&'a self, textures: &'a [Texture], uv: Vec2) -> Bsdf<'a> {
        if let Some(c) = &self.custom {
            return Bsdf::Custom(c.as_ref(), uv);
        }
        let color = |c: &ColorTex| eval_color(c, textures, uv);
        let float = |f: &FloatTex| eval_float(f, textures, uv);
        let rough = |r: &Option<lucent_scene::Rough>| {
            r.as_ref().map(|r| match &r.alpha_v {
                None => Microfacet::new(r.dist, float(&r.alpha)),
                Some(v) => Microfacet::anisotropic(r.dist, float(&r.alpha), float(v)),
            })
        };
        match &self.desc {
            Desc::Diffuse { reflectance } => Bsdf::Diffuse(Diffuse { r: color(reflectance) }),
            Desc::Conductor { eta, k, specular, rough: r } => {
                Bsdf::Conductor(Conductor { eta: *eta, k: *k, spec: color(specular), mf: rough(r) })
            }
            Desc::Dielectric { eta, reflectance, transmittance, rough: r } => {
                Bsdf::Dielectric(Dielectric { eta: *eta, refl: color(reflectance), trans: color(transmittance), mf: rough(r) })
            }
            Desc::ThinDielectric { eta, reflectance, transmittance } => {
                Bsdf::Thin(ThinDielectric { eta: *eta, refl: color(reflectance), trans: color(transmittance) })
            }
            Desc::Plastic { diffuse, specular, eta, nonlinear, rough: r } => match (r, &self.tables) {
                (Some((dist, alpha)), Some(tables)) => Bsdf::RoughPlastic(RoughPlastic {
                    diffuse: color(diffuse),
                    spec: color(specular),
                    nonlinear: *nonlinear,
                    spec_weight: self.spec_weight,
                    mf: Microfacet::new(*dist, *alpha),
                    tables,
                }),
                _ => Bsdf::Plastic(Plastic {
                    diffuse: color(diffuse),
                    spec: color(specular),
                    eta: *eta,
                    nonlinear: *nonlinear,
                    spec_weight: self.spec_weight,
                    fdr_int: self.fdr_int,
                }),
            },
            Desc::MetallicRoughness { base_color, metallic, roughness, transmission, ior } => {
                let r = float(roughness).clamp(0.0, 1.0);
                let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
                Bsdf::MetallicRoughness(MetallicRoughness {
                    base: color(base_color),
                    metallic: float(metallic).clamp(0.0, 1.0),
                    mf: Microfacet::new(lucent_scene::Distribution::Ggx, r * r),
                    transmission: float(transmission).clamp(0.0, 1.0),
                    f0: if f0.is_finite() { f0 } else { 0.04 },
                })
            }
            Desc::Principled(p) => {
                let has = p.has;
                let on = |on: bool, f: &FloatTex| if on { float(f) } else { 0.0 };
                let (r, an) = (float(&p.roughness), on(has.anisotropic, &p.anisotropic));
                // (Burley's α = roughness², stretched by the anisotropy, as Mitsuba's
                // `calc_dist_params`.)
                let r2 = r * r;
                let (ax, ay) = if has.anisotropic {
                    let aspect = (1.0 - 0.9 * an).sqrt();
                    ((r2 / aspect).max(0.001), (r2 * aspect).max(0.001))
                } else {
                    (r2.max(0.001), r2.max(0.001))
                };
                let gloss = float(&p.clearcoat_gloss);
                let cc_alpha = 0.1 * (1.0 - gloss) + 0.001 * gloss;
                Bsdf::Principled(Principled {
                    base: color(&p.base_color),
                    roughness: r,
                    metallic: on(has.metallic, &p.metallic),
                    spec_trans: on(has.spec_trans, &p.spec_trans),
                    spec_tint: on(has.spec_tint, &p.spec_tint),
                    sheen: on(has.sheen, &p.sheen),
                    sheen_tint: on(has.sheen_tint, &p.sheen_tint),
                    flatness: on(has.flatness, &p.flatness),
                    clearcoat: on(has.clearcoat, &p.clearcoat),
                    cc_alpha,
                    cc_ln: Principled::cc_ln_of(cc_alpha),
                    mf: Microfacet::anisotropic(lucent_scene::Distribution::Ggx, ax, ay),
                    eta: p.eta,
                    rates: p.rates,
                    has,
                })
            }
            Desc::DiffuseGlossy { diffuse, specular, alpha } => Bsdf::DiffuseGlossy(DiffuseGlossy {
                kd: color(diffuse),
                ks: *specular,
                mf: Microfacet::new(lucent_scene::Distribution::Beckmann, *alpha),
            }),
            Desc::Blend { weight, .. } => match &self.blend {
                Some(parts) => Bsdf::Blend(Blend { weight: float(weight).clamp(0.0, 1.0), parts: [&parts.0, &parts.1], textures, uv }),
                None => Bsdf::Diffuse(Diffuse { r: Vec3::ZERO }),
            },
            Desc::Mask { opacity, .. } => match &self.masked {
                Some(inner) => Bsdf::Mask(Mask { opacity: float(opacity).clamp(0.0, 1.0), inner: &**inner, textures, uv }),
                None => Bsdf::Diffuse(Diffuse { r: Vec3::ZERO }),
            },
        }
    }

    /// The diffuse reflectance of a model that has one (its diffuse, base or blended
    /// colour: what Mitsuba's `eval_diffuse_reflectance` returns for those); `None` for
    /// conductors and dielectrics, the user's BSDFs and Phong materials read as them.
    #[must_use]
    pub fn diffuse_reflectance(&self, textures: &[Texture], uv: Vec2) -> Option<Vec3> {
        let diffuse_like = |d: &Desc| {
            matches!(
                d,
                Desc::Diffuse { .. }
                    | Desc::Plastic { .. }
                    | Desc::Principled(_)
                    | Desc::MetallicRoughness { .. }
                    | Desc::DiffuseGlossy { .. }
                    | Desc::Blend { .. }
                    | Desc::Mask { .. }
            )
        };
        (self.custom.is_none() && diffuse_like(&self.desc)).then(|| self.albedo(textures, uv))
    }

    /// The albedo a denoiser's AOV shows: the diffuse or base colour where there is one,
    /// else the specular factor.
    #[must_use]
    pub fn albedo(&self, textures: &[Texture], uv: Vec2) -> Vec3 {
        let color = |c: &ColorTex| eval_color(c, textures, uv);
        match &self.desc {
            Desc::Diffuse { reflectance } => color(reflectance),
            Desc::Conductor { specular, .. } => color(specular),
            Desc::Dielectric { transmittance, .. } | Desc::ThinDielectric { transmittance, .. } => color(transmittance),
            Desc::Plastic { diffuse, .. } | Desc::DiffuseGlossy { diffuse, .. } => color(diffuse),
            Desc::MetallicRoughness { base_color, .. } => color(base_color),
            Desc::Principled(p) => color(&p.base_color),
            Desc::Blend { weight, .. } => match &self.blend {
                Some(parts) => {
                    let w = eval_float(weight, textures, uv).clamp(0.0, 1.0);
                    parts.0.albedo(textures, uv) * (1.0 - w) + parts.1.albedo(textures, uv) * w
                }
                None => Vec3::ZERO,
            },
            Desc::Mask { .. } => self.masked.as_ref().map_or(Vec3::ZERO, |m| m.albedo(textures, uv)),
        }
    }
}

impl crate::bsdf::Nested for PreparedMaterial {
    fn bsdf_at<'a>(&'a self, textures: &'a [Texture], uv: Vec2) -> Bsdf<'a> {
        PreparedMaterial::bsdf_at(self, textures, uv)
    }
}

/// A colour parameter at `uv`.
pub(crate) fn eval_color(c: &ColorTex, textures: &[Texture], uv: Vec2) -> Vec3 {
    match c {
        ColorTex::Const(v) => *v,
        ColorTex::Image { tex, scale, to_uv } => match textures.get(*tex as usize) {
            Some(t) => sample(t, to_uv.transform_point2(uv)).truncate() * *scale,
            None => *scale,
        },
        ColorTex::Checker { a, b, to_uv } => {
            if ColorTex::checker_even(to_uv, uv) {
                *a
            } else {
                *b
            }
        }
    }
}

/// A scalar parameter at `uv`.
pub(crate) fn eval_float(f: &FloatTex, textures: &[Texture], uv: Vec2) -> f32 {
    match f {
        FloatTex::Const(v) => *v,
        FloatTex::Image { tex, channel, scale, to_uv } => match textures.get(*tex as usize) {
            Some(t) => sample(t, to_uv.transform_point2(uv))[(*channel).min(3) as usize] * scale,
            None => *scale,
        },
        FloatTex::Checker { a, b, to_uv } => {
            if ColorTex::checker_even(to_uv, uv) {
                *a
            } else {
                *b
            }
        }
    }
}

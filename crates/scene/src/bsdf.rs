//! Physically based materials as plain data: which BSDF a surface has and its parameters,
//! as the scene file gave them. `lucent_render::bsdf` evaluates them.
//!
//! The models and their parameters follow Mitsuba 3's plugins of the same names (so that
//! a Mitsuba scene means the same thing to lucent), plus the glTF 2.0 metallic-roughness
//! BRDF (glTF 2.0 specification, Appendix B) and the reading of MTL's `Kd Ks Ns` below.
//!
//! How each importer maps its materials (documented here, in one place):
//!
//! - **Mitsuba XML**: one to one (`diffuse`, `conductor`, `roughconductor`, `dielectric`,
//!   `roughdielectric`, `thindielectric`, `plastic`, `roughplastic`, `twosided`), with
//!   Mitsuba's defaults.
//! - **glTF**: [`Bsdf::MetallicRoughness`] with the base colour, metallic and roughness
//!   factors and textures (roughness from the green channel, metallic from the blue of
//!   `metallicRoughnessTexture`), `KHR_materials_transmission` (factor and red channel of
//!   its texture) and `KHR_materials_ior` (1.5 by default); emission, normal maps and alpha
//!   are [`Material`](crate::Material) fields. BART scenes' Phong terms
//!   (`extras.aff_fm`) are read as MTL's below, since they are the source's own.
//! - **MTL**: with the PBR extension's `Pr` or `Pm`: [`Bsdf::MetallicRoughness`] (base
//!   colour `Kd`/`map_Kd`, roughness `Pr`, metallic `Pm`, transmission `1 − d` or `Tr`,
//!   index `Ni`). Otherwise: a transparent material (`d < 1`, `Tr > 0`, `Tf`, or `illum`
//!   4, 6, 7) is a smooth [`Bsdf::Dielectric`] of index `Ni` (a
//!   [`Bsdf::ThinDielectric`] of index 1.5 when `Ni` ≤ 1: a surface with no bending, such
//!   as a window pane), transmittance `Tf` or `1 − d`; any other is
//!   [`Bsdf::DiffuseGlossy`]: the Lambertian `Kd` plus, when `Ks` is not black, a
//!   microfacet lobe of reflectance `Ks` whose roughness comes from the Phong exponent
//!   `Ns` by Walter et al.'s correspondence α = √(2 / (Ns + 2)) (Beckmann). `illum` 3 and 5
//!   ("reflection on") change nothing for the path tracer: a glossy lobe of exponent `Ns`
//!   is already the reflection. The Whitted fields of the material are read as before.
//! - **PLY** and built-in scenes without a [`Material::bsdf`](crate::Material): see
//!   [`Bsdf::from_phong`].

use glam::{Affine2, Vec2, Vec3};

/// A colour parameter that may vary over the surface.
#[derive(Clone, Debug, PartialEq)]
pub enum ColorTex {
    /// The same everywhere.
    Const(Vec3),
    /// Texture `tex` of [`Scene::textures`](crate::Scene) (linear RGB after decoding)
    /// times `scale`, at texture coordinates `to_uv · uv`.
    Image {
        /// Texture index.
        tex: u32,
        /// Factor.
        scale: Vec3,
        /// Texture-coordinate transform.
        to_uv: Affine2,
    },
    /// Mitsuba's `checkerboard`: `a` where ⌊2u⌋ + ⌊2v⌋ is even (of `to_uv · uv`), else `b`.
    Checker {
        /// First colour.
        a: Vec3,
        /// Second colour.
        b: Vec3,
        /// Texture-coordinate transform.
        to_uv: Affine2,
    },
}

impl ColorTex {
    /// A constant grey.
    #[must_use]
    pub fn grey(v: f32) -> Self {
        Self::Const(Vec3::splat(v))
    }

    /// The mean value over the surface, as far as it is known without the texture (the
    /// factor for images; the checkerboard's mean): what Mitsuba's `mean()` gives for the
    /// lobe-sampling weights, with a texture's texels taken as 1.
    #[must_use]
    pub fn mean_guess(&self) -> Vec3 {
        match self {
            Self::Const(c) => *c,
            Self::Image { scale, .. } => *scale,
            Self::Checker { a, b, .. } => (*a + *b) * 0.5,
        }
    }

    /// Which checker colour `uv` falls on (`true`: `a`).
    #[must_use]
    pub fn checker_even(to_uv: &Affine2, uv: Vec2) -> bool {
        let p = to_uv.transform_point2(uv);
        let s = (p.x * 2.0).floor() as i64 + (p.y * 2.0).floor() as i64;
        s.rem_euclid(2) == 0
    }
}

/// A scalar parameter that may vary over the surface.
#[derive(Clone, Debug, PartialEq)]
pub enum FloatTex {
    /// The same everywhere.
    Const(f32),
    /// Channel `channel` (0 red .. 3 alpha) of texture `tex`, linear, times `scale`.
    Image {
        /// Texture index.
        tex: u32,
        /// Channel.
        channel: u8,
        /// Factor.
        scale: f32,
        /// Texture-coordinate transform.
        to_uv: Affine2,
    },
    /// `a` and `b` in a checkerboard of 2 × 2 squares per unit of (u, v) after `to_uv`
    /// (Mitsuba's `checkerboard` read as a number: as [`ColorTex::Checker`]).
    Checker {
        /// The value of the squares of even index sum.
        a: f32,
        /// The other squares' value.
        b: f32,
        /// Texture-coordinate transform.
        to_uv: Affine2,
    },
}

impl FloatTex {
    /// The factor (the value where there is no texture; a checkerboard's mean).
    #[must_use]
    pub fn factor(&self) -> f32 {
        match self {
            Self::Const(v) => *v,
            Self::Image { scale, .. } => *scale,
            Self::Checker { a, b, .. } => 0.5 * (a + b),
        }
    }
}

/// A microfacet distribution (Walter, Marschner, Li and Torrance, "Microfacet Models for
/// Refraction through Rough Surfaces", EGSR 2007).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Distribution {
    /// Beckmann (Mitsuba's default).
    #[default]
    Beckmann,
    /// GGX / Trowbridge-Reitz.
    Ggx,
}

/// Roughness of a microfacet surface: the distribution and its α, isotropic or along the
/// surface's two texture directions (Mitsuba's `alpha_u`, `alpha_v`).
#[derive(Clone, Debug, PartialEq)]
pub struct Rough {
    /// Distribution.
    pub dist: Distribution,
    /// α (the RMS slope for Beckmann), clamped to at least 10⁻⁴ as Mitsuba does; with
    /// `alpha_v`, α along the tangent ∂p/∂u.
    pub alpha: FloatTex,
    /// α along the bitangent (anisotropic roughness); `None`: isotropic.
    pub alpha_v: Option<FloatTex>,
}

impl Rough {
    /// Isotropic roughness `alpha` of distribution `dist`.
    #[must_use]
    pub fn isotropic(dist: Distribution, alpha: FloatTex) -> Self {
        Self { dist, alpha, alpha_v: None }
    }
}

/// Which BSDF a surface has.
#[derive(Clone, Debug, PartialEq)]
pub enum Bsdf {
    /// Lambertian reflection (Mitsuba `diffuse`).
    Diffuse {
        /// Albedo.
        reflectance: ColorTex,
    },
    /// A metal (Mitsuba `conductor`, `roughconductor`): Fresnel reflection of a complex
    /// index `eta + i k` (relative to the outside), times `specular`.
    Conductor {
        /// Real part of the relative index, per channel.
        eta: Vec3,
        /// Imaginary part, per channel.
        k: Vec3,
        /// Factor on the reflectance.
        specular: ColorTex,
        /// `None`: a smooth mirror.
        rough: Option<Rough>,
    },
    /// The interface between two dielectrics (Mitsuba `dielectric`, `roughdielectric`).
    Dielectric {
        /// Relative index: inside over outside.
        eta: f32,
        /// Factor on reflection.
        reflectance: ColorTex,
        /// Factor on transmission.
        transmittance: ColorTex,
        /// `None`: smooth.
        rough: Option<Rough>,
    },
    /// A thin sheet of dielectric, reflections inside it summed, light passing straight
    /// through (Mitsuba `thindielectric`).
    ThinDielectric {
        /// Relative index of the sheet.
        eta: f32,
        /// Factor on reflection.
        reflectance: ColorTex,
        /// Factor on transmission.
        transmittance: ColorTex,
    },
    /// A diffuse base under a dielectric coating, with the coating's internal scattering
    /// (Weidlich and Wilkie 2007, as Mitsuba `plastic`, `roughplastic`).
    Plastic {
        /// Albedo of the base.
        diffuse: ColorTex,
        /// Factor on the coating's reflection.
        specular: ColorTex,
        /// Relative index of the coating.
        eta: f32,
        /// Mitsuba's `nonlinear`: internal scattering darkens and saturates the base.
        nonlinear: bool,
        /// `None`: a smooth coating. Rough coatings take a constant α (as Mitsuba's).
        rough: Option<(Distribution, f32)>,
    },
    /// The glTF 2.0 metallic-roughness BRDF (Appendix B of the specification), with
    /// `KHR_materials_transmission` (thin-walled) and `KHR_materials_ior`.
    MetallicRoughness {
        /// Base colour.
        base_color: ColorTex,
        /// Metallic (0 dielectric .. 1 metal).
        metallic: FloatTex,
        /// Perceptual roughness (α = roughness²).
        roughness: FloatTex,
        /// Fraction of the dielectric base that is transmitted.
        transmission: FloatTex,
        /// Index of refraction of the dielectric.
        ior: f32,
    },
    /// A mix of two BSDFs, `(1 − weight)·first + weight·second` (Mitsuba's `blendbsdf`).
    Blend {
        /// The second BSDF's share, in [0, 1] (clamped).
        weight: FloatTex,
        /// The first BSDF.
        first: Box<Bsdf>,
        /// The second BSDF.
        second: Box<Bsdf>,
    },
    /// A surface that exists with probability `opacity`: elsewhere light passes straight
    /// through (a null, delta transmission), as Mitsuba's `mask` BSDF. (Mitsuba's path
    /// tracer, and so lucent's, lets only sampled paths through: shadow rays stop at it.)
    Mask {
        /// Probability of meeting the surface, in [0, 1] (clamped).
        opacity: FloatTex,
        /// The surface's BSDF.
        inner: Box<Bsdf>,
    },
    /// Mitsuba 3's `principled` BSDF (Burley's Disney BSDF, 2012 and 2015, as Mitsuba
    /// writes it: its parameters in [`Principled`]).
    Principled(Box<Principled>),
    /// MTL's diffuse + specular terms read physically: Lambertian `diffuse` plus a
    /// Beckmann microfacet lobe of reflectance `specular` (no Fresnel: MTL's `Ks` is the
    /// reflectance) and roughness `alpha`.
    DiffuseGlossy {
        /// Lambertian albedo (`Kd`).
        diffuse: ColorTex,
        /// Reflectance of the glossy lobe (`Ks`).
        specular: Vec3,
        /// Beckmann α.
        alpha: f32,
    },
}

/// The parameters of Mitsuba 3's `principled` BSDF (all in [0, 1] but the index and the
/// sampling rates), with Mitsuba's defaults; a lobe whose parameter the file does not set
/// (or sets to the number 0) is off, as in Mitsuba.
#[derive(Clone, Debug, PartialEq)]
pub struct Principled {
    /// Base colour (default 0.5).
    pub base_color: ColorTex,
    /// Roughness of the main specular lobes (default 0.5; α = roughness²).
    pub roughness: FloatTex,
    /// Anisotropy of the main specular lobes.
    pub anisotropic: FloatTex,
    /// Metallic weight.
    pub metallic: FloatTex,
    /// Specular transmission weight (the rough dielectric lobe).
    pub spec_trans: FloatTex,
    /// Tint of the dielectric reflection toward the base colour.
    pub spec_tint: FloatTex,
    /// Sheen weight.
    pub sheen: FloatTex,
    /// Tint of the sheen toward the base colour.
    pub sheen_tint: FloatTex,
    /// Blend of the diffuse lobe toward Hanrahan-Krueger's fake subsurface.
    pub flatness: FloatTex,
    /// Clearcoat weight.
    pub clearcoat: FloatTex,
    /// Clearcoat glossiness (its GTR1 α from 0.1 to 0.001).
    pub clearcoat_gloss: FloatTex,
    /// Relative index (from `eta`, or from `specular` s as 2 / (1 − √(0.08 s)) − 1).
    pub eta: f32,
    /// Sampling rates: diffuse, main specular, clearcoat.
    pub rates: [f32; 3],
    /// Which lobes are on: anisotropy, metallic, transmission, specular tint, sheen,
    /// sheen tint, flatness, clearcoat.
    pub has: PrincipledLobes,
}

/// Which optional parts of a [`Principled`] BSDF are on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[allow(clippy::struct_excessive_bools)]
pub struct PrincipledLobes {
    /// Anisotropic roughness.
    pub anisotropic: bool,
    /// Metallic Fresnel.
    pub metallic: bool,
    /// The transmission lobe.
    pub spec_trans: bool,
    /// Tinted dielectric reflection.
    pub spec_tint: bool,
    /// Sheen.
    pub sheen: bool,
    /// Tinted sheen.
    pub sheen_tint: bool,
    /// Fake subsurface.
    pub flatness: bool,
    /// Clearcoat.
    pub clearcoat: bool,
}

/// How the back of a surface scatters.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum Sides {
    /// The front's BSDF seen from either side (Mitsuba's `twosided` with one BSDF; what
    /// OBJ, PLY and glTF surfaces are).
    #[default]
    Both,
    /// Only the front scatters; light meeting the back of a reflecting surface is absorbed
    /// (a bare BSDF in Mitsuba). Dielectrics handle both sides themselves.
    Front,
    /// The back has a BSDF of its own (`twosided` with two BSDFs).
    Back(Box<Bsdf>),
}

/// A normal map (tangent space: x along ∂p/∂u, z along the shading normal), as glTF's
/// `normalTexture` or Mitsuba's `normalmap`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalMap {
    /// Texture index (linear).
    pub tex: u32,
    /// Scale of the map's x and y.
    pub scale: f32,
    /// Texture coordinates to the map's (after the texture's own transform).
    pub to_uv: glam::Affine2,
    /// Mitsuba's conventions: y along n × x (glTF's: along ∂p/∂v), and a bent normal that
    /// turns the surface away from the viewer has its tangent part reversed (Mitsuba's
    /// `flip_invalid_normals`, after Schüssler et al. 2017).
    pub mitsuba: bool,
    /// The texture is a height field (Mitsuba's `bumpmap`): the gradient of its
    /// luminance times `scale` tilts ∂p/∂u and ∂p/∂v along the normal, whose cross
    /// product is the bent normal. Else it holds normals (x, y, z as (c + 1)/2).
    pub height: bool,
}

impl NormalMap {
    /// A glTF normal map of texture `tex`, its x and y scaled by `scale`.
    #[must_use]
    pub fn gltf(tex: u32, scale: f32) -> Self {
        Self { tex, scale, to_uv: glam::Affine2::IDENTITY, mitsuba: false, height: false }
    }
}

/// Which parts of a surface exist (glTF `alphaMode`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Alpha {
    /// Everywhere.
    #[default]
    Opaque,
    /// Where the alpha (the base colour's: the factor times the texture's alpha channel)
    /// is at least `cutoff`. glTF's `BLEND` is read as a mask at 0.5.
    Mask {
        /// Threshold.
        cutoff: f32,
        /// Texture whose alpha channel multiplies the factor.
        tex: Option<u32>,
        /// Alpha factor.
        factor: f32,
    },
}

/// Named indices of refraction Mitsuba knows (`int_ior`/`ext_ior` by name), at 589 nm.
pub const NAMED_IOR: &[(&str, f32)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

/// The index of refraction of a name in [`NAMED_IOR`] (case-insensitive).
#[must_use]
pub fn named_ior(name: &str) -> Option<f32> {
    let n = name.to_ascii_lowercase();
    NAMED_IOR.iter().find(|(k, _)| *k == n).map(|&(_, v)| v)
}

/// Mitsuba 3's named conductors in its RGB variants: `(name, eta, k)`, the values Mitsuba
/// 3.9.1 `llvm_ad_rgb` derives from its spectral tables (read from `mi.traverse` of a
/// `conductor` with each `material`; measured data by Palik and others, as Mitsuba
/// credits them). `none` is a perfect mirror.
pub const NAMED_CONDUCTORS: &[(&str, [f32; 3], [f32; 3])] = &[
    ("none", [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
    ("a-C", [2.94405, 2.22714, 1.96816], [0.887465, 0.799299, 0.81529]),
    ("Ag", [0.155276, 0.116728, 0.138388], [4.82835, 3.12222, 2.1469]),
    ("Al", [1.6575, 0.880405, 0.521244], [9.22381, 6.2695, 4.837]),
    ("AlAs", [3.6053, 3.23294, 2.21632], [0.000679437, 0.0, 0.00751271]),
    ("AlSb", [0.0, 4.13937, 4.66925], [0.0, 0.0940091, 1.30057]),
    ("Au", [0.143036, 0.375307, 1.44205], [3.983, 2.38556, 1.60336]),
    ("Be", [4.18501, 3.18503, 2.78406], [3.83547, 3.01012, 2.86899]),
    ("Cr", [4.36967, 2.91651, 1.6549], [5.20655, 4.23131, 3.7547]),
    ("CsI", [2.1449, 1.70232, 1.66243], [0.0, 0.0, 0.0]),
    ("Cu", [0.201005, 0.92375, 1.10222], [3.91326, 2.45305, 2.14209]),
    ("Cu_palik", [0.213229, 0.919715, 1.10241], [3.92187, 2.45733, 2.13658]),
    ("Cu2O", [3.55177, 2.94987, 2.75188], [0.114207, 0.193897, 0.606134]),
    ("CuO", [3.24754, 2.44781, 2.21022], [0.52109, 0.570031, 0.722179]),
    ("d-C", [2.70872, 2.31883, 2.2289], [0.0, 0.0, 0.0]),
    ("Hg", [2.39894, 1.44003, 0.90957], [6.32759, 4.37192, 3.42176]),
    ("HgTe", [4.77904, 3.2312, 2.6599], [1.63161, 1.58081, 1.72929]),
    ("Ir", [3.0863, 2.08219, 1.61791], [5.59215, 4.06709, 3.26731]),
    ("K", [0.0640432, 0.0464098, 0.0381849], [2.1042, 1.34894, 0.913126]),
    ("Li", [0.265791, 0.195618, 0.220949], [3.54015, 2.31112, 1.66861]),
    ("MgO", [2.08958, 1.65072, 1.59488], [0.0, 0.0, 0.0]),
    ("Mo", [4.48397, 3.52513, 2.77631], [4.11144, 3.42083, 3.15061]),
    ("Na_palik", [0.0602694, 0.0561409, 0.0619884], [3.17927, 2.11249, 1.57904]),
    ("Nb", [3.42007, 2.79009, 2.39563], [3.44139, 2.73767, 2.57975]),
    ("Ni_palik", [2.3673, 1.66337, 1.46708], [4.49881, 3.05015, 2.34544]),
    ("Rh", [2.58579, 1.86022, 1.55426], [6.78226, 4.70299, 3.97607]),
    ("Se", [4.05831, 2.84294, 2.82085], [0.75405, 0.638444, 0.521808]),
    ("SiC", [3.17234, 2.52597, 2.47937], [0.0, 0.0, 0.0]),
    ("SnTe", [4.52425, 1.98164, 1.28159], [0.0, 0.0, 0.0]),
    ("Ta", [2.06272, 2.39294, 2.62793], [2.40836, 1.74149, 1.94703]),
    ("Te", [7.39023, 4.4821, 2.63711], [3.25602, 3.52706, 3.29205]),
    ("ThF4", [1.83071, 1.44223, 1.38765], [0.0, 0.0, 0.0]),
    ("TiC", [3.70053, 2.83742, 2.58229], [3.26564, 2.35159, 2.17279]),
    ("TiN", [1.64845, 1.15052, 1.37982], [3.36833, 1.9435, 1.10207]),
    ("TiO2", [3.45661, 2.80174, 2.90517], [0.0, 0.0, 0.0]),
    ("VC", [3.65757, 2.75274, 2.53267], [3.0683, 2.19869, 1.96319]),
    ("V_palik", [4.27758, 3.51295, 2.76107], [3.4913, 2.88945, 3.11152]),
    ("VN", [2.8656, 2.11919, 1.94009], [3.03224, 2.05612, 1.61631]),
    ("W", [4.37082, 3.30025, 2.99841], [3.50064, 2.60487, 2.27323]),
];

/// The complex index `(eta, k)` of a named conductor (Mitsuba's names; a `_palik` suffix
/// names the same data where Mitsuba has both).
#[must_use]
pub fn named_conductor(name: &str) -> Option<(Vec3, Vec3)> {
    let find = |n: &str| NAMED_CONDUCTORS.iter().find(|(k, _, _)| *k == n).map(|(_, e, k)| (Vec3::from(*e), Vec3::from(*k)));
    find(name).or_else(|| name.strip_suffix("_palik").and_then(find))
}

/// Walter et al.'s Beckmann α for a Phong exponent: α = √(2 / (n + 2)).
#[must_use]
pub fn phong_to_alpha(n: f32) -> f32 {
    (2.0 / (n.max(0.0) + 2.0)).sqrt()
}

/// What Whitted's shading reads of a material (see [`Bsdf::whitted_terms`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WhittedTerms {
    /// Diffuse colour.
    pub diffuse: Vec3,
    /// Diffuse texture.
    pub diffuse_tex: Option<u32>,
    /// Highlight colour.
    pub specular: Vec3,
    /// Phong exponent.
    pub shininess: f32,
    /// Mirror reflectance.
    pub reflect: Vec3,
    /// Transmittance.
    pub transmit: Vec3,
    /// Index of refraction.
    pub ior: f32,
    /// Fresnel-weighted.
    pub fresnel: bool,
}

impl Default for WhittedTerms {
    fn default() -> Self {
        Self {
            diffuse: Vec3::ZERO,
            diffuse_tex: None,
            specular: Vec3::ZERO,
            shininess: 32.0,
            reflect: Vec3::ZERO,
            transmit: Vec3::ZERO,
            ior: 1.5,
            fresnel: false,
        }
    }
}

impl Bsdf {
    /// Whether the BSDF reads texture coordinates (a texture of any of its parameters).
    #[must_use]
    pub fn uses_uv(&self) -> bool {
        let c = |t: &ColorTex| !matches!(t, ColorTex::Const(_));
        let f = |t: &FloatTex| !matches!(t, FloatTex::Const(_));
        let r = |t: &Option<Rough>| t.as_ref().is_some_and(|r| f(&r.alpha) || r.alpha_v.as_ref().is_some_and(f));
        match self {
            Self::Diffuse { reflectance } => c(reflectance),
            Self::Conductor { specular, rough, .. } => c(specular) || r(rough),
            Self::Dielectric { reflectance, transmittance, rough, .. } => c(reflectance) || c(transmittance) || r(rough),
            Self::ThinDielectric { reflectance, transmittance, .. } => c(reflectance) || c(transmittance),
            Self::Plastic { diffuse, specular, .. } => c(diffuse) || c(specular),
            Self::MetallicRoughness { base_color, metallic, roughness, transmission, .. } => {
                c(base_color) || f(metallic) || f(roughness) || f(transmission)
            }
            Self::DiffuseGlossy { diffuse, .. } => c(diffuse),
            Self::Principled(p) => {
                c(&p.base_color)
                    || [
                        &p.roughness,
                        &p.anisotropic,
                        &p.metallic,
                        &p.spec_trans,
                        &p.spec_tint,
                        &p.sheen,
                        &p.sheen_tint,
                        &p.flatness,
                        &p.clearcoat,
                        &p.clearcoat_gloss,
                    ]
                    .into_iter()
                    .any(f)
            }
            Self::Blend { weight, first, second } => f(weight) || first.uses_uv() || second.uses_uv(),
            Self::Mask { opacity, inner } => f(opacity) || inner.uses_uv(),
        }
    }

    /// Whether any of its microfacet layers has anisotropic roughness (its shading frame
    /// then follows the surface's ∂p/∂u).
    #[must_use]
    pub fn anisotropic(&self) -> bool {
        let r = |t: &Option<Rough>| t.as_ref().is_some_and(|r| r.alpha_v.is_some());
        match self {
            Self::Conductor { rough, .. } | Self::Dielectric { rough, .. } => r(rough),
            Self::Principled(p) => p.has.anisotropic,
            Self::Blend { first, second, .. } => first.anisotropic() || second.anisotropic(),
            Self::Mask { inner, .. } => inner.anisotropic(),
            _ => false,
        }
    }

    /// A rough Phong-like reading for Whitted's fields from this BSDF (the inverse
    /// direction, for scenes whose materials are physically based, e.g. Mitsuba's): the
    /// diffuse colour, mirror reflectance, transmittance, index and Phong exponent that
    /// Whitted's shading approximates it with.
    #[must_use]
    pub fn whitted_terms(&self) -> WhittedTerms {
        let mean = |c: &ColorTex| c.mean_guess();
        let tex = |c: &ColorTex| match c {
            ColorTex::Image { tex, .. } => Some(*tex),
            _ => None,
        };
        let alpha_exp = |a: f32| (2.0 / (a * a).max(1e-6) - 2.0).clamp(1.0, 4096.0);
        let w = WhittedTerms::default();
        match self {
            Self::Diffuse { reflectance } => WhittedTerms { diffuse: mean(reflectance), diffuse_tex: tex(reflectance), ..w },
            Self::Conductor { eta, k, specular, rough } => {
                // Reflectance at normal incidence: ((η−1)² + k²) / ((η+1)² + k²).
                let f0 = ((*eta - 1.0) * (*eta - 1.0) + *k * *k) / ((*eta + 1.0) * (*eta + 1.0) + *k * *k);
                let c = f0 * mean(specular);
                let a = rough.as_ref().map_or(0.0, |r| r.alpha.factor());
                WhittedTerms {
                    specular: c,
                    shininess: alpha_exp(a.max(0.01)),
                    reflect: if a < 0.2 { c } else { Vec3::ZERO },
                    diffuse: if a >= 0.2 { c * 0.5 } else { Vec3::ZERO },
                    ..w
                }
            }
            Self::Dielectric { eta, transmittance, .. } => {
                WhittedTerms { transmit: mean(transmittance), ior: *eta, fresnel: true, specular: Vec3::splat(0.5), shininess: 256.0, ..w }
            }
            Self::ThinDielectric { transmittance, .. } => {
                WhittedTerms { transmit: mean(transmittance), ior: 1.0, fresnel: true, specular: Vec3::splat(0.5), shininess: 256.0, ..w }
            }
            Self::Plastic { diffuse, rough, .. } => WhittedTerms {
                diffuse: mean(diffuse),
                diffuse_tex: tex(diffuse),
                specular: Vec3::splat(0.2),
                shininess: alpha_exp(rough.map_or(0.02, |r| r.1)),
                ..w
            },
            Self::MetallicRoughness { base_color, metallic, roughness, transmission, ior } => {
                let (b, m, r) = (mean(base_color), metallic.factor().clamp(0.0, 1.0), roughness.factor().clamp(0.02, 1.0));
                WhittedTerms {
                    diffuse: b * (1.0 - m),
                    diffuse_tex: tex(base_color),
                    specular: Vec3::splat(0.04 * (1.0 - m)) + b * m,
                    shininess: (2.0 / (r * r * r * r) - 2.0).clamp(1.0, 4096.0),
                    reflect: b * m,
                    transmit: Vec3::splat(transmission.factor()),
                    fresnel: transmission.factor() > 0.0,
                    ior: *ior,
                }
            }
            Self::DiffuseGlossy { diffuse, specular, alpha } => {
                WhittedTerms { diffuse: mean(diffuse), diffuse_tex: tex(diffuse), specular: *specular, shininess: alpha_exp(*alpha), ..w }
            }
            Self::Principled(p) => {
                let (b, m, r) = (mean(&p.base_color), p.metallic.factor().clamp(0.0, 1.0), p.roughness.factor().clamp(0.02, 1.0));
                let t = p.spec_trans.factor().clamp(0.0, 1.0) * (1.0 - m);
                WhittedTerms {
                    diffuse: b * (1.0 - m) * (1.0 - t),
                    diffuse_tex: tex(&p.base_color),
                    specular: Vec3::splat(0.04 * (1.0 - m)) + b * m,
                    shininess: (2.0 / (r * r * r * r) - 2.0).clamp(1.0, 4096.0),
                    reflect: b * m,
                    transmit: Vec3::splat(t),
                    fresnel: t > 0.0,
                    ior: p.eta,
                }
            }
            Self::Mask { opacity, inner } => {
                let t = inner.whitted_terms();
                let a = opacity.factor().clamp(0.0, 1.0);
                WhittedTerms { transmit: t.transmit * a + Vec3::splat(1.0 - a), ..t }
            }
            Self::Blend { weight, first, second } => {
                // The two readings mixed (the first's texture and index kept).
                let (a, b, t) = (first.whitted_terms(), second.whitted_terms(), weight.factor().clamp(0.0, 1.0));
                let mix = |x: Vec3, y: Vec3| x * (1.0 - t) + y * t;
                WhittedTerms {
                    diffuse: mix(a.diffuse, b.diffuse),
                    diffuse_tex: a.diffuse_tex.or(b.diffuse_tex),
                    specular: mix(a.specular, b.specular),
                    shininess: a.shininess * (1.0 - t) + b.shininess * t,
                    reflect: mix(a.reflect, b.reflect),
                    transmit: mix(a.transmit, b.transmit),
                    ior: if t < 0.5 { a.ior } else { b.ior },
                    fresnel: a.fresnel || b.fresnel,
                }
            }
        }
    }
}

//! The BSDFs by content:
//! - against Mitsuba 3's own plugins: `eval` at 64 direction pairs, and the delta lobes'
//!   directions and weights from `sample`, recorded by `tools/mitsuba/bsdf_values.py`
//!   (`tests/data/mitsuba/bsdf/values.json`; no Mitsuba needed here);
//! - sampling against the pdf: a chi-square test per BSDF and viewing direction (the
//!   histogram of sampled directions over a (cos θ, φ) grid against the pdf integrated
//!   over each cell, as Mitsuba's and pbrt's test suites do), and every sample's weight and
//!   pdf equal to `eval / pdf` and `pdf()` at its direction;
//! - white furnace: the albedo from sampling equals the albedo from `eval` integrated
//!   over the sphere, and closed forms where energy is conserved;
//! - reciprocity: f(wo, wi) = f(wi, wo) for reflection, and radiance's (η_i/η_o)² for
//!   transmission.

use glam::{Affine2, Vec2, Vec3};
use lucent_render::bsdf::Bsdf;
use lucent_render::materials::PreparedMaterial;
use lucent_scene::{Bsdf as Desc, ColorTex, Distribution, FloatTex, Rough, Scene};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::Value;
use std::f64::consts::PI;

fn rgb(r: f32, g: f32, b: f32) -> ColorTex {
    ColorTex::Const(Vec3::new(r, g, b))
}

fn conductor(name: &str) -> (Vec3, Vec3) {
    lucent_scene::bsdf::named_conductor(name).expect("named conductor")
}

fn rough(dist: Distribution, alpha: f32) -> Option<Rough> {
    Some(Rough::isotropic(dist, FloatTex::Const(alpha)))
}

/// Anisotropic roughness: `ax` along the frame's x, `ay` along y.
fn aniso(dist: Distribution, ax: f32, ay: f32) -> Option<Rough> {
    Some(Rough { dist, alpha: FloatTex::Const(ax), alpha_v: Some(FloatTex::Const(ay)) })
}

/// Mitsuba's configurations in `values.json`, as lucent descriptions.
fn mitsuba_equivalent(name: &str) -> Desc {
    let air = lucent_scene::bsdf::named_ior("air").expect("air");
    let bk7 = lucent_scene::bsdf::named_ior("bk7").expect("bk7");
    let pp = lucent_scene::bsdf::named_ior("polypropylene").expect("polypropylene");
    match name {
        "diffuse" => Desc::Diffuse { reflectance: rgb(0.7, 0.5, 0.2) },
        "conductor_au" => {
            let (eta, k) = conductor("Au");
            Desc::Conductor { eta: eta / air, k: k / air, specular: ColorTex::grey(1.0), rough: None }
        }
        "conductor_none_tinted" => Desc::Conductor { eta: Vec3::ZERO, k: Vec3::ONE, specular: rgb(0.9, 0.6, 0.3), rough: None },
        "roughconductor_cu_ggx" => {
            let (eta, k) = conductor("Cu");
            Desc::Conductor { eta: eta / air, k: k / air, specular: ColorTex::grey(1.0), rough: rough(Distribution::Ggx, 0.3) }
        }
        "roughconductor_al_beckmann" => {
            let (eta, k) = conductor("Al");
            Desc::Conductor { eta: eta / air, k: k / air, specular: ColorTex::grey(1.0), rough: rough(Distribution::Beckmann, 0.2) }
        }
        "dielectric" => {
            Desc::Dielectric { eta: bk7 / air, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::grey(1.0), rough: None }
        }
        "dielectric_water" => {
            Desc::Dielectric { eta: 1.3330 / air, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::grey(1.0), rough: None }
        }
        "roughdielectric_ggx" => Desc::Dielectric {
            eta: 1.5,
            reflectance: ColorTex::grey(1.0),
            transmittance: ColorTex::grey(1.0),
            rough: rough(Distribution::Ggx, 0.3),
        },
        "roughdielectric_beckmann" => Desc::Dielectric {
            eta: 1.33,
            reflectance: ColorTex::grey(1.0),
            transmittance: ColorTex::grey(1.0),
            rough: rough(Distribution::Beckmann, 0.1),
        },
        "thindielectric" => Desc::ThinDielectric { eta: 1.5, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::grey(1.0) },
        "plastic" => {
            Desc::Plastic { diffuse: rgb(0.3, 0.5, 0.7), specular: ColorTex::grey(1.0), eta: pp / air, nonlinear: false, rough: None }
        }
        "plastic_nonlinear" => {
            Desc::Plastic { diffuse: rgb(0.8, 0.2, 0.1), specular: ColorTex::grey(1.0), eta: 1.7 / air, nonlinear: true, rough: None }
        }
        "roughplastic_ggx" => Desc::Plastic {
            diffuse: rgb(0.2, 0.6, 0.4),
            specular: ColorTex::grey(1.0),
            eta: pp / air,
            nonlinear: false,
            rough: Some((Distribution::Ggx, 0.2)),
        },
        "roughplastic_beckmann" => Desc::Plastic {
            diffuse: rgb(0.6, 0.3, 0.2),
            specular: ColorTex::grey(1.0),
            eta: pp / air,
            nonlinear: true,
            rough: Some((Distribution::Beckmann, 0.1)),
        },
        "roughconductor_al_aniso_ggx" => {
            let (eta, k) = conductor("Al");
            Desc::Conductor { eta: eta / air, k: k / air, specular: ColorTex::grey(1.0), rough: aniso(Distribution::Ggx, 0.05, 0.3) }
        }
        "roughconductor_cu_aniso_beckmann" => {
            let (eta, k) = conductor("Cu");
            Desc::Conductor { eta: eta / air, k: k / air, specular: ColorTex::grey(1.0), rough: aniso(Distribution::Beckmann, 0.4, 0.1) }
        }
        "roughdielectric_aniso_ggx" => Desc::Dielectric {
            eta: 1.5,
            reflectance: ColorTex::grey(1.0),
            transmittance: ColorTex::grey(1.0),
            rough: aniso(Distribution::Ggx, 0.1, 0.35),
        },
        "principled_default" => principled(|_| {}),
        "principled_reflective" => principled(|p| {
            p.base_color = rgb(0.8, 0.5, 0.3);
            p.anisotropic = FloatTex::Const(0.5);
            p.metallic = FloatTex::Const(0.3);
            p.spec_tint = FloatTex::Const(0.4);
            p.sheen = FloatTex::Const(0.5);
            p.sheen_tint = FloatTex::Const(0.5);
            p.flatness = FloatTex::Const(0.3);
            p.clearcoat = FloatTex::Const(0.8);
            p.clearcoat_gloss = FloatTex::Const(0.6);
        }),
        "principled_transmissive" => principled(|p| {
            p.base_color = rgb(0.9, 0.8, 0.6);
            p.roughness = FloatTex::Const(0.3);
            p.metallic = FloatTex::Const(0.2);
            p.spec_trans = FloatTex::Const(0.7);
            p.eta = 1.4;
            p.spec_tint = FloatTex::Const(0.3);
            p.clearcoat = FloatTex::Const(0.5);
        }),
        other => panic!("no lucent equivalent for {other}"),
    }
}

/// Mitsuba's principled BSDF with its defaults, changed by `set`; a lobe is on where its
/// parameter is not 0 (as Mitsuba's flags).
fn principled(set: impl FnOnce(&mut lucent_scene::Principled)) -> Desc {
    let zero = FloatTex::Const(0.0);
    let mut p = lucent_scene::Principled {
        base_color: ColorTex::grey(0.5),
        roughness: FloatTex::Const(0.5),
        anisotropic: zero.clone(),
        metallic: zero.clone(),
        spec_trans: zero.clone(),
        spec_tint: zero.clone(),
        sheen: zero.clone(),
        sheen_tint: zero.clone(),
        flatness: zero.clone(),
        clearcoat: zero.clone(),
        clearcoat_gloss: zero,
        eta: 1.5,
        rates: [1.0, 1.0, 1.0],
        has: lucent_scene::PrincipledLobes::default(),
    };
    set(&mut p);
    let on = |f: &FloatTex| *f != FloatTex::Const(0.0);
    p.has = lucent_scene::PrincipledLobes {
        anisotropic: on(&p.anisotropic),
        metallic: on(&p.metallic),
        spec_trans: on(&p.spec_trans),
        spec_tint: on(&p.spec_tint),
        sheen: on(&p.sheen),
        sheen_tint: on(&p.sheen_tint),
        flatness: on(&p.flatness),
        clearcoat: on(&p.clearcoat),
    };
    Desc::Principled(Box::new(p))
}

fn v3(v: &Value) -> Vec3 {
    let a = v.as_array().expect("array");
    Vec3::new(a[0].as_f64().unwrap_or(0.0) as f32, a[1].as_f64().unwrap_or(0.0) as f32, a[2].as_f64().unwrap_or(0.0) as f32)
}

fn close(a: Vec3, b: Vec3, rel: f32, abs: f32) -> bool {
    (a - b).abs().cmple(b.abs() * rel + Vec3::splat(abs)).all()
}

#[test]
fn bsdfs_match_mitsuba() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/bsdf/values.json");
    let data: Value = serde_json::from_str(&std::fs::read_to_string(path).expect("values.json")).expect("json");
    let wos: Vec<Vec3> = data["pairs"]["wo"].as_array().expect("wo").iter().map(v3).collect();
    let wis: Vec<Vec3> = data["pairs"]["wi"].as_array().expect("wi").iter().map(v3).collect();
    let scene = Scene::default();
    let mut checked = 0;
    for (name, entry) in data["bsdfs"].as_object().expect("bsdfs") {
        let prep = PreparedMaterial::new(mitsuba_equivalent(name), &scene);
        let bsdf = prep.bsdf_at(&[], Vec2::ZERO);
        for (k, (wo, wi)) in wos.iter().zip(&wis).enumerate() {
            let want = v3(&entry["eval"][k]);
            let got = bsdf.eval(wo.normalize(), wi.normalize());
            // Rough plastic's coating tables are integrals Mitsuba and lucent compute by
            // their own quadratures: 0.3% apart at most.
            assert!(close(got, want, 3e-3, 1e-5), "{name} pair {k}: wo {wo} wi {wi}: lucent {got}, Mitsuba {want}");
            // (The densities of the principled BSDF, written after Mitsuba's: the others
            // differ from Mitsuba's where the value is zero, e.g. Mitsuba's rough plastic
            // gives a density below the surface.)
            if let Some(want) = entry["pdf"].get(k).and_then(Value::as_f64).filter(|_| name.starts_with("principled")) {
                let got = bsdf.pdf(wo.normalize(), wi.normalize());
                let want = want as f32;
                assert!(
                    (got - want).abs() <= 3e-3 * want.abs() + 1e-5,
                    "{name} pair {k}: wo {wo} wi {wi}: density {got}, Mitsuba's {want}"
                );
            }
            checked += 1;
        }
        // Delta lobes: the same direction, weight × probability (the lobe's value) and
        // probability for the same lobe choice.
        for s in entry["samples"].as_array().expect("samples") {
            let u = s["u"].as_f64().unwrap_or(0.0) as f32;
            for (j, wo) in s["wo"].as_array().expect("wo").iter().map(v3).enumerate() {
                if !s["delta"][j].as_bool().unwrap_or(false) {
                    continue;
                }
                let wo = wo.normalize();
                let (w_want, pdf_want, wi_want) = (v3(&s["weight"][j]), s["pdf"][j].as_f64().unwrap_or(0.0) as f32, v3(&s["wi"][j]));
                let bs = bsdf.sample(wo, u, (0.37, 0.61)).unwrap_or_else(|| panic!("{name}: no sample for {wo}"));
                assert!(bs.delta, "{name}: {wo} sampled a non-delta lobe where Mitsuba sampled a delta one");
                assert!((bs.wi - wi_want).abs().max_element() < 1e-4, "{name}: {wo}: direction {} against {wi_want}", bs.wi);
                assert!(
                    close(bs.weight * bs.pdf, w_want * pdf_want, 1e-3, 1e-6),
                    "{name}: {wo}: value {} against {}",
                    bs.weight * bs.pdf,
                    w_want * pdf_want
                );
                assert!((bs.pdf - pdf_want).abs() < 1e-4, "{name}: {wo}: probability {} against {pdf_want}", bs.pdf);
                checked += 1;
            }
        }
    }
    assert!(checked > 17 * 64, "{checked}");
}

/// Every BSDF the tests below exercise, with a name (non-delta lobes for the chi-square
/// test; all for the furnace).
fn all_bsdfs() -> Vec<(&'static str, Desc)> {
    let (au_eta, au_k) = conductor("Au");
    vec![
        ("diffuse", Desc::Diffuse { reflectance: rgb(0.8, 0.6, 0.3) }),
        (
            "rough conductor ggx",
            Desc::Conductor { eta: au_eta, k: au_k, specular: ColorTex::grey(1.0), rough: rough(Distribution::Ggx, 0.25) },
        ),
        (
            "rough conductor beckmann",
            Desc::Conductor { eta: au_eta, k: au_k, specular: ColorTex::grey(1.0), rough: rough(Distribution::Beckmann, 0.4) },
        ),
        (
            "anisotropic rough conductor ggx",
            Desc::Conductor { eta: au_eta, k: au_k, specular: ColorTex::grey(1.0), rough: aniso(Distribution::Ggx, 0.08, 0.4) },
        ),
        (
            "anisotropic rough conductor beckmann",
            Desc::Conductor { eta: au_eta, k: au_k, specular: ColorTex::grey(1.0), rough: aniso(Distribution::Beckmann, 0.5, 0.15) },
        ),
        (
            "anisotropic rough dielectric beckmann",
            Desc::Dielectric {
                eta: 1.5,
                reflectance: ColorTex::grey(1.0),
                transmittance: ColorTex::grey(1.0),
                rough: aniso(Distribution::Beckmann, 0.15, 0.45),
            },
        ),
        (
            "rough dielectric ggx",
            Desc::Dielectric {
                eta: 1.5,
                reflectance: ColorTex::grey(1.0),
                transmittance: ColorTex::grey(1.0),
                rough: rough(Distribution::Ggx, 0.3),
            },
        ),
        (
            "rough dielectric beckmann",
            Desc::Dielectric {
                eta: 1.33,
                reflectance: ColorTex::grey(1.0),
                transmittance: ColorTex::grey(1.0),
                rough: rough(Distribution::Beckmann, 0.2),
            },
        ),
        ("plastic", Desc::Plastic { diffuse: rgb(0.5, 0.4, 0.3), specular: ColorTex::grey(1.0), eta: 1.49, nonlinear: false, rough: None }),
        (
            "rough plastic ggx",
            Desc::Plastic {
                diffuse: rgb(0.5, 0.4, 0.3),
                specular: ColorTex::grey(1.0),
                eta: 1.49,
                nonlinear: false,
                rough: Some((Distribution::Ggx, 0.3)),
            },
        ),
        (
            "rough plastic beckmann",
            Desc::Plastic {
                diffuse: rgb(0.2, 0.7, 0.3),
                specular: ColorTex::grey(1.0),
                eta: 1.6,
                nonlinear: true,
                rough: Some((Distribution::Beckmann, 0.15)),
            },
        ),
        (
            "metallic-roughness",
            Desc::MetallicRoughness {
                base_color: rgb(0.9, 0.5, 0.2),
                metallic: FloatTex::Const(0.3),
                roughness: FloatTex::Const(0.5),
                transmission: FloatTex::Const(0.0),
                ior: 1.5,
            },
        ),
        (
            "metallic-roughness transmission",
            Desc::MetallicRoughness {
                base_color: rgb(0.9, 0.9, 0.8),
                metallic: FloatTex::Const(0.0),
                roughness: FloatTex::Const(0.4),
                transmission: FloatTex::Const(0.7),
                ior: 1.5,
            },
        ),
        ("diffuse glossy", Desc::DiffuseGlossy { diffuse: rgb(0.4, 0.3, 0.2), specular: Vec3::splat(0.4), alpha: 0.2 }),
        // (Every lobe but transmission: with it, Mitsuba's lobe choice depends on the Fresnel
        // term of the sampled facet while its density takes the half vector's, so sampling
        // does not follow the density, in Mitsuba as here.)
        (
            "principled without transmission",
            Desc::Principled(Box::new(lucent_scene::Principled {
                base_color: rgb(0.8, 0.5, 0.3),
                roughness: FloatTex::Const(0.5),
                anisotropic: FloatTex::Const(0.5),
                metallic: FloatTex::Const(0.3),
                spec_trans: FloatTex::Const(0.0),
                spec_tint: FloatTex::Const(0.4),
                sheen: FloatTex::Const(0.5),
                sheen_tint: FloatTex::Const(0.5),
                flatness: FloatTex::Const(0.3),
                clearcoat: FloatTex::Const(0.8),
                clearcoat_gloss: FloatTex::Const(0.6),
                eta: 1.5,
                rates: [1.0, 1.0, 1.0],
                has: lucent_scene::PrincipledLobes {
                    anisotropic: true,
                    metallic: true,
                    spec_trans: false,
                    spec_tint: true,
                    sheen: true,
                    sheen_tint: true,
                    flatness: true,
                    clearcoat: true,
                },
            })),
        ),
        (
            "blend of diffuse and rough conductor",
            Desc::Blend {
                weight: FloatTex::Const(0.35),
                first: Box::new(Desc::Diffuse { reflectance: rgb(0.7, 0.4, 0.2) }),
                second: Box::new(Desc::Conductor {
                    eta: Vec3::new(0.2, 0.9, 1.1),
                    k: Vec3::new(3.9, 2.4, 2.2),
                    specular: ColorTex::grey(1.0),
                    rough: rough(Distribution::Ggx, 0.3),
                }),
            },
        ),
        (
            "blend of rough plastic and smooth conductor",
            Desc::Blend {
                weight: FloatTex::Const(0.5),
                first: Box::new(Desc::Plastic {
                    diffuse: rgb(0.3, 0.5, 0.7),
                    specular: ColorTex::grey(1.0),
                    eta: 1.5,
                    nonlinear: false,
                    rough: Some((Distribution::Beckmann, 0.2)),
                }),
                second: Box::new(Desc::Conductor {
                    eta: Vec3::splat(0.2),
                    k: Vec3::splat(3.0),
                    specular: ColorTex::grey(1.0),
                    rough: None,
                }),
            },
        ),
        (
            "textured diffuse (checker)",
            Desc::Diffuse { reflectance: ColorTex::Checker { a: Vec3::splat(0.2), b: Vec3::splat(0.9), to_uv: Affine2::IDENTITY } },
        ),
    ]
}

/// The regularised lower incomplete gamma function P(a, x) (series, or Lentz's continued
/// fraction for the complement), for the chi-square distribution's tail.
fn gamma_p(a: f64, x: f64) -> f64 {
    let ln_gamma = |z: f64| -> f64 {
        // Lanczos (g = 7, n = 9).
        let c = [
            0.999_999_999_999_809_9,
            676.520_368_121_885_1,
            -1_259.139_216_722_402_8,
            771.323_428_777_653_1,
            -176.615_029_162_140_6,
            12.507_343_278_686_905,
            -0.138_571_095_265_720_12,
            9.984_369_578_019_572e-6,
            1.505_632_735_149_311_6e-7,
        ];
        let z = z - 1.0;
        let mut s = c[0];
        for (i, &ci) in c.iter().enumerate().skip(1) {
            s += ci / (z + i as f64);
        }
        let t = z + 7.5;
        0.5 * (2.0 * PI).ln() + (z + 0.5) * t.ln() - t + s.ln()
    };
    if x <= 0.0 {
        return 0.0;
    }
    if x < a + 1.0 {
        let (mut sum, mut term, mut n) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        sum * (-x + a * x.ln() - ln_gamma(a)).exp()
    } else {
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / 1e-300;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < 1e-300 {
                d = 1e-300;
            }
            c = b + an / c;
            if c.abs() < 1e-300 {
                c = 1e-300;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        1.0 - (-x + a * x.ln() - ln_gamma(a)).exp() * h
    }
}

fn sphere_dir(cos_t: f64, phi: f64) -> Vec3 {
    let s = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, cos_t as f32)
}

/// The chi-square test of one BSDF at one viewing direction: returns the p-value.
fn chi2(bsdf: &Bsdf, wo: Vec3, rng: &mut Pcg64, name: &str) -> f64 {
    const N_COS: usize = 20;
    const N_PHI: usize = 40;
    const SAMPLES: usize = 300_000;
    let mut observed = vec![0f64; N_COS * N_PHI];
    let cell = |d: Vec3| -> usize {
        let c = ((f64::from(d.z) + 1.0) * 0.5 * N_COS as f64).clamp(0.0, N_COS as f64 - 1.0) as usize;
        let mut phi = f64::from(d.y).atan2(f64::from(d.x));
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let p = (phi / (2.0 * PI) * N_PHI as f64).clamp(0.0, N_PHI as f64 - 1.0) as usize;
        c * N_PHI + p
    };
    for _ in 0..SAMPLES {
        let u = rng.random::<f32>();
        let u2 = (rng.random::<f32>(), rng.random::<f32>());
        let Some(s) = bsdf.sample(wo, u, u2) else { continue };
        if s.delta {
            continue;
        }
        // The sample's own numbers agree with the functions.
        let pdf = bsdf.pdf(wo, s.wi);
        assert!((pdf - s.pdf).abs() <= 1e-3 * pdf.max(1e-3), "{name}: pdf {} against pdf() {pdf} at {}", s.pdf, s.wi);
        let f = bsdf.eval(wo, s.wi);
        assert!(close(s.weight * s.pdf, f, 2e-3, 1e-6), "{name}: weight × pdf {} against eval {f}", s.weight * s.pdf);
        observed[cell(s.wi)] += 1.0;
    }
    // Expected counts: the pdf integrated over each cell by a midpoint rule in (θ, φ)
    // (dω = sin θ dθ dφ; θ rather than cos θ, in which the lobes peaked at the poles are
    // too narrow for a grid).
    let mut expected = vec![0f64; N_COS * N_PHI];
    const SUB_T: usize = 64;
    const SUB_PHI: usize = 6;
    for c in 0..N_COS {
        let (c0, c1) = (-1.0 + 2.0 * c as f64 / N_COS as f64, -1.0 + 2.0 * (c + 1) as f64 / N_COS as f64);
        let (t_hi, t_lo) = (c0.clamp(-1.0, 1.0).acos(), c1.clamp(-1.0, 1.0).acos());
        let dt = (t_hi - t_lo) / SUB_T as f64;
        for p in 0..N_PHI {
            let mut sum = 0.0;
            for i in 0..SUB_T {
                let t = t_lo + (i as f64 + 0.5) * dt;
                for j in 0..SUB_PHI {
                    let ph = 2.0 * PI * (p as f64 + (j as f64 + 0.5) / SUB_PHI as f64) / N_PHI as f64;
                    sum += f64::from(bsdf.pdf(wo, sphere_dir(t.cos(), ph))) * t.sin() * dt;
                }
            }
            expected[c * N_PHI + p] = sum / SUB_PHI as f64 * (2.0 * PI / N_PHI as f64) * SAMPLES as f64;
        }
    }
    // Cells expecting fewer than 5 are pooled.
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut chi, mut dof, mut pool_e, mut pool_o) = (0.0, 0usize, 0.0, 0.0);
    for &i in &order {
        if expected[i] == 0.0 {
            assert!(observed[i] == 0.0, "{name}: {} samples where the pdf is zero (cell {i})", observed[i]);
            continue;
        }
        if expected[i] < 5.0 || pool_e > 0.0 && pool_e < 5.0 {
            pool_e += expected[i];
            pool_o += observed[i];
            continue;
        }
        chi += (observed[i] - expected[i]).powi(2) / expected[i];
        dof += 1;
    }
    if std::env::var_os("LUCENT_CHI2_DEBUG").is_some() {
        let mut worst: Vec<usize> = (0..expected.len()).collect();
        worst.sort_by(|&a, &b| {
            let d = |i: usize| (observed[i] - expected[i]).powi(2) / expected[i].max(1e-9);
            d(b).total_cmp(&d(a))
        });
        for &i in worst.iter().take(8) {
            eprintln!("{name} {wo}: cell cos {} phi {}: observed {} expected {:.1}", i / N_PHI, i % N_PHI, observed[i], expected[i]);
        }
    }
    if pool_e > 0.0 {
        chi += (pool_o - pool_e).powi(2) / pool_e;
        dof += 1;
    }
    1.0 - gamma_p((dof.saturating_sub(1)) as f64 / 2.0, chi / 2.0)
}

#[test]
fn sampling_follows_the_pdf_chi_square() {
    let scene = Scene::default();
    let mut rng = Pcg64::seed_from_u64(34);
    let wos =
        [Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.3, 0.9, 0.2).normalize(), Vec3::new(0.5, 0.2, -0.7).normalize()];
    let bsdfs = all_bsdfs();
    let tests = bsdfs.len() * wos.len();
    for (name, desc) in &bsdfs {
        let prep = PreparedMaterial::new(desc.clone(), &scene);
        let bsdf = prep.bsdf_at(&[], Vec2::new(0.3, 0.7));
        for wo in wos {
            if wo.z < 0.0 && (!bsdf.transmits() || bsdf.symmetric()) {
                continue;
            }
            let p = chi2(&bsdf, wo, &mut rng, name);
            // Bonferroni: a 1% level over all the tests.
            assert!(p > 0.01 / tests as f64, "{name} at wo {wo}: chi-square p-value {p:.2e}");
        }
    }
}

/// The albedo for `wo` two ways: the mean sample weight, and `eval` integrated over the
/// sphere by stratified uniform directions.
fn albedos(bsdf: &Bsdf, wo: Vec3, rng: &mut Pcg64) -> (Vec3, Vec3) {
    const N: usize = 400_000;
    let mut by_sampling = Vec3::ZERO;
    for _ in 0..N {
        // (Delta lobes are not part of `eval`.)
        if let Some(s) = bsdf.sample(wo, rng.random(), (rng.random(), rng.random())).filter(|s| !s.delta) {
            by_sampling += s.weight;
        }
    }
    let mut by_eval = glam::DVec3::ZERO;
    const G: usize = 600;
    for i in 0..G {
        for j in 0..G {
            let ct = -1.0 + 2.0 * (i as f64 + rng.random::<f64>()) / G as f64;
            let ph = 2.0 * PI * (j as f64 + rng.random::<f64>()) / G as f64;
            by_eval += bsdf.eval(wo, sphere_dir(ct, ph)).as_dvec3();
        }
    }
    (by_sampling / N as f32, (by_eval * (4.0 * PI / (G * G) as f64)).as_vec3())
}

#[test]
fn white_furnace() {
    let scene = Scene::default();
    let mut rng = Pcg64::seed_from_u64(35);
    let wo = Vec3::new(0.4, -0.2, 0.85).normalize();
    // Sampling and evaluation give the same albedo for every non-delta BSDF.
    for (name, desc) in all_bsdfs() {
        let prep = PreparedMaterial::new(desc, &scene);
        let bsdf = prep.bsdf_at(&[], Vec2::new(0.3, 0.7));
        let (a, b) = albedos(&bsdf, wo, &mut rng);
        assert!(close(a, b, 0.02, 2e-3), "{name}: albedo {a} by sampling, {b} by eval");
        assert!(a.max_element() <= 1.0 + 0.01, "{name}: albedo {a} above one");
    }
    // Closed forms: what conserves energy reflects all of it.
    let white = |desc: Desc| PreparedMaterial::new(desc, &scene);
    let one = |desc: Desc, tol: f32, name: &str, rng: &mut Pcg64| {
        let p = white(desc);
        let b = p.bsdf_at(&[], Vec2::ZERO);
        let mut sum = Vec3::ZERO;
        let n = 200_000;
        for _ in 0..n {
            if let Some(s) = b.sample(wo, rng.random(), (rng.random(), rng.random())) {
                sum += s.weight * if s.eta != 1.0 { s.eta * s.eta } else { 1.0 };
            }
        }
        let a = sum / n as f32;
        assert!((a - Vec3::ONE).abs().max_element() < tol, "{name}: albedo {a}, expected 1");
    };
    one(Desc::Diffuse { reflectance: ColorTex::grey(1.0) }, 1e-3, "white diffuse", &mut rng);
    one(Desc::Conductor { eta: Vec3::ZERO, k: Vec3::ONE, specular: ColorTex::grey(1.0), rough: None }, 1e-6, "mirror", &mut rng);
    one(
        Desc::ThinDielectric { eta: 1.5, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::grey(1.0) },
        1e-6,
        "thin dielectric",
        &mut rng,
    );
    // (Radiance entering a denser medium is compressed by 1/η²: the weights times η² of
    // the refracted ones sum to one.)
    one(
        Desc::Dielectric { eta: 1.5, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::grey(1.0), rough: None },
        1e-6,
        "smooth dielectric",
        &mut rng,
    );
    // A smooth-ish rough mirror loses only what single scattering's masking loses.
    one(
        Desc::Conductor { eta: Vec3::ZERO, k: Vec3::ONE, specular: ColorTex::grey(1.0), rough: rough(Distribution::Ggx, 0.05) },
        0.01,
        "GGX mirror, α 0.05",
        &mut rng,
    );
    one(
        Desc::Dielectric {
            eta: 1.5,
            reflectance: ColorTex::grey(1.0),
            transmittance: ColorTex::grey(1.0),
            rough: rough(Distribution::Ggx, 0.05),
        },
        0.01,
        "GGX dielectric, α 0.05",
        &mut rng,
    );
}

#[test]
fn reciprocity() {
    let scene = Scene::default();
    let mut rng = Pcg64::seed_from_u64(36);
    for (name, desc) in all_bsdfs() {
        let eta = match desc {
            Desc::Dielectric { eta, .. } => eta,
            _ => 1.0,
        };
        let prep = PreparedMaterial::new(desc, &scene);
        let b = prep.bsdf_at(&[], Vec2::new(0.3, 0.7));
        let mut checked = 0;
        for _ in 0..2000 {
            let rnd =
                |rng: &mut Pcg64| Vec3::new(rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5).normalize();
            let (wo, wi) = (rnd(&mut rng), rnd(&mut rng));
            if wo.z.abs() < 0.05 || wi.z.abs() < 0.05 {
                continue;
            }
            // (A symmetric BSDF is evaluated with the frame turned toward the viewer.)
            let eval = |a: Vec3, c: Vec3| if b.symmetric() && a.z < 0.0 { b.eval(-a, -c) } else { b.eval(a, c) };
            let f_oi = eval(wo, wi) / wi.z.abs();
            let f_io = eval(wi, wo) / wo.z.abs();
            // Transmission of radiance: f(wo, wi) (η on wi's side / η on wo's side)² = f(wi, wo).
            let scale = if wo.z * wi.z < 0.0 && eta != 1.0 {
                let side = |v: Vec3| if v.z > 0.0 { 1.0 } else { eta };
                (side(wi) / side(wo)).powi(2)
            } else {
                1.0
            };
            let lhs = f_oi * scale;
            assert!(close(lhs, f_io, 2e-3, 1e-6), "{name}: f({wo}, {wi}) = {f_oi} (× {scale}), f({wi}, {wo}) = {f_io}");
            checked += 1;
        }
        assert!(checked > 1000);
    }
}

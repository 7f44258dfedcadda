//! The path-traced, VPL, guide and denoised images, bit for bit: a 64-bit hash of every
//! pixel's f32 bits for a set of frames (the demo scene, Mitsuba's four reference scenes,
//! Sponza, the animated BART kitchen posed at two times), recorded before issue 57 moved
//! the renderer's files (one file per BSDF and light, the floor modules, the integrator
//! seam, the world split by concern) so that the move is shown to change no image. The
//! scalar path tracer stays the reference of the lane integrator (issue 58): these hashes
//! are its images.
//!
//! As `whitted_bits.rs`: recorded on this project's AVX-512 machine; every SIMD path must
//! give the scalar path's answers, so another CPU must give the same bits.

mod common;
use common::scene;
use lucent_accel::MeshOptions;
use lucent_render::{
    denoise, render, render_aovs, render_region, Camera, DenoiseSettings, Film, FilmAccumulator, Integrator, PathSettings, Region,
    RenderSettings, VplSettings, World,
};
use std::path::PathBuf;

/// FNV-1a over the pixels' bits.
fn hash_pixels(pixels: &[glam::Vec3]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for p in pixels {
        for c in p.to_array() {
            for b in c.to_bits().to_le_bytes() {
                h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    h
}

fn hash(f: &Film) -> u64 {
    hash_pixels(&f.pixels)
}

fn mitsuba(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba").join(name).join("scene.xml")
}

/// (name, hash) of every frame, in order.
fn frames() -> Vec<(String, u64)> {
    let (w, h) = (64, 48);
    let mut out = Vec::new();
    let mut worlds: Vec<(String, World, Camera)> = Vec::new();
    for name in ["cornell_box", "bunny", "envmap", "materials"] {
        let defines = [("scenes".to_string(), common::scenes_dir().display().to_string())];
        let sc = lucent_scene::load_mitsuba_with(&mitsuba(name), &defines).expect("scene");
        let cam = Camera::new(&sc.camera.expect("camera"), w, h);
        worlds.push((name.into(), World::new(sc, MeshOptions::default()).expect("world"), cam));
    }
    let demo = World::new(lucent_scene::demo_scene(), MeshOptions::default()).expect("demo");
    let (lo, hi) = demo.scene().bounds().expect("the demo has geometry");
    let cam = Camera::new(&demo.scene().camera.unwrap_or_else(|| lucent_render::framing_camera(lo, hi)), w, h);
    worlds.push(("demo".into(), demo, cam));
    // Sponza lit by a point and a spot light (its OBJ has none).
    let mut sc = lucent_scene::load(&scene("sponza_dabrovic/sponza.obj.gz")).expect("sponza");
    use lucent_scene::{Light, LightKind};
    let v = glam::Vec3::new;
    sc.lights.push(Light { kind: LightKind::Point { position: v(0.0, 8.0, 0.0) }, color: v(60.0, 55.0, 50.0), inverse_square: true });
    let spot = LightKind::Spot { position: v(8.0, 4.0, 0.0), direction: v(-1.0, -0.5, 0.0), inner: 0.3, outer: 0.5 };
    sc.lights.push(Light { kind: spot, color: v(80.0, 80.0, 90.0), inverse_square: true });
    let sponza = World::new(sc, MeshOptions::default()).expect("world");
    let cam = Camera::new(&lucent_scene::CameraDesc::from_view(&[-10.0, 2.5, 0.0, 0.0, 4.5, 0.0, 0.0, 1.0, 0.0, 70.0]), w, h);
    worlds.push(("sponza".into(), sponza, cam));
    let mut kitchen =
        World::new(lucent_scene::load(&scene("bart/kitchen/kitchen.gltf")).expect("kitchen"), MeshOptions::default()).expect("world");
    for t in [3.0, 11.5] {
        let desc = kitchen.set_time(t).expect("pose").expect("the kitchen has a camera");
        let cam = Camera::new(&desc, w, h);
        let film = path_render(&kitchen, &cam, &path_settings(w, h, 4, PathSettings::default()));
        out.push((format!("kitchen t {t} path 4"), hash(&film)));
        let vpl = Integrator::Vpl(VplSettings { count: 64, ..VplSettings::default() });
        let (film, _) = render(&kitchen, &cam, &RenderSettings { spp: 1, integrator: vpl, ..RenderSettings::new(w, h) }, &|_| {});
        out.push((format!("kitchen t {t} vpl"), hash(&film)));
    }
    for (name, world, cam) in &worlds {
        for (spp, sampling) in [(4, lucent_render::LightSampling::Mis), (2, lucent_render::LightSampling::Nee)] {
            let ps = PathSettings { sampling, max_depth: 8, ..PathSettings::default() };
            let film = path_render(world, cam, &path_settings(w, h, spp, ps));
            out.push((format!("{name} path {spp} {sampling:?}"), hash(&film)));
        }
        // Samples 2..5 of an 8-sample image as two regions, merged.
        let rs = path_settings(w, h, 8, PathSettings::default());
        let mut acc = FilmAccumulator::new(w, h);
        for r in [Region { x0: 0, y0: 0, x1: w, y1: h, s0: 2, s1: 3 }, Region { x0: 0, y0: 0, x1: w, y1: h, s0: 3, s1: 5 }] {
            acc.merge(render_region(world, cam, &rs, r, &|_| {}).0).expect("regions");
        }
        out.push((format!("{name} path regions"), hash(&acc.resolve(world.scene().background))));
        let vpl = Integrator::Vpl(VplSettings { count: 64, max_depth: 8, ..VplSettings::default() });
        let (film, _) = render(world, cam, &RenderSettings { spp: 2, integrator: vpl, ..RenderSettings::new(w, h) }, &|_| {});
        out.push((format!("{name} vpl"), hash(&film)));
        let aovs = render_aovs(world, cam, w, h);
        out.push((format!("{name} albedo"), hash(&aovs.albedo)));
        out.push((format!("{name} normal"), hash(&aovs.normal)));
        out.push((format!("{name} emission"), hash(&aovs.emission)));
        let depth: Vec<glam::Vec3> = aovs.depth.iter().map(|&d| glam::Vec3::splat(d)).collect();
        out.push((format!("{name} depth"), hash_pixels(&depth)));
        let noisy = path_render(world, cam, &path_settings(w, h, 4, PathSettings::default()));
        out.push((format!("{name} denoised"), hash(&denoise(&noisy, &aovs, &DenoiseSettings::default()))));
    }
    out
}

fn path_settings(w: u32, h: u32, spp: u32, ps: PathSettings) -> RenderSettings {
    RenderSettings { spp, integrator: Integrator::Path(ps), ..RenderSettings::new(w, h) }
}

/// A path-traced image by the lane path tracer, checked against the scalar one (the same
/// estimator, number for number: the same bits).
fn path_render(world: &World, cam: &Camera, rs: &RenderSettings) -> Film {
    let Integrator::Path(ps) = rs.integrator else { panic!("a path tracer's settings") };
    let lanes = render(world, cam, &RenderSettings { integrator: Integrator::Path(PathSettings { lanes: true, ..ps }), ..*rs }, &|_| {}).0;
    let scalar =
        render(world, cam, &RenderSettings { integrator: Integrator::Path(PathSettings { lanes: false, ..ps }), ..*rs }, &|_| {}).0;
    let bits = |f: &Film| f.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    let (a, b) = (bits(&lanes), bits(&scalar));
    let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "lanes and scalar differ in {differ} of {} pixels", a.len());
    lanes
}

/// Recorded at add57ab (before issue 57), on the AVX-512 machine; unchanged by issue 57's
/// moves. Re-recorded once since, when the sampling warps (cosine-weighted hemisphere,
/// disk, sphere, cone) began to take their sines and cosines from `lanes::sin_cos` (a
/// polynomial within 4 ulp of the library's) for the lane path tracer: a deliberate change
/// of the last bits of sampled directions (the Whitted images, which use no warp, kept
/// theirs; the path tracer still meets Mitsuba's references, tests/mitsuba.rs). The
/// environment map's MIS frames were re-recorded when its light samples took the
/// compensated density (Karlík et al. 2019; its NEE-only frame kept its bits), and the
/// materials scene's frames (path, VPL, albedo, denoised) when its emitters without a BSDF
/// stopped reflecting light (Mitsuba gives them a black diffuse one).
const WANT: &[(&str, u64)] = &[
    ("kitchen t 3 path 4", 0x83b856d8e31c9e83),
    ("kitchen t 3 vpl", 0xb3b8c428fa06ce32),
    ("kitchen t 11.5 path 4", 0x3124b89358f05c39),
    ("kitchen t 11.5 vpl", 0x88711f60fbe10652),
    ("cornell_box path 4 Mis", 0x98c46103ef4ce212),
    ("cornell_box path 2 Nee", 0x0afe278234481488),
    ("cornell_box path regions", 0x076568845f33a86d),
    ("cornell_box vpl", 0x238a568db6dc6b65),
    ("cornell_box albedo", 0x9694e37c6c877fba),
    ("cornell_box normal", 0xfe35653ea91f3c1c),
    ("cornell_box emission", 0x4da068f166621af5),
    ("cornell_box depth", 0x0f03beac25ede846),
    ("cornell_box denoised", 0x9c8ac837c6e28fc6),
    ("bunny path 4 Mis", 0xf1c0a418aecfe200),
    ("bunny path 2 Nee", 0x42264796ed03d741),
    ("bunny path regions", 0xd32090d53d311ca7),
    ("bunny vpl", 0x79d0dc5cd5d6da3d),
    ("bunny albedo", 0x324aa08dd3f1c665),
    ("bunny normal", 0xb69f29bc7f26d7a7),
    ("bunny emission", 0xbe7134315f056325),
    ("bunny depth", 0x060d5f6099bf0695),
    ("bunny denoised", 0x31645ee5c0837993),
    ("envmap path 4 Mis", 0xba02f021667895f7),
    ("envmap path 2 Nee", 0x80cf975df3b6869b),
    ("envmap path regions", 0xed7d74a1e7335852),
    ("envmap vpl", 0xf3652366442c1141),
    ("envmap albedo", 0x7d26983ca5882037),
    ("envmap normal", 0x7903662bf7148234),
    ("envmap emission", 0xbe7134315f056325),
    ("envmap depth", 0xabb4439c866cc22f),
    ("envmap denoised", 0xf8e1aacd4c9b691f),
    ("materials path 4 Mis", 0x7f779c9813d94c0a),
    ("materials path 2 Nee", 0x71b12286ec1cf5aa),
    ("materials path regions", 0x901107551dc45723),
    ("materials vpl", 0x2f5773fb79cb4da7),
    ("materials albedo", 0xaf48f2b44867082a),
    ("materials normal", 0x9c0ec9c208f467fc),
    ("materials emission", 0x50841d900dd33dae),
    ("materials depth", 0x3efa70933ed747ce),
    ("materials denoised", 0x5006584afe0c5233),
    ("demo path 4 Mis", 0xb34365a9d7245f67),
    ("demo path 2 Nee", 0x5bf0bb844e9b3ecf),
    ("demo path regions", 0xa1b28d36a1307449),
    ("demo vpl", 0xe9e3b88bbb200607),
    ("demo albedo", 0x28acfb6e18c14612),
    ("demo normal", 0xe3bf947a24618deb),
    ("demo emission", 0xbe7134315f056325),
    ("demo depth", 0xa485bbfdd3118ca3),
    ("demo denoised", 0x9f12f8a9a78d7807),
    ("sponza path 4 Mis", 0xa7f4ec882bb0b6ac),
    ("sponza path 2 Nee", 0xbda432f09872c30e),
    ("sponza path regions", 0x79c5b2f4dc70772f),
    ("sponza vpl", 0x8ccff053a928732f),
    ("sponza albedo", 0x5904ea4ccb963246),
    ("sponza normal", 0xcdab194a964c9b71),
    ("sponza emission", 0xbe7134315f056325),
    ("sponza depth", 0x6af6b4af1c5fb268),
    ("sponza denoised", 0x98dd5d16b37a77ad),
];

#[test]
fn path_vpl_guide_and_denoised_images_keep_their_bits() {
    let got = frames();
    let listing: String = got.iter().map(|(n, h)| format!("    ({n:?}, {h:#018x}),\n")).collect();
    assert_eq!(got.len(), WANT.len(), "frames changed; now:\n{listing}");
    for ((n, h), (wn, wh)) in got.iter().zip(WANT) {
        assert_eq!((n.as_str(), *h), (*wn, *wh), "the image {n} changed; all frames now:\n{listing}");
    }
}

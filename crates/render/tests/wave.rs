//! The path tracer on lanes (issue 58): its images are the scalar path tracer's bit for bit
//! (`image_bits.rs` checks that on six scenes); here, that every build of its lane loops
//! (AVX-512, AVX2, the baseline) gives the same bits, and that an image does not depend on
//! the thread count, nor on how its samples are split into regions and passes.

use lucent_accel::MeshOptions;
use lucent_render::lanes::Level;
use lucent_render::{render, render_region, Camera, Film, FilmAccumulator, Integrator, PathSettings, Region, RenderSettings, World};
use std::path::PathBuf;

fn scene(name: &str) -> (World, Camera) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba").join(name).join("scene.xml");
    let s = lucent_scene::load_mitsuba_with(&dir, &[]).expect("scene");
    let cam = Camera::new(&s.camera.expect("camera"), 40, 30);
    (World::new(s, MeshOptions::default()).expect("world"), cam)
}

fn settings(spp: u32) -> RenderSettings {
    RenderSettings {
        spp,
        integrator: Integrator::Path(PathSettings { max_depth: 8, ..PathSettings::default() }),
        ..RenderSettings::new(40, 30)
    }
}

fn bits(f: &Film) -> Vec<[u32; 3]> {
    f.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// Every level the CPU runs gives the portable build's bits (every BSDF and light kind of
/// the materials scene, the Cornell box, Beckmann's rough conductors and plastics with
/// their vector loops (bumpmap), anisotropic roughness, an environment map's batches, the
/// principled BSDF's lobes, blends' and masks' parts, and a light tree's choices).
#[test]
fn every_build_of_the_lanes_gives_the_same_bits() {
    for name in ["materials", "cornell_box", "bumpmap", "anisotropic", "envmap", "principled", "blendbsdf", "mask", "plaza"] {
        let (w, cam) = scene(name);
        let mut images = Vec::new();
        for level in [Level::Portable, Level::Avx2, Level::Avx512] {
            Level::force(level);
            images.push((level, Level::current(), bits(&render(&w, &cam, &settings(4), &|_| {}).0)));
        }
        Level::unforce();
        for (level, ran, img) in &images[1..] {
            assert_eq!(img, &images[0].2, "{name}: {level:?} (ran as {ran:?}) against the portable build");
        }
    }
}

/// The lane forms of the principled BSDF (its direction, value and density on lanes), of
/// the blend (each part packed with its model: the mix's value and density, the chosen
/// part's sample mixed with the other's density toward it) and of the mask (its inner
/// BSDF packed, the null lobe chosen lane by lane) give the scalar path tracer's image bit
/// for bit (`image_bits.rs` has none of these scenes): metallic, transmitting,
/// clearcoated, sheened and flat lobes; diffuse and rough gold mixed by a texture, rough
/// plastic and smooth glass mixed 70/30; a textured opacity. And the light tree's choices
/// and densities among many lights (the plaza and the hall).
#[test]
fn principled_blend_and_mask_lanes_are_the_scalar_path_tracer() {
    for name in ["principled", "blendbsdf", "mask", "plaza", "hall"] {
        let (w, cam) = scene(name);
        let st = settings(8);
        let Integrator::Path(ps) = st.integrator else { unreachable!() };
        let scalar = RenderSettings { integrator: Integrator::Path(PathSettings { lanes: false, ..ps }), ..st };
        let (a, b) = (bits(&render(&w, &cam, &st, &|_| {}).0), bits(&render(&w, &cam, &scalar, &|_| {}).0));
        let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        assert_eq!(differ, 0, "{name}: lanes and scalar differ in {differ} of {} pixels", a.len());
        assert!(a.iter().any(|p| p.iter().any(|&c| f32::from_bits(c) > 0.0)), "{name}: a lit image");
    }
}

/// One thread or three, pixels in one region or in tiles: the same bits. Samples split
/// into passes: the same bits as the scalar path tracer given the same passes (a sample's
/// value does not depend on which others share its wave or its packets; the passes' sums,
/// added in another association, round apart from one pass's).
#[test]
fn threads_regions_and_passes_do_not_change_an_image() {
    let (w, cam) = scene("materials");
    let st = settings(12);
    let same = |a: &Film, b: &Film, what: &str| {
        let (a, b) = (bits(a), bits(b));
        let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
        assert_eq!(differ, 0, "{what}: {differ} of {} pixels differ", a.len());
    };
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool").install(|| render(&w, &cam, &st, &|_| {}).0);
    let three = rayon::ThreadPoolBuilder::new().num_threads(3).build().expect("pool").install(|| render(&w, &cam, &st, &|_| {}).0);
    same(&one, &three, "one thread against three");
    let merged = |st: &RenderSettings, passes: &[(u32, u32)]| {
        let mut acc = FilmAccumulator::new(40, 30);
        for &(s0, s1) in passes {
            for (x0, x1) in [(0, 16), (16, 40)] {
                let r = Region { x0, y0: 0, x1, y1: 30, s0, s1 };
                acc.merge(render_region(&w, &cam, st, r, &|_| {}).0).expect("regions");
            }
        }
        acc.resolve(w.scene().background)
    };
    same(&merged(&st, &[(0, 12)]), &one, "tiles against the whole image");
    let passes = [(0, 1), (1, 3), (3, 7), (7, 12)];
    let Integrator::Path(ps) = st.integrator else { unreachable!() };
    let scalar = RenderSettings { integrator: Integrator::Path(PathSettings { lanes: false, ..ps }), ..st };
    same(&merged(&st, &passes), &merged(&scalar, &passes), "passes, lanes against scalar");
}

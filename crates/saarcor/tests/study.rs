//! The hardware study on every shared scene and program: the kd index against the
//! reference kernel, the model's tables by content, and REND3R's cycles.

use glam::Vec3;
use lucent_accel::reference::{intersect_instances, RefGeometry};
use lucent_accel::{Geometry, MeshOptions, Ray};
use lucent_render::{Camera, World};
use lucent_scene::{load, CameraDesc};
use saarcor::dynrtp::{model_frame, Machine, Traced};

fn scenes_dir() -> std::path::PathBuf {
    if let Ok(d) = std::env::var("LUCENT_SCENES") {
        return d.into();
    }
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes")
}

/// Every shared scene (and the sunflowers demo), with a camera framing it.
fn worlds() -> Vec<(String, World)> {
    let files = [
        "cornell_box/cornell_box.obj",
        "cornell_box_original/CornellBox-Original.obj",
        "bart/museum/museum5_t0.obj.gz",
        "bart/museum/museum5.gltf",
        "bart/kitchen/kitchen_t0.obj.gz",
        "bart/kitchen/kitchen.gltf",
        "sponza_dabrovic/sponza.obj.gz",
        "conference/conference.obj.gz",
        "stanford/bunny.ply",
        "gltf_animated/BoxAnimated.glb",
        "gltf_animated/CesiumMan.glb",
    ];
    let mut out: Vec<(String, World)> = files
        .iter()
        .map(|f| {
            let s = load(&scenes_dir().join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
            ((*f).to_string(), World::new(s, MeshOptions::default()).expect("world"))
        })
        .collect();
    out.push(("sunflowers".into(), World::new(lucent_scene::sunflower_scene(), MeshOptions::default()).expect("world")));
    out
}

fn camera(w: &World, width: u32, height: u32) -> Camera {
    let s = w.scene();
    let desc = s.camera.unwrap_or_else(|| {
        let (lo, hi) = s.bounds().expect("bounds");
        lucent_render::framing_camera(lo, hi)
    });
    Camera::new(&desc, width, height)
}

/// The kd index (single rays and packets of 4) finds the reference kernel's hits on every
/// shared scene: camera rays and random rays through the bounds.
#[test]
fn kd_matches_reference_on_every_shared_scene() {
    for (name, world) in worlds() {
        let kd = saarcor::kd_of_world(&world).expect("kd");
        let meshes = &world.scene().meshes;
        let geoms: Vec<RefGeometry<'_>> = world
            .accel()
            .geometries()
            .iter()
            .enumerate()
            .map(|(i, g)| match g {
                Geometry::Mesh(_) => RefGeometry::Mesh(&meshes[i].positions, &meshes[i].indices),
                Geometry::Shape(s) => RefGeometry::Shape(*s),
            })
            .collect();
        let insts: Vec<(u32, glam::Affine3A)> = world.accel().instances().iter().map(|i| (i.geometry, i.world_from_object)).collect();
        let identity = world.accel().instances().iter().all(lucent_accel::Instance::is_identity);
        let cam = camera(&world, 32, 24);
        let (lo, hi) = world.scene().bounds().expect("bounds");
        let mut rays: Vec<Ray> =
            (0..24).flat_map(|y| (0..32).map(move |x| (x, y))).map(|(x, y)| cam.ray(x as f32 + 0.5, y as f32 + 0.5)).collect();
        let mut seed = 0x9E37_79B9_u32;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        for _ in 0..200 {
            let a = lo + (hi - lo) * Vec3::new(rnd(), rnd(), rnd());
            let b = lo + (hi - lo) * Vec3::new(rnd(), rnd(), rnd());
            rays.push(Ray::new(a, (b - a).normalize_or(Vec3::Y)));
        }
        // The brute-force reference costs rays x triangles: big scenes get a sample.
        let triangles: usize = insts.iter().map(|(g, _)| meshes.get(*g as usize).map_or(1, |m| m.indices.len())).sum::<usize>().max(1);
        let step = (rays.len() * triangles / 20_000_000).max(1);
        let mut differ = 0;
        for (k, r) in rays.iter().enumerate().step_by(step) {
            let want = intersect_instances(&geoms, &insts, r);
            let got = kd.intersect(r);
            let same = match (got, want) {
                (Some(g), Some(w)) => g.t.to_bits() == w.t.to_bits() || (!identity && (g.t - w.t).abs() <= 1e-5 * w.t.abs()),
                (None, None) => true,
                _ => false,
            };
            if identity {
                assert!(same, "{name}: ray {k} {r:?}: kd {got:?}, reference {want:?}");
            } else if !same {
                // Instances: the reference inverts each matrix itself; the index uses the
                // cached inverse, which may differ in the last bit.
                differ += 1;
            }
        }
        assert!(differ * 200 <= rays.len() / step, "{name}: {differ} of {} rays differ", rays.len() / step);
        // Packets of 4 give the single rays' answers.
        for q in rays[..768].chunks_exact(4) {
            let p: [Ray; 4] = [q[0], q[1], q[2], q[3]];
            let got = kd.intersect4_with::<saarcor::kd::Exact, _>(&p, &mut ());
            for l in 0..4 {
                assert_eq!(got[l], kd.intersect(&p[l]), "{name}: packet lane {l}");
            }
            // Shadow rays: occlusion up to half the way to each lane's hit (or its far
            // end), and up to just beyond it, single rays and packets.
            for scale in [0.5f32, 1.001] {
                let s: [Ray; 4] = std::array::from_fn(|l| Ray { tmax: got[l].map_or(1e30, |h| h.t * scale), ..p[l] });
                let occ = kd.occluded4_with::<saarcor::kd::Exact, _>(&s, &mut ());
                for l in 0..4 {
                    let want = kd.intersect(&s[l]).is_some();
                    assert_eq!(occ[l], want, "{name}: shadow packet lane {l} x{scale}");
                    assert_eq!(kd.occluded_with::<saarcor::kd::Exact, _>(&s[l], &mut ()), want, "{name}: shadow lane {l}");
                }
            }
        }
        kd.top().validate(world.accel().instances().len()).expect("top well formed");
    }
}

/// The model's tables by content on every shared scene: as many hit rays as the world's
/// own kernel finds, usages within 0..100 with the busiest unit (or memory) at 100%, hit
/// rates within 0..100, fps = 90 MHz / cycles, and bandwidth consistent with fps.
#[test]
fn model_tables_on_every_shared_scene() {
    let m = Machine::default();
    for (name, world) in worlds() {
        let kd = saarcor::kd_of_world(&world).expect("kd");
        let cam = camera(&world, 64, 48);
        let hits = (0..48)
            .flat_map(|y| (0..64).map(move |x| (x, y)))
            .filter(|&(x, y)| world.intersect(&cam.ray(x as f32 + 0.5, y as f32 + 0.5)).is_some())
            .count() as u64;
        for ix in [Traced::Bvh(world.accel()), Traced::Kd(&kd)] {
            let f = model_frame(&ix, &cam, &m);
            assert_eq!(f.hit_rays, hits, "{name} {}: hit rays", f.index);
            assert!((f.fps - 90e6 / f.cycles as f64).abs() < 1e-6 * f.fps, "{name}");
            let top = f.busy.iter().copied().max().unwrap_or(0);
            assert!(top <= f.cycles, "{name}: no unit is busier than the frame is long");
            // 64 threads keep the busiest unit (or the memory) busy most of the frame on
            // scenes of more than a handful of packets' work.
            assert!(top == 0 || f.cycles < 50 * top, "{name}: {} cycles for {top} of the busiest unit", f.cycles);
            assert!(f.usage.iter().all(|u| (0.0..=100.0 + 1e-9).contains(u)), "{name}: usage {:?}", f.usage);
            assert!(f.hit.iter().all(|h| (0.0..=100.0).contains(h)), "{name}: hit {:?}", f.hit);
            assert!(f.busy[0] > 0 || hits == 0, "{name}: no traversal counted");
            assert!((f.mb_s[2] - f.mb_s[0] - f.mb_s[1]).abs() < 1e-6, "{name}");
            // Bigger caches never hit less often: direct-mapped caches whose item counts are
            // powers of two nest (traversal 8 B, list 4 B items; the 12-byte items of the
            // transformation cache make counts like 170 and 341, which do not).
            for w in f.sweep.windows(2) {
                for c in 0..2 {
                    assert!(w[1].1[c] + 1e-9 >= w[0].1[c], "{name} {}: cache {c} {:?}", f.index, f.sweep);
                }
            }
            assert_eq!(f.heat_steps.len(), 64 * 48);
        }
    }
}

/// Hand-counted: a one-triangle scene seen by one packet whose four rays all hit it.
#[test]
fn model_of_one_triangle() {
    let mut s = lucent_scene::Scene::default();
    let mesh = lucent_scene::Mesh {
        positions: vec![Vec3::new(-10.0, -10.0, 0.0), Vec3::new(10.0, -10.0, 0.0), Vec3::new(0.0, 10.0, 0.0)],
        indices: vec![[0, 1, 2]],
        material: vec![0],
        ..Default::default()
    };
    s.materials.push(lucent_scene::Material::default());
    s.add_mesh(mesh);
    let world = World::new(s, MeshOptions::default()).expect("world");
    let kd = saarcor::kd_of_world(&world).expect("kd");
    let desc = CameraDesc::from_view(&[0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 10.0]);
    let cam = Camera::new(&desc, 2, 2);
    let f = model_frame(&Traced::Kd(&kd), &cam, &Machine::default());
    // A leaf of the top level and one of the mesh's tree, a list entry in each (the
    // instance is the identity: no transformation); the packet's 4 rays made in 4 + 1
    // transformation steps; 4 rays through one triangle: 4 + 1 transformation steps, 4
    // intersections, 2 shading steps per hit ray.
    assert_eq!(f.busy[..4], [2, 2, 5 + 5 + 8, 4]);
    // One packet on an idle machine: every step waits for the one before; its reads all
    // miss (5 items: 2 nodes, 2 list entries, the triangle's map of 40 B in four 12-byte
    // items).
    assert!(f.cycles > f.busy[..4].iter().sum::<u64>() + 5 * u64::from(Machine::default().memory_latency));
    assert_eq!(f.hit_rays, 4);
}

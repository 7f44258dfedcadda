//! Every fast kernel against the brute-force reference, on seeded random triangle soups.

use glam::{Affine3A, Quat, Vec3};
use lucent_accel::reference::{intersect_instances, intersect_triangles, intersect_triangles_watertight, occluded_triangles, RefGeometry};
use lucent_accel::{Geometry, Instance, Kernel, MeshBvh, MeshOptions, Ray, Shape, TriangleTest, TwoLevel, Width};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

fn soup(rng: &mut Pcg64, n: usize, scale: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    let mut idx = Vec::new();
    for i in 0..n {
        let c = Vec3::new(rng.random(), rng.random(), rng.random()) * scale;
        for _ in 0..3 {
            p.push(c + Vec3::new(rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5) * scale * 0.1);
        }
        idx.push([3 * i as u32, 3 * i as u32 + 1, 3 * i as u32 + 2]);
    }
    (p, idx)
}

fn random_ray(rng: &mut Pcg64, scale: f32) -> Ray {
    let o = Vec3::new(rng.random(), rng.random(), rng.random()) * scale * 1.4 - Vec3::splat(scale * 0.2);
    let target = Vec3::new(rng.random(), rng.random(), rng.random()) * scale;
    Ray::new(o, (target - o).normalize_or(Vec3::X))
}

fn all_variants() -> Vec<(Width, Kernel)> {
    Kernel::available().into_iter().flat_map(|k| [(Width::W4, k), (Width::W8, k)]).collect()
}

#[test]
fn mesh_kernels_match_reference() {
    for (seed, scale) in [(1u64, 1.0f32), (2, 1e-3), (3, 1e3)] {
        let mut rng = Pcg64::seed_from_u64(seed);
        let (p, idx) = soup(&mut rng, 3000, scale);
        for (width, kernel) in all_variants() {
            let mut bvh =
                MeshBvh::build(&p, &idx, MeshOptions { width, test: TriangleTest::UnitTriangle, ..MeshOptions::default() }).expect("build");
            bvh.validate().expect("well formed");
            bvh.set_kernel(kernel);
            let mut rng = Pcg64::seed_from_u64(seed + 100);
            for _ in 0..400 {
                let r = random_ray(&mut rng, scale);
                let want = intersect_triangles(&p, &idx, &r);
                let got = bvh.intersect(&r);
                match (want, got) {
                    (None, None) => {}
                    (Some(w), Some(g)) => {
                        // Same distance to the bit; the id may differ only on an exact tie.
                        assert_eq!(w.t, g.t, "{width:?} {kernel:?} scale {scale}: t differs for {r:?}");
                        if w.prim != g.prim {
                            assert!(intersect_triangles(&p, &idx[g.prim as usize..=g.prim as usize], &r).is_some_and(|h| h.t == w.t));
                        }
                    }
                    _ => panic!("{width:?} {kernel:?} scale {scale}: hit/miss differs for {r:?}: want {want:?} got {got:?}"),
                }
                let short = r.with_range(0.0, want.map_or(f32::INFINITY, |h| h.t * 0.999));
                assert_eq!(bvh.occluded(&short), occluded_triangles(&p, &idx, &short), "{width:?} {kernel:?}: occluded differs");
                assert_eq!(bvh.occluded(&r), want.is_some());
            }
        }
    }
}

#[test]
fn watertight_kernel_matches_reference() {
    let mut rng = Pcg64::seed_from_u64(7);
    let (p, idx) = soup(&mut rng, 2000, 10.0);
    for (width, kernel) in all_variants() {
        let mut bvh =
            MeshBvh::build(&p, &idx, MeshOptions { width, test: TriangleTest::Watertight, ..MeshOptions::default() }).expect("build");
        bvh.set_kernel(kernel);
        for _ in 0..300 {
            let r = random_ray(&mut rng, 10.0);
            let want = intersect_triangles_watertight(&p, &idx, &r);
            let got = bvh.intersect(&r);
            assert_eq!(want.map(|h| h.t), got.map(|h| h.t), "{width:?} {kernel:?}");
        }
    }
}

#[test]
fn every_kernel_gives_identical_hits() {
    // On an AVX2 (+AVX-512) machine this compares the SIMD kernels with the scalar one; on
    // other machines only the scalar kernel exists and there is nothing to compare.
    let kernels = Kernel::available();
    let mut rng = Pcg64::seed_from_u64(11);
    let (p, idx) = soup(&mut rng, 5000, 5.0);
    for width in [Width::W4, Width::W8] {
        let mut a = MeshBvh::build(&p, &idx, MeshOptions { width, ..MeshOptions::default() }).expect("build");
        a.set_kernel(Kernel::Scalar);
        for &k in &kernels[1..] {
            let mut b = a.clone();
            b.set_kernel(k);
            assert_eq!(b.kernel(), k);
            let mut rng = Pcg64::seed_from_u64(12);
            for _ in 0..2000 {
                let r = random_ray(&mut rng, 5.0);
                assert_eq!(a.intersect(&r), b.intersect(&r), "{k:?}");
                assert_eq!(a.occluded(&r), b.occluded(&r), "{k:?}");
            }
        }
    }
}

#[test]
fn nan_and_degenerate_input_never_breaks_the_build() {
    let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(f32::NAN, 0.0, 0.0), Vec3::splat(f32::INFINITY), Vec3::X * 2.0];
    let idx = vec![[0, 1, 2], [0, 3, 2], [4, 1, 2], [0, 1, 5], [1, 1, 1], [0, 1, 2]];
    let bvh = MeshBvh::build(&p, &idx, MeshOptions::default()).expect("build");
    assert_eq!(bvh.stats().prims, 2, "only the two proper triangles are indexed");
    let h = bvh.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).expect("hit");
    assert_eq!(h.t, 1.0);
    assert!(bvh.intersect(&Ray::new(Vec3::new(5.0, 5.0, 1.0), -Vec3::Z)).is_none());
    // A NaN ray finds nothing and does not hang.
    assert!(bvh.intersect(&Ray::new(Vec3::splat(f32::NAN), -Vec3::Z)).is_none());
    let err = MeshBvh::build(&p, &[[0, 1, 9]], MeshOptions::default()).expect_err("index out of range");
    assert!(err.to_string().contains("vertex 9"), "{err}");
}

#[test]
fn many_identical_triangles_build_a_bounded_tree() {
    let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
    let idx = vec![[0u32, 1, 2]; 20000];
    let bvh = MeshBvh::build(&p, &idx, MeshOptions::default()).expect("build");
    bvh.validate().expect("well formed");
    assert!(bvh.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).is_some());
}

#[test]
fn two_level_matches_reference() {
    let mut rng = Pcg64::seed_from_u64(5);
    let (p1, i1) = soup(&mut rng, 500, 1.0);
    let (p2, i2) = soup(&mut rng, 300, 1.0);
    let shapes = [Shape::Sphere, Shape::CappedCylinder, Shape::CappedCone, Shape::Box, Shape::Disk, Shape::Cylinder];
    let mut geoms = vec![
        Geometry::Mesh(MeshBvh::build(&p1, &i1, MeshOptions::default()).expect("b1")),
        Geometry::Mesh(MeshBvh::build(&p2, &i2, MeshOptions { width: Width::W4, ..MeshOptions::default() }).expect("b2")),
    ];
    let mut refs = vec![RefGeometry::Mesh(&p1, &i1), RefGeometry::Mesh(&p2, &i2)];
    for s in shapes {
        geoms.push(Geometry::Shape(s));
        refs.push(RefGeometry::Shape(s));
    }
    let mut placed = Vec::new();
    // Enough instances for the clustered top level (runs of 8, SAH over the runs).
    for k in 0..200u32 {
        let g = k % geoms.len() as u32;
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(rng.random_range(0.2..1.5), rng.random_range(0.2..1.5), rng.random_range(0.2..1.5)),
            Quat::from_euler(glam::EulerRot::XYZ, rng.random(), rng.random(), rng.random()),
            Vec3::new(rng.random(), rng.random(), rng.random()) * 20.0,
        );
        placed.push((g, m));
    }
    let insts: Vec<Instance> = placed.iter().map(|&(g, m)| Instance::new(g, m)).collect();
    let mut tl = TwoLevel::new(geoms, insts).expect("tlas");
    // Both top-level builders, every kernel.
    let mut variants = Vec::new();
    for builder in [lucent_accel::TopBuilder::Sah, lucent_accel::TopBuilder::Linear] {
        tl.set_top_builder(builder);
        tl.rebuild().expect("rebuild");
        variants.extend(Kernel::available().into_iter().map(|k| (k, tl.clone())));
    }
    for (kernel, mut tl) in variants {
        tl.set_kernel(kernel);
        let mut rng = Pcg64::seed_from_u64(6);
        for _ in 0..300 {
            let r = random_ray(&mut rng, 20.0);
            let want = intersect_instances(&refs, &placed, &r);
            let got = tl.intersect(&r);
            match (want, got) {
                (None, None) => {}
                (Some(w), Some(g)) => {
                    assert!((w.t - g.t).abs() <= 1e-4 * w.t.abs().max(1.0), "{kernel:?}: t {} vs {}", w.t, g.t);
                    if w.inst != g.inst {
                        assert!((w.t - g.t).abs() <= 1e-5 * w.t.abs().max(1.0), "different instances at different t");
                    }
                }
                _ => panic!("{kernel:?}: hit/miss differs: {want:?} vs {got:?}"),
            }
            assert_eq!(tl.occluded(&r), want.is_some());
        }
    }
}

#[test]
fn moved_instance_is_hit_where_it_now_is() {
    let geoms = vec![Geometry::Shape(Shape::Sphere)];
    let mut tl = TwoLevel::new(geoms, vec![Instance::new(0, Affine3A::from_translation(Vec3::new(0.0, 0.0, -5.0)))]).expect("tlas");
    let r = Ray::new(Vec3::ZERO, -Vec3::Z);
    assert!((tl.intersect(&r).expect("hit").t - 4.0).abs() < 1e-5);
    tl.set_instances(vec![Instance::new(0, Affine3A::from_translation(Vec3::new(10.0, 0.0, -5.0)))]).expect("rebuild");
    assert!(tl.intersect(&r).is_none());
    assert!(tl.intersect(&Ray::new(Vec3::new(10.0, 0.0, 0.0), -Vec3::Z)).is_some());
}

#[test]
fn axis_aligned_rays_are_cheap_and_correct() {
    // Rays with zero direction components must not disable the slab test of that axis
    // (which would make them visit every node): check the answers against the reference and
    // count the node visits.
    let mut rng = Pcg64::seed_from_u64(21);
    let (p, idx) = soup(&mut rng, 20000, 1.0);
    for kernel in Kernel::available() {
        let mut bvh = MeshBvh::build(&p, &idx, MeshOptions::default()).expect("build");
        bvh.set_kernel(kernel);
        let dirs = [
            Vec3::X,
            -Vec3::X,
            Vec3::Y,
            -Vec3::Y,
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(1.0, 1.0, 0.0).normalize(),
            Vec3::new(0.0, -1.0, 1.0).normalize(),
        ];
        for _ in 0..50 {
            let o = Vec3::new(rng.random(), rng.random(), rng.random()) * 1.2 - Vec3::splat(0.1);
            for d in dirs {
                let r = Ray::new(o, d);
                assert_eq!(bvh.intersect(&r).map(|h| h.t), intersect_triangles(&p, &idx, &r).map(|h| h.t), "{kernel:?} {r:?}");
                assert_eq!(bvh.occluded(&r), occluded_triangles(&p, &idx, &r), "{kernel:?} {r:?}");
            }
        }
        // Rays along +y from below the soup and beside it in x: only the x slab rejects
        // them, so they visit the root alone (with the x slab disabled they would walk every
        // node whose y and z ranges they cross).
        let mut st = lucent_accel::TraversalStats::default();
        for i in 0..1000 {
            let o = Vec3::new(1.5 + i as f32 / 1000.0, -0.5, 0.5);
            assert!(bvh.intersect_with_stats(&Ray::new(o, Vec3::Y), &mut st).is_none());
            assert!(!bvh.occluded_with_stats(&Ray::new(o, Vec3::Y), &mut st));
        }
        let total = bvh.stats().nodes as u64;
        assert!(st.nodes < 2000 * 3, "axis-aligned rays walk the tree: {} node visits for 2000 queries ({total} nodes)", st.nodes);
    }
}

#[test]
fn a_refit_bvh_gives_the_hits_of_a_fresh_build() {
    let mut rng = Pcg64::seed_from_u64(21);
    let (p, mut idx) = soup(&mut rng, 4000, 5.0);
    // A few zero-area triangles that gain area when the mesh deforms.
    for t in idx.iter_mut().take(50) {
        t[2] = t[1];
    }
    let moved = |p: &[Vec3], k: f32| -> Vec<Vec3> {
        p.iter().map(|v| *v + Vec3::new((v.y * 1.7 + k).sin(), 0.3 * (v.x * 2.3).cos() * k, 0.2 * k)).collect()
    };
    for test in [TriangleTest::UnitTriangle, TriangleTest::Watertight] {
        for width in [Width::W4, Width::W8] {
            let opts = MeshOptions { width, test, refittable: true, ..MeshOptions::default() };
            let mut bvh = MeshBvh::build(&p, &idx, opts).expect("build");
            let mut idx2 = idx.clone();
            for (i, t) in idx2.iter_mut().take(50).enumerate() {
                t[2] = 3 * i as u32 + 2;
            }
            for k in [0.5f32, 2.0] {
                let q = moved(&p, k);
                let ratio = bvh.refit(&q, &idx2).expect("refit");
                assert!(ratio.is_finite() && ratio > 0.5, "cost ratio {ratio}");
                bvh.validate().expect("valid after refit");
                let fresh =
                    MeshBvh::build(&q, &idx2, MeshOptions { width, test, refittable: false, ..MeshOptions::default() }).expect("fresh");
                let mut rng = Pcg64::seed_from_u64(22);
                let mut hits = 0;
                for _ in 0..3000 {
                    let r = random_ray(&mut rng, 5.0);
                    let (a, b) = (bvh.intersect(&r), fresh.intersect(&r));
                    assert_eq!(a.map(|h| (h.t, h.prim)), b.map(|h| (h.t, h.prim)), "{test:?} {width:?} k={k}");
                    assert_eq!(bvh.occluded(&r), fresh.occluded(&r));
                    hits += usize::from(a.is_some());
                }
                assert!(hits > 300, "{hits} hits");
            }
            // The once-degenerate triangles are found where they now are.
            let q = moved(&p, 2.0);
            bvh.refit(&q, &idx2).expect("refit");
            let [a, b, c] = idx2[7].map(|i| q[i as usize]);
            let n = (b - a).cross(c - a).normalize();
            let centre = (a + b + c) / 3.0;
            let h = bvh.intersect(&Ray::new(centre + n * 1e-3, -n).with_range(0.0, 2e-3)).expect("hit");
            assert_eq!(h.prim, 7);
        }
    }
}

/// Insertion-based optimization keeps every primitive in exactly one leaf and every box
/// around its children, lowers the SAH cost, and leaves the answers unchanged. The largest
/// soup is built by median splits (a poor tree, with much to move), so its passes have
/// enough candidates for the parallel search and for moves that collide; its tree must not
/// depend on the number of threads.
#[test]
fn reinsertion_keeps_the_tree_valid_and_lowers_its_cost() {
    use lucent_accel::build::{build_binary, BuildConfig, PrimRef};
    use lucent_accel::{Aabb, Quality};
    let mut rng = Pcg64::seed_from_u64(11);
    for n in [5usize, 60, 3000, 40_000] {
        let (p, idx) = soup(&mut rng, n, 10.0);
        let prims: Vec<PrimRef> = idx
            .iter()
            .enumerate()
            .map(|(i, t)| PrimRef::new(Aabb::from_points(&[p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]]), i as u32))
            .collect();
        let cfg = BuildConfig { median_max: if n > 10_000 { n } else { 0 }, ..BuildConfig::default() };
        let optimized = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| {
                let mut bin = build_binary(prims.clone(), &cfg);
                let costs = lucent_accel::reinsert::optimize(&mut bin, &cfg);
                (bin, costs)
            })
        };
        let (bin, (before, after)) = optimized(2);
        bin.validate(&cfg).expect("valid after reinsertion");
        assert!(after <= before, "{n}: cost {before} -> {after}");
        assert!((after - bin.sah_cost(&cfg)).abs() <= 1e-4 * after, "{n}: reported {after}, tree {}", bin.sah_cost(&cfg));
        if n > 10_000 {
            assert!(after < 0.97 * before, "{n}: cost {before} -> {after}");
            let (one, _) = optimized(1);
            assert!(
                one.nodes
                    .iter()
                    .zip(&bin.nodes)
                    .all(|(a, b)| (a.first, a.right, a.count, a.bounds) == (b.first, b.right, b.count, b.bounds)),
                "{n}: the tree depends on the thread count"
            );
        }
        let plain = MeshBvh::build(&p, &idx, MeshOptions { quality: Quality::Sah, ..MeshOptions::default() }).expect("build");
        let high = MeshBvh::build(&p, &idx, MeshOptions { quality: Quality::High, ..MeshOptions::default() }).expect("build");
        high.validate().expect("well formed");
        for _ in 0..300 {
            let r = random_ray(&mut rng, 10.0);
            assert_eq!(plain.intersect(&r).map(|h| h.t), high.intersect(&r).map(|h| h.t), "{n}: {r:?}");
            assert_eq!(plain.occluded(&r), high.occluded(&r));
        }
    }
}

/// A soup of 4,000 triangles in a 10-unit cube (seed `seed`), an eye in front of it and an
/// 8×8 fan of rays from the eye toward +z, their slopes from `first` in steps of 0.01.
fn soup_and_tile(seed: u64, first: f32) -> (MeshBvh, Vec<Ray>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (p, idx) = soup(&mut rng, 4000, 10.0);
    let bvh = MeshBvh::build(&p, &idx, MeshOptions::default()).expect("build");
    let eye = Vec3::new(5.0, 5.0, -20.0);
    let slope = |k: usize| first + k as f32 * 0.01;
    let rays = (0..64).map(|i| Ray::new(eye, Vec3::new(slope(i % 8), slope(i / 8), 1.0).normalize())).collect();
    (bvh, rays)
}

/// The counting packet kernels give the plain ones' answers and count their work: a packet
/// of coherent rays visits far fewer nodes than its rays do one by one.
#[test]
fn packet_stats_count_and_agree() {
    use lucent_accel::TraversalStats;
    // An 8×8 fan of rays from one point (a pinhole tile) and their shadow rays toward a light.
    let (bvh, rays) = soup_and_tile(5, 0.001);
    let (mut plain, mut counted) = (vec![None; 64], vec![None; 64]);
    bvh.intersect_packet(&rays, &mut plain);
    let mut st = TraversalStats::default();
    bvh.intersect_packet_with_stats(&rays, &mut counted, &mut st);
    assert_eq!(plain, counted);
    assert!(plain.iter().filter(|h| h.is_some()).count() > 32, "the fan looks into the soup");
    let mut single = TraversalStats::default();
    for r in &rays {
        let _ = bvh.intersect_with_stats(r, &mut single);
    }
    assert!(st.nodes > 0 && st.nodes * 4 < single.nodes, "packet {st:?}, rays one by one {single:?}");
    let light = Vec3::new(5.0, 30.0, 5.0);
    let shadow: Vec<Ray> = plain
        .iter()
        .zip(&rays)
        .filter_map(|(h, r)| h.map(|h| r.at(h.t) - r.dir * 1e-3))
        .map(|o| Ray::new(o, (light - o).normalize()).with_range(0.0, (light - o).length()))
        .collect();
    let (mut a, mut b) = (vec![false; shadow.len()], vec![false; shadow.len()]);
    bvh.occluded_packet(&shadow, &mut a);
    let mut st = TraversalStats::default();
    bvh.occluded_packet_with_stats(&shadow, &mut b, &mut st);
    assert_eq!(a, b);
    assert!(st.nodes > 0);
    for (r, o) in shadow.iter().zip(&a) {
        assert_eq!(bvh.occluded(r), *o);
    }
}

/// A tile whose rays straddle an axis (a view straight down `z`, or shadow rays toward a
/// light right above the tile) mixes direction signs: no one interval bounds it. Its rays
/// are split by sign into coherent packets (not traced one by one), with the single-ray
/// answers.
#[test]
fn packets_that_mix_direction_signs_are_split_by_sign() {
    use lucent_accel::TraversalStats;
    let (bvh, rays) = soup_and_tile(9, -0.035);
    let mut hits = vec![None; 64];
    let mut st = TraversalStats::default();
    bvh.intersect_packet_with_stats(&rays, &mut hits, &mut st);
    let mut single = TraversalStats::default();
    for (r, h) in rays.iter().zip(&hits) {
        assert_eq!(bvh.intersect_with_stats(r, &mut single), *h);
    }
    assert!(hits.iter().filter(|h| h.is_some()).count() > 32, "the tile looks into the soup");
    assert!(st.nodes * 2 < single.nodes, "packet {st:?}, rays one by one {single:?}");
    // Shadow rays from an 8×8 patch of a floor toward a light straight above its centre,
    // in the lower layer of the soup.
    let light = Vec3::new(5.0, 5.0, 1.0);
    let origins: Vec<Vec3> =
        (0..64).map(|i| Vec3::new(5.0 + ((i % 8) as f32 - 3.5) * 0.04, 5.0 + ((i / 8) as f32 - 3.5) * 0.04, -1.0)).collect();
    let shadow: Vec<Ray> = origins.iter().map(|&o| Ray::new(o, (light - o).normalize()).with_range(0.0, (light - o).length())).collect();
    let mut occ = vec![false; shadow.len()];
    let mut st = TraversalStats::default();
    bvh.occluded_packet_with_stats(&shadow, &mut occ, &mut st);
    let mut single = TraversalStats::default();
    for (r, o) in shadow.iter().zip(&occ) {
        assert_eq!(bvh.occluded_with_stats(r, &mut single), *o);
    }
    assert!(st.nodes * 2 < single.nodes, "shadow packet {st:?}, rays one by one {single:?}");
}

/// Shadow rays toward a directional light through the light-space grid give the walk's
/// answers: over a field of spheres and mesh instances (rotated, unequally scaled, some
/// large), from points on their surfaces and from points above them, on every kernel. The
/// grid lists few instances per ray, and every instance a ray meets is listed.
#[test]
fn shadow_grid_packets_match_single_rays() {
    let mut rng = Pcg64::seed_from_u64(33);
    let (p, idx) = soup(&mut rng, 300, 1.0);
    let mesh = MeshBvh::build(&p, &idx, MeshOptions::default()).expect("mesh");
    let mut insts = Vec::new();
    for i in 0..300u32 {
        let (x, y) = ((i % 20) as f32 * 3.0 - 30.0, (i / 20) as f32 * 2.2 - 16.0);
        let s = Vec3::new(rng.random_range(0.3..1.4), rng.random_range(0.3..1.4), rng.random_range(0.3..1.4));
        let q = Quat::from_euler(glam::EulerRot::XYZ, rng.random(), rng.random(), rng.random());
        let g = u32::from(i % 7 == 0);
        let s = if i % 50 == 0 { s * 3.0 } else { s };
        insts.push(Instance::new(g, Affine3A::from_scale_rotation_translation(s, q, Vec3::new(x, y, -20.0 - (i % 3) as f32))));
    }
    let base = TwoLevel::new(vec![Geometry::Shape(Shape::Sphere), Geometry::Mesh(mesh)], insts).expect("tlas");
    for (round, d) in
        [Vec3::new(-1.0, 1.0, 1.0), Vec3::new(0.2, 0.1, 1.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, -0.3, 0.05)].into_iter().enumerate()
    {
        let d = d.normalize();
        let mut with_grid = base.clone();
        with_grid.set_shadow_directions(&[d]);
        // Origins: hits of rays from a camera (on surfaces), and points in the gaps.
        let mut shadow = Vec::new();
        for k in 0..64 * 48 {
            let (px, py) = (k % 64, k / 64);
            let dir = Vec3::new((px as f32 + 0.5) / 64.0 - 0.5, (py as f32 + 0.5) / 48.0 - 0.5, -0.75) * 2.7;
            let r = Ray::new(Vec3::new(0.3, -0.2, 5.0), dir);
            let o = match base.intersect(&r) {
                Some(h) => r.org + r.dir * h.t,
                None => r.org + r.dir * 7.0,
            };
            shadow.push(Ray { org: o, dir: d, tmin: 1e-4, tmax: f32::INFINITY });
        }
        let (mut listed, mut blocked) = (0usize, 0usize);
        for kernel in Kernel::available() {
            let mut tl = with_grid.clone();
            tl.set_kernel(kernel);
            let mut occ = vec![false; shadow.len()];
            tl.occluded_packet(&shadow, &mut occ);
            for (r, o) in shadow.iter().zip(&occ) {
                assert_eq!(base.occluded(r), *o, "round {round}, {kernel:?}: {r:?}");
                blocked += usize::from(*o);
            }
        }
        for r in &shadow {
            let Some(ids) = with_grid.shadow_candidates_at(d, r.org) else { continue };
            listed += 1;
            // Every instance the ray meets (closest hits after moving past each) is listed.
            let mut ray = *r;
            while let Some(h) = base.intersect(&ray) {
                assert!(ids.contains(&h.inst), "round {round}: {r:?} meets instance {} not in {ids:?}", h.inst);
                ray.tmin = h.t * 1.0001 + 1e-4;
            }
        }
        assert!(listed > shadow.len() * 3 / 5, "round {round}: the grid listed {listed} of {}", shadow.len());
        assert!(blocked > 0, "round {round}: nothing blocked");
    }
}

/// Packets over a field of sphere instances (the REND3R Table IV kind of scene, with
/// rotations and unequal scales) give the single-ray answers bit for bit on every kernel:
/// camera tiles, and shadow rays that start on the spheres they hit (the SIMD sphere test
/// of the packet kernels must round exactly as the scalar one).
#[test]
fn sphere_packets_match_single_rays() {
    let mut rng = Pcg64::seed_from_u64(21);
    let mut insts = Vec::new();
    for i in 0..400u32 {
        let (x, y) = ((i % 20) as f32 * 3.0 - 30.0, (i / 20) as f32 * 2.2 - 22.0);
        let s = if i % 3 == 0 {
            Vec3::splat(1.1)
        } else {
            Vec3::new(rng.random_range(0.3..1.4), rng.random_range(0.3..1.4), rng.random_range(0.3..1.4))
        };
        let q = Quat::from_euler(glam::EulerRot::XYZ, rng.random(), rng.random(), rng.random());
        insts.push(Instance::new(0, Affine3A::from_scale_rotation_translation(s, q, Vec3::new(x, y, -20.0 - (i % 3) as f32))));
    }
    let tl = TwoLevel::new(vec![Geometry::Shape(Shape::Sphere)], insts).expect("tlas");
    // 64×48 primary rays from one eye, in 8×8 tiles of 64.
    let mut primary = Vec::new();
    for ty in 0..6 {
        for tx in 0..8 {
            for k in 0..64 {
                let (px, py) = (tx * 8 + k % 8, ty * 8 + k / 8);
                let d = Vec3::new((px as f32 + 0.5) / 64.0 - 0.5, (py as f32 + 0.5) / 48.0 - 0.5, -0.75);
                primary.push(Ray::new(Vec3::new(0.3, -0.2, 5.0), d * 2.7));
            }
        }
    }
    for kernel in Kernel::available() {
        let mut tl = tl.clone();
        tl.set_kernel(kernel);
        let mut got = vec![None; primary.len()];
        tl.intersect_packet(&primary, &mut got);
        let mut shadow = Vec::new();
        let mut hits = 0;
        for (r, g) in primary.iter().zip(&got) {
            let want = tl.intersect(r);
            assert_eq!(want.map(|h| (h.t.to_bits(), h.prim, h.inst)), g.map(|h| (h.t.to_bits(), h.prim, h.inst)), "{kernel:?}: {r:?}");
            // A shadow ray from the hit toward a point light (limited) and one toward a
            // directional light (unlimited), both starting exactly on the surface.
            let p = match g {
                Some(h) => {
                    hits += 1;
                    r.org + r.dir * h.t
                }
                None => r.org + r.dir * 7.0,
            };
            let l = Vec3::new(-15.0, 12.0, 10.0) - p;
            shadow.push(Ray { org: p, dir: l, tmin: 1e-4, tmax: 0.999 });
            shadow.push(Ray { org: p, dir: Vec3::new(-1.0, 1.0, 1.0), tmin: 1e-4, tmax: f32::INFINITY });
        }
        assert!(hits > primary.len() / 3, "{kernel:?}: only {hits} hits");
        let mut occ = vec![false; shadow.len()];
        tl.occluded_packet(&shadow, &mut occ);
        let mut blocked = 0;
        for (r, o) in shadow.iter().zip(&occ) {
            assert_eq!(tl.occluded(r), *o, "{kernel:?}: {r:?}");
            blocked += *o as usize;
        }
        assert!(blocked > 0 && blocked < shadow.len(), "{kernel:?}: {blocked} of {} blocked", shadow.len());
        // Closest hits of the shadow rays too (rays that start on a surface, spread origins).
        let mut sh = vec![None; shadow.len()];
        tl.intersect_packet(&shadow, &mut sh);
        for (r, g) in shadow.iter().zip(&sh) {
            let want = tl.intersect(r);
            assert_eq!(want.map(|h| (h.t.to_bits(), h.inst)), g.map(|h| (h.t.to_bits(), h.inst)), "{kernel:?}: {r:?}");
        }
    }
}

/// A hit's instance and primitive always belong together. Two instances of different
/// meshes that share one triangle at the same place give ties (equal `t` after the
/// division), and a tie that replaced the primitive without the instance once paired one
/// mesh's triangle index with another instance (the BART kitchen's coplanar parts panicked
/// the shader). Every kernel, single rays and packets.
#[test]
fn ties_between_instances_keep_instance_and_primitive_together() {
    // A triangle in general position (an axis-aligned one divides exactly and never ties).
    let shared = [Vec3::new(0.31, -1.13, 0.27), Vec3::new(1.73, 0.41, -0.52), Vec3::new(-0.66, 1.29, 0.93)];
    // Mesh 0: the shared triangle alone. Mesh 1: nine small far-away triangles, then the
    // shared triangle as number 9.
    let mut p1 = Vec::new();
    let mut i1 = Vec::new();
    for k in 0..9u32 {
        let o = Vec3::new(10.0 + k as f32, 10.0, 10.0);
        p1.extend([o, o + Vec3::X * 0.1, o + Vec3::Y * 0.1]);
        i1.push([3 * k, 3 * k + 1, 3 * k + 2]);
    }
    p1.extend(shared);
    i1.push([27, 28, 29]);
    let counts = [1u32, 10];
    let geoms = vec![
        Geometry::Mesh(MeshBvh::build(&shared, &[[0, 1, 2]], MeshOptions::default()).expect("a")),
        Geometry::Mesh(MeshBvh::build(&p1, &i1, MeshOptions::default()).expect("b")),
    ];
    let insts = vec![Instance::new(0, Affine3A::IDENTITY), Instance::new(1, Affine3A::IDENTITY), Instance::new(0, Affine3A::IDENTITY)];
    let mut rng = Pcg64::seed_from_u64(8);
    let rays: Vec<Ray> = (0..4096)
        .map(|_| {
            let o = Vec3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(3.0..9.0));
            let (a, b) = (rng.random_range(0.05..0.45f32), rng.random_range(0.05..0.45f32));
            let target = shared[0] + (shared[1] - shared[0]) * a + (shared[2] - shared[0]) * b;
            Ray::new(o, target - o)
        })
        .collect();
    for kernel in Kernel::available() {
        let mut tl = TwoLevel::new(geoms.clone(), insts.clone()).expect("tlas");
        tl.set_kernel(kernel);
        let mut packed = vec![None; rays.len()];
        tl.intersect_packet(&rays, &mut packed);
        for (r, p) in rays.iter().zip(&packed) {
            for h in [tl.intersect(r), *p] {
                let h = h.expect("every ray meets the shared triangle");
                let mesh = insts[h.inst as usize].geometry as usize;
                assert!(h.prim < counts[mesh], "{kernel:?}: instance {} (mesh {mesh}) with triangle {}", h.inst, h.prim);
            }
        }
    }
}

#[test]
fn clustered_top_level_gives_every_instance_its_own_slot() {
    use lucent_accel::build::{build_binary, build_clustered, BuildConfig, PrimRef};
    use lucent_accel::wide::{collapse_spread, leaf_range, WideNode, EMPTY, LEAF};
    use lucent_accel::Aabb;
    let mut rng = Pcg64::seed_from_u64(11);
    for n in [1usize, 5, 33, 300, 5000] {
        let boxes: Vec<Aabb> = (0..n)
            .map(|_| {
                let c = Vec3::new(rng.random(), rng.random(), rng.random()) * 100.0;
                let e = Vec3::new(rng.random(), rng.random(), rng.random()) * 2.0;
                Aabb { min: c - e, max: c + e }
            })
            .collect();
        let prims: Vec<PrimRef> = boxes.iter().enumerate().map(|(i, b)| PrimRef::new(*b, i as u32)).collect();
        let cfg = BuildConfig { max_leaf: 2, leaf_block: 1, cost_traverse: 1.0, median_max: 8, spatial: 0.0 };
        let bin = build_clustered(prims.clone(), &cfg, 8);
        bin.validate(&BuildConfig { max_leaf: 8, ..cfg }).unwrap_or_else(|e| panic!("{n}: {e}"));
        let mut nodes: Vec<WideNode<8>> = Vec::new();
        collapse_spread::<8>(&bin, &mut nodes).expect("collapse");
        // Every instance in exactly one slot of its own, inside every box above it.
        let mut seen = vec![0u32; n];
        let mut stack = vec![(0u32, Aabb { min: Vec3::splat(f32::NEG_INFINITY), max: Vec3::splat(f32::INFINITY) })];
        while let Some((i, outer)) = stack.pop() {
            let node = &nodes[WideNode::<8>::index_of(i)];
            for k in 0..8 {
                let c = node.child[k];
                if c == EMPTY {
                    continue;
                }
                let b = node.child_bounds(k);
                assert!(outer.contains(b.min) && outer.contains(b.max), "{n}: child box outside its parent's");
                if c & LEAF != 0 {
                    let (first, count) = leaf_range(c);
                    assert_eq!(count, 1, "{n}: a slot with {count} instances");
                    let id = bin.prims[first as usize].id() as usize;
                    assert_eq!((b.min, b.max), (boxes[id].min, boxes[id].max), "{n}: slot box is not the instance's");
                    seen[id] += 1;
                } else {
                    stack.push((c, b));
                }
            }
        }
        assert!(seen.iter().all(|&s| s == 1), "{n}: instances missing or repeated");
        if n >= 300 {
            // The wide tree costs little more than one over a fully binned tree (SAH of the
            // wide nodes: 12% and 15% more at 300 and 5000 boxes when written; the instances'
            // own boxes are the same in both).
            let mut full_nodes: Vec<WideNode<8>> = Vec::new();
            collapse_spread::<8>(&build_binary(prims, &cfg), &mut full_nodes).expect("collapse");
            let cost = |nodes: &[WideNode<8>]| -> f64 {
                let mut c = 0.0;
                for node in nodes {
                    for k in 0..8 {
                        if node.child[k] & LEAF == 0 {
                            c += f64::from(node.child_bounds(k).half_area());
                        }
                    }
                }
                c
            };
            let (c, f) = (cost(&nodes), cost(&full_nodes));
            eprintln!("{n}: wide-node SAH clustered {c:.0}, fully binned {f:.0}");
            assert!(c < 1.25 * f, "{n}: clustered wide-node SAH {c} against {f}");
        }
    }
}

/// A scene of one mesh in world space (one OBJ file) skips the object-space transform and
/// the top-level walk: its two-level answers, ray by ray and in packets, are the mesh's own.
#[test]
fn one_world_space_mesh_answers_like_the_mesh_itself() {
    let (mesh, rays) = soup_and_tile(11, 0.0);
    for kernel in Kernel::available() {
        let mut m = mesh.clone();
        m.set_kernel(kernel);
        let mut tl = TwoLevel::new(vec![Geometry::Mesh(m.clone())], vec![Instance::new(0, Affine3A::IDENTITY)]).expect("tlas");
        tl.set_kernel(kernel);
        let mut packet = vec![None; rays.len()];
        tl.intersect_packet(&rays, &mut packet);
        let mut blocked = vec![false; rays.len()];
        tl.occluded_packet(&rays, &mut blocked);
        for (i, r) in rays.iter().enumerate() {
            let want = m.intersect(r).map(|h| (h.t, h.prim));
            let single = tl.intersect(r);
            assert_eq!(single.map(|h| (h.t, h.prim)), want, "{kernel:?} ray {i}");
            assert!(single.is_none_or(|h| h.inst == 0));
            assert_eq!(packet[i].map(|h| h.t), want.map(|w| w.0), "{kernel:?} packet ray {i}");
            assert_eq!(tl.occluded(r), m.occluded(r), "{kernel:?} ray {i}");
            assert_eq!(blocked[i], m.occluded(r), "{kernel:?} packet ray {i}");
        }
    }
}

/// Rays streamed as SoA blocks (a run of many packets, starting at an odd block so the
/// slice is not line-aligned, with a short last packet and some empty lanes) give the
/// answers of the same rays one by one, with every kernel and width.
#[test]
fn streamed_blocks_match_single_rays() {
    let mut rng = Pcg64::seed_from_u64(41);
    let (p, idx) = soup(&mut rng, 3000, 1.0);
    let eye = Vec3::new(0.5, 0.5, -1.0);
    // 8x8 tiles of a 48x40 image (30 tiles, 240 blocks), then 3 blocks of random rays.
    let mut rays = Vec::new();
    for tile in 0..30 {
        let (tx, ty) = (tile % 6, tile / 6);
        for k in 0..64 {
            let (x, y) = (tx * 8 + k % 8, ty * 8 + k / 8);
            rays.push(Ray::new(eye, Vec3::new(x as f32 / 48.0 - 0.5, y as f32 / 40.0 - 0.5, 1.0).normalize()));
        }
    }
    for _ in 0..24 {
        rays.push(random_ray(&mut rng, 1.0));
    }
    let mut blocks: Vec<lucent_accel::RayBlock> = rays
        .chunks(8)
        .enumerate()
        .map(|(i, eight)| {
            let mut b = lucent_accel::RayBlock::EMPTY;
            for (l, r) in eight.iter().enumerate() {
                for k in 0..3 {
                    b.org[k][l] = r.org[k];
                    b.dir[k][l] = r.dir[k];
                }
                // Every thirteenth lane is left empty.
                b.tmin[l] = 0.0;
                b.tmax[l] = if (i * 8 + l) % 13 == 5 { f32::NEG_INFINITY } else { f32::INFINITY };
            }
            b
        })
        .collect();
    blocks.insert(0, lucent_accel::RayBlock::EMPTY);
    let stream = &blocks[1..];
    for (width, kernel) in all_variants() {
        let mut bvh = MeshBvh::build(&p, &idx, MeshOptions { width, ..MeshOptions::default() }).expect("build");
        bvh.set_kernel(kernel);
        let mut hits = vec![None; stream.len() * 8];
        let mut occ = vec![false; stream.len() * 8];
        bvh.intersect_blocks(stream, &mut hits);
        bvh.occluded_blocks(stream, &mut occ);
        let mut live = 0;
        for (i, b) in stream.iter().enumerate() {
            for l in 0..8 {
                let s = i * 8 + l;
                if b.tmax[l] < b.tmin[l] {
                    assert!(hits[s].is_none() && !occ[s], "{width:?} {kernel:?}: empty lane {s} answered");
                    continue;
                }
                live += 1;
                let r = Ray::new(Vec3::new(b.org[0][l], b.org[1][l], b.org[2][l]), Vec3::new(b.dir[0][l], b.dir[1][l], b.dir[2][l]));
                let want = bvh.intersect(&r);
                assert_eq!(hits[s].map(|h| h.t), want.map(|h| h.t), "{width:?} {kernel:?}: ray {s}");
                assert_eq!(occ[s], want.is_some(), "{width:?} {kernel:?}: ray {s}");
            }
        }
        assert!(live > stream.len() * 6, "most lanes carry rays");
    }
}

/// Packets from one point whose rays pass through the corners and along the edges of
/// separate squares (a checkerboard of two-triangle cells, each at its own distance), where
/// the whole-packet triangle cull's margins matter, and rays parallel to box faces: the
/// packet kernels give the single-ray answers, every kernel, in many orientations and at
/// several scales. Tiles also straddle the board's border and look past it.
#[test]
fn packets_through_corners_and_edges_match_single_rays() {
    let mut rng = Pcg64::seed_from_u64(77);
    let mut hits = 0;
    for case in 0..90 {
        let scale = [1e-3f32, 1.0, 1e3][case % 3];
        // Every other board faces the eye square on: then the tile's direction box (the
        // cull's bound) has rays at its corners, and the cull's margins are what keeps the
        // corner rays' hits.
        let rot = if case % 2 == 0 {
            Quat::IDENTITY
        } else {
            Quat::from_euler(glam::EulerRot::XYZ, rng.random::<f32>() * 6.3, rng.random::<f32>() * 6.3, rng.random::<f32>() * 6.3)
        };
        let eye = Vec3::new(rng.random(), rng.random(), rng.random()) * scale * 3.0;
        // Without the quarter-cell shift, square boards put the rays toward the grid's
        // axes exactly parallel to box faces, some of them lying in one (the slab test's
        // `0·(1/0)` case).
        let shift = if case % 3 == 0 { 0.0 } else { 0.25 };
        // Grid point (x, y) seen from the eye, at distance factor `f`.
        let place = |x: f32, y: f32, f: f32| eye + rot * (Vec3::new(x + shift, y + shift, 100.0) * scale) * f;
        let mut p = Vec::new();
        let mut idx = Vec::new();
        for j in 0..16 {
            for i in 0..16 {
                if (i + j) % 2 != 0 {
                    continue;
                }
                let f = 1.0 + 0.01 * ((i * 7 + j * 3) % 5) as f32;
                let (x, y) = (i as f32 - 8.0, j as f32 - 8.0);
                let b = p.len() as u32;
                p.extend([place(x, y, f), place(x + 1.0, y, f), place(x + 1.0, y + 1.0, f), place(x, y + 1.0, f)]);
                if case % 8 < 4 {
                    idx.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
                } else {
                    idx.extend([[b, b + 1, b + 3], [b + 1, b + 2, b + 3]]);
                }
            }
        }
        // An 8×8 tile aimed at grid points (steps of a half or a whole cell).
        let step = if case % 4 < 2 { 0.5 } else { 1.0 };
        let (x0, y0) = (rng.random_range(-11..4) as f32, rng.random_range(-11..4) as f32);
        let rays: Vec<Ray> =
            (0..64).map(|k| Ray::new(eye, place(x0 + step * (k % 8) as f32, y0 + step * (k / 8) as f32, 1.0) - eye)).collect();
        let mut bvh = MeshBvh::build(&p, &idx, MeshOptions::default()).expect("build");
        for kernel in Kernel::available() {
            bvh.set_kernel(kernel);
            let mut got = vec![None; 64];
            bvh.intersect_packet(&rays, &mut got);
            for (r, g) in rays.iter().zip(&got) {
                let want = bvh.intersect(r);
                hits += want.is_some() as usize;
                assert_eq!(g.map(|h| h.t), want.map(|h| h.t), "case {case} {kernel:?}: ray {r:?}");
            }
        }
    }
    assert!(hits > 1000, "the tiles see the board ({hits} hits)");
}

/// Every hit along a ray, against the brute-force list: both triangle tests, spatial
/// splits (one triangle in several leaves, reported once), instances of meshes and of
/// every analytic shape (met at each crossing), rays from inside and limited ranges.
#[test]
fn all_hits_match_reference() {
    let mut rng = Pcg64::seed_from_u64(41);
    let (p1, i1) = soup(&mut rng, 400, 1.0);
    let (p2, i2) = soup(&mut rng, 250, 1.0);
    let shapes = [Shape::Sphere, Shape::CappedCylinder, Shape::CappedCone, Shape::Box, Shape::Disk, Shape::Cylinder, Shape::Cone];
    for (test, watertight) in [(TriangleTest::UnitTriangle, false), (TriangleTest::Watertight, true)] {
        let opts = |width, quality| MeshOptions { width, test, quality, ..MeshOptions::default() };
        let mut geoms = vec![
            Geometry::Mesh(MeshBvh::build(&p1, &i1, opts(Width::W8, lucent_accel::Quality::Spatial)).expect("b1")),
            Geometry::Mesh(MeshBvh::build(&p2, &i2, opts(Width::W4, lucent_accel::Quality::Sah)).expect("b2")),
        ];
        let mut refs = vec![RefGeometry::Mesh(&p1, &i1), RefGeometry::Mesh(&p2, &i2)];
        for s in shapes {
            geoms.push(Geometry::Shape(s));
            refs.push(RefGeometry::Shape(s));
        }
        let mut placed = vec![(0u32, Affine3A::IDENTITY)];
        for k in 0..60u32 {
            let m = Affine3A::from_scale_rotation_translation(
                Vec3::splat(rng.random_range(0.3..1.5)),
                Quat::from_euler(glam::EulerRot::XYZ, rng.random(), rng.random(), rng.random()),
                Vec3::new(rng.random(), rng.random(), rng.random()) * 6.0,
            );
            placed.push((k % geoms.len() as u32, m));
        }
        let insts: Vec<Instance> = placed.iter().map(|&(g, m)| Instance::new(g, m)).collect();
        let tl = TwoLevel::new(geoms, insts).expect("tlas");
        let mut got = Vec::new();
        let mut total = 0;
        for i in 0..400 {
            let mut r = random_ray(&mut rng, 6.0);
            if i % 3 == 0 {
                r = r.with_range(rng.random_range(0.0..2.0), rng.random_range(2.0..8.0));
            }
            let want = lucent_accel::reference::all_hits_instances(&refs, &placed, &r, watertight);
            got.clear();
            tl.intersect_all(&r, &mut got);
            let key = |h: &lucent_accel::Hit| (h.t.to_bits(), h.inst, h.prim);
            assert_eq!(got.iter().map(key).collect::<Vec<_>>(), want.iter().map(key).collect::<Vec<_>>(), "{test:?}: ray {r:?}");
            let mut scratch = Vec::new();
            assert_eq!(tl.count_hits(&r, &mut scratch), want.len());
            // The closest of them is the closest hit.
            if let (Some(first), Some(h)) = (want.first(), tl.intersect(&r)) {
                assert!((first.t - h.t).abs() <= 1e-5 * h.t.max(1.0), "{test:?}: first of all {} vs closest {}", first.t, h.t);
            }
            total += want.len();
        }
        assert!(total > 400, "{test:?}: rays met {total} surfaces in all");
    }
}

//! Randomized stress test of every build quality: thousands of seeded meshes of every kind a
//! user can hand the builders (soups, grids, duplicates, degenerate, non-finite, huge and
//! tiny, coplanar, identical, and overlapping parts of very different sizes), each built,
//! checked for well-formedness and traced against the brute-force reference.
//!
//! It exists because the default build (`Quality::High`) once panicked on a 724-triangle
//! mesh of a public scene (`../shared/scenes/regressions/reinsert_root.obj`): a reinsertion
//! move that put a subtree beside the root and had to be undone. The `parts` family stands
//! for that class (a large part whose SAH split at the root is poor, so a grandchild of the
//! root is best moved up), and reproduces the panic without the fix.

use glam::{Affine3A, Quat, Vec3};
use lucent_accel::build::{build_binary, BuildConfig, PrimRef};
use lucent_accel::reference::{intersect_instances, intersect_triangles, occluded_triangles, RefGeometry};
use lucent_accel::{Aabb, Geometry, Instance, Kernel, MeshBvh, MeshOptions, Quality, Ray, TriangleTest, TwoLevel, Width};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

type Mesh = (Vec<Vec3>, Vec<[u32; 3]>);

/// Mesh families; every seed picks one.
const FAMILIES: [&str; 12] = [
    "soup",
    "grid",
    "duplicates",
    "degenerate",
    "non-finite",
    "huge",
    "beyond-range",
    "tiny",
    "mixed-scale",
    "coplanar",
    "identical",
    "parts",
];

fn v3(rng: &mut Pcg64) -> Vec3 {
    Vec3::new(rng.random(), rng.random(), rng.random())
}

/// A size from 1 to about 3000 triangles, log-uniform.
fn size(rng: &mut Pcg64) -> usize {
    (3000f64.powf(rng.random::<f64>())) as usize
}

fn soup(rng: &mut Pcg64, n: usize, scale: f32, spread: f32) -> Mesh {
    let mut p = Vec::with_capacity(3 * n);
    for _ in 0..n {
        let c = v3(rng) * scale;
        for _ in 0..3 {
            p.push(c + (v3(rng) - 0.5) * scale * spread);
        }
    }
    let idx = (0..n as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    (p, idx)
}

/// A closed box of `k`×`k` quads per face (shared vertices along the edges of a face).
fn boxy(lo: Vec3, hi: Vec3, k: u32, p: &mut Vec<Vec3>, idx: &mut Vec<[u32; 3]>) {
    for axis in 0..3 {
        for side in [0.0f32, 1.0] {
            let base = p.len() as u32;
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for j in 0..=k {
                for i in 0..=k {
                    let mut q = Vec3::ZERO;
                    q[axis] = side;
                    q[u] = i as f32 / k as f32;
                    q[v] = j as f32 / k as f32;
                    p.push(lo + q * (hi - lo));
                }
            }
            for j in 0..k {
                for i in 0..k {
                    let a = base + j * (k + 1) + i;
                    idx.push([a, a + 1, a + k + 2]);
                    idx.push([a, a + k + 2, a + k + 1]);
                }
            }
        }
    }
}

fn mesh(family: &str, rng: &mut Pcg64) -> Mesh {
    let n = size(rng);
    match family {
        "soup" => {
            let spread = [0.01, 0.1, 1.0][rng.random_range(0..3)];
            soup(rng, n, 10.0, spread)
        }
        "grid" => {
            let k = ((n as f32 / 2.0).sqrt().ceil() as u32).max(1);
            let bumpy = rng.random_bool(0.5);
            let mut p = Vec::new();
            for j in 0..=k {
                for i in 0..=k {
                    let h = if bumpy { rng.random::<f32>() * 0.3 } else { 0.0 };
                    p.push(Vec3::new(i as f32, h, j as f32));
                }
            }
            let mut idx = Vec::new();
            for j in 0..k {
                for i in 0..k {
                    let a = j * (k + 1) + i;
                    idx.push([a, a + 1, a + k + 2]);
                    idx.push([a, a + k + 2, a + k + 1]);
                }
            }
            (p, idx)
        }
        "duplicates" => {
            let (p, idx) = soup(rng, n.div_ceil(8).max(1), 5.0, 0.3);
            let copies = rng.random_range(2..=8);
            let all = (0..copies).flat_map(|_| idx.iter().copied()).collect();
            (p, all)
        }
        "degenerate" => {
            let (mut p, idx) = soup(rng, n, 10.0, 0.2);
            for t in &idx {
                match rng.random_range(0..4) {
                    0 => p[t[1] as usize] = p[t[0] as usize],                            // two corners equal
                    1 => p[t[2] as usize] = (p[t[0] as usize] + p[t[1] as usize]) * 0.5, // collinear
                    2 => (p[t[1] as usize], p[t[2] as usize]) = (p[t[0] as usize], p[t[0] as usize]), // a point
                    _ => {}
                }
            }
            (p, idx)
        }
        "non-finite" => {
            let (mut p, idx) = soup(rng, n, 10.0, 0.2);
            for q in p.iter_mut() {
                if rng.random_bool(0.2) {
                    q[rng.random_range(0..3)] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX][rng.random_range(0..4)];
                }
            }
            (p, idx)
        }
        // Near the largest coordinate lucent traces (`triangle::MAX_COORD`, 2^60), and past
        // it (left out of every build: nothing is hit).
        "huge" => soup(rng, n, 5e17, 0.1),
        "beyond-range" => soup(rng, n, 1e30, 0.1),
        "tiny" => soup(rng, n, 1e-30, 0.1),
        "mixed-scale" => {
            // Details of 1e-4 beside triangles of 1e4, and one of 1e36.
            let (mut p, mut idx) = soup(rng, n, 1e-4, 0.5);
            let (q, j) = soup(rng, n.div_ceil(10), 1e4, 0.5);
            let base = p.len() as u32;
            p.extend(q);
            idx.extend(j.iter().map(|t| t.map(|i| i + base)));
            let base = p.len() as u32;
            p.extend([Vec3::splat(-1e36), Vec3::new(1e36, -1e36, 0.0), Vec3::new(0.0, 1e36, 1e36)]);
            idx.push([base, base + 1, base + 2]);
            (p, idx)
        }
        "coplanar" => {
            let (mut p, idx) = soup(rng, n, 10.0, 0.2);
            let z = rng.random::<f32>();
            for q in p.iter_mut() {
                q.z = z;
            }
            (p, idx)
        }
        "identical" => {
            let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
            (p, vec![[0, 1, 2]; n])
        }
        "parts" => {
            // Overlapping tessellated boxes of very different sizes and a few outliers,
            // as in a robot's parts: the shape class of the reinsertion regression.
            let mut p = Vec::new();
            let mut idx = Vec::new();
            let parts = rng.random_range(2..12);
            while idx.len() < n.max(12) && p.len() < 20_000 {
                for _ in 0..parts {
                    let c = (v3(rng) - 0.5) * 2.0;
                    let e = Vec3::new(rng.random(), rng.random(), rng.random()) * [0.05f32, 0.5, 1.5][rng.random_range(0..3)];
                    boxy(c - e, c + e, rng.random_range(1..5), &mut p, &mut idx);
                }
            }
            idx.truncate(n.max(12));
            (p, idx)
        }
        _ => unreachable!("unknown family {family}"),
    }
}

/// Rays aimed at the mesh: at triangles' centroids and corners (where leaks and ties live),
/// and some in random directions, from outside and inside the bounds.
fn rays(rng: &mut Pcg64, (p, idx): &Mesh, count: usize) -> Vec<Ray> {
    let finite: Vec<Vec3> = p.iter().copied().filter(|q| q.is_finite()).collect();
    let b = Aabb::from_points(&finite);
    let (c, r) = if b.is_finite() && !b.is_empty() { (b.center(), b.extent().length().max(1e-30)) } else { (Vec3::ZERO, 1.0) };
    (0..count)
        .map(|i| {
            let o = c + (v3(rng) - 0.5).normalize_or(Vec3::X) * r * if i % 4 == 0 { 0.3 } else { 1.5 };
            let target = match (i % 3, idx.get(rng.random_range(0..idx.len().max(1)))) {
                (0, Some(t)) => (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0,
                (1, Some(t)) => p[t[rng.random_range(0..3)] as usize],
                _ => c + (v3(rng) - 0.5) * r,
            };
            let d = (target - o).normalize_or(Vec3::Y);
            Ray::new(o, if d.is_finite() { d } else { Vec3::Y })
        })
        .collect()
}

/// Closest distances agree: to the bit, or within a few ulps where neighbouring triangles
/// meet. The test compares `t·|D'z|` with `tmax·|D'z|` before its division, so among
/// hits less than an ulp apart the first one found wins, in the reference (mesh order) as
/// in a tree (traversal order): rays aimed at a grid's shared corners meet such ties.
fn same_t(a: f32, b: f32) -> bool {
    a == b || (a - b).abs() <= 4.0 * f32::EPSILON * a.abs().max(b.abs())
}

/// The built tree against the reference: the same closest distance (see [`same_t`]) on a
/// triangle that the ray really hits there, and the same any-hit answer.
fn check_hits(what: &str, bvh: &MeshBvh, (p, idx): &Mesh, rays: &[Ray]) {
    for r in rays {
        let want = intersect_triangles(p, idx, r);
        let got = bvh.intersect(r);
        match (want, got) {
            (None, None) => {}
            (Some(w), Some(g)) => {
                assert!(same_t(w.t, g.t), "{what}: t {} instead of {} for {r:?}", g.t, w.t);
                if (w.prim, w.t) != (g.prim, g.t) {
                    let alone = intersect_triangles(p, &idx[g.prim as usize..=g.prim as usize], r);
                    assert!(alone.is_some_and(|h| h.t == g.t), "{what}: prim {} instead of {} for {r:?}", g.prim, w.prim);
                }
            }
            _ => panic!("{what}: hit/miss differs for {r:?}: want {want:?} got {got:?}"),
        }
        assert_eq!(bvh.occluded(r), occluded_triangles(p, idx, r), "{what}: occluded differs for {r:?}");
    }
}

const QUALITIES: [(&str, Quality, bool); 4] =
    [("sah", Quality::Sah, false), ("high", Quality::High, false), ("spatial", Quality::Spatial, false), ("refit", Quality::High, true)];

/// Meshes per quality (every one of `FAMILIES` about equally often).
const MESHES: u64 = 1100;

#[test]
fn every_build_quality_survives_thousands_of_random_meshes() {
    let kernels = Kernel::available();
    let mut per_family = [0usize; FAMILIES.len()];
    for seed in 0..MESHES {
        let mut rng = Pcg64::seed_from_u64(seed);
        let f = (seed as usize) % FAMILIES.len();
        per_family[f] += 1;
        let m = mesh(FAMILIES[f], &mut rng);
        let rays = rays(&mut rng, &m, 24);
        for (qname, quality, refittable) in QUALITIES {
            let width = if seed.is_multiple_of(2) { Width::W8 } else { Width::W4 };
            let what = format!("seed {seed} ({}, {} tris) {qname} {width:?}", FAMILIES[f], m.1.len());
            let opts = MeshOptions { width, test: TriangleTest::UnitTriangle, refittable, quality };
            let mut bvh = MeshBvh::build(&m.0, &m.1, opts).unwrap_or_else(|e| panic!("{what}: {e}"));
            bvh.validate().unwrap_or_else(|e| panic!("{what}: {e}"));
            bvh.set_kernel(kernels[seed as usize % kernels.len()]);
            if refittable {
                // Deform (every vertex moved, some made degenerate or non-finite) and refit.
                let mut q = m.0.clone();
                for v in q.iter_mut() {
                    *v += (v3(&mut rng) - 0.5) * 0.05;
                    if rng.random_bool(0.02) {
                        *v = Vec3::splat(f32::NAN);
                    }
                }
                bvh.refit(&q, &m.1).unwrap_or_else(|e| panic!("{what}: refit: {e}"));
                bvh.validate().unwrap_or_else(|e| panic!("{what} refitted: {e}"));
                check_hits(&what, &bvh, &(q, m.1.clone()), &rays);
            } else {
                check_hits(&what, &bvh, &m, &rays);
            }
        }
    }
    eprintln!("stress: {MESHES} meshes × {} qualities; per family {per_family:?} ({FAMILIES:?})", QUALITIES.len());
}

/// A random top level: meshes, placements (hostile ones every fourth seed), rays.
struct TopCase {
    geoms: Vec<Mesh>,
    placements: Vec<(u32, Affine3A)>,
    rays: Vec<Ray>,
    hostile: bool,
}

fn top_case(seed: u64) -> TopCase {
    let mut rng = Pcg64::seed_from_u64(1_000_000 + seed);
    let geoms: Vec<Mesh> = (0..rng.random_range(1..4))
        .map(|_| {
            let f = rng.random_range(0..FAMILIES.len());
            let (p, mut idx) = mesh(FAMILIES[f], &mut rng);
            idx.truncate(300);
            (p, idx)
        })
        .collect();
    let hostile = seed.is_multiple_of(4);
    let placements: Vec<(u32, Affine3A)> = (0..rng.random_range(0..60))
        .map(|_| {
            let g = rng.random_range(0..geoms.len() as u32);
            let mut m = Affine3A::from_scale_rotation_translation(
                Vec3::splat(rng.random_range(0.1..3.0)),
                Quat::from_axis_angle((v3(&mut rng) - 0.5).normalize_or(Vec3::Z), rng.random::<f32>() * 6.0),
                (v3(&mut rng) - 0.5) * 40.0,
            );
            if hostile && rng.random_bool(0.3) {
                match rng.random_range(0..3) {
                    0 => m = Affine3A::from_scale(Vec3::ZERO),
                    1 => m.translation.x = f32::NAN,
                    _ => m.matrix3.x_axis.y = f32::INFINITY,
                }
            }
            (g, m)
        })
        .collect();
    let rays = (0..32)
        .map(|_| {
            let o = (v3(&mut rng) - 0.5) * 80.0;
            let target = (v3(&mut rng) - 0.5) * 40.0;
            Ray::new(o, (target - o).normalize_or(Vec3::X))
        })
        .collect();
    TopCase { geoms, placements, rays, hostile }
}

/// The top level over random instances of random meshes, including placements a user can
/// give by mistake (zero scale, non-finite entries): it builds, and wherever every
/// placement is invertible, traces as the reference does.
#[test]
fn the_top_level_survives_random_instances() {
    let mut levels = 0;
    for seed in 0..400u64 {
        let TopCase { geoms, placements, rays, hostile } = top_case(seed);
        let built: Vec<Geometry> =
            geoms.iter().map(|(p, i)| Geometry::Mesh(MeshBvh::build(p, i, MeshOptions::default()).expect("mesh build"))).collect();
        let instances = placements.iter().map(|&(g, m)| Instance::new(g, m)).collect();
        let mut tl = TwoLevel::new(built, instances).unwrap_or_else(|e| panic!("seed {seed}: top level: {e}"));
        levels += 1;
        let refs: Vec<RefGeometry<'_>> = geoms.iter().map(|(p, i)| RefGeometry::Mesh(p, i)).collect();
        for k in Kernel::available() {
            tl.set_kernel(k);
            for r in &rays {
                let got = tl.intersect(r);
                let _ = tl.occluded(r);
                if hostile {
                    continue;
                }
                let want = intersect_instances(&refs, &placements, r);
                assert!(
                    match (want, got) {
                        (Some(w), Some(g)) => same_t(w.t, g.t),
                        (w, g) => w.is_none() && g.is_none(),
                    },
                    "seed {seed} {k:?}: {got:?} instead of {want:?} for {r:?}"
                );
                assert_eq!(tl.occluded(r), want.is_some(), "seed {seed} {k:?}: occluded {r:?}");
            }
        }
        // Rebuilding after every instance moved (what dynamic scenes do each frame).
        tl.update_instances(|inst| {
            for i in inst.iter_mut() {
                *i = Instance::new(i.geometry, Affine3A::from_translation(Vec3::X) * i.world_from_object);
            }
        })
        .unwrap_or_else(|e| panic!("seed {seed}: rebuild: {e}"));
    }
    eprintln!("stress: {levels} top levels");
}

/// The binary builder and the optimization alone, on primitive boxes a library user may
/// pass (empty, inverted, non-finite, all equal): they build a valid tree or leave the bad
/// boxes out, and never panic.
#[test]
fn the_binary_builder_takes_any_boxes() {
    for seed in 0..600u64 {
        let mut rng = Pcg64::seed_from_u64(2_000_000 + seed);
        let n = size(&mut rng);
        let prims: Vec<PrimRef> = (0..n as u32)
            .map(|i| {
                let a = v3(&mut rng) * 10.0;
                let b = match rng.random_range(0..8) {
                    0 => a,                          // a point
                    1 => a - Vec3::ONE,              // inverted
                    2 => Vec3::splat(f32::NAN),      // not a number
                    3 => Vec3::splat(f32::INFINITY), // unbounded
                    4 => Vec3::splat(1.0),           // all alike
                    _ => a + v3(&mut rng),
                };
                PrimRef::new(Aabb { min: a.min(b), max: a.max(b) }, i)
            })
            .collect();
        for median_max in [0, 16] {
            let cfg = BuildConfig { median_max, ..BuildConfig::default() };
            let mut bin = build_binary(prims.clone(), &cfg);
            bin.validate(&cfg).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            lucent_accel::reinsert::optimize(&mut bin, &cfg);
            bin.validate(&cfg).unwrap_or_else(|e| panic!("seed {seed} optimized: {e}"));
        }
    }
}

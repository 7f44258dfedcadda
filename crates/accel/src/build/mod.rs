//! Binned SAH construction of the canonical binary BVH.
//!
//! Follows Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies" (RT 2007):
//! primitive centroids are binned along each axis, the surface area heuristic is evaluated
//! at every bin boundary, and primitives are partitioned in place. Subtrees above
//! [`PARALLEL_MIN`] primitives are built in parallel with `rayon::join`, and the binning of
//! very large nodes is itself parallel. Leaf cost counts SIMD blocks (`leaf_block`
//! primitives are tested at once), as Embree's builders do.
//!
//! - [`prim`]: settings, primitive references, the binary BVH, partitions;
//! - [`binned`]: the binned SAH builder, with `spatial` splits;
//! - [`morton`]: clustered and linear builders by Morton order.

pub mod binned;
pub mod morton;
pub mod prim;
pub(crate) mod spatial;

pub use binned::build_binary;
pub(crate) use binned::build_binary_with;
pub use morton::{build_clustered, build_clustered_into, build_lbvh, build_lbvh_into, MortonScratch};
pub use prim::{BinNode, BinaryBvh, BuildConfig, PrimRef, BINS, MAX_DEPTH, MAX_PRIMS, MEDIAN_DEPTH, PARALLEL_MIN};
pub use spatial::ALPHA;
pub(crate) use spatial::{NoClip, TriangleClip};

#[cfg(test)]
mod tests {
    use super::binned::*;
    use super::prim::*;
    use super::*;
    use crate::geom::Aabb;
    use glam::Vec3;
    use rand::{Rng, SeedableRng};

    /// Spatial splits on seeded soups of long, large and small triangles: the tree is
    /// valid, some triangles were split, the spare room is respected, and every point of
    /// every triangle (a barycentric grid, vertices and edges included) lies in the box of
    /// a leaf that holds that triangle.
    #[test]
    fn split_references_cover_their_triangles() {
        for seed in 0..6u64 {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            let n = [40usize, 2000, 5000][seed as usize % 3];
            let mut positions = Vec::new();
            let mut indices = Vec::new();
            for i in 0..n {
                // Mostly small triangles; every fifth spans most of the scene.
                let size = if i % 5 == 0 { 10.0 } else { 0.2 };
                let c = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
                for _ in 0..3 {
                    positions.push(c + (Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5) * size);
                }
                let v = 3 * i as u32;
                indices.push([v, v + 1, v + 2]);
            }
            let prims: Vec<PrimRef> = indices
                .iter()
                .enumerate()
                .map(|(i, t)| PrimRef::new(Aabb::from_points(&t.map(|v| positions[v as usize])), i as u32))
                .collect();
            let cfg = BuildConfig { spatial: 0.3, ..BuildConfig::default() };
            let bvh = build_binary_with(prims, &cfg, &TriangleClip { positions: &positions, indices: &indices });
            bvh.validate(&cfg).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            assert!(bvh.prims.len() <= n + (n as f32 * 0.3) as usize, "seed {seed}: spare room overrun");
            let mut leaves_of = vec![Vec::new(); n];
            let mut refs = 0;
            for node in bvh.nodes.iter().filter(|x| x.is_leaf()) {
                for p in &bvh.prims[node.first as usize..(node.first + node.count) as usize] {
                    leaves_of[p.id() as usize].push(node.bounds);
                    refs += 1;
                }
            }
            assert!(refs > n || n < spatial::MIN_REFS, "seed {seed}: no triangle was split ({refs} references)");
            for (id, t) in indices.iter().enumerate() {
                let v = t.map(|i| positions[i as usize]);
                // The points in f64, so that their own rounding does not leave the triangle.
                let inside = |bx: &Aabb, p: [f64; 3]| (0..3).all(|k| f64::from(bx.min[k]) <= p[k] && p[k] <= f64::from(bx.max[k]));
                for a in 0..=16 {
                    for b in 0..=16 - a {
                        let (s, u) = (f64::from(a) / 16.0, f64::from(b) / 16.0);
                        let p: [f64; 3] = std::array::from_fn(|k| {
                            let (x, y, z) = (f64::from(v[0][k]), f64::from(v[1][k]), f64::from(v[2][k]));
                            x * (1.0 - s - u) + y * s + z * u
                        });
                        assert!(
                            leaves_of[id].iter().any(|bx| inside(bx, p)),
                            "seed {seed}: triangle {id} point {p:?} is in none of its leaves"
                        );
                    }
                }
            }
        }
    }

    /// Both partitions against their definition, on sizes around their block boundaries
    /// and size limit, and with every share of right-hand elements (seeded).
    #[test]
    fn partitions_split_every_arrangement() {
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let b = PART_BLOCK;
        type Side = fn(&PrimRef) -> bool;
        let small: fn(&mut [PrimRef], Side) -> usize = |v, r| small_partition(v, r);
        let block: fn(&mut [PrimRef], Side) -> usize = |v, r| block_partition(v, r);
        let cases = (0..5 * b + 3).chain([16 * b, 16 * b + 1, 1000]).map(|n| (n, block, "block"));
        let cases = cases.chain((0..=SMALL_PART).map(|n| (n, small, "small")));
        for (n, partition, name) in cases {
            for share in [0u64, 1, 10, 50, 90, 99, 100] {
                let mut v: Vec<PrimRef> = (0..n)
                    .map(|i| {
                        let x = if next() % 100 < share { 1.0 } else { 0.0 };
                        PrimRef::new(Aabb { min: Vec3::splat(x), max: Vec3::splat(x) }, i as u32)
                    })
                    .collect();
                let right: Side = |p| p.min().x > 0.5;
                let want = v.iter().filter(|p| !right(p)).count();
                let mut before: Vec<(u32, bool)> = v.iter().map(|p| (p.id(), right(p))).collect();
                let nl = partition(&mut v, right);
                assert_eq!(nl, want, "{name}: n {n} share {share}");
                assert!(v[..nl].iter().all(|p| !right(p)) && v[nl..].iter().all(right), "{name}: n {n} share {share}");
                let mut after: Vec<(u32, bool)> = v.iter().map(|p| (p.id(), right(p))).collect();
                before.sort_unstable();
                after.sort_unstable();
                assert_eq!(before, after, "{name}: not a permutation: n {n} share {share}");
            }
        }
    }
}

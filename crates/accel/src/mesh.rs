//! The bottom-level index over one triangle mesh.

use crate::build::{BinNode, BinaryBvh, BuildConfig, PrimRef};
use crate::geom::{Aabb, Hit, Ray, INVALID};
use crate::kernel::{Kernel, KernelSet, ScalarSet};
use crate::traverse::{self, Counters, Leaves, RayPre, TraversalStats};
use crate::triangle::{
    in_range, tri4_intersect_scalar, tri4_occluded_scalar, unit_map_possible, unit_maps4_soa, Tri4, UnitTriangle, WatertightRay, NEVER_HIT,
};
use crate::wide::{collapse, leaf_code, leaf_range, WideNode, EMPTY, LEAF};
use glam::Vec3;
use rayon::prelude::*;

/// Errors of building an acceleration structure.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum BuildError {
    /// A triangle names a vertex that does not exist.
    #[error("triangle {tri} uses vertex {index}, but the mesh has only {vertices} vertices")]
    IndexOutOfRange {
        /// Triangle index.
        tri: usize,
        /// The bad vertex index.
        index: u32,
        /// Number of vertices.
        vertices: usize,
    },
    /// More primitives than the node encoding can address.
    #[error("too many primitives for one acceleration structure ({0})")]
    TooLarge(usize),
    /// An instance names a geometry that does not exist.
    #[error("instance {inst} uses geometry {geom}, but there are only {count}")]
    NoSuchGeometry {
        /// Instance index.
        inst: usize,
        /// The bad geometry index.
        geom: u32,
        /// Number of geometries.
        count: usize,
    },
}

/// Node width of the traversal layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Width {
    /// 4 children per node (SSE).
    W4,
    /// 8 children per node (AVX2).
    #[default]
    W8,
}

/// Which ray/triangle test the leaves use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TriangleTest {
    /// SaarCOR's unit-triangle test on precomputed affine maps (4 triangles at once).
    #[default]
    UnitTriangle,
    /// Woop–Benthin–Wald watertight test on the vertices.
    Watertight,
}

/// How hard the builder works for a better tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Quality {
    /// Binned SAH (parallel) only: the shortest build.
    Sah,
    /// Binned SAH with spatial splits (Stich, Friedrich & Dietrich 2009; see
    /// `build::spatial`): a triangle may be cut between leaves, each part with its own
    /// box, for at most `SPATIAL_SHARE` more references. It pays where large triangles
    /// overlap many small ones, and costs elsewhere. Measured on the shared scenes' single
    /// rays against `Sah` (1 thread): Sponza's primary rays 1.21×, diffuse 1.25×; the
    /// kitchen's shadow rays 0.56×; Conference and the museum 0.84–0.97×; the bunny
    /// unchanged. Builds take 1.5–1.9× as long. Meshes built `refittable` get plain SAH.
    Spatial,
    /// The default: binned SAH, then insertion-based optimization ([`crate::reinsert`],
    /// parallel). Single rays 5-15% faster than with `Sah` on four of the five shared
    /// scenes (the bunny's tree is left as it is), for builds 1.15-1.3× as long. Meshes
    /// built `refittable` (rebuilt while they deform) get plain SAH.
    #[default]
    High,
}

/// Options of a mesh build.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeshOptions {
    /// Node width.
    pub width: Width,
    /// Triangle test.
    pub test: TriangleTest,
    /// Keep zero-area triangles (with finite vertices) in the tree, as lanes that never hit,
    /// so that [`MeshBvh::refit`] can give them back their area when the mesh deforms.
    pub refittable: bool,
    /// Build quality.
    pub quality: Quality,
}

#[derive(Clone, Debug)]
pub(crate) enum Nodes {
    W4(Vec<WideNode<4>>),
    W8(Vec<WideNode<8>>),
}

/// Size and quality figures of a built structure.
#[derive(Clone, Copy, Debug, Default)]
pub struct BvhStats {
    /// Wide nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Primitives indexed (degenerate and non-finite ones are left out).
    pub prims: usize,
    /// References in the leaves: `prims`, plus the parts that spatial splits made.
    pub refs: usize,
    /// SAH cost of the binary tree (relative to the root's area).
    pub sah: f32,
    /// SAH cost of the wide tree in Embree's convention (`BVHNStatistics::sah`, printed by
    /// Embree with `verbose=2`): each wide node 1 and each block of four triangles 1, at
    /// their boxes' areas relative to the root's, as built. Compares tree quality with
    /// Embree's. (0 for a top level.)
    pub wide_sah: f32,
    /// Bytes of nodes plus leaf data.
    pub bytes: usize,
}

/// A BVH over one triangle mesh (a BLAS).
#[derive(Clone, Debug)]
pub struct MeshBvh {
    pub(crate) nodes: Nodes,
    pub(crate) tris: Vec<Tri4>,
    pub(crate) wt_verts: Vec<[Vec3; 3]>,
    pub(crate) wt_ids: Vec<u32>,
    pub(crate) test: TriangleTest,
    bounds: Aabb,
    kernel: Kernel,
    stats: BvhStats,
    /// `tree_cost()` as built (the reference for refits), computed at the first refit
    /// before it changes the tree. PERF: not at the build (a sequential walk of the tree,
    /// 2% of the kitchen's build on 2 threads).
    built_cost: Option<f32>,
}

/// Triangles past a leaf whose vertex indices the leaf fill asks for in advance.
const PREFETCH_AHEAD: usize = 8;

/// Triangles per task of the build's first pass (which triangles are kept).
const PREP_CHUNK: usize = 512;

/// Most triangles in one leaf of a mesh BVH.
const MAX_LEAF: usize = 8;

/// Most extra references [`Quality::Spatial`] adds, as a share of the triangles (Embree's
/// spatial-split builder allows a similar budget).
pub const SPATIAL_SHARE: f32 = 0.3;

impl MeshBvh {
    /// Builds the BVH of triangles `indices` over `positions`. Triangles with non-finite
    /// vertices or zero area are left out (no ray can hit them).
    pub fn build(positions: &[Vec3], indices: &[[u32; 3]], opts: MeshOptions) -> Result<Self, BuildError> {
        let nv = positions.len();
        if let Some((tri, index)) = indices.iter().enumerate().find_map(|(t, i)| i.iter().find(|&&v| v as usize >= nv).map(|&v| (t, v))) {
            return Err(BuildError::IndexOutOfRange { tri, index, vertices: nv });
        }
        if indices.len() >= (1 << 29) {
            return Err(BuildError::TooLarge(indices.len()));
        }
        let verts = |t: &[u32; 3]| [positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize]];
        let n = indices.len();
        let refittable = opts.refittable;
        // Two indexed parallel passes over chunks of triangles. The first finds which
        // triangles are kept (those a ray can hit, or with a refit every finite one) and
        // counts them per chunk; the second writes the kept triangles' references, each
        // chunk at its place in the packed array. PERF: a sequential `retain` of the
        // references was 2 ms of Conference's 50 ms. The unit-triangle maps are made
        // later, leaf by leaf, from the vertices: made here in mesh order, they were
        // copied into the leaves in tree order, a scattered read of 36 bytes per triangle
        // from an array larger than the cache (a tenth of the kitchen's build).
        let mut keep: Vec<bool> = Vec::with_capacity(n);
        let mut kept: Vec<usize> = Vec::new();
        keep.spare_capacity_mut()[..n]
            .par_chunks_mut(PREP_CHUNK)
            .zip(indices.par_chunks(PREP_CHUNK))
            .map(|(k_out, idx)| {
                let mut count = 0;
                for (k_out, t) in k_out.iter_mut().zip(idx) {
                    let v = verts(t);
                    let k = unit_map_possible(v[0], v[1], v[2]) || refittable && v.iter().all(|&p| in_range(p));
                    k_out.write(k);
                    count += usize::from(k);
                }
                count
            })
            .collect_into_vec(&mut kept);
        // SAFETY: the chunks above tile `[0, n)` of the spare capacity (`indices` has `n`
        // entries, chunked alike) and every slot of every chunk was written.
        unsafe { keep.set_len(n) };
        let total: usize = kept.iter().sum();
        let mut prims: Vec<PrimRef> = Vec::with_capacity(total);
        let mut rest = &mut prims.spare_capacity_mut()[..total];
        let mut outs = Vec::with_capacity(kept.len());
        for &k in &kept {
            let (mine, tail) = rest.split_at_mut(k);
            outs.push(mine);
            rest = tail;
        }
        outs.into_par_iter().zip(keep.par_chunks(PREP_CHUNK)).enumerate().for_each(|(c, (out, keep))| {
            let ids = (c * PREP_CHUNK..).zip(keep).filter(|(_, k)| **k).map(|(i, _)| i);
            for (slot, i) in out.iter_mut().zip(ids) {
                slot.write(PrimRef::new(Aabb::from_points(&verts(&indices[i])), i as u32));
            }
        });
        // SAFETY: the chunk outputs tile `[0, total)`, and chunk `c` has exactly `kept[c]`
        // kept triangles (counted above from the same `keep` flags), so every slot was written.
        unsafe { prims.set_len(total) };
        let cfg = BuildConfig {
            max_leaf: MAX_LEAF,
            leaf_block: if opts.test == TriangleTest::UnitTriangle { 4 } else { 1 },
            cost_traverse: 1.0,
            median_max: 0,
            // A refit would loosen the parts' boxes to whole triangles.
            spatial: if opts.quality == Quality::Spatial && !refittable { SPATIAL_SHARE } else { 0.0 },
        };
        let mut bin = if cfg.spatial > 0.0 {
            crate::build::build_binary_with(prims, &cfg, &crate::build::TriangleClip { positions, indices })
        } else {
            // The first pass kept only triangles with finite, non-empty boxes.
            crate::build::build_binary_with(prims, &cfg, &crate::build::NoClip)
        };
        // Insertion-based optimization (`Quality::High`) moves subtrees between inner nodes
        // only: leaves keep their indices and primitive ranges, so the leaves' triangle
        // groups can be numbered and filled while it runs. Returns the tree's SAH cost.
        let optimize = |nodes: &mut [BinNode]| {
            if opts.quality == Quality::High && !refittable {
                crate::reinsert::optimize_nodes(nodes, &cfg).1
            } else {
                BinaryBvh::cost_of(nodes, &cfg)
            }
        };
        let bounds = bin.nodes.first().map_or(Aabb::EMPTY, |n| n.bounds);
        let too_large = || BuildError::TooLarge(indices.len());
        let mut wt_verts = Vec::new();
        let mut wt_ids = Vec::new();
        let mut tris: Vec<Tri4> = Vec::new();
        let (nodes, leaves, sah) = match opts.test {
            TriangleTest::UnitTriangle => {
                // Every binary leaf becomes one wide leaf, so each gets its range of
                // 4-triangle groups here, in the binary tree's order, before the collapse.
                // The groups are then filled in parallel while the collapse (sequential)
                // runs. PERF: filled after the collapse, they waited for it (5% of the
                // kitchen's build on 2 threads); the fill was ~15% of a sequential build.
                let mut start_of = vec![u32::MAX; bin.prims.len()]; // by the leaf's first prim
                let mut leaf_groups: Vec<(u32, u32, u32)> = Vec::new(); // (first prim, count, first group)
                let mut next_group = 0u32;
                for n in bin.nodes.iter().filter(|n| n.is_leaf()) {
                    if let Some(s) = start_of.get_mut(n.first as usize) {
                        *s = next_group;
                    }
                    leaf_groups.push((n.first, n.count, next_group));
                    next_group += n.count.div_ceil(4);
                }
                let total = next_group as usize;
                tris.reserve_exact(total);
                // Hand every leaf its own slice of the uninitialised storage (the leaves were
                // numbered in order, so their group ranges tile [0, total)).
                let mut rest = &mut tris.spare_capacity_mut()[..total];
                let mut jobs = Vec::with_capacity(leaf_groups.len());
                for &(first, count, _) in &leaf_groups {
                    let (mine, tail) = rest.split_at_mut(count.div_ceil(4) as usize);
                    jobs.push((first, count, mine));
                    rest = tail;
                }
                let fill = |(first, count, out): (u32, u32, &mut [std::mem::MaybeUninit<Tri4>]), prims: &[PrimRef]| {
                    let by_area = largest_first(&prims[first as usize..(first + count) as usize]);
                    let ids = &by_area[..count as usize];
                    // PERF: the triangles are read in tree order, scattered over the mesh's
                    // order, and each read waited on memory. Ask in two stages, for the
                    // triangles past this leaf (the next leaves' ranges follow this one's):
                    // the vertex indices of those PREFETCH_AHEAD to twice that ahead, and
                    // the vertices of the nearer ones, whose indices were asked for earlier.
                    let end = (first + count) as usize;
                    for p in prims.get(end + PREFETCH_AHEAD..).unwrap_or(&[]).iter().take(PREFETCH_AHEAD) {
                        crate::traverse::prefetch(&indices[p.id() as usize]);
                    }
                    for p in prims.get(end..).unwrap_or(&[]).iter().take(PREFETCH_AHEAD) {
                        for &v in &indices[p.id() as usize] {
                            crate::traverse::prefetch(&positions[v as usize]);
                        }
                    }
                    for (slot, chunk) in out.iter_mut().zip(ids.chunks(4)) {
                        // Four maps at once, already in the group's SoA form; a short chunk
                        // repeats its first triangle in the unused lanes, which then get the
                        // padding map.
                        let mut v = [verts(&indices[chunk[0] as usize]); 4];
                        for (vv, &id) in v.iter_mut().zip(chunk).skip(1) {
                            *vv = verts(&indices[id as usize]);
                        }
                        let (m, axes, _) = unit_maps4_soa(&v);
                        let mut t4 = Tri4 { m, prim: [u32::MAX; 4] };
                        for (lane, &id) in chunk.iter().enumerate() {
                            t4.prim[lane] = Tri4::prim_of(id, axes[lane]);
                        }
                        for lane in chunk.len()..4 {
                            t4.pad(lane);
                        }
                        slot.write(t4);
                    }
                };
                let mut make_leaf = |first: u32, count: u32| -> Result<u32, BuildError> {
                    let start = start_of.get(first as usize).copied().unwrap_or(u32::MAX);
                    leaf_code(start, count.div_ceil(4)).ok_or_else(too_large)
                };
                // The optimization and the collapse (sequential) beside the fill.
                let ntris = bin.prims.len();
                let BinaryBvh { nodes: bnodes, prims: bprims } = &mut bin;
                let bprims = &*bprims;
                let ((nodes, sah), ()) = rayon::join(
                    || {
                        let sah = optimize(bnodes);
                        (collapse_to(opts.width, bnodes, ntris, cfg.leaf_block as u32, &mut make_leaf), sah)
                    },
                    || jobs.into_par_iter().for_each(|j| fill(j, bprims)),
                );
                // SAFETY: the leaves' group ranges tile [0, total) and every group of every
                // leaf was written by `fill` (a leaf of `count` triangles has
                // `count.div_ceil(4)` groups, one per chunk of 4), so all `total` elements
                // are initialised.
                unsafe { tris.set_len(total) };
                (nodes?, leaf_groups.len(), sah)
            }
            TriangleTest::Watertight => {
                let mut leaves = 0;
                let mut make_leaf = |first: u32, count: u32| -> Result<u32, BuildError> {
                    let start = wt_ids.len() as u32;
                    let by_area = largest_first(&bin.prims[first as usize..(first + count) as usize]);
                    for &id in &by_area[..count as usize] {
                        wt_verts.push(verts(&indices[id as usize]));
                        wt_ids.push(id);
                    }
                    leaves += 1;
                    leaf_code(start, count).ok_or_else(too_large)
                };
                let sah = optimize(&mut bin.nodes);
                let nodes = collapse_to(opts.width, &bin.nodes, bin.prims.len(), cfg.leaf_block as u32, &mut make_leaf)?;
                (nodes, leaves, sah)
            }
        };
        let (n_nodes, node_bytes) = match &nodes {
            Nodes::W4(n) => (n.len(), std::mem::size_of_val(n.as_slice())),
            Nodes::W8(n) => (n.len(), std::mem::size_of_val(n.as_slice())),
        };
        let bytes = node_bytes + std::mem::size_of_val(tris.as_slice()) + std::mem::size_of_val(wt_verts.as_slice()) + 4 * wt_ids.len();
        let refs = bin.nodes.iter().filter(|n| n.is_leaf()).map(|n| n.count as usize).sum();
        let stats = BvhStats { nodes: n_nodes, leaves, prims: total, refs, sah, wide_sah: 0.0, bytes };
        let me = Self { nodes, tris, wt_verts, wt_ids, test: opts.test, bounds, kernel: Kernel::detect(), stats, built_cost: None };
        Ok(me)
    }

    /// Moves the triangles to new vertex `positions` (same triangles, same order as at the
    /// build) and refits every box bottom-up, keeping the tree. Returns the tree's SAH cost
    /// relative to its cost when it was built: a deformation that scatters neighbours
    /// makes boxes overlap and the ratio grow, and the caller rebuilds when it is too large.
    /// Triangles left out of the build (non-finite, or zero-area without
    /// `MeshOptions::refittable`) stay out.
    pub fn refit(&mut self, positions: &[Vec3], indices: &[[u32; 3]]) -> Result<f32, BuildError> {
        let nv = positions.len();
        if let Some((tri, index)) = indices.iter().enumerate().find_map(|(t, i)| i.iter().find(|&&v| v as usize >= nv).map(|&v| (t, v))) {
            return Err(BuildError::IndexOutOfRange { tri, index, vertices: nv });
        }
        let built = match self.built_cost {
            Some(c) => c,
            None => *self.built_cost.insert(self.tree_cost()),
        };
        let verts = |id: u32| indices.get(id as usize).map(|t| t.map(|i| positions[i as usize]));
        // Triangle data: new unit-triangle maps (or vertices), in place.
        let remap = |t4: &mut Tri4| {
            for lane in 0..4 {
                if t4.is_pad(lane) {
                    continue;
                }
                let id = t4.id(lane);
                let m = verts(id).and_then(|v| UnitTriangle::new(v[0], v[1], v[2])).unwrap_or(NEVER_HIT);
                t4.set(lane, &m, id);
            }
        };
        // Small meshes: one thread (waking the pool costs more than the work).
        if self.tris.len() > 2048 {
            self.tris.par_iter_mut().for_each(remap);
        } else {
            self.tris.iter_mut().for_each(remap);
        }
        for (slot, &id) in self.wt_verts.iter_mut().zip(&self.wt_ids) {
            if let Some(v) = verts(id) {
                *slot = v;
            }
        }
        // Boxes, bottom-up from the root.
        let leaf_box = |code: u32, tris: &[Tri4], wt_ids: &[u32]| -> Aabb {
            let (first, count) = leaf_range(code);
            let mut b = Aabb::EMPTY;
            let ids: Vec<u32> = if tris.is_empty() {
                wt_ids[first as usize..(first + count) as usize].to_vec()
            } else {
                tris[first as usize..(first + count) as usize].iter().flat_map(Tri4::ids).collect()
            };
            // A triangle with a corner out of range can't be hit (its lane never hits); its
            // box would spread NaN or infinity into the node's and lose the whole subtree.
            for id in ids {
                if let Some(v) = verts(id).filter(|v| v.iter().all(|&p| in_range(p))) {
                    b = b.union(Aabb::from_points(&v));
                }
            }
            b
        };
        fn refit_node<const W: usize>(nodes: &mut [WideNode<W>], i: usize, leaf: &dyn Fn(u32) -> Aabb) -> Aabb {
            let mut total = Aabb::EMPTY;
            for k in 0..W {
                let code = nodes[i].child[k];
                if code == EMPTY {
                    continue;
                }
                let b = if code & LEAF != 0 { leaf(code) } else { refit_node(nodes, WideNode::<W>::index_of(code), leaf) };
                nodes[i].set(k, &b, code);
                total = total.union(b);
            }
            total
        }
        let (tris, wt_ids) = (&self.tris, &self.wt_ids);
        let leaf = |code: u32| leaf_box(code, tris, wt_ids);
        self.bounds = match &mut self.nodes {
            Nodes::W4(n) if !n.is_empty() => refit_node(n, 0, &leaf),
            Nodes::W8(n) if !n.is_empty() => refit_node(n, 0, &leaf),
            _ => Aabb::EMPTY,
        };
        let cost = self.tree_cost();
        Ok(if built > 0.0 { cost / built } else { 1.0 })
    }

    /// SAH cost of the wide tree as it is (node boxes and leaf sizes; traversal step 1,
    /// triangle test 1), relative to the root box.
    fn tree_cost(&self) -> f32 {
        self.wide_costs().0
    }

    /// Two SAH costs of the wide tree as it is, relative to the root box, from one walk:
    /// `.0` with a traversal step and a triangle test costing 1 each (the refit reference),
    /// `.1` in Embree's convention (its `BVHNStatistics::sah`): every wide node 1 at its box,
    /// every block of four triangles 1 at its leaf's box, the root node included.
    fn wide_costs(&self) -> (f32, f32) {
        fn area(b: &Aabb) -> f32 {
            let d = (b.max - b.min).max(Vec3::ZERO);
            if d.is_finite() {
                2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
            } else {
                0.0
            }
        }
        fn walk<const W: usize>(nodes: &[WideNode<W>], tri_groups: bool) -> (f32, f32) {
            let (mut c, mut e) = (0.0, 0.0);
            for n in nodes {
                for k in 0..W {
                    let code = n.child[k];
                    if code == EMPTY {
                        continue;
                    }
                    let a = area(&n.child_bounds(k));
                    if code & LEAF != 0 {
                        let items = leaf_range(code).1 as f32;
                        // Groups of four, or single triangles (watertight leaves).
                        let (tris, blocks) = if tri_groups { (items * 4.0, items) } else { (items, (items / 4.0).ceil()) };
                        c += a * tris;
                        e += a * blocks;
                    } else {
                        c += a;
                        e += a;
                    }
                }
            }
            (c, e)
        }
        let root = area(&self.bounds).max(1e-30);
        let groups = !self.tris.is_empty();
        let (c, e) = match &self.nodes {
            Nodes::W4(n) => walk(n, groups),
            Nodes::W8(n) => walk(n, groups),
        };
        (c / root, 1.0 + e / root)
    }

    /// Bounds of the indexed triangles.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// [`Self::stats`] without the figures worked out on demand (`wide_sah` is 0).
    #[must_use]
    pub(crate) fn stats_counts(&self) -> BvhStats {
        self.stats
    }

    /// Size and quality figures.
    #[must_use]
    pub fn stats(&self) -> BvhStats {
        // The SAH in Embree's convention is worked out here, when asked for, not at the
        // build (a sequential walk of the tree).
        BvhStats { wide_sah: self.wide_costs().1, ..self.stats }
    }

    /// The kernel queries run.
    #[must_use]
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// Chooses the kernel (falls back to scalar when the CPU lacks the SIMD one).
    pub fn set_kernel(&mut self, k: Kernel) {
        self.kernel = k.supported();
    }

    /// Closest hit of `ray` (`inst` is `INVALID`).
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        // PERF: the ray constants are made inside the kernel function, so they stay in
        // registers instead of a store and reload across the call.
        match self.kernel {
            // SAFETY: `Kernel::Simd` is only ever set when AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd => unsafe { simd_intersect(self, ray) },
            // SAFETY: `Kernel::Avx512` is only set when AVX-512F/VL (and AVX2, FMA) were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => unsafe { avx512_intersect(self, ray) },
            _ => {
                let mut hit = Hit::none(ray.tmax);
                self.intersect_k::<ScalarSet, ()>(&RayPre::new(ray), &mut hit, &mut ());
                hit.is_hit().then_some(hit)
            }
        }
    }

    /// True when anything blocks `ray` within `[tmin, tmax)`.
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        match self.kernel {
            // SAFETY: as in `intersect`.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd => unsafe { simd_occluded(self, ray) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => unsafe { avx512_occluded(self, ray) },
            _ => self.occluded_k::<ScalarSet, ()>(&RayPre::new(ray), ray.tmax, &mut ()),
        }
    }

    /// Closest-hit query with kernel set `K`; returns true when this mesh wrote `hit` (the
    /// caller then owns it and sets its instance).
    #[inline(always)]
    pub(crate) fn intersect_k<K: KernelSet, C: Counters>(&self, pre: &RayPre, hit: &mut Hit, c: &mut C) -> bool {
        // Whether this mesh replaced the hit is told by the primitive the leaves write, not
        // by a smaller `t`: the scaled range test can accept a triangle whose divided-out `t`
        // rounds to the current one (a tie), and the caller must then take the instance
        // too, or the hit pairs one mesh's triangle with another instance.
        let before = hit.prim;
        hit.prim = INVALID;
        // SAFETY (all arms): the caller selected K for this CPU.
        let unit = UnitLeaves::<K>::new(&self.tris);
        match (self.test, &self.nodes) {
            (TriangleTest::UnitTriangle, Nodes::W8(n)) => unsafe { traverse::intersect::<8, K::B8, _, _>(n, &unit, pre, hit, c) },
            (TriangleTest::UnitTriangle, Nodes::W4(n)) => unsafe { traverse::intersect::<4, K::B4, _, _>(n, &unit, pre, hit, c) },
            (TriangleTest::Watertight, Nodes::W8(n)) => unsafe { traverse::intersect::<8, K::B8, _, _>(n, &self.wt_leaves(), pre, hit, c) },
            (TriangleTest::Watertight, Nodes::W4(n)) => unsafe { traverse::intersect::<4, K::B4, _, _>(n, &self.wt_leaves(), pre, hit, c) },
        }
        if hit.prim == INVALID {
            hit.prim = before;
            false
        } else {
            unit.finish(hit);
            true
        }
    }

    #[inline(always)]
    pub(crate) fn occluded_k<K: KernelSet, C: Counters>(&self, pre: &RayPre, tmax: f32, c: &mut C) -> bool {
        // SAFETY (all arms): the caller selected K for this CPU.
        match (self.test, &self.nodes) {
            (TriangleTest::UnitTriangle, Nodes::W8(n)) => unsafe {
                traverse::occluded::<8, K::B8, _, _>(n, &UnitLeaves::<K>::new(&self.tris), pre, tmax, c)
            },
            (TriangleTest::UnitTriangle, Nodes::W4(n)) => unsafe {
                traverse::occluded::<4, K::B4, _, _>(n, &UnitLeaves::<K>::new(&self.tris), pre, tmax, c)
            },
            (TriangleTest::Watertight, Nodes::W8(n)) => unsafe { traverse::occluded::<8, K::B8, _, _>(n, &self.wt_leaves(), pre, tmax, c) },
            (TriangleTest::Watertight, Nodes::W4(n)) => unsafe { traverse::occluded::<4, K::B4, _, _>(n, &self.wt_leaves(), pre, tmax, c) },
        }
    }

    /// Closest hit, counting the work into `stats` (scalar kernel: same answers as the
    /// fast ones, and the same nodes visited).
    pub fn intersect_with_stats(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit> {
        let mut hit = Hit::none(ray.tmax);
        self.intersect_k::<ScalarSet, _>(&RayPre::new(ray), &mut hit, stats);
        hit.is_hit().then_some(hit)
    }

    /// Any-hit query counting the work into `stats` (scalar kernel).
    pub fn occluded_with_stats(&self, ray: &Ray, stats: &mut TraversalStats) -> bool {
        self.occluded_k::<ScalarSet, _>(&RayPre::new(ray), ray.tmax, stats)
    }

    fn wt_leaves(&self) -> WtLeaves<'_> {
        WtLeaves { verts: &self.wt_verts, ids: &self.wt_ids, ray: std::cell::Cell::new(None) }
    }

    /// Checks the node structure: every child index in range, every leaf range in range.
    pub fn validate(&self) -> Result<(), String> {
        fn check<const W: usize>(nodes: &[WideNode<W>], items: usize) -> Result<(), String> {
            for (i, n) in nodes.iter().enumerate() {
                for &c in &n.child {
                    if c == crate::wide::EMPTY {
                        continue;
                    }
                    if c & crate::wide::LEAF != 0 {
                        let (f, k) = crate::wide::leaf_range(c);
                        if (f + k) as usize > items {
                            return Err(format!("node {i}: leaf {f}+{k} beyond {items} items"));
                        }
                    } else {
                        let j = WideNode::<W>::index_of(c);
                        if c % WideNode::<W>::STRIDE != 0 || j >= nodes.len() || j <= i {
                            return Err(format!("node {i}: child code {c} not a node after it"));
                        }
                    }
                }
            }
            Ok(())
        }
        let items = if self.test == TriangleTest::UnitTriangle { self.tris.len() } else { self.wt_ids.len() };
        match &self.nodes {
            Nodes::W4(n) => check(n, items),
            Nodes::W8(n) => check(n, items),
        }
    }
}

/// An optimal 19-comparator sorting network for eight keys (Knuth, The Art of Computer
/// Programming vol. 3, §5.3.4), applied largest first by [`largest_first`]; the tests check
/// it on all 256 inputs of zeros and ones, which by the 0-1 principle covers every input.
const LEAF_SORT_NET: [(usize, usize); 19] = [
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (2, 4),
    (3, 5),
    (1, 4),
    (3, 6),
    (1, 2),
    (3, 4),
    (5, 6),
];

/// The triangle ids of one leaf, largest triangle first (by box area), so an any-hit
/// query, which stops at the first triangle that blocks it, meets the triangles most likely
/// to block first. Stable: equal areas keep the tree's order. PERF: the BART kitchen's
/// shadow rays end in their first leaf (1.3 nodes per ray), and its single shadow rays
/// moved by -25% and +1% between two arbitrary orders of the same leaves; this order is as
/// fast as the best of them there and neutral elsewhere.
///
/// PERF: each area is computed once, and the sort is a fixed network on integer keys
/// (area bits above the reversed position), without branches. Sorting the references with
/// `sort_by`, the area computed per comparison, was about 6% of a build (half of it in
/// `memcpy` calls); an insertion sort on (area, id) pairs still spent 3.5% on its
/// mispredicted comparisons.
///
/// `leaf` holds at most `MAX_LEAF` references (the builder's `max_leaf`, which
/// `BinaryBvh::validate` checks); the first `leaf.len()` entries of the result are set.
#[inline]
fn largest_first(leaf: &[crate::build::PrimRef]) -> [u32; MAX_LEAF] {
    const _: () = assert!(MAX_LEAF == 8, "the sorting network below is for eight keys");
    debug_assert!(!leaf.is_empty() && leaf.len() <= MAX_LEAF);
    let n = leaf.len().min(MAX_LEAF);
    // Key: the area's bits (non-negative floats order as their bits) above 7 - position,
    // so equal areas keep their order when the keys are sorted descending. Unused slots
    // get 0, below every real key but that of an area-0 triangle in the last slot, which
    // exists only when all eight slots are used.
    let mut key = [0u64; MAX_LEAF];
    for (i, p) in leaf[..n].iter().enumerate() {
        // `max` also maps a NaN area (never produced: the boxes are finite) to 0.
        let a = Aabb { min: p.min(), max: p.max() }.half_area().max(0.0);
        key[i] = (u64::from(a.to_bits()) << 32) | (MAX_LEAF - 1 - i) as u64;
    }
    for (a, b) in LEAF_SORT_NET {
        let (x, y) = (key[a], key[b]);
        key[a] = x.max(y);
        key[b] = x.min(y);
    }
    std::array::from_fn(|k| leaf[(MAX_LEAF - 1 - (key[k] & 7) as usize).min(n - 1)].id())
}

/// The wide nodes of `bin` at `width` (see [`collapse`]).
fn collapse_to(
    width: Width,
    nodes: &[BinNode],
    tris: usize,
    leaf_block: u32,
    make_leaf: &mut impl FnMut(u32, u32) -> Result<u32, BuildError>,
) -> Result<Nodes, BuildError> {
    let too_many = || BuildError::TooLarge(tris);
    Ok(match width {
        Width::W4 => Nodes::W4(collapse::<4, _>(nodes, leaf_block, make_leaf, too_many)?),
        Width::W8 => Nodes::W8(collapse::<8, _>(nodes, leaf_block, make_leaf, too_many)?),
    })
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn simd_intersect(b: &MeshBvh, ray: &Ray) -> Option<Hit> {
    let mut hit = Hit::none(ray.tmax);
    b.intersect_k::<crate::kernel::SimdSet, ()>(&RayPre::new(ray), &mut hit, &mut ());
    hit.is_hit().then(|| hit.reload())
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn simd_occluded(b: &MeshBvh, ray: &Ray) -> bool {
    b.occluded_k::<crate::kernel::SimdSet, ()>(&RayPre::new(ray), ray.tmax, &mut ())
}

// PERF: the same generic kernels compiled with AVX-512VL: 32 vector registers, so the ray
// constants stay in registers; the arithmetic (and so every answer) is the AVX2 kernel's.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
fn avx512_intersect(b: &MeshBvh, ray: &Ray) -> Option<Hit> {
    let mut hit = Hit::none(ray.tmax);
    b.intersect_k::<crate::kernel::Avx512Set, ()>(&RayPre::new(ray), &mut hit, &mut ());
    hit.is_hit().then(|| hit.reload())
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
fn avx512_occluded(b: &MeshBvh, ray: &Ray) -> bool {
    b.occluded_k::<crate::kernel::Avx512Set, ()>(&RayPre::new(ray), ray.tmax, &mut ())
}

/// The four-triangle test of the SIMD kernel sets (which run only where AVX2 and FMA
/// were detected), without a detection of its own; the barycentrics are left scaled (see
/// `sse::intersect_scaled`).
#[inline(always)]
fn simd_tri4_intersect_scaled(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32, f32, f32, usize)> {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: called only under `K::SIMD`, whose kernels run only where FMA was detected.
    return unsafe { crate::triangle::sse::intersect_scaled(t4, o, d, tmin, tmax) };
    #[cfg(not(target_arch = "x86_64"))]
    crate::triangle::tri4_intersect(t4, o, d, tmin, tmax).map(|h| (h.t, h.u, h.v, 1.0, h.lane))
}

/// The any-hit counterpart of [`simd_tri4_intersect_scaled`].
#[inline(always)]
fn simd_tri4_occluded(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: as in `simd_tri4_intersect`.
    return unsafe { crate::triangle::sse::occluded(t4, o, d, tmin, tmax) };
    #[cfg(not(target_arch = "x86_64"))]
    crate::triangle::tri4_occluded(t4, o, d, tmin, tmax)
}

struct UnitLeaves<'a, K> {
    tris: &'a [Tri4],
    /// The divisor of the barycentrics in `hit.u`, `hit.v` (1 once divided): the SIMD test
    /// leaves them scaled, and [`UnitLeaves::finish`] divides once, for the final hit.
    den: std::cell::Cell<f32>,
    k: std::marker::PhantomData<K>,
}

impl<'a, K> UnitLeaves<'a, K> {
    fn new(tris: &'a [Tri4]) -> Self {
        Self { tris, den: std::cell::Cell::new(1.0), k: std::marker::PhantomData }
    }
    /// Divides the barycentrics of the hit the leaves found.
    ///
    /// PERF: `u` and `v` are read one by one, as the leaves wrote them (see [`Hit::reload`]).
    #[inline(always)]
    fn finish(&self, hit: &mut Hit) {
        let den = self.den.get();
        // SAFETY: reads of valid, aligned f32 fields of `hit`.
        let (u, v) = unsafe { (std::ptr::read_volatile(&hit.u), std::ptr::read_volatile(&hit.v)) };
        hit.u = u / den;
        hit.v = v / den;
    }
}

impl<K: KernelSet> Leaves for UnitLeaves<'_, K> {
    #[inline(always)]
    fn intersect<C: Counters>(&self, first: u32, count: u32, r: &RayPre, hit: &mut Hit, c: &mut C) {
        for g in first..first + count {
            // SAFETY: leaf ranges are checked against `tris` by `validate` (tests) and built in range.
            let t4 = unsafe { self.tris.get_unchecked(g as usize) };
            c.triangles(std::ptr::from_ref(t4) as usize, std::mem::size_of::<Tri4>(), 4);
            if K::SIMD {
                if let Some((t, u, v, den, lane)) = simd_tri4_intersect_scaled(t4, r.org, r.dir, r.tmin, hit.t) {
                    hit.t = t;
                    hit.u = u;
                    hit.v = v;
                    self.den.set(den);
                    hit.prim = t4.id(lane);
                }
            } else if let Some(h) = tri4_intersect_scalar(t4, r.org, r.dir, r.tmin, hit.t) {
                hit.t = h.t;
                hit.u = h.u;
                hit.v = h.v;
                hit.prim = t4.id(h.lane);
            }
        }
    }
    #[inline(always)]
    fn occluded<C: Counters>(&self, first: u32, count: u32, r: &RayPre, tmax: f32, c: &mut C) -> bool {
        // PERF: a plain loop; as `Iterator::any` with a closure it was left out of line
        // once the leaf test grew, a call per leaf (shadow rays 20% slower).
        for g in first..first + count {
            // SAFETY: as above.
            let t4 = unsafe { self.tris.get_unchecked(g as usize) };
            c.triangles(std::ptr::from_ref(t4) as usize, std::mem::size_of::<Tri4>(), 4);
            let hit = if K::SIMD {
                simd_tri4_occluded(t4, r.org, r.dir, r.tmin, tmax)
            } else {
                tri4_occluded_scalar(t4, r.org, r.dir, r.tmin, tmax)
            };
            if hit {
                return true;
            }
        }
        false
    }
}

struct WtLeaves<'a> {
    verts: &'a [[Vec3; 3]],
    ids: &'a [u32],
    /// The ray's shear constants, made at the first leaf reached.
    // PERF: made lazily so the three divisions are not paid by rays that reach no leaf
    // (and cannot be hoisted into the unit-triangle path).
    ray: std::cell::Cell<Option<WatertightRay>>,
}

impl WtLeaves<'_> {
    #[inline(always)]
    fn ray(&self, r: &RayPre) -> WatertightRay {
        match self.ray.get() {
            Some(w) => w,
            None => {
                let w = WatertightRay::new(r.org, r.dir);
                self.ray.set(Some(w));
                w
            }
        }
    }
}

impl Leaves for WtLeaves<'_> {
    fn intersect<C: Counters>(&self, first: u32, count: u32, r: &RayPre, hit: &mut Hit, k: &mut C) {
        let w = self.ray(r);
        for i in first as usize..(first + count) as usize {
            k.triangles(std::ptr::from_ref(&self.verts[i]) as usize, std::mem::size_of::<[Vec3; 3]>(), 1);
            let [a, b, c] = self.verts[i];
            if let Some((t, u, v)) = w.hit(a, b, c, r.tmin, hit.t) {
                *hit = Hit { t, u, v, prim: self.ids[i], inst: hit.inst };
            }
        }
    }
    fn occluded<C: Counters>(&self, first: u32, count: u32, r: &RayPre, tmax: f32, k: &mut C) -> bool {
        let w = self.ray(r);
        (first as usize..(first + count) as usize).any(|i| {
            k.triangles(std::ptr::from_ref(&self.verts[i]) as usize, std::mem::size_of::<[Vec3; 3]>(), 1);
            let [a, b, c] = self.verts[i];
            w.hit(a, b, c, r.tmin, tmax).is_some()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The SIMD box tests must visit exactly the nodes (and leaf groups) the scalar one
    /// visits, ray by ray: same hits is not enough (a looser test finds the same hits
    /// while doing more work).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn simd_traversal_visits_the_nodes_of_the_scalar_one() {
        if !Kernel::simd_available() {
            return;
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut p = Vec::new();
        let mut idx = Vec::new();
        for i in 0..3000u32 {
            let c = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
            for _ in 0..3 {
                p.push(c + Vec3::new(rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5));
            }
            idx.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        for width in [Width::W4, Width::W8] {
            let m = MeshBvh::build(&p, &idx, MeshOptions { width, ..MeshOptions::default() }).expect("build");
            for _ in 0..2000 {
                let o = Vec3::new(rng.random(), rng.random(), rng.random()) * 14.0 - Vec3::splat(2.0);
                let d = Vec3::new(rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5).normalize_or(Vec3::X);
                let pre = RayPre::new(&Ray::new(o, d));
                let (mut a, mut b) = (TraversalStats::default(), TraversalStats::default());
                let (mut ha, mut hb) = (Hit::none(f32::INFINITY), Hit::none(f32::INFINITY));
                m.intersect_k::<ScalarSet, _>(&pre, &mut ha, &mut a);
                // SAFETY: AVX2 and FMA were detected above.
                unsafe { simd_stats(&m, &pre, &mut hb, &mut b) };
                assert_eq!((a, ha.prim), (b, hb.prim), "{width:?}: ray {o} {d}");
                let (mut a, mut b) = (TraversalStats::default(), TraversalStats::default());
                let oa = m.occluded_k::<ScalarSet, _>(&pre, 8.0, &mut a);
                // SAFETY: as above.
                let ob = unsafe { simd_occluded_stats(&m, &pre, 8.0, &mut b) };
                assert_eq!((a, oa), (b, ob), "{width:?}: shadow ray {o} {d}");
            }
        }
    }

    /// Every leaf, with either triangle test, holds its triangles largest box first (the
    /// any-hit walk's order; see `largest_first`).
    #[test]
    fn leaves_hold_their_triangles_largest_first() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let mut p = Vec::new();
        let mut idx = Vec::new();
        for i in 0..4000u32 {
            let c = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
            // Sizes over two orders of magnitude, so neighbours differ.
            let s = 0.02 + 2.0 * rng.random::<f32>().powi(3);
            for _ in 0..3 {
                p.push(c + s * Vec3::new(rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5));
            }
            idx.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let area = |id: u32| Aabb::from_points(&idx[id as usize].map(|v| p[v as usize])).half_area();
        for test in [TriangleTest::UnitTriangle, TriangleTest::Watertight] {
            let m = MeshBvh::build(&p, &idx, MeshOptions { test, ..MeshOptions::default() }).expect("build");
            let Nodes::W8(nodes) = &m.nodes else { panic!("8-wide by default") };
            let (mut leaves, mut sorted_pairs) = (0, 0);
            for code in nodes.iter().flat_map(|n| n.child).filter(|&c| c != EMPTY && c & LEAF != 0) {
                let (first, count) = leaf_range(code);
                let ids: Vec<u32> = match test {
                    TriangleTest::UnitTriangle => m.tris[first as usize..(first + count) as usize].iter().flat_map(Tri4::ids).collect(),
                    TriangleTest::Watertight => m.wt_ids[first as usize..(first + count) as usize].to_vec(),
                };
                for w in ids.windows(2) {
                    assert!(area(w[0]) >= area(w[1]), "{test:?}: leaf {first}+{count}: {ids:?}");
                    sorted_pairs += 1;
                }
                leaves += 1;
            }
            // (Watertight leaves are mostly single triangles: a leaf there costs per triangle.)
            let want = if test == TriangleTest::UnitTriangle { 1000 } else { 100 };
            assert!(leaves > 100 && sorted_pairs > want, "{test:?}: {leaves} leaves, {sorted_pairs} pairs checked");
        }
    }

    /// `largest_first` is the stable descending sort by box area: every length up to
    /// `MAX_LEAF`, with many equal areas (seeded).
    #[test]
    fn largest_first_is_a_stable_sort_by_area() {
        // The network sorts every 0-1 input (and so, by the 0-1 principle, every input).
        for bits in 0u32..256 {
            let mut v: [u32; 8] = std::array::from_fn(|i| (bits >> i) & 1);
            for (a, b) in LEAF_SORT_NET {
                let (x, y) = (v[a], v[b]);
                (v[a], v[b]) = (x.max(y), x.min(y));
            }
            assert!(v.windows(2).all(|w| w[0] >= w[1]), "0-1 input {bits:08b} gives {v:?}");
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for _ in 0..20_000 {
            let n = rng.random_range(1..=MAX_LEAF);
            // Three sizes only, and zero-area (flat) boxes, so ties are common.
            let leaf: Vec<crate::build::PrimRef> = (0..n)
                .map(|i| {
                    let s = [0.0f32, 1.0, 2.0][rng.random_range(0..3)];
                    let lo = Vec3::new(rng.random(), rng.random(), rng.random());
                    let hi = lo + Vec3::new(s, s, if rng.random_bool(0.2) { 0.0 } else { s });
                    crate::build::PrimRef::new(Aabb { min: lo, max: hi }, 100 + i as u32)
                })
                .collect();
            let mut want = leaf.clone();
            let area = |p: &crate::build::PrimRef| Aabb { min: p.min(), max: p.max() }.half_area();
            want.sort_by(|a, b| area(b).total_cmp(&area(a)));
            let want: Vec<u32> = want.iter().map(|p| p.id()).collect();
            assert_eq!(largest_first(&leaf)[..n], want[..], "n {n}");
        }
    }

    /// The wide SAH in Embree's convention: the root node 1, and each block of four
    /// triangles 1 at its leaf's share of the root's area.
    #[test]
    fn wide_sah_counts_nodes_and_blocks_as_embree_does() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::new(0.0, 1.0, 1.0)];
        for test in [TriangleTest::UnitTriangle, TriangleTest::Watertight] {
            let opts = MeshOptions { test, ..MeshOptions::default() };
            let one = MeshBvh::build(&tri, &[[0, 1, 2]], opts).expect("build");
            assert_eq!(one.stats().wide_sah, 2.0, "{test:?}: one node, one block at the root's box");
            // Two clusters of eight identical triangles (box [0,1]³, half area 3), 100 apart:
            // a root over two leaves of two blocks each; the root box's half area is 203.
            let mut p = Vec::new();
            let mut idx = Vec::new();
            for c in [0.0, 100.0] {
                for _ in 0..8 {
                    let b = p.len() as u32;
                    p.extend(tri.map(|v| v + Vec3::new(c, 0.0, 0.0)));
                    idx.push([b, b + 1, b + 2]);
                }
            }
            let two = MeshBvh::build(&p, &idx, opts).expect("build");
            let want = 1.0 + 2.0 * 2.0 * 3.0 / 203.0;
            assert!((two.stats().wide_sah - want).abs() < 1e-5, "{test:?}: {} against {want}", two.stats().wide_sah);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn simd_stats(m: &MeshBvh, pre: &RayPre, hit: &mut Hit, c: &mut TraversalStats) {
        m.intersect_k::<crate::kernel::SimdSet, _>(pre, hit, c);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn simd_occluded_stats(m: &MeshBvh, pre: &RayPre, tmax: f32, c: &mut TraversalStats) -> bool {
        m.occluded_k::<crate::kernel::SimdSet, _>(pre, tmax, c)
    }
}

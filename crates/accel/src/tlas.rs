//! The two-level index (SaarCOR §2): one bottom-level structure per geometry (a triangle
//! mesh BVH or an analytic shape) and a top-level BVH over instances, each a geometry plus
//! an affine `world_from_object` map. Rays are carried into object space at the instance
//! (their direction is not renormalized, so `t` is shared by both levels). The top level is
//! cheap to rebuild, which is what dynamic scenes do every frame.

use crate::build::{build_binary, build_clustered_into, build_lbvh_into, BuildConfig, MortonScratch, PrimRef};
use crate::geom::{Aabb, Hit, Ray};
use crate::kernel::{Kernel, KernelSet, ScalarSet};
use crate::mesh::{BuildError, BvhStats, MeshBvh};
use crate::shape::Shape;
use crate::traverse::{self, Counters, Leaves, Level, RayPre};
use crate::wide::{collapse_spread, WideNode};
use glam::{Affine3A, Vec3};

/// What an instance draws.
#[derive(Clone, Debug)]
pub enum Geometry {
    /// A triangle mesh with its BVH.
    Mesh(MeshBvh),
    /// An analytic shape in canonical form.
    Shape(Shape),
}

impl Geometry {
    /// Bounds in object space.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        match self {
            Geometry::Mesh(m) => m.bounds(),
            Geometry::Shape(s) => s.bounds_local(),
        }
    }
}

/// One placed copy of a geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index into the geometry list.
    pub geometry: u32,
    /// Object space to world space.
    pub world_from_object: Affine3A,
    /// World space to object space (cached inverse).
    pub object_from_world: Affine3A,
}

impl Instance {
    /// An instance of geometry `geometry` placed by `world_from_object`.
    #[must_use]
    pub fn new(geometry: u32, world_from_object: Affine3A) -> Self {
        Self { geometry, world_from_object, object_from_world: world_from_object.inverse() }
    }

    /// True when object space is world space (every instance of a scene loaded from one
    /// OBJ or PLY file): queries then use the world rays as they are, in both the
    /// single-ray and the packet paths, so the two still agree. PERF: carrying a 64-ray
    /// packet into object space copies it and takes 24 divisions; for Conference's one
    /// instance that was most of the top level's share of a frame.
    #[inline(always)]
    #[must_use]
    pub fn is_identity(&self) -> bool {
        self.object_from_world == Affine3A::IDENTITY
    }

    /// The origin and direction of ray `pre` in object space (the direction not
    /// renormalised, so distances along it are the world ray's): what a shape needs.
    #[inline(always)]
    pub(crate) fn object_ray(&self, pre: &RayPre) -> (Vec3, Vec3) {
        if self.is_identity() {
            return (pre.org, pre.dir);
        }
        let m = &self.object_from_world;
        (m.transform_point3(pre.org), m.transform_vector3(pre.dir))
    }

    /// Ray `pre` in object space with its box-test constants made again: what a mesh's
    /// walk needs ([`Instance::object_ray`] with the constants).
    #[inline(always)]
    pub(crate) fn local_ray(&self, pre: &RayPre) -> RayPre {
        if self.is_identity() {
            return *pre;
        }
        let (org, dir) = self.object_ray(pre);
        RayPre::new(&Ray { org, dir, tmin: pre.tmin, tmax: f32::INFINITY })
    }
}

/// Most instances in one Morton run of the clustered SAH top level
/// ([`crate::build::build_clustered`]). At 10,000 instances, runs of 8 made the build 3.5
/// times faster than binning every instance (0.81 against 2.87 ms on one thread), for a
/// wide tree whose node boxes have about 15% more surface area.
const TOP_CLUSTER: usize = 8;
/// From this many instances on, the top level is built over Morton runs; below, every
/// instance is binned. (The BART kitchen's 393 instances of very different sizes traced
/// 10% slower over runs, and build in well under a millisecond either way.)
const CLUSTER_MIN: usize = 2048;

/// How the top level is built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TopBuilder {
    /// Binned SAH over Morton runs of a few instances (the default: the better tree).
    #[default]
    Sah,
    /// Linear BVH in Morton order: about 4× faster to build, about 20% slower to trace
    /// (`lucent bench dynamic` measures both on the sunflower field).
    Linear,
}

/// Geometries, instances and the top-level BVH over them.
#[derive(Clone, Debug)]
pub struct TwoLevel {
    geometries: Vec<Geometry>,
    instances: Vec<Instance>,
    pub(crate) nodes: Vec<WideNode<8>>,
    /// Instance ids in leaf order.
    pub(crate) order: Vec<u32>,
    /// Instances with infinite bounds, tested outside the tree.
    pub(crate) unbounded: Vec<u32>,
    bounds: Aabb,
    pub(crate) kernel: Kernel,
    builder: TopBuilder,
    /// Build buffers kept between rebuilds.
    boxes: Vec<Aabb>,
    prims: Vec<PrimRef>,
    scratch: MortonScratch,
    /// Directions toward directional lights, and the shadow-ray grids over the instances
    /// along them (rebuilt with the top level).
    shadow_dirs: Vec<Vec3>,
    pub(crate) shadow_grids: Vec<crate::shadow_grid::DirGrid>,
}

impl TwoLevel {
    /// Builds the top level over `instances` of `geometries`.
    ///
    /// # Example
    /// Two instances of one triangle and a unit sphere: a ray meets the nearest.
    /// ```
    /// use glam::{Affine3A, Vec3};
    /// use lucent_accel::{Geometry, Instance, MeshBvh, MeshOptions, Ray, Shape, TwoLevel};
    /// let tri = MeshBvh::build(&[Vec3::ZERO, Vec3::X, Vec3::Y], &[[0, 1, 2]], MeshOptions::default()).unwrap();
    /// let geoms = vec![Geometry::Mesh(tri), Geometry::Shape(Shape::Sphere)];
    /// let at = |z: f32| Affine3A::from_translation(Vec3::new(0.0, 0.0, z));
    /// let scene = TwoLevel::new(geoms, vec![Instance::new(0, at(-2.0)), Instance::new(0, at(-5.0)), Instance::new(1, at(-10.0))]).unwrap();
    /// let down = Ray::new(Vec3::new(0.25, 0.25, 0.0), -Vec3::Z);
    /// let hit = scene.intersect(&down).expect("a hit");
    /// assert_eq!((hit.inst, hit.t), (0, 2.0));
    /// assert!(scene.occluded(&down));
    /// ```
    pub fn new(geometries: Vec<Geometry>, instances: Vec<Instance>) -> Result<Self, BuildError> {
        let mut s = Self {
            geometries,
            instances,
            nodes: Vec::new(),
            order: Vec::new(),
            unbounded: Vec::new(),
            bounds: Aabb::EMPTY,
            kernel: Kernel::detect(),
            builder: TopBuilder::Sah,
            boxes: Vec::new(),
            prims: Vec::new(),
            scratch: MortonScratch::default(),
            shadow_dirs: Vec::new(),
            shadow_grids: Vec::new(),
        };
        s.rebuild()?;
        Ok(s)
    }

    /// Geometries.
    #[must_use]
    pub fn geometries(&self) -> &[Geometry] {
        &self.geometries
    }

    /// Instances.
    #[must_use]
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// Chooses the top-level builder for the next rebuilds.
    pub fn set_top_builder(&mut self, b: TopBuilder) {
        self.builder = b;
    }

    /// Geometry `i`, to refit in place (then call [`TwoLevel::rebuild`]).
    pub fn geometry_mut(&mut self, i: usize) -> Option<&mut Geometry> {
        self.geometries.get_mut(i)
    }

    /// Replaces geometry `i` (a deformed mesh rebuilt or refitted). The top level is not
    /// rebuilt: call [`TwoLevel::rebuild`] or [`TwoLevel::set_instances`] after.
    pub fn set_geometry(&mut self, i: usize, g: Geometry) -> Result<(), BuildError> {
        let count = self.geometries.len();
        let slot = self.geometries.get_mut(i).ok_or(BuildError::NoSuchGeometry { inst: 0, geom: i as u32, count })?;
        *slot = g;
        Ok(())
    }

    /// Replaces the instance list (e.g. new transforms for a frame) and rebuilds the top level.
    pub fn set_instances(&mut self, instances: Vec<Instance>) -> Result<(), BuildError> {
        self.instances = instances;
        self.rebuild()
    }

    /// Lets `f` change the instances in place (new transforms for a frame: keep
    /// `object_from_world` the inverse, e.g. through [`Instance::new`]), then rebuilds the top
    /// level. Unlike [`TwoLevel::set_instances`] this moves no instance list in or out, which
    /// matters for per-frame rebuilds of many instances.
    pub fn update_instances(&mut self, f: impl FnOnce(&mut [Instance])) -> Result<(), BuildError> {
        f(&mut self.instances);
        self.rebuild()
    }

    /// Declares the unit directions toward directional lights (as their shadow rays carry
    /// them, bit for bit). Packets of shadow rays along one of them are then tested against
    /// the instances a light-space grid lists near their origins, instead of walking the
    /// top level (see `shadow_grid`); the answers are the same. The grids are rebuilt with
    /// the top level.
    pub fn set_shadow_directions(&mut self, dirs: &[Vec3]) {
        // The same directions (bit for bit): the grids are current already, since every
        // rebuild rebuilds them (a posed frame rebuilt them once with its instances).
        let bits = |v: &Vec3| v.to_array().map(f32::to_bits);
        if self.shadow_dirs.len() == dirs.len() && self.shadow_dirs.iter().zip(dirs).all(|(a, b)| bits(a) == bits(b)) {
            return;
        }
        self.shadow_dirs.clear();
        self.shadow_dirs.extend_from_slice(dirs);
        self.build_shadow_grids();
    }

    fn build_shadow_grids(&mut self) {
        self.shadow_grids.clear();
        for &d in &self.shadow_dirs {
            if let Some(g) = crate::shadow_grid::DirGrid::build(d, &self.boxes, &self.bounds) {
                self.shadow_grids.push(g);
            }
        }
    }

    /// The instances besides the unbounded ones that the shadow grid of `dir` lists for a
    /// ray from `origin` (for tests and tools): `None` when `dir` has no grid (see
    /// [`TwoLevel::set_shadow_directions`]) or the list is too long to be used.
    #[must_use]
    pub fn shadow_candidates_at(&self, dir: Vec3, origin: Vec3) -> Option<Vec<u32>> {
        let grid = self.shadow_grids.iter().find(|g| g.dir == dir)?;
        let mut out = [0; crate::shadow_grid::MAX_CANDIDATES];
        let n = grid.candidates(origin, origin, &mut out)?;
        Some(out[..n].to_vec())
    }

    /// World bounds of the bounded instances.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Chooses the kernel for both levels (falls back to scalar without AVX2).
    pub fn set_kernel(&mut self, k: Kernel) {
        self.kernel = k.supported();
        for g in &mut self.geometries {
            if let Geometry::Mesh(m) = g {
                m.set_kernel(k);
            }
        }
    }

    /// Figures of the top level (nodes and bytes) and of all bottom levels together.
    #[must_use]
    pub fn stats(&self) -> (BvhStats, BvhStats) {
        let top = BvhStats {
            nodes: self.nodes.len(),
            leaves: 0,
            prims: self.instances.len(),
            refs: self.instances.len(),
            sah: 0.0,
            wide_sah: 0.0,
            bytes: std::mem::size_of_val(self.nodes.as_slice())
                + 4 * (self.order.len() + self.unbounded.len())
                + std::mem::size_of_val(self.instances.as_slice()),
        };
        let mut bottom = BvhStats::default();
        for g in &self.geometries {
            if let Geometry::Mesh(m) = g {
                let s = m.stats_counts();
                bottom.nodes += s.nodes;
                bottom.leaves += s.leaves;
                bottom.prims += s.prims;
                bottom.refs += s.refs;
                bottom.bytes += s.bytes;
            }
        }
        (top, bottom)
    }

    /// Rebuilds the top-level BVH from the current instances.
    pub fn rebuild(&mut self) -> Result<(), BuildError> {
        let ng = self.geometries.len();
        if self.instances.len() >= crate::build::MAX_PRIMS as usize {
            return Err(BuildError::TooLarge(self.instances.len()));
        }
        if let Some((inst, i)) = self.instances.iter().enumerate().find(|(_, i)| i.geometry as usize >= ng) {
            return Err(BuildError::NoSuchGeometry { inst, geom: i.geometry, count: ng });
        }
        // World boxes (in parallel for many instances), then the build's references.
        let geoms = &self.geometries;
        let world_box = |inst: &Instance| geoms[inst.geometry as usize].bounds().transformed(&inst.world_from_object);
        self.boxes.clear();
        self.boxes.resize(self.instances.len(), Aabb::EMPTY);
        if self.instances.len() >= 4096 {
            use rayon::prelude::*;
            self.boxes.par_chunks_mut(1024).zip(self.instances.par_chunks(1024)).for_each(|(b, i)| {
                for (b, i) in b.iter_mut().zip(i) {
                    *b = world_box(i);
                }
            });
        } else {
            for (b, i) in self.boxes.iter_mut().zip(&self.instances) {
                *b = world_box(i);
            }
        }
        self.unbounded.clear();
        let prims = &mut self.prims;
        prims.clear();
        for (i, b) in self.boxes.iter().enumerate() {
            if b.is_empty() {
                continue;
            }
            if b.is_finite() {
                prims.push(PrimRef::new(*b, i as u32));
            } else {
                self.unbounded.push(i as u32);
            }
        }
        let cfg = BuildConfig { max_leaf: 2, leaf_block: 1, cost_traverse: 1.0, median_max: 8, spatial: 0.0 };
        match self.builder {
            TopBuilder::Linear => build_lbvh_into(prims, 2, &mut self.scratch),
            TopBuilder::Sah if prims.len() >= CLUSTER_MIN => build_clustered_into(prims, &cfg, TOP_CLUSTER, &mut self.scratch),
            TopBuilder::Sah => {
                // The references go into the tree, and the old tree's list becomes the next
                // rebuild's buffer: no copy and no allocation per frame.
                let old = std::mem::replace(&mut self.scratch.bvh, build_binary(std::mem::take(prims), &cfg));
                *prims = old.prims;
            }
        }
        let bin = &self.scratch.bvh;
        self.bounds = bin.nodes.first().map_or(Aabb::EMPTY, |n| n.bounds);
        self.order.clear();
        self.order.extend(bin.prims.iter().map(PrimRef::id));
        let n = self.instances.len();
        collapse_spread::<8>(bin, &mut self.nodes).map_err(|_| BuildError::TooLarge(n))?;
        self.build_shadow_grids();
        Ok(())
    }

    /// Closest hit over all instances.
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        // PERF: ray constants are made inside the kernel function (kept in registers).
        match self.kernel {
            // SAFETY: `Kernel::Simd` is only set when AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd => unsafe { simd_intersect(self, ray) },
            // SAFETY: `Kernel::Avx512` is only set when AVX-512F/VL (and AVX2, FMA) were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => unsafe { avx512_intersect(self, ray) },
            _ => {
                let mut hit = Hit::none(ray.tmax);
                self.intersect_k::<ScalarSet>(&RayPre::new(ray), &mut hit);
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
            _ => self.occluded_k::<ScalarSet>(&RayPre::new(ray), ray.tmax),
        }
    }

    /// The mesh of a top level that holds one mesh instance in world space (a scene from
    /// one OBJ or PLY file): queries go straight to it, without the top-level walk (and,
    /// for packets, its packet set-up).
    #[inline(always)]
    pub(crate) fn only_mesh(&self) -> Option<&MeshBvh> {
        match self.instances.as_slice() {
            [only] if only.is_identity() => match self.geometries.get(only.geometry as usize) {
                Some(Geometry::Mesh(m)) => Some(m),
                _ => None,
            },
            _ => None,
        }
    }

    #[inline(always)]
    pub(crate) fn intersect_k<K: KernelSet>(&self, pre: &RayPre, hit: &mut Hit) {
        self.intersect_kc::<K, ()>(pre, hit, &mut ());
    }

    #[inline(always)]
    pub(crate) fn occluded_k<K: KernelSet>(&self, pre: &RayPre, tmax: f32) -> bool {
        self.occluded_kc::<K, ()>(pre, tmax, &mut ())
    }

    #[inline(always)]
    pub(crate) fn intersect_kc<K: KernelSet, C: Counters>(&self, pre: &RayPre, hit: &mut Hit, c: &mut C) {
        if let Some(mesh) = self.only_mesh() {
            c.enter(Level::Bottom);
            if mesh.intersect_k::<K, C>(pre, hit, c) {
                hit.inst = 0;
            }
            return;
        }
        let leaves = InstLeaves::<K> { tl: self, k: std::marker::PhantomData };
        c.enter(Level::Top);
        // SAFETY: the caller selected K for this CPU.
        unsafe { traverse::intersect::<8, K::B8, _, _>(&self.nodes, &leaves, pre, hit, c) };
        for &i in &self.unbounded {
            leaves.hit_instance(i, pre, hit, c);
        }
    }

    #[inline(always)]
    pub(crate) fn occluded_kc<K: KernelSet, C: Counters>(&self, pre: &RayPre, tmax: f32, c: &mut C) -> bool {
        if let Some(mesh) = self.only_mesh() {
            c.enter(Level::Bottom);
            return mesh.occluded_k::<K, C>(pre, tmax, c);
        }
        let leaves = InstLeaves::<K> { tl: self, k: std::marker::PhantomData };
        c.enter(Level::Top);
        // SAFETY: the caller selected K for this CPU.
        self.unbounded.iter().any(|&i| leaves.occludes(i, pre, tmax, c))
            || unsafe { traverse::occluded::<8, K::B8, _, _>(&self.nodes, &leaves, pre, tmax, c) }
    }

    /// Closest hit over all instances with the portable kernel, reporting every step to
    /// `c` (the hardware study's seam): the same answers and the same visits as
    /// [`TwoLevel::intersect`]'s single-ray kernels.
    pub fn intersect_counted<C: Counters>(&self, ray: &Ray, c: &mut C) -> Option<Hit> {
        let mut hit = Hit::none(ray.tmax);
        self.intersect_kc::<ScalarSet, C>(&RayPre::new(ray), &mut hit, c);
        hit.is_hit().then_some(hit)
    }

    /// [`TwoLevel::occluded`] with the portable kernel, reporting every step to `c`.
    pub fn occluded_counted<C: Counters>(&self, ray: &Ray, c: &mut C) -> bool {
        self.occluded_kc::<ScalarSet, C>(&RayPre::new(ray), ray.tmax, c)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn simd_intersect(t: &TwoLevel, ray: &Ray) -> Option<Hit> {
    let mut hit = Hit::none(ray.tmax);
    t.intersect_k::<crate::kernel::SimdSet>(&RayPre::new(ray), &mut hit);
    hit.is_hit().then(|| hit.reload())
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn simd_occluded(t: &TwoLevel, ray: &Ray) -> bool {
    t.occluded_k::<crate::kernel::SimdSet>(&RayPre::new(ray), ray.tmax)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
fn avx512_intersect(t: &TwoLevel, ray: &Ray) -> Option<Hit> {
    let mut hit = Hit::none(ray.tmax);
    t.intersect_k::<crate::kernel::Avx512Set>(&RayPre::new(ray), &mut hit);
    hit.is_hit().then(|| hit.reload())
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
fn avx512_occluded(t: &TwoLevel, ray: &Ray) -> bool {
    t.occluded_k::<crate::kernel::Avx512Set>(&RayPre::new(ray), ray.tmax)
}

/// Reports `inst`'s transformation to `c` when it is one.
#[inline(always)]
fn count_transform<C: Counters>(inst: &Instance, c: &mut C) {
    if !inst.is_identity() {
        c.transform(std::ptr::from_ref(&inst.object_from_world) as usize, std::mem::size_of::<Affine3A>());
    }
}

pub(crate) struct InstLeaves<'a, K> {
    pub(crate) tl: &'a TwoLevel,
    pub(crate) k: std::marker::PhantomData<K>,
}

impl<K: KernelSet> InstLeaves<'_, K> {
    #[inline(always)]
    pub(crate) fn hit_instance<C: Counters>(&self, id: u32, pre: &RayPre, hit: &mut Hit, c: &mut C) {
        let inst = &self.tl.instances[id as usize];
        match &self.tl.geometries[inst.geometry as usize] {
            Geometry::Mesh(m) => {
                let lp = self.transform(inst, pre, c);
                c.enter(Level::Bottom);
                if m.intersect_k::<K, C>(&lp, hit, c) {
                    hit.inst = id;
                }
                c.enter(Level::Top);
            }
            Geometry::Shape(s) => {
                let (o, d) = self.shape_ray(inst, pre, c);
                c.shape(std::ptr::from_ref(s) as usize, std::mem::size_of::<Shape>());
                if let Some(h) = s.intersect_local(o, d, pre.tmin, hit.t) {
                    *hit = Hit { t: h.t, u: 0.0, v: 0.0, prim: h.part, inst: id };
                }
            }
        }
    }

    /// The origin and direction of the ray in `inst`'s object space, for a shape, counted
    /// as a transformation when it is one. PERF: without the box-test constants a shape
    /// does not read (three divisions per ray and shape).
    #[inline(always)]
    fn shape_ray<C: Counters>(&self, inst: &Instance, pre: &RayPre, c: &mut C) -> (Vec3, Vec3) {
        count_transform(inst, c);
        inst.object_ray(pre)
    }

    /// The ray in `inst`'s object space, counted as a transformation when it is one.
    #[inline(always)]
    fn transform<C: Counters>(&self, inst: &Instance, pre: &RayPre, c: &mut C) -> RayPre {
        count_transform(inst, c);
        inst.local_ray(pre)
    }

    #[inline(always)]
    pub(crate) fn occludes<C: Counters>(&self, id: u32, pre: &RayPre, tmax: f32, c: &mut C) -> bool {
        let inst = &self.tl.instances[id as usize];
        match &self.tl.geometries[inst.geometry as usize] {
            Geometry::Mesh(m) => {
                let lp = self.transform(inst, pre, c);
                c.enter(Level::Bottom);
                let o = m.occluded_k::<K, C>(&lp, tmax, c);
                c.enter(Level::Top);
                o
            }
            Geometry::Shape(s) => {
                let (o, d) = self.shape_ray(inst, pre, c);
                c.shape(std::ptr::from_ref(s) as usize, std::mem::size_of::<Shape>());
                s.intersect_local(o, d, pre.tmin, tmax).is_some()
            }
        }
    }
}

impl<K: KernelSet> Leaves for InstLeaves<'_, K> {
    #[inline(always)]
    fn intersect<C: Counters>(&self, first: u32, count: u32, r: &RayPre, hit: &mut Hit, c: &mut C) {
        for i in first..first + count {
            let e = &self.tl.order[i as usize];
            c.list_read(std::ptr::from_ref(e) as usize, 4);
            self.hit_instance(*e, r, hit, c);
        }
    }
    #[inline(always)]
    fn occluded<C: Counters>(&self, first: u32, count: u32, r: &RayPre, tmax: f32, c: &mut C) -> bool {
        (first..first + count).any(|i| {
            let e = &self.tl.order[i as usize];
            c.list_read(std::ptr::from_ref(e) as usize, 4);
            self.occludes(*e, r, tmax, c)
        })
    }
}

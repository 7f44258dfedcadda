//! The render-side view of a scene: the two-level acceleration structure built from it,
//! plus everything shading needs to rebuild a surface point from a hit.

use crate::bsdf::BsdfModel;
use crate::lights::{emissive_triangles, LightModel, LightSet};
use crate::materials::Prepared;
use glam::{Mat3A, Vec2, Vec3};
use lucent_accel::{Geometry, Hit, Instance, MeshBvh, MeshOptions, Ray, Shape, TwoLevel};
use lucent_scene::{Geom, Light, LightKind, Scene, ShapeKind};
use rayon::prelude::*;
use std::sync::Arc;

/// Errors of preparing a scene for rendering.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// Building an acceleration structure failed.
    #[error("mesh '{mesh}': {source}")]
    Build {
        /// Mesh name.
        mesh: String,
        /// Cause.
        source: lucent_accel::BuildError,
    },
    /// The top level failed.
    #[error("instances: {0}")]
    Top(lucent_accel::BuildError),
}

/// Maps a scene shape kind to the accel one.
#[must_use]
pub fn shape_of(k: ShapeKind) -> Shape {
    match k {
        ShapeKind::Sphere => Shape::Sphere,
        ShapeKind::Cylinder => Shape::Cylinder,
        ShapeKind::CappedCylinder => Shape::CappedCylinder,
        ShapeKind::Cone => Shape::Cone,
        ShapeKind::CappedCone => Shape::CappedCone,
        ShapeKind::Box => Shape::Box,
        ShapeKind::Disk => Shape::Disk,
        ShapeKind::Tube => Shape::Tube,
    }
}

/// Per instance: what shading needs.
#[derive(Clone, Copy, Debug)]
struct InstInfo {
    geom: Geom,
    normal_to_world: Mat3A,
    /// `normal_to_world` is the identity: object normals are world normals as they are.
    identity: bool,
    /// `world_from_object` is the identity: object points are world points as they are.
    in_place: bool,
    /// For the error bounds of hits on the instance (see [`World::surface`]): `|M| |M⁻¹|`
    /// and `|M| |t⁻¹|`, with `M` the linear part of `world_from_object` and `t⁻¹` the
    /// translation of its inverse (absolute values entry by entry): how an error of the ray
    /// carried into object space shows in world space.
    err_k: Mat3A,
    err_c: Vec3,
}

impl InstInfo {
    fn new(geom: Geom, inst: &Instance) -> Self {
        let normal_to_world = normal_matrix(inst);
        let abs = |m: Mat3A| Mat3A::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
        let m = abs(inst.world_from_object.matrix3);
        Self {
            geom,
            normal_to_world,
            identity: normal_to_world == Mat3A::IDENTITY,
            in_place: inst.world_from_object == glam::Affine3A::IDENTITY,
            err_k: m * abs(inst.object_from_world.matrix3),
            err_c: (m * inst.object_from_world.translation.abs()).into(),
        }
    }
}

/// A deforming mesh's BVH is refitted each frame and rebuilt when its SAH cost reaches
/// this multiple of its cost when built (see `lucent bench dynamic` for the data).
pub const REBUILD_RATIO: f32 = 1.5;

/// A scene with its acceleration structure.
///
/// Its fields are private: the index and the per-instance and per-triangle caches must
/// agree with the scene, so the scene changes only through methods that keep them so
/// ([`World::set_time`], [`World::set_lights`], [`World::ensure_light`]).
pub struct World {
    /// The scene.
    pub(crate) scene: Scene,
    /// Two-level index: geometry `i < meshes.len()` is mesh `i`; shapes follow.
    pub(crate) accel: TwoLevel,
    info: Vec<InstInfo>,
    /// Lights used for rendering (the scene's, or ones derived from emitters).
    pub(crate) lights: Vec<Light>,
    /// Diagonal of the world bounds.
    pub(crate) scale: f32,
    /// The lights the path tracer samples.
    pub(crate) light_set: LightSet,
    /// The materials prepared for the path tracer (one per scene material).
    pub(crate) prepared: Vec<Prepared>,
    /// Lights of the user's own.
    custom_lights: Vec<Arc<dyn LightModel>>,
    /// Per mesh, its emitting triangles ([`crate::lights::emissive_triangles`]).
    emissive: Vec<Box<[u32]>>,
    /// Some material has an alpha mask: intersections skip its cut-out parts.
    has_alpha: bool,
    opts: MeshOptions,
    /// Per mesh, per triangle: the unit geometric normal `(b − a) × (c − a)` in object
    /// space (zero for a degenerate triangle). PERF: `surface` reads this one vector
    /// instead of three vertex indices and three vertices scattered over the mesh (12
    /// bytes per triangle), and for an instance with the identity transform does no
    /// square root or division per hit (the normalisation's latency was a quarter of
    /// `surface`'s samples in a Conference frame).
    faces: Vec<Vec<Vec3>>,
}

/// The unit normal `(b − a) × (c − a)` of triangle `idx` (zero when an index is out of
/// range or the triangle has no normal).
fn face_normal(positions: &[Vec3], idx: &[u32; 3]) -> Vec3 {
    match idx.map(|i| positions.get(i as usize).copied()) {
        [Some(a), Some(b), Some(c)] => (b - a).cross(c - a).normalize_or_zero(),
        _ => Vec3::ZERO,
    }
}

/// [`face_normal`] of every triangle.
fn face_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
    indices.par_iter().map(|idx| face_normal(positions, idx)).collect()
}

/// A surface point rebuilt from a hit.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// World position.
    pub p: Vec3,
    /// Geometric normal (world, unit, as the geometry is wound).
    pub ng: Vec3,
    /// Shading normal (world, unit, same side as `ng`).
    pub ns: Vec3,
    /// Texture coordinates (left at zero on analytic shapes whose material has no texture).
    pub uv: Vec2,
    /// Material index.
    pub material: u32,
    /// A bound on the floating-point error of each coordinate of `p`, and on how far from
    /// the surface the intersection tests may still meet a ray starting there: see
    /// [`Surface::offset`].
    pub p_err: Vec3,
}

impl Surface {
    /// How far along the geometric normal a ray leaving the surface starts: the error
    /// bound projected on the normal, `|ng| · p_err` (pbrt-v4 §6.8.6, "Robust Spawned Ray
    /// Origins"), so that every point within `p_err` of `p` lies behind the plane through
    /// the new origin parallel to the surface, and the new ray cannot meet the surface it
    /// leaves. Two margins for the addition `p + offset · ng` itself, which is rounded: a
    /// whole ulp of each coordinate (`ε |ng| · |p|`; rounding costs at most half of one
    /// along the normal), and the least normal float, so that a zero bound (a point
    /// computed exactly, on a plane the tests evaluate exactly, such as x = 0) still
    /// leaves the plane. (pbrt rounds each coordinate on to the next float instead; per
    /// lane that took 6% of a shaded frame.)
    #[inline]
    #[must_use]
    pub fn offset(&self) -> f32 {
        self.ng.abs().dot(self.p_err + self.p.abs() * f32::EPSILON) + f32::MIN_POSITIVE
    }

    /// A ray leaving the surface along `dir`: its origin moved off `p` by
    /// [`Surface::offset`] to the side `dir` goes. The one way secondary rays start (the
    /// Whitted shader's lanes do the same arithmetic).
    #[inline]
    #[must_use]
    pub fn spawn(&self, dir: Vec3) -> Ray {
        let n = if dir.dot(self.ng) < 0.0 { -self.ng } else { self.ng };
        Ray::new(self.p + n * self.offset(), dir)
    }
}

impl World {
    /// Builds BLASes (in parallel) and the TLAS.
    pub fn new(scene: Scene, opts: MeshOptions) -> Result<Self, WorldError> {
        // Meshes that deform (morph targets, skins) keep zero-area triangles so refits stay exact.
        let deforming: Vec<u32> = scene
            .animation
            .as_ref()
            .map(|a| a.morphs.iter().map(|m| m.mesh).chain(a.skins.iter().map(|s| s.mesh)).collect())
            .unwrap_or_default();
        let meshes: Result<Vec<Geometry>, WorldError> = scene
            .meshes
            .par_iter()
            .enumerate()
            .map(|(i, m)| {
                let opts = MeshOptions { refittable: deforming.contains(&(i as u32)), ..opts };
                MeshBvh::build(&m.positions, &m.indices, opts)
                    .map(Geometry::Mesh)
                    .map_err(|source| WorldError::Build { mesh: m.name.clone(), source })
            })
            .collect();
        let mut geoms = meshes?;
        let kinds = [
            ShapeKind::Sphere,
            ShapeKind::Cylinder,
            ShapeKind::CappedCylinder,
            ShapeKind::Cone,
            ShapeKind::CappedCone,
            ShapeKind::Box,
            ShapeKind::Disk,
            ShapeKind::Tube,
        ];
        let shape_base = geoms.len() as u32;
        geoms.extend(kinds.iter().map(|&k| Geometry::Shape(shape_of(k))));
        let mut insts = Vec::with_capacity(scene.instances.len());
        let mut info = Vec::with_capacity(scene.instances.len());
        for i in &scene.instances {
            let g = match i.geom {
                Geom::Mesh(m) => m,
                Geom::Shape { kind, .. } => shape_base + kinds.iter().position(|&k| k == kind).unwrap_or(0) as u32,
            };
            let inst = Instance::new(g, i.world_from_object);
            info.push(InstInfo::new(i.geom, &inst));
            insts.push(inst);
        }
        let accel = TwoLevel::new(geoms, insts).map_err(WorldError::Top)?;
        let bounds = scene.bounds();
        let scale = bounds.map_or(1.0, |(lo, hi)| (hi - lo).length().max(1e-6));
        let faces = scene.meshes.iter().map(|m| face_normals(&m.positions, &m.indices)).collect();
        let prepared = scene.materials.par_iter().map(|m| Prepared::of(m, &scene)).collect();
        let has_alpha = scene.materials.iter().any(|m| m.alpha != lucent_scene::Alpha::Opaque);
        let emissive = emissive_triangles(&scene);
        let mut w = Self {
            scene,
            accel,
            info,
            lights: Vec::new(),
            scale,
            opts,
            faces,
            light_set: LightSet::default(),
            prepared,
            custom_lights: Vec::new(),
            emissive,
            has_alpha,
        };
        w.light_set = LightSet::of(&w.scene, bounds, &w.emissive, &w.custom_lights);
        w.lights = if w.scene.lights.is_empty() { w.emitter_lights(bounds) } else { w.scene.lights.clone() };
        w.sync_shadow_grids();
        Ok(w)
    }

    /// Gives the top level the directions toward the directional lights, for its
    /// shadow-ray grids (exactly as the shading makes the rays). Rays along any other
    /// direction take the walk, so a light changed afterwards costs speed, never
    /// correctness.
    fn sync_shadow_grids(&mut self) {
        let dirs: Vec<Vec3> = self
            .lights
            .iter()
            .filter_map(|l| match l.kind {
                LightKind::Directional { direction } => Some(crate::shading::toward_directional(direction)),
                _ => None,
            })
            .collect();
        self.accel.set_shadow_directions(&dirs);
    }

    /// Poses an animated scene at time `t` (glTF seconds): instance transforms from the
    /// node hierarchy (the top level is rebuilt), deforming meshes (their bottom level is
    /// refitted or rebuilt; skinned normals are skinned with the positions, and a morphing
    /// mesh that had normals gets smooth ones from its posed triangles, [`vertex_normals`]),
    /// and lights on animated nodes. Returns the scene's camera at `t`. A static scene is
    /// left as it is.
    pub fn set_time(&mut self, t: f32) -> Result<Option<lucent_scene::CameraDesc>, WorldError> {
        let Some(anim) = self.scene.animation.as_ref() else { return Ok(self.scene.camera) };
        let mut pose = anim.pose(t);
        // Whether an emitter moved: then the light set is made again (else only the point,
        // spot and directional lights follow their nodes).
        let mut emitters_moved = false;
        for (m, positions) in pose.meshes {
            emitters_moved |= self.emissive.get(m as usize).is_some_and(|e| !e.is_empty());
            let Some(mesh) = self.scene.meshes.get_mut(m as usize) else { continue };
            mesh.positions = positions;
            if let Some(f) = self.faces.get_mut(m as usize) {
                *f = face_normals(&mesh.positions, &mesh.indices);
            }
            // Shading normals follow the deformation: a skinned mesh's own normals are skinned
            // with it; a morphing mesh that came with normals gets smooth ones from its posed
            // triangles (vertices split at hard edges stay split); one without stays faceted.
            if let Some(k) = pose.normals.iter().position(|(nm, _)| *nm == m) {
                mesh.normals = lucent_scene::Attr { values: pose.normals.swap_remove(k).1, indices: None };
            } else if !mesh.normals.values.is_empty() {
                mesh.normals = lucent_scene::Attr { values: vertex_normals(&mesh.positions, &mesh.indices), indices: None };
            }
            let name = mesh.name.clone();
            let err = |source| WorldError::Build { mesh: name.clone(), source };
            // Refit; rebuild once the refitted tree costs REBUILD_RATIO times a fresh one.
            let ratio = match self.accel.geometry_mut(m as usize) {
                Some(Geometry::Mesh(bvh)) => bvh.refit(&mesh.positions, &mesh.indices).map_err(err)?,
                _ => f32::INFINITY,
            };
            if ratio > REBUILD_RATIO {
                let opts = MeshOptions { refittable: true, ..self.opts };
                let bvh = MeshBvh::build(&mesh.positions, &mesh.indices, opts).map_err(err)?;
                self.accel.set_geometry(m as usize, Geometry::Mesh(bvh)).map_err(WorldError::Top)?;
            }
        }
        let (info, scene, light_set) = (&mut self.info, &mut self.scene, &self.light_set);
        self.accel
            .update_instances(|insts| {
                for (k, ((inst, m), (info, si))) in
                    insts.iter_mut().zip(&pose.instances).zip(info.iter_mut().zip(scene.instances.iter_mut())).enumerate()
                {
                    emitters_moved |= light_set.lights_instance(k) && si.world_from_object != *m;
                    *inst = Instance::new(inst.geometry, *m);
                    *info = InstInfo::new(info.geom, inst);
                    si.world_from_object = *m;
                }
            })
            .map_err(WorldError::Top)?;
        if self.lights.len() == self.scene.lights.len() {
            for (li, m) in pose.lights {
                let Some(l) = self.lights.get_mut(li) else { continue };
                l.kind = match l.kind {
                    LightKind::Point { .. } => LightKind::Point { position: m.transform_point3(Vec3::ZERO) },
                    LightKind::Directional { .. } => {
                        LightKind::Directional { direction: m.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z) }
                    }
                    LightKind::Spot { inner, outer, .. } => LightKind::Spot {
                        position: m.transform_point3(Vec3::ZERO),
                        direction: m.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z),
                        inner,
                        outer,
                    },
                };
            }
        }
        self.sync_shadow_grids();
        // Made again when an emitter moved, or the scene's bounds did (the power of
        // directional and environment light, and where their light paths start, follow
        // them); posing the sunflower field's 5,622 instances walked 180 M triangles here.
        let bounds = self.scene.bounds();
        if emitters_moved || bounds_bits(bounds) != bounds_bits(self.light_set.bounds()) {
            self.remake_light_set(bounds);
        }
        if self.lights.len() == self.scene.lights.len() {
            self.light_set.set_delta(&self.lights);
        }
        Ok(pose.camera.or(self.scene.camera))
    }

    /// Makes the light set again, for the scene's `bounds`.
    fn remake_light_set(&mut self, bounds: Option<(Vec3, Vec3)>) {
        self.light_set = LightSet::of(&self.scene, bounds, &self.emissive, &self.custom_lights);
    }

    /// The scene (as posed by the last [`World::set_time`]).
    #[must_use]
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The two-level index.
    #[must_use]
    pub fn accel(&self) -> &TwoLevel {
        &self.accel
    }

    /// The lights used for rendering: the scene's, or, for a scene without lights, point
    /// lights at its emitters.
    #[must_use]
    pub fn lights(&self) -> &[Light] {
        &self.lights
    }

    /// Replaces the lights used for rendering (the top level's shadow-ray grids, and the
    /// lights the path tracer and the VPL integrator sample, follow).
    pub fn set_lights(&mut self, lights: Vec<Light>) {
        if lights != self.scene.lights {
            self.scene.lights.clone_from(&lights);
            self.remake_light_set(self.scene.bounds());
        }
        self.lights = lights;
        self.sync_shadow_grids();
    }

    /// Gives material `index` a BSDF of the user's own (see [`BsdfModel`]); the path
    /// tracer uses it instead of the material's. Returns false for an index out of range.
    pub fn set_bsdf(&mut self, index: u32, bsdf: Arc<dyn BsdfModel>) -> bool {
        match self.prepared.get_mut(index as usize) {
            Some(p) => {
                p.custom = Some(bsdf);
                true
            }
            None => false,
        }
    }

    /// Adds a light of the user's own (see [`LightModel`]) to those the path tracer samples.
    pub fn add_light(&mut self, light: Arc<dyn LightModel>) {
        self.custom_lights.push(light);
        self.remake_light_set(self.scene.bounds());
    }

    /// The prepared material `index` (the default one when out of range).
    pub(crate) fn prepared(&self, index: u32) -> &Prepared {
        static DEFAULT: std::sync::OnceLock<Prepared> = std::sync::OnceLock::new();
        self.prepared.get(index as usize).unwrap_or_else(|| {
            DEFAULT.get_or_init(|| Prepared::new(lucent_scene::Bsdf::from_phong(&lucent_scene::Material::default()), &Scene::default()))
        })
    }

    /// Whether the surface a hit found is cut out by its material's alpha mask.
    fn cut_out(&self, r: &Ray, h: &Hit) -> bool {
        let surf = self.surface(r, h);
        let Some(m) = self.scene.materials.get(surf.material as usize) else { return false };
        match m.alpha {
            lucent_scene::Alpha::Opaque => false,
            lucent_scene::Alpha::Mask { cutoff, tex, factor } => {
                let a =
                    factor * tex.and_then(|t| self.scene.textures.get(t as usize)).map_or(1.0, |t| crate::texture::sample(t, surf.uv).w);
                a < cutoff
            }
        }
    }

    /// The closest hit of a surface that exists (alpha masks skipped): the hit, and the
    /// ray it belongs to (a ray continued past cut-out parts starts beyond them).
    #[must_use]
    pub fn intersect_solid(&self, r: &Ray) -> Option<(Ray, Hit)> {
        let mut ray = *r;
        for _ in 0..64 {
            let h = self.intersect(&ray)?;
            if !self.has_alpha || !self.cut_out(&ray, &h) {
                return Some((ray, h));
            }
            let surf = self.surface(&ray, &h);
            let left = ray.tmax - h.t;
            ray = surf.spawn(ray.dir).with_range(0.0, left);
        }
        None
    }

    /// A camera path's first hit: `known`, a packet's closest hit for this ray, when given
    /// (see `integrator::packet_first_hits`: a miss stands, and a hit does where no surface
    /// has an alpha mask), else [`World::intersect_solid`].
    #[must_use]
    pub(crate) fn first_hit(&self, r: &Ray, known: Option<Option<Hit>>) -> Option<(Ray, Hit)> {
        match known {
            Some(Some(h)) if !self.has_alpha => Some((*r, h)),
            Some(None) => None,
            _ => self.intersect_solid(r),
        }
    }

    /// Whether a surface that exists (alpha masks skipped) blocks the ray.
    #[must_use]
    pub fn occluded_solid(&self, r: &Ray) -> bool {
        if !self.has_alpha {
            return self.occluded(r);
        }
        self.intersect_solid(r).is_some()
    }

    /// Whether some material has an alpha mask.
    #[must_use]
    pub fn has_alpha(&self) -> bool {
        self.has_alpha
    }

    /// The diagonal of the scene's bounds.
    #[must_use]
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// How the top level is rebuilt when instances move (see `TwoLevel::set_top_builder`).
    pub fn set_top_builder(&mut self, builder: lucent_accel::TopBuilder) {
        self.accel.set_top_builder(builder);
    }

    /// Gives a scene with no lights and no emitters a headlight at the camera, so it is
    /// not black; returns true when it did.
    pub fn ensure_light(&mut self, eye: Vec3) -> bool {
        if !self.lights.is_empty() {
            return false;
        }
        // (A point light: the shadow-ray grids, for directional lights, stay as they are.)
        self.lights.push(Light { kind: LightKind::Point { position: eye }, color: Vec3::splat(0.9), inverse_square: false });
        true
    }

    /// Closest hit.
    #[must_use]
    pub fn intersect(&self, r: &Ray) -> Option<Hit> {
        count_rays(1, |q| q.closest.push(*r));
        self.accel.intersect(r)
    }

    /// Any hit.
    #[must_use]
    pub fn occluded(&self, r: &Ray) -> bool {
        count_rays(1, |q| q.shadow.push(*r));
        self.accel.occluded(r)
    }

    /// Closest hits of coherent rays, traced in packets (see `TwoLevel::intersect_packet`).
    pub fn intersect_packet(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        count_rays(rays.len(), |q| q.closest_packets.push((rays.to_vec(), None)));
        self.accel.intersect_packet(rays, out);
    }

    /// Closest hits of coherent rays that can meet no instance but those of `ids` (see
    /// `TwoLevel::intersect_packet_among`).
    pub fn intersect_packet_among(&self, rays: &[Ray], ids: &[u32], out: &mut [Option<Hit>]) {
        count_rays(rays.len(), |q| q.closest_packets.push((rays.to_vec(), Some(ids.to_vec()))));
        self.accel.intersect_packet_among(rays, ids, out);
    }

    /// Occlusion of coherent rays (for example shadow rays leaving one point), traced in
    /// packets; surfaces cut out by alpha masks do not block (rays are then traced alone).
    pub fn occluded_packet(&self, rays: &[Ray], out: &mut [bool]) {
        if self.has_alpha {
            for (o, r) in out.iter_mut().zip(rays) {
                *o = self.occluded_solid(r);
            }
            return;
        }
        count_rays(rays.len(), |q| q.shadow_packets.push(rays.to_vec()));
        self.accel.occluded_packet(rays, out);
    }

    /// Occlusion of rays in SoA blocks (empty lanes allowed), `rays` of them real.
    pub(crate) fn occluded_blocks(&self, blocks: &[lucent_accel::RayBlock], out: &mut [bool], rays: usize) {
        count_rays(rays, |q| q.shadow_blocks.push((blocks.to_vec(), rays)));
        self.accel.occluded_blocks(blocks, out);
    }

    /// Rebuilds the surface point of a hit.
    #[must_use]
    pub fn surface(&self, r: &Ray, h: &Hit) -> Surface {
        let inst = &self.info[h.inst as usize];
        let object_from_world = &self.accel.instances()[h.inst as usize].object_from_world;
        match inst.geom {
            Geom::Mesh(m) => {
                let mesh = &self.scene.meshes[m as usize];
                let tri = h.prim as usize;
                // The hit point `o + t d`, and a bound on its distance from the triangle's
                // plane as the triangle test sees it (the unit-triangle test, `triangle.rs`,
                // has no error bound on t of its own): its map is rounded to f32 (2^-24 of
                // each entry) and evaluated at the origin with three fused multiply-adds,
                // and t = -z(o) / z(d) with z(d) rounded as much, so the point found lies
                // within γ(9)·(|o| + |t d|) + γ(6)·|p| of the plane in each coordinate (the
                // plane's own offset, |n · p0| = |n · p| there, counted by the |p| term).
                // An error in t moves the point along the ray, which is why no division by
                // the ray's slope appears: what matters is the distance from the plane.
                // PERF: no vertex is read (rebuilding p from its barycentrics, as pbrt-v4
                // §6.8.5 does, reads three, and took 10% of a shaded Conference frame).
                let p = r.at(h.t);
                let (oa, td) = (r.org.abs(), (r.dir * h.t).abs());
                let p_err = (oa + td) * lucent_accel::gamma(9) + p.abs() * lucent_accel::gamma(6);
                let p_err = if inst.in_place {
                    p_err
                } else {
                    // The test ran in object space, on the ray carried there by the inverse
                    // (rounded: γ(3) of its terms) and against the same bound there, so
                    // those errors show in world space through |M| (`err_k`, `err_c`).
                    p_err
                        + Vec3::from(inst.err_k * glam::Vec3A::from(oa + td + p.abs()) + glam::Vec3A::from(inst.err_c))
                            * lucent_accel::gamma(12)
                };
                let ng_obj = match self.faces.get(m as usize).and_then(|f| f.get(tri)) {
                    Some(f) => *f,
                    None => face_normal(&mesh.positions, &mesh.indices[tri]),
                };
                let ng = if inst.identity { ng_obj } else { (inst.normal_to_world * glam::Vec3A::from(ng_obj)).normalize_or_zero().into() };
                let w = Vec3::new(1.0 - h.u - h.v, h.u, h.v);
                // The vertex indices only for per-vertex normals or texture coordinates.
                let idx = if mesh.normals.values.is_empty() && mesh.uvs.values.is_empty() { [0; 3] } else { mesh.indices[tri] };
                let ns = match mesh.normals.corners(tri, &idx) {
                    Some([n0, n1, n2]) => {
                        let n: Vec3 = (inst.normal_to_world * glam::Vec3A::from(n0 * w.x + n1 * w.y + n2 * w.z)).into();
                        let n = n.normalize_or_zero();
                        if n == Vec3::ZERO || !n.is_finite() {
                            ng
                        } else if n.dot(ng) < 0.0 {
                            // Keep shading normals on the geometric side (flipped winding).
                            -n
                        } else {
                            n
                        }
                    }
                    None => ng,
                };
                let uv = mesh.uvs.corners(tri, &idx).map_or(Vec2::new(h.u, h.v), |[t0, t1, t2]| t0 * w.x + t1 * w.y + t2 * w.z);
                Surface { p, ng, ns, uv, material: mesh.material.get(tri).copied().unwrap_or(0), p_err }
            }
            Geom::Shape { kind, material } => {
                // The hit point `o + t d`. The shape tests solve in f64 (exact next to
                // f32, even near tangency, where a root's error is about the square root
                // of f64's unit roundoff), on the ray carried into object space by the
                // inverse in f32 (γ(3) of its terms): the point is off the surface by at
                // most that carried error, seen through |M| (`err_k`, `err_c`), plus the
                // rounding of t and of `o + t d`.
                let p = r.at(h.t);
                let ot = r.org.abs() + (r.dir * h.t).abs();
                let p_err = ot * lucent_accel::gamma(5)
                    + Vec3::from(inst.err_k * glam::Vec3A::from(ot) + glam::Vec3A::from(inst.err_c)) * lucent_accel::gamma(4);
                let p_obj = object_from_world.transform_point3(p);
                let n_obj = shape_of(kind).normal_local(p_obj, h.prim);
                let ng: Vec3 = (inst.normal_to_world * glam::Vec3A::from(n_obj)).normalize_or_zero().into();
                // PERF: the uv (atan2, acos) only for textured materials (a tenth of a
                // 4,096-sphere REND3R frame went to uvs nobody read).
                let textured = self.scene.materials.get(material as usize).is_some_and(|m| m.diffuse_tex.is_some());
                let uv = if textured {
                    let (u, v) = shape_of(kind).uv_local(p_obj, h.prim);
                    Vec2::new(u, v)
                } else {
                    Vec2::ZERO
                };
                Surface { p, ng, ns: ng, uv, material, p_err }
            }
        }
    }

    /// The world-space derivatives ∂p/∂u and ∂p/∂v of a mesh hit's triangle, from its
    /// corners' texture coordinates (`None` for shapes, meshes without texture coordinates
    /// and triangles whose coordinates are degenerate).
    #[must_use]
    pub fn uv_tangents(&self, _r: &Ray, h: &Hit) -> Option<(Vec3, Vec3)> {
        let inst = self.info.get(h.inst as usize)?;
        let Geom::Mesh(m) = inst.geom else { return None };
        let mesh = self.scene.meshes.get(m as usize)?;
        let idx = *mesh.indices.get(h.prim as usize)?;
        let [t0, t1, t2] = mesh.uvs.corners(h.prim as usize, &idx)?;
        let p = idx.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::NAN));
        let (dp1, dp2) = (p[1] - p[0], p[2] - p[0]);
        let (d1, d2) = (t1 - t0, t2 - t0);
        let det = d1.x * d2.y - d1.y * d2.x;
        if det.abs() < 1e-20 || !det.is_finite() {
            return None;
        }
        let dpdu = (dp1 * d2.y - dp2 * d1.y) / det;
        let dpdv = (dp2 * d1.x - dp1 * d2.x) / det;
        let m3 = self.accel.instances()[h.inst as usize].world_from_object.matrix3;
        let (u, v): (Vec3, Vec3) = ((m3 * glam::Vec3A::from(dpdu)).into(), (m3 * glam::Vec3A::from(dpdv)).into());
        (u.is_finite() && v.is_finite()).then_some((u, v))
    }

    /// Point lights at the emitting surfaces (one per emissive material and instance), for
    /// scenes such as the Cornell box that light themselves by geometry.
    fn emitter_lights(&self, bounds: Option<(Vec3, Vec3)>) -> Vec<Light> {
        let mut out = Vec::new();
        for inst in &self.scene.instances {
            let Geom::Mesh(m) = inst.geom else { continue };
            let mesh = &self.scene.meshes[m as usize];
            let mut acc: std::collections::BTreeMap<u32, (Vec3, Vec3, f32)> = Default::default();
            for &t in self.emissive.get(m as usize).map_or(&[][..], |e| &e[..]) {
                let (t, idx) = (t as usize, &mesh.indices[t as usize]);
                let mat = mesh.material.get(t).copied().unwrap_or(0);
                let Some(mm) = self.scene.materials.get(mat as usize) else {
                    continue;
                };
                if mm.emission.max_element() <= 0.0 {
                    continue;
                }
                let [a, b, c] = idx.map(|i| inst.world_from_object.transform_point3(mesh.positions[i as usize]));
                let n = (b - a).cross(c - a);
                let area = n.length() * 0.5;
                if area.is_nan() || area <= 0.0 {
                    continue;
                }
                let e = acc.entry(mat).or_insert((Vec3::ZERO, Vec3::ZERO, 0.0));
                e.0 += (a + b + c) / 3.0 * area;
                e.1 += n;
                e.2 += area;
            }
            for (mat, (pc, n, area)) in acc {
                let em = self.scene.materials[mat as usize].emission;
                // Just off the emitter, on the side it faces (the side the camera sees for a ceiling light).
                let mut nn = n.normalize_or_zero();
                if let Some((lo, hi)) = bounds {
                    if nn.dot((lo + hi) * 0.5 - pc / area) < 0.0 {
                        nn = -nn;
                    }
                }
                let position = pc / area + nn * (self.scale * 0.02);
                out.push(Light { kind: LightKind::Point { position }, color: em / em.max_element(), inverse_square: false });
            }
        }
        out
    }
}

/// Bounds as bits (equal bits: the same bounds; NaN included).
fn bounds_bits(b: Option<(Vec3, Vec3)>) -> Option<[u32; 6]> {
    b.map(|(lo, hi)| {
        let (l, h) = (lo.to_array().map(f32::to_bits), hi.to_array().map(f32::to_bits));
        [l[0], l[1], l[2], h[0], h[1], h[2]]
    })
}

/// Luminance of linear sRGB (Rec. 709 weights).
#[inline]
#[must_use]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

thread_local! {
    static RAYS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    /// Whether this thread keeps the rays it traces in [`RECORD`] (see [`record_rays`]).
    static RECORDING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    static RECORD: std::cell::RefCell<RecordedRays> = std::cell::RefCell::new(RecordedRays::default());
}

/// The queries a piece of work sent to a [`World`], kept by [`record_rays`] so that they
/// can be traced again alone: how much of a renderer's time its rays take, with nothing
/// else between them (the ceiling a faster integrator could reach with the same kernels).
#[derive(Clone, Debug, Default)]
pub struct RecordedRays {
    /// Closest-hit rays traced one by one.
    pub closest: Vec<Ray>,
    /// Shadow rays traced one by one.
    pub shadow: Vec<Ray>,
    /// Packets of closest-hit rays, with the instances they were restricted to.
    pub closest_packets: Vec<(Vec<Ray>, Option<Vec<u32>>)>,
    /// Packets of shadow rays.
    pub shadow_packets: Vec<Vec<Ray>>,
    /// Shadow rays in SoA blocks, and how many of their lanes are rays.
    pub shadow_blocks: Vec<(Vec<lucent_accel::RayBlock>, usize)>,
}

impl RecordedRays {
    /// Rays recorded.
    #[must_use]
    pub fn rays(&self) -> u64 {
        (self.closest.len()
            + self.shadow.len()
            + self.closest_packets.iter().map(|p| p.0.len()).sum::<usize>()
            + self.shadow_packets.iter().map(Vec::len).sum::<usize>()
            + self.shadow_blocks.iter().map(|b| b.1).sum::<usize>()) as u64
    }

    /// Traces every recorded query again on `w` (on all of rayon's threads, each query as
    /// it was traced: alone or in its packet), for timing; returns the hits and blocked rays
    /// found, so that the work cannot be optimised away.
    pub fn trace(&self, w: &World) -> u64 {
        /// The sum of `f` over `items`, in chunks on rayon's threads.
        fn par_sum<T: Sync>(items: &[T], chunk: usize, f: impl Fn(&T) -> usize + Sync) -> usize {
            items.par_chunks(chunk).map(|c| c.iter().map(&f).sum::<usize>()).sum()
        }
        let closest = par_sum(&self.closest, 4096, |r| usize::from(w.accel.intersect(r).is_some()));
        let shadow = par_sum(&self.shadow, 4096, |r| usize::from(w.accel.occluded(r)));
        let closest_packets = par_sum(&self.closest_packets, 64, |(rays, ids)| {
            let mut out = [None; lucent_accel::MAX_PACKET];
            let out = &mut out[..rays.len()];
            match ids {
                Some(ids) => w.accel.intersect_packet_among(rays, ids, out),
                None => w.accel.intersect_packet(rays, out),
            }
            out.iter().filter(|h| h.is_some()).count()
        });
        let shadow_packets = par_sum(&self.shadow_packets, 64, |rays| {
            let mut out = [false; lucent_accel::MAX_PACKET];
            let out = &mut out[..rays.len()];
            w.accel.occluded_packet(rays, out);
            out.iter().filter(|&&b| b).count()
        });
        let shadow_blocks = par_sum(&self.shadow_blocks, 64, |(blocks, _)| {
            let mut out = vec![false; blocks.len() * lucent_accel::simd::LANES];
            w.accel.occluded_blocks(blocks, &mut out);
            out.iter().filter(|&&b| b).count()
        });
        (closest + shadow + closest_packets + shadow_packets + shadow_blocks) as u64
    }
}

/// Runs `f` while keeping every ray that this thread sends to a [`World`] (work that `f`
/// hands to other threads is not seen: run it in a one-thread pool), and returns what `f`
/// returned with those rays. When nothing is recorded, a query pays one flag test.
pub fn record_rays<R>(f: impl FnOnce() -> R) -> (R, RecordedRays) {
    /// Stops the recording even when `f` panics.
    struct Stop;
    impl Drop for Stop {
        fn drop(&mut self) {
            RECORDING.set(false);
        }
    }
    RECORD.with_borrow_mut(|q| *q = RecordedRays::default());
    RECORDING.set(true);
    let stop = Stop;
    let r = f();
    drop(stop);
    (r, RECORD.take())
}

/// Counts `n` rays of a query on this thread, and keeps the query with `keep` while
/// [`record_rays`] records.
#[inline]
fn count_rays(n: usize, keep: impl FnOnce(&mut RecordedRays)) {
    RAYS.with(|c| c.set(c.get() + n as u64));
    if RECORDING.get() {
        RECORD.with_borrow_mut(keep);
    }
}

/// Rays traced by this thread so far (closest-hit and shadow queries).
#[must_use]
pub fn rays_traced_here() -> u64 {
    RAYS.with(|c| c.get())
}

/// The inverse transpose of the linear part (for normals).
fn normal_matrix(inst: &Instance) -> Mat3A {
    // The instance already holds the inverse (`Affine3A::inverse` inverts the linear part
    // exactly as `Mat3A::inverse` does), so it is not computed a second time.
    let inv = inst.object_from_world.matrix3;
    if inv.is_finite() {
        inv.transpose()
    } else {
        inst.world_from_object.matrix3
    }
}

/// Smooth vertex normals of a triangle mesh: each vertex gets the sum of its triangles'
/// area-weighted normals, normalized (zero where that sum is zero, e.g. a vertex of
/// degenerate triangles only; the shader then uses the face normal). Triangles with
/// indices out of range or non-finite corners are skipped.
#[must_use]
pub fn vertex_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; positions.len()];
    for idx in indices {
        let at = |k: usize| positions.get(idx[k] as usize).copied();
        let (Some(a), Some(b), Some(c)) = (at(0), at(1), at(2)) else { continue };
        let f = (b - a).cross(c - a);
        if !f.is_finite() {
            continue;
        }
        for &i in idx {
            n[i as usize] += f;
        }
    }
    for v in &mut n {
        *v = v.normalize_or_zero();
    }
    n
}

//! The render-side view of a scene: the two-level acceleration structure built from it,
//! plus everything shading needs to rebuild a surface point from a hit. Split by concern:
//! this file builds a [`World`]; [`pose`] changes it (animation, lights, the user's
//! BSDFs); [`query`] traces rays through it; [`surface`] rebuilds surface points from
//! hits; [`record`] counts and records the rays it traces.

pub mod pose;
pub mod query;
pub mod record;
pub mod surface;

use crate::lights::{emissive_triangles, LightModel, LightSet};
use crate::materials::PreparedMaterial;
use glam::{Mat3A, Vec3};
use lucent_accel::{Geometry, Instance, MeshBvh, MeshOptions, Shape, TwoLevel};
use lucent_scene::{Geom, Light, LightKind, Scene, ShapeKind};
use rayon::prelude::*;
use std::sync::Arc;

/// Errors of preparing a scene for rendering.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// Building an acceleration structure failed.
    #[error("mesh '{mesh}': {cause}")]
    Build {
        /// Mesh name.
        mesh: String,
        /// Cause (in the message, so not also a `source()`).
        cause: lucent_accel::BuildError,
    },
    /// The top level failed.
    #[error("instances: {0}")]
    Top(lucent_accel::BuildError),
    /// An edit that does not fit the world (an index out of range, a count that differs).
    #[error("{0}")]
    Edit(String),
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
    pub(crate) prepared: Vec<PreparedMaterial>,
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

impl World {
    /// Builds BLASes (in parallel) and the TLAS.
    ///
    /// # Example
    /// The built-in demo scene: a ray from its camera through the middle of the image meets
    /// a surface, which [`World::surface`] rebuilds.
    /// ```
    /// use lucent_render::{Camera, World};
    /// let scene = lucent_scene::demo_scene();
    /// let camera = Camera::new(&scene.camera.expect("the demo has a camera"), 64, 48);
    /// let world = World::new(scene, lucent_accel::MeshOptions::default()).unwrap();
    /// let ray = camera.ray(32.0, 24.0);
    /// let hit = world.intersect(&ray).expect("something in the middle");
    /// let surf = world.surface(&ray, &hit);
    /// assert!((surf.ng.length() - 1.0).abs() < 1e-5 && surf.ng.dot(ray.dir) < 0.0);
    /// ```
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
                    .map_err(|cause| WorldError::Build { mesh: m.name.clone(), cause })
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
        let prepared = scene.materials.par_iter().map(|m| PreparedMaterial::of(m, &scene)).collect();
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

    /// The prepared material `index` (the default one when out of range).
    pub(crate) fn prepared(&self, index: u32) -> &PreparedMaterial {
        static DEFAULT: std::sync::OnceLock<PreparedMaterial> = std::sync::OnceLock::new();
        self.prepared.get(index as usize).unwrap_or_else(|| {
            DEFAULT.get_or_init(|| {
                PreparedMaterial::new(lucent_scene::Bsdf::from_phong(&lucent_scene::Material::default()), &Scene::default())
            })
        })
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

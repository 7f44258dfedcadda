//! Changing a world: posing an animated scene at a time ([`World::set_time`]), replacing
//! its lights, the user's BSDFs and lights, how the top level is rebuilt. Each keeps the
//! index and the per-instance and per-triangle caches in step with the scene.

use super::{face_normals, InstInfo, World, WorldError, REBUILD_RATIO};
use crate::bsdf::BsdfModel;
use crate::lights::{toward_directional, LightModel, LightSet};
use glam::Vec3;
use lucent_accel::{Geometry, Instance, MeshBvh, MeshOptions};
use lucent_scene::{Light, LightKind};
use std::sync::Arc;

impl World {
    /// Gives the top level the directions toward the directional lights, for its
    /// shadow-ray grids (exactly as the shading makes the rays). Rays along any other
    /// direction take the walk, so a light changed afterwards costs speed, never
    /// correctness.
    pub(super) fn sync_shadow_grids(&mut self) {
        let dirs: Vec<Vec3> = self
            .lights
            .iter()
            .filter_map(|l| match l.kind {
                LightKind::Directional { direction } => Some(toward_directional(direction)),
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
            let normals = pose.normals.iter().position(|(nm, _)| *nm == m).map(|k| pose.normals.swap_remove(k).1);
            self.pose_mesh(m as usize, positions, normals)?;
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

    /// Moves mesh `m`'s vertices to `positions` (as many as it has): its bottom level is
    /// refitted (rebuilt once a refit costs [`REBUILD_RATIO`] times a fresh build), its
    /// face normals follow, and so do its shading normals: `normals` when given, else
    /// smooth ones from the moved triangles where it had any. Every instance of the mesh
    /// moves with it; the lights follow when it emits.
    pub fn set_mesh_positions(&mut self, m: usize, positions: Vec<Vec3>, normals: Option<Vec<Vec3>>) -> Result<(), WorldError> {
        let count = self.scene.meshes.get(m).map_or(0, |mesh| mesh.positions.len());
        if m >= self.scene.meshes.len() || positions.len() != count {
            return Err(WorldError::Edit(format!(
                "mesh {m}: {} positions given where it has {count} (of {} meshes)",
                positions.len(),
                self.scene.meshes.len()
            )));
        }
        let emits = self.emissive.get(m).is_some_and(|e| !e.is_empty());
        self.pose_mesh(m, positions, normals)?;
        // (The mesh's bounds moved: so do its instances' in the top level.)
        self.accel.rebuild().map_err(WorldError::Top)?;
        self.refresh_lights(emits);
        Ok(())
    }

    /// Gives instances new transforms (`(instance, world_from_object)` pairs) and rebuilds
    /// the top level once; the lights follow when an emitter moved or the bounds did.
    pub fn set_instance_transforms(&mut self, moves: &[(usize, glam::Affine3A)]) -> Result<(), WorldError> {
        let n = self.scene.instances.len();
        if let Some(&(i, _)) = moves.iter().find(|(i, m)| *i >= n || !m.is_finite() || m.matrix3.determinant() == 0.0) {
            return Err(WorldError::Edit(if i >= n {
                format!("instance {i} out of range ({n} instances)")
            } else {
                format!("instance {i}: the transform is not finite or not invertible")
            }));
        }
        let mut emitters_moved = false;
        let (info, scene, light_set) = (&mut self.info, &mut self.scene, &self.light_set);
        self.accel
            .update_instances(|insts| {
                for &(i, m) in moves {
                    emitters_moved |= light_set.lights_instance(i) && scene.instances[i].world_from_object != m;
                    insts[i] = Instance::new(insts[i].geometry, m);
                    info[i] = InstInfo::new(info[i].geom, &insts[i]);
                    scene.instances[i].world_from_object = m;
                }
            })
            .map_err(WorldError::Top)?;
        self.refresh_lights(emitters_moved);
        Ok(())
    }

    /// Keeps the instances for which `keep` is true (in order; the others are gone, and
    /// the later ones' indices close up) and rebuilds the top level; the bottom levels stay.
    pub fn retain_instances(&mut self, keep: &[bool]) -> Result<(), WorldError> {
        if keep.len() != self.scene.instances.len() {
            return Err(WorldError::Edit(format!("{} flags for {} instances", keep.len(), self.scene.instances.len())));
        }
        let mut k = keep.iter();
        self.scene.instances.retain(|_| *k.next().unwrap_or(&true));
        let mut k = keep.iter();
        self.info.retain(|_| *k.next().unwrap_or(&true));
        let insts: Vec<Instance> = self.accel.instances().iter().zip(keep).filter(|(_, &keep)| keep).map(|(inst, _)| *inst).collect();
        self.accel.set_instances(insts).map_err(WorldError::Top)?;
        // (Instance indices moved: the light set, which names them, is made again.)
        self.refresh_lights(true);
        Ok(())
    }

    /// Mesh `m` posed at `positions` (and `normals`), its index refitted or rebuilt.
    fn pose_mesh(&mut self, m: usize, positions: Vec<Vec3>, normals: Option<Vec<Vec3>>) -> Result<(), WorldError> {
        let Some(mesh) = self.scene.meshes.get_mut(m) else { return Ok(()) };
        mesh.positions = positions;
        if let Some(f) = self.faces.get_mut(m) {
            *f = face_normals(&mesh.positions, &mesh.indices);
        }
        // Shading normals follow the deformation: given ones (a skinned mesh's own,
        // skinned with it), else a mesh that came with normals gets smooth ones from its
        // posed triangles (vertices split at hard edges stay split); one without stays
        // faceted.
        if let Some(n) = normals {
            mesh.normals = lucent_scene::Attr { values: n, indices: None };
        } else if !mesh.normals.values.is_empty() {
            mesh.normals = lucent_scene::Attr { values: vertex_normals(&mesh.positions, &mesh.indices), indices: None };
        }
        let name = mesh.name.clone();
        let err = |cause| WorldError::Build { mesh: name.clone(), cause };
        // Refit; rebuild once the refitted tree costs REBUILD_RATIO times a fresh one.
        let ratio = match self.accel.geometry_mut(m) {
            Some(Geometry::Mesh(bvh)) => bvh.refit(&mesh.positions, &mesh.indices).map_err(err)?,
            _ => f32::INFINITY,
        };
        if ratio > REBUILD_RATIO {
            let opts = MeshOptions { refittable: true, ..self.opts };
            let bvh = MeshBvh::build(&mesh.positions, &mesh.indices, opts).map_err(err)?;
            self.accel.set_geometry(m, Geometry::Mesh(bvh)).map_err(WorldError::Top)?;
        }
        Ok(())
    }

    /// After an edit: the light set made again when an emitter moved or the bounds did.
    fn refresh_lights(&mut self, emitters_moved: bool) {
        let bounds = self.scene.bounds();
        if emitters_moved || bounds_bits(bounds) != bounds_bits(self.light_set.bounds()) {
            self.remake_light_set(bounds);
        }
    }

    /// Makes the light set again, for the scene's `bounds`.
    pub(super) fn remake_light_set(&mut self, bounds: Option<(Vec3, Vec3)>) {
        self.light_set = LightSet::of(&self.scene, bounds, &self.emissive, &self.custom_lights);
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
}

/// Bounds as bits (equal bits: the same bounds; NaN included).
fn bounds_bits(b: Option<(Vec3, Vec3)>) -> Option<[u32; 6]> {
    b.map(|(lo, hi)| {
        let (l, h) = (lo.to_array().map(f32::to_bits), hi.to_array().map(f32::to_bits));
        [l[0], l[1], l[2], h[0], h[1], h[2]]
    })
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

//! glTF animation: node translation, rotation and scale channels (LINEAR, STEP and
//! CUBICSPLINE, as the glTF 2.0 specification defines them, Appendix C), morph-target
//! weights, and the nodes that instances, the camera and lights hang from. A
//! [`SceneAnimation`] evaluates the scene at any time into a [`Pose`]: world transforms of
//! the instances, the camera, light positions and morphed vertex positions.

use crate::camera::CameraDesc;
use glam::{Affine3A, Mat4, Quat, Vec3};

/// How a sampler interpolates between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interp {
    /// Hold the previous key.
    Step,
    /// Linear (spherical-linear for rotations).
    Linear,
    /// Cubic Hermite with in/out tangents per key.
    CubicSpline,
}

/// What a channel animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// Node translation (3 values a key).
    Translation,
    /// Node rotation quaternion x, y, z, w (4 values a key).
    Rotation,
    /// Node scale (3 values a key).
    Scale,
    /// Morph-target weights of the node's mesh (one value per target a key).
    Weights,
}

/// One animation channel with its sampler.
#[derive(Clone, Debug)]
pub struct Channel {
    /// Node index.
    pub node: u32,
    /// Property.
    pub target: Target,
    /// Interpolation.
    pub interp: Interp,
    /// Key times (seconds, ascending).
    pub times: Vec<f32>,
    /// Key values, flattened: `width` values a key, or 3 × `width` (in-tangent, value,
    /// out-tangent) for CUBICSPLINE.
    pub values: Vec<f32>,
    /// Values per key element (3, 4, or the number of morph targets).
    pub width: usize,
}

/// A node of the hierarchy (its rest transform and parent).
#[derive(Clone, Copy, Debug)]
pub struct Node {
    /// Parent node.
    pub parent: Option<u32>,
    /// Rest translation.
    pub t: Vec3,
    /// Rest rotation.
    pub r: Quat,
    /// Rest scale.
    pub s: Vec3,
}

/// A mesh whose vertices follow morph-target weights.
#[derive(Clone, Debug)]
pub struct Morph {
    /// Mesh index in `Scene::meshes`.
    pub mesh: u32,
    /// Node whose weights drive it.
    pub node: u32,
    /// Base positions.
    pub base: Vec<Vec3>,
    /// Position displacements, one array per target.
    pub targets: Vec<Vec<Vec3>>,
    /// Weights when no channel animates them.
    pub default_weights: Vec<f32>,
}

/// A skinned mesh (glTF skins): vertices follow joint nodes (linear blend skinning).
#[derive(Clone, Debug)]
pub struct Skin {
    /// Mesh index in `Scene::meshes`.
    pub mesh: u32,
    /// Instance that draws it (its transform becomes the identity: skinned vertices are
    /// in world space, as glTF specifies).
    pub instance: u32,
    /// Joint nodes.
    pub joints: Vec<u32>,
    /// Inverse bind matrix per joint.
    pub inverse_bind: Vec<Mat4>,
    /// Bind-pose positions.
    pub base: Vec<Vec3>,
    /// Bind-pose normals, one per position (empty when the mesh has none or they are
    /// indexed apart from the positions).
    pub base_normals: Vec<Vec3>,
    /// Four joint indices (into `joints`) per vertex.
    pub vertex_joints: Vec<[u16; 4]>,
    /// Four weights per vertex.
    pub vertex_weights: Vec<[f32; 4]>,
}

/// Translation, rotation, scale.
type Trs = (Vec3, Quat, Vec3);

/// The animated parts of a scene.
#[derive(Clone, Debug, Default)]
pub struct SceneAnimation {
    /// Every node of the file.
    pub nodes: Vec<Node>,
    /// Channels of every animation (all play together).
    pub channels: Vec<Channel>,
    /// Node of each `Scene::instances` entry.
    pub instance_nodes: Vec<u32>,
    /// Node of the camera, with its vertical fov (degrees) and orthographic height.
    pub camera: Option<(u32, f32, Option<f32>)>,
    /// Node of each `Scene::lights` entry (lights from nodes only).
    pub light_nodes: Vec<(usize, u32)>,
    /// Morphing meshes.
    pub morphs: Vec<Morph>,
    /// Skinned meshes.
    pub skins: Vec<Skin>,
}

/// The scene at one time.
#[derive(Clone, Debug, Default)]
pub struct Pose {
    /// World transform of each instance.
    pub instances: Vec<Affine3A>,
    /// The camera, when the scene has one.
    pub camera: Option<CameraDesc>,
    /// (light index, world transform of its node).
    pub lights: Vec<(usize, Affine3A)>,
    /// (mesh index, posed normals) of skinned meshes with bind-pose normals.
    pub normals: Vec<(u32, Vec<Vec3>)>,
    /// (mesh index, new positions) of morphing meshes.
    pub meshes: Vec<(u32, Vec<Vec3>)>,
}

impl SceneAnimation {
    /// True when something moves.
    #[must_use]
    pub fn is_animated(&self) -> bool {
        !self.channels.is_empty()
    }

    /// First and last key time over all channels.
    #[must_use]
    pub fn time_range(&self) -> (f32, f32) {
        let lo = self.channels.iter().filter_map(|c| c.times.first()).copied().fold(f32::INFINITY, f32::min);
        let hi = self.channels.iter().filter_map(|c| c.times.last()).copied().fold(f32::NEG_INFINITY, f32::max);
        if lo <= hi {
            (lo, hi)
        } else {
            (0.0, 0.0)
        }
    }

    /// Local TRS of every node at time `t`, and morph weights per node.
    fn locals(&self, t: f32) -> (Vec<Trs>, Vec<Option<Vec<f32>>>) {
        let mut l: Vec<Trs> = self.nodes.iter().map(|n| (n.t, n.r, n.s)).collect();
        let mut w: Vec<Option<Vec<f32>>> = vec![None; self.nodes.len()];
        for c in &self.channels {
            let Some(v) = sample(c, t) else { continue };
            let Some(slot) = l.get_mut(c.node as usize) else { continue };
            match c.target {
                Target::Translation => slot.0 = Vec3::new(v[0], v[1], v[2]),
                Target::Rotation => slot.1 = Quat::from_xyzw(v[0], v[1], v[2], v[3]).normalize(),
                Target::Scale => slot.2 = Vec3::new(v[0], v[1], v[2]),
                Target::Weights => w[c.node as usize] = Some(v),
            }
        }
        (l, w)
    }

    /// World matrices of every node at time `t` (parents before children is not assumed).
    #[must_use]
    pub fn world_matrices(&self, t: f32) -> Vec<Mat4> {
        let (locals, _) = self.locals(t);
        self.compose(&locals)
    }

    fn compose(&self, locals: &[Trs]) -> Vec<Mat4> {
        let n = self.nodes.len();
        let mut world: Vec<Option<Mat4>> = vec![None; n];
        for i in 0..n {
            // Walk up to the first known ancestor (bounded: the loader refuses cycles).
            let mut chain = vec![i];
            let mut cur = i;
            while world[cur].is_none() {
                match self.nodes[cur].parent {
                    Some(p) if (p as usize) < n && chain.len() <= n => {
                        cur = p as usize;
                        if world[cur].is_none() {
                            chain.push(cur);
                        }
                    }
                    _ => break,
                }
            }
            for &k in chain.iter().rev() {
                if world[k].is_some() {
                    continue;
                }
                let (t, r, s) = locals[k];
                let local = Mat4::from_scale_rotation_translation(s, r, t);
                let parent = self.nodes[k].parent.and_then(|p| world.get(p as usize).copied().flatten()).unwrap_or(Mat4::IDENTITY);
                world[k] = Some(parent * local);
            }
        }
        world.into_iter().map(|m| m.unwrap_or(Mat4::IDENTITY)).collect()
    }

    /// The scene at time `t` (seconds, glTF time).
    #[must_use]
    pub fn pose(&self, t: f32) -> Pose {
        let (locals, weights) = self.locals(t);
        let world = self.compose(&locals);
        let at = |n: u32| Affine3A::from_mat4(world.get(n as usize).copied().unwrap_or(Mat4::IDENTITY));
        let camera = self.camera.map(|(n, vfov, ortho)| {
            let m = at(n);
            let eye = m.transform_point3(Vec3::ZERO);
            let fwd = m.transform_vector3(-Vec3::Z);
            CameraDesc { eye, look_at: eye + fwd, up: m.transform_vector3(Vec3::Y), vfov_deg: vfov, ortho_height: ortho }
        });
        let mut meshes: Vec<(u32, Vec<Vec3>)> = self
            .morphs
            .iter()
            .map(|m| {
                let w = weights.get(m.node as usize).cloned().flatten().unwrap_or_else(|| m.default_weights.clone());
                let mut p = m.base.clone();
                for (tw, disp) in w.iter().zip(&m.targets) {
                    if *tw != 0.0 {
                        for (p, d) in p.iter_mut().zip(disp) {
                            *p += *d * *tw;
                        }
                    }
                }
                (m.mesh, p)
            })
            .collect();
        let mut instances: Vec<Affine3A> = self.instance_nodes.iter().map(|&n| at(n)).collect();
        let mut normals = Vec::new();
        for sk in &self.skins {
            let joint: Vec<Mat4> = sk
                .joints
                .iter()
                .zip(&sk.inverse_bind)
                .map(|(&j, ibm)| world.get(j as usize).copied().unwrap_or(Mat4::IDENTITY) * *ibm)
                .collect();
            // Each vertex's blended joint matrix (linear blend skinning).
            let blend = |js: &[u16; 4], ws: &[f32; 4]| {
                let mut m = Mat4::ZERO;
                for k in 0..4 {
                    if ws[k] != 0.0 {
                        m += joint.get(usize::from(js[k])).copied().unwrap_or(Mat4::IDENTITY) * ws[k];
                    }
                }
                m
            };
            // Positions, and normals by the inverse transpose of the same blended matrix
            // (when the mesh has them), in one pass.
            let with_normals = sk.base_normals.len() == sk.base.len() && !sk.base_normals.is_empty();
            let mut p = Vec::with_capacity(sk.base.len());
            let mut n = Vec::with_capacity(if with_normals { sk.base.len() } else { 0 });
            for (i, (v, (js, ws))) in sk.base.iter().zip(sk.vertex_joints.iter().zip(&sk.vertex_weights)).enumerate() {
                let m = blend(js, ws);
                let unskinned = m == Mat4::ZERO;
                p.push(if unskinned { *v } else { m.transform_point3(*v) });
                if let Some(bn) = sk.base_normals.get(i).filter(|_| with_normals) {
                    let v = if unskinned { *bn } else { (glam::Mat3::from_mat4(m).inverse().transpose() * *bn).normalize_or_zero() };
                    n.push(if v.is_finite() { v } else { Vec3::ZERO });
                }
            }
            meshes.push((sk.mesh, p));
            if with_normals {
                normals.push((sk.mesh, n));
            }
            if let Some(slot) = instances.get_mut(sk.instance as usize) {
                *slot = Affine3A::IDENTITY;
            }
        }
        Pose { instances, camera, lights: self.light_nodes.iter().map(|&(l, n)| (l, at(n))).collect(), meshes, normals }
    }
}

/// A channel's value at time `t` (clamped to its first and last keys), or `None` when the
/// channel has no keys.
#[must_use]
pub fn sample(c: &Channel, t: f32) -> Option<Vec<f32>> {
    let n = c.times.len();
    let w = c.width;
    let cubic = c.interp == Interp::CubicSpline;
    let stride = if cubic { 3 * w } else { w };
    if n == 0 || c.values.len() < n * stride || w == 0 {
        return None;
    }
    // The value (not tangent) of key k.
    let value = |k: usize| -> &[f32] {
        let o = k * stride + if cubic { w } else { 0 };
        &c.values[o..o + w]
    };
    if t.is_nan() || t <= c.times[0] || n == 1 {
        return Some(value(0).to_vec());
    }
    if t >= c.times[n - 1] {
        return Some(value(n - 1).to_vec());
    }
    // Last key with time <= t.
    let k = c.times.partition_point(|&x| x <= t) - 1;
    let (t0, t1) = (c.times[k], c.times[k + 1]);
    let dt = t1 - t0;
    let s = if dt > 0.0 { (t - t0) / dt } else { 0.0 };
    let (a, b) = (value(k), value(k + 1));
    let out = match c.interp {
        Interp::Step => a.to_vec(),
        Interp::Linear if c.target == Target::Rotation && w == 4 => {
            let qa = Quat::from_xyzw(a[0], a[1], a[2], a[3]);
            let qb = Quat::from_xyzw(b[0], b[1], b[2], b[3]);
            // Shortest path.
            let qb = if qa.dot(qb) < 0.0 { -qb } else { qb };
            let q = qa.slerp(qb, s);
            vec![q.x, q.y, q.z, q.w]
        }
        Interp::Linear => a.iter().zip(b).map(|(x, y)| x + (y - x) * s).collect(),
        Interp::CubicSpline => {
            let out_tangent = &c.values[k * stride + 2 * w..k * stride + 3 * w];
            let in_tangent = &c.values[(k + 1) * stride..(k + 1) * stride + w];
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let h11 = s3 - s2;
            let mut v: Vec<f32> = (0..w).map(|i| h00 * a[i] + h10 * dt * out_tangent[i] + h01 * b[i] + h11 * dt * in_tangent[i]).collect();
            if c.target == Target::Rotation && w == 4 {
                let q = Quat::from_xyzw(v[0], v[1], v[2], v[3]).normalize();
                v = vec![q.x, q.y, q.z, q.w];
            }
            v
        }
    };
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ch(target: Target, interp: Interp, times: Vec<f32>, values: Vec<f32>, width: usize) -> Channel {
        Channel { node: 0, target, interp, times, values, width }
    }

    #[test]
    fn keys_are_hit_exactly_and_clamped_outside() {
        let c = ch(Target::Translation, Interp::Linear, vec![1.0, 2.0, 4.0], vec![0., 0., 0., 2., 4., 6., 4., 0., 0.], 3);
        assert_eq!(sample(&c, 1.0), Some(vec![0., 0., 0.]));
        assert_eq!(sample(&c, 2.0), Some(vec![2., 4., 6.]));
        assert_eq!(sample(&c, 4.0), Some(vec![4., 0., 0.]));
        assert_eq!(sample(&c, 1.5), Some(vec![1., 2., 3.]));
        assert_eq!(sample(&c, 3.0), Some(vec![3., 2., 3.]));
        assert_eq!(sample(&c, -5.0), Some(vec![0., 0., 0.]));
        assert_eq!(sample(&c, 9.0), Some(vec![4., 0., 0.]));
        let s = Channel { interp: Interp::Step, ..c };
        assert_eq!(sample(&s, 3.9), Some(vec![2., 4., 6.]));
    }

    #[test]
    fn rotations_slerp_the_short_way_and_cubic_splines_hit_keys() {
        let q1 = Quat::from_rotation_y(0.0);
        let q2 = -Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let c = ch(Target::Rotation, Interp::Linear, vec![0.0, 1.0], vec![q1.x, q1.y, q1.z, q1.w, q2.x, q2.y, q2.z, q2.w], 4);
        let v = sample(&c, 0.5).unwrap_or_default();
        let q = Quat::from_xyzw(v[0], v[1], v[2], v[3]);
        assert!(q.angle_between(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4)) < 1e-5, "{q}");
        // Cubic: [in, value, out] per key; zero tangents give smoothstep between keys.
        let c = ch(
            Target::Translation,
            Interp::CubicSpline,
            vec![0.0, 2.0],
            vec![0., 0., 0., 1., 1., 1., 0., 0., 0., 0., 0., 0., 3., 3., 3., 0., 0., 0.],
            3,
        );
        assert_eq!(sample(&c, 0.0), Some(vec![1., 1., 1.]));
        assert_eq!(sample(&c, 2.0), Some(vec![3., 3., 3.]));
        assert_eq!(sample(&c, 1.0), Some(vec![2., 2., 2.]));
        let v = sample(&c, 0.5).unwrap_or_default();
        assert!((v[0] - (1.0 + 2.0 * 0.15625)).abs() < 1e-6, "{v:?}");
    }

    #[test]
    fn hierarchy_composes_parent_times_child() {
        let a = SceneAnimation {
            nodes: vec![
                Node { parent: None, t: Vec3::new(1.0, 0.0, 0.0), r: Quat::IDENTITY, s: Vec3::splat(2.0) },
                Node { parent: Some(0), t: Vec3::new(0.0, 1.0, 0.0), r: Quat::IDENTITY, s: Vec3::ONE },
            ],
            channels: vec![Channel { node: 0, ..ch(Target::Translation, Interp::Linear, vec![0.0, 1.0], vec![1., 0., 0., 3., 0., 0.], 3) }],
            instance_nodes: vec![1],
            ..SceneAnimation::default()
        };
        let p = a.pose(0.5);
        // Child origin: parent translation (2,0,0) + parent scale 2 × (0,1,0).
        assert!((p.instances[0].transform_point3(Vec3::ZERO) - Vec3::new(2.0, 2.0, 0.0)).length() < 1e-6);
        assert_eq!(a.time_range(), (0.0, 1.0));
    }
}

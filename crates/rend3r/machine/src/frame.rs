//! Frames from the device state: the ray-tracing mode (what REND3R's paper intends,
//! rendered by lucent's engine) and the rasterization mode.
//!
//! lucent's decisions where the paper is silent (SPEC.md §10 lists the board's gaps):
//! - "A register still zero from reset means default": lucent tracks which properties a
//!   program wrote. A camera quaternion never written (or all zero) is the identity; fov
//!   properties never written leave the default 10 × 7.5 viewport at distance 1 (written,
//!   `hfov`/`vfov` *scale* its width/height); near/far clip never written do not clip.
//! - Lights: `src` written 0 = off, 1 directional (along `forward`), 2 point (at `loc`).
//!   A light whose `src` was never written but whose forward (or position) was is taken as
//!   directional (or point): that is how the board lights `raytrace.rdr`. Colour never
//!   written = white, intensity never written = 1. No distance falloff. A program that
//!   writes no light record at all gets a white headlight along the view direction.
//! - Shapes: type 0 off, 1 sphere, 2 cylinder, 3 cone (REND3R's infinite normal forms,
//!   SPEC §6.3) under translate · rotate(q) · scale, the stored scale being the inverse
//!   factor. A quaternion never written (or zero) is the identity, a scale never written
//!   (or written 0) is 1. Types 4–15 are skipped with one warning. Colour never written is
//!   white. Material 0 matte, 1 mirror, 2 glass, 3 glossy.
//! - Colours are RGB565, read as sRGB.
//! - Image y is up (the paper's intent; the board's ray tracer has +y down, SPEC §5).

use crate::processor::{DeviceState, Record};
use glam::{Affine3A, Quat, Vec3};
use lucent_render::Camera;
use lucent_scene::{Attr, Geom, Instance, Light, LightKind, Material, Mesh, Scene, ShapeKind};
use rend3r_isa::CameraTable;

/// How SE/SD records are read (`sp` and `tr` encode identically).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetKind {
    /// Shapes (ray-tracing table).
    Shapes,
    /// Triangles (rasterization table).
    Triangles,
}

/// How a program's assembly source reads its SE/SD records: `tr` lines mean triangles,
/// `sp` lines shapes; `None` when it uses neither or both.
#[must_use]
pub fn set_kind_of_source(src: &str) -> Option<SetKind> {
    let uses = |m: &str| src.lines().any(|l| l.trim().to_lowercase().split(' ').next() == Some(m));
    match (uses("sp"), uses("tr")) {
        (false, true) => Some(SetKind::Triangles),
        (true, false) => Some(SetKind::Shapes),
        _ => None,
    }
}

/// Which renderer draws a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// lucent's Whitted ray tracer over analytic shapes (and triangles).
    Raytrace,
    /// Edge-function rasterizer over triangles.
    Raster,
}

impl SetKind {
    /// How words with no source to tell read their records: shapes when ray tracing,
    /// triangles when rasterizing.
    #[must_use]
    pub fn for_mode(mode: Mode) -> Self {
        if mode == Mode::Raster {
            Self::Triangles
        } else {
            Self::Shapes
        }
    }
}

/// Frame settings.
#[derive(Clone, Copy, Debug)]
pub struct FrameSettings {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Renderer.
    pub mode: Mode,
    /// How to read SE/SD records.
    pub sets: SetKind,
    /// Rasterizer: painter's order (farthest centroid first) instead of a z-buffer.
    pub painter: bool,
    /// Samples per pixel (ray tracing).
    pub spp: u32,
}

/// Linear RGB of an RGB565 colour (read as sRGB).
#[must_use]
pub fn rgb565(c: u16) -> Vec3 {
    // PERF: the 32 + 64 channel values decoded once (three `powf` per shape were most of
    // turning a 256-sphere state into a scene); the same values as decoding each time.
    static LINEAR: std::sync::OnceLock<([f32; 32], [f32; 64])> = std::sync::OnceLock::new();
    let (five, six) = LINEAR.get_or_init(|| {
        (
            std::array::from_fn(|i| lucent_scene::srgb_to_linear(i as f32 / 31.0)),
            std::array::from_fn(|i| lucent_scene::srgb_to_linear(i as f32 / 63.0)),
        )
    });
    Vec3::new(five[usize::from((c >> 11) & 31)], six[usize::from((c >> 5) & 63)], five[usize::from(c & 31)])
}

fn v3(r: &Record, a: u8) -> Vec3 {
    Vec3::new(r.f(a), r.f(a + 1), r.f(a + 2))
}

fn quat(r: &Record, a: u8) -> Quat {
    // Stored as (w, x, y, z).
    let (w, x, y, z) = (r.f(a), r.f(a + 1), r.f(a + 2), r.f(a + 3));
    let q = Quat::from_xyzw(x, y, z, w);
    let len = q.length();
    if !(a..a + 4).any(|p| r.has(p)) || len.is_nan() || len <= 0.0 || !len.is_finite() {
        Quat::IDENTITY
    } else {
        q / len
    }
}

/// REND3R's camera for a frame.
#[must_use]
pub fn camera(state: &DeviceState, width: u32, height: u32) -> Camera {
    let c = &state.camera;
    let eye = v3(c, 1);
    let finite = |v: Vec3| if v.is_finite() { v } else { Vec3::ZERO };
    let eye = finite(eye);
    let (right, up, forward, (near, far, hfov, vfov)) = match state.camera_table {
        CameraTable::Final => {
            let q = quat(c, 4);
            (q * Vec3::X, q * Vec3::Y, q * -Vec3::Z, (8, 9, 10, 11))
        }
        CameraTable::Old => {
            let f = v3(c, 4);
            let u = v3(c, 7);
            let f = if (4..7).any(|p| c.has(p)) { f.normalize_or(-Vec3::Z) } else { -Vec3::Z };
            let u = if (7..10).any(|p| c.has(p)) { u.normalize_or(Vec3::Y) } else { Vec3::Y };
            let r = f.cross(u).normalize_or(Vec3::X);
            (r, r.cross(f), f, (10, 11, 12, 13))
        }
    };
    let scale = |p: u8| {
        let v = c.f(p);
        if c.has(p) && v > 0.0 && v.is_finite() {
            v
        } else {
            1.0
        }
    };
    let tmin = if c.has(near) && c.f(near) > 0.0 { c.f(near) } else { 0.0 };
    let tmax = if c.has(far) && c.f(far) > tmin { c.f(far) } else { f32::INFINITY };
    Camera::viewport(eye, right, up, forward, 5.0 * scale(hfov), 3.75 * scale(vfov), tmin, tmax, width, height)
}

/// The lights of the state (see the module notes for defaults). A program that writes
/// no light record at all gets a white headlight along the view direction, so it is not
/// black (`lt 0, src, 0` is an explicit "no light").
#[must_use]
pub fn lights(state: &DeviceState) -> Vec<Light> {
    if state.used_lights() > 0 {
        return program_lights(state);
    }
    let cam = camera(state, 2, 2);
    let d = cam.ray(1.0, 1.0).dir.normalize_or(-Vec3::Z);
    vec![Light { kind: LightKind::Directional { direction: d }, color: Vec3::ONE, inverse_square: false }]
}

fn program_lights(state: &DeviceState) -> Vec<Light> {
    let mut out = Vec::new();
    for l in &state.lights {
        if !l.used() {
            continue;
        }
        let fwd_set = (4..7).any(|p| l.has(p));
        let loc_set = (1..4).any(|p| l.has(p));
        let kind = if l.has(0) {
            match l.u(0) & 3 {
                1 => 1,
                2 => 2,
                _ => 0,
            }
        } else if fwd_set {
            1
        } else if loc_set {
            2
        } else {
            0
        };
        let color = if l.has(7) { rgb565(l.u(7)) } else { Vec3::ONE };
        let intensity = if l.has(8) && l.f(8).is_finite() { l.f(8).max(0.0) } else { 1.0 };
        let k = match kind {
            1 => {
                let d = v3(l, 4);
                if !d.is_finite() || d.length_squared() <= 0.0 {
                    continue;
                }
                LightKind::Directional { direction: d.normalize() }
            }
            2 => {
                let p = v3(l, 1);
                if !p.is_finite() {
                    continue;
                }
                LightKind::Point { position: p }
            }
            _ => continue,
        };
        out.push(Light { kind: k, color: color * intensity, inverse_square: false });
    }
    out
}

fn material(kind: u16, color: Vec3) -> Material {
    match kind & 3 {
        1 => Material {
            name: "mirror".into(),
            diffuse: color * 0.1,
            specular: Vec3::splat(0.6),
            shininess: 200.0,
            reflect: Vec3::splat(0.85),
            ..Material::default()
        },
        2 => Material {
            name: "glass".into(),
            diffuse: Vec3::ZERO,
            specular: Vec3::splat(0.6),
            shininess: 300.0,
            transmit: color.max(Vec3::splat(0.05)),
            ior: 1.5,
            fresnel: true,
            ..Material::default()
        },
        3 => Material {
            name: "glossy".into(),
            diffuse: color * 0.8,
            specular: Vec3::splat(0.5),
            shininess: 80.0,
            reflect: color * 0.25,
            ..Material::default()
        },
        _ => Material { name: "matte".into(), diffuse: color, specular: Vec3::splat(0.05), shininess: 10.0, ..Material::default() },
    }
}

/// Builds a lucent scene from the state. Returns the scene and how many records were
/// skipped (shape types 4–15).
#[must_use]
pub fn scene(state: &DeviceState, sets: SetKind) -> (Scene, usize) {
    let mut s = Scene { ambient: Vec3::splat(0.05), background: Vec3::ZERO, lights: lights(state), ..Scene::default() };
    let mut skipped = 0;
    let mut mats: std::collections::HashMap<(u16, u16), u32> = Default::default();
    let mut mat_id = |s: &mut Scene, col: u16, m: u16| {
        *mats.entry((col, m & 3)).or_insert_with(|| {
            s.materials.push(material(m, rgb565(col)));
            (s.materials.len() - 1) as u32
        })
    };
    match sets {
        SetKind::Shapes => {
            for r in state.sets.iter() {
                let kind = match r.u(13) & 15 {
                    0 => continue,
                    1 => ShapeKind::Sphere,
                    2 => ShapeKind::Cylinder,
                    3 => ShapeKind::Cone,
                    _ => {
                        skipped += 1;
                        continue;
                    }
                };
                let t = v3(r, 1);
                let q = quat(r, 4);
                let inv = |p: u8| {
                    let v = r.f(p);
                    if r.has(p) && v != 0.0 && v.is_finite() {
                        1.0 / v
                    } else {
                        1.0
                    }
                };
                let sc = Vec3::new(inv(8), inv(9), inv(10));
                if !t.is_finite() || !sc.is_finite() {
                    skipped += 1;
                    continue;
                }
                let col = if r.has(11) { r.u(11) } else { 0xFFFF };
                let material = mat_id(&mut s, col, r.u(12));
                s.instances.push(Instance {
                    geom: Geom::Shape { kind, material },
                    world_from_object: Affine3A::from_scale_rotation_translation(sc, q, t),
                });
            }
        }
        SetKind::Triangles => {
            let mut mesh = Mesh { name: "triangles".into(), ..Mesh::default() };
            for r in state.sets.iter().filter(|r| r.used()) {
                let base = mesh.positions.len() as u32;
                let vs = [v3(r, 1), v3(r, 4), v3(r, 7)];
                mesh.positions.extend(vs);
                mesh.indices.push([base, base + 1, base + 2]);
                let col = if r.has(11) { r.u(11) } else { 0xFFFF };
                let m = mat_id(&mut s, col, r.u(12));
                mesh.material.push(m);
            }
            mesh.normals = Attr::default();
            if !mesh.indices.is_empty() {
                s.add_mesh(mesh);
            }
        }
    }
    (s, skipped)
}

/// What a frame contained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameInfo {
    /// Shapes or triangles drawn.
    pub shapes: usize,
    /// Lights used.
    pub lights: usize,
    /// Records skipped (undefined shape types, non-finite data).
    pub skipped: usize,
    /// Rays traced (ray-tracing mode).
    pub rays: u64,
}

//! NaN, infinite and degenerate geometry in every loader never breaks a build or a frame:
//! each file loads (or is refused with an error), builds its world, and renders a frame
//! whose every pixel is finite.

use lucent_accel::MeshOptions;
use lucent_render::{framing_camera, render, Camera, RenderSettings, World};
use std::path::Path;

/// Loads `name` from `dir`, builds its world and renders it small; the frame must be finite.
fn survive(dir: &Path, name: &str, data: &[u8]) {
    let path = dir.join(name);
    std::fs::write(&path, data).expect("write");
    let scene = match lucent_scene::load(&path) {
        Ok(s) => s,
        Err(e) => {
            assert!(e.to_string().contains(name), "{name}: error does not name the file: {e}");
            return;
        }
    };
    let desc = scene.camera.unwrap_or_else(|| match scene.bounds() {
        Some((lo, hi)) => framing_camera(lo, hi),
        None => framing_camera(glam::Vec3::splat(-1.0), glam::Vec3::ONE),
    });
    let world = World::new(scene, MeshOptions::default()).unwrap_or_else(|e| panic!("{name}: world: {e}"));
    let (w, h) = (32, 24);
    let film = render(&world, &Camera::new(&desc, w, h), &RenderSettings { spp: 2, ..RenderSettings::new(w, h) }, &|_| {}).0;
    for y in 0..h {
        for x in 0..w {
            assert!(film.get(x, y).is_finite(), "{name}: pixel {x},{y} is {:?}", film.get(x, y));
        }
    }
}

const OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nv inf 1 -inf\nv 1e38 1e38 0\nv 0 0 0\nv 2 2 2\n\
vn nan nan nan\nvn 0 0 0\nvt nan inf\n\
f 1 2 3\nf 1 2 4\nf 5 6 7\nf 1 7 8\nf 1 1 1\nf 1//1 2//2 3//2\nf 1/1 2/1 3/1\n";

#[test]
fn obj_with_nan_infinite_and_degenerate_geometry() {
    let d = tempfile::tempdir().expect("tmp");
    survive(d.path(), "hostile.obj", OBJ.as_bytes());
    // Only bad geometry: nothing can be hit.
    survive(d.path(), "nothing.obj", b"v nan nan nan\nv inf inf inf\nv 0 0 0\nf 1 2 3\nf 3 3 3\n");
}

#[test]
fn ply_with_nan_infinite_and_degenerate_geometry() {
    let d = tempfile::tempdir().expect("tmp");
    let head = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n";
    let body = "0 0 0 nan nan nan\n1 0 0 0 0 0\n0 1 0 0 0 1\nnan inf -inf 0 0 1\n1 0 0 0 0 1\n3 0 1 2\n3 0 1 3\n3 1 4 1\n";
    survive(d.path(), "hostile.ply", format!("{head}{body}").as_bytes());
    // Binary: the same with NaN bits in the middle.
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [0.0f32, 0.0, 0.0, f32::NAN, 1.0, f32::INFINITY, 0.0, 1.0, 0.0] {
        b.extend(v.to_le_bytes());
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend(i.to_le_bytes());
    }
    survive(d.path(), "hostile_binary.ply", &b);
}

/// A glTF file with its buffer as a data URI: a triangle with a NaN corner and a good one,
/// placed by nodes with a zero scale, a zero quaternion, a NaN matrix, an infinite
/// translation and a camera of zero field of view.
#[test]
fn gltf_with_nan_zero_scales_and_zero_quaternions() {
    use base64::Engine as _;
    let mut bytes = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, f32::NAN, 0.0, 0.0, 0.0, f32::INFINITY, 0.0, 0.0, 0.0, 0.0] {
        bytes.extend(v.to_le_bytes());
    }
    let uri = format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bytes));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1,2,3,4,5]}}],
        "nodes":[{{"mesh":0}},{{"mesh":0,"scale":[0,0,0]}},{{"mesh":0,"rotation":[0,0,0,0]}},
                 {{"mesh":0,"matrix":[NaN]}},{{"mesh":0,"translation":[1e39,0,0]}},{{"camera":0,"translation":[0,0,3]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.0,"znear":0.1}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}},{{"attributes":{{"POSITION":1}}}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}},
                     {{"bufferView":0,"byteOffset":36,"componentType":5126,"count":3,"type":"VEC3"}}],
        "bufferViews":[{{"buffer":0,"byteLength":72}}],
        "buffers":[{{"byteLength":72,"uri":"{uri}"}}]}}"#
    );
    let d = tempfile::tempdir().expect("tmp");
    // `NaN` is not JSON: that file is refused with a clear error; the same without it loads.
    survive(d.path(), "hostile_nan_literal.gltf", json.as_bytes());
    survive(d.path(), "hostile.gltf", json.replace("[NaN]", "[0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0]").as_bytes());
}

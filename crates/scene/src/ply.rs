//! Stanford PLY (ASCII and binary), through the `ply-rs-bw` crate.

use crate::error::ImportError;
use crate::model::{Attr, Material, Mesh, Scene};
use glam::{Vec2, Vec3};
use ply_rs_bw::ply::{DefaultElement, Property};
use std::path::Path;

fn scalar(p: &Property) -> Option<f32> {
    p.to_f32_lossy()
}

fn list(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUChar(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListShort(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUShort(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListInt(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUInt(v) => v.iter().map(|&x| x as i64).collect(),
        _ => return None,
    })
}

/// Loads a PLY file into a scene with one mesh.
pub fn load_ply(path: &Path) -> Result<Scene, ImportError> {
    let bytes = crate::obj::read_maybe_gz(path)?;
    parse_ply(path, &bytes)
}

/// Reads PLY `bytes` (ASCII or binary) into a scene with one mesh; `path` names the file
/// in errors and the mesh.
pub fn parse_ply(path: &Path, bytes: &[u8]) -> Result<Scene, ImportError> {
    let invalid = |at: String, msg: String| ImportError::Invalid { path: path.to_path_buf(), at, msg };
    let parser = ply_rs_bw::parser::Parser::<DefaultElement>::new();
    let ply = parser.read_ply(&mut &bytes[..]).map_err(|e| invalid("file".into(), e.to_string()))?;
    let verts = ply.payload.get("vertex").ok_or_else(|| invalid("header".into(), "no 'vertex' element".into()))?;
    let mut mesh = Mesh { name: path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(), ..Mesh::default() };
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    for (i, v) in verts.iter().enumerate() {
        let get = |k: &str| v.get(k).and_then(scalar);
        let (Some(x), Some(y), Some(z)) = (get("x"), get("y"), get("z")) else {
            return Err(invalid(format!("vertex {i}"), "needs scalar x, y and z".into()));
        };
        mesh.positions.push(Vec3::new(x, y, z));
        if let (Some(nx), Some(ny), Some(nz)) = (get("nx"), get("ny"), get("nz")) {
            normals.push(Vec3::new(nx, ny, nz));
        }
        if let (Some(u), Some(t)) =
            (get("u").or_else(|| get("s")).or_else(|| get("texture_u")), get("v").or_else(|| get("t")).or_else(|| get("texture_v")))
        {
            uvs.push(Vec2::new(u, t));
        }
    }
    let nv = mesh.positions.len();
    if let Some(faces) = ply.payload.get("face") {
        for (i, f) in faces.iter().enumerate() {
            let idx = f
                .get("vertex_indices")
                .or_else(|| f.get("vertex_index"))
                .and_then(list)
                .ok_or_else(|| invalid(format!("face {i}"), "needs a 'vertex_indices' list".into()))?;
            if idx.len() < 3 {
                return Err(invalid(format!("face {i}"), format!("a face needs at least 3 vertices, found {}", idx.len())));
            }
            if let Some(bad) = idx.iter().find(|&&x| x < 0 || x as usize >= nv) {
                return Err(invalid(format!("face {i}"), format!("vertex index {bad} out of range (there are {nv} vertices)")));
            }
            for k in 2..idx.len() {
                mesh.indices.push([idx[0] as u32, idx[k - 1] as u32, idx[k] as u32]);
                mesh.material.push(0);
            }
        }
    }
    if normals.len() == nv {
        mesh.normals = Attr { values: normals, indices: None };
    }
    if uvs.len() == nv {
        mesh.uvs = Attr { values: uvs, indices: None };
    }
    let mut scene = Scene { materials: vec![Material::default()], ambient: crate::model::DEFAULT_AMBIENT, ..Scene::default() };
    scene.add_mesh(mesh);
    Ok(scene)
}

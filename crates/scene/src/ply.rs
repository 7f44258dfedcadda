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
    check_claims(bytes).map_err(|msg| invalid("header".into(), msg))?;
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

/// Bytes of a PLY scalar type (`None`: not a PLY type).
fn type_size(t: &str) -> Option<u64> {
    Some(match t {
        "char" | "int8" | "uchar" | "uint8" => 1,
        "short" | "int16" | "ushort" | "uint16" => 2,
        "int" | "int32" | "uint" | "uint32" | "float" | "float32" => 4,
        "double" | "float64" => 8,
        _ => return None,
    })
}

/// Checks what the header claims against the bytes after it, before the parser allocates
/// anything for it: every element's items need at least some bytes each (binary: their
/// scalars and list counts; ASCII: a token and a separator per property), and all of them
/// must fit in what follows the header. An element with items but no properties is refused
/// (its items would take no bytes: a parser would make them forever). A fuzzed header of
/// 6.7e18 such vertices made the parser allocate until memory ran out.
fn check_claims(bytes: &[u8]) -> Result<(), String> {
    let Some(end) = bytes.windows(10).position(|w| w == b"end_header") else {
        return Ok(()); // The parser reports a missing end_header itself.
    };
    let rest = bytes.len().saturating_sub(end + 10) as u64;
    let head = String::from_utf8_lossy(&bytes[..end]);
    let binary = head.lines().any(|l| l.trim_start().starts_with("format binary"));
    // (name, count, minimum bytes per item, properties)
    let mut elements: Vec<(String, u64, u64, u32)> = Vec::new();
    for line in head.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["element", name, count, ..] => {
                let n = count.parse::<u64>().map_err(|_| format!("element '{name}': count '{count}' is not a number"))?;
                elements.push(((*name).to_string(), n, 0, 0));
            }
            ["property", "list", count_type, ..] => {
                if let Some(e) = elements.last_mut() {
                    e.2 += if binary { type_size(count_type).unwrap_or(1) } else { 2 };
                    e.3 += 1;
                }
            }
            ["property", ty, ..] => {
                if let Some(e) = elements.last_mut() {
                    e.2 += if binary { type_size(ty).unwrap_or(1) } else { 2 };
                    e.3 += 1;
                }
            }
            _ => {}
        }
    }
    let mut need: u64 = 0;
    for (name, n, min, props) in &elements {
        if *n > 0 && *props == 0 {
            return Err(format!("element '{name}' claims {n} items but has no properties"));
        }
        need = need.saturating_add(n.saturating_mul(*min));
        if need > rest {
            return Err(format!(
                "element '{name}' claims {n} items of at least {min} bytes each; the file has {rest} bytes after the header"
            ));
        }
    }
    Ok(())
}

//! glTF 2.0 (`.gltf` + `.bin`, `.glb`): node hierarchy to instances (a mesh used by several
//! nodes becomes one mesh, instanced), PBR materials mapped to Phong/Whitted terms,
//! textures, cameras, `KHR_lights_punctual`, animation, skins and morph targets.
//!
//! The reader is lucent's own (`json.rs`), over the JSON as the specification defines it:
//! the `gltf` crate's validation refused valid files (accessors without buffer views,
//! integers written as `1.0`, scenes without nodes, `KHR_animation_pointer` channels) and
//! panicked on some invalid ones. What lucent cannot use (points and lines, images in
//! formats it does not decode, unknown channel targets) is skipped with a warning; what is
//! malformed is an error naming the JSON pointer.

mod json;
mod pointer;
mod rules;
mod schema;

use crate::anim::{Channel, Interp, Morph, Node, SceneAnimation, Skin, Target};
use crate::bsdf::{Bsdf, ColorTex, FloatTex};
use crate::camera::CameraDesc;
use crate::error::ImportError;
use crate::model::{Attr, Geom, Instance, Light, LightKind, Material, Mesh, Scene};
use crate::texture::texture_from_image;
use crate::texture::Wrap;
use glam::{Affine2, Affine3A, Mat4, Quat, Vec2, Vec3};
use json::{Doc, R};
use pointer::ptr;
use serde_json::Value;
use std::path::Path;

/// Extensions lucent reads; a file that requires another still loads (with a warning),
/// without what the extension adds.
const SUPPORTED: &[&str] =
    &["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior", "KHR_mesh_quantization", "KHR_materials_emissive_strength"];

fn f32_at(v: &Value, key: &str) -> Option<f32> {
    v.get(key).and_then(Value::as_f64).map(|x| x as f32)
}

fn floats<const N: usize>(v: &Value, key: &str) -> Option<[f32; N]> {
    let a = v.get(key)?.as_array()?;
    (a.len() == N).then(|| std::array::from_fn(|i| a[i].as_f64().unwrap_or(0.0) as f32))
}

/// Loads a glTF or GLB file, reading what it can of a file that breaks a rule of the
/// specification (with a warning); see [`load_gltf_with`].
pub fn load_gltf(path: &Path) -> Result<Scene, ImportError> {
    load_gltf_with(path, &crate::LoadOptions::default())
}

/// Loads a glTF or GLB file; with `options.strict` a file that breaks any rule of the
/// specification is refused, with the JSON pointer of what is wrong.
pub fn load_gltf_with(path: &Path, options: &crate::LoadOptions) -> Result<Scene, ImportError> {
    let bytes = std::fs::read(path).map_err(|cause| ImportError::Io { path: path.to_path_buf(), cause })?;
    parse_gltf_with(path, path.parent().unwrap_or(Path::new(".")), &bytes, options)
}

/// Reads glTF JSON or GLB `bytes`; `path` names the file in errors, and relative URIs are
/// read from `base`.
pub fn parse_gltf(path: &Path, base: &Path, bytes: &[u8]) -> Result<Scene, ImportError> {
    parse_gltf_with(path, base, bytes, &crate::LoadOptions::default())
}

/// [`parse_gltf`] with options (`strict`: refuse any file that breaks a rule).
pub fn parse_gltf_with(path: &Path, base: &Path, bytes: &[u8], options: &crate::LoadOptions) -> Result<Scene, ImportError> {
    let doc = Doc::parse(bytes, path, base, options.strict)?;
    let scene = build(&doc)?;
    if scene.instances.is_empty() {
        tracing::warn!("{}: nothing to draw (no node places a mesh with triangles)", path.display());
    }
    Ok(scene)
}

fn build(doc: &Doc<'_>) -> R<Scene> {
    let warn = |at: &str, msg: &str| tracing::warn!("{}: {at}: {msg}", doc.file.display());
    for (i, e) in doc.items("extensionsRequired")?.iter().enumerate() {
        let name = e.as_str().unwrap_or("");
        if !SUPPORTED.contains(&name) {
            warn(&ptr(&[&"extensionsRequired", &i]), &format!("extension {name:?} is not supported; loading without it"));
        }
    }
    let asset_extras = doc.root.pointer("/asset/extras").cloned();
    let bart = asset_extras.as_ref().is_some_and(|e| e.get("aff_time_offset").is_some());
    let mut scene = Scene { ambient: crate::model::DEFAULT_AMBIENT, ..Scene::default() };

    // Images: decoded once each (a texture may share one); failures warn.
    let images = doc.items("images")?;
    let mut decoded: Vec<Option<image::DynamicImage>> = Vec::with_capacity(images.len());
    for (i, img) in images.iter().enumerate() {
        let at = ptr(&[&"images", &i]);
        let bytes = match (img.get("uri").and_then(Value::as_str), doc.index(img, "bufferView", &at, doc.view_count(), "buffer view")?) {
            (Some(uri), _) => doc.read_uri(uri, &format!("{at}/uri")).map_err(|e| e.to_string()),
            (None, Some(v)) => doc.view_bytes(v).map(<[u8]>::to_vec),
            (None, None) => Err("no uri and no buffer view".to_string()),
        };
        match bytes.and_then(|b| crate::texture::decode_image(&b).map_err(|e| e.to_string())) {
            Ok(im) => decoded.push(Some(im)),
            Err(e) => {
                warn(&at, &format!("not loaded ({e}); textures using it show the plain colour"));
                decoded.push(None);
            }
        }
    }
    // Textures: one per glTF texture (None where its image is missing or in a format an
    // extension provides).
    let samplers = doc.items("samplers")?;
    // Per glTF texture: its image and wrap modes; lucent textures are made on first use,
    // one per (texture, colour space): base colour and emission are sRGB, the rest data.
    let mut sources: Vec<Option<(usize, Wrap, Wrap)>> = Vec::new();
    for (i, t) in doc.items("textures")?.iter().enumerate() {
        let at = ptr(&[&"textures", &i]);
        let src = doc.index(t, "source", &at, images.len(), "image")?;
        let wrap = |key: &str| -> R<Wrap> {
            let Some(s) = doc.index(t, "sampler", &at, samplers.len(), "sampler")? else { return Ok(Wrap::Repeat) };
            Ok(match doc.uint(&samplers[s], key, &ptr(&[&"samplers", &s]))? {
                Some(33071) => Wrap::Clamp,
                Some(33648) => Wrap::Mirror,
                _ => Wrap::Repeat,
            })
        };
        let (wu, wv) = (wrap("wrapS")?, wrap("wrapT")?);
        match src.filter(|&s| decoded[s].is_some()) {
            Some(s) => sources.push(Some((s, wu, wv))),
            None => {
                if src.is_none() {
                    warn(&at, "no image lucent can decode (an extension's image?); using the plain colour");
                }
                sources.push(None);
            }
        }
    }
    let mut made: std::collections::HashMap<(usize, bool), u32> = std::collections::HashMap::new();
    let mut texture = |scene: &mut Scene, t: usize, srgb: bool| -> Option<u32> {
        let (s, wu, wv) = sources.get(t).copied().flatten()?;
        if let Some(&id) = made.get(&(t, srgb)) {
            return Some(id);
        }
        let im = decoded[s].clone()?;
        let name = images[s].get("name").and_then(Value::as_str).unwrap_or("texture").to_string();
        scene.textures.push(texture_from_image(name, im, wu, wv, srgb));
        let id = (scene.textures.len() - 1) as u32;
        made.insert((t, srgb), id);
        Some(id)
    };
    // Materials (index 0 = default for primitives without one).
    scene.materials.push(Material::default());
    let materials = doc.items("materials")?;
    for (i, m) in materials.iter().enumerate() {
        let at = ptr(&[&"materials", &i]);
        let pbr = m.get("pbrMetallicRoughness").cloned().unwrap_or(Value::Null);
        // A texture reference's index (checked), at `parent`/`key`.
        let tex_ref = |parent: &Value, key: &str, at: &str| -> R<Option<usize>> {
            match parent.get(key) {
                Some(t) => doc.index(t, "index", &format!("{at}/{key}"), sources.len(), "texture"),
                None => Ok(None),
            }
        };
        let pat = format!("{at}/pbrMetallicRoughness");
        let bc = floats::<4>(&pbr, "baseColorFactor").unwrap_or([1.0; 4]);
        let base = Vec3::new(bc[0], bc[1], bc[2]);
        let metallic_f = f32_at(&pbr, "metallicFactor").unwrap_or(1.0).clamp(0.0, 1.0);
        let rough_f = f32_at(&pbr, "roughnessFactor").unwrap_or(1.0).clamp(0.0, 1.0);
        let rough = rough_f.max(0.02);
        let base_tex = tex_ref(&pbr, "baseColorTexture", &pat)?.and_then(|t| texture(&mut scene, t, true));
        let mr_tex = tex_ref(&pbr, "metallicRoughnessTexture", &pat)?.and_then(|t| texture(&mut scene, t, false));
        let normal = tex_ref(m, "normalTexture", &at)?.and_then(|t| texture(&mut scene, t, false));
        let emissive_tex = tex_ref(m, "emissiveTexture", &at)?.and_then(|t| texture(&mut scene, t, true));
        let strength =
            m.pointer("/extensions/KHR_materials_emissive_strength/emissiveStrength").and_then(Value::as_f64).unwrap_or(1.0) as f32;
        let mut mat = Material {
            name: m.get("name").and_then(Value::as_str).unwrap_or("material").to_string(),
            diffuse: base * (1.0 - metallic_f),
            diffuse_tex: base_tex,
            specular: Vec3::splat(0.04 * (1.0 - metallic_f)) + base * metallic_f,
            shininess: (2.0 / (rough * rough * rough * rough) - 2.0).clamp(1.0, 4096.0),
            emission: Vec3::from(floats::<3>(m, "emissiveFactor").unwrap_or([0.0; 3])) * strength,
            emission_tex: emissive_tex,
            reflect: base * metallic_f,
            ..Material::default()
        };
        if let Some(n) = normal {
            let scale = m.pointer("/normalTexture/scale").and_then(Value::as_f64).unwrap_or(1.0) as f32;
            mat.normal_map = Some(crate::bsdf::NormalMap::gltf(n, scale));
        }
        if let Some(mode @ ("MASK" | "BLEND")) = m.get("alphaMode").and_then(Value::as_str) {
            let cutoff = if mode == "MASK" { f32_at(m, "alphaCutoff").unwrap_or(0.5) } else { 0.5 };
            mat.alpha = crate::bsdf::Alpha::Mask { cutoff, tex: base_tex, factor: bc[3] };
        }
        let mut transmission = FloatTex::Const(0.0);
        if let Some(t) = m.pointer("/extensions/KHR_materials_transmission") {
            let factor = f32_at(t, "transmissionFactor").unwrap_or(0.0).clamp(0.0, 1.0);
            mat.transmit = Vec3::splat(factor);
            mat.fresnel = true;
            let tat = format!("{at}/extensions/KHR_materials_transmission");
            transmission = match tex_ref(t, "transmissionTexture", &tat)?.and_then(|x| texture(&mut scene, x, false)) {
                Some(tex) => FloatTex::Image { tex, channel: 0, scale: factor, to_uv: Affine2::IDENTITY },
                None => FloatTex::Const(factor),
            };
        }
        if let Some(ior) = m.pointer("/extensions/KHR_materials_ior").map(|e| f32_at(e, "ior").unwrap_or(1.5)) {
            mat.ior = ior;
        }
        let channel = |channel: u8, scale: f32| match mr_tex {
            Some(tex) => FloatTex::Image { tex, channel, scale, to_uv: Affine2::IDENTITY },
            None => FloatTex::Const(scale),
        };
        mat.bsdf = Some(Bsdf::MetallicRoughness {
            base_color: match base_tex {
                Some(tex) => ColorTex::Image { tex, scale: base, to_uv: Affine2::IDENTITY },
                None => ColorTex::Const(base),
            },
            metallic: channel(2, metallic_f),
            roughness: channel(1, rough_f),
            transmission,
            // glTF's default 1.5; an index of 0 (allowed by the extension) means a
            // perfect reflector, which the BRDF reads as its limit, a very large index.
            ior: if mat.ior == 0.0 { 1e4 } else { mat.ior.max(1.0) },
        });
        if let Some(fm) = m.pointer("/extras/aff_fm") {
            // BART/NFF material: use its Phong terms directly.
            let v3 = |k: &str| floats::<3>(fm, k).map(Vec3::from);
            let f = |k: &str| f32_at(fm, k);
            mat.ambient = v3("ambient").unwrap_or(mat.ambient);
            // A texture modulates the AFF diffuse term (the glTF base colour factor is 1).
            mat.diffuse = v3("diffuse").unwrap_or(mat.diffuse);
            mat.specular = v3("specular").unwrap_or(mat.specular);
            mat.reflect = mat.specular;
            mat.shininess = f("shine").unwrap_or(mat.shininess).max(1.0);
            mat.transmit = Vec3::splat(f("transmittance").unwrap_or(0.0));
            mat.fresnel = false;
            if let Some(ior) = f("ior").filter(|&x| x > 0.0) {
                mat.ior = ior;
            }
            // The path tracer reads the AFF terms as MTL's (crate::bsdf).
            mat.bsdf = Some(crate::obj::phong_bsdf(&mat));
        }
        scene.materials.push(mat);
    }
    let accessors = doc.items("accessors")?.len();
    // Meshes: all primitives of a glTF mesh become one mesh with per-triangle materials.
    let mut mesh_map: Vec<Option<u32>> = Vec::new();
    let mut morph_targets: Vec<Vec<Vec<Vec3>>> = Vec::new();
    type SkinData = Option<(Vec<[u16; 4]>, Vec<[f32; 4]>)>;
    let mut skin_data: Vec<SkinData> = Vec::new();
    let meshes = doc.items("meshes")?;
    for (mi, m) in meshes.iter().enumerate() {
        let mat_ = ptr(&[&"meshes", &mi]);
        let mut mesh = Mesh { name: m.get("name").and_then(Value::as_str).unwrap_or("mesh").to_string(), ..Mesh::default() };
        let prims = doc.list(m, "primitives", &mat_)?;
        let n_targets = prims.iter().map(|p| p.get("targets").and_then(Value::as_array).map_or(0, Vec::len)).max().unwrap_or(0);
        let mut targets: Vec<Vec<Vec3>> = vec![Vec::new(); n_targets];
        let (mut vjoints, mut vweights, mut skinned) = (Vec::new(), Vec::new(), true);
        let (mut normals, mut uvs) = (Vec::new(), Vec::new());
        let (mut all_n, mut all_uv) = (true, true);
        for (pi, p) in prims.iter().enumerate() {
            let at = format!("{mat_}/primitives/{pi}");
            let mode = doc.uint(p, "mode", &at)?.unwrap_or(4);
            if mode > 6 {
                return Err(doc.err(&format!("{at}/mode"), format!("{mode} is not a primitive mode")));
            }
            if mode < 4 {
                warn(&at, &format!("mode {mode} (points or lines) is not drawn; skipped"));
                continue;
            }
            let attrs = p.get("attributes").cloned().unwrap_or(Value::Null);
            let aat = format!("{at}/attributes");
            let attr = |name: &str| doc.index(&attrs, name, &aat, accessors, "accessor");
            let Some(pa) = attr("POSITION")? else {
                warn(&at, "no POSITION attribute; skipped");
                continue;
            };
            let Some(pos) = doc.accessor(pa)? else { continue };
            if pos.ncomp != 3 {
                return Err(doc.err(&format!("{aat}/POSITION"), "must be a VEC3 accessor"));
            }
            let n = pos.count();
            let same = |v: &json::Values, at: &str, ncomp: usize| -> R<()> {
                if v.ncomp != ncomp || v.count() != n {
                    return Err(
                        doc.err(at, format!("{} elements of {} components; POSITION has {n} of 3, expected {ncomp}", v.count(), v.ncomp))
                    );
                }
                Ok(())
            };
            let base = mesh.positions.len() as u32;
            let idx: Vec<u32> = match doc.index(p, "indices", &at, accessors, "accessor")? {
                Some(ia) => {
                    let Some(v) = doc.accessor(ia)? else { continue };
                    if v.ncomp != 1 {
                        return Err(doc.err(&format!("{at}/indices"), "must be a SCALAR accessor"));
                    }
                    v.data.iter().map(|&x| x as u32).collect()
                }
                None => (0..n as u32).collect(),
            };
            if let Some(bad) = idx.iter().find(|&&i| i as usize >= n) {
                return Err(doc.err(&format!("{at}/indices"), format!("index {bad} out of range ({n} vertices)")));
            }
            let tris: Vec<[u32; 3]> = match mode {
                5 => (2..idx.len())
                    .map(|k| if k % 2 == 0 { [idx[k - 2], idx[k - 1], idx[k]] } else { [idx[k - 1], idx[k - 2], idx[k]] })
                    .collect(),
                6 => (2..idx.len()).map(|k| [idx[0], idx[k - 1], idx[k]]).collect(),
                _ => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            };
            let mat = doc.index(p, "material", &at, materials.len(), "material")?.map_or(0, |i| i as u32 + 1);
            match attr("NORMAL")?.map(|a| doc.accessor(a)).transpose()?.flatten() {
                Some(v) => {
                    same(&v, &format!("{aat}/NORMAL"), 3)?;
                    normals.extend(v.elements::<3>().map(Vec3::from));
                }
                None => {
                    all_n = false;
                    normals.extend(std::iter::repeat_n(Vec3::ZERO, n));
                }
            }
            match attr("TEXCOORD_0")?.map(|a| doc.accessor(a)).transpose()?.flatten() {
                // glTF's v runs down the image; ours runs up (OBJ convention).
                Some(v) => {
                    same(&v, &format!("{aat}/TEXCOORD_0"), 2)?;
                    uvs.extend(v.elements::<2>().map(|[u, v]| Vec2::new(u, 1.0 - v)));
                }
                None => {
                    all_uv = false;
                    uvs.extend(std::iter::repeat_n(Vec2::ZERO, n));
                }
            }
            let read = |name: &str| -> R<Option<json::Values>> { Ok(attr(name)?.map(|a| doc.accessor(a)).transpose()?.flatten()) };
            match (read("JOINTS_0")?, read("WEIGHTS_0")?) {
                (Some(j), Some(w)) => {
                    same(&j, &format!("{aat}/JOINTS_0"), 4)?;
                    same(&w, &format!("{aat}/WEIGHTS_0"), 4)?;
                    vjoints.extend(j.elements::<4>().map(|e| e.map(|x| x.clamp(0.0, 65535.0) as u16)));
                    vweights.extend(w.elements::<4>());
                }
                _ => skinned = false,
            }
            let tlist = doc.list(p, "targets", &at)?;
            for (ti, tgt) in targets.iter_mut().enumerate() {
                let tat = format!("{at}/targets/{ti}");
                let d = match tlist
                    .get(ti)
                    .map(|t| doc.index(t, "POSITION", &tat, accessors, "accessor"))
                    .transpose()?
                    .flatten()
                    .map(|a| doc.accessor(a))
                    .transpose()?
                    .flatten()
                {
                    Some(v) => {
                        same(&v, &format!("{tat}/POSITION"), 3)?;
                        v.elements::<3>().map(Vec3::from).collect()
                    }
                    None => vec![Vec3::ZERO; n],
                };
                tgt.extend(d);
            }
            mesh.positions.extend(pos.elements::<3>().map(Vec3::from));
            mesh.indices.extend(tris.iter().map(|t| t.map(|i| i + base)));
            mesh.material.extend(std::iter::repeat_n(mat, tris.len()));
        }
        morph_targets.push(targets);
        skin_data.push(skinned.then_some((vjoints, vweights)));
        if mesh.indices.is_empty() {
            mesh_map.push(None);
            continue;
        }
        if all_n {
            mesh.normals = Attr { values: normals, indices: None };
        }
        if all_uv {
            mesh.uvs = Attr { values: uvs, indices: None };
        }
        mesh_map.push(Some(scene.meshes.len() as u32));
        scene.meshes.push(mesh);
    }

    // Nodes: children checked (each node has at most one parent), transforms read.
    let nodes = doc.items("nodes")?;
    let cameras = doc.items("cameras")?;
    let skins = doc.items("skins")?;
    let lights = doc.root.pointer("/extensions/KHR_lights_punctual/lights").and_then(Value::as_array).map_or(&[][..], Vec::as_slice);
    let mut parents: Vec<Option<u32>> = vec![None; nodes.len()];
    let mut children: Vec<Vec<usize>> = Vec::with_capacity(nodes.len());
    // Each node's local matrix, and its translation, rotation and scale (for animation).
    let mut local: Vec<(Vec3, Quat, Vec3)> = Vec::with_capacity(nodes.len());
    let mut local_matrix: Vec<Mat4> = Vec::with_capacity(nodes.len());
    for (i, n) in nodes.iter().enumerate() {
        let at = ptr(&[&"nodes", &i]);
        let c = doc.indices(n, "children", &at, nodes.len(), "node")?;
        for &k in &c {
            if parents[k].is_some() || k == i {
                return Err(doc.err(&format!("{at}/children"), format!("node {k} has more than one parent (the nodes must form trees)")));
            }
            parents[k] = Some(i as u32);
        }
        children.push(c);
        let (m, trs) = match floats::<16>(n, "matrix") {
            Some(m) => {
                let m = Mat4::from_cols_array(&m);
                let (s, r, t) = m.to_scale_rotation_translation();
                (m, (t, r, s))
            }
            None => {
                let t = Vec3::from(floats::<3>(n, "translation").unwrap_or([0.0; 3]));
                let r = Quat::from_array(floats::<4>(n, "rotation").unwrap_or([0.0, 0.0, 0.0, 1.0]));
                let s = Vec3::from(floats::<3>(n, "scale").unwrap_or([1.0; 3]));
                (Mat4::from_scale_rotation_translation(s, r, t), (t, r, s))
            }
        };
        local_matrix.push(m);
        local.push(trs);
    }
    // A loop in which every node has one parent has no root: its nodes (and those below
    // them) are the ones no walk down from a parentless node reaches. One linear walk.
    let mut rooted = vec![false; nodes.len()];
    let mut down: Vec<usize> = (0..nodes.len()).filter(|&k| parents[k].is_none()).collect();
    while let Some(k) = down.pop() {
        rooted[k] = true;
        down.extend(&children[k]);
    }
    if let Some(i) = rooted.iter().position(|&r| !r) {
        return Err(doc.err(&ptr(&[&"nodes", &i]), "is its own ancestor (the node hierarchy has a loop)"));
    }
    let mut anim = SceneAnimation {
        nodes: (0..nodes.len()).map(|i| Node { parent: parents[i], t: local[i].0, r: local[i].1, s: local[i].2 }).collect(),
        ..SceneAnimation::default()
    };
    // The scene to show: `scene`, else the first; with no scenes, every root node.
    let scenes = doc.items("scenes")?;
    let roots: Vec<usize> = match doc.index(&doc.root, "scene", "", scenes.len(), "scene")?.or((!scenes.is_empty()).then_some(0)) {
        Some(s) => {
            let at = ptr(&[&"scenes", &s]);
            let r = doc.indices(&scenes[s], "nodes", &at, nodes.len(), "node")?;
            if let Some(&k) = r.iter().find(|&&k| parents[k].is_some()) {
                return Err(doc.err(&format!("{at}/nodes"), format!("node {k} is a child of another node, not a root")));
            }
            r
        }
        None => (0..nodes.len()).filter(|&k| parents[k].is_none()).collect(),
    };
    let mut stack: Vec<(usize, Mat4)> = roots.into_iter().map(|n| (n, Mat4::IDENTITY)).collect();
    // Meshes already placed by some node, and those a node deforms (skin or morph targets):
    // a deformed mesh gets a copy of its own for each further node that places it, so one
    // node's pose never moves another node's vertices.
    let mut placed: Vec<bool> = vec![false; scene.meshes.len()];
    let mut deformed: Vec<bool> = vec![false; scene.meshes.len()];
    let mut visited = vec![false; nodes.len()];
    while let Some((ni, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[ni], true) {
            return Err(doc.err(&ptr(&[&"nodes", &ni]), "is reached twice (listed in the scene more than once?)"));
        }
        let node = &nodes[ni];
        let at = ptr(&[&"nodes", &ni]);
        let world = parent * local_matrix[ni];
        let affine = Affine3A::from_mat4(world);
        if let Some(mi) = doc.index(node, "mesh", &at, meshes.len(), "mesh")? {
            if let Some(first) = mesh_map[mi] {
                let skin = doc.index(node, "skin", &at, skins.len(), "skin")?;
                let skinned = skin.is_some() && skin_data[mi].is_some();
                let morphing = !morph_targets[mi].is_empty();
                let deforms = skinned || morphing;
                let (was_placed, was_deformed) = (placed[first as usize], deformed[first as usize]);
                let id = if (deforms && was_placed) || was_deformed {
                    let copy = scene.meshes[first as usize].clone();
                    scene.meshes.push(copy);
                    placed.push(false);
                    deformed.push(false);
                    (scene.meshes.len() - 1) as u32
                } else {
                    first
                };
                placed[id as usize] = true;
                deformed[id as usize] |= deforms;
                scene.instances.push(Instance { geom: Geom::Mesh(id), world_from_object: affine });
                anim.instance_nodes.push(ni as u32);
                if let (Some(si), Some((vj, vw))) = (skin, &skin_data[mi]) {
                    let sat = ptr(&[&"skins", &si]);
                    let joints: Vec<u32> =
                        doc.indices(&skins[si], "joints", &sat, nodes.len(), "node")?.into_iter().map(|j| j as u32).collect();
                    let ibm = doc.index(&skins[si], "inverseBindMatrices", &sat, accessors, "accessor")?;
                    let mut inverse_bind: Vec<Mat4> = match ibm.map(|a| doc.accessor(a)).transpose()?.flatten() {
                        Some(v) => {
                            if v.ncomp != 16 {
                                return Err(doc.err(&format!("{sat}/inverseBindMatrices"), "must be a MAT4 accessor"));
                            }
                            v.elements::<16>().map(|m| Mat4::from_cols_array(&m)).collect()
                        }
                        None => Vec::new(),
                    };
                    inverse_bind.resize(joints.len(), Mat4::IDENTITY);
                    let m = &scene.meshes[id as usize];
                    let base_normals = if m.normals.indices.is_none() && m.normals.values.len() == m.positions.len() {
                        m.normals.values.clone()
                    } else {
                        Vec::new()
                    };
                    anim.skins.push(Skin {
                        mesh: id,
                        instance: (scene.instances.len() - 1) as u32,
                        joints,
                        inverse_bind,
                        base: m.positions.clone(),
                        base_normals,
                        vertex_joints: vj.clone(),
                        vertex_weights: vw.clone(),
                    });
                }
                if !morph_targets[mi].is_empty() {
                    let targets = &morph_targets[mi];
                    let w = |v: &Value| {
                        v.get("weights")
                            .and_then(Value::as_array)
                            .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(0.0) as f32).collect::<Vec<f32>>())
                    };
                    let mut weights = w(node).or_else(|| w(&meshes[mi])).unwrap_or_default();
                    weights.resize(targets.len(), 0.0);
                    anim.morphs.push(Morph {
                        mesh: id,
                        node: ni as u32,
                        base: scene.meshes[id as usize].positions.clone(),
                        targets: targets.clone(),
                        default_weights: weights,
                    });
                }
            }
        }
        if let Some(ci) = doc.index(node, "camera", &at, cameras.len(), "camera")? {
            if scene.camera.is_none() {
                let cam = &cameras[ci];
                let ortho = cam.get("type").and_then(Value::as_str) == Some("orthographic");
                let (vfov, ortho_height) = if ortho {
                    (45.0, Some(2.0 * cam.get("orthographic").and_then(|o| f32_at(o, "ymag")).unwrap_or(1.0)))
                } else {
                    (cam.get("perspective").and_then(|p| f32_at(p, "yfov")).unwrap_or(0.8).to_degrees(), None)
                };
                anim.camera = Some((ni as u32, vfov, ortho_height));
                let eye = affine.transform_point3(Vec3::ZERO);
                let fwd = affine.transform_vector3(-Vec3::Z);
                let up = affine.transform_vector3(Vec3::Y);
                scene.camera = Some(CameraDesc { eye, look_at: eye + fwd, up, vfov_deg: vfov, ortho_height });
            }
        }
        if let Some(l) = node.pointer("/extensions/KHR_lights_punctual") {
            let lat = format!("{at}/extensions/KHR_lights_punctual");
            if let Some(li) = doc.index(l, "light", &lat, lights.len(), "light")? {
                let l = &lights[li];
                let color = Vec3::from(floats::<3>(l, "color").unwrap_or([1.0; 3])) * f32_at(l, "intensity").unwrap_or(1.0);
                let position = affine.transform_point3(Vec3::ZERO);
                let direction = affine.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z);
                let kind = match l.get("type").and_then(Value::as_str) {
                    Some("directional") => LightKind::Directional { direction },
                    Some("spot") => {
                        let s = l.get("spot").cloned().unwrap_or(Value::Null);
                        let inner = f32_at(&s, "innerConeAngle").unwrap_or(0.0);
                        let outer = f32_at(&s, "outerConeAngle").unwrap_or(std::f32::consts::FRAC_PI_4);
                        LightKind::Spot { position, direction, inner, outer }
                    }
                    _ => LightKind::Point { position },
                };
                anim.light_nodes.push((scene.lights.len(), ni as u32));
                scene.lights.push(Light { kind, color, inverse_square: !bart && !matches!(kind, LightKind::Directional { .. }) });
            }
        }
        for &c in &children[ni] {
            stack.push((c, world));
        }
    }

    // Animations: every channel of every animation plays on one clock.
    for (ai, a) in doc.items("animations")?.iter().enumerate() {
        let aat = ptr(&[&"animations", &ai]);
        let samplers = doc.list(a, "samplers", &aat)?;
        for (ci, c) in doc.list(a, "channels", &aat)?.iter().enumerate() {
            let at = format!("{aat}/channels/{ci}");
            let si =
                doc.index(c, "sampler", &at, samplers.len(), "sampler")?.ok_or_else(|| doc.err(&format!("{at}/sampler"), "missing"))?;
            let t = c.get("target").cloned().unwrap_or(Value::Null);
            let tpath = t.get("path").and_then(Value::as_str).unwrap_or("");
            let target = match tpath {
                "translation" => Target::Translation,
                "rotation" => Target::Rotation,
                "scale" => Target::Scale,
                "weights" => Target::Weights,
                _ => {
                    warn(&at, &format!("target path {tpath:?} is not animated by lucent; skipped"));
                    continue;
                }
            };
            let Some(node) = doc.index(&t, "node", &format!("{at}/target"), nodes.len(), "node")? else {
                warn(&at, "no target node; skipped");
                continue;
            };
            let s = &samplers[si];
            let sat = format!("{aat}/samplers/{si}");
            let input = doc.index(s, "input", &sat, accessors, "accessor")?.ok_or_else(|| doc.err(&format!("{sat}/input"), "missing"))?;
            let output =
                doc.index(s, "output", &sat, accessors, "accessor")?.ok_or_else(|| doc.err(&format!("{sat}/output"), "missing"))?;
            let (Some(times), Some(values)) = (doc.accessor(input)?, doc.accessor(output)?) else { continue };
            if times.ncomp != 1 {
                return Err(doc.err(&format!("{sat}/input"), "must be a SCALAR accessor"));
            }
            let times = times.data;
            if times.iter().any(|t| !t.is_finite() || *t < 0.0) || times.windows(2).any(|w| w[1] < w[0]) {
                return Err(doc.err(&format!("{sat}/input"), "key times must be finite, non-negative and ascending"));
            }
            let interp = match s.get("interpolation").and_then(Value::as_str).unwrap_or("LINEAR") {
                "STEP" => Interp::Step,
                "CUBICSPLINE" => Interp::CubicSpline,
                _ => Interp::Linear,
            };
            let width = match target {
                Target::Translation | Target::Scale => 3,
                Target::Rotation => 4,
                Target::Weights => {
                    let per_key = values.data.len().checked_div(times.len()).unwrap_or(0);
                    if interp == Interp::CubicSpline {
                        per_key / 3
                    } else {
                        per_key
                    }
                }
            };
            if target != Target::Weights && values.ncomp != width {
                return Err(
                    doc.err(&format!("{sat}/output"), format!("{tpath} needs {width} components, the accessor has {}", values.ncomp))
                );
            }
            let stride = if interp == Interp::CubicSpline { 3 * width } else { width };
            if width == 0 || values.data.len() != times.len() * stride {
                return Err(doc.err(&at, format!("{} output values for {} keys", values.data.len(), times.len())));
            }
            anim.channels.push(Channel { node: node as u32, target, interp, times, values: values.data, width });
        }
    }
    if anim.is_animated() {
        scene.animation = Some(std::sync::Arc::new(anim));
    }
    if let Some(e) = &asset_extras {
        if let Some(a) = floats::<3>(e, "aff_ambient") {
            scene.ambient = Vec3::from(a);
        }
        if let Some(b) = floats::<3>(e, "aff_background") {
            scene.background = Vec3::from(b);
        }
    }
    Ok(scene)
}

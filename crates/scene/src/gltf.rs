//! glTF 2.0 (`.gltf` + `.bin`, `.glb`): node hierarchy to instances (a mesh used by several
//! nodes becomes one mesh, instanced), PBR materials mapped to Phong/Whitted terms,
//! textures, cameras and `KHR_lights_punctual`.

use crate::anim::{Channel, Interp, Morph, Node, SceneAnimation, Skin, Target};
use crate::error::ImportError;
use crate::model::{Attr, CameraDesc, Geom, Instance, Light, LightKind, Material, Mesh, Scene, Wrap};
use crate::texture::texture_from_image;
use base64::Engine as _;
use glam::{Affine3A, Mat4, Quat, Vec2, Vec3};
use std::path::Path;

/// Loads a glTF or GLB file.
pub fn load_gltf(path: &Path) -> Result<Scene, ImportError> {
    let invalid = |at: &str, msg: String| ImportError::Invalid { path: path.to_path_buf(), at: at.to_string(), msg };
    let bytes = std::fs::read(path).map_err(|source| ImportError::Io { path: path.to_path_buf(), source })?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| invalid("document", e.to_string()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let doc = &gltf.document;
    let buffers = load_buffers(path, doc, base, gltf.blob.clone())?;
    let extras = |e: &gltf::json::Extras| -> Option<serde_json::Value> { e.as_ref().and_then(|r| serde_json::from_str(r.get()).ok()) };
    let asset_extras = extras(&doc.as_json().asset.extras);
    let bart = asset_extras.as_ref().is_some_and(|e| e.get("aff_time_offset").is_some());

    let mut scene = Scene { ambient: crate::model::DEFAULT_AMBIENT, ..Scene::default() };
    // Textures: one per glTF texture; missing images give a warning and no texture.
    let mut tex_map: Vec<Option<u32>> = Vec::new();
    for t in doc.textures() {
        let img = t.source();
        let sampler = t.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        let decoded = match img.source() {
            gltf::image::Source::View { view, .. } => {
                let b = &buffers[view.buffer().index()];
                b.get(view.offset()..view.offset() + view.length())
                    .ok_or_else(|| "buffer view out of range".to_string())
                    .and_then(|s| image::load_from_memory(s).map_err(|e| e.to_string()))
            }
            gltf::image::Source::Uri { uri, .. } => {
                if let Some(data) = uri.strip_prefix("data:") {
                    data.split_once(";base64,").ok_or_else(|| "unsupported data URI".to_string()).and_then(|(_, b64)| {
                        base64::engine::general_purpose::STANDARD
                            .decode(b64)
                            .map_err(|e| e.to_string())
                            .and_then(|b| image::load_from_memory(&b).map_err(|e| e.to_string()))
                    })
                } else {
                    image::open(base.join(percent_decode(uri))).map_err(|e| e.to_string())
                }
            }
        };
        match decoded {
            Ok(im) => {
                scene.textures.push(texture_from_image(
                    img.name().unwrap_or("texture").to_string(),
                    im,
                    wrap(sampler.wrap_s()),
                    wrap(sampler.wrap_t()),
                    true,
                ));
                tex_map.push(Some((scene.textures.len() - 1) as u32));
            }
            Err(e) => {
                tracing::warn!(
                    "{}: textures[{}]: image {} not loaded ({e}); using the plain colour",
                    path.display(),
                    t.index(),
                    img.index()
                );
                tex_map.push(None);
            }
        }
    }
    // Materials (index 0 = default for primitives without one).
    scene.materials.push(Material::default());
    for m in doc.materials() {
        let pbr = m.pbr_metallic_roughness();
        let bc = pbr.base_color_factor();
        let base = Vec3::new(bc[0], bc[1], bc[2]);
        let metallic = pbr.metallic_factor();
        let rough = pbr.roughness_factor().clamp(0.02, 1.0);
        let mut mat = Material {
            name: m.name().unwrap_or("material").to_string(),
            diffuse: base * (1.0 - metallic),
            diffuse_tex: pbr.base_color_texture().and_then(|t| tex_map.get(t.texture().index()).copied().flatten()),
            specular: Vec3::splat(0.04 * (1.0 - metallic)) + base * metallic,
            shininess: (2.0 / (rough * rough * rough * rough) - 2.0).clamp(1.0, 4096.0),
            emission: Vec3::from(m.emissive_factor()),
            reflect: base * metallic,
            ..Material::default()
        };
        if let Some(t) = m.transmission() {
            mat.transmit = Vec3::splat(t.transmission_factor());
            mat.fresnel = true;
        }
        if let Some(ior) = m.ior() {
            mat.ior = ior;
        }
        if let Some(fm) = extras(m.extras()).and_then(|e| e.get("aff_fm").cloned()) {
            // BART/NFF material: use its Phong terms directly.
            let v3 = |k: &str| fm.get(k).and_then(|v| serde_json::from_value::<[f32; 3]>(v.clone()).ok()).map(Vec3::from);
            let f = |k: &str| fm.get(k).and_then(|v| v.as_f64()).map(|x| x as f32);
            mat.ambient = v3("ambient").unwrap_or(mat.ambient);
            // A texture modulates the AFF diffuse term (the glTF base colour factor is 1).
            mat.diffuse = v3("diffuse").unwrap_or(mat.diffuse);
            mat.specular = v3("specular").unwrap_or(mat.specular);
            mat.reflect = mat.specular;
            mat.shininess = f("shine").unwrap_or(mat.shininess).max(1.0);
            let t = f("transmittance").unwrap_or(0.0);
            mat.transmit = Vec3::splat(t);
            mat.fresnel = false;
            if let Some(ior) = f("ior").filter(|&x| x > 0.0) {
                mat.ior = ior;
            }
        }
        scene.materials.push(mat);
    }
    // Meshes: all primitives of a glTF mesh become one mesh with per-triangle materials.
    let mut mesh_map: Vec<Option<u32>> = Vec::new();
    // Morph-target position displacements per glTF mesh (concatenated over primitives).
    let mut morph_targets: Vec<Vec<Vec<Vec3>>> = Vec::new();
    // Per glTF mesh: joints and weights of every vertex, when every primitive has them.
    type SkinData = Option<(Vec<[u16; 4]>, Vec<[f32; 4]>)>;
    let mut skin_data: Vec<SkinData> = Vec::new();
    for m in doc.meshes() {
        let mut mesh = Mesh { name: m.name().unwrap_or("mesh").to_string(), ..Mesh::default() };
        let n_targets = m.primitives().map(|p| p.morph_targets().len()).max().unwrap_or(0);
        let mut targets: Vec<Vec<Vec3>> = vec![Vec::new(); n_targets];
        let (mut vjoints, mut vweights, mut skinned) = (Vec::new(), Vec::new(), true);
        let (mut normals, mut uvs) = (Vec::new(), Vec::new());
        let (mut all_n, mut all_uv) = (true, true);
        for (pi, p) in m.primitives().enumerate() {
            let at = format!("meshes[{}].primitives[{pi}]", m.index());
            let mode = p.mode();
            if !matches!(mode, gltf::mesh::Mode::Triangles | gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan) {
                tracing::warn!("{}: {at}: mode {mode:?} is not triangles; skipped", path.display());
                continue;
            }
            let reader = p.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
            let pos: Vec<Vec3> =
                reader.read_positions().ok_or_else(|| invalid(&at, "no POSITION attribute".into()))?.map(Vec3::from).collect();
            let base = mesh.positions.len() as u32;
            let n = pos.len();
            let idx: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..n as u32).collect(),
            };
            if let Some(bad) = idx.iter().find(|&&i| i as usize >= n) {
                return Err(invalid(&at, format!("index {bad} out of range ({n} vertices)")));
            }
            let tris: Vec<[u32; 3]> = match mode {
                gltf::mesh::Mode::TriangleStrip => (2..idx.len())
                    .map(|k| if k % 2 == 0 { [idx[k - 2], idx[k - 1], idx[k]] } else { [idx[k - 1], idx[k - 2], idx[k]] })
                    .collect(),
                gltf::mesh::Mode::TriangleFan => (2..idx.len()).map(|k| [idx[0], idx[k - 1], idx[k]]).collect(),
                _ => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            };
            let mat = p.material().index().map_or(0, |i| i as u32 + 1);
            match reader.read_normals() {
                Some(ns) => normals.extend(ns.map(Vec3::from)),
                None => {
                    all_n = false;
                    normals.extend(std::iter::repeat_n(Vec3::ZERO, n));
                }
            }
            match reader.read_tex_coords(0) {
                // glTF's v runs down the image; ours runs up (OBJ convention).
                Some(t) => uvs.extend(t.into_f32().map(|[u, v]| Vec2::new(u, 1.0 - v))),
                None => {
                    all_uv = false;
                    uvs.extend(std::iter::repeat_n(Vec2::ZERO, n));
                }
            }
            match (reader.read_joints(0), reader.read_weights(0)) {
                (Some(j), Some(w)) => {
                    let j: Vec<[u16; 4]> = j.into_u16().collect();
                    let w: Vec<[f32; 4]> = w.into_f32().collect();
                    if j.len() == n && w.len() == n {
                        vjoints.extend(j);
                        vweights.extend(w);
                    } else {
                        skinned = false;
                    }
                }
                _ => skinned = false,
            }
            let mut read_targets = reader.read_morph_targets();
            for tgt in &mut targets {
                let d: Vec<Vec3> = read_targets.next().and_then(|(p, _, _)| p).map(|p| p.map(Vec3::from).collect()).unwrap_or_default();
                if d.len() == n {
                    tgt.extend(d);
                } else {
                    tgt.extend(std::iter::repeat_n(Vec3::ZERO, n));
                }
            }
            mesh.positions.extend(pos);
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
    // Node hierarchy.
    let root_nodes: Vec<gltf::Node<'_>> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => doc.nodes().collect(),
    };
    let mut anim = SceneAnimation::default();
    let mut parents: Vec<Option<u32>> = vec![None; doc.nodes().len()];
    for n in doc.nodes() {
        for c in n.children() {
            if let Some(p) = parents.get_mut(c.index()) {
                *p = Some(n.index() as u32);
            }
        }
    }
    anim.nodes = doc
        .nodes()
        .map(|n| {
            let (t, r, s) = n.transform().decomposed();
            Node { parent: parents[n.index()], t: Vec3::from(t), r: Quat::from_array(r), s: Vec3::from(s) }
        })
        .collect();
    let mut stack: Vec<(gltf::Node<'_>, Mat4, usize)> = root_nodes.into_iter().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    // Meshes already placed by some node, and those a node deforms (skin or morph targets):
    // a deformed mesh gets a copy of its own for each further node that places it, so one
    // node's pose never moves another node's vertices.
    let mut placed: Vec<bool> = vec![false; scene.meshes.len()];
    let mut deformed: Vec<bool> = vec![false; scene.meshes.len()];
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 256 {
            return Err(invalid(&format!("nodes[{}]", node.index()), "node hierarchy deeper than 256 (a cycle?)".into()));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let affine = Affine3A::from_mat4(world);
        if let Some(m) = node.mesh() {
            if let Some(&Some(first)) = mesh_map.get(m.index()) {
                let skinned = node.skin().is_some() && matches!(skin_data.get(m.index()), Some(Some(_)));
                let morphing = morph_targets.get(m.index()).is_some_and(|t| !t.is_empty());
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
                anim.instance_nodes.push(node.index() as u32);
                if let (Some(skin), Some(Some((vj, vw)))) = (node.skin(), skin_data.get(m.index())) {
                    let joints: Vec<u32> = skin.joints().map(|j| j.index() as u32).collect();
                    let reader = skin.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
                    let mut inverse_bind: Vec<Mat4> = reader
                        .read_inverse_bind_matrices()
                        .map(|it| it.map(|m| Mat4::from_cols_array_2d(&m)).collect())
                        .unwrap_or_default();
                    inverse_bind.resize(joints.len(), Mat4::IDENTITY);
                    anim.skins.push(Skin {
                        mesh: id,
                        instance: (scene.instances.len() - 1) as u32,
                        joints,
                        inverse_bind,
                        base: scene.meshes[id as usize].positions.clone(),
                        base_normals: {
                            let m = &scene.meshes[id as usize];
                            if m.normals.indices.is_none() && m.normals.values.len() == m.positions.len() {
                                m.normals.values.clone()
                            } else {
                                Vec::new()
                            }
                        },
                        vertex_joints: vj.clone(),
                        vertex_weights: vw.clone(),
                    });
                }
                let targets = morph_targets.get(m.index()).filter(|t| !t.is_empty());
                if let Some(targets) = targets {
                    let weights = node.weights().or_else(|| m.weights()).map(<[f32]>::to_vec).unwrap_or_else(|| vec![0.0; targets.len()]);
                    anim.morphs.push(Morph {
                        mesh: id,
                        node: node.index() as u32,
                        base: scene.meshes[id as usize].positions.clone(),
                        targets: targets.clone(),
                        default_weights: weights,
                    });
                }
            }
        }
        if let Some(cam) = node.camera() {
            if scene.camera.is_none() {
                anim.camera = Some(match cam.projection() {
                    gltf::camera::Projection::Perspective(p) => (node.index() as u32, p.yfov().to_degrees(), None),
                    gltf::camera::Projection::Orthographic(o) => (node.index() as u32, 45.0, Some(2.0 * o.ymag())),
                });
                let eye = affine.transform_point3(Vec3::ZERO);
                let fwd = affine.transform_vector3(-Vec3::Z);
                let up = affine.transform_vector3(Vec3::Y);
                scene.camera = Some(match cam.projection() {
                    gltf::camera::Projection::Perspective(p) => {
                        CameraDesc { eye, look_at: eye + fwd, up, vfov_deg: p.yfov().to_degrees(), ortho_height: None }
                    }
                    gltf::camera::Projection::Orthographic(o) => {
                        CameraDesc { eye, look_at: eye + fwd, up, vfov_deg: 45.0, ortho_height: Some(2.0 * o.ymag()) }
                    }
                });
            }
        }
        if let Some(l) = node.light() {
            let color = Vec3::from(l.color()) * l.intensity();
            let position = affine.transform_point3(Vec3::ZERO);
            let direction = affine.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z);
            let kind = match l.kind() {
                gltf::khr_lights_punctual::Kind::Point => LightKind::Point { position },
                gltf::khr_lights_punctual::Kind::Directional => LightKind::Directional { direction },
                gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                    LightKind::Spot { position, direction, inner: inner_cone_angle, outer: outer_cone_angle }
                }
            };
            anim.light_nodes.push((scene.lights.len(), node.index() as u32));
            scene.lights.push(Light { kind, color, inverse_square: !bart && !matches!(kind, LightKind::Directional { .. }) });
        }
        for c in node.children() {
            stack.push((c, world, depth + 1));
        }
    }
    // Animations: every channel of every animation plays on one clock.
    for a in doc.animations() {
        for (ci, c) in a.channels().enumerate() {
            let at = format!("animations[{}].channels[{ci}]", a.index());
            let reader = c.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
            let times: Vec<f32> = reader.read_inputs().ok_or_else(|| invalid(&at, "sampler input not readable".into()))?.collect();
            if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] < w[0]) {
                return Err(invalid(&at, "key times must be finite and ascending".into()));
            }
            use gltf::animation::util::ReadOutputs;
            let (target, values, width): (Target, Vec<f32>, usize) =
                match reader.read_outputs().ok_or_else(|| invalid(&at, "sampler output not readable".into()))? {
                    ReadOutputs::Translations(v) => (Target::Translation, v.flatten().collect(), 3),
                    ReadOutputs::Rotations(v) => (Target::Rotation, v.into_f32().flatten().collect(), 4),
                    ReadOutputs::Scales(v) => (Target::Scale, v.flatten().collect(), 3),
                    ReadOutputs::MorphTargetWeights(v) => {
                        let v: Vec<f32> = v.into_f32().collect();
                        let per_key = if times.is_empty() { 0 } else { v.len() / times.len() };
                        let cubic = c.sampler().interpolation() == gltf::animation::Interpolation::CubicSpline;
                        (Target::Weights, v, if cubic { per_key / 3 } else { per_key })
                    }
                };
            let interp = match c.sampler().interpolation() {
                gltf::animation::Interpolation::Step => Interp::Step,
                gltf::animation::Interpolation::Linear => Interp::Linear,
                gltf::animation::Interpolation::CubicSpline => Interp::CubicSpline,
            };
            let stride = if interp == Interp::CubicSpline { 3 * width } else { width };
            if width == 0 || values.len() != times.len() * stride {
                return Err(invalid(&at, format!("{} output values for {} keys", values.len(), times.len())));
            }
            anim.channels.push(Channel { node: c.target().node().index() as u32, target, interp, times, values, width });
        }
    }
    if anim.is_animated() {
        scene.animation = Some(std::sync::Arc::new(anim));
    }
    if let Some(e) = &asset_extras {
        let v3 = |k: &str| e.get(k).and_then(|v| serde_json::from_value::<[f32; 3]>(v.clone()).ok()).map(Vec3::from);
        if let Some(a) = v3("aff_ambient") {
            scene.ambient = a;
        }
        if let Some(b) = v3("aff_background") {
            scene.background = b;
        }
    }
    Ok(scene)
}

fn load_buffers(path: &Path, doc: &gltf::Document, base: &Path, mut blob: Option<Vec<u8>>) -> Result<Vec<Vec<u8>>, ImportError> {
    let mut out = Vec::new();
    for b in doc.buffers() {
        let at = format!("buffers[{}]", b.index());
        let invalid = |msg: String| ImportError::Invalid { path: path.to_path_buf(), at: at.clone(), msg };
        let data = match b.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| invalid("refers to the GLB binary chunk, but there is none".into()))?,
            gltf::buffer::Source::Uri(uri) => {
                if let Some(data) = uri.strip_prefix("data:") {
                    let (_, b64) = data.split_once(";base64,").ok_or_else(|| invalid("data URI is not base64".into()))?;
                    base64::engine::general_purpose::STANDARD.decode(b64).map_err(|e| invalid(format!("bad base64: {e}")))?
                } else {
                    let file = base.join(percent_decode(uri));
                    std::fs::read(&file).map_err(|e| invalid(format!("cannot read '{}': {e}", file.display())))?
                }
            }
        };
        if data.len() < b.length() {
            return Err(invalid(format!("has {} bytes, but byteLength says {}", data.len(), b.length())));
        }
        out.push(data);
    }
    Ok(out)
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            if let Ok(v) = u8::from_str_radix(&s[i + 1..i + 3], 16) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

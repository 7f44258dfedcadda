//! Wavefront OBJ and MTL (also gzip-compressed `.obj.gz`).
//!
//! Our own parser, so that every error carries `file:line` and triangles keep file order
//! (polygons fan-triangulated, as the benchmark harness numbers them).

use crate::bsdf::{Bsdf, ColorTex, FloatTex};
use crate::error::ImportError;
use crate::model::{Attr, Material, Mesh, Scene};
use crate::texture::TextureCache;
use crate::texture::Wrap;
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Reads a file, gunzipping names that end in `.gz`.
pub(crate) fn read_maybe_gz(path: &Path) -> Result<Vec<u8>, ImportError> {
    let io = |cause| ImportError::Io { path: path.to_path_buf(), cause };
    let raw = std::fs::read(path).map_err(io)?;
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gz")) {
        use std::io::Read;
        let mut out = Vec::new();
        flate2::read::GzDecoder::new(raw.as_slice()).read_to_end(&mut out).map_err(io)?;
        Ok(out)
    } else {
        Ok(raw)
    }
}

struct Lines<'a> {
    path: &'a Path,
}

impl Lines<'_> {
    fn err(&self, line: usize, msg: impl Into<String>) -> ImportError {
        ImportError::Parse { path: self.path.to_path_buf(), line, msg: msg.into() }
    }
    fn floats<const N: usize>(
        &self,
        line: usize,
        what: &str,
        it: &mut std::str::SplitWhitespace<'_>,
        need: usize,
    ) -> Result<[f32; N], ImportError> {
        let mut out = [0.0f32; N];
        for (k, slot) in out.iter_mut().enumerate() {
            match it.next() {
                Some(tok) => *slot = tok.parse::<f32>().map_err(|_| self.err(line, format!("'{what}' record: '{tok}' is not a number")))?,
                None if k < need => return Err(self.err(line, format!("'{what}' record needs {need} numbers, found {k}"))),
                None => break,
            }
        }
        Ok(out)
    }
}

/// Parses an OBJ file (and the MTL files it names) into a scene with one mesh.
pub fn load_obj(path: &Path) -> Result<Scene, ImportError> {
    let bytes = read_maybe_gz(path)?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        ImportError::Parse { path: path.to_path_buf(), line, msg: "not UTF-8 text".into() }
    })?;
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    parse_obj(path, &dir, text)
}

/// Parses OBJ text; `dir` is where `mtllib` and textures are looked up.
pub fn parse_obj(path: &Path, dir: &Path, text: &str) -> Result<Scene, ImportError> {
    parse_obj_with(path, dir, text, &mut |p| std::fs::read_to_string(p))
}

/// [`parse_obj`] with the material libraries it names read by `read_mtl` (given each one's
/// path under `dir`): for OBJ files held in memory, an archive or a network message. A
/// library `read_mtl` cannot give is a warning, and its materials get defaults; textures
/// are still looked up under `dir`.
pub fn parse_obj_with(
    path: &Path,
    dir: &Path,
    text: &str,
    read_mtl: &mut dyn FnMut(&Path) -> std::io::Result<String>,
) -> Result<Scene, ImportError> {
    let lx = Lines { path };
    let mut scene = Scene { materials: vec![Material::default()], ambient: crate::model::DEFAULT_AMBIENT, ..Scene::default() };
    let mut textures = TextureCache::default();
    let mut mat_ids: HashMap<String, u32> = HashMap::new();
    let mut mesh = Mesh { name: path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(), ..Mesh::default() };
    let mut vt: Vec<Vec2> = Vec::new();
    let mut vn: Vec<Vec3> = Vec::new();
    let mut uv_idx: Vec<[u32; 3]> = Vec::new();
    let mut n_idx: Vec<[u32; 3]> = Vec::new();
    let (mut any_uv, mut any_n) = (false, false);
    let mut cur_mat = 0u32;
    let mut corners: Vec<[i64; 3]> = Vec::new();
    for (ln, raw) in text.lines().enumerate() {
        let line = ln + 1;
        let l = raw.split('#').next().unwrap_or("").trim();
        let mut it = l.split_whitespace();
        let Some(tag) = it.next() else { continue };
        match tag {
            "v" => {
                let [x, y, z] = lx.floats::<3>(line, "v", &mut it, 3)?;
                mesh.positions.push(Vec3::new(x, y, z));
            }
            "vt" => {
                let [u, v] = lx.floats::<2>(line, "vt", &mut it, 1)?;
                vt.push(Vec2::new(u, v));
            }
            "vn" => {
                let [x, y, z] = lx.floats::<3>(line, "vn", &mut it, 3)?;
                vn.push(Vec3::new(x, y, z));
            }
            "f" => {
                corners.clear();
                for tok in it {
                    let mut parts = tok.split('/');
                    let mut idx = [0i64; 3];
                    for (k, slot) in idx.iter_mut().enumerate() {
                        match parts.next() {
                            Some("") | None if k > 0 => *slot = 0,
                            Some(p) => {
                                *slot = p.parse::<i64>().map_err(|_| lx.err(line, format!("face corner '{tok}': '{p}' is not an index")))?
                            }
                            None => return Err(lx.err(line, format!("face corner '{tok}' has no vertex index"))),
                        }
                    }
                    if idx[0] == 0 {
                        return Err(lx.err(line, format!("face corner '{tok}': index 0 (OBJ indices start at 1)")));
                    }
                    let resolve = |i: i64, n: usize, what: &str| -> Result<i64, ImportError> {
                        if i == 0 {
                            return Ok(-1);
                        }
                        let r = if i > 0 { i - 1 } else { n as i64 + i };
                        if r < 0 || r >= n as i64 {
                            return Err(lx.err(line, format!("face corner '{tok}': {what} index {i} out of range (there are {n} so far)")));
                        }
                        Ok(r)
                    };
                    corners.push([
                        resolve(idx[0], mesh.positions.len(), "vertex")?,
                        resolve(idx[1], vt.len(), "texture")?,
                        resolve(idx[2], vn.len(), "normal")?,
                    ]);
                }
                if corners.len() < 3 {
                    return Err(lx.err(line, format!("a face needs at least 3 corners, found {}", corners.len())));
                }
                for k in 2..corners.len() {
                    let c = [corners[0], corners[k - 1], corners[k]];
                    mesh.indices.push(c.map(|c| c[0] as u32));
                    any_uv |= c.iter().all(|c| c[1] >= 0);
                    any_n |= c.iter().all(|c| c[2] >= 0);
                    uv_idx.push(if c.iter().all(|c| c[1] >= 0) { c.map(|c| c[1] as u32) } else { [u32::MAX; 3] });
                    n_idx.push(if c.iter().all(|c| c[2] >= 0) { c.map(|c| c[2] as u32) } else { [u32::MAX; 3] });
                    mesh.material.push(cur_mat);
                }
            }
            "usemtl" => {
                let name = it.collect::<Vec<_>>().join(" ");
                cur_mat = match mat_ids.get(&name) {
                    Some(&id) => id,
                    None => {
                        tracing::warn!("{}:{line}: material '{name}' is not defined; using a default", path.display());
                        let id = scene.materials.len() as u32;
                        scene.materials.push(Material { name: name.clone(), ..Material::default() });
                        mat_ids.insert(name, id);
                        id
                    }
                };
            }
            "mtllib" => {
                for file in it {
                    let mpath = dir.join(file);
                    match read_mtl(&mpath) {
                        Ok(t) => parse_mtl(&mpath, &t, dir, &mut scene, &mut mat_ids, &mut textures)?,
                        Err(e) => tracing::warn!(
                            "{}:{line}: cannot read material library {}: {e}; using defaults",
                            path.display(),
                            mpath.display()
                        ),
                    }
                }
            }
            "o" | "g" | "s" | "l" | "p" | "cstype" | "deg" | "curv" | "surf" | "parm" | "end" | "mg" | "vp" | "usemap" | "maplib"
            | "shadow_obj" | "trace_obj" | "lod" | "bevel" | "c_interp" | "d_interp" => {}
            other => tracing::debug!("{}:{line}: ignoring '{other}' record", path.display()),
        }
    }
    // A triangle whose corner lacks an attribute gets [MAX; 3] and is shaded without it.
    if any_uv {
        mesh.uvs = Attr { values: vt, indices: Some(uv_idx) };
    }
    if any_n {
        mesh.normals = Attr { values: vn, indices: Some(n_idx) };
    }
    scene.textures = textures.into_textures();
    scene.add_mesh(mesh);
    Ok(scene)
}

fn parse_mtl(
    path: &Path,
    text: &str,
    dir: &Path,
    scene: &mut Scene,
    ids: &mut HashMap<String, u32>,
    textures: &mut TextureCache,
) -> Result<(), ImportError> {
    let lx = Lines { path };
    let mut cur: Option<usize> = None;
    let mut illum: Vec<(usize, i32)> = Vec::new();
    // The PBR extension's terms and what says a material is transparent, per material.
    let mut pbr: HashMap<usize, MtlPbr> = HashMap::new();
    for (ln, raw) in text.lines().enumerate() {
        let line = ln + 1;
        let l = raw.split('#').next().unwrap_or("").trim();
        let mut it = l.split_whitespace();
        let Some(tag) = it.next() else { continue };
        if tag == "newmtl" {
            let name = it.collect::<Vec<_>>().join(" ");
            let id = scene.materials.len();
            scene.materials.push(Material { name: name.clone(), specular: Vec3::ZERO, ..Material::default() });
            ids.insert(name, id as u32);
            cur = Some(id);
            continue;
        }
        let Some(m) = cur else {
            if !tag.is_empty() {
                return Err(lx.err(line, format!("'{tag}' before any 'newmtl'")));
            }
            continue;
        };
        let rgb = |it: &mut std::str::SplitWhitespace<'_>, what: &str| -> Result<Vec3, ImportError> {
            let v = lx.floats::<3>(line, what, it, 1)?;
            // "Kd 0.5" means grey; "Kd r g b" is a colour.
            Ok(if l.split_whitespace().count() == 2 { Vec3::splat(v[0]) } else { Vec3::from(v) })
        };
        let mat = &mut scene.materials[m];
        match tag {
            "Kd" => mat.diffuse = rgb(&mut it, tag)?,
            "Ka" => mat.ambient = rgb(&mut it, tag)?,
            "Ks" => mat.specular = rgb(&mut it, tag)?,
            "Ke" => mat.emission = rgb(&mut it, tag)?,
            "Tf" => mat.transmit = rgb(&mut it, tag)?,
            "Ns" => mat.shininess = lx.floats::<1>(line, tag, &mut it, 1)?[0],
            "Ni" => mat.ior = lx.floats::<1>(line, tag, &mut it, 1)?[0],
            "Pr" => pbr.entry(m).or_default().roughness = Some(lx.floats::<1>(line, tag, &mut it, 1)?[0]),
            "Pm" => pbr.entry(m).or_default().metallic = Some(lx.floats::<1>(line, tag, &mut it, 1)?[0]),
            "d" => {
                let d = lx.floats::<1>(line, tag, &mut it, 1)?[0];
                if d < 1.0 {
                    mat.transmit = Vec3::splat(1.0 - d.clamp(0.0, 1.0));
                }
            }
            "Tr" => {
                let tr = lx.floats::<1>(line, tag, &mut it, 1)?[0];
                if tr > 0.0 {
                    mat.transmit = Vec3::splat(tr.clamp(0.0, 1.0));
                }
            }
            "illum" => illum.push((m, lx.floats::<1>(line, tag, &mut it, 1)?[0] as i32)),
            "map_Kd" => {
                // Options (-bm 1, -clamp on, ...) come before the file name.
                let toks: Vec<&str> = it.collect();
                let mut wrap = Wrap::Repeat;
                let mut i = 0;
                while i < toks.len() && toks[i].starts_with('-') {
                    if toks[i] == "-clamp" && toks.get(i + 1) == Some(&"on") {
                        wrap = Wrap::Clamp;
                    }
                    i += option_args(toks[i]) + 1;
                }
                let file = toks.get(i..).map(|t| t.join(" ")).unwrap_or_default();
                if file.is_empty() {
                    return Err(lx.err(line, "map_Kd without a file name"));
                }
                let tpath: PathBuf = dir.join(file.replace('\\', "/"));
                mat.diffuse_tex = textures.load(&tpath, wrap, true, &format!("{}:{line}", path.display()));
            }
            _ => {}
        }
    }
    for mat in scene.materials.iter_mut() {
        // Old convention (Embree's Cornell box): an ambient term above 1 marks a light.
        if mat.emission == Vec3::ZERO && mat.ambient.max_element() > 1.0 {
            mat.emission = mat.ambient;
            mat.ambient = Vec3::ZERO;
        }
    }
    for (m, il) in illum {
        let mat = &mut scene.materials[m];
        match il {
            3 | 5 => mat.reflect = mat.specular,
            4 | 6 | 7 => {
                if mat.transmit == Vec3::ZERO {
                    mat.transmit = Vec3::ONE;
                }
                mat.fresnel = true;
                mat.reflect = mat.specular;
            }
            _ => {}
        }
        if il == 5 {
            mat.fresnel = true;
        }
    }
    for (m, mat) in scene.materials.iter_mut().enumerate() {
        if ids.values().any(|&id| id as usize == m) {
            mat.bsdf = Some(mtl_bsdf(mat, pbr.get(&m)));
        }
    }
    Ok(())
}

/// The PBR extension's terms of one MTL material.
#[derive(Clone, Copy, Debug, Default)]
struct MtlPbr {
    roughness: Option<f32>,
    metallic: Option<f32>,
}

/// The BSDF of Phong terms as MTL gives them (`Kd`/`map_Kd`, `Ks`, `Ns`, `Ni`,
/// transparency in `transmit`): the mapping documented in [`crate::bsdf`].
pub(crate) fn phong_bsdf(mat: &Material) -> Bsdf {
    mtl_bsdf(mat, None)
}

/// The BSDF of an MTL material (the mapping documented in [`crate::bsdf`]).
fn mtl_bsdf(mat: &Material, pbr: Option<&MtlPbr>) -> Bsdf {
    let kd = match mat.diffuse_tex {
        Some(tex) => ColorTex::Image { tex, scale: mat.diffuse, to_uv: glam::Affine2::IDENTITY },
        None => ColorTex::Const(mat.diffuse),
    };
    let t = mat.transmit.clamp(Vec3::ZERO, Vec3::ONE);
    if let Some(p) = pbr.filter(|p| p.roughness.is_some() || p.metallic.is_some()) {
        return Bsdf::MetallicRoughness {
            base_color: kd,
            metallic: FloatTex::Const(p.metallic.unwrap_or(0.0).clamp(0.0, 1.0)),
            roughness: FloatTex::Const(p.roughness.unwrap_or(1.0).clamp(0.0, 1.0)),
            transmission: FloatTex::Const(t.max_element()),
            ior: if mat.ior > 1.0 { mat.ior } else { 1.5 },
        };
    }
    if t.max_element() > 0.0 {
        return if mat.ior > 1.0 && mat.ior.is_finite() {
            Bsdf::Dielectric { eta: mat.ior, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::Const(t), rough: None }
        } else {
            Bsdf::ThinDielectric { eta: 1.5, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::Const(t) }
        };
    }
    let ks = mat.specular.max(Vec3::ZERO);
    if ks.max_element() > 0.0 {
        Bsdf::DiffuseGlossy { diffuse: kd, specular: ks, alpha: crate::bsdf::phong_to_alpha(mat.shininess) }
    } else {
        Bsdf::Diffuse { reflectance: kd }
    }
}

/// How many arguments an MTL texture option takes.
fn option_args(opt: &str) -> usize {
    match opt {
        "-o" | "-s" | "-t" => 3,
        "-mm" => 2,
        _ => 1,
    }
}

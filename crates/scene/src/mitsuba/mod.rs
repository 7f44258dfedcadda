//! Mitsuba 3 scenes (`.xml`), so that users can render their Mitsuba scenes and both
//! renderers can be given the very same input. What is read (Mitsuba's plugin names and
//! defaults):
//!
//! - shapes `obj`, `ply` (through lucent's readers; the file's own materials give way to
//!   the shape's BSDF, as in Mitsuba), `serialized` (`shape_index`; [`serialized`]),
//!   `rectangle`, `cube` (as the meshes Mitsuba makes),
//!   `sphere` (`center`, `radius`), `disk`, `cylinder` (`p0`, `p1`, `radius`, open),
//!   `shapegroup` and `instance`; `to_world` of `translate`, `rotate`, `scale`, `matrix`,
//!   `lookat`; `flip_normals`, `face_normals`;
//! - BSDFs `diffuse`, `conductor`, `roughconductor`, `dielectric`, `roughdielectric`,
//!   `thindielectric`, `plastic`, `roughplastic`, `twosided` (one or two BSDFs),
//!   `blendbsdf`, `mask`, `normalmap`, `bumpmap`, by `id`
//!   and `ref`; textures `bitmap` (`filename`, `raw`, `wrap_mode`, `filter_type`, `to_uv`) and
//!   `checkerboard`;
//! - emitters `area`, `point`, `spot`, `directional`, `constant`, `envmap` (and their
//!   `sampling_weight`: see `emitter`);
//! - the sensor `perspective` (`fov`, `fov_axis`, `focal_length`, `near_clip`,
//!   `far_clip`), `thinlens` (`aperture_radius`, `focus_distance`) and `orthographic`; the
//!   `hdrfilm`'s size and crop window (`crop_offset_x`, `crop_offset_y`, `crop_width`,
//!   `crop_height`) and reconstruction filter (`box`, `tent`, `gaussian`, `mitchell`,
//!   `catmullrom`, `lanczos`); the sampler's `sample_count`; the `path` integrator's `max_depth`,
//!   `rr_depth`, `hide_emitters` ([`RenderHints`]);
//! - `<default name value>` and `$name` in attribute values.
//!
//! Malformed input is an error with line:column and what was expected. A plugin lucent
//! does not have is one warning per kind with the fallback taken (an unknown BSDF is a
//! grey diffuse one, an unknown emitter or shape is left out, an unknown reconstruction
//! filter is Mitsuba's default Gaussian).

mod files;
pub mod serialized;

use crate::bsdf::{
    named_conductor, named_ior, Alpha, Bsdf, ColorTex, Distribution, FloatTex, NormalMap, Principled, PrincipledLobes, Rough, Sides,
};
use crate::camera::CameraDesc;
use crate::error::ImportError;
use crate::model::{
    AovKind, Environment, Geom, HdrImage, Instance, Light, LightKind, Material, Mesh, Outputs, PixelFilter, RenderHints, Scene, ShapeKind,
};
use crate::spectrum::SpectrumUse;
use crate::texture::{TextureCache, Wrap};
use glam::{Affine2, Affine3A, Mat3, Mat4, Vec2, Vec3};
use roxmltree::{Document, Node};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// How deep references may chain (a `twosided` of a `ref` to ...), against cycles.
const MAX_REF_DEPTH: u32 = 16;

/// At most this many shapes (instances included), against files that would exhaust memory.
const MAX_SHAPES: usize = 1 << 22;

type R<T> = Result<T, ImportError>;

/// Loads a Mitsuba 3 XML scene.
pub fn load_mitsuba(path: &Path) -> R<Scene> {
    load_mitsuba_with(path, &[])
}

/// Loads a Mitsuba 3 XML scene with parameters set from outside (Mitsuba's `-D name=value`:
/// they take the place of the file's `<default>`s), ready to render: meshes one shape each
/// draws are merged in world space ([`Scene::merge_single_use_meshes`]), where
/// [`parse_mitsuba_with`] keeps each shape its own mesh and instance.
pub fn load_mitsuba_with(path: &Path, defines: &[(String, String)]) -> R<Scene> {
    let bytes = std::fs::read(path).map_err(|cause| ImportError::Io { path: path.to_path_buf(), cause })?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        ImportError::Parse { path: path.to_path_buf(), line, msg: "not UTF-8 text".into() }
    })?;
    let mut scene = parse_mitsuba_with(path, path.parent().unwrap_or(Path::new(".")), text, defines)?;
    // (Ready to render, as Mitsuba gives Embree its shapes in world space; `parse_mitsuba`
    // keeps the file's shapes apart.)
    scene.merge_single_use_meshes();
    Ok(scene)
}

/// Reads Mitsuba XML `text`; `path` names it in messages, files it names are read from
/// `base`.
pub fn parse_mitsuba(path: &Path, base: &Path, text: &str) -> R<Scene> {
    parse_mitsuba_with(path, base, text, &[])
}

/// [`parse_mitsuba`] with parameters set from outside (see [`load_mitsuba_with`]).
pub fn parse_mitsuba_with(path: &Path, base: &Path, text: &str, defines: &[(String, String)]) -> R<Scene> {
    // The file and those it includes, each parsed once more here (the first pass only
    // found the includes).
    let files = files::gather(path, base, text)?;
    let docs = files.texts.iter().map(|(p, t)| files::parse(p, t)).collect::<R<Vec<_>>>()?;
    let mut cx = Cx {
        paths: files.texts.iter().map(|(p, _)| p.clone()).collect(),
        base: base.to_path_buf(),
        dirs: files.dirs,
        search: files.search,
        includes: files.includes,
        docs: &docs,
        defaults: HashMap::new(),
        ids: HashMap::new(),
        scene: Scene { materials: vec![Material::default()], ..Scene::default() },
        textures: TextureCache::default(),
        warned: HashSet::new(),
        groups: HashMap::new(),
        meshes: HashMap::new(),
        hints: RenderHints {
            width: 768,
            height: 576,
            spp: 4,
            max_depth: None,
            rr_depth: 5,
            hide_emitters: false,
            lens: None,
            clip: (0.01, 10000.0),
            // (Mitsuba's film default; a film of the scene's sets its own.)
            filter: PixelFilter::Gaussian { stddev: 0.5 },
            crop: None,
            strategies: crate::model::Strategies::Both,
        },
        shapes: 0,
        normal_map: None,
        film_alpha: false,
        aov: None,
    };
    cx.defaults.extend(defines.iter().cloned());
    for doc in &docs {
        let root = doc.root_element();
        if root.tag_name().name() != "scene" {
            return Err(cx.err(root, format!("expected <scene>, found <{}>", root.tag_name().name())));
        }
    }
    // Every element with an id, in every file, for references (Mitsuba allows them
    // anywhere). (A `<ref id>` names one; it defines nothing. The first definition of an
    // id counts.) Then `<alias id="a" as="b"/>`: b names what a names.
    for (k, doc) in docs.iter().enumerate() {
        for n in doc.root_element().descendants().filter(|n| n.is_element() && !matches!(n.tag_name().name(), "ref" | "alias")) {
            if let Some(id) = n.attribute("id") {
                cx.ids.entry(id.to_string()).or_insert((k, n.id()));
            }
        }
    }
    for doc in &docs {
        for n in doc.root_element().descendants().filter(|n| n.is_element() && n.tag_name().name() == "alias") {
            let (id, alias) = (cx.attr_raw(n, "id")?, cx.attr_raw(n, "as")?);
            let Some(&target) = cx.ids.get(id) else { return Err(cx.err(n, format!("<alias>: no element has id '{id}'"))) };
            cx.ids.entry(alias.to_string()).or_insert(target);
        }
    }
    cx.children(0, 0)?;
    let mut scene = cx.scene;
    scene.textures = cx.textures.into_textures();
    scene.hints = Some(cx.hints);
    scene.outputs = match cx.aov {
        Some((inner, aovs)) => Some(Outputs { alpha: cx.film_alpha, inner, aovs }),
        None => cx.film_alpha.then(|| Outputs { alpha: true, ..Outputs::default() }),
    };
    scene.ambient = Vec3::ZERO;
    scene.background = Vec3::ZERO;
    Ok(scene)
}

struct Cx<'a, 'd> {
    /// The scene's files (the first is the scene; see `files`), their folders, the
    /// `<path>` folders, and which file each `<include>` brings in.
    paths: Vec<PathBuf>,
    base: PathBuf,
    dirs: Vec<PathBuf>,
    search: Vec<PathBuf>,
    includes: HashMap<(usize, roxmltree::NodeId), usize>,
    docs: &'a [Document<'d>],
    defaults: HashMap<String, String>,
    ids: HashMap<String, (usize, roxmltree::NodeId)>,
    scene: Scene,
    textures: TextureCache,
    warned: HashSet<String>,
    /// Shape groups: their geometry and object-to-group transforms.
    groups: HashMap<String, Vec<(Geom, Affine3A)>>,
    /// Meshes read from files: (file, mesh in the file, material, face normals, flipped)
    /// to mesh index.
    meshes: HashMap<(PathBuf, u32, u32, bool, bool), u32>,
    hints: RenderHints,
    shapes: usize,
    /// The normal map of the BSDF read last (a `normalmap` adapter), for its material.
    normal_map: Option<NormalMap>,
    /// The film's `pixel_format` has an alpha channel.
    film_alpha: bool,
    /// An `aov` integrator: the name of the integrator it wraps, and its layers.
    aov: Option<AovSpec>,
}

/// An `aov` integrator as read: the name of the integrator it wraps, and its layers.
type AovSpec = (Option<String>, Vec<(String, AovKind)>);

/// A BSDF as read: the model, and how its back scatters.
type ReadBsdf = (Bsdf, Sides);

impl<'a, 'd> Cx<'a, 'd> {
    /// The file `n` is in.
    fn file_of(&self, n: Node) -> usize {
        self.docs.iter().position(|d| std::ptr::eq(d, n.document())).unwrap_or(0)
    }

    fn pos(&self, n: Node) -> (u32, u32) {
        let p = n.document().text_pos_at(n.range().start);
        (p.row, p.col)
    }

    fn err(&self, n: Node, msg: impl Into<String>) -> ImportError {
        let (line, column) = self.pos(n);
        let path = self.paths.get(self.file_of(n)).cloned().unwrap_or_default();
        ImportError::At { path, line, column, msg: msg.into() }
    }

    fn warn(&mut self, n: Node, kind: &str, msg: &str) {
        if self.warned.insert(kind.to_string()) {
            let (line, column) = self.pos(n);
            let path = self.paths.get(self.file_of(n)).cloned().unwrap_or_default();
            tracing::warn!("{}:{line}:{column}: {msg}", path.display());
        }
    }

    /// A file a scene names (relative to the naming file's folder, the `<path>` folders,
    /// then the scene's): the first of them where it exists, else under the scene's folder.
    fn find(&self, n: Node, name: &str) -> PathBuf {
        let dir = self.dirs.get(self.file_of(n)).unwrap_or(&self.base);
        files::resolve(name, dir, &self.search, &self.base).unwrap_or_else(|| self.base.join(name.replace('\\', "/")))
    }

    /// Refuses a named file that is not a regular file (a device such as /dev/zero would
    /// be read forever, a folder fails later with a vaguer message).
    fn regular_file(&self, n: Node, path: &Path) -> R<()> {
        match std::fs::metadata(path) {
            Ok(m) if !m.is_file() => Err(self.err(n, format!("{}: not a regular file", path.display()))),
            _ => Ok(()),
        }
    }

    /// The node with `id` (per file).
    fn node(&self, (k, id): (usize, roxmltree::NodeId)) -> Option<Node<'a, 'd>> {
        self.docs.get(k).and_then(|d| d.get_node(id))
    }

    /// The top-level elements of file `k` (an `<include>`d file's in its place).
    fn children(&mut self, k: usize, depth: usize) -> R<()> {
        let Some(doc) = self.docs.get(k) else { return Ok(()) };
        for n in doc.root_element().children().filter(Node::is_element) {
            match n.tag_name().name() {
                "default" => {
                    let name = self.attr_raw(n, "name")?;
                    let value = self.attr_raw(n, "value")?;
                    self.defaults.entry(name.to_string()).or_insert_with(|| value.to_string());
                }
                "integrator" => self.integrator(n)?,
                "sensor" => self.sensor(n)?,
                "shape" => {
                    let Some(items) = self.shape(n, 0)? else { continue };
                    for (geom, m) in items {
                        self.push_instance(n, geom, m)?;
                    }
                }
                // (An area emitter at the top is defined for the shapes that name it.)
                "emitter" if n.attribute("type") == Some("area") && n.attribute("id").is_some() => {}
                "emitter" => self.emitter(n, None)?,
                // (Defined here, used by reference.)
                "bsdf" | "texture" | "medium" | "spectrum" | "rfilter" | "sampler" | "film" => {}
                // (Read with the files: see `files` and the id pass.)
                "path" | "alias" => {}
                "include" => match self.includes.get(&(k, n.id())) {
                    Some(&j) if depth < files::MAX_INCLUDE_DEPTH => self.children(j, depth + 1)?,
                    _ => return Err(self.err(n, "<include>: the file was not read")),
                },
                other => self.warn(n, other, &format!("<{other}> is not supported; left out")),
            }
        }
        Ok(())
    }

    /// An attribute as written.
    fn attr_raw<'n>(&self, n: Node<'n, 'd>, key: &str) -> R<&'n str> {
        n.attribute(key).ok_or_else(|| self.err(n, format!("<{}> needs a '{key}' attribute", n.tag_name().name())))
    }

    /// An attribute with `$name` defaults substituted.
    fn attr(&self, n: Node, key: &str) -> R<String> {
        let raw = self.attr_raw(n, key)?;
        self.subst(n, raw)
    }

    fn subst(&self, n: Node, raw: &str) -> R<String> {
        if !raw.contains('$') {
            return Ok(raw.to_string());
        }
        let mut out = String::new();
        let mut rest = raw;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let tail = &rest[i + 1..];
            let end = tail.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(tail.len());
            let name = &tail[..end];
            match self.defaults.get(name) {
                Some(v) => out.push_str(v),
                None => return Err(self.err(n, format!("'${name}' has no <default name=\"{name}\" value=...>"))),
            }
            rest = &tail[end..];
        }
        out.push_str(rest);
        Ok(out)
    }

    /// The element a `<ref id>` names (or the node itself).
    fn deref(&self, n: Node<'a, 'd>, depth: u32) -> R<Node<'a, 'd>> {
        if n.tag_name().name() != "ref" {
            return Ok(n);
        }
        if depth > MAX_REF_DEPTH {
            return Err(self.err(n, "references nest too deep (a cycle?)"));
        }
        let id = self.attr(n, "id")?;
        let target = self.ids.get(&id).and_then(|&i| self.node(i)).ok_or_else(|| self.err(n, format!("no element has id '{id}'")))?;
        self.deref(target, depth + 1)
    }

    /// The property child named `name`.
    fn prop(&self, plugin: Node<'a, 'd>, name: &str) -> Option<Node<'a, 'd>> {
        plugin.children().filter(Node::is_element).find(|c| c.attribute("name") == Some(name))
    }

    fn numbers(&self, n: Node, s: &str) -> R<Vec<f32>> {
        s.split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
            .map(|t| t.parse::<f32>().map_err(|_| self.err(n, format!("'{t}' is not a number"))))
            .collect()
    }

    fn number(&self, n: Node, s: &str) -> R<f32> {
        let v = self.numbers(n, s)?;
        match v.as_slice() {
            [x] => Ok(*x),
            _ => Err(self.err(n, format!("expected one number, found '{s}'"))),
        }
    }

    fn float(&self, plugin: Node<'a, 'd>, name: &str, default: f32) -> R<f32> {
        match self.prop(plugin, name) {
            None => Ok(default),
            Some(p) if matches!(p.tag_name().name(), "float" | "integer") => {
                let v = self.attr(p, "value")?;
                self.number(p, &v)
            }
            Some(p) => Err(self.err(p, format!("'{name}' must be a <float>"))),
        }
    }

    /// A float property that must be positive and finite (a size).
    fn positive(&self, plugin: Node<'a, 'd>, name: &str, default: f32) -> R<f32> {
        let v = self.float(plugin, name, default)?;
        if v > 0.0 && v.is_finite() && v < 64.0 {
            Ok(v)
        } else {
            Err(self.err(plugin, format!("'{name}' must be a positive size below 64 (got {v})")))
        }
    }

    fn integer(&self, plugin: Node<'a, 'd>, name: &str, default: i64) -> R<i64> {
        match self.prop(plugin, name) {
            None => Ok(default),
            Some(p) => {
                let v = self.attr(p, "value")?;
                v.trim().parse::<i64>().map_err(|_| self.err(p, format!("'{name}' must be an integer, found '{v}'")))
            }
        }
    }

    fn boolean(&self, plugin: Node<'a, 'd>, name: &str, default: bool) -> R<bool> {
        match self.prop(plugin, name) {
            None => Ok(default),
            Some(p) => match self.attr(p, "value")?.trim() {
                "true" | "1" => Ok(true),
                "false" | "0" => Ok(false),
                v => Err(self.err(p, format!("'{name}' must be true or false, found '{v}'"))),
            },
        }
    }

    fn string(&self, plugin: Node<'a, 'd>, name: &str) -> R<Option<String>> {
        self.prop(plugin, name).map(|p| self.attr(p, "value")).transpose()
    }

    /// A point or vector: `value="x y z"` or `x=`, `y=`, `z=` attributes.
    fn xyz(&self, n: Node, default: Vec3) -> R<Vec3> {
        if let Some(v) = n.attribute("value") {
            let v = self.numbers(n, &self.subst(n, v)?)?;
            return match v.as_slice() {
                [x, y, z] => Ok(Vec3::new(*x, *y, *z)),
                [x] => Ok(Vec3::splat(*x)),
                _ => Err(self.err(n, "expected three numbers")),
            };
        }
        let c = |k: &str, d: f32| -> R<f32> {
            match n.attribute(k) {
                Some(s) => self.number(n, &self.subst(n, s)?),
                None => Ok(d),
            }
        };
        Ok(Vec3::new(c("x", default.x)?, c("y", default.y)?, c("z", default.z)?))
    }

    fn point(&self, plugin: Node<'a, 'd>, name: &str, default: Vec3) -> R<Vec3> {
        match self.prop(plugin, name) {
            None => Ok(default),
            Some(p) => self.xyz(p, Vec3::ZERO),
        }
    }

    /// A colour: `<rgb>`, a uniform `<spectrum>` or `<float>`.
    fn color_node(&mut self, p: Node<'a, 'd>) -> R<Vec3> {
        match p.tag_name().name() {
            "rgb" => {
                let v = self.attr(p, "value")?;
                let v = self.numbers(p, &v)?;
                match v.as_slice() {
                    [r, g, b] => Ok(Vec3::new(*r, *g, *b)),
                    [x] => Ok(Vec3::splat(*x)),
                    _ => Err(self.err(p, "<rgb> needs three numbers")),
                }
            }
            "float" | "integer" => {
                let v = self.attr(p, "value")?;
                Ok(Vec3::splat(self.number(p, &v)?))
            }
            "spectrum" => {
                // As Mitsuba's RGB variants read spectra (crate::spectrum): emission and
                // unitless terms convert differently from reflectances.
                let usage = if p.ancestors().any(|a| a.tag_name().name() == "emitter") {
                    SpectrumUse::Emission
                } else if matches!(p.attribute("name"), Some("eta" | "k" | "int_ior" | "ext_ior")) {
                    SpectrumUse::Unbounded
                } else {
                    SpectrumUse::Reflectance
                };
                let (w, v) = match (p.attribute("filename"), p.attribute("value")) {
                    _ if p.attribute("type").is_some() => return self.spectrum_plugin(p, usage),
                    (Some(_), _) => {
                        let file = self.attr(p, "filename")?;
                        let path = self.find(p, &file);
                        let text = files::read_text(&path).map_err(|e| self.err(p, format!("{}: {e}", path.display())))?;
                        crate::spectrum::parse_spd(&text).map_err(|e| self.err(p, format!("{}: {e}", path.display())))?
                    }
                    (None, _) => {
                        let v = self.attr(p, "value")?;
                        if !v.contains(':') {
                            let x = self.number(p, &v)?;
                            return Ok(if usage == SpectrumUse::Emission {
                                crate::spectrum::EQUAL_ENERGY_EMISSION * x
                            } else {
                                Vec3::splat(x)
                            });
                        }
                        crate::spectrum::parse_pairs(&v).map_err(|e| self.err(p, format!("<spectrum value>: {e}")))?
                    }
                };
                crate::spectrum::spectrum_to_rgb(&w, &v, usage).ok_or_else(|| self.err(p, "a spectrum needs increasing wavelengths"))
            }
            other => Err(self.err(p, format!("expected <rgb>, <spectrum> or <float>, found <{other}>"))),
        }
    }

    /// A `<spectrum type=...>` plugin: `uniform` and `d65` (white in Mitsuba's RGB
    /// variants, times `scale`), `blackbody` (`temperature`), `regular` and `irregular`
    /// (sampled spectra, converted as `<spectrum value>` pairs are). Mitsuba's RGB variants
    /// refuse the last three; lucent converts them as its spectral variants see them.
    fn spectrum_plugin(&mut self, p: Node<'a, 'd>, usage: SpectrumUse) -> R<Vec3> {
        let kind = self.attr(p, "type")?;
        let list = |cx: &Self, name: &str| -> R<Vec<f32>> {
            let v = cx.string(p, name)?.ok_or_else(|| cx.err(p, format!("a '{kind}' spectrum needs '{name}'")))?;
            cx.numbers(p, &v)
        };
        let (w, v) = match kind.as_str() {
            "uniform" => return Ok(Vec3::splat(self.float(p, "value", 1.0)?)),
            "d65" => return Ok(Vec3::splat(self.float(p, "scale", 1.0)?)),
            "blackbody" => {
                let t = self.float(p, "temperature", f32::NAN)?;
                crate::spectrum::blackbody(t)
                    .ok_or_else(|| self.err(p, format!("a blackbody needs a positive 'temperature' in kelvin (got {t})")))?
            }
            "irregular" => (list(self, "wavelengths")?, list(self, "values")?),
            "regular" => {
                let (lo, hi) = (self.float(p, "wavelength_min", f32::NAN)?, self.float(p, "wavelength_max", f32::NAN)?);
                let v = list(self, "values")?;
                if lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less) || v.len() < 2 {
                    return Err(self.err(p, "a 'regular' spectrum needs wavelength_min < wavelength_max and two or more values"));
                }
                let n = (v.len() - 1) as f32;
                ((0..v.len()).map(|i| lo + (hi - lo) * i as f32 / n).collect(), v)
            }
            other => return Err(self.err(p, format!("spectrum type '{other}': expected uniform, d65, blackbody, regular or irregular"))),
        };
        let scale = if kind == "blackbody" { 1.0 } else { self.float(p, "scale", 1.0)? };
        crate::spectrum::spectrum_to_rgb(&w, &v, usage)
            .map(|c| c * scale)
            .ok_or_else(|| self.err(p, "a spectrum needs as many values as wavelengths, the wavelengths increasing"))
    }

    fn color(&mut self, plugin: Node<'a, 'd>, name: &str, default: Vec3) -> R<Vec3> {
        match self.prop(plugin, name) {
            None => Ok(default),
            Some(p) => self.color_node(p),
        }
    }

    /// A colour that may be a texture.
    fn color_tex(&mut self, plugin: Node<'a, 'd>, name: &str, default: Vec3) -> R<ColorTex> {
        let Some(p) = self.prop(plugin, name) else { return Ok(ColorTex::Const(default)) };
        let p = self.deref(p, 0)?;
        if p.tag_name().name() == "texture" {
            return self.texture(p);
        }
        Ok(ColorTex::Const(self.color_node(p)?))
    }

    fn texture(&mut self, t: Node<'a, 'd>) -> R<ColorTex> {
        let kind = self.attr(t, "type")?;
        let to_uv = match self.prop(t, "to_uv") {
            Some(tr) => {
                let m = self.transform(tr)?;
                // The 2D part: u and v from the first two rows and the translation.
                let m = Mat4::from(m);
                Affine2::from_cols_array(&[m.x_axis.x, m.x_axis.y, m.y_axis.x, m.y_axis.y, m.w_axis.x, m.w_axis.y])
            }
            None => Affine2::IDENTITY,
        };
        match kind.as_str() {
            "bitmap" => {
                let file = self.string(t, "filename")?.ok_or_else(|| self.err(t, "a bitmap needs a 'filename'"))?;
                let raw = self.boolean(t, "raw", false)?;
                let wrap = match self.string(t, "wrap_mode")?.as_deref() {
                    None | Some("repeat") => Wrap::Repeat,
                    Some("mirror") => Wrap::Mirror,
                    Some("clamp") => Wrap::Clamp,
                    Some(w) => return Err(self.err(t, format!("wrap_mode '{w}': expected repeat, mirror or clamp"))),
                };
                let path = self.find(t, &file);
                let at = format!("{}:{}", self.paths.get(self.file_of(t)).cloned().unwrap_or_default().display(), self.pos(t).0);
                // Mitsuba looks images up with v = 0 at their first row, lucent (as OBJ)
                // at their last: v is turned over after the texture's own transform.
                let to_uv = Affine2::from_cols_array(&[1.0, 0.0, 0.0, -1.0, 0.0, 1.0]) * to_uv;
                let nearest = match self.string(t, "filter_type")?.as_deref() {
                    None | Some("bilinear") => false,
                    Some("nearest") => true,
                    Some(f) => return Err(self.err(t, format!("filter_type '{f}': expected bilinear or nearest"))),
                };
                match self.textures.load_with(&path, wrap, !raw, nearest, &at) {
                    Some(tex) => Ok(ColorTex::Image { tex, scale: Vec3::ONE, to_uv }),
                    None => Ok(ColorTex::grey(0.5)),
                }
            }
            "checkerboard" => {
                let a = self.color(t, "color0", Vec3::splat(0.4))?;
                let b = self.color(t, "color1", Vec3::splat(0.2))?;
                Ok(ColorTex::Checker { a, b, to_uv })
            }
            other => {
                self.warn(t, &format!("texture {other}"), &format!("texture '{other}' is not supported; a grey of 0.5 instead"));
                Ok(ColorTex::grey(0.5))
            }
        }
    }

    /// An index of refraction: a number or a name of Mitsuba's table.
    fn ior(&self, plugin: Node<'a, 'd>, name: &str, default: &str) -> R<f32> {
        let (p, v) = match self.prop(plugin, name) {
            Some(p) => (p, self.attr(p, "value")?),
            None => (plugin, default.to_string()),
        };
        if let Ok(x) = v.trim().parse::<f32>() {
            return if x > 0.0 && x.is_finite() { Ok(x) } else { Err(self.err(p, format!("'{name}' must be positive"))) };
        }
        named_ior(v.trim()).ok_or_else(|| self.err(p, format!("'{v}' is not an index of refraction Mitsuba names")))
    }

    fn roughness(&mut self, b: Node<'a, 'd>) -> R<Rough> {
        let dist = match self.string(b, "distribution")?.as_deref() {
            None | Some("beckmann") => Distribution::Beckmann,
            Some("ggx") => Distribution::Ggx,
            Some(d) => return Err(self.err(b, format!("distribution '{d}': expected beckmann or ggx"))),
        };
        match self.prop(b, "alpha") {
            Some(_) => Ok(Rough::isotropic(dist, self.float_tex(b, "alpha", 0.1)?)),
            None => match (self.prop(b, "alpha_u"), self.prop(b, "alpha_v")) {
                (Some(_), Some(_)) => {
                    let (u, v) = (self.float_tex(b, "alpha_u", 0.1)?, self.float_tex(b, "alpha_v", 0.1)?);
                    Ok(if u == v { Rough::isotropic(dist, u) } else { Rough { dist, alpha: u, alpha_v: Some(v) } })
                }
                (Some(p), None) | (None, Some(p)) => {
                    Err(self.err(p, "alpha_u and alpha_v come together (anisotropic roughness)".to_string()))
                }
                (None, None) => Ok(Rough::isotropic(dist, FloatTex::Const(0.1))),
            },
        }
    }

    /// The BSDFs inside an adapter `b` (children or references), in order.
    fn inner_bsdfs(&self, b: Node<'a, 'd>, depth: u32) -> Vec<Node<'a, 'd>> {
        b.children()
            .filter(|c| {
                matches!(c.tag_name().name(), "bsdf" | "ref") && self.deref(*c, depth + 1).is_ok_and(|x| x.tag_name().name() == "bsdf")
            })
            .collect()
    }

    /// A scalar that may be a bitmap texture (its first channel) or a number.
    fn float_tex(&mut self, plugin: Node<'a, 'd>, name: &str, default: f32) -> R<FloatTex> {
        match self.prop(plugin, name) {
            Some(p) if self.deref(p, 0)?.tag_name().name() == "texture" => {
                let t = self.deref(p, 0)?;
                Ok(match self.texture(t)? {
                    ColorTex::Image { tex, to_uv, .. } => FloatTex::Image { tex, channel: 0, scale: 1.0, to_uv },
                    // (Its colours read as numbers by their luminance, as Mitsuba's. Mitsuba
                    // 3.9.1's checkerboard puts color0 where u and v lie in the same half of
                    // their unit square when it gives a colour, and in different halves when
                    // it gives a number (`eval` against `eval_1`): as a number, the squares
                    // trade places.)
                    ColorTex::Checker { a, b, to_uv } => {
                        let lum = |c: Vec3| c.dot(Vec3::new(0.212_671, 0.715_160, 0.072_169));
                        FloatTex::Checker { a: lum(b), b: lum(a), to_uv }
                    }
                    other => FloatTex::Const(other.mean_guess().x),
                })
            }
            _ => Ok(FloatTex::Const(self.float(plugin, name, default)?)),
        }
    }

    /// Mitsuba's `principled` BSDF: its parameters (numbers or textures), which lobes
    /// are on (a parameter set to anything but the number 0, as Mitsuba's `get_flag`), and
    /// the index from `eta` or `specular` (not both).
    fn principled(&mut self, b: Node<'a, 'd>) -> R<Principled> {
        let on = |s: &Self, name: &str| match s.prop(b, name) {
            None => Ok(false),
            Some(p) if p.tag_name().name() == "float" => Ok(s.number(p, &s.attr(p, "value")?)? != 0.0),
            Some(_) => Ok(true),
        };
        let has = PrincipledLobes {
            anisotropic: on(self, "anisotropic")?,
            metallic: on(self, "metallic")?,
            spec_trans: on(self, "spec_trans")?,
            spec_tint: on(self, "spec_tint")?,
            sheen: on(self, "sheen")?,
            sheen_tint: on(self, "sheen_tint")?,
            flatness: on(self, "flatness")?,
            clearcoat: on(self, "clearcoat")?,
        };
        let eta = match (self.prop(b, "eta"), self.prop(b, "specular")) {
            (Some(_), Some(p)) => return Err(self.err(p, "principled takes 'eta' or 'specular', not both")),
            (Some(p), None) => {
                let eta = self.float(b, "eta", 1.5)?;
                if !(eta > 0.0 && eta.is_finite()) {
                    return Err(self.err(p, "'eta' must be positive"));
                }
                // (As Mitsuba: an index of 1 cannot refract.)
                if has.spec_trans && eta == 1.0 {
                    1.001
                } else {
                    eta
                }
            }
            (None, _) => {
                let mut specular = self.float(b, "specular", 0.5)?;
                if has.spec_trans && specular == 0.0 {
                    specular = 1e-3;
                }
                let eta = 2.0 / (1.0 - (0.08 * specular).sqrt()) - 1.0;
                if !(eta > 0.0 && eta.is_finite()) {
                    let at = self.prop(b, "specular").unwrap_or(b);
                    return Err(self.err(at, "'specular' must lie in [0, 1]"));
                }
                eta
            }
        };
        Ok(Principled {
            base_color: self.color_tex(b, "base_color", Vec3::splat(0.5))?,
            roughness: self.float_tex(b, "roughness", 0.5)?,
            anisotropic: self.float_tex(b, "anisotropic", 0.0)?,
            metallic: self.float_tex(b, "metallic", 0.0)?,
            spec_trans: self.float_tex(b, "spec_trans", 0.0)?,
            spec_tint: self.float_tex(b, "spec_tint", 0.0)?,
            sheen: self.float_tex(b, "sheen", 0.0)?,
            sheen_tint: self.float_tex(b, "sheen_tint", 0.0)?,
            flatness: self.float_tex(b, "flatness", 0.0)?,
            clearcoat: self.float_tex(b, "clearcoat", 0.0)?,
            clearcoat_gloss: self.float_tex(b, "clearcoat_gloss", 0.0)?,
            eta,
            rates: [
                self.float(b, "diffuse_reflectance_sampling_rate", 1.0)?,
                self.float(b, "main_specular_sampling_rate", 1.0)?,
                self.float(b, "clearcoat_sampling_rate", 1.0)?,
            ],
            has,
        })
    }

    fn bsdf(&mut self, n: Node<'a, 'd>, depth: u32) -> R<ReadBsdf> {
        let b = self.deref(n, depth)?;
        if b.tag_name().name() != "bsdf" {
            return Err(self.err(n, format!("expected a <bsdf>, found <{}>", b.tag_name().name())));
        }
        if depth > MAX_REF_DEPTH {
            return Err(self.err(b, "BSDFs nest too deep"));
        }
        let kind = self.attr(b, "type")?;
        let one = Vec3::ONE;
        Ok(match kind.as_str() {
            "twosided" => {
                let inner: Vec<Node> = b.children().filter(|c| matches!(c.tag_name().name(), "bsdf" | "ref")).collect();
                match inner.as_slice() {
                    [f] => (self.bsdf(*f, depth + 1)?.0, Sides::Both),
                    [f, k] => {
                        let front = self.bsdf(*f, depth + 1)?.0;
                        let back = self.bsdf(*k, depth + 1)?.0;
                        (front, Sides::Back(Box::new(back)))
                    }
                    _ => return Err(self.err(b, "twosided needs one or two BSDFs")),
                }
            }
            "diffuse" => (Bsdf::Diffuse { reflectance: self.color_tex(b, "reflectance", Vec3::splat(0.5))? }, Sides::Front),
            "conductor" | "roughconductor" => {
                let ext = self.ior(b, "ext_eta", "air")?;
                let (eta, k) = match (self.prop(b, "eta"), self.prop(b, "k")) {
                    (Some(_), Some(_)) => (self.color(b, "eta", Vec3::ZERO)?, self.color(b, "k", one)?),
                    _ => {
                        let m = self.string(b, "material")?.unwrap_or_else(|| "none".into());
                        named_conductor(&m).ok_or_else(|| self.err(b, format!("'{m}' is not a conductor Mitsuba names")))?
                    }
                };
                let rough = if kind == "roughconductor" { Some(self.roughness(b)?) } else { None };
                let specular = self.color_tex(b, "specular_reflectance", one)?;
                (Bsdf::Conductor { eta: eta / ext, k: k / ext, specular, rough }, Sides::Front)
            }
            "dielectric" | "roughdielectric" | "thindielectric" => {
                let eta = self.ior(b, "int_ior", "bk7")? / self.ior(b, "ext_ior", "air")?;
                let reflectance = self.color_tex(b, "specular_reflectance", one)?;
                let transmittance = self.color_tex(b, "specular_transmittance", one)?;
                let d = match kind.as_str() {
                    "thindielectric" => Bsdf::ThinDielectric { eta, reflectance, transmittance },
                    "roughdielectric" => Bsdf::Dielectric { eta, reflectance, transmittance, rough: Some(self.roughness(b)?) },
                    _ => Bsdf::Dielectric { eta, reflectance, transmittance, rough: None },
                };
                (d, Sides::Both)
            }
            "plastic" | "roughplastic" => {
                let eta = self.ior(b, "int_ior", "polypropylene")? / self.ior(b, "ext_ior", "air")?;
                let rough = if kind == "roughplastic" {
                    let r = self.roughness(b)?;
                    if r.alpha_v.is_some() {
                        self.warn(b, "anisotropic plastic", "roughplastic is isotropic (as Mitsuba's): alpha_u is its roughness");
                    }
                    let alpha = match r.alpha {
                        FloatTex::Const(a) => a,
                        _ => return Err(self.err(b, "roughplastic's alpha cannot be a texture (as in Mitsuba)")),
                    };
                    Some((r.dist, alpha))
                } else {
                    None
                };
                let d = Bsdf::Plastic {
                    diffuse: self.color_tex(b, "diffuse_reflectance", Vec3::splat(0.5))?,
                    specular: self.color_tex(b, "specular_reflectance", one)?,
                    eta,
                    nonlinear: self.boolean(b, "nonlinear", false)?,
                    rough,
                };
                (d, Sides::Front)
            }
            "normalmap" => {
                let Some(map) = self.prop(b, "normalmap") else { return Err(self.err(b, "a normalmap needs a 'normalmap' texture")) };
                let map = self.deref(map, depth + 1)?;
                let nm = match (map.tag_name().name(), self.texture(map)?) {
                    ("texture", ColorTex::Image { tex, to_uv, .. }) => NormalMap { tex, scale: 1.0, to_uv, mitsuba: true, height: false },
                    _ => return Err(self.err(map, "a normalmap's 'normalmap' must be a bitmap texture")),
                };
                let inner =
                    self.inner_bsdfs(b, depth).into_iter().next().ok_or_else(|| self.err(b, "a normalmap needs one BSDF inside"))?;
                let read = self.bsdf(inner, depth + 1)?;
                self.normal_map = Some(nm);
                read
            }
            "blendbsdf" => {
                let inner: Vec<Node> = self.inner_bsdfs(b, depth);
                let [f, k] = inner.as_slice() else { return Err(self.err(b, "a blendbsdf needs two BSDFs inside")) };
                let weight = self.float_tex(b, "weight", 0.5)?;
                let (first, s0) = self.bsdf(*f, depth + 1)?;
                let (second, s1) = self.bsdf(*k, depth + 1)?;
                // (Both sides scatter when both BSDFs say so.)
                let sides = if s0 == Sides::Both && s1 == Sides::Both { Sides::Both } else { Sides::Front };
                (Bsdf::Blend { weight, first: Box::new(first), second: Box::new(second) }, sides)
            }
            "bumpmap" => {
                // (The height field: the adapter's texture, whatever its name.)
                let map = b
                    .children()
                    .filter(|c| matches!(c.tag_name().name(), "texture" | "ref"))
                    .find_map(|c| self.deref(c, depth + 1).ok().filter(|x| x.tag_name().name() == "texture"))
                    .ok_or_else(|| self.err(b, "a bumpmap needs a height texture"))?;
                let scale = self.float(b, "scale", 1.0)?;
                let nm = match self.texture(map)? {
                    ColorTex::Image { tex, to_uv, .. } => NormalMap { tex, scale, to_uv, mitsuba: true, height: true },
                    _ => return Err(self.err(map, "a bumpmap's height must be a bitmap texture")),
                };
                let inner = self.inner_bsdfs(b, depth).into_iter().next().ok_or_else(|| self.err(b, "a bumpmap needs one BSDF inside"))?;
                let read = self.bsdf(inner, depth + 1)?;
                self.normal_map = Some(nm);
                read
            }
            "principled" => (Bsdf::Principled(Box::new(self.principled(b)?)), Sides::Front),
            "mask" => {
                let opacity = self.float_tex(b, "opacity", 0.5)?;
                let inner = self.inner_bsdfs(b, depth).into_iter().next().ok_or_else(|| self.err(b, "a mask needs one BSDF inside"))?;
                let (inner, sides) = self.bsdf(inner, depth + 1)?;
                (Bsdf::Mask { opacity, inner: Box::new(inner) }, sides)
            }
            other => {
                self.warn(b, other, &format!("BSDF '{other}' is not supported; a diffuse one of its base colour (or 0.5) instead"));
                let base = self.color_tex(b, "base_color", Vec3::splat(0.5)).unwrap_or(ColorTex::grey(0.5));
                (Bsdf::Diffuse { reflectance: base }, Sides::Front)
            }
        })
    }

    /// A `<transform>`'s matrix: each operation applied after the ones before it.
    fn transform(&self, t: Node<'a, 'd>) -> R<Affine3A> {
        let mut m = Affine3A::IDENTITY;
        for op in t.children().filter(Node::is_element) {
            let step = match op.tag_name().name() {
                "translate" => Affine3A::from_translation(self.xyz(op, Vec3::ZERO)?),
                "scale" => {
                    let s = match op.attribute("value") {
                        Some(v) => {
                            let v = self.numbers(op, &self.subst(op, v)?)?;
                            match v.as_slice() {
                                [x] => Vec3::splat(*x),
                                [x, y, z] => Vec3::new(*x, *y, *z),
                                _ => return Err(self.err(op, "scale needs one or three numbers")),
                            }
                        }
                        None => self.xyz(op, Vec3::ONE)?,
                    };
                    Affine3A::from_scale(s)
                }
                "rotate" => {
                    let axis = self.xyz(op, Vec3::ZERO)?;
                    let angle = self.number(op, &self.attr(op, "angle")?)?;
                    let axis = axis.normalize_or_zero();
                    if axis == Vec3::ZERO {
                        return Err(self.err(op, "rotate needs a non-zero axis"));
                    }
                    Affine3A::from_axis_angle(axis, angle.to_radians())
                }
                "matrix" => {
                    let v = self.numbers(op, &self.attr(op, "value")?)?;
                    match v.len() {
                        16 => {
                            // Row-major, as written.
                            let m4 = Mat4::from_cols_array(&v.try_into().unwrap_or([0.0; 16])).transpose();
                            Affine3A::from_mat4(m4)
                        }
                        9 => Affine3A::from_mat3(Mat3::from_cols_array(&v.try_into().unwrap_or([0.0; 9])).transpose()),
                        n => return Err(self.err(op, format!("matrix needs 16 (or 9) numbers, found {n}"))),
                    }
                }
                "lookat" => {
                    let o = self.vec_attr(op, "origin")?;
                    let target = self.vec_attr(op, "target")?;
                    let up = match op.attribute("up") {
                        Some(_) => self.vec_attr(op, "up")?,
                        None => Vec3::Y,
                    };
                    let dir = (target - o).normalize_or_zero();
                    let mut left = up.normalize_or_zero().cross(dir).normalize_or_zero();
                    if dir == Vec3::ZERO {
                        return Err(self.err(op, "lookat: origin and target are the same point"));
                    }
                    if left == Vec3::ZERO {
                        left = dir.any_orthonormal_vector();
                    }
                    let new_up = dir.cross(left);
                    Affine3A::from_cols(left.into(), new_up.into(), dir.into(), o.into())
                }
                other => {
                    return Err(self.err(op, format!("unknown transform '{other}' (expected translate, rotate, scale, matrix or lookat)")))
                }
            };
            m = step * m;
        }
        if !m.is_finite() {
            return Err(self.err(t, "the transform is not finite"));
        }
        Ok(m)
    }

    fn vec_attr(&self, n: Node, key: &str) -> R<Vec3> {
        let v = self.numbers(n, &self.attr(n, key)?)?;
        match v.as_slice() {
            [x, y, z] => Ok(Vec3::new(*x, *y, *z)),
            _ => Err(self.err(n, format!("'{key}' needs three numbers"))),
        }
    }

    fn to_world(&self, plugin: Node<'a, 'd>) -> R<Affine3A> {
        match self.prop(plugin, "to_world") {
            Some(t) => self.transform(t),
            None => Ok(Affine3A::IDENTITY),
        }
    }

    fn integrator(&mut self, n: Node<'a, 'd>) -> R<()> {
        let kind = self.attr(n, "type")?;
        match kind.as_str() {
            "path" | "direct" => {
                let d = self.integer(n, "max_depth", if kind == "direct" { 2 } else { -1 })?;
                self.hints.max_depth = if d < 0 { None } else { Some(d.min(i64::from(u32::MAX)) as u32) };
                self.hints.rr_depth = self.integer(n, "rr_depth", 5)?.clamp(1, i64::from(u32::MAX)) as u32;
                self.hints.hide_emitters = self.boolean(n, "hide_emitters", false)?;
                if kind == "direct" {
                    // One bounce of direct light: the path tracer's with max_depth 2, and
                    // the strategies the sample counts name.
                    let (e, b) = (self.integer(n, "emitter_samples", 1)?, self.integer(n, "bsdf_samples", 1)?);
                    if e < 0 || b < 0 {
                        return Err(self.err(n, format!("emitter_samples {e}, bsdf_samples {b}: expected counts of 0 or more")));
                    }
                    self.hints.strategies = match (e, b) {
                        (0, 0) => {
                            self.hints.max_depth = Some(1);
                            crate::model::Strategies::Both
                        }
                        (0, _) => crate::model::Strategies::Bsdf,
                        (_, 0) => crate::model::Strategies::Emitters,
                        _ => crate::model::Strategies::Both,
                    };
                    if e > 1 || b > 1 {
                        self.warn(
                            n,
                            "direct samples",
                            "the 'direct' integrator takes one sample of each strategy per path sample (its image is the same, its noise higher than with several)",
                        );
                    }
                }
            }
            "aov" => {
                let spec = self.string(n, "aovs")?.unwrap_or_default();
                let mut aovs = Vec::new();
                for item in spec.split(',').map(str::trim).filter(|t| !t.is_empty()) {
                    let Some((name, kind)) = item.split_once(':').filter(|(a, b)| !a.is_empty() && !b.is_empty()) else {
                        return Err(self.err(n, format!("AOV '{item}': expected <name>:<type>")));
                    };
                    match (AovKind::named(kind), kind) {
                        (Some(k), _) => aovs.push((name.to_string(), k)),
                        (None, "duv_dx" | "duv_dy" | "boundary_test") => self.warn(
                            n,
                            &format!("aov {kind}"),
                            &format!("the AOV type '{kind}' is not supported: its layer '{name}' is left out"),
                        ),
                        (None, _) => {
                            return Err(self.err(
                                n,
                                format!(
                                    "AOV type '{kind}': expected albedo, depth, position, uv, geo_normal, sh_normal, dp_du, dp_dv, prim_index or shape_index"
                                ),
                            ))
                        }
                    }
                }
                let inner = n.children().find(|c| c.tag_name().name() == "integrator");
                let name = inner.map(|c| c.attribute("name").unwrap_or("image").to_string());
                self.aov = Some((name, aovs));
                if let Some(inner) = inner {
                    return self.integrator(inner);
                }
            }
            other => {
                // A wrapper (moment, ...) around a path tracer: read the inner one.
                if let Some(inner) = n.children().find(|c| c.tag_name().name() == "integrator") {
                    return self.integrator(inner);
                }
                self.warn(n, &format!("integrator {other}"), &format!("integrator '{other}' is not supported; the path tracer instead"));
            }
        }
        Ok(())
    }

    fn sensor(&mut self, n: Node<'a, 'd>) -> R<()> {
        let kind = self.attr(n, "type")?;
        if let Some(film) = n.children().find(|c| c.tag_name().name() == "film") {
            let w = self.integer(film, "width", 768)?;
            let h = self.integer(film, "height", 576)?;
            if !(1..=65536).contains(&w) || !(1..=65536).contains(&h) {
                return Err(self.err(film, format!("film size {w}x{h}: expected 1 to 65536 pixels a side")));
            }
            (self.hints.width, self.hints.height) = (w as u32, h as u32);
            // The crop window (inside the film; the whole film when it names none).
            let (cx, cy) = (self.integer(film, "crop_offset_x", 0)?, self.integer(film, "crop_offset_y", 0)?);
            let (cw, ch) = (self.integer(film, "crop_width", w - cx)?, self.integer(film, "crop_height", h - cy)?);
            if cx < 0 || cy < 0 || cw < 1 || ch < 1 || cx + cw > w || cy + ch > h {
                return Err(self.err(film, format!("crop window {cw}x{ch} at ({cx}, {cy}): expected inside the {w}x{h} film")));
            }
            self.hints.crop = ((cx, cy, cw, ch) != (0, 0, w, h)).then_some([cx as u32, cy as u32, cw as u32, ch as u32]);
            // Its channels: an alpha channel after R, G, B when the format has one.
            self.film_alpha = match self.string(film, "pixel_format")?.as_deref() {
                None | Some("rgb") => false,
                Some("rgba") => true,
                Some(f @ ("luminance" | "xyz")) => {
                    self.warn(film, &format!("pixel_format {f}"), &format!("pixel_format '{f}' is not supported: R, G, B instead"));
                    false
                }
                Some(f @ ("luminance_alpha" | "xyza")) => {
                    self.warn(film, &format!("pixel_format {f}"), &format!("pixel_format '{f}' is not supported: R, G, B, A instead"));
                    true
                }
                Some(f) => {
                    return Err(self.err(film, format!("pixel_format '{f}': expected rgb, rgba, luminance, luminance_alpha, xyz or xyza")))
                }
            };
            // The film's reconstruction filter, Mitsuba's Gaussian when it names none.
            self.hints.filter = match film.children().find(|c| c.tag_name().name() == "rfilter") {
                Some(f) => {
                    let f = self.deref(f, 0)?;
                    match self.attr(f, "type")?.as_str() {
                        "box" => PixelFilter::Box,
                        "tent" => PixelFilter::Tent { radius: self.positive(f, "radius", 1.0)? },
                        "gaussian" => PixelFilter::Gaussian { stddev: self.positive(f, "stddev", 0.5)? },
                        "mitchell" => {
                            let (b, c) = (self.float(f, "B", 1.0 / 3.0)?, self.float(f, "C", 1.0 / 3.0)?);
                            if !(b.abs() < 16.0 && c.abs() < 16.0) {
                                return Err(self.err(f, format!("mitchell B {b}, C {c}: expected finite values below 16")));
                            }
                            PixelFilter::Mitchell { b, c }
                        }
                        "catmullrom" => PixelFilter::Mitchell { b: 0.0, c: 0.5 },
                        "lanczos" => {
                            let lobes = self.integer(f, "lobes", 3)?;
                            if !(1..=16).contains(&lobes) {
                                return Err(self.err(f, format!("lanczos lobes {lobes}: expected 1 to 16")));
                            }
                            PixelFilter::Lanczos { lobes: lobes as f32 }
                        }
                        other => {
                            self.warn(
                                f,
                                "rfilter",
                                &format!(
                                    "rfilter '{other}' is not supported (box, tent, gaussian, mitchell, catmullrom, lanczos are); a Gaussian of σ 0.5 instead"
                                ),
                            );
                            PixelFilter::Gaussian { stddev: 0.5 }
                        }
                    }
                }
                None => PixelFilter::Gaussian { stddev: 0.5 },
            };
        }
        if let Some(s) = n.children().find(|c| c.tag_name().name() == "sampler") {
            let c = self.integer(s, "sample_count", 4)?;
            if !(1..=1 << 24).contains(&c) {
                return Err(self.err(s, format!("sample_count {c}: expected 1 to 2^24")));
            }
            self.hints.spp = c as u32;
        }
        let m = self.to_world(n)?;
        let eye: Vec3 = m.transform_point3(Vec3::ZERO);
        let fwd = m.transform_vector3(Vec3::Z).normalize_or_zero();
        let up = m.transform_vector3(Vec3::Y).normalize_or_zero();
        if fwd == Vec3::ZERO || up == Vec3::ZERO {
            return Err(self.err(n, "the sensor's to_world is singular"));
        }
        if m.matrix3.determinant() < 0.0 {
            self.warn(n, "mirror", "the sensor's to_world mirrors the image; lucent renders it unmirrored");
        }
        let near = self.float(n, "near_clip", 0.01)?;
        let far = self.float(n, "far_clip", 10000.0)?;
        if !(near >= 0.0 && far > near) {
            return Err(self.err(n, format!("clips {near}..{far}: expected 0 ≤ near < far")));
        }
        self.hints.clip = (near, far);
        let aspect = self.hints.width as f32 / self.hints.height as f32;
        let mut desc = CameraDesc { eye, look_at: eye + fwd, up, vfov_deg: 45.0, ortho_height: None };
        match kind.as_str() {
            "perspective" | "thinlens" => {
                // Mitsuba's `fov` is along `fov_axis` (x by default); a focal length is
                // for a 36 × 24 mm film, along its diagonal.
                let (fov, axis) = match (self.prop(n, "fov"), self.string(n, "focal_length")?) {
                    (Some(_), _) => (self.float(n, "fov", 45.0)?, self.string(n, "fov_axis")?.unwrap_or_else(|| "x".into())),
                    (None, f) => {
                        let f = f.unwrap_or_else(|| "50mm".into());
                        let mm = self.number(n, f.trim().trim_end_matches("mm"))?;
                        (2.0 * (36f32.hypot(24.0) / (2.0 * mm)).atan().to_degrees(), "diagonal".into())
                    }
                };
                if !(fov > 0.0 && fov < 180.0) {
                    return Err(self.err(n, format!("fov {fov}: expected between 0 and 180 degrees")));
                }
                let t = (fov.to_radians() * 0.5).tan();
                let tan_v = match axis.as_str() {
                    "x" => t / aspect,
                    "y" => t,
                    "diagonal" => t / (1.0 + aspect * aspect).sqrt(),
                    "smaller" => {
                        if aspect > 1.0 {
                            t
                        } else {
                            t / aspect
                        }
                    }
                    "larger" => {
                        if aspect > 1.0 {
                            t / aspect
                        } else {
                            t
                        }
                    }
                    a => return Err(self.err(n, format!("fov_axis '{a}': expected x, y, diagonal, smaller or larger"))),
                };
                desc.vfov_deg = (2.0 * tan_v.atan()).to_degrees();
                if kind == "thinlens" {
                    let r = self.float(n, "aperture_radius", 0.0)?;
                    let f = self.float(n, "focus_distance", 0.0)?;
                    self.hints.lens = Some((r, f));
                }
            }
            "orthographic" => {
                // Mitsuba's orthographic view is [-1, 1]² scaled by to_world.
                desc.ortho_height = Some(2.0 * m.matrix3.y_axis.length());
            }
            other => {
                self.warn(
                    n,
                    &format!("sensor {other}"),
                    &format!("sensor '{other}' is not supported; a perspective camera of 45° instead"),
                );
            }
        }
        self.scene.camera = Some(desc);
        Ok(())
    }

    fn material_index(&mut self, name: &str, bsdf: ReadBsdf, emission: Vec3) -> u32 {
        let mut m = Material::physical(name, bsdf.0);
        m.sides = bsdf.1;
        m.normal_map = self.normal_map.take();
        m.emission = emission;
        m.alpha = Alpha::Opaque;
        self.scene.materials.push(m);
        (self.scene.materials.len() - 1) as u32
    }

    fn push_instance(&mut self, n: Node, geom: Geom, m: Affine3A) -> R<()> {
        self.shapes += 1;
        if self.shapes > MAX_SHAPES {
            return Err(self.err(n, format!("more than {MAX_SHAPES} shapes")));
        }
        self.scene.instances.push(Instance { geom, world_from_object: m });
        Ok(())
    }

    /// A shape's geometry (one or more pieces, each with its object-to-world transform);
    /// `None` for a shape group (remembered for instances) or what is left out.
    fn shape(&mut self, n: Node<'a, 'd>, depth: u32) -> R<Option<Vec<(Geom, Affine3A)>>> {
        let kind = self.attr(n, "type")?;
        if kind == "shapegroup" {
            let id = self.attr(n, "id")?;
            if depth > 0 {
                return Err(self.err(n, "a shapegroup cannot be inside another"));
            }
            let mut items = Vec::new();
            for c in n.children().filter(|c| c.tag_name().name() == "shape") {
                if let Some(v) = self.shape(c, depth + 1)? {
                    items.extend(v);
                }
            }
            self.groups.insert(id, items);
            return Ok(None);
        }
        if kind == "instance" {
            let r = n
                .children()
                .find(|c| c.tag_name().name() == "ref")
                .ok_or_else(|| self.err(n, "an instance needs a <ref id=...> to a shapegroup"))?;
            let id = self.attr(r, "id")?;
            if !self.groups.contains_key(&id) {
                // (Defined later in the file: read it now.)
                if let Some(g) = self.ids.get(&id).and_then(|&i| self.node(i)).filter(|g| g.attribute("type") == Some("shapegroup")) {
                    self.shape(g, 0)?;
                }
            }
            let m = self.to_world(n)?;
            let group = self.groups.get(&id).ok_or_else(|| self.err(r, format!("'{id}' is not a shapegroup")))?;
            return Ok(Some(group.iter().map(|&(g, local)| (g, m * local)).collect()));
        }
        // The material: a BSDF child (or ref to one) and an area emitter.
        self.normal_map = None;
        let mut bsdf = None;
        let mut emission = Vec3::ZERO;
        for c in n.children().filter(Node::is_element) {
            match c.tag_name().name() {
                "bsdf" => bsdf = Some(self.bsdf(c, 0)?),
                "ref" => {
                    let t = self.deref(c, 0)?;
                    match t.tag_name().name() {
                        "bsdf" => bsdf = Some(self.bsdf(t, 1)?),
                        "emitter" => self.emitter(t, Some(&mut emission))?,
                        _ => {}
                    }
                }
                "emitter" => self.emitter(c, Some(&mut emission))?,
                _ => {}
            }
        }
        // (Mitsuba's default BSDF: diffuse, of reflectance 0.5, or 0 on an emitter.)
        let default = if emission.max_element() > 0.0 { 0.0 } else { 0.5 };
        let bsdf = bsdf.unwrap_or((Bsdf::Diffuse { reflectance: ColorTex::grey(default) }, Sides::Front));
        let name = n.attribute("id").unwrap_or(&kind).to_string();
        let mat = self.material_index(&name, bsdf, emission);
        let m = self.to_world(n)?;
        let flip = self.boolean(n, "flip_normals", false)?;
        let geom = match kind.as_str() {
            "obj" | "ply" | "serialized" => {
                let file = self.string(n, "filename")?.ok_or_else(|| self.err(n, format!("a '{kind}' shape needs a 'filename'")))?;
                let path = self.find(n, &file);
                self.regular_file(n, &path)?;
                let mut face_normals = self.boolean(n, "face_normals", false)?;
                let index = match kind.as_str() {
                    "serialized" => u32::try_from(self.integer(n, "shape_index", 0)?)
                        .map_err(|_| self.err(n, "shape_index must be 0 or more (and below 2^32)"))?,
                    _ => 0,
                };
                let key = (path.clone(), index, mat, face_normals, flip);
                let mesh = match self.meshes.get(&key) {
                    Some(&i) => i,
                    None => {
                        let failed = |e: &dyn std::fmt::Display| self.err(n, format!("{}: {e}", path.display()));
                        let mut mesh = match kind.as_str() {
                            "serialized" => {
                                let bytes = std::fs::read(&path).map_err(|e| failed(&e))?;
                                let m = serialized::parse_serialized(&bytes, index).map_err(|e| failed(&e))?;
                                face_normals |= m.face_normals;
                                serialized_mesh(m, mat)
                            }
                            "obj" => {
                                let mut mesh = merge_meshes(&crate::obj::load_obj(&path).map_err(|e| failed(&e))?, mat);
                                // (Mitsuba's OBJ reader turns v over; its other shapes keep it.)
                                for uv in &mut mesh.uvs.values {
                                    uv.y = 1.0 - uv.y;
                                }
                                mesh
                            }
                            _ => merge_meshes(&crate::ply::load_ply(&path).map_err(|e| failed(&e))?, mat),
                        };
                        if face_normals {
                            mesh.normals = Default::default();
                        } else if mesh.normals.values.is_empty() {
                            // As Mitsuba: a mesh without normals gets smooth ones.
                            mesh.normals =
                                crate::model::Attr { values: angle_weighted_normals(&mesh.positions, &mesh.indices), indices: None };
                        }
                        if flip {
                            flip_mesh(&mut mesh);
                        }
                        self.scene.meshes.push(mesh);
                        let i = (self.scene.meshes.len() - 1) as u32;
                        self.meshes.insert(key, i);
                        i
                    }
                };
                return Ok(Some(vec![(Geom::Mesh(mesh), m)]));
            }
            "rectangle" | "cube" => {
                let mut mesh = if kind == "cube" { cube(mat) } else { rectangle(mat) };
                if flip {
                    flip_mesh(&mut mesh);
                }
                self.scene.meshes.push(mesh);
                Geom::Mesh((self.scene.meshes.len() - 1) as u32)
            }
            "sphere" => {
                let c = self.point(n, "center", Vec3::ZERO)?;
                let r = self.float(n, "radius", 1.0)?;
                if flip {
                    self.warn(n, "flip sphere", "flip_normals on a sphere is not supported");
                }
                return Ok(Some(vec![(
                    Geom::Shape { kind: ShapeKind::Sphere, material: mat },
                    m * Affine3A::from_scale_rotation_translation(Vec3::splat(r), glam::Quat::IDENTITY, c),
                )]));
            }
            "disk" => {
                let local = if flip { Affine3A::from_scale(Vec3::new(1.0, -1.0, -1.0)) } else { Affine3A::IDENTITY };
                return Ok(Some(vec![(Geom::Shape { kind: ShapeKind::Disk, material: mat }, m * local)]));
            }
            "cylinder" => {
                let p0 = self.point(n, "p0", Vec3::ZERO)?;
                let p1 = self.point(n, "p1", Vec3::Z)?;
                let r = self.float(n, "radius", 1.0)?;
                let axis = p1 - p0;
                let len = axis.length();
                if !(len > 0.0 && r > 0.0) {
                    return Err(self.err(n, "a cylinder needs p0 ≠ p1 and a positive radius"));
                }
                let rot = glam::Quat::from_rotation_arc(Vec3::Z, axis / len);
                // lucent's tube spans z in [-1, 1]: moved to [0, 1], then along p0 → p1.
                let local = Affine3A::from_scale_rotation_translation(Vec3::new(r, r, len * 0.5), rot, p0 + axis * 0.5);
                return Ok(Some(vec![(Geom::Shape { kind: ShapeKind::Tube, material: mat }, m * local)]));
            }
            other => {
                self.warn(n, &format!("shape {other}"), &format!("shape '{other}' is not supported; left out"));
                return Ok(None);
            }
        };
        Ok(Some(vec![(geom, m)]))
    }

    /// An emitter: `area` adds to `emission` (inside a shape); the others become lights.
    fn emitter(&mut self, n: Node<'a, 'd>, emission: Option<&mut Vec3>) -> R<()> {
        let kind = self.attr(n, "type")?;
        // `sampling_weight`: how often Mitsuba's light sampling picks the emitter. lucent
        // picks lights by what each can send to the point, which the weight does not
        // change (the image is the same); a weight of zero on a point, spot or directional
        // light, which only light sampling reaches, leaves it dark in Mitsuba's image, and
        // so out of lucent's.
        let weight = self.float(n, "sampling_weight", 1.0)?;
        if !(weight >= 0.0 && weight.is_finite()) {
            return Err(self.err(n, format!("sampling_weight {weight}: expected 0 or more")));
        }
        if weight == 0.0 && matches!(kind.as_str(), "point" | "spot" | "directional") {
            return Ok(());
        }
        match (kind.as_str(), emission) {
            ("area", Some(e)) => *e = self.color(n, "radiance", Vec3::ONE)?,
            ("area", None) => return Err(self.err(n, "an area emitter belongs inside a <shape>")),
            ("point", _) => {
                let m = self.to_world(n)?;
                let position = match self.prop(n, "position") {
                    Some(p) => self.xyz(p, Vec3::ZERO)?,
                    None => m.transform_point3(Vec3::ZERO),
                };
                let color = self.color(n, "intensity", Vec3::ONE)?;
                self.scene.lights.push(Light { kind: LightKind::Point { position }, color, inverse_square: true });
            }
            ("spot", _) => {
                if self.prop(n, "texture").is_some() {
                    self.warn(n, "spot texture", "a spot light's projected 'texture' is not supported; its intensity alone is used");
                }
                let m = self.to_world(n)?;
                let cutoff = self.float(n, "cutoff_angle", 20.0)?;
                let beam = self.float(n, "beam_width", cutoff * 0.75)?;
                let color = self.color(n, "intensity", Vec3::ONE)?;
                let direction = m.transform_vector3(Vec3::Z).normalize_or(Vec3::Z);
                self.scene.lights.push(Light {
                    kind: LightKind::Spot {
                        position: m.transform_point3(Vec3::ZERO),
                        direction,
                        inner: beam.to_radians(),
                        outer: cutoff.to_radians(),
                    },
                    color,
                    inverse_square: true,
                });
            }
            ("directional", _) => {
                let m = self.to_world(n)?;
                let direction = match self.prop(n, "direction") {
                    Some(p) => self.xyz(p, Vec3::Z)?,
                    None => m.transform_vector3(Vec3::Z),
                }
                .normalize_or_zero();
                if direction == Vec3::ZERO {
                    return Err(self.err(n, "a directional emitter needs a direction"));
                }
                let color = self.color(n, "irradiance", Vec3::ONE)?;
                self.scene.lights.push(Light { kind: LightKind::Directional { direction }, color, inverse_square: false });
            }
            ("constant", _) => {
                let scale = self.color(n, "radiance", Vec3::ONE)?;
                self.scene.environment = Some(Environment { scale, image: None, to_world: Affine3A::IDENTITY });
            }
            ("envmap", _) => {
                let file = self.string(n, "filename")?.ok_or_else(|| self.err(n, "an envmap needs a 'filename'"))?;
                let path = self.find(n, &file);
                self.regular_file(n, &path)?;
                let scale = self.float(n, "scale", 1.0)?;
                let to_world = self.to_world(n)?;
                let image = load_hdr(&path).map_err(|e| self.err(n, format!("{}: {e}", path.display())))?;
                if image.width < 2 || image.height < 3 {
                    return Err(self.err(n, "the environment map must be at least 2 × 3 pixels (as Mitsuba's)"));
                }
                self.scene.environment = Some(Environment { scale: Vec3::splat(scale), image: Some(Arc::new(image)), to_world });
            }
            (other, _) => self.warn(n, &format!("emitter {other}"), &format!("emitter '{other}' is not supported; left out")),
        }
        Ok(())
    }
}

/// All meshes of a loaded file as one, every triangle of material `mat`, placed by the
/// file's instances (OBJ and PLY files have one identity instance per mesh).
fn merge_meshes(s: &Scene, mat: u32) -> Mesh {
    let mut out = Mesh { name: s.meshes.first().map(|m| m.name.clone()).unwrap_or_default(), ..Mesh::default() };
    let any_normals = s.meshes.iter().any(|m| !m.normals.values.is_empty());
    let any_uvs = s.meshes.iter().any(|m| !m.uvs.values.is_empty());
    for m in &s.meshes {
        let base = out.positions.len() as u32;
        out.positions.extend(&m.positions);
        out.indices.extend(m.indices.iter().map(|t| t.map(|i| i + base)));
        // Per-corner attributes become per-position ones, corner by corner.
        let n = m.indices.len();
        if any_normals {
            // (Zero normals where a mesh has none: the shading normal is then the face's.)
            let ni = out.normals.indices.get_or_insert_with(Vec::new);
            for (t, idx) in m.indices.iter().enumerate() {
                let c = m.normals.corners(t, idx).unwrap_or([Vec3::ZERO; 3]);
                let k = out.normals.values.len() as u32;
                out.normals.values.extend(c);
                ni.push([k, k + 1, k + 2]);
            }
        }
        if any_uvs {
            let ui = out.uvs.indices.get_or_insert_with(Vec::new);
            for (t, idx) in m.indices.iter().enumerate() {
                let c = m.uvs.corners(t, idx).unwrap_or([Vec2::ZERO; 3]);
                let k = out.uvs.values.len() as u32;
                out.uvs.values.extend(c);
                ui.push([k, k + 1, k + 2]);
            }
        }
        out.material.extend(std::iter::repeat_n(mat, n));
    }
    out
}

/// A `.serialized` mesh as lucent's, every triangle of material `mat`.
fn serialized_mesh(m: serialized::SerializedMesh, mat: u32) -> Mesh {
    Mesh {
        name: m.name,
        material: vec![mat; m.indices.len()],
        positions: m.positions,
        normals: crate::model::Attr { values: m.normals, indices: None },
        uvs: crate::model::Attr { values: m.uvs, indices: None },
        indices: m.indices,
    }
}

/// Smooth vertex normals, each the sum of its triangles' unit normals weighted by the
/// triangle's angle at the vertex (Thürmer and Wüthrich, "Computing Vertex Normals from
/// Polygonal Facets", 1998, as Mitsuba does for meshes that come without normals).
fn angle_weighted_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; positions.len()];
    for idx in indices {
        let p = idx.map(|i| positions.get(i as usize).copied().unwrap_or(Vec3::NAN));
        let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        if face == Vec3::ZERO || !face.is_finite() {
            continue;
        }
        for k in 0..3 {
            let (a, b) = ((p[(k + 1) % 3] - p[k]).normalize_or_zero(), (p[(k + 2) % 3] - p[k]).normalize_or_zero());
            let angle = a.dot(b).clamp(-1.0, 1.0).acos();
            if let Some(v) = n.get_mut(idx[k] as usize) {
                *v += face * angle;
            }
        }
    }
    for v in &mut n {
        *v = v.normalize_or_zero();
    }
    n
}

/// Turns a mesh inside out: every triangle's winding and every normal reversed.
fn flip_mesh(m: &mut Mesh) {
    for t in &mut m.indices {
        t.swap(1, 2);
    }
    for idx in [m.normals.indices.as_mut(), m.uvs.indices.as_mut()].into_iter().flatten() {
        for t in idx {
            t.swap(1, 2);
        }
    }
    for n in &mut m.normals.values {
        *n = -*n;
    }
}

/// Mitsuba's `rectangle`: [-1, 1]² in z = 0, facing +z, texture coordinates 0..1.
fn rectangle(mat: u32) -> Mesh {
    Mesh {
        name: "rectangle".into(),
        positions: vec![Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)],
        indices: vec![[0, 1, 2], [2, 3, 0]],
        uvs: crate::model::Attr {
            values: vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)],
            indices: None,
        },
        material: vec![mat; 2],
        ..Mesh::default()
    }
}

/// Mitsuba's `cube`: [-1, 1]³, faces wound outward, each with texture coordinates 0..1,
/// laid out as Mitsuba's `cube` plugin lays them (its corner order, so that texture
/// coordinates, ∂p/∂u and triangle indices are Mitsuba's): the faces −y, +y, +x, +z, −x,
/// −z, each two triangles (0, 1, 2) and (3, 0, 2) of corners with coordinates (0, 1),
/// (1, 1), (1, 0), (0, 0).
fn cube(mat: u32) -> Mesh {
    // (Per face, its corners: x, y, z signs.)
    const FACES: [[[f32; 3]; 4]; 6] = [
        [[1.0, -1.0, -1.0], [1.0, -1.0, 1.0], [-1.0, -1.0, 1.0], [-1.0, -1.0, -1.0]],
        [[1.0, 1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, 1.0, 1.0], [1.0, 1.0, 1.0]],
        [[1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [1.0, 1.0, 1.0], [1.0, -1.0, 1.0]],
        [[1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0], [-1.0, -1.0, 1.0]],
        [[-1.0, -1.0, 1.0], [-1.0, 1.0, 1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, -1.0]],
        [[1.0, 1.0, -1.0], [1.0, -1.0, -1.0], [-1.0, -1.0, -1.0], [-1.0, 1.0, -1.0]],
    ];
    let mut m = Mesh { name: "cube".into(), ..Mesh::default() };
    for face in FACES {
        let base = m.positions.len() as u32;
        for (corner, uv) in face.iter().zip([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]) {
            m.positions.push(Vec3::from_array(*corner));
            m.uvs.values.push(Vec2::from_array(uv));
        }
        m.indices.push([base, base + 1, base + 2]);
        m.indices.push([base + 3, base, base + 2]);
    }
    m.material = vec![mat; m.indices.len()];
    m
}

/// Reads an environment map: OpenEXR or Radiance HDR as they are (linear), other images
/// from sRGB.
pub fn load_hdr(path: &Path) -> Result<HdrImage, String> {
    let img = image::ImageReader::open(path).map_err(|e| e.to_string())?.with_guessed_format().map_err(|e| e.to_string())?;
    let (w, h) = img.into_dimensions().map_err(|e| e.to_string())?;
    if u64::from(w) * u64::from(h) > crate::texture::MAX_TEXTURE_BYTES / 16
        || w > crate::texture::MAX_TEXTURE_SIDE
        || h > crate::texture::MAX_TEXTURE_SIDE
    {
        return Err(format!("{w} × {h} is larger than lucent reads"));
    }
    let img = image::ImageReader::open(path).map_err(|e| e.to_string())?.with_guessed_format().map_err(|e| e.to_string())?;
    let linear = matches!(img.format(), Some(image::ImageFormat::OpenExr | image::ImageFormat::Hdr));
    let img = img.decode().map_err(|e| e.to_string())?;
    let texels: Vec<Vec3> = if linear {
        img.to_rgb32f().pixels().map(|p| Vec3::from(p.0)).collect()
    } else {
        img.to_rgb8().pixels().map(|p| Vec3::from(p.0.map(|c| crate::texture::srgb_to_linear(f32::from(c) / 255.0)))).collect()
    };
    Ok(HdrImage { width: img.width(), height: img.height(), texels })
}

//! The glTF 2.0 rules that hold between objects (specification §3.6 to §3.11 and the
//! extensions' texts), checked after the schema ([`super::schema`]) and the references
//! ([`Doc::check_references`]): how accessors may be used (indices, attributes, animation
//! inputs, inverse bind matrices; strides, alignment, formats, bounds), attribute names
//! and morph targets, animation targets, skins' joint hierarchies, texture coordinates a
//! material needs, image MIME types, and the references extensions add.
//!
//! What is checked here is what the Khronos validator reports as an error. Checks of the
//! data itself (declared bounds against the values, unit normals, weights) are in
//! [`Doc::check_data`].

use super::json::{Doc, R};
use super::pointer::{as_uint, esc, known_layout, ptr, UNIT_TOLERANCE};
use serde_json::Value;
use std::collections::{HashMap, HashSet};

/// How a buffer view is used (a view holds one kind of data).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Usage {
    Vertex,
    Index,
    Other,
}

/// `TEXCOORD_3` → `("TEXCOORD", Some(3))`; a name without an index → `(name, None)`;
/// `None` when the index is malformed (`TEXCOORD_03`, `TEXCOORD_`).
fn semantic(name: &str) -> Option<(&str, Option<u64>)> {
    match name.rsplit_once('_') {
        Some((base, n)) if ["TEXCOORD", "COLOR", "JOINTS", "WEIGHTS"].contains(&base) => {
            let ok = !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) && (n == "0" || !n.starts_with('0'));
            ok.then(|| (base, n.parse().ok())).filter(|(_, i)| i.is_some())
        }
        _ => Some((name, None)),
    }
}

impl Doc<'_> {
    fn get_index(&self, v: &Value, key: &str) -> Option<usize> {
        v.get(key).and_then(as_uint).map(|i| i as usize)
    }

    fn accessor_json(&self, i: usize) -> Option<&Value> {
        self.root.get("accessors")?.as_array()?.get(i)
    }

    /// The buffer view of accessor `i`, with its JSON.
    fn view_of(&self, i: usize) -> Option<(usize, &Value)> {
        let v = self.get_index(self.accessor_json(i)?, "bufferView")?;
        Some((v, self.root.get("bufferViews")?.as_array()?.get(v)?))
    }

    fn strided(&self, accessor: usize) -> bool {
        self.view_of(accessor).is_some_and(|(_, v)| v.get("byteStride").is_some())
    }

    /// `(componentType, type)` of accessor `i`.
    fn format(&self, i: usize) -> (u64, &str) {
        let a = self.accessor_json(i);
        (
            a.and_then(|a| a.get("componentType")).and_then(as_uint).unwrap_or(0),
            a.and_then(|a| a.get("type")).and_then(Value::as_str).unwrap_or(""),
        )
    }

    fn count(&self, i: usize) -> u64 {
        self.accessor_json(i).and_then(|a| a.get("count")).and_then(as_uint).unwrap_or(0)
    }

    fn has_bounds(&self, i: usize) -> bool {
        self.accessor_json(i).is_some_and(|a| a.get("min").is_some() && a.get("max").is_some())
    }

    /// Attribute `name` (at `here`) parsed as `(semantic, index, whether glTF defines it)`:
    /// a glTF semantic, indexed (`TEXCOORD_0`) or not (`POSITION`) as the specification
    /// says, or a custom one beginning with '_'. A morph `target` allows only the
    /// semantics a target can change.
    fn attribute<'n>(&self, name: &'n str, target: bool, here: &str) -> R<(&'n str, Option<u64>, bool)> {
        let bad = |why: &str| Err(self.err(here, format!("{name:?} {why}")));
        let Some((base, index)) = semantic(name) else { return bad("is not a valid attribute name") };
        let semantics: &[&str] = if target {
            &["POSITION", "NORMAL", "TANGENT", "TEXCOORD", "COLOR"]
        } else {
            &["POSITION", "NORMAL", "TANGENT", "TEXCOORD", "COLOR", "JOINTS", "WEIGHTS"]
        };
        let known = semantics.contains(&base);
        let unindexed = ["POSITION", "NORMAL", "TANGENT"].contains(&base);
        match (known, target) {
            (false, _) if base.starts_with('_') => Ok((base, index, false)),
            (true, _) if index.is_none() == unindexed => Ok((base, index, true)),
            (_, true) => bad("is not a morph target attribute"),
            (false, false) => bad("is not a glTF attribute (custom ones begin with '_')"),
            (true, false) => bad("is not a valid attribute name"),
        }
    }

    /// Every rule of this module; the first broken one is the error.
    pub fn check_rules(&self) -> R<()> {
        self.check_accessors()?;
        let usage = self.check_meshes()?;
        self.check_views(&usage)?;
        self.check_nodes()?;
        self.check_animations()?;
        self.check_skins()?;
        self.check_images()?;
        self.check_extension_references()
    }

    fn check_accessors(&self) -> R<()> {
        for (i, a) in self.items("accessors")?.iter().enumerate() {
            let at = ptr(&[&"accessors", &i]);
            let (comp, _) = self.format(i);
            if a.get("normalized").and_then(Value::as_bool) == Some(true) && ![5120, 5121, 5122, 5123].contains(&comp) {
                return Err(self.err(&format!("{at}/normalized"), "only (unsigned) byte and short accessors can be normalized"));
            }
            if let Some(s) = a.get("sparse") {
                let n = s.get("count").and_then(as_uint).unwrap_or(0);
                if n > self.count(i) {
                    return Err(
                        self.err(&format!("{at}/sparse/count"), format!("{n} sparse elements, more than the accessor's {}", self.count(i)))
                    );
                }
                for part in ["indices", "values"] {
                    let view = s.pointer(&format!("/{part}/bufferView")).and_then(as_uint);
                    let strided =
                        view.and_then(|v| self.root.get("bufferViews")?.get(v as usize)).is_some_and(|v| v.get("byteStride").is_some());
                    if strided {
                        return Err(
                            self.err(&format!("{at}/sparse/{part}/bufferView"), "a sparse accessor's buffer views cannot have byteStride")
                        );
                    }
                }
            }
        }
        Ok(())
    }

    /// Mesh rules; returns how each buffer view is used, with where it was first used.
    fn check_meshes(&self) -> R<HashMap<usize, (Usage, String)>> {
        let mut usage: HashMap<usize, (Usage, String)> = HashMap::new();
        let mut use_view = |doc: &Self, accessor: usize, u: Usage, at: &str| -> R<()> {
            let Some((v, _)) = doc.view_of(accessor) else { return Ok(()) };
            match usage.get(&v) {
                Some((prev, _)) if *prev != u => {
                    Err(doc.err(at, format!("buffer view {v} is used as {u:?} data here and as {prev:?} data elsewhere")))
                }
                Some(_) => Ok(()),
                None => {
                    usage.insert(v, (u, at.to_string()));
                    Ok(())
                }
            }
        };
        let materials = self.items("materials")?;
        for (mi, m) in self.items("meshes")?.iter().enumerate() {
            let prims = self.list(m, "primitives", &ptr(&[&"meshes", &mi]))?;
            let targets_of = |p: &Value| p.get("targets").and_then(Value::as_array).map_or(0, Vec::len);
            let n_targets = prims.first().map_or(0, targets_of);
            if let Some(w) = m.get("weights").and_then(Value::as_array) {
                if w.len() != n_targets {
                    return Err(self.err(&ptr(&[&"meshes", &mi, &"weights"]), format!("{} weights for {n_targets} morph targets", w.len())));
                }
            }
            for (pi, p) in prims.iter().enumerate() {
                let at = ptr(&[&"meshes", &mi, &"primitives", &pi]);
                if targets_of(p) != n_targets {
                    return Err(self.err(&format!("{at}/targets"), "every primitive of a mesh needs the same number of morph targets"));
                }
                let Some(attrs) = p.get("attributes").and_then(Value::as_object) else { continue };
                let mut sets: HashMap<&str, Vec<u64>> = HashMap::new();
                let mut count = None;
                let mut views_used: HashMap<usize, HashSet<usize>> = HashMap::new();
                for (name, acc) in attrs {
                    let here = format!("{at}/attributes/{}", esc(name));
                    let Some(acc) = as_uint(acc).map(|a| a as usize) else { continue };
                    let (base, index, known) = self.attribute(name, false, &here)?;
                    if let Some(n) = index {
                        sets.entry(base).or_default().push(n);
                    }
                    let c = self.count(acc);
                    if *count.get_or_insert(c) != c {
                        return Err(self.err(&here, "all attribute accessors of a primitive need the same count"));
                    }
                    if self.format(acc).0 == 5125 {
                        return Err(self.err(&here, "attribute accessors cannot be unsigned int"));
                    }
                    if known {
                        if let Some((v, view)) = self.view_of(acc) {
                            let offset = self.accessor_json(acc).and_then(|a| a.get("byteOffset")).and_then(as_uint).unwrap_or(0)
                                + view.get("byteOffset").and_then(as_uint).unwrap_or(0);
                            let stride = view.get("byteStride").and_then(as_uint).unwrap_or(0);
                            if !offset.is_multiple_of(4) || !stride.is_multiple_of(4) {
                                return Err(self.err(&here, "vertex attribute data must be aligned to 4 bytes"));
                            }
                            let users = views_used.entry(v).or_default();
                            users.insert(acc);
                            if users.len() > 1 && view.get("byteStride").is_none() {
                                return Err(self.err(&here, format!("buffer view {v} holds several accessors and needs byteStride")));
                            }
                        }
                    }
                    if base == "POSITION" && !self.has_bounds(acc) {
                        return Err(self.err(&here, "a POSITION accessor needs min and max"));
                    }
                    use_view(self, acc, Usage::Vertex, &here)?;
                }
                for (base, ns) in &mut sets {
                    ns.sort_unstable();
                    if ns.iter().enumerate().any(|(k, &n)| n != k as u64) {
                        return Err(self
                            .err(&format!("{at}/attributes"), format!("{base}_n attributes must be numbered 0, 1, 2, ... without gaps")));
                    }
                }
                let n = |b: &str| sets.get(b).map_or(0, Vec::len);
                if n("JOINTS") != n("WEIGHTS") {
                    return Err(
                        self.err(&format!("{at}/attributes"), format!("{} JOINTS attributes but {} WEIGHTS", n("JOINTS"), n("WEIGHTS")))
                    );
                }
                if let Some(ti) = self.get_index(p, "indices") {
                    let here = format!("{at}/indices");
                    let (comp, ty) = self.format(ti);
                    if ty != "SCALAR" || ![5121, 5123, 5125].contains(&comp) {
                        return Err(self.err(&here, "indices must be SCALAR unsigned byte, short or int"));
                    }
                    if self.strided(ti) {
                        return Err(self.err(&here, "an indices accessor's buffer view cannot have byteStride"));
                    }
                    use_view(self, ti, Usage::Index, &here)?;
                }
                for (ti, t) in p.get("targets").and_then(Value::as_array).into_iter().flatten().enumerate() {
                    for (name, acc) in t.as_object().into_iter().flatten() {
                        let here = format!("{at}/targets/{ti}/{}", esc(name));
                        let (base, _, _) = self.attribute(name, true, &here)?;
                        if !attrs.contains_key(name) {
                            return Err(self.err(&here, format!("the primitive has no {name} for this target to change")));
                        }
                        if let Some(acc) = as_uint(acc).map(|a| a as usize) {
                            if base == "POSITION" && !self.has_bounds(acc) {
                                return Err(self.err(&here, "a POSITION accessor needs min and max"));
                            }
                            use_view(self, acc, Usage::Vertex, &here)?;
                        }
                    }
                }
                if let Some(mat) = self.get_index(p, "material").and_then(|m| materials.get(m)) {
                    self.check_material_fit(mat, attrs, &format!("{at}/material"))?;
                }
            }
        }
        Ok(usage)
    }

    /// The texture coordinates and tangent space a material needs, against a primitive's
    /// attributes.
    fn check_material_fit(&self, m: &Value, attrs: &serde_json::Map<String, Value>, at: &str) -> R<()> {
        fn walk<'v>(v: &'v Value, path: String, out: &mut Vec<(String, &'v Value)>) {
            if let Some(o) = v.as_object() {
                if o.contains_key("index") && path.ends_with("Texture") {
                    out.push((path.clone(), v));
                }
                for (k, x) in o {
                    walk(x, format!("{path}/{k}"), out);
                }
            }
        }
        let mut textures = Vec::new();
        walk(m, String::new(), &mut textures);
        for (path, t) in textures {
            let set = t.pointer("/extensions/KHR_texture_transform/texCoord").or_else(|| t.get("texCoord")).and_then(as_uint).unwrap_or(0);
            if !attrs.contains_key(&format!("TEXCOORD_{set}")) {
                return Err(self.err(at, format!("the material's texture {path} needs TEXCOORD_{set}, which the primitive lacks")));
            }
        }
        let needs_tangents = m.pointer("/extensions/KHR_materials_anisotropy").is_some()
            || m.pointer("/extensions/KHR_materials_clearcoat/clearcoatNormalTexture").is_some();
        if needs_tangents && !attrs.contains_key("TANGENT") && m.get("normalTexture").is_none() {
            return Err(self.err(at, "the material needs a tangent space: the primitive has no TANGENT and the material no normal map"));
        }
        Ok(())
    }

    fn check_views(&self, usage: &HashMap<usize, (Usage, String)>) -> R<()> {
        for (i, v) in self.items("bufferViews")?.iter().enumerate() {
            let at = ptr(&[&"bufferViews", &i]);
            let stride = v.get("byteStride").and_then(as_uint);
            let len = v.get("byteLength").and_then(as_uint).unwrap_or(0);
            if let Some(s) = stride {
                if s > len {
                    return Err(self.err(&format!("{at}/byteStride"), format!("stride {s} is larger than the view ({len} bytes)")));
                }
                if v.get("target").and_then(as_uint) == Some(34963) {
                    return Err(self.err(&format!("{at}/byteStride"), "an index buffer view cannot have byteStride"));
                }
            }
            let declared = match v.get("target").and_then(as_uint) {
                Some(34962) => Some(Usage::Vertex),
                Some(34963) => Some(Usage::Index),
                _ => None,
            };
            if let (Some(d), Some((u, where_))) = (declared, usage.get(&i)) {
                if d != *u && *u != Usage::Other {
                    return Err(self.err(where_, format!("buffer view {i} is declared {d:?} data but used as {u:?} data")));
                }
            }
        }
        Ok(())
    }

    fn check_nodes(&self) -> R<()> {
        let meshes = self.items("meshes")?;
        for (i, n) in self.items("nodes")?.iter().enumerate() {
            let at = ptr(&[&"nodes", &i]);
            if let Some(m) = n.get("matrix").and_then(Value::as_array) {
                let e: Vec<f64> = m.iter().filter_map(Value::as_f64).collect();
                // Column-major. Translation, rotation and scale make an affine matrix
                // (last row 0 0 0 1) whose 3x3 columns are orthogonal (R times a diagonal).
                let affine = e.len() == 16 && e[3] == 0.0 && e[7] == 0.0 && e[11] == 0.0 && e[15] == 1.0;
                let col = |c: usize| [e[4 * c], e[4 * c + 1], e[4 * c + 2]];
                let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
                let orthogonal = affine
                    && [(0, 1), (0, 2), (1, 2)].iter().all(|&(a, b)| {
                        let (ca, cb) = (col(a), col(b));
                        dot(ca, cb).abs() <= 1e-3 * (dot(ca, ca) * dot(cb, cb)).sqrt()
                    });
                if !orthogonal {
                    return Err(self.err(&format!("{at}/matrix"), "the matrix cannot be decomposed into translation, rotation and scale"));
                }
            }
            let mesh = self.get_index(n, "mesh").and_then(|m| meshes.get(m));
            let prims = mesh.and_then(|m| m.get("primitives")).and_then(Value::as_array);
            if let Some(w) = n.get("weights").and_then(Value::as_array) {
                let targets = prims.and_then(|p| p.first()).and_then(|p| p.get("targets")).and_then(Value::as_array).map_or(0, Vec::len);
                if w.len() != targets {
                    return Err(self.err(&format!("{at}/weights"), format!("{} weights for {targets} morph targets", w.len())));
                }
            }
            if n.get("skin").is_some() {
                let skinned = prims.is_some_and(|p| p.iter().any(|p| p.pointer("/attributes/JOINTS_0").is_some()));
                if !skinned {
                    return Err(self.err(&at, "the node has a skin, but its mesh has no JOINTS_0"));
                }
            }
        }
        Ok(())
    }

    fn check_animations(&self) -> R<()> {
        let nodes = self.items("nodes")?;
        let meshes = self.items("meshes")?;
        for (ai, a) in self.items("animations")?.iter().enumerate() {
            let at = ptr(&[&"animations", &ai]);
            let samplers = self.list(a, "samplers", &at)?;
            for (si, s) in samplers.iter().enumerate() {
                let here = format!("{at}/samplers/{si}");
                for key in ["input", "output"] {
                    if self.get_index(s, key).is_some_and(|x| self.strided(x)) {
                        return Err(
                            self.err(&format!("{here}/{key}"), "an animation sampler's accessors cannot lie in a strided buffer view")
                        );
                    }
                }
                if let Some(input) = self.get_index(s, "input") {
                    if self.format(input) != (5126, "SCALAR") {
                        return Err(self.err(&format!("{here}/input"), "key times must be SCALAR float"));
                    }
                    if !self.has_bounds(input) {
                        return Err(self.err(&format!("{here}/input"), "the key-time accessor needs min and max"));
                    }
                    let cubic = s.get("interpolation").and_then(Value::as_str) == Some("CUBICSPLINE");
                    if cubic && self.count(input) < 2 {
                        return Err(self.err(&format!("{here}/input"), "cubic-spline interpolation needs at least 2 key times"));
                    }
                }
            }
            let mut seen = HashSet::new();
            for (ci, c) in self.list(a, "channels", &at)?.iter().enumerate() {
                let here = format!("{at}/channels/{ci}/target");
                let Some(t) = c.get("target") else { continue };
                let path = t.get("path").and_then(Value::as_str).unwrap_or("");
                if let Some(p) = t.pointer("/extensions/KHR_animation_pointer") {
                    let ext = format!("{here}/extensions/KHR_animation_pointer");
                    if t.get("node").is_some() {
                        return Err(self.err(&ext, "with KHR_animation_pointer the target has no node"));
                    }
                    if path != "pointer" {
                        return Err(self.err(&ext, format!("with KHR_animation_pointer the target path is \"pointer\", not {path:?}")));
                    }
                    if !seen.insert((None, p.get("pointer").and_then(Value::as_str).unwrap_or("").to_string())) {
                        return Err(self.err(&here, "two channels of the animation have the same target"));
                    }
                    continue;
                }
                let Some(ni) = self.get_index(t, "node") else { continue };
                if !seen.insert((Some(ni), path.to_string())) {
                    return Err(self.err(&here, "two channels of the animation have the same target"));
                }
                let node = nodes.get(ni);
                if ["translation", "rotation", "scale"].contains(&path) && node.is_some_and(|n| n.get("matrix").is_some()) {
                    return Err(self.err(&here, format!("node {ni} has a matrix; its {path} cannot be animated")));
                }
                if path == "weights" {
                    let morphs = node
                        .and_then(|n| self.get_index(n, "mesh"))
                        .and_then(|m| meshes.get(m))
                        .and_then(|m| m.pointer("/primitives/0/targets"))
                        .and_then(Value::as_array)
                        .is_some_and(|t| !t.is_empty());
                    if !morphs {
                        return Err(self.err(&here, format!("node {ni}'s mesh has no morph targets whose weights could be animated")));
                    }
                }
            }
        }
        Ok(())
    }

    fn check_skins(&self) -> R<()> {
        let nodes = self.items("nodes")?;
        let mut parent = vec![None; nodes.len()];
        for (i, n) in nodes.iter().enumerate() {
            for c in n.get("children").and_then(Value::as_array).into_iter().flatten().filter_map(as_uint) {
                if let Some(p) = parent.get_mut(c as usize) {
                    *p = Some(i);
                }
            }
        }
        // Ancestors of a node, itself first (the forest was checked for cycles).
        let chain = |mut n: usize| {
            let mut out = vec![n];
            while let Some(p) = parent.get(n).copied().flatten() {
                if out.len() > nodes.len() {
                    break;
                }
                out.push(p);
                n = p;
            }
            out
        };
        // Each node's root, found once.
        let root: Vec<usize> = (0..nodes.len()).map(|n| *chain(n).last().unwrap_or(&n)).collect();
        for (si, s) in self.items("skins")?.iter().enumerate() {
            let at = ptr(&[&"skins", &si]);
            let joints: Vec<usize> =
                s.get("joints").and_then(Value::as_array).into_iter().flatten().filter_map(as_uint).map(|j| j as usize).collect();
            if let Some(ibm) = self.get_index(s, "inverseBindMatrices") {
                let here = format!("{at}/inverseBindMatrices");
                if self.strided(ibm) {
                    return Err(self.err(&here, "inverse bind matrices cannot lie in a strided buffer view"));
                }
                if self.format(ibm) != (5126, "MAT4") {
                    return Err(self.err(&here, "inverse bind matrices must be MAT4 float"));
                }
                if (self.count(ibm) as usize) < joints.len() {
                    return Err(self.err(&here, format!("{} matrices for {} joints", self.count(ibm), joints.len())));
                }
            }
            let Some(&first) = joints.first() else { continue };
            // A common root: some node that is an ancestor (or self) of every joint.
            let chains: Vec<Vec<usize>> = joints.iter().map(|&j| chain(j)).collect();
            if !chains[0].iter().any(|a| chains.iter().all(|c| c.contains(a))) {
                return Err(self.err(&format!("{at}/joints"), "the joints have no common root"));
            }
            if let Some(sk) = self.get_index(s, "skeleton") {
                if !chains.iter().all(|c| c.contains(&sk)) {
                    return Err(self.err(&format!("{at}/skeleton"), format!("node {sk} is not a common root of the joints")));
                }
            }
            // Every scene that shows a node with this skin also holds its joints.
            let joint_root = root.get(first).copied().unwrap_or(first);
            for (sci, sc) in self.items("scenes")?.iter().enumerate() {
                let roots: Vec<usize> =
                    sc.get("nodes").and_then(Value::as_array).into_iter().flatten().filter_map(as_uint).map(|n| n as usize).collect();
                let shown = |n: usize| roots.contains(&root[n]);
                for (ni, n) in nodes.iter().enumerate() {
                    if self.get_index(n, "skin") == Some(si) && shown(ni) && !roots.contains(&joint_root) {
                        return Err(
                            self.err(&ptr(&[&"nodes", &ni]), format!("a skinned node in scene {sci}, whose joints are not in that scene"))
                        );
                    }
                }
            }
        }
        Ok(())
    }

    fn check_images(&self) -> R<()> {
        let used = |e: &str| self.root.get("extensionsUsed").and_then(Value::as_array).is_some_and(|u| u.iter().any(|x| x == e));
        let images = self.items("images")?;
        let mime = |i: usize| -> Option<String> {
            let img = images.get(i)?;
            if let Some(m) = img.get("mimeType").and_then(Value::as_str) {
                return Some(m.to_string());
            }
            let uri = img.get("uri").and_then(Value::as_str)?;
            if let Some(d) = uri.strip_prefix("data:") {
                return d.split([';', ',']).next().map(str::to_string);
            }
            let ext = uri.rsplit('.').next()?.to_ascii_lowercase();
            Some(
                match ext.as_str() {
                    "png" => "image/png",
                    "jpg" | "jpeg" => "image/jpeg",
                    "webp" => "image/webp",
                    "ktx2" => "image/ktx2",
                    _ => return None,
                }
                .to_string(),
            )
        };
        for (i, img) in images.iter().enumerate() {
            let at = ptr(&[&"images", &i]);
            if self
                .get_index(img, "bufferView")
                .is_some_and(|v| self.root.get("bufferViews").and_then(|b| b.get(v)).is_some_and(|v| v.get("byteStride").is_some()))
            {
                return Err(self.err(&format!("{at}/bufferView"), "an image's buffer view cannot have byteStride"));
            }
            for (m, ext) in [("image/webp", "EXT_texture_webp"), ("image/ktx2", "KHR_texture_basisu"), ("image/avif", "EXT_texture_avif")] {
                if img.get("mimeType").and_then(Value::as_str) == Some(m) && !used(ext) {
                    return Err(self.err(&at, format!("{m} images need the {ext} extension")));
                }
            }
            // A data URI's media type against the declared one.
            if let (Some(uri), Some(declared)) = (img.get("uri").and_then(Value::as_str), img.get("mimeType").and_then(Value::as_str)) {
                if let Some(d) = uri.strip_prefix("data:") {
                    let found = d.split([';', ',']).next().unwrap_or("");
                    if found.starts_with("image/") && found != declared {
                        return Err(self.err(&format!("{at}/uri"), format!("the data is {found}, but mimeType says {declared}")));
                    }
                }
            }
        }
        for (i, t) in self.items("textures")?.iter().enumerate() {
            let at = ptr(&[&"textures", &i]);
            if let Some(m) = self.get_index(t, "source").and_then(mime) {
                if m != "image/png" && m != "image/jpeg" {
                    return Err(self.err(
                        &format!("{at}/source"),
                        format!("a texture's source must be PNG or JPEG, is {m} (extensions give other formats)"),
                    ));
                }
            }
            for (ext, want) in
                [("EXT_texture_webp", "image/webp"), ("KHR_texture_basisu", "image/ktx2"), ("EXT_texture_avif", "image/avif")]
            {
                if let Some(m) = t.pointer(&format!("/extensions/{ext}/source")).and_then(as_uint).and_then(|s| mime(s as usize)) {
                    if m != want {
                        return Err(self.err(&format!("{at}/extensions/{ext}/source"), format!("{ext} needs a {want} image, is {m}")));
                    }
                }
            }
        }
        for (i, b) in self.items("buffers")?.iter().enumerate() {
            if let Some(d) = b.get("uri").and_then(Value::as_str).and_then(|u| u.strip_prefix("data:")) {
                let at = ptr(&[&"buffers", &i, &"uri"]);
                let Some((head, _)) = d.split_once(',') else { return Err(self.err(&at, "a data URI needs a comma")) };
                let media = head.strip_suffix(";base64").unwrap_or(head);
                if media.contains(';') && !media.split(';').skip(1).all(|p| p.contains('=')) {
                    return Err(self.err(&at, format!("malformed data URI parameters {media:?}")));
                }
                let media = media.split(';').next().unwrap_or("");
                if !["application/octet-stream", "application/gltf-buffer"].contains(&media) {
                    return Err(self.err(
                        &at,
                        format!("a buffer's data URI must be application/octet-stream or application/gltf-buffer, is {media:?}"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// References that extensions add (texture sources, variants and their materials).
    fn check_extension_references(&self) -> R<()> {
        let len = |c: &Value| c.as_array().map_or(0, Vec::len);
        let n_images = self.root.get("images").map_or(0, len);
        for (i, t) in self.items("textures")?.iter().enumerate() {
            for ext in ["EXT_texture_webp", "KHR_texture_basisu", "EXT_texture_avif"] {
                if let Some(s) = t.pointer(&format!("/extensions/{ext}/source")).and_then(as_uint) {
                    if s as usize >= n_images {
                        return Err(self.err(
                            &ptr(&[&"textures", &i, &"extensions", &ext, &"source"]),
                            format!("image {s} does not exist (there are {n_images})"),
                        ));
                    }
                }
            }
        }
        let n_variants = self.root.pointer("/extensions/KHR_materials_variants/variants").map_or(0, len);
        let n_materials = self.root.get("materials").map_or(0, len);
        for (mi, m) in self.items("meshes")?.iter().enumerate() {
            for (pi, p) in m.get("primitives").and_then(Value::as_array).into_iter().flatten().enumerate() {
                let mut seen = HashSet::new();
                let maps = p.pointer("/extensions/KHR_materials_variants/mappings").and_then(Value::as_array);
                for (k, map) in maps.into_iter().flatten().enumerate() {
                    let at = format!("{}/extensions/KHR_materials_variants/mappings/{k}", ptr(&[&"meshes", &mi, &"primitives", &pi]));
                    if let Some(mat) = map.get("material").and_then(as_uint) {
                        if mat as usize >= n_materials {
                            return Err(
                                self.err(&format!("{at}/material"), format!("material {mat} does not exist (there are {n_materials})"))
                            );
                        }
                    }
                    for (vi, v) in map.get("variants").and_then(Value::as_array).into_iter().flatten().enumerate() {
                        let Some(v) = as_uint(v) else { continue };
                        if v as usize >= n_variants {
                            return Err(
                                self.err(&format!("{at}/variants/{vi}"), format!("variant {v} does not exist (there are {n_variants})"))
                            );
                        }
                        if !seen.insert(v) {
                            return Err(self.err(&format!("{at}/variants/{vi}"), format!("variant {v} is mapped twice for this primitive")));
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

impl Doc<'_> {
    /// Whether accessor `i` has stored values of a known layout to check: one without a
    /// buffer view and without sparse values is all zeros, whatever it declares (the
    /// validator leaves such data unchecked too); one of an unknown type is refused only
    /// where it is read.
    fn has_data(&self, i: usize) -> bool {
        self.accessor_json(i).is_some_and(|a| known_layout(a) && (a.get("bufferView").is_some() || a.get("sparse").is_some()))
    }

    /// Checks of the values themselves: finite floats, declared `min`/`max` equal to the
    /// data's, and what each use of an accessor needs (no primitive-restart index, unit
    /// normals and tangents with w = ±1, colours in 0..1, weights that are non-negative
    /// and sum to 1, joints inside the skin and not repeated, affine inverse bind
    /// matrices, unit rotation keys). Accessors whose buffers lack data are skipped here,
    /// as when they are read.
    pub fn check_data(&self) -> R<()> {
        for (i, a) in self.items("accessors")?.iter().enumerate() {
            let at = ptr(&[&"accessors", &i]);
            if !self.has_data(i) {
                continue;
            }
            let Some(raw) = self.accessor_values(i, false)? else { continue };
            if let Some(k) = raw.data.iter().position(|x| !x.is_finite()) {
                return Err(self.err(&at, format!("element {} is {}", k / raw.ncomp.max(1), raw.data[k])));
            }
            for (key, is_min) in [("min", true), ("max", false)] {
                let Some(decl) = a.get(key).and_then(Value::as_array) else { continue };
                if decl.len() != raw.ncomp {
                    return Err(self.err(&format!("{at}/{key}"), format!("has {} values for {} components", decl.len(), raw.ncomp)));
                }
                for (c, d) in decl.iter().enumerate() {
                    let d = d.as_f64().unwrap_or(0.0) as f32;
                    let col = raw.data.iter().skip(c).step_by(raw.ncomp).copied();
                    let actual = if is_min { col.fold(f32::INFINITY, f32::min) } else { col.fold(f32::NEG_INFINITY, f32::max) };
                    if actual != d {
                        return Err(self.err(&format!("{at}/{key}/{c}"), format!("declares {d}, but the data's {key} is {actual}")));
                    }
                }
            }
        }
        let read = |acc: usize| if self.has_data(acc) { self.accessor(acc) } else { Ok(None) };
        let skins = self.items("skins")?;
        // The fewest joints of any skin a node gives each mesh (one walk over the nodes).
        let mut fewest_joints: HashMap<usize, usize> = HashMap::new();
        for n in self.items("nodes")? {
            let (Some(mesh), Some(skin)) = (self.get_index(n, "mesh"), self.get_index(n, "skin")) else { continue };
            if let Some(j) = skins.get(skin).and_then(|s| s.get("joints")?.as_array().map(Vec::len)) {
                fewest_joints.entry(mesh).and_modify(|m| *m = (*m).min(j)).or_insert(j);
            }
        }
        for (mi, m) in self.items("meshes")?.iter().enumerate() {
            let joints = fewest_joints.get(&mi).copied();
            for (pi, p) in m.get("primitives").and_then(Value::as_array).into_iter().flatten().enumerate() {
                let at = ptr(&[&"meshes", &mi, &"primitives", &pi]);
                if let Some(ix) = self.get_index(p, "indices") {
                    let restart = match self.format(ix).0 {
                        5121 => 255.0,
                        5123 => 65535.0,
                        _ => 4_294_967_295.0,
                    };
                    if let Some(v) = read(ix)? {
                        if let Some(k) = v.data.iter().position(|&x| x == restart) {
                            return Err(self.err(&format!("{at}/indices"), format!("index {k} is the primitive-restart value {restart}")));
                        }
                    }
                }
                let Some(attrs) = p.get("attributes").and_then(Value::as_object) else { continue };
                let acc = |name: &str| attrs.get(name).and_then(as_uint).map(|a| a as usize);
                for name in ["NORMAL", "TANGENT"] {
                    let Some(v) = acc(name).map(read).transpose()?.flatten() else { continue };
                    for (k, e) in v.data.chunks_exact(v.ncomp.max(1)).enumerate() {
                        if e.len() >= 3 && ((e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt() - 1.0).abs() > UNIT_TOLERANCE {
                            return Err(self.err(&format!("{at}/attributes/{name}"), format!("element {k} is not of unit length")));
                        }
                        if name == "TANGENT" && e.len() == 4 && e[3].abs() != 1.0 {
                            return Err(self.err(&format!("{at}/attributes/{name}"), format!("element {k} has w = {}, not 1 or -1", e[3])));
                        }
                    }
                }
                for (name, a) in attrs {
                    let Some(a) = as_uint(a).map(|a| a as usize) else { continue };
                    let here = format!("{at}/attributes/{}", esc(name));
                    if name.starts_with("COLOR_") && self.format(a).0 == 5126 {
                        if let Some(v) = read(a)? {
                            if let Some(k) = v.data.iter().position(|x| !(0.0..=1.0).contains(x)) {
                                return Err(self.err(&here, format!("colour component {k} is {}, outside 0..1", v.data[k])));
                            }
                        }
                    }
                    if let Some(set) = name.strip_prefix("WEIGHTS_") {
                        let Some(w) = read(a)? else { continue };
                        if let Some(k) = w.data.iter().position(|&x| x < 0.0) {
                            return Err(self.err(&here, format!("weight {k} is negative")));
                        }
                        // The sum over every WEIGHTS_n set of a vertex is 1.
                        if set == "0" {
                            let mut sum: Vec<f32> = w.data.chunks_exact(4).map(|c| c.iter().sum()).collect();
                            for n in 1.. {
                                let Some(more) = acc(&format!("WEIGHTS_{n}")).map(read).transpose()?.flatten() else { break };
                                for (s, c) in sum.iter_mut().zip(more.data.chunks_exact(4)) {
                                    *s += c.iter().sum::<f32>();
                                }
                            }
                            // Normalized integers sum to 1 within their rounding.
                            let tol = if self.format(a).0 == 5126 { 2e-3 } else { 1e-2 };
                            if let Some(k) = sum.iter().position(|s| (s - 1.0).abs() > tol && *s != 0.0) {
                                return Err(self.err(&here, format!("the weights of vertex {k} sum to {}, not 1", sum[k])));
                            }
                        }
                    }
                    if name == "JOINTS_0" {
                        let mut sets = Vec::new();
                        for n in 0.. {
                            let (Some(j), Some(w)) = (acc(&format!("JOINTS_{n}")), acc(&format!("WEIGHTS_{n}"))) else { break };
                            let (Some(j), Some(w)) = (read(j)?, read(w)?) else { break };
                            sets.push((n, j, w));
                        }
                        let verts = sets.first().map_or(0, |s| s.1.count());
                        for v in 0..verts {
                            let mut used = Vec::new();
                            for (n, j, w) in &sets {
                                for c in 0..4 {
                                    let (ji, wi) =
                                        (j.data.get(v * 4 + c).copied().unwrap_or(0.0), w.data.get(v * 4 + c).copied().unwrap_or(0.0));
                                    let jat = format!("{at}/attributes/JOINTS_{n}");
                                    if joints.is_some_and(|m| ji as usize >= m) {
                                        return Err(
                                            self.err(&jat, format!("vertex {v} names joint {ji}; the skin has {}", joints.unwrap_or(0)))
                                        );
                                    }
                                    if wi != 0.0 {
                                        if used.contains(&ji) {
                                            return Err(self.err(&jat, format!("vertex {v} names joint {ji} twice")));
                                        }
                                        used.push(ji);
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        for (si, s) in skins.iter().enumerate() {
            let Some(ibm) = self.get_index(s, "inverseBindMatrices") else { continue };
            let Some(v) = read(ibm)? else { continue };
            for (k, m) in v.data.chunks_exact(16).enumerate() {
                if m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0 {
                    return Err(self.err(
                        &ptr(&[&"skins", &si, &"inverseBindMatrices"]),
                        format!("matrix {k} is not affine (its last row is not 0 0 0 1)"),
                    ));
                }
            }
        }
        for (ai, a) in self.items("animations")?.iter().enumerate() {
            let samplers = a.get("samplers").and_then(Value::as_array);
            for c in a.get("channels").and_then(Value::as_array).into_iter().flatten() {
                if c.pointer("/target/path").and_then(Value::as_str) != Some("rotation") {
                    continue;
                }
                let Some(si) = self.get_index(c, "sampler") else { continue };
                let Some(s) = samplers.and_then(|l| l.get(si)) else { continue };
                let Some(out) = self.get_index(s, "output") else { continue };
                let Some(v) = read(out)? else { continue };
                let cubic = s.get("interpolation").and_then(Value::as_str) == Some("CUBICSPLINE");
                for (k, q) in v.data.chunks_exact(4).enumerate() {
                    // A cubic spline's keys are (in-tangent, value, out-tangent): only values are unit.
                    if cubic && k % 3 != 1 {
                        continue;
                    }
                    if ((q.iter().map(|x| x * x).sum::<f32>()).sqrt() - 1.0).abs() > UNIT_TOLERANCE {
                        return Err(self.err(
                            &ptr(&[&"animations", &ai, &"samplers", &si, &"output"]),
                            format!("rotation key {k} is not a unit quaternion"),
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

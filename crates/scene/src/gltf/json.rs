//! The glTF document as JSON, read as the specification defines it (not stricter): the GLB
//! container, buffers, buffer views and accessors (sparse ones, and those without a
//! buffer view, which read as zeros), with every index checked before it is used and
//! every size bounded before anything is allocated. Errors name the file and the JSON
//! pointer of what is wrong (`/meshes/0/primitives/1/indices`).

use super::pointer::{as_uint, comp_size, known_layout, ptr};
use crate::error::ImportError;
use base64::Engine as _;
use serde_json::Value;
use std::path::Path;

/// The most values (components) one accessor may make without a buffer view behind it
/// (zeros, or a sparse accessor's base): 2^26, 256 MB of f32. Accessors over buffer views
/// are bounded by their views, which are bounded by the buffers read.
pub(crate) const MAX_ZERO_VALUES: usize = 1 << 26;

pub(crate) type R<T> = Result<T, ImportError>;

/// One glTF document: its JSON root, its buffers (read and checked against their
/// `byteLength`), its buffer views (checked against their buffers).
pub(crate) struct Doc<'a> {
    pub root: Value,
    pub file: &'a Path,
    pub base: &'a Path,
    /// Each buffer's bytes, or why it could not be read: an error only for what uses it
    /// (a buffer no view reads may lack its data, as the specification allows).
    buffers: Vec<Result<Vec<u8>, String>>,
    views: Vec<View>,
    /// Whether the document came in a GLB container.
    glb: bool,
}

#[derive(Clone, Copy)]
struct View {
    buffer: usize,
    offset: usize,
    len: usize,
    stride: Option<usize>,
}

impl View {
    /// Whether the bytes lie inside a buffer of `n` bytes.
    fn fits(&self, n: usize) -> bool {
        self.offset.checked_add(self.len).is_some_and(|end| end <= n)
    }
}

/// An accessor's values, converted to f32 (normalized integers mapped to [0, 1] or
/// [-1, 1] as the specification says; other integers as they are), `ncomp` per element.
pub(crate) struct Values {
    pub data: Vec<f32>,
    pub ncomp: usize,
}

impl Values {
    pub fn count(&self) -> usize {
        self.data.len().checked_div(self.ncomp).unwrap_or(0)
    }
    /// Elements of exactly `N` components (the caller checked `ncomp`).
    pub fn elements<const N: usize>(&self) -> impl Iterator<Item = [f32; N]> + '_ {
        self.data.chunks_exact(N).map(|c| std::array::from_fn(|i| c[i]))
    }
}

/// What an accessor claims, checked ([`Doc::accessor_layout`]).
struct Layout {
    comp: u64,
    csize: usize,
    ncomp: usize,
    rows: usize,
    col_size: usize,
    elem: usize,
    normalized: bool,
    count: usize,
    view: Option<usize>,
    offset: usize,
    stride: usize,
}

impl<'a> Doc<'a> {
    /// Parses `bytes` (a `.gltf` JSON text or a `.glb` container) and reads its buffers.
    ///
    /// With `strict`, a file that breaks any rule of the specification is refused (the
    /// schema, [`super::rules`] and the data checks, as the Khronos validator reports
    /// errors); without, lucent warns once, naming the first broken rule, and reads what
    /// it can: what it needs to read safely (references, sizes, formats, the container) is
    /// checked either way. Exporters commonly write files that break a rule harmlessly
    /// (weights that do not sum to 1, `min`/`max` a little off), and such a scene should
    /// render.
    pub fn parse(bytes: &[u8], file: &'a Path, base: &'a Path, strict: bool) -> R<Self> {
        let invalid = |at: &str, msg: String| ImportError::Invalid { path: file.to_path_buf(), at: at.into(), msg };
        let is_glb = bytes.starts_with(b"glTF");
        let (json, blob) = if is_glb { glb(bytes).map_err(|(at, m)| invalid(at, m))? } else { (bytes, None) };
        let root: Value = serde_json::from_slice(json).map_err(|e| invalid("JSON", format!("{e}")))?;
        if !root.is_object() {
            return Err(invalid("JSON", "the document is not a JSON object".into()));
        }
        // Conformance: an error when strict; otherwise the first broken rule is a warning.
        let mut warned = false;
        let mut conform = |r: R<()>| -> R<()> {
            match r {
                Err(e) if !strict => {
                    if !warned {
                        tracing::warn!("not valid glTF ({e}); loading what can be read (--strict refuses such files)");
                        warned = true;
                    }
                    Ok(())
                }
                r => r,
            }
        };
        conform(super::schema::check(&root).map_err(|(at, m)| invalid(&at, m)))?;
        let mut doc = Doc { root, file, base, buffers: Vec::new(), views: Vec::new(), glb: is_glb };
        let version = doc.root.pointer("/asset/version").and_then(Value::as_str).map(str::to_owned);
        match version {
            None => return Err(doc.err("/asset/version", "missing: glTF needs an asset with a version")),
            Some(v) if !v.starts_with("2.") => return Err(doc.err("/asset/version", format!("is {v:?}; only glTF 2.x is read"))),
            _ => {}
        }
        doc.buffers = doc.read_buffers(blob)?;
        doc.views = doc.read_views()?;
        doc.check_references()?;
        conform(doc.check_rules())?;
        // The data checks read every accessor once more: only when strict.
        if strict {
            doc.check_data()?;
        }
        Ok(doc)
    }

    pub fn err(&self, at: &str, msg: impl Into<String>) -> ImportError {
        ImportError::Invalid { path: self.file.to_path_buf(), at: at.to_string(), msg: msg.into() }
    }

    /// The top-level array `key` (empty when absent).
    pub fn items(&self, key: &str) -> R<&[Value]> {
        self.list(&self.root, key, "")
    }

    /// `v[key]` as an array: empty when absent, an error when not an array.
    pub fn list<'v>(&self, v: &'v Value, key: &str, at: &str) -> R<&'v [Value]> {
        match v.get(key) {
            None | Some(Value::Null) => Ok(&[]),
            Some(Value::Array(a)) => Ok(a),
            Some(_) => Err(self.err(&format!("{at}/{key}"), "must be an array")),
        }
    }

    /// `v[key]` as a non-negative integer (`3` or `3.0`, as JSON numbers are).
    pub fn uint(&self, v: &Value, key: &str, at: &str) -> R<Option<u64>> {
        match v.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(x) => {
                as_uint(x).map(Some).ok_or_else(|| self.err(&format!("{at}/{key}"), format!("must be a non-negative integer, is {x}")))
            }
        }
    }

    /// `v[key]` as an index into a list of `len` `what`s.
    pub fn index(&self, v: &Value, key: &str, at: &str, len: usize, what: &str) -> R<Option<usize>> {
        match self.uint(v, key, at)? {
            None => Ok(None),
            Some(i) if (i as usize) < len && i <= usize::MAX as u64 => Ok(Some(i as usize)),
            Some(i) => Err(self.err(&format!("{at}/{key}"), format!("{what} {i} does not exist (there are {len})"))),
        }
    }

    /// An element of `v[key]` (an array of indices) checked against `len`.
    pub fn indices(&self, v: &Value, key: &str, at: &str, len: usize, what: &str) -> R<Vec<usize>> {
        self.list(v, key, at)?
            .iter()
            .enumerate()
            .map(|(k, x)| match as_uint(x) {
                Some(i) if (i as usize) < len => Ok(i as usize),
                _ => Err(self.err(&format!("{at}/{key}/{k}"), format!("{x} is not one of the {len} {what}s"))),
            })
            .collect()
    }

    fn read_buffers(&self, mut blob: Option<Vec<u8>>) -> R<Vec<Result<Vec<u8>, String>>> {
        let mut out = Vec::new();
        for (i, b) in self.items("buffers")?.iter().enumerate() {
            let at = ptr(&[&"buffers", &i]);
            let len = self.uint(b, "byteLength", &at)?.ok_or_else(|| self.err(&format!("{at}/byteLength"), "missing"))? as usize;
            // Missing data (no uri outside a GLB, a network uri) is an error only where
            // something reads it; a file that cannot be read, or holds fewer bytes than
            // byteLength, is an error now.
            let data = match b.get("uri").and_then(Value::as_str) {
                None if i == 0 && blob.is_some() => blob.take().unwrap_or_default(),
                None if i == 0 && self.glb => return Err(self.err(&at, "has no uri, and the GLB file has no binary chunk")),
                None => {
                    out.push(Err(format!("{at} has no uri and is not the GLB binary chunk")));
                    continue;
                }
                Some(uri) if uri.contains("://") => {
                    out.push(Err(format!("{at}: {uri:?} is not a relative path; lucent reads no network resources")));
                    continue;
                }
                Some(uri) => self.read_uri(uri, &format!("{at}/uri"))?,
            };
            if data.len() < len {
                return Err(self.err(&at, format!("has {} bytes, but byteLength says {len}", data.len())));
            }
            out.push(Ok(data));
        }
        Ok(out)
    }

    /// The bytes a `uri` names: a base64 data URI, or a file beside the document.
    pub fn read_uri(&self, uri: &str, at: &str) -> R<Vec<u8>> {
        if let Some(data) = uri.strip_prefix("data:") {
            match data.split_once(";base64,") {
                Some((_, b64)) => {
                    base64::engine::general_purpose::STANDARD.decode(b64.trim()).map_err(|e| self.err(at, format!("bad base64: {e}")))
                }
                // RFC 2397 without base64: the bytes percent-encoded after the comma.
                None => {
                    data.split_once(',').map(|(_, text)| percent_decode_bytes(text)).ok_or_else(|| self.err(at, "data URI without a comma"))
                }
            }
        } else if uri.contains("://") {
            Err(self.err(at, format!("{uri:?} is not a relative path; lucent reads no network resources")))
        } else {
            let file = self.base.join(percent_decode(uri));
            std::fs::read(&file).map_err(|e| self.err(at, format!("cannot read '{}': {e}", file.display())))
        }
    }

    fn read_views(&self) -> R<Vec<View>> {
        let mut out = Vec::new();
        for (i, v) in self.items("bufferViews")?.iter().enumerate() {
            let at = ptr(&[&"bufferViews", &i]);
            let buffer =
                self.index(v, "buffer", &at, self.buffers.len(), "buffer")?.ok_or_else(|| self.err(&format!("{at}/buffer"), "missing"))?;
            let offset = self.uint(v, "byteOffset", &at)?.unwrap_or(0) as usize;
            let len = self.uint(v, "byteLength", &at)?.ok_or_else(|| self.err(&format!("{at}/byteLength"), "missing"))? as usize;
            let stride = self.uint(v, "byteStride", &at)?.map(|s| s as usize);
            let view = View { buffer, offset, len, stride };
            if let Ok(b) = &self.buffers[buffer] {
                if !view.fits(b.len()) {
                    return Err(self.err(&at, format!("bytes {offset}..+{len} lie outside buffer {buffer} ({} bytes)", b.len())));
                }
            }
            if stride.is_some_and(|s| !(4..=252).contains(&s)) {
                return Err(self.err(&format!("{at}/byteStride"), "must be 4 to 252"));
            }
            out.push(view);
        }
        Ok(out)
    }

    /// The bytes of buffer view `i` (its range was checked at parse time), or why its
    /// buffer has none.
    pub fn view_bytes(&self, i: usize) -> Result<&[u8], String> {
        let v = self.views.get(i).ok_or_else(|| format!("buffer view {i} does not exist"))?;
        match self.buffers.get(v.buffer) {
            Some(Ok(b)) => b.get(v.offset..v.offset + v.len).ok_or_else(|| format!("buffer view {i} lies outside its buffer")),
            Some(Err(e)) => Err(format!("buffer view {i}: {e}")),
            None => Err(format!("buffer view {i}: no buffer {}", v.buffer)),
        }
    }

    pub fn view_count(&self) -> usize {
        self.views.len()
    }

    /// The layout accessor `i` (the JSON `a`) claims, checked: known component and element
    /// types, and its elements inside its buffer view (whose bytes need not be available).
    fn accessor_layout(&self, i: usize, a: &Value) -> R<Layout> {
        let at = ptr(&[&"accessors", &i]);
        let comp = self.uint(a, "componentType", &at)?.ok_or_else(|| self.err(&format!("{at}/componentType"), "missing"))?;
        let csize =
            comp_size(comp).ok_or_else(|| self.err(&format!("{at}/componentType"), format!("{comp} is not a glTF component type")))?;
        let ty = a.get("type").and_then(Value::as_str).unwrap_or("");
        let (ncomp, cols) = match ty {
            "SCALAR" => (1, 1),
            "VEC2" => (2, 1),
            "VEC3" => (3, 1),
            "VEC4" => (4, 1),
            "MAT2" => (4, 2),
            "MAT3" => (9, 3),
            "MAT4" => (16, 4),
            _ => return Err(self.err(&format!("{at}/type"), format!("{ty:?} is not an accessor type"))),
        };
        let normalized = a.get("normalized").and_then(Value::as_bool).unwrap_or(false);
        let count = self.uint(a, "count", &at)?.ok_or_else(|| self.err(&format!("{at}/count"), "missing"))? as usize;
        if count == 0 {
            return Err(self.err(&format!("{at}/count"), "must be at least 1"));
        }
        // Matrix columns of 1- and 2-byte components start on 4-byte boundaries.
        let rows = ncomp / cols;
        let col_size = if cols > 1 { (rows * csize).div_ceil(4) * 4 } else { rows * csize };
        let elem = cols * col_size;
        let view = self.index(a, "bufferView", &at, self.views.len(), "buffer view")?;
        let offset = self.uint(a, "byteOffset", &at)?.unwrap_or(0) as usize;
        let stride = view.and_then(|v| self.views[v].stride).unwrap_or(elem);
        if let Some(vi) = view {
            let len = self.views[vi].len;
            if stride < elem {
                return Err(self.err(&at, format!("elements of {elem} bytes in buffer view {vi} of stride {stride}")));
            }
            // The last element ends with its last column (no padding after it).
            let used = elem - col_size + rows * csize;
            let end = (count - 1).checked_mul(stride).and_then(|x| x.checked_add(offset + used));
            if end.is_none_or(|e| e > len) {
                return Err(self.err(
                    &at,
                    format!(
                        "{count} elements of {used} bytes (stride {stride}, offset {offset}) do not fit buffer view {vi} ({len} bytes)"
                    ),
                ));
            }
        } else if count.checked_mul(ncomp).is_none_or(|n| n > MAX_ZERO_VALUES) {
            return Err(self.err(&at, format!("{count} elements without a buffer view exceed the limit of {MAX_ZERO_VALUES} values")));
        }
        Ok(Layout { comp, csize, ncomp, rows, col_size, elem, normalized, count, view, offset, stride })
    }

    /// Reads accessor `i` (values converted to f32, see [`Values`]); `None`, with a
    /// warning, when a buffer it needs has no data (a buffer without a uri outside a GLB,
    /// or one that could not be read): what uses it is then skipped.
    pub fn accessor(&self, i: usize) -> R<Option<Values>> {
        self.accessor_values(i, true)
    }

    /// Accessor `i` as [`Doc::accessor`] reads it, or with `normalize` false the stored
    /// integers as they are (what its `min` and `max` describe).
    pub fn accessor_values(&self, i: usize, normalize: bool) -> R<Option<Values>> {
        let at = ptr(&[&"accessors", &i]);
        let list = self.items("accessors")?;
        let a = list.get(i).ok_or_else(|| self.err(&at, format!("does not exist (there are {})", list.len())))?;
        let Layout { comp, csize, ncomp, rows, col_size, elem, normalized, count, view, offset, stride } = self.accessor_layout(i, a)?;
        let normalized = normalized && normalize;
        let read = |bytes: &[u8], base: usize, out: &mut [f32]| {
            for (k, o) in out.iter_mut().enumerate() {
                let (c, r) = (k / rows, k % rows);
                *o = component(bytes, base + c * col_size + r * csize, comp, normalized);
            }
        };
        let mut data = match view {
            None => vec![0.0; count * ncomp],
            Some(vi) => {
                let bytes = match self.view_bytes(vi) {
                    Ok(b) => b,
                    Err(e) => {
                        tracing::warn!("{}: {at}: no data ({e}); skipped", self.file.display());
                        return Ok(None);
                    }
                };
                let mut data = vec![0.0; count * ncomp];
                for (e, out) in data.chunks_exact_mut(ncomp).enumerate() {
                    read(bytes, offset + e * stride, out);
                }
                data
            }
        };
        if let Some(s) = a.get("sparse") {
            let sat = format!("{at}/sparse");
            let n = self.uint(s, "count", &sat)?.unwrap_or(0) as usize;
            if n > count {
                return Err(self.err(&format!("{sat}/count"), format!("{n} exceeds the accessor's {count} elements")));
            }
            let part = |key: &str| -> R<Option<(&[u8], usize)>> {
                let pat = format!("{sat}/{key}");
                let p = s.get(key).ok_or_else(|| self.err(&pat, "missing"))?;
                let vi = self
                    .index(p, "bufferView", &pat, self.views.len(), "buffer view")?
                    .ok_or_else(|| self.err(&format!("{pat}/bufferView"), "missing"))?;
                let offset = self.uint(p, "byteOffset", &pat)?.unwrap_or(0) as usize;
                Ok(match self.view_bytes(vi) {
                    Ok(b) => Some((b, offset)),
                    Err(e) => {
                        tracing::warn!("{}: {pat}: no data ({e}); skipped", self.file.display());
                        None
                    }
                })
            };
            let (Some((ib, io)), Some((vb, vo))) = (part("indices")?, part("values")?) else { return Ok(None) };
            let icomp = self.uint(&s["indices"], "componentType", &sat)?.unwrap_or(0);
            let isize = match icomp {
                5121 => 1,
                5123 => 2,
                5125 => 4,
                _ => return Err(self.err(&format!("{sat}/indices/componentType"), format!("{icomp} is not an unsigned index type"))),
            };
            if io + n * isize > ib.len() || vo + n * elem > vb.len() {
                return Err(self.err(&sat, format!("{n} sparse entries do not fit their buffer views")));
            }
            for k in 0..n {
                let e = component(ib, io + k * isize, icomp, false) as usize;
                if e >= count {
                    return Err(self.err(&format!("{sat}/indices"), format!("entry {k} names element {e} of {count}")));
                }
                read(vb, vo + k * elem, &mut data[e * ncomp..(e + 1) * ncomp]);
            }
        }
        Ok(Some(Values { data, ncomp }))
    }
}

/// Component `comp` at `at` (little endian; in range, checked by the caller), as f32.
fn component(b: &[u8], at: usize, comp: u64, normalized: bool) -> f32 {
    let bytes = |n: usize| -> [u8; 4] {
        let mut x = [0u8; 4];
        if let Some(s) = b.get(at..at + n) {
            x[..n].copy_from_slice(s);
        }
        x
    };
    match comp {
        5120 => {
            let v = bytes(1)[0] as i8 as f32;
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        5121 => {
            let v = f32::from(bytes(1)[0]);
            if normalized {
                v / 255.0
            } else {
                v
            }
        }
        5122 => {
            let x = bytes(2);
            let v = f32::from(i16::from_le_bytes([x[0], x[1]]));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        5123 => {
            let x = bytes(2);
            let v = f32::from(u16::from_le_bytes([x[0], x[1]]));
            if normalized {
                v / 65535.0
            } else {
                v
            }
        }
        5125 => {
            let v = u32::from_le_bytes(bytes(4)) as f32;
            if normalized {
                v / u32::MAX as f32
            } else {
                v
            }
        }
        _ => f32::from_le_bytes(bytes(4)),
    }
}

/// The JSON and binary chunks of a GLB container (glTF 2.0 §4.4), bounds-checked.
/// A GLB's JSON chunk and its binary chunk.
type Chunks<'b> = (&'b [u8], Option<Vec<u8>>);

fn glb(b: &[u8]) -> Result<Chunks<'_>, (&'static str, String)> {
    let u32_at = |o: usize| b.get(o..o + 4).map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]) as usize);
    let version = u32_at(4).ok_or(("GLB header", "shorter than 12 bytes".to_string()))?;
    if version != 2 {
        return Err(("GLB header", format!("container version {version}; only 2 is read")));
    }
    // Bytes after the container's length are ignored; fewer bytes are an error.
    let total = u32_at(8).unwrap_or(0);
    if total > b.len() {
        return Err(("GLB header", format!("says the file has {total} bytes; it has {}", b.len())));
    }
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    let mut second = false;
    while at < total {
        let (Some(len), Some(kind)) = (u32_at(at), u32_at(at + 4)) else {
            return Err(("GLB chunk", format!("chunk header at byte {at} runs past the end")));
        };
        if len % 4 != 0 {
            return Err(("GLB chunk", format!("chunk at byte {at} has length {len}, not a multiple of 4")));
        }
        let data = b
            .get(at + 8..total)
            .and_then(|r| r.get(..len))
            .ok_or(("GLB chunk", format!("chunk at byte {at} of {len} bytes runs past the container's end ({total} bytes)")))?;
        match kind {
            0x4E4F_534A if at == 12 => json = Some(data),
            0x4E4F_534A => return Err(("GLB chunk", format!("a second JSON chunk at byte {at}"))),
            // The binary chunk, if any, is the second one (glTF 2.0 §4.4.3.2).
            0x004E_4942 if json.is_some() && bin.is_none() && second => bin = Some(data.to_vec()),
            0x004E_4942 => return Err(("GLB chunk", format!("an unexpected binary chunk at byte {at}"))),
            _ => {}
        }
        second = at == 12;
        at += 8 + len;
    }
    Ok((json.ok_or(("GLB chunk", "the first chunk is not JSON".to_string()))?, bin))
}

/// Where one glTF object refers to another: (collection, JSON pointer inside an element
/// with `*` for every array element or object member, the collection referred to).
const REFERENCES: &[(&str, &str, &str)] = &[
    ("accessors", "/bufferView", "bufferViews"),
    ("accessors", "/sparse/indices/bufferView", "bufferViews"),
    ("accessors", "/sparse/values/bufferView", "bufferViews"),
    ("bufferViews", "/buffer", "buffers"),
    ("images", "/bufferView", "bufferViews"),
    ("textures", "/sampler", "samplers"),
    ("textures", "/source", "images"),
    ("materials", "/pbrMetallicRoughness/baseColorTexture/index", "textures"),
    ("materials", "/pbrMetallicRoughness/metallicRoughnessTexture/index", "textures"),
    ("materials", "/normalTexture/index", "textures"),
    ("materials", "/occlusionTexture/index", "textures"),
    ("materials", "/emissiveTexture/index", "textures"),
    ("meshes", "/primitives/*/attributes/*", "accessors"),
    ("meshes", "/primitives/*/indices", "accessors"),
    ("meshes", "/primitives/*/material", "materials"),
    ("meshes", "/primitives/*/targets/*/*", "accessors"),
    ("nodes", "/camera", "cameras"),
    ("nodes", "/children/*", "nodes"),
    ("nodes", "/skin", "skins"),
    ("nodes", "/mesh", "meshes"),
    ("skins", "/inverseBindMatrices", "accessors"),
    ("skins", "/skeleton", "nodes"),
    ("skins", "/joints/*", "nodes"),
    ("animations", "/channels/*/target/node", "nodes"),
    ("animations", "/samplers/*/input", "accessors"),
    ("animations", "/samplers/*/output", "accessors"),
    ("scenes", "/nodes/*", "nodes"),
];

impl Doc<'_> {
    /// Every reference of [`REFERENCES`] names an object that exists (glTF 2.0 §3.7: ids
    /// are indices into the top-level arrays), and the sizes every accessor claims fit
    /// its buffer view; also the root's `scene` and the animation channels' samplers.
    pub fn check_references(&self) -> R<()> {
        fn walk<'v>(v: &'v Value, parts: &[&str], at: String, out: &mut Vec<(String, &'v Value)>) {
            let Some((&first, rest)) = parts.split_first() else {
                out.push((at, v));
                return;
            };
            match (first, v) {
                ("*", Value::Array(a)) => a.iter().enumerate().for_each(|(i, x)| walk(x, rest, format!("{at}/{i}"), out)),
                ("*", Value::Object(o)) => o.iter().for_each(|(k, x)| walk(x, rest, format!("{at}/{k}"), out)),
                ("*", _) => {}
                (key, _) => {
                    if let Some(x) = v.get(key) {
                        walk(x, rest, format!("{at}/{key}"), out);
                    }
                }
            }
        }
        let len = |c: &str| self.root.get(c).and_then(Value::as_array).map_or(0, Vec::len);
        for &(coll, path, target) in REFERENCES {
            let parts: Vec<&str> = path.split('/').filter(|p| !p.is_empty()).collect();
            let mut refs = Vec::new();
            for (i, item) in self.items(coll)?.iter().enumerate() {
                walk(item, &parts, format!("/{coll}/{i}"), &mut refs);
            }
            let n = len(target);
            for (at, v) in refs {
                match as_uint(v) {
                    Some(k) if (k as usize) < n => {}
                    Some(k) => return Err(self.err(&at, format!("{target} {k} does not exist (there are {n})"))),
                    None => return Err(self.err(&at, format!("must be an index into {target}, is {v}"))),
                }
            }
        }
        self.index(&self.root, "scene", "", len("scenes"), "scene")?;
        for (ai, a) in self.items("animations")?.iter().enumerate() {
            let at = ptr(&[&"animations", &ai]);
            let n = self.list(a, "samplers", &at)?.len();
            for (ci, c) in self.list(a, "channels", &at)?.iter().enumerate() {
                self.index(c, "sampler", &format!("{at}/channels/{ci}"), n, "sampler")?;
            }
        }
        // Sizes of every accessor (one of an unknown type is an error only where read).
        for (i, a) in self.items("accessors")?.iter().enumerate() {
            if known_layout(a) {
                self.accessor_layout(i, a)?;
            }
        }
        Ok(())
    }
}
pub(crate) fn percent_decode(s: &str) -> String {
    String::from_utf8_lossy(&percent_decode_bytes(s)).into_owned()
}

fn percent_decode_bytes(s: &str) -> Vec<u8> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            if let Some(v) = s.get(i + 1..i + 3).and_then(|h| u8::from_str_radix(h, 16).ok()) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    out
}

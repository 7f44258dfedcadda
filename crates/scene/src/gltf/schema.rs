//! The glTF 2.0 JSON schema (glTF 2.0 specification §5, "Properties Reference", and the
//! schemas of the Khronos extensions lucent knows), checked before anything is read:
//! types, required properties, value ranges and enumerations, array lengths, empty
//! arrays, dependencies between properties, and where each known extension may appear.
//! Only what the specification makes an error is refused: unknown properties and unknown
//! extensions are allowed (the validator calls them warnings or information).
//!
//! The tables below are written from the specification's property reference; the checker
//! walks the document once.

use serde_json::Value;

/// What a JSON value must be.
#[derive(Clone, Copy)]
pub(super) enum T {
    Bool,
    Str,
    /// A string matching a JSON pointer (RFC 6901: empty, or `/`-separated tokens).
    Pointer,
    /// A `major.minor` version string.
    Version,
    /// One of these strings.
    Strs(&'static [&'static str]),
    /// An integer at least this (`3` or `3.0`).
    Int(i64),
    /// One of these integers.
    Ints(&'static [i64]),
    /// An integer in `[min, max]` that is a multiple of `step`.
    IntStep(i64, i64, i64),
    /// A number in a range.
    Num(Range),
    /// An array: items, min and max length, items unique.
    Arr(&'static T, usize, usize, bool),
    /// An object with any keys, each value of this type, at least this many members.
    Map(&'static T, usize),
    /// An object of a schema.
    Obj(&'static Schema),
    /// An index of refraction: 0 (the specification's "no refraction"), or at least 1.
    Ior,
}

/// A number's range; `*_open` excludes the bound.
#[derive(Clone, Copy)]
pub(super) struct Range {
    min: f64,
    max: f64,
    min_open: bool,
    max_open: bool,
}

const fn num(min: f64, max: f64) -> T {
    T::Num(Range { min, max, min_open: false, max_open: false })
}
const fn above(min: f64) -> T {
    T::Num(Range { min, max: f64::INFINITY, min_open: true, max_open: false })
}
const ANY_NUM: T = num(f64::NEG_INFINITY, f64::INFINITY);
const UNIT: T = num(0.0, 1.0);
const NONNEG: T = num(0.0, f64::INFINITY);
const INDEX: T = T::Int(0);

/// One object type: its name (where extensions attach: "material", "textureInfo", ...),
/// its properties `(name, type, required)`, and its dependencies (`a` needs `b`).
pub(super) struct Schema {
    kind: &'static str,
    props: &'static [(&'static str, T, bool)],
    deps: &'static [(&'static str, &'static str)],
}

const fn obj(kind: &'static str, props: &'static [(&'static str, T, bool)]) -> Schema {
    Schema { kind, props, deps: &[] }
}

static TEXTURE_INFO: Schema = obj("textureInfo", &[("index", INDEX, true), ("texCoord", INDEX, false)]);
static NORMAL_TEXTURE: Schema = obj("textureInfo", &[("index", INDEX, true), ("texCoord", INDEX, false), ("scale", ANY_NUM, false)]);
static OCCLUSION_TEXTURE: Schema = obj("textureInfo", &[("index", INDEX, true), ("texCoord", INDEX, false), ("strength", UNIT, false)]);
const TEX: T = T::Obj(&TEXTURE_INFO);
const COLOR3: T = T::Arr(&UNIT, 3, 3, false);
const COLOR4: T = T::Arr(&UNIT, 4, 4, false);
const STRINGS: T = T::Arr(&T::Str, 1, usize::MAX, true);
const INDICES: T = T::Arr(&INDEX, 1, usize::MAX, true);

/// A non-empty array of objects of a schema.
macro_rules! list {
    ($s:expr) => {
        T::Arr(&T::Obj(&$s), 1, usize::MAX, false)
    };
}

static SPARSE_INDICES: Schema = obj(
    "accessorSparseIndices",
    &[("bufferView", INDEX, true), ("byteOffset", INDEX, false), ("componentType", T::Ints(&[5121, 5123, 5125]), true)],
);
static SPARSE_VALUES: Schema = obj("accessorSparseValues", &[("bufferView", INDEX, true), ("byteOffset", INDEX, false)]);
static SPARSE: Schema = obj(
    "accessorSparse",
    &[("count", T::Int(1), true), ("indices", T::Obj(&SPARSE_INDICES), true), ("values", T::Obj(&SPARSE_VALUES), true)],
);
static ACCESSOR: Schema = Schema {
    kind: "accessor",
    props: &[
        ("bufferView", INDEX, false),
        ("byteOffset", INDEX, false),
        ("componentType", T::Ints(&[5120, 5121, 5122, 5123, 5125, 5126]), true),
        ("normalized", T::Bool, false),
        ("count", T::Int(1), true),
        ("type", T::Strs(&["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"]), true),
        ("max", T::Arr(&ANY_NUM, 1, 16, false), false),
        ("min", T::Arr(&ANY_NUM, 1, 16, false), false),
        ("sparse", T::Obj(&SPARSE), false),
    ],
    deps: &[("byteOffset", "bufferView")],
};
static TARGET: Schema = obj("animationChannelTarget", &[("node", INDEX, false), ("path", T::Str, true)]);
static CHANNEL: Schema = obj("animationChannel", &[("sampler", INDEX, true), ("target", T::Obj(&TARGET), true)]);
static ANIM_SAMPLER: Schema = obj(
    "animationSampler",
    &[("input", INDEX, true), ("interpolation", T::Strs(&["LINEAR", "STEP", "CUBICSPLINE"]), false), ("output", INDEX, true)],
);
static ANIMATION: Schema = obj(
    "animation",
    &[
        ("channels", T::Arr(&T::Obj(&CHANNEL), 1, usize::MAX, false), true),
        ("samplers", T::Arr(&T::Obj(&ANIM_SAMPLER), 1, usize::MAX, false), true),
    ],
);
static ASSET: Schema = obj(
    "asset",
    &[("copyright", T::Str, false), ("generator", T::Str, false), ("version", T::Version, true), ("minVersion", T::Version, false)],
);
static BUFFER: Schema = obj("buffer", &[("uri", T::Str, false), ("byteLength", T::Int(1), true)]);
static BUFFER_VIEW: Schema = obj(
    "bufferView",
    &[
        ("buffer", INDEX, true),
        ("byteOffset", INDEX, false),
        ("byteLength", T::Int(1), true),
        ("byteStride", T::IntStep(4, 252, 4), false),
        ("target", T::Ints(&[34962, 34963]), false),
    ],
);
static ORTHOGRAPHIC: Schema =
    obj("cameraOrthographic", &[("xmag", ANY_NUM, true), ("ymag", ANY_NUM, true), ("zfar", above(0.0), true), ("znear", NONNEG, true)]);
static PERSPECTIVE: Schema = obj(
    "cameraPerspective",
    &[("aspectRatio", above(0.0), false), ("yfov", above(0.0), true), ("zfar", above(0.0), false), ("znear", above(0.0), true)],
);
static CAMERA: Schema = obj(
    "camera",
    &[
        ("orthographic", T::Obj(&ORTHOGRAPHIC), false),
        ("perspective", T::Obj(&PERSPECTIVE), false),
        ("type", T::Strs(&["perspective", "orthographic"]), true),
    ],
);
static IMAGE: Schema = Schema {
    kind: "image",
    props: &[("uri", T::Str, false), ("mimeType", T::Str, false), ("bufferView", INDEX, false)],
    deps: &[("bufferView", "mimeType")],
};
static PBR: Schema = obj(
    "materialPbrMetallicRoughness",
    &[
        ("baseColorFactor", COLOR4, false),
        ("baseColorTexture", TEX, false),
        ("metallicFactor", UNIT, false),
        ("roughnessFactor", UNIT, false),
        ("metallicRoughnessTexture", TEX, false),
    ],
);
static MATERIAL: Schema = obj(
    "material",
    &[
        ("pbrMetallicRoughness", T::Obj(&PBR), false),
        ("normalTexture", T::Obj(&NORMAL_TEXTURE), false),
        ("occlusionTexture", T::Obj(&OCCLUSION_TEXTURE), false),
        ("emissiveTexture", TEX, false),
        ("emissiveFactor", COLOR3, false),
        ("alphaMode", T::Strs(&["OPAQUE", "MASK", "BLEND"]), false),
        ("alphaCutoff", NONNEG, false),
        ("doubleSided", T::Bool, false),
    ],
);
static PRIMITIVE: Schema = obj(
    "meshPrimitive",
    &[
        ("attributes", T::Map(&INDEX, 1), true),
        ("indices", INDEX, false),
        ("material", INDEX, false),
        ("mode", T::Ints(&[0, 1, 2, 3, 4, 5, 6]), false),
        ("targets", T::Arr(&T::Map(&INDEX, 1), 1, usize::MAX, false), false),
    ],
);
static MESH: Schema = obj(
    "mesh",
    &[("primitives", T::Arr(&T::Obj(&PRIMITIVE), 1, usize::MAX, false), true), ("weights", T::Arr(&ANY_NUM, 1, usize::MAX, false), false)],
);
static NODE: Schema = Schema {
    kind: "node",
    props: &[
        ("camera", INDEX, false),
        ("children", INDICES, false),
        ("skin", INDEX, false),
        ("matrix", T::Arr(&ANY_NUM, 16, 16, false), false),
        ("mesh", INDEX, false),
        ("rotation", T::Arr(&num(-1.0, 1.0), 4, 4, false), false),
        ("scale", T::Arr(&ANY_NUM, 3, 3, false), false),
        ("translation", T::Arr(&ANY_NUM, 3, 3, false), false),
        ("weights", T::Arr(&ANY_NUM, 1, usize::MAX, false), false),
    ],
    deps: &[("skin", "mesh"), ("weights", "mesh")],
};
const WRAP: T = T::Ints(&[33071, 33648, 10497]);
static SAMPLER: Schema = obj(
    "sampler",
    &[
        ("magFilter", T::Ints(&[9728, 9729]), false),
        ("minFilter", T::Ints(&[9728, 9729, 9984, 9985, 9986, 9987]), false),
        ("wrapS", WRAP, false),
        ("wrapT", WRAP, false),
    ],
);
static SCENE: Schema = obj("scene", &[("nodes", INDICES, false)]);
static SKIN: Schema = obj("skin", &[("inverseBindMatrices", INDEX, false), ("skeleton", INDEX, false), ("joints", INDICES, true)]);
static TEXTURE: Schema = obj("texture", &[("sampler", INDEX, false), ("source", INDEX, false)]);

/// The document's root (glTF 2.0 §5.17).
pub(super) static ROOT: Schema = Schema {
    kind: "glTF",
    props: &[
        ("extensionsUsed", STRINGS, false),
        ("extensionsRequired", STRINGS, false),
        ("accessors", list!(ACCESSOR), false),
        ("animations", list!(ANIMATION), false),
        ("asset", T::Obj(&ASSET), true),
        ("buffers", list!(BUFFER), false),
        ("bufferViews", list!(BUFFER_VIEW), false),
        ("cameras", list!(CAMERA), false),
        ("images", list!(IMAGE), false),
        ("materials", list!(MATERIAL), false),
        ("meshes", list!(MESH), false),
        ("nodes", list!(NODE), false),
        ("samplers", list!(SAMPLER), false),
        ("scene", INDEX, false),
        ("scenes", list!(SCENE), false),
        ("skins", list!(SKIN), false),
        ("textures", list!(TEXTURE), false),
    ],
    deps: &[("extensionsRequired", "extensionsUsed")],
};

// Extensions: (name, the object kind it attaches to, its schema). A known extension met
// anywhere else is an error; an unknown one is not checked.
static LIGHT_SPOT: Schema = obj(
    "lightSpot",
    &[
        ("innerConeAngle", T::Num(Range { min: 0.0, max: std::f64::consts::FRAC_PI_2, min_open: false, max_open: true }), false),
        ("outerConeAngle", T::Num(Range { min: 0.0, max: std::f64::consts::FRAC_PI_2, min_open: true, max_open: false }), false),
    ],
);
static LIGHT: Schema = obj(
    "light",
    &[
        ("color", COLOR3, false),
        ("intensity", NONNEG, false),
        ("spot", T::Obj(&LIGHT_SPOT), false),
        ("type", T::Strs(&["directional", "point", "spot"]), true),
        ("range", above(0.0), false),
    ],
);
static LIGHTS_ROOT: Schema = obj("KHR_lights_punctual", &[("lights", list!(LIGHT), true)]);
static LIGHTS_NODE: Schema = obj("KHR_lights_punctual", &[("light", INDEX, true)]);
static ANISOTROPY: Schema = obj(
    "KHR_materials_anisotropy",
    &[("anisotropyStrength", UNIT, false), ("anisotropyRotation", ANY_NUM, false), ("anisotropyTexture", TEX, false)],
);
static CLEARCOAT: Schema = obj(
    "KHR_materials_clearcoat",
    &[
        ("clearcoatFactor", UNIT, false),
        ("clearcoatTexture", TEX, false),
        ("clearcoatRoughnessFactor", UNIT, false),
        ("clearcoatRoughnessTexture", TEX, false),
        ("clearcoatNormalTexture", T::Obj(&NORMAL_TEXTURE), false),
    ],
);
static DISPERSION: Schema = obj("KHR_materials_dispersion", &[("dispersion", NONNEG, false)]);
static EMISSIVE_STRENGTH: Schema = obj("KHR_materials_emissive_strength", &[("emissiveStrength", NONNEG, false)]);
static IOR: Schema = obj("KHR_materials_ior", &[("ior", T::Ior, false)]);
static IRIDESCENCE: Schema = obj(
    "KHR_materials_iridescence",
    &[
        ("iridescenceFactor", UNIT, false),
        ("iridescenceTexture", TEX, false),
        ("iridescenceIor", num(1.0, f64::INFINITY), false),
        ("iridescenceThicknessMinimum", NONNEG, false),
        ("iridescenceThicknessMaximum", NONNEG, false),
        ("iridescenceThicknessTexture", TEX, false),
    ],
);
static SPEC_GLOSS: Schema = obj(
    "KHR_materials_pbrSpecularGlossiness",
    &[
        ("diffuseFactor", COLOR4, false),
        ("diffuseTexture", TEX, false),
        ("specularFactor", COLOR3, false),
        ("glossinessFactor", UNIT, false),
        ("specularGlossinessTexture", TEX, false),
    ],
);
static SHEEN: Schema = obj(
    "KHR_materials_sheen",
    &[
        ("sheenColorFactor", COLOR3, false),
        ("sheenColorTexture", TEX, false),
        ("sheenRoughnessFactor", UNIT, false),
        ("sheenRoughnessTexture", TEX, false),
    ],
);
static SPECULAR: Schema = obj(
    "KHR_materials_specular",
    &[
        ("specularFactor", UNIT, false),
        ("specularTexture", TEX, false),
        ("specularColorFactor", T::Arr(&NONNEG, 3, 3, false), false),
        ("specularColorTexture", TEX, false),
    ],
);
static TRANSMISSION: Schema =
    obj("KHR_materials_transmission", &[("transmissionFactor", UNIT, false), ("transmissionTexture", TEX, false)]);
static UNLIT: Schema = obj("KHR_materials_unlit", &[]);
static VOLUME: Schema = obj(
    "KHR_materials_volume",
    &[
        ("thicknessFactor", NONNEG, false),
        ("thicknessTexture", TEX, false),
        ("attenuationDistance", above(0.0), false),
        ("attenuationColor", COLOR3, false),
    ],
);
static VARIANT: Schema = obj("variant", &[("name", T::Str, true)]);
static VARIANTS_ROOT: Schema = obj("KHR_materials_variants", &[("variants", list!(VARIANT), true)]);
static MAPPING: Schema = obj("mapping", &[("variants", INDICES, true), ("material", INDEX, true), ("name", T::Str, false)]);
static VARIANTS_PRIMITIVE: Schema = obj("KHR_materials_variants", &[("mappings", list!(MAPPING), true)]);
static TEXTURE_TRANSFORM: Schema = obj(
    "KHR_texture_transform",
    &[
        ("offset", T::Arr(&ANY_NUM, 2, 2, false), false),
        ("rotation", ANY_NUM, false),
        ("scale", T::Arr(&ANY_NUM, 2, 2, false), false),
        ("texCoord", INDEX, false),
    ],
);
static NODE_VISIBILITY: Schema = obj("KHR_node_visibility", &[("visible", T::Bool, false)]);
static TEXTURE_SOURCE: Schema = obj("textureSource", &[("source", INDEX, false)]);
static POINTER: Schema = obj("KHR_animation_pointer", &[("pointer", T::Pointer, true)]);

/// Known extensions: (name, kind of object it extends, schema).
pub(super) const EXTENSIONS: &[(&str, &str, &Schema)] = &[
    ("KHR_lights_punctual", "glTF", &LIGHTS_ROOT),
    ("KHR_lights_punctual", "node", &LIGHTS_NODE),
    ("KHR_materials_anisotropy", "material", &ANISOTROPY),
    ("KHR_materials_clearcoat", "material", &CLEARCOAT),
    ("KHR_materials_dispersion", "material", &DISPERSION),
    ("KHR_materials_emissive_strength", "material", &EMISSIVE_STRENGTH),
    ("KHR_materials_ior", "material", &IOR),
    ("KHR_materials_iridescence", "material", &IRIDESCENCE),
    ("KHR_materials_pbrSpecularGlossiness", "material", &SPEC_GLOSS),
    ("KHR_materials_sheen", "material", &SHEEN),
    ("KHR_materials_specular", "material", &SPECULAR),
    ("KHR_materials_transmission", "material", &TRANSMISSION),
    ("KHR_materials_unlit", "material", &UNLIT),
    ("KHR_materials_volume", "material", &VOLUME),
    ("KHR_materials_variants", "glTF", &VARIANTS_ROOT),
    ("KHR_materials_variants", "meshPrimitive", &VARIANTS_PRIMITIVE),
    ("KHR_texture_transform", "textureInfo", &TEXTURE_TRANSFORM),
    ("KHR_node_visibility", "node", &NODE_VISIBILITY),
    ("EXT_texture_webp", "texture", &TEXTURE_SOURCE),
    ("KHR_texture_basisu", "texture", &TEXTURE_SOURCE),
    ("EXT_texture_avif", "texture", &TEXTURE_SOURCE),
    ("KHR_animation_pointer", "animationChannelTarget", &POINTER),
    // An extension without objects of its own: met as an object anywhere, it is misplaced.
    ("KHR_mesh_quantization", "", &UNLIT),
];

/// The first schema violation in `root`, as (JSON pointer, message).
pub(super) fn check(root: &Value) -> Result<(), (String, String)> {
    let strings = |key: &str| -> Vec<String> {
        root.get(key).and_then(Value::as_array).map(|u| u.iter().filter_map(Value::as_str).map(str::to_owned).collect()).unwrap_or_default()
    };
    let root_extensions = root.get("extensions").and_then(Value::as_object).map(|e| e.keys().cloned().collect()).unwrap_or_default();
    let c = Checker { used: strings("extensionsUsed"), root_extensions };
    c.object(root, &ROOT, String::new())?;
    let required = strings("extensionsRequired");
    for (i, r) in required.iter().enumerate() {
        if !c.used.contains(r) {
            return fail(&format!("/extensionsRequired/{i}"), format!("{r:?} is required but not in extensionsUsed"));
        }
    }
    // Extensions that change how data is read cannot be optional.
    for (i, u) in c.used.iter().enumerate() {
        if u == "KHR_mesh_quantization" && !required.contains(u) {
            return fail(&format!("/extensionsUsed/{i}"), format!("{u} must also be in extensionsRequired"));
        }
    }
    Ok(())
}

struct Checker {
    /// `extensionsUsed`.
    used: Vec<String>,
    /// The extensions of the root object (the lights and variants that nodes and
    /// primitives refer to).
    root_extensions: Vec<String>,
}

type Res = Result<(), (String, String)>;

fn fail(at: &str, msg: String) -> Res {
    Err((if at.is_empty() { "/".to_string() } else { at.to_string() }, msg))
}

/// A JSON number that is an integer (`3` or `3.0`).
fn int_of(v: &Value) -> Option<i64> {
    v.as_i64().or_else(|| v.as_f64().filter(|x| x.fract() == 0.0 && x.abs() < 9.0e15).map(|x| x as i64))
}

fn kind_name(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

impl Checker {
    fn object(&self, v: &Value, s: &Schema, at: String) -> Res {
        let Some(o) = v.as_object() else { return fail(&at, format!("must be an object, is {}", kind_name(v))) };
        for &(name, ref ty, required) in s.props {
            match o.get(name) {
                Some(x) => self.value(x, ty, format!("{at}/{name}"))?,
                None if required => return fail(&format!("{at}/{name}"), format!("missing: a {} needs '{name}'", s.kind)),
                None => {}
            }
        }
        for &(a, b) in s.deps {
            if o.contains_key(a) && !o.contains_key(b) {
                return fail(&format!("{at}/{a}"), format!("needs '{b}', which is not defined"));
            }
        }
        if let Some(n) = o.get("name") {
            if !n.is_string() {
                return fail(&format!("{at}/name"), format!("must be a string, is {}", kind_name(n)));
            }
        }
        if let Some(e) = o.get("extensions") {
            self.extensions(e, s.kind, &format!("{at}/extensions"))?;
        }
        self.rules(o, s.kind, &at)
    }

    fn extensions(&self, e: &Value, kind: &str, at: &str) -> Res {
        let Some(e) = e.as_object() else { return fail(at, format!("must be an object, is {}", kind_name(e))) };
        for (name, x) in e {
            let here = format!("{at}/{}", super::pointer::esc(name));
            if !x.is_object() {
                return fail(&here, format!("an extension must be an object, is {}", kind_name(x)));
            }
            if !self.used.iter().any(|u| u == name) {
                return fail(&here, format!("extension {name:?} is not declared in extensionsUsed"));
            }
            let mut known = EXTENSIONS.iter().filter(|k| k.0 == name).peekable();
            if known.peek().is_none() {
                continue;
            }
            match known.find(|k| k.1 == kind) {
                Some(&(_, _, s)) => {
                    let has_root_part = EXTENSIONS.iter().any(|k| k.0 == name && k.1 == "glTF");
                    if kind != "glTF" && has_root_part && !self.root_extensions.contains(name) {
                        return fail(&here, format!("needs /extensions/{name}, which is not defined"));
                    }
                    self.object(x, s, here)?;
                }
                None => return fail(&here, format!("{name} cannot extend a {kind}")),
            }
        }
        Ok(())
    }

    fn value(&self, v: &Value, ty: &T, at: String) -> Res {
        let bad = |want: &str| fail(&at, format!("must be {want}, is {v}"));
        match *ty {
            T::Bool => {
                if v.is_boolean() {
                    Ok(())
                } else {
                    bad("true or false")
                }
            }
            T::Str => {
                if v.is_string() {
                    Ok(())
                } else {
                    bad("a string")
                }
            }
            T::Pointer => match v.as_str() {
                Some(p) if p.is_empty() || (p.starts_with('/') && valid_escapes(p)) => Ok(()),
                _ => bad("a JSON pointer (RFC 6901: /a/b/0)"),
            },
            T::Version => match v.as_str() {
                Some(s) if is_version(s) => Ok(()),
                _ => bad("a version \"major.minor\""),
            },
            // Enumerations are open (the schema's `anyOf` of constants and a type, for
            // future versions): a value outside the list is a warning; the reader skips
            // what it cannot use.
            T::Strs(set) => match v.as_str() {
                Some(s) => {
                    if !set.contains(&s) {
                        tracing::warn!("{at}: {s:?} is not one of {set:?}");
                    }
                    Ok(())
                }
                None => bad("a string"),
            },
            T::Int(min) => match int_of(v) {
                Some(i) if i >= min => Ok(()),
                Some(_) => bad(&format!("at least {min}")),
                None => bad("an integer"),
            },
            T::Ints(set) => match int_of(v) {
                Some(i) => {
                    if !set.contains(&i) {
                        tracing::warn!("{at}: {i} is not one of {set:?}");
                    }
                    Ok(())
                }
                None => bad("an integer"),
            },
            T::IntStep(min, max, step) => match int_of(v) {
                Some(i) if (min..=max).contains(&i) && i % step == 0 => Ok(()),
                _ => bad(&format!("an integer from {min} to {max}, a multiple of {step}")),
            },
            T::Num(r) => match v.as_f64() {
                Some(x) => {
                    let lo = if r.min_open { x > r.min } else { x >= r.min };
                    let hi = if r.max_open { x < r.max } else { x <= r.max };
                    if lo && hi {
                        Ok(())
                    } else {
                        let (a, b) = (if r.min_open { "(" } else { "[" }, if r.max_open { ")" } else { "]" });
                        bad(&format!("a number in {a}{}, {}{b}", r.min, r.max))
                    }
                }
                None => bad("a number"),
            },
            T::Arr(item, min, max, unique) => {
                let Some(a) = v.as_array() else { return bad("an array") };
                if a.is_empty() && min > 0 {
                    return fail(&at, "must not be empty".into());
                }
                if a.len() < min || a.len() > max {
                    let want = if min == max { format!("{min}") } else { format!("{min} to {max}") };
                    return fail(&at, format!("has {} elements; it needs {want}", a.len()));
                }
                for (i, x) in a.iter().enumerate() {
                    self.value(x, item, format!("{at}/{i}"))?;
                    if unique && a[..i].contains(x) {
                        return fail(&format!("{at}/{i}"), format!("{x} appears twice"));
                    }
                }
                Ok(())
            }
            T::Map(item, min) => {
                let Some(o) = v.as_object() else { return bad("an object") };
                if o.len() < min {
                    return fail(&at, "must not be empty".into());
                }
                o.iter().try_for_each(|(k, x)| self.value(x, item, format!("{at}/{}", super::pointer::esc(k))))
            }
            T::Obj(s) => self.object(v, s, at),
            T::Ior => match v.as_f64() {
                Some(x) if x == 0.0 || x >= 1.0 => Ok(()),
                _ => bad("0 or a number of at least 1"),
            },
        }
    }

    /// Rules the schema tables cannot say (one of two properties, orders of values).
    fn rules(&self, o: &serde_json::Map<String, Value>, kind: &str, at: &str) -> Res {
        let f = |k: &str| o.get(k).and_then(Value::as_f64);
        match kind {
            "camera" => {
                let t = o.get("type").and_then(Value::as_str).unwrap_or("");
                let Some(other) = (match t {
                    "perspective" => Some("orthographic"),
                    "orthographic" => Some("perspective"),
                    _ => None,
                }) else {
                    return Ok(());
                };
                if !o.contains_key(t) {
                    return fail(&format!("{at}/{t}"), format!("missing: a camera of type {t:?} needs '{t}'"));
                }
                if o.contains_key(other) {
                    return fail(&format!("{at}/{other}"), format!("a camera of type {t:?} cannot also have '{other}'"));
                }
            }
            "cameraPerspective" | "cameraOrthographic" => {
                if let (Some(n), Some(z)) = (f("znear"), f("zfar")) {
                    if z <= n {
                        return fail(&format!("{at}/zfar"), format!("zfar ({z}) must be greater than znear ({n})"));
                    }
                }
                if kind == "cameraOrthographic" {
                    for k in ["xmag", "ymag"] {
                        if f(k) == Some(0.0) {
                            return fail(&format!("{at}/{k}"), format!("{k} must not be zero"));
                        }
                    }
                }
            }
            "asset" => {
                let v = |k: &str| {
                    o.get(k)
                        .and_then(Value::as_str)
                        .and_then(|s| s.split_once('.'))
                        .and_then(|(a, b)| Some((a.parse::<u64>().ok()?, b.parse::<u64>().ok()?)))
                };
                if let (Some(min), Some(ver)) = (v("minVersion"), v("version")) {
                    if min > ver {
                        return fail(
                            &format!("{at}/minVersion"),
                            format!("minVersion {}.{} is greater than version {}.{}", min.0, min.1, ver.0, ver.1),
                        );
                    }
                }
            }
            "image" if o.contains_key("uri") == o.contains_key("bufferView") => {
                return fail(at, "an image needs exactly one of 'uri' and 'bufferView'".into());
            }
            "node" => {
                if o.contains_key("matrix") && ["translation", "rotation", "scale"].iter().any(|k| o.contains_key(*k)) {
                    return fail(&format!("{at}/matrix"), "a node has a matrix or translation/rotation/scale, not both".into());
                }
                if let Some(Value::Array(q)) = o.get("rotation") {
                    let n2: f64 = q.iter().filter_map(Value::as_f64).map(|x| x * x).sum();
                    if (n2.sqrt() - 1.0).abs() > f64::from(super::pointer::UNIT_TOLERANCE) {
                        return fail(
                            &format!("{at}/rotation"),
                            format!("the rotation quaternion has length {:.6}; it must be normalized", n2.sqrt()),
                        );
                    }
                }
            }
            "light" if o.get("type").and_then(Value::as_str) == Some("spot") && !o.contains_key("spot") => {
                return fail(&format!("{at}/spot"), "missing: a spot light needs 'spot'".into());
            }
            "lightSpot" => {
                let inner = f("innerConeAngle").unwrap_or(0.0);
                let outer = f("outerConeAngle").unwrap_or(std::f64::consts::FRAC_PI_4);
                if outer <= inner {
                    return fail(
                        &format!("{at}/outerConeAngle"),
                        format!("outerConeAngle ({outer}) must be greater than innerConeAngle ({inner})"),
                    );
                }
            }
            _ => {}
        }
        Ok(())
    }
}

fn is_version(s: &str) -> bool {
    let mut parts = s.split('.');
    let digits = |p: Option<&str>| p.is_some_and(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()));
    digits(parts.next()) && digits(parts.next()) && parts.next().is_none()
}

/// `~` only as `~0` or `~1` (RFC 6901 §3).
fn valid_escapes(p: &str) -> bool {
    let b = p.as_bytes();
    b.iter().enumerate().all(|(i, &c)| c != b'~' || matches!(b.get(i + 1), Some(b'0' | b'1')))
}

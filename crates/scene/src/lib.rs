//! # lucent_scene
//!
//! What the world contains, as plain data ([`Scene`]), and importers that fill it:
//! Wavefront OBJ + MTL (also `.obj.gz`), PLY (ASCII and binary) and glTF 2.0
//! (`.gltf` + `.bin`, `.glb`) and Mitsuba 3 XML scenes. Every error names the file and the
//! line (and column) or glTF path.
//! Missing textures give a warning and the plain colour.
#![deny(missing_docs)]

pub mod anim;
pub mod bsdf;
mod camera;
mod demo;
mod error;
mod gltf;
mod mitsuba;
mod model;
mod obj;
mod options;
mod ply;
pub mod spectrum;
mod sunflowers;
mod texture;

pub use bsdf::{Alpha, Bsdf, ColorTex, Distribution, FloatTex, NormalMap, Principled, PrincipledLobes, Rough, Sides};
pub use camera::CameraDesc;
pub use demo::{demo_scene, studio_scene, torus};
pub use error::ImportError;
pub use gltf::{load_gltf, load_gltf_with, parse_gltf, parse_gltf_with};
pub use mitsuba::serialized::{parse_serialized, serialized_count, SerializedMesh};
pub use mitsuba::{load_hdr, load_mitsuba, load_mitsuba_with, parse_mitsuba, parse_mitsuba_with};
pub use model::*;
pub use obj::{load_obj, parse_obj, parse_obj_with};
pub use options::LoadOptions;
pub use ply::{load_ply, parse_ply};
pub use sunflowers::{sunflower_mesh, sunflower_scene, FLOWERS};
pub use texture::{
    contain_decoder_panics, decode_image, decoder_panic, open_image, srgb_to_linear, texture_from_image, Texture, Wrap, FREE_TEXEL_BYTES,
    MAX_EXPANSION, MAX_TEXTURE_BYTES, MAX_TEXTURE_SIDE,
};

use std::path::Path;

/// Loads a scene file, choosing the importer by extension.
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    load_with(path, &LoadOptions::default())
}

/// [`load`] with options.
pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Scene, ImportError> {
    let name = path.file_name().map(|n| n.to_string_lossy().to_lowercase()).unwrap_or_default();
    let stem = name.strip_suffix(".gz").unwrap_or(&name);
    if stem.ends_with(".obj") {
        load_obj(path)
    } else if stem.ends_with(".ply") {
        load_ply(path)
    } else if name.ends_with(".gltf") || name.ends_with(".glb") {
        load_gltf_with(path, options)
    } else if name.ends_with(".xml") {
        load_mitsuba(path)
    } else {
        Err(ImportError::UnknownFormat(path.to_path_buf()))
    }
}

//! Texture loading: decoded once into 8-bit texels (sRGB colours are linearized when sampled).

use crate::model::{Texture, Wrap};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The sRGB transfer function, inverted.
#[must_use]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Decodes an image into a texture (`srgb`: colour data to linearize).
pub fn texture_from_image(name: String, img: image::DynamicImage, wrap_u: Wrap, wrap_v: Wrap, srgb: bool) -> Texture {
    let rgba = img.to_rgba8();
    let (width, height) = (rgba.width(), rgba.height());
    let texels = rgba.pixels().map(|p| p.0).collect();
    Texture::new(name, width, height, texels, srgb, wrap_u, wrap_v)
}

/// Loads each texture file once; missing or broken files give a warning and no texture.
#[derive(Default)]
pub(crate) struct TextureCache {
    by_path: HashMap<PathBuf, Option<u32>>,
    textures: Vec<Texture>,
}

impl TextureCache {
    pub(crate) fn load(&mut self, path: &Path, wrap: Wrap, srgb: bool, referrer: &str) -> Option<u32> {
        if let Some(&id) = self.by_path.get(path) {
            return id;
        }
        let id = match image::open(path) {
            Ok(img) => {
                self.textures.push(texture_from_image(path.display().to_string(), img, wrap, wrap, srgb));
                Some((self.textures.len() - 1) as u32)
            }
            Err(e) => {
                tracing::warn!("{referrer}: texture {} not loaded ({e}); using the plain colour", path.display());
                None
            }
        };
        self.by_path.insert(path.to_path_buf(), id);
        id
    }

    pub(crate) fn into_textures(self) -> Vec<Texture> {
        self.textures
    }
}

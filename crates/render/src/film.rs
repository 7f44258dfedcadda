//! The film: linear RGB per pixel, written as 8-bit sRGB PNG or linear float EXR.

use glam::Vec3;
use std::path::Path;

/// Errors of writing an image.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// Encoding or writing failed.
    #[error("{path}: {source}")]
    Image {
        /// File.
        path: String,
        /// Cause.
        source: image::ImageError,
    },
    /// Unknown extension.
    #[error("{0}: unknown image type (use .png or .exr)")]
    Format(String),
}

/// A rendered image in linear RGB.
#[derive(Clone, Debug)]
pub struct Film {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Pixels, row-major, top row first.
    pub pixels: Vec<Vec3>,
}

/// Linear to sRGB transfer.
#[must_use]
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

impl Film {
    /// A black film.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        // PERF: a constant zero fill compiles to `memset` (`filled` stores the 12-byte
        // pixel one by one).
        Self { width, height, pixels: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    /// A film with every pixel `c`.
    #[must_use]
    pub fn filled(width: u32, height: u32, c: Vec3) -> Self {
        Self { width, height, pixels: vec![c; width as usize * height as usize] }
    }

    /// Pixel at (x, y).
    #[must_use]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }

    /// 8-bit sRGB bytes (RGB, row-major).
    #[must_use]
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| {
                let q = |c: f32| (linear_to_srgb(if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 }) * 255.0 + 0.5) as u8;
                [q(p.x), q(p.y), q(p.z)]
            })
            .collect()
    }

    /// Writes `.png` (8-bit sRGB) or `.exr` (linear f32).
    pub fn save(&self, path: &Path) -> Result<(), OutputError> {
        let name = path.display().to_string();
        let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
        let err = |source| OutputError::Image { path: name.clone(), source };
        match ext.as_str() {
            "png" => image::RgbImage::from_raw(self.width, self.height, self.to_srgb8()).map_or(Ok(()), |img| img.save(path).map_err(err)),
            "exr" => {
                let data: Vec<f32> = self.pixels.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
                image::Rgb32FImage::from_raw(self.width, self.height, data).map_or(Ok(()), |img| img.save(path).map_err(err))
            }
            _ => Err(OutputError::Format(name)),
        }
    }
}

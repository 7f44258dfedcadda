//! Texture loading: decoded once into 8-bit texels (sRGB colours are linearized when sampled).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// How texture coordinates outside [0, 1] are treated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Wrap {
    /// Tile.
    #[default]
    Repeat,
    /// Clamp to the edge.
    Clamp,
    /// Tile, mirrored every other time.
    Mirror,
}

/// An RGBA texture: 8-bit codes as the image stored them, decoded to linear values when
/// sampled (through `lut`, the sRGB curve for colour images).
///
/// PERF: four bytes a texel, not four floats: the BART kitchen's textures went from 40 to
/// 10 MB, and their sampling (random accesses into far-away floors) was a sixth of a frame.
#[derive(Clone, Debug)]
pub struct Texture {
    /// Name or path.
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Texels in 4×4 blocks (one 64-byte cache line each, blocks row by row; see
    /// [`Texture::texel_at`]): red, green, blue codes (through `lut`) and a linear alpha
    /// code. PERF: a bilinear lookup's four texels share one line most of the time, where
    /// rows in order always needed two.
    texels: Vec<[u8; 4]>,
    /// Blocks per row.
    blocks_x: usize,
    /// Linear value of each colour code.
    pub lut: [f32; 256],
    /// Wrap mode in u.
    pub wrap_u: Wrap,
    /// Wrap mode in v.
    pub wrap_v: Wrap,
    /// Lookups take the nearest texel (Mitsuba's `filter_type` `nearest`), else blend the
    /// four around bilinearly.
    pub nearest: bool,
}

impl Texture {
    /// A texture over 8-bit texels; `srgb`: the colour codes are sRGB-encoded (colour
    /// images), else linear (data such as roughness, or made-up textures).
    ///
    /// `texels` are row-major, row 0 at the top; missing ones (fewer than `width ×
    /// height`) are white.
    #[must_use]
    pub fn new(name: String, width: u32, height: u32, texels: Vec<[u8; 4]>, srgb: bool, wrap_u: Wrap, wrap_v: Wrap) -> Self {
        let mut lut = [0.0f32; 256];
        for (i, v) in lut.iter_mut().enumerate() {
            let c = i as f32 / 255.0;
            *v = if srgb { crate::texture::srgb_to_linear(c) } else { c };
        }
        let (w, h) = (width as usize, height as usize);
        let blocks_x = w.div_ceil(4);
        let mut tiled = vec![[255u8; 4]; blocks_x * 4 * h.div_ceil(4) * 4];
        for y in 0..h {
            for x in 0..w {
                if let (Some(t), Some(&c)) = (tiled.get_mut(Self::index(blocks_x, x, y)), texels.get(y * w + x)) {
                    *t = c;
                }
            }
        }
        Self { name, width, height, texels: tiled, blocks_x, lut, wrap_u, wrap_v, nearest: false }
    }

    #[inline(always)]
    fn index(blocks_x: usize, x: usize, y: usize) -> usize {
        (((y >> 2) * blocks_x + (x >> 2)) << 4) | ((y & 3) << 2) | (x & 3)
    }

    /// The texel at column `x`, row `y` (row 0 at the top) in linear RGBA; white outside
    /// the image.
    #[inline(always)]
    #[must_use]
    pub fn texel_at(&self, x: usize, y: usize) -> glam::Vec4 {
        if x >= self.width as usize || y >= self.height as usize {
            return glam::Vec4::ONE;
        }
        self.texels.get(Self::index(self.blocks_x, x, y)).map_or(glam::Vec4::ONE, |p| {
            glam::Vec4::new(self.lut[p[0] as usize], self.lut[p[1] as usize], self.lut[p[2] as usize], f32::from(p[3]) / 255.0)
        })
    }
}

/// The sRGB transfer function, inverted.
#[must_use]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The largest texture side lucent decodes (pixels).
pub const MAX_TEXTURE_SIDE: u32 = 16_384;
/// The most memory one texture's decoding may take (bytes): a 16k × 16k RGBA image.
pub const MAX_TEXTURE_BYTES: u64 = 4 * (MAX_TEXTURE_SIDE as u64) * (MAX_TEXTURE_SIDE as u64);

fn limits() -> image::Limits {
    let mut l = image::Limits::default();
    l.max_image_width = Some(MAX_TEXTURE_SIDE);
    l.max_image_height = Some(MAX_TEXTURE_SIDE);
    l.max_alloc = Some(MAX_TEXTURE_BYTES);
    l
}

/// How many bytes of RGBA texels one encoded byte may claim, beyond
/// [`FREE_TEXEL_BYTES`]. No real PNG or JPEG comes near it (deflate expands at most about
/// 1032 to 1; a flat 4:2:0 JPEG needs some 12 bits per 16×16 block, about 700 to 1), but a
/// truncated file whose header claims 16k × 16k pixels does: its decoder fills the
/// missing rows, so 520 bytes would make 1 GB (found by the fuzz campaign).
pub const MAX_EXPANSION: u64 = 4096;
/// Texel bytes any image may claim whatever its size (a 2048 × 2048 RGBA texture).
pub const FREE_TEXEL_BYTES: u64 = 1 << 24;

/// Decodes an encoded image (PNG or JPEG, by its first bytes) within the texture limits: an
/// image whose header claims more than [`MAX_TEXTURE_SIDE`] pixels a side, more than
/// [`MAX_TEXTURE_BYTES`] to decode, or more texels than its bytes can hold (see
/// [`MAX_EXPANSION`]) is an error before anything is allocated.
pub fn decode_image(bytes: &[u8]) -> image::ImageResult<image::DynamicImage> {
    // (A header the probe cannot read goes on to the decoder, which names what is wrong.)
    if let Ok((w, h)) = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format()?.into_dimensions() {
        let claimed = 4 * u64::from(w) * u64::from(h);
        if claimed > FREE_TEXEL_BYTES + MAX_EXPANSION * bytes.len() as u64 {
            tracing::warn!("an image of {} bytes claims {w} x {h} pixels: truncated or hostile", bytes.len());
            return Err(image::ImageError::Limits(image::error::LimitError::from_kind(image::error::LimitErrorKind::DimensionError)));
        }
    }
    let mut r = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format()?;
    r.limits(limits());
    // The decoders are third-party code that untrusted bytes reach, and one of them panics
    // on some malformed JPEGs (zune-jpeg 0.5.15, the newest release: an assertion in its
    // AVX2 upsampler, found by `scripts/fuzz`; the same class is open upstream as
    // etemesi254/zune-image#281). Such a panic is caught here and becomes this image's
    // error, so a bad texture is a warning and never takes the process down.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| r.decode())).unwrap_or_else(|p| {
        let why = p.downcast_ref::<&str>().map(|s| (*s).to_string()).or_else(|| p.downcast_ref::<String>().cloned()).unwrap_or_default();
        Err(image::ImageError::Decoding(image::error::DecodingError::new(
            image::error::ImageFormatHint::Unknown,
            format!("the image decoder failed on this data ({why})"),
        )))
    })
}

/// Whether a panic at `file` is one [`decode_image`] contains: inside an image decoder it
/// calls.
#[must_use]
pub fn decoder_panic(file: &str) -> bool {
    ["/zune-jpeg-0.", "/zune-core-0.", "/png-0.", "/image-0."].iter().any(|c| file.contains(c))
}

/// Wraps the process's panic hook (once) so that panics [`decode_image`] contains
/// ([`decoder_panic`]) are not reported as crashes: the image's warning already gives the
/// decoder's message. Every other panic goes to the hook that was there. For binaries and
/// for harnesses whose hook aborts on any panic (libFuzzer's), which would otherwise stop
/// at a contained one.
pub fn contain_decoder_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let prev = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !info.location().is_some_and(|l| decoder_panic(l.file())) {
                prev(info);
            }
        }));
    });
}

/// Opens and decodes an image file within the texture limits (see [`decode_image`]).
pub fn open_image(path: &Path) -> image::ImageResult<image::DynamicImage> {
    decode_image(&std::fs::read(path)?)
}

/// Decodes an image into a texture (`srgb`: colour data to linearize).
pub fn texture_from_image(name: String, img: image::DynamicImage, wrap_u: Wrap, wrap_v: Wrap, srgb: bool) -> Texture {
    let rgba = img.to_rgba8();
    let (width, height) = (rgba.width(), rgba.height());
    let texels = rgba.pixels().map(|p| p.0).collect();
    Texture::new(name, width, height, texels, srgb, wrap_u, wrap_v)
}

/// Loads each texture file once; missing or broken files give a warning and no texture.
/// (A file read with other settings, wrap mode, sRGB or nearest lookups, is another
/// texture.)
#[derive(Default)]
pub(crate) struct TextureCache {
    by_path: HashMap<(PathBuf, Wrap, bool, bool), Option<u32>>,
    textures: Vec<Texture>,
}

impl TextureCache {
    pub(crate) fn load(&mut self, path: &Path, wrap: Wrap, srgb: bool, referrer: &str) -> Option<u32> {
        self.load_with(path, wrap, srgb, false, referrer)
    }

    pub(crate) fn load_with(&mut self, path: &Path, wrap: Wrap, srgb: bool, nearest: bool, referrer: &str) -> Option<u32> {
        let key = (path.to_path_buf(), wrap, srgb, nearest);
        if let Some(&id) = self.by_path.get(&key) {
            return id;
        }
        let id = match open_image(path) {
            Ok(img) => {
                let mut t = texture_from_image(path.display().to_string(), img, wrap, wrap, srgb);
                t.nearest = nearest;
                self.textures.push(t);
                Some((self.textures.len() - 1) as u32)
            }
            Err(e) => {
                tracing::warn!("{referrer}: texture {} not loaded ({e}); using the plain colour", path.display());
                None
            }
        };
        self.by_path.insert(key, id);
        id
    }

    pub(crate) fn into_textures(self) -> Vec<Texture> {
        self.textures
    }
}

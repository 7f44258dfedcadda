//! The film: linear RGB per pixel, written as 8-bit sRGB PNG or linear float EXR.

use crate::color::srgb8_table;
use glam::Vec3;
use std::path::Path;

/// Errors of writing an image.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// Encoding or writing failed.
    #[error("{path}: {cause}")]
    Image {
        /// File.
        path: String,
        /// Cause (in the message, so not also a `source()`).
        cause: image::ImageError,
    },
    /// Unknown extension.
    #[error("{0}: unknown image type (use .png or .exr)")]
    Format(String),
    /// Writing a layered EXR failed.
    #[error("{path}: {msg}")]
    Exr {
        /// File.
        path: String,
        /// What failed.
        msg: String,
    },
}

/// What a denoiser is guided by, per pixel: the albedo of the first visible surface that is
/// not a mirror or clear glass (seen through them: times their throughput), its shading
/// normal (world space, unit; zero where the ray meets nothing) and its distance along the
/// way (infinite where the ray meets nothing); see `render_aovs`.
#[derive(Clone, Debug)]
pub struct Aovs {
    /// Albedo (the background colour where nothing is met).
    pub albedo: Film,
    /// Shading normal.
    pub normal: Film,
    /// Distance.
    pub depth: Vec<f32>,
    /// Emitted radiance of the surface toward the camera (zero for most; not written to
    /// files): a denoiser keeps it out of what it filters.
    pub emission: Film,
}

impl Aovs {
    /// The window `[x, y, width, height]` of every layer (see [`Film::crop`]).
    #[must_use]
    pub fn crop(&self, window: [u32; 4]) -> Aovs {
        let (_, depth) = crop_rows(&self.depth, self.albedo.width, self.albedo.height, window);
        Aovs { albedo: self.albedo.crop(window), normal: self.normal.crop(window), depth, emission: self.emission.crop(window) }
    }
}

/// The window `[x, y, width, height]` of a `width` × `height` row-major image `v`, clipped
/// to it: its size and its values.
fn crop_rows<T: Copy>(v: &[T], width: u32, height: u32, [x, y, cw, ch]: [u32; 4]) -> ((u32, u32), Vec<T>) {
    let (x0, y0) = (x.min(width), y.min(height));
    let (x1, y1) = (x.saturating_add(cw).min(width), y.saturating_add(ch).min(height));
    let w = width as usize;
    let row = |r: u32| v.get(r as usize * w + x0 as usize..r as usize * w + x1 as usize).unwrap_or(&[]);
    ((x1 - x0, y1 - y0), (y0..y1).flat_map(|r| row(r).iter().copied()).collect())
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

impl Film {
    /// The window `[x, y, width, height]` of the image (clipped to it: a window past the
    /// image's edge keeps what lies inside).
    #[must_use]
    pub fn crop(&self, window: [u32; 4]) -> Film {
        let ((width, height), pixels) = crop_rows(&self.pixels, self.width, self.height, window);
        Film { width, height, pixels }
    }

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
        let t = srgb8_table();
        // PERF: three `powf` per pixel took 4.4 ms of one thread per 512×384 frame (the
        // network device and `lucent animate` convert every frame); the table gives the
        // same bytes in 1.9 ms.
        // A sized buffer filled in place (collecting a `flat_map` grew it byte by byte).
        let mut out = vec![0u8; 3 * self.pixels.len()];
        for (o, p) in out.chunks_exact_mut(3).zip(&self.pixels) {
            o.copy_from_slice(&[t.encode(p.x), t.encode(p.y), t.encode(p.z)]);
        }
        out
    }

    /// Reads an image as linear RGB: `.exr` as it is, other formats (PNG, ...) decoded
    /// from sRGB. For reference images.
    pub fn load(path: &Path) -> Result<Self, OutputError> {
        let name = path.display().to_string();
        let img = image::open(path).map_err(|cause| OutputError::Image { path: name, cause })?;
        let exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        let rgb = img.to_rgb32f();
        let (width, height) = rgb.dimensions();
        let lin = |c: f32| if exr { c } else { lucent_scene::srgb_to_linear(c) };
        let pixels = rgb.pixels().map(|p| Vec3::new(lin(p.0[0]), lin(p.0[1]), lin(p.0[2]))).collect();
        Ok(Self { width, height, pixels })
    }

    /// The relative mean squared error against `reference` (issue 34's measure):
    /// mean((x − ref)² / (ref² + 0.01)) over pixels and channels; `None` when the sizes
    /// differ.
    #[must_use]
    pub fn rel_mse(&self, reference: &Film) -> Option<f64> {
        if (self.width, self.height) != (reference.width, reference.height) {
            return None;
        }
        let sum: f64 = self
            .pixels
            .iter()
            .zip(&reference.pixels)
            .flat_map(|(a, r)| (0..3).map(move |k| (f64::from(a[k]) - f64::from(r[k])).powi(2) / (f64::from(r[k]).powi(2) + 0.01)))
            .sum();
        Some(sum / (3 * self.pixels.len().max(1)) as f64)
    }

    /// Writes an `.exr` of the image (`R`, `G`, `B`) with the denoiser's layers beside it:
    /// `albedo.R/G/B`, `N.X/Y/Z` and `Z` (linear f32, one part).
    pub fn save_exr_with_aovs(&self, path: &Path, aovs: &Aovs) -> Result<(), OutputError> {
        let n = self.pixels.len();
        if aovs.albedo.pixels.len() != n || aovs.normal.pixels.len() != n || aovs.depth.len() != n {
            return Err(OutputError::Format(format!("{}: the layers are not the image's size", path.display())));
        }
        let ch = |name: &str, f: &dyn Fn(usize) -> f32| (name.to_string(), (0..n).map(f).collect());
        let channels = vec![
            ch("R", &|i| self.pixels[i].x),
            ch("G", &|i| self.pixels[i].y),
            ch("B", &|i| self.pixels[i].z),
            ch("albedo.R", &|i| aovs.albedo.pixels[i].x),
            ch("albedo.G", &|i| aovs.albedo.pixels[i].y),
            ch("albedo.B", &|i| aovs.albedo.pixels[i].z),
            ch("N.X", &|i| aovs.normal.pixels[i].x),
            ch("N.Y", &|i| aovs.normal.pixels[i].y),
            ch("N.Z", &|i| aovs.normal.pixels[i].z),
            ch("Z", &|i| aovs.depth[i]),
        ];
        Self::save_exr_channels(path, self.width, self.height, channels)
    }

    /// Writes an `.exr` of named channels of `width` × `height` values each (linear f32,
    /// one part; readers sort them by name, as EXR stores them).
    pub fn save_exr_channels(path: &Path, width: u32, height: u32, channels: Vec<(String, Vec<f32>)>) -> Result<(), OutputError> {
        use exr::prelude::*;
        let n = width as usize * height as usize;
        if let Some((name, _)) = channels.iter().find(|(_, v)| v.len() != n) {
            return Err(OutputError::Format(format!("{}: channel {name} is not the image's size", path.display())));
        }
        let list: Vec<AnyChannel<FlatSamples>> =
            channels.into_iter().map(|(name, v)| AnyChannel::new(name.as_str(), FlatSamples::F32(v))).collect();
        let image = Image::from_channels((width as usize, height as usize), AnyChannels::sort(list.into()));
        image.write().to_file(path).map_err(|e| OutputError::Exr { path: path.display().to_string(), msg: e.to_string() })
    }

    /// Writes `.png` (8-bit sRGB) or `.exr` (linear f32).
    pub fn save(&self, path: &Path) -> Result<(), OutputError> {
        let name = path.display().to_string();
        let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
        let err = |cause| OutputError::Image { path: name.clone(), cause };
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

/// A part of an image's work: the pixels `x0..x1` × `y0..y1` and the sample indices
/// `s0..s1` of each (the unit the tile renderer, the viewer's passes and, later, other
/// processes hand out).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Region {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
    /// First sample index.
    pub s0: u32,
    /// One past the last sample index.
    pub s1: u32,
}

impl Region {
    /// The whole `width` × `height` image, samples `s0..s1`.
    #[must_use]
    pub const fn full(width: u32, height: u32, s0: u32, s1: u32) -> Self {
        Self { x0: 0, y0: 0, x1: width, y1: height, s0, s1 }
    }
    /// The part of the region inside a `width` × `height` image (an empty range where
    /// nothing is left: never one that ends before it starts).
    #[must_use]
    pub fn clip(self, width: u32, height: u32) -> Self {
        let r = Self { x1: self.x1.min(width), y1: self.y1.min(height), ..self };
        Self { x0: r.x0.min(r.x1), y0: r.y0.min(r.y1), s1: r.s1.max(r.s0), ..r }
    }
    /// Pixels in the region.
    #[must_use]
    pub fn pixels(&self) -> usize {
        self.x1.saturating_sub(self.x0) as usize * self.y1.saturating_sub(self.y0) as usize
    }
    /// Whether the region holds no pixel or no sample.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.pixels() == 0 || self.s1 <= self.s0
    }
    /// Whether two regions share a pixel and a sample index.
    #[must_use]
    pub fn overlaps(&self, o: &Self) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1 && self.s0 < o.s1 && o.s0 < self.s1
    }
}

/// The weighted sums of one region's samples: per pixel (row-major inside the region), the
/// sum of weight × radiance and the sum of weights.
#[derive(Clone, Debug, PartialEq)]
pub struct RegionFilm {
    /// What was rendered.
    pub region: Region,
    /// Σ weight · radiance per pixel.
    pub sum: Vec<Vec3>,
    /// Σ weight per pixel.
    pub weight: Vec<f32>,
}

impl RegionFilm {
    /// An empty (all-zero) film of `region`.
    #[must_use]
    pub fn new(region: Region) -> Self {
        let n = region.pixels();
        Self { region, sum: vec![Vec3::ZERO; n], weight: vec![0.0; n] }
    }
    /// Adds a sample of `weight` to pixel `(x, y)` (image coordinates, inside the region).
    pub fn add(&mut self, x: u32, y: u32, radiance: Vec3, weight: f32) {
        let r = &self.region;
        let i = ((y - r.y0) * (r.x1 - r.x0) + (x - r.x0)) as usize;
        self.sum[i] += radiance * weight;
        self.weight[i] += weight;
    }
}

/// Errors of merging regions.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum MergeError {
    /// The region reaches outside the image.
    #[error("region {0:?} lies outside the {1} x {2} image")]
    Outside(Region, u32, u32),
    /// The region's sums do not have one entry per pixel.
    #[error("region {0:?} has {1} sums for {2} pixels")]
    Length(Region, usize, usize),
    /// The region's samples were merged before at a pixel (the work was handed out twice).
    #[error("region {region:?}: pixel ({x}, {y}) already has samples {s0}..{s1}")]
    Overlap {
        /// The region refused.
        region: Region,
        /// Column of the first pixel found twice.
        x: u32,
        /// Its row.
        y: u32,
        /// The sample indices merged there before (the range the two share starts here).
        s0: u32,
        /// One past them.
        s1: u32,
    },
}

/// Gathers [`RegionFilm`]s into an image, bit for bit the same whatever order the regions
/// arrive in (from tiles on threads, passes of the viewer, or other processes): each
/// pixel's sums are added in the order of their first sample index. A region whose
/// samples come next at all its pixels is added at once (the usual case: tiles of the same
/// samples, passes in order), so memory stays one sum, weight and sample count per pixel;
/// one that arrives early waits until the samples before it are in (or until
/// [`FilmAccumulator::resolve`], which adds the waiting ones in order on a copy).
#[derive(Clone, Debug)]
pub struct FilmAccumulator {
    width: u32,
    height: u32,
    sum: Vec<Vec3>,
    weight: Vec<f32>,
    /// Per pixel: the samples `0..next` are added.
    next: Vec<u32>,
    /// Regions waiting for earlier samples, by first sample index.
    pending: Vec<RegionFilm>,
    merged: usize,
}

impl FilmAccumulator {
    /// An empty `width` × `height` image.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self { width, height, sum: vec![Vec3::ZERO; n], weight: vec![0.0; n], next: vec![0; n], pending: Vec::new(), merged: 0 }
    }

    /// The image's size.
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Pixel indices of region `r`'s rows: (index of the row's first pixel in the image,
    /// in the region).
    fn rows(&self, r: Region) -> impl Iterator<Item = (usize, usize)> + '_ {
        let w = (r.x1 - r.x0) as usize;
        (r.y0..r.y1).map(move |y| ((y * self.width + r.x0) as usize, (y - r.y0) as usize * w))
    }

    /// Adds a rendered region (checked: inside the image, one sum per pixel, no sample
    /// merged before at any of its pixels).
    pub fn merge(&mut self, part: RegionFilm) -> Result<(), MergeError> {
        let r = part.region;
        if r.x1 > self.width || r.y1 > self.height || r.x0 > r.x1 || r.y0 > r.y1 || r.s0 > r.s1 {
            return Err(MergeError::Outside(r, self.width, self.height));
        }
        let n = r.pixels();
        if part.sum.len() != n || part.weight.len() != n {
            return Err(MergeError::Length(r, part.sum.len().min(part.weight.len()), n));
        }
        if r.is_empty() {
            return Ok(());
        }
        let w = (r.x1 - r.x0) as usize;
        let mut ready = true;
        for (row, _) in self.rows(r) {
            for k in 0..w {
                let next = self.next[row + k];
                if r.s0 < next {
                    let (x, y) = ((row + k) as u32 % self.width, (row + k) as u32 / self.width);
                    return Err(MergeError::Overlap { region: r, x, y, s0: 0, s1: next });
                }
                ready &= next == r.s0;
            }
        }
        if let Some(o) = self.pending.iter().find(|o| o.region.overlaps(&r)) {
            let (x, y) = (r.x0.max(o.region.x0), r.y0.max(o.region.y0));
            return Err(MergeError::Overlap { region: r, x, y, s0: o.region.s0, s1: o.region.s1 });
        }
        self.merged += 1;
        if !ready {
            let at = self.pending.partition_point(|o| o.region.s0 <= r.s0);
            self.pending.insert(at, part);
            return Ok(());
        }
        self.add(&part);
        // Regions that waited for these samples.
        while let Some(i) = self.pending.iter().position(|o| {
            self.rows(o.region).all(|(row, _)| self.next[row..row + (o.region.x1 - o.region.x0) as usize].iter().all(|&n| n == o.region.s0))
        }) {
            let o = self.pending.remove(i);
            self.add(&o);
        }
        Ok(())
    }

    /// Adds a region's sums (its samples come next at each of its pixels).
    fn add(&mut self, part: &RegionFilm) {
        let r = part.region;
        let w = (r.x1 - r.x0) as usize;
        let rows: Vec<(usize, usize)> = self.rows(r).collect();
        for (row, src) in rows {
            for k in 0..w {
                self.sum[row + k] += part.sum[src + k];
                self.weight[row + k] += part.weight[src + k];
                self.next[row + k] = r.s1;
            }
        }
    }

    /// Regions merged so far.
    #[must_use]
    pub fn len(&self) -> usize {
        self.merged
    }

    /// Whether nothing was merged.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.merged == 0
    }

    /// Samples added at pixel (x, y) in order from sample 0 (those of regions still
    /// waiting for earlier ones not counted).
    #[must_use]
    pub fn samples_at(&self, x: u32, y: u32) -> u32 {
        self.next.get((y * self.width + x) as usize).copied().unwrap_or(0)
    }

    /// The image: each pixel's weighted mean, or `background` where no sample landed.
    #[must_use]
    pub fn resolve(&self, background: Vec3) -> Film {
        let (mut sum, mut weight) = (self.sum.clone(), self.weight.clone());
        for p in &self.pending {
            let w = (p.region.x1 - p.region.x0) as usize;
            for (row, src) in self.rows(p.region) {
                for k in 0..w {
                    sum[row + k] += p.sum[src + k];
                    weight[row + k] += p.weight[src + k];
                }
            }
        }
        let pixels = sum.iter().zip(&weight).map(|(s, &w)| if w > 0.0 { *s / w } else { background }).collect();
        Film { width: self.width, height: self.height, pixels }
    }
}

#[cfg(test)]
mod region_tests {
    use super::*;

    /// A fake render of a region: sample `s` of pixel (x, y) is a hash of the three.
    fn render(r: Region) -> RegionFilm {
        let mut f = RegionFilm::new(r);
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                for s in r.s0..r.s1 {
                    let h = crate::sampler::hash32(x * 7 + y * 131 + s * 9973);
                    f.add(x, y, Vec3::new(h as f32 / 4e9, (h >> 8) as f32 / 1.6e7, 0.1 * s as f32), 1.0 + (s % 3) as f32);
                }
            }
        }
        f
    }

    fn split(w: u32, h: u32, spp: u32) -> Vec<Region> {
        let mut v = Vec::new();
        for s0 in (0..spp).step_by(4) {
            for y0 in (0..h).step_by(16) {
                for x0 in (0..w).step_by(16) {
                    v.push(Region { x0, y0, x1: (x0 + 16).min(w), y1: (y0 + 16).min(h), s0, s1: (s0 + 4).min(spp) });
                }
            }
        }
        v
    }

    /// Regions merged in any order give the same bits; tiles cover the image exactly.
    #[test]
    fn merge_order_does_not_change_a_bit() {
        let (w, h, spp) = (50, 37, 10);
        let parts = split(w, h, spp);
        let mut a = FilmAccumulator::new(w, h);
        for r in &parts {
            a.merge(render(*r)).expect("merge");
        }
        let first = a.resolve(Vec3::ZERO);
        for seed in 1..6u32 {
            let mut order = parts.clone();
            // A seeded shuffle.
            for i in (1..order.len()).rev() {
                order.swap(i, crate::sampler::hash32(seed * 1000 + i as u32) as usize % (i + 1));
            }
            let mut b = FilmAccumulator::new(w, h);
            for r in order {
                b.merge(render(r)).expect("merge");
            }
            let img = b.resolve(Vec3::ZERO);
            assert!(img.pixels.iter().zip(&first.pixels).all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits)));
        }
        // Every pixel was covered: the weighted mean of its samples, nothing left as background.
        assert!(first.pixels.iter().all(|p| p.z > 0.0));
    }

    /// Regions outside the image, of the wrong length, or rendered twice are refused.
    #[test]
    fn bad_regions_are_refused() {
        let mut a = FilmAccumulator::new(8, 8);
        let r = Region { x0: 0, y0: 0, x1: 4, y1: 4, s0: 0, s1: 2 };
        a.merge(render(r)).expect("merge");
        assert!(matches!(a.merge(render(Region { x1: 9, ..r })), Err(MergeError::Outside(..))));
        assert_eq!(
            a.merge(render(Region { x0: 3, x1: 6, ..r })),
            Err(MergeError::Overlap { region: Region { x0: 3, x1: 6, ..r }, x: 3, y: 0, s0: 0, s1: 2 })
        );
        let mut short = render(Region { x0: 4, x1: 8, ..r });
        short.sum.pop();
        assert!(matches!(a.merge(short), Err(MergeError::Length(..))));
        // The same pixels with other samples are fine; unrendered pixels show the background.
        a.merge(render(Region { s0: 2, s1: 3, ..r })).expect("more samples");
        let img = a.resolve(Vec3::splat(7.0));
        assert_eq!(img.get(7, 7), Vec3::splat(7.0));
        assert_ne!(img.get(0, 0), Vec3::splat(7.0));
        assert_eq!(a.len(), 2);
    }
}

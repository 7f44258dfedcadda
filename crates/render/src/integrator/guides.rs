//! The guides of a denoiser ([`render_aovs`]): per pixel, the albedo, shading normal,
//! distance and emission of the first surface its rays meet that is not a mirror or glass:
//! through a delta BSDF the guides follow its dominant lobe (`through_specular`) and
//! carry the chain's throughput in the albedo and emission, as Intel Open Image Denoise
//! asks of its guides, so that what is seen in a mirror or through glass keeps its own
//! edges instead of being filtered as the smooth surface in front of it.

use super::hit::{bsdf_frame, emission_at, packet_first_hits, shading_normal};
use crate::bsdf::{Bsdf, Conductor, Dielectric};
use crate::camera::Camera;
use crate::film::{Aovs, Film};
use crate::tiles::NO_RAYS;
use crate::world::surface::Surface;
use crate::world::World;
use glam::Vec3;
use lucent_accel::{Hit, Ray};
use rayon::prelude::*;

/// Weight of each quarter point's shading normal in a pixel's guide normal, the centre's
/// being 1 (so the centre counts half): the normal of a pixel that straddles an edge
/// leans as its samples do. At 4 samples denoised, relMSE Cornell / Sponza / kitchen
/// 0.0015 / 0.0081 / 0.0315 with the centre's normal alone; 0.0014 / 0.0073 / 0.0313 at
/// 0.25; 0.0014 / 0.0073 / 0.0314 at 0.5; 0.0014 / 0.0074 / 0.0314 at 1; the quarters
/// alone 0.0014 / 0.0074 / 0.0319.
const QUARTER_NORMAL: f32 = 0.25;

/// The guide layers of a denoiser for every pixel: the shading normal (the centre's and
/// the quarter points' blended, see `QUARTER_NORMAL`) and the distance of the first
/// surface the ray through its centre sees; the albedo, as the mean over four points
/// of the pixel's quarters (a pixel's colour mixes what its samples see, so a texture's
/// edges demodulate and remodulate with the pixel's mean albedo: on Sponza at 4 samples,
/// the denoised relMSE fell from 0.0114 to 0.0091 against the centre's albedo); and the
/// emission seen, as the mean over the centre and those four points, so that pixels an
/// emitter covers even in part are known (see [`crate::film::Aovs`]).
#[must_use]
///
/// Each 8 × 8 block's five sets of rays (centres, then each quarter point) are traced as
/// packets when they are coherent and no surface has an alpha mask (the same hits as
/// single rays, bit for bit); on Sponza at 512 × 384 on 2 threads, 224 ms one ray at a
/// time.
pub fn render_aovs(w: &World, cam: &Camera, width: u32, height: u32) -> Aovs {
    type Guide = (Vec3, Vec3, f32, Vec3);
    let n = width as usize * height as usize;
    let mut flat: Vec<Guide> = vec![(Vec3::ZERO, Vec3::ZERO, 0.0, Vec3::ZERO); n];
    if n == 0 {
        let empty = || Film { width, height, pixels: Vec::new() };
        return Aovs { albedo: empty(), normal: empty(), depth: Vec::new(), emission: empty() };
    }
    // Bands of 8 rows, blocks of 8 × 8 pixels.
    flat.par_chunks_mut(width as usize * 8).enumerate().for_each(|(band, rows)| {
        let y0 = band as u32 * 8;
        let y1 = (y0 + 8).min(height);
        for x0 in (0..width).step_by(8) {
            let x1 = (x0 + 8).min(width);
            let mut at = [(0u32, 0u32); 64];
            let mut m = 0;
            for y in y0..y1 {
                for x in x0..x1 {
                    at[m] = (x, y);
                    m += 1;
                }
            }
            for (k, (dx, dy)) in [(0.5, 0.5), (0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75)].into_iter().enumerate() {
                let mut pts = [(0f32, 0f32); 64];
                for (p, &(x, y)) in pts.iter_mut().zip(&at[..m]) {
                    *p = (x as f32 + dx, y as f32 + dy);
                }
                let mut rays = NO_RAYS;
                cam.rays_at(&pts[..m], &mut rays[..m]);
                let mut hits = [None; 64];
                let packet = packet_first_hits(w, &rays[..m], None, true, &mut hits[..m]);
                for j in 0..m {
                    let first = w.first_hit(&rays[j], packet.then_some(hits[j]));
                    let (x, y) = at[j];
                    let g = &mut rows[((y - y0) * width + x) as usize];
                    if k == 0 {
                        (g.1, g.2, g.3) = centre_guides(w, first);
                    } else {
                        let (a, e, n) = quarter_guides(w, first);
                        g.0 += a;
                        g.3 += e;
                        // (Where the centre sees a surface too.)
                        if let Some(n) = n.filter(|_| g.2.is_finite()) {
                            g.1 += n * QUARTER_NORMAL;
                        }
                    }
                }
            }
        }
    });
    for g in &mut flat {
        g.0 /= 4.0;
        g.3 /= 5.0;
        g.1 = g.1.normalize_or_zero();
    }
    Aovs {
        albedo: Film { width, height, pixels: flat.iter().map(|a| a.0).collect() },
        normal: Film { width, height, pixels: flat.iter().map(|a| a.1).collect() },
        depth: flat.iter().map(|a| a.2).collect(),
        emission: Film { width, height, pixels: flat.iter().map(|a| a.3).collect() },
    }
}

/// The regression's guides per pixel, each the mean over points spread over the pixel
/// ([`render_features`]), as the regression denoiser
/// ([`crate::denoise::regression`]) takes them.
#[derive(Clone, Debug, Default)]
pub struct Features {
    /// Albedo (past mirrors and glass, times the chain's throughput).
    pub albedo: Vec<Vec3>,
    /// Shading normal (the mean, not normalised), over the points that meet a surface.
    pub normal: Vec<Vec3>,
    /// Distance, over the points that meet a surface (infinite: none does).
    pub depth: Vec<f32>,
}

/// The regression denoiser's guides ([`Features`]): per
/// pixel, the means over a `grid` × `grid` lattice of points in it (as the box filter
/// averages the colour's samples, so that a pixel straddling an edge gets the mixture of
/// both sides' guides its colour is a mixture of) of the albedo, the shading normal and
/// the distance of the first surface past mirrors and glass that each point's ray meets
/// (the normal and distance over the points that meet one).
#[must_use]
pub fn render_features(w: &World, cam: &Camera, width: u32, height: u32, grid: u32) -> Features {
    let n = width as usize * height as usize;
    let grid = grid.max(1);
    let px: Vec<(Vec3, Vec3, f32)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (x, y) = ((i % width as usize) as f32, (i / width as usize) as f32);
            let (mut al, mut nn, mut d, mut hits) = (Vec3::ZERO, Vec3::ZERO, 0.0f32, 0.0f32);
            for sy in 0..grid {
                for sx in 0..grid {
                    let (u, v) = ((sx as f32 + 0.5) / grid as f32, (sy as f32 + 0.5) / grid as f32);
                    let r = cam.ray(x + u, y + v);
                    match through_specular(w, w.intersect_solid(&r)) {
                        (Some(End { r, surf, ns }), beta, dist) => {
                            al += beta * w.prepared(surf.material).albedo(&w.scene.textures, surf.uv);
                            nn += ns;
                            d += dist + (surf.p - r.org).length();
                            hits += 1.0;
                        }
                        _ => al += w.scene.background,
                    }
                }
            }
            let m = (grid * grid) as f32;
            if hits > 0.0 {
                (al / m, nn / hits, d / hits)
            } else {
                (al / m, Vec3::ZERO, f32::INFINITY)
            }
        })
        .collect();
    Features { albedo: px.iter().map(|p| p.0).collect(), normal: px.iter().map(|p| p.1).collect(), depth: px.iter().map(|p| p.2).collect() }
}

/// Most mirrors and glass surfaces the guides follow (as the VPL integrator's camera paths).
const SPECULAR_DEPTH: u32 = 8;

/// Below this roughness (α) a conductor or a dielectric counts as a mirror or clear glass
/// for the guides: what such a lobe reflects is nearly as sharp as a mirror's image.
const NEAR_DELTA_ALPHA: f32 = 0.1;

/// The mirror or clear glass the guides see `b` as: `b` itself when it is a delta BSDF, its
/// smooth counterpart when it is a conductor or dielectric rougher than none but smoother
/// than [`NEAR_DELTA_ALPHA`]; `None` for anything else.
fn as_specular<'w>(b: Bsdf<'w>) -> Option<Bsdf<'w>> {
    match b {
        _ if b.is_delta() => Some(b),
        Bsdf::Conductor(c) if c.mf.is_some_and(|m| m.alpha_max() < NEAR_DELTA_ALPHA) => Some(Bsdf::Conductor(Conductor { mf: None, ..c })),
        Bsdf::Dielectric(d) if d.mf.is_some_and(|m| m.alpha_max() < NEAR_DELTA_ALPHA) => {
            Some(Bsdf::Dielectric(Dielectric { mf: None, ..d }))
        }
        _ => None,
    }
}

/// Where a camera ray's way past mirrors and glass ends ([`through_specular`]): the ray and
/// hit there, and the surface point and shading normal rebuilt from them.
pub(crate) struct End {
    r: Ray,
    surf: Surface,
    ns: Vec3,
}

/// The first surface past mirrors and glass: from a camera ray's first hit `first` (as
/// [`World::intersect_solid`] finds it), the dominant lobe of each delta BSDF, or of the
/// smooth counterpart of a nearly smooth metal or glass (`as_specular`), is followed: its
/// sample with the lobe choice at ½ (glass refracts unless its Fresnel reflectance passes
/// ½), up to [`SPECULAR_DEPTH`] of them. Returns where that ends, the chain's throughput,
/// and the length of the path before that hit's own segment. A chain that leaves the scene
/// ends at its last mirror or glass surface instead (`None` only for a camera ray that
/// meets nothing): a sky seen through glass is lit by the glass's other, noisy lobes (its
/// reflection of the sun), which the denoiser must still see as a surface to filter.
pub(crate) fn through_specular(w: &World, first: Option<(Ray, Hit)>) -> (Option<End>, Vec3, f32) {
    let Some((mut r, mut hit)) = first else { return (None, Vec3::ONE, 0.0) };
    let (mut beta, mut dist, mut followed) = (Vec3::ONE, 0.0f32, 0);
    loop {
        let surf = w.surface(&r, &hit);
        let ns = shading_normal(w, &r, &hit, &surf);
        let next = (followed < SPECULAR_DEPTH).then(|| {
            let d = r.dir.normalize();
            let (bsdf, frame) = bsdf_frame(w, &r, &hit, &surf, ns, d);
            let bsdf = as_specular(bsdf).filter(|_| emission_at(w, &r, &surf) == Vec3::ZERO)?;
            let s = bsdf.sample(frame.to_local(-d), 0.5, (0.5, 0.5))?;
            let b = beta * s.weight;
            if !b.is_finite() || b.max_element() <= 0.0 {
                return None;
            }
            Some((b, w.intersect_solid(&surf.spawn(frame.to_world(s.wi)))?))
        });
        let Some((b, (r_next, hit_next))) = next.flatten() else {
            return (Some(End { r, surf, ns }), beta, dist);
        };
        beta = b;
        dist += (surf.p - r.org).length();
        (r, hit) = (r_next, hit_next);
        followed += 1;
    }
}

/// A denoiser's guides from the ray through a pixel's centre: the shading normal, the
/// distance (along mirrors and glass) and the emitted radiance of its first visible surface
/// that is neither ([`through_specular`]; zero, infinity and zero where it meets nothing).
/// `first`: what the ray meets first (as [`World::intersect_solid`] finds it).
pub(crate) fn centre_guides(w: &World, first: Option<(Ray, Hit)>) -> (Vec3, f32, Vec3) {
    let (Some(End { r, surf, ns }), beta, dist) = through_specular(w, first) else {
        return (Vec3::ZERO, f32::INFINITY, Vec3::ZERO);
    };
    let depth = dist + (surf.p - r.org).length();
    (ns, depth, beta * emission_at(w, &r, &surf))
}

/// What a denoiser's guides take from each quarter point of a pixel (beside
/// [`centre_guides`]): the albedo, the emitted radiance and the shading normal of the
/// first surface a ray meets past mirrors and glass (the background's colour, zero and
/// `None` where it meets nothing), the first two times the chain's throughput; `first`:
/// what the ray meets first (as [`World::intersect_solid`] finds it).
pub(crate) fn quarter_guides(w: &World, first: Option<(Ray, Hit)>) -> (Vec3, Vec3, Option<Vec3>) {
    let (Some(End { r, surf, ns }), beta, _) = through_specular(w, first) else {
        return (w.scene.background, Vec3::ZERO, None);
    };
    (beta * w.prepared(surf.material).albedo(&w.scene.textures, surf.uv), beta * emission_at(w, &r, &surf), Some(ns))
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_accel::MeshOptions;

    /// The guides traced in packets are those of single rays, pixel by pixel, bit for bit
    /// (the Cornell box, large enough for its blocks to be coherent, at a size whose blocks
    /// are not all whole).
    #[test]
    fn packet_guides_are_single_ray_guides() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/cornell_box/scene.xml");
        let scene = lucent_scene::load_mitsuba_with(&dir, &[]).expect("scene");
        let (wd, ht) = (403, 301);
        let cam = Camera::new(&scene.camera.expect("camera"), wd, ht);
        let w = World::new(scene, MeshOptions::default()).expect("world");
        let a = render_aovs(&w, &cam, wd, ht);
        for y in 0..ht {
            for x in 0..wd {
                let i = (y * wd + x) as usize;
                let r = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
                let (mut normal, depth, mut emission) = centre_guides(&w, w.intersect_solid(&r));
                let mut albedo = Vec3::ZERO;
                for (dx, dy) in [(0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75)] {
                    let (al, e, n) = quarter_guides(&w, w.intersect_solid(&cam.ray(x as f32 + dx, y as f32 + dy)));
                    albedo += al;
                    emission += e;
                    if let Some(n) = n.filter(|_| depth.is_finite()) {
                        normal += n * QUARTER_NORMAL;
                    }
                }
                assert_eq!(a.normal.pixels[i], normal.normalize_or_zero(), "normal at ({x}, {y})");
                assert_eq!(a.depth[i].to_bits(), depth.to_bits(), "depth at ({x}, {y})");
                assert_eq!(a.albedo.pixels[i], albedo / 4.0, "albedo at ({x}, {y})");
                assert_eq!(a.emission.pixels[i], emission / 5.0, "emission at ({x}, {y})");
            }
        }
    }
}

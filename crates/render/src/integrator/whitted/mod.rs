//! The Whitted integrator (Whitted, "An Improved Illumination Model for Shaded Display",
//! CACM 1980): Phong-like local shading (ambient, Lambert diffuse, Phong specular) from
//! every light with a hard shadow ray, plus recursive mirror reflection and refraction
//! (Snell's law, exact dielectric Fresnel, total internal reflection) up to a depth limit.

mod phong;

use super::hit::{default_material, material, textured_kd};
use crate::tiles::NO_RAYS;
use crate::world::surface::Surface;
use crate::world::World;
use glam::Vec3;
use lucent_accel::{Hit, Ray};
use lucent_scene::{Light, Material};
use phong::{light_sample, mat_terms, offset, orient, put3, v3, with_scratch, LightConst, LitPoint, Scratch};

/// The Whitted integrator's settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WhittedSettings {
    /// Most bounces (reflection or refraction generations).
    pub max_depth: u32,
    /// Trace shadow rays.
    pub shadows: bool,
}

impl Default for WhittedSettings {
    fn default() -> Self {
        Self { max_depth: 6, shadows: true }
    }
}

/// Unpolarized Fresnel reflectance of a dielectric; `cos_i` > 0 on the incident side,
/// `eta` = n_incident / n_transmitted. Returns 1 on total internal reflection.
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Refracts unit `d` through unit normal `n` (facing against `d`) with ratio `eta`;
/// `None` on total internal reflection.
#[must_use]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalize())
}

fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - n * (2.0 * d.dot(n))
}

/// Radiance along `ray`.
#[must_use]
pub fn li(w: &World, ray: &Ray, s: &WhittedSettings, depth: u32) -> Vec3 {
    let Some(hit) = w.intersect(ray) else {
        return w.scene.background;
    };
    let surf = w.surface(ray, &hit);
    shade(w, ray, &surf, material(w, surf.material), s, depth)
}

/// What shading one hit needs, found before any light is asked.
#[derive(Clone, Copy)]
struct Local<'a> {
    p: Vec3,
    mat: &'a Material,
    /// Unit ray direction.
    d: Vec3,
    front: bool,
    /// Normals facing the viewer.
    ng: Vec3,
    ns: Vec3,
    kd: Vec3,
    transmit: f32,
    opaque: f32,
    /// Where rays leaving on the viewer's side start, and how far that is from `p`.
    p_out: Vec3,
    off: f32,
}

impl Local<'_> {
    fn lit_point(&self) -> LitPoint<f32> {
        LitPoint {
            p: self.p.into(),
            d: self.d.into(),
            ng: self.ng.into(),
            ns: self.ns.into(),
            off: self.off,
            kd: self.kd.into(),
            opaque: self.opaque,
            specular: self.mat.specular.into(),
            spec_any: self.mat.specular.max_element() > 0.0,
            shininess: self.mat.shininess,
        }
    }
}

#[inline(always)]
fn local<'a>(w: &World, ray: &Ray, surf: Surface, mat: &'a Material) -> (Local<'a>, Vec3) {
    let t = mat_terms(mat, textured_kd(w, mat, surf.uv), w.scene.ambient);
    let o = orient(ray.dir.into(), surf.ng.into(), surf.ns.into(), surf.p.into(), surf.offset());
    let h = Local {
        p: surf.p,
        mat,
        d: o.d.into(),
        front: o.front,
        ng: o.ng.into(),
        ns: o.ns.into(),
        kd: t.kd,
        transmit: t.transmit,
        opaque: t.opaque,
        p_out: o.p_out.into(),
        off: o.off,
    };
    (h, t.c)
}

/// Light `l`'s contribution at a hit, and the shadow ray that must be clear for it to count
/// (`None` when shadows are off); `None` when the light cannot reach the surface anyway.
#[inline(always)]
fn light_term(l: &Light, h: &Local, s: &WhittedSettings) -> Option<(Vec3, Option<Ray>)> {
    let ls = light_sample(&LightConst::new(l), &h.lit_point());
    if !ls.valid {
        return None;
    }
    let shadow = s.shadows.then(|| Ray::new(h.p_out, ls.ldir.into()).with_range(0.0, ls.tmax));
    Some((ls.term.into(), shadow))
}

/// The refracted and the reflected ray of a hit, each with its weight (either may be
/// absent), in the order their light is added.
fn secondary_rays(h: &Local) -> [Option<(Vec3, Ray)>; 2] {
    let (d, mat) = (h.d, h.mat);
    let mut out = [None, None];
    let mut kr = mat.reflect;
    if h.transmit > 0.0 {
        // Entering when the ray meets the front side.
        let eta = if h.front { 1.0 / mat.ior.max(1e-3) } else { mat.ior.max(1e-3) };
        let cos_i = -d.dot(h.ns).clamp(-1.0, 1.0);
        let f = if mat.fresnel { fresnel_dielectric(cos_i.abs(), eta) } else { 0.0 };
        match refract(d, h.ns, eta) {
            Some(t) if f < 1.0 => {
                let p_in: Vec3 = offset(h.p.into(), (-h.ng).into(), h.off).into();
                out[0] = Some((mat.transmit * (1.0 - f), Ray::new(p_in, t)));
                if mat.fresnel {
                    kr = kr.max(Vec3::splat(f));
                }
            }
            _ => kr = Vec3::ONE, // total internal reflection
        }
    }
    if kr.max_element() > 0.0 {
        out[1] = Some((kr, Ray::new(h.p_out, reflect(d, h.ns))));
    }
    out
}

/// Adds the refracted and reflected light (traced ray by ray) to `c`.
fn secondary(w: &World, h: &Local, s: &WhittedSettings, depth: u32, c: &mut Vec3) {
    if depth >= s.max_depth {
        return;
    }
    for (k, r) in secondary_rays(h).into_iter().flatten() {
        *c += k * li(w, &r, s, depth + 1);
    }
}

fn shade(w: &World, ray: &Ray, surf: &Surface, mat: &Material, s: &WhittedSettings, depth: u32) -> Vec3 {
    let (h, mut c) = local(w, ray, *surf, mat);
    for l in &w.lights {
        let Some((term, shadow)) = light_term(l, &h, s) else { continue };
        if shadow.is_some_and(|r| w.occluded(&r)) {
            continue;
        }
        c += term;
    }
    secondary(w, &h, s, depth, &mut c);
    c
}

/// [`li`] for up to [`lucent_accel::MAX_PACKET`] coherent rays (e.g. an 8×8 tile of primary
/// rays): the closest hits and then each light's shadow rays are traced as packets, the
/// reflected and refracted rays one by one. The same radiance as [`li`] on each ray (only
/// which of two surfaces at exactly the same distance is seen may differ).
pub fn li_packet(w: &World, rays: &[Ray], s: &WhittedSettings, out: &mut [Vec3]) {
    li_packet_at(w, rays, None, s, 0, out);
}

/// [`li_packet`] for rays that can meet no instance but those of `among` (when given: a
/// screen block's candidates from [`crate::Coverage::candidates`]), which are then tested
/// without the top-level walk.
pub(crate) fn li_packet_among(w: &World, rays: &[Ray], among: Option<&[u32]>, s: &WhittedSettings, out: &mut [Vec3]) {
    li_packet_at(w, rays, among, s, 0, out);
}

/// [`li_packet`] at recursion depth `depth`: the refracted rays of the block, then its
/// reflected rays, are traced as packets of their own (a flat mirror's or a window's rays
/// stay coherent; scattered ones fall back to single rays inside the kernels).
fn li_packet_at(w: &World, rays: &[Ray], among: Option<&[u32]>, s: &WhittedSettings, depth: u32, out: &mut [Vec3]) {
    const N: usize = lucent_accel::MAX_PACKET;
    let bg = w.scene.background;
    for (rays, out) in rays.chunks(N).zip(out.chunks_mut(N)) {
        let n = rays.len();
        let mut hits = [None; N];
        match among {
            Some(ids) => w.intersect_packet_among(rays, ids, &mut hits[..n]),
            None => w.intersect_packet(rays, &mut hits[..n]),
        }
        // PERF: a block that met nothing shows the background; the per-hit arrays below
        // (about 10 KB to initialise) are skipped.
        if hits[..n].iter().all(Option::is_none) {
            out.fill(bg);
            continue;
        }
        with_scratch(|sc| shade_hits(w, rays, &hits[..n], s, depth, out, sc));
    }
}

/// Shades the hits of one packet (`hits[i]` of `rays[i]`, into `out[i]`; misses show the
/// background), in the lane buffers `sc`.
fn shade_hits(w: &World, rays: &[Ray], hits: &[Option<Hit>], s: &WhittedSettings, depth: u32, out: &mut [Vec3], sc: &mut Scratch) {
    const N: usize = lucent_accel::MAX_PACKET;
    let bg = w.scene.background;
    // PERF: no light, and at every hit a material without texture that neither reflects
    // nor transmits (REND3R's matte spheres in a frame without a light): each pixel is its
    // material's own colour, and no surface point is rebuilt (a third of Table IV's
    // 256-sphere frame went to rebuilding and gathering them). The same values as below.
    if w.lights.is_empty() {
        let flat = |hit: &Hit| {
            let mat = material(w, w.material_of(hit));
            !mat.uses_uv() && mat.reflect.max_element() <= 0.0 && mat.transmit.max_element() <= 0.0
        };
        if hits.iter().flatten().all(flat) {
            for (o, hit) in out.iter_mut().zip(hits) {
                *o = match hit {
                    Some(hit) => {
                        let mat = material(w, w.material_of(hit));
                        mat_terms(mat, mat.diffuse, w.scene.ambient).c
                    }
                    None => bg,
                };
            }
            return;
        }
    }
    // The hits, gathered into lanes (structure of arrays) for the shading arithmetic.
    let h = &mut sc.h;
    h.spec_any = 0;
    let mut mats: [&Material; N] = [default_material(); N];
    let mut transmit = [0.0f32; N];
    let mut m = 0;
    for (i, (ray, hit)) in rays.iter().zip(hits).enumerate() {
        let Some(hit) = hit else {
            out[i] = bg;
            continue;
        };
        let surf = w.surface(ray, hit);
        let mat = material(w, surf.material);
        let t = mat_terms(mat, textured_kd(w, mat, surf.uv), w.scene.ambient);
        out[i] = t.c;
        h.slot[m] = i as u8;
        put3(&mut h.p, m, surf.p);
        put3(&mut h.dir, m, ray.dir);
        put3(&mut h.ng, m, surf.ng);
        put3(&mut h.ns, m, surf.ns);
        put3(&mut h.kd, m, t.kd);
        put3(&mut h.specular, m, mat.specular);
        h.opaque[m] = t.opaque;
        h.off[m] = surf.offset();
        h.spec_any |= u64::from(mat.specular.max_element() > 0.0) << m;
        h.shininess[m] = mat.shininess;
        mats[m] = mat;
        transmit[m] = t.transmit;
        m += 1;
    }
    h.m = m;
    h.orient();
    // Each light at every hit at once, then its shadow rays as one packet.
    if !w.lights.is_empty() {
        let ll = &mut sc.ll;
        let mut blocked = [false; N];
        let nb = m.div_ceil(8);
        for l in &w.lights {
            let rays = h.light(l, ll);
            if rays == 0 {
                continue;
            }
            if s.shadows {
                w.occluded_blocks(&ll.blocks[..nb], &mut blocked[..nb * 8], rays);
            }
            let mut lit = ll.valid;
            while lit != 0 {
                let j = lit.trailing_zeros() as usize;
                lit &= lit - 1;
                if !blocked[j] {
                    out[h.slot[j] as usize] += v3(&ll.term, j);
                }
            }
        }
    }
    // PERF: blocks where nothing reflects or transmits (REND3R's matte spheres) skip
    // the secondary stage and its buffers (a tenth of a 256-sphere frame).
    if depth >= s.max_depth || !(0..m).any(|j| transmit[j] > 0.0 || mats[j].reflect.max_element() > 0.0) {
        return;
    }
    // Transmitted light first, then reflected, as `secondary` adds them.
    // PERF: a fixed array, as the lanes (no allocation per block and depth).
    let mut sec = [[None; 2]; N];
    for (j, slot) in sec[..m].iter_mut().enumerate() {
        let local = Local {
            p: v3(&h.p, j),
            mat: mats[j],
            d: v3(&h.dir, j),
            front: (h.front >> j) & 1 == 1,
            ng: v3(&h.ng, j),
            ns: v3(&h.ns, j),
            kd: v3(&h.kd, j),
            transmit: transmit[j],
            opaque: h.opaque[j],
            p_out: v3(&h.p_out, j),
            off: h.off[j],
        };
        *slot = secondary_rays(&local);
    }
    let sec = &sec[..m];
    let mut next = NO_RAYS;
    let mut who = [0usize; N];
    let mut res = [Vec3::ZERO; N];
    for pass in 0..2 {
        let mut k = 0;
        for (j, r) in sec.iter().enumerate() {
            if let Some((_, ray)) = r[pass] {
                next[k] = ray;
                who[k] = j;
                k += 1;
            }
        }
        if k == 0 {
            continue;
        }
        li_packet_at(w, &next[..k], None, s, depth + 1, &mut res[..k]);
        for (&j, r) in who[..k].iter().zip(&res) {
            if let Some((weight, _)) = sec[j][pass] {
                out[h.slot[j] as usize] += weight * *r;
            }
        }
    }
}

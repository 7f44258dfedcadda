//! Asking a world about rays: closest and any hits, one by one or in packets and blocks,
//! the solid forms that skip the cut-out parts of alpha-masked surfaces. Every query is
//! counted (and kept while [`crate::record_rays`] records).

use super::record::count_rays;
use super::World;
use lucent_accel::{Hit, Ray};

impl World {
    /// Whether the surface a hit found is cut out by its material's alpha mask.
    pub(super) fn cut_out(&self, r: &Ray, h: &Hit) -> bool {
        let surf = self.surface(r, h);
        let Some(m) = self.scene.materials.get(surf.material as usize) else { return false };
        match m.alpha {
            lucent_scene::Alpha::Opaque => false,
            lucent_scene::Alpha::Mask { cutoff, tex, factor } => {
                let a =
                    factor * tex.and_then(|t| self.scene.textures.get(t as usize)).map_or(1.0, |t| crate::texture::sample(t, surf.uv).w);
                a < cutoff
            }
        }
    }

    /// The closest hit of a surface that exists (alpha masks skipped): the hit, and the
    /// ray it belongs to (a ray continued past cut-out parts starts beyond them).
    #[must_use]
    pub fn intersect_solid(&self, r: &Ray) -> Option<(Ray, Hit)> {
        let mut ray = *r;
        for _ in 0..64 {
            let h = self.intersect(&ray)?;
            if !self.has_alpha || !self.cut_out(&ray, &h) {
                return Some((ray, h));
            }
            let surf = self.surface(&ray, &h);
            let left = ray.tmax - h.t;
            ray = surf.spawn(ray.dir).with_range(0.0, left);
        }
        None
    }

    /// A camera path's first hit: `known`, a packet's closest hit for this ray, when given
    /// (see `integrator::packet_first_hits`: a miss stands, and a hit does where no surface
    /// has an alpha mask), else [`World::intersect_solid`].
    #[must_use]
    pub(crate) fn first_hit(&self, r: &Ray, known: Option<Option<Hit>>) -> Option<(Ray, Hit)> {
        match known {
            Some(Some(h)) if !self.has_alpha => Some((*r, h)),
            Some(None) => None,
            _ => self.intersect_solid(r),
        }
    }

    /// Whether a surface that exists (alpha masks skipped) blocks the ray.
    #[must_use]
    pub fn occluded_solid(&self, r: &Ray) -> bool {
        if !self.has_alpha {
            return self.occluded(r);
        }
        self.intersect_solid(r).is_some()
    }

    /// Closest hit.
    #[must_use]
    pub fn intersect(&self, r: &Ray) -> Option<Hit> {
        count_rays(1, |q| q.closest.push(*r));
        self.accel.intersect(r)
    }

    /// Any hit.
    #[must_use]
    pub fn occluded(&self, r: &Ray) -> bool {
        count_rays(1, |q| q.shadow.push(*r));
        self.accel.occluded(r)
    }

    /// Closest hits of coherent rays, traced in packets (see `TwoLevel::intersect_packet`).
    pub fn intersect_packet(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        count_rays(rays.len(), |q| q.closest_packets.push((rays.to_vec(), None)));
        self.accel.intersect_packet(rays, out);
    }

    /// Closest hits of coherent rays that can meet no instance but those of `ids` (see
    /// `TwoLevel::intersect_packet_among`).
    pub fn intersect_packet_among(&self, rays: &[Ray], ids: &[u32], out: &mut [Option<Hit>]) {
        count_rays(rays.len(), |q| q.closest_packets.push((rays.to_vec(), Some(ids.to_vec()))));
        self.accel.intersect_packet_among(rays, ids, out);
    }

    /// Occlusion of coherent rays (for example shadow rays leaving one point), traced in
    /// packets; surfaces cut out by alpha masks do not block (rays are then traced alone).
    pub fn occluded_packet(&self, rays: &[Ray], out: &mut [bool]) {
        if self.has_alpha {
            for (o, r) in out.iter_mut().zip(rays) {
                *o = self.occluded_solid(r);
            }
            return;
        }
        count_rays(rays.len(), |q| q.shadow_packets.push(rays.to_vec()));
        self.accel.occluded_packet(rays, out);
    }

    /// Occlusion of rays in SoA blocks (empty lanes allowed), `rays` of them real.
    pub(crate) fn occluded_blocks(&self, blocks: &[lucent_accel::RayBlock], out: &mut [bool], rays: usize) {
        count_rays(rays, |q| q.shadow_blocks.push((blocks.to_vec(), rays)));
        self.accel.occluded_blocks(blocks, out);
    }
}

//! Every hit along a ray, not only the closest: the any-hit walk of the trees with leaves
//! that note each surface they meet and never stop the walk (the way Embree's filter
//! callbacks collect hits; Wald et al., "Embree: a kernel framework for efficient CPU ray
//! tracing", 2014, section 4.4). Each surface is reported once, however many leaves hold it
//! (spatial splits reference a triangle from several); hits come sorted by distance.
//!
//! The walk uses the portable kernels: the query serves counting and listing (how many
//! surfaces a ray crosses, inside tests), not the renderer's hot loop.

use crate::geom::{Hit, Ray};
use crate::kernel::{KernelSet, ScalarSet};
use crate::mesh::{MeshBvh, Nodes};
use crate::shape::Shape;
use crate::tlas::{Geometry, TwoLevel};
use crate::traverse::{self, Counters, Leaves, RayPre};
use crate::triangle::{unit_triangle_hit, WatertightRay};
use crate::TriangleTest;
use std::cell::RefCell;

/// Most hits one analytic shape may report along a ray (a box or a capped cylinder is
/// met at most twice, an infinite cone four times); a guard, never reached.
const SHAPE_HITS: usize = 8;

/// The leaves of one mesh: every triangle met within the ray's range is noted.
struct MeshAll<'a> {
    bvh: &'a MeshBvh,
    inst: u32,
    out: &'a RefCell<Vec<Hit>>,
}

impl Leaves for MeshAll<'_> {
    fn intersect<C: Counters>(&self, _: u32, _: u32, _: &RayPre, _: &mut Hit, _: &mut C) {
        // Only the any-hit walk runs over these leaves.
    }

    fn occluded<C: Counters>(&self, first: u32, count: u32, r: &RayPre, tmax: f32, _: &mut C) -> bool {
        let mut out = self.out.borrow_mut();
        match self.bvh.test {
            TriangleTest::UnitTriangle => {
                for g in first..first + count {
                    let Some(t4) = self.bvh.tris.get(g as usize) else { continue };
                    for lane in 0..4 {
                        if t4.is_pad(lane) {
                            continue;
                        }
                        if let Some((t, u, v)) = unit_triangle_hit(&t4.lane(lane), r.org, r.dir, r.tmin, tmax) {
                            out.push(Hit { t, u, v, prim: t4.id(lane), inst: self.inst });
                        }
                    }
                }
            }
            TriangleTest::Watertight => {
                let w = WatertightRay::new(r.org, r.dir);
                for i in first as usize..(first + count) as usize {
                    let (Some(&[a, b, c]), Some(&id)) = (self.bvh.wt_verts.get(i), self.bvh.wt_ids.get(i)) else { continue };
                    if let Some((t, u, v)) = w.hit(a, b, c, r.tmin, tmax) {
                        out.push(Hit { t, u, v, prim: id, inst: self.inst });
                    }
                }
            }
        }
        false
    }
}

/// Notes every hit of `pre` with the mesh `bvh` (instance `inst`) within `[tmin, tmax)`.
fn mesh_all(bvh: &MeshBvh, inst: u32, pre: &RayPre, tmax: f32, out: &RefCell<Vec<Hit>>) {
    let leaves = MeshAll { bvh, inst, out };
    // SAFETY (both arms): the portable box test runs on every CPU.
    match &bvh.nodes {
        Nodes::W8(n) => unsafe {
            traverse::occluded::<8, <ScalarSet as KernelSet>::B8, _, _>(n, &leaves, pre, tmax, &mut ());
        },
        Nodes::W4(n) => unsafe {
            traverse::occluded::<4, <ScalarSet as KernelSet>::B4, _, _>(n, &leaves, pre, tmax, &mut ());
        },
    }
}

/// Notes every crossing of an analytic shape: its closest hit, then the next beyond it.
fn shape_all(s: Shape, inst: u32, pre: &RayPre, tmax: f32, out: &mut Vec<Hit>) {
    let mut tmin = pre.tmin;
    for _ in 0..SHAPE_HITS {
        let Some(h) = s.intersect_local(pre.org, pre.dir, tmin, tmax) else { return };
        out.push(Hit { t: h.t, u: 0.0, v: 0.0, prim: h.part, inst });
        tmin = h.t.next_up();
    }
}

/// The leaves of the top level: each instance's geometry is walked in its own space.
struct InstAll<'a> {
    tl: &'a TwoLevel,
    out: &'a RefCell<Vec<Hit>>,
}

impl InstAll<'_> {
    fn instance(&self, id: u32, pre: &RayPre, tmax: f32) {
        let Some(inst) = self.tl.instances().get(id as usize) else { return };
        let local = inst.local_ray(pre);
        match self.tl.geometries().get(inst.geometry as usize) {
            Some(Geometry::Mesh(m)) => mesh_all(m, id, &local, tmax, self.out),
            Some(Geometry::Shape(s)) => shape_all(*s, id, &local, tmax, &mut self.out.borrow_mut()),
            None => {}
        }
    }
}

impl Leaves for InstAll<'_> {
    fn intersect<C: Counters>(&self, _: u32, _: u32, _: &RayPre, _: &mut Hit, _: &mut C) {}

    fn occluded<C: Counters>(&self, first: u32, count: u32, r: &RayPre, tmax: f32, _: &mut C) -> bool {
        for i in first..first + count {
            if let Some(&id) = self.tl.order.get(i as usize) {
                self.instance(id, r, tmax);
            }
        }
        false
    }
}

impl TwoLevel {
    /// Every surface `ray` meets within `[tmin, tmax)`, appended to `out` sorted by
    /// distance (ties by instance, then primitive): each triangle once, an analytic shape
    /// at each crossing. The hits are those [`TwoLevel::intersect`] would find one after
    /// another by moving `tmin` past each, without the risk of skipping a surface at the
    /// same distance or meeting one twice.
    pub fn intersect_all(&self, ray: &Ray, out: &mut Vec<Hit>) {
        let start = out.len();
        let found = RefCell::new(std::mem::take(out));
        let pre = RayPre::new(ray);
        let leaves = InstAll { tl: self, out: &found };
        // SAFETY: the portable box test runs on every CPU.
        unsafe { traverse::occluded::<8, <ScalarSet as KernelSet>::B8, _, _>(&self.nodes, &leaves, &pre, ray.tmax, &mut ()) };
        for &i in &self.unbounded {
            leaves.instance(i, &pre, ray.tmax);
        }
        *out = found.into_inner();
        let new = &mut out[start..];
        new.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.inst.cmp(&b.inst)).then(a.prim.cmp(&b.prim)));
        // A triangle held by several leaves is met at the same distance each time.
        let mut keep = start;
        for i in start..out.len() {
            let h = out[i];
            let dup = out[start..keep].iter().rev().take_while(|k| k.t == h.t).any(|k| k.inst == h.inst && k.prim == h.prim);
            if !dup {
                out[keep] = h;
                keep += 1;
            }
        }
        out.truncate(keep);
    }

    /// How many surfaces `ray` meets within `[tmin, tmax)` (the length of
    /// [`TwoLevel::intersect_all`]'s list), with `scratch` as its buffer.
    pub fn count_hits(&self, ray: &Ray, scratch: &mut Vec<Hit>) -> usize {
        scratch.clear();
        self.intersect_all(ray, scratch);
        scratch.len()
    }
}

//! A model of SaarCOR's DynRTP prototype (Schmittler et al., Graphics Hardware 2004) fed
//! with the work lucent's kernels count on real scenes.
//!
//! The machine: one pipeline at 90 MHz with 64 threads of packets of 4 rays; a traversal
//! unit, a list unit (mailboxed object lists), a transformation unit (instances' rays,
//! SaarCOR's unit-triangle transformation and shading computations all use it) and one
//! intersection unit; direct-mapped caches in front of the traversal (4 KB), list (2 KB)
//! and transformation (6 KB) units, 512 items each; 1 GB/s of external memory to the core.
//!
//! Modelling assumptions (printed with every report, [`ASSUMPTIONS`]).

use crate::cache::DirectMapped;
use crate::kd::{Exact, KdTwoLevel};
use lucent_accel::{Counters, Level, Ray, TwoLevel};
use lucent_render::Camera;
use rayon::prelude::*;
use std::collections::HashMap;

/// What the model assumes, in the report's words.
pub const ASSUMPTIONS: &[&str] = &[
    "Rays: one primary ray through each pixel centre; packets are the 2x2 pixel quads, traced in 8x8-pixel tiles in row order; the 64 threads hide every latency, so a frame takes as many cycles as its busiest unit or its memory traffic (whichever is larger).",
    "Traversal unit: one cycle per node a packet visits (both indices walk the 4 rays as one packet: kd as SaarCOR does, the bvh with its interval test of a node's 8 children; packets whose rays disagree on direction signs go ray by ray, and each ray's nodes count). List unit: one cycle per object-list entry a packet reads.",
    "Transformation unit: n+1 steps (cycles) to carry n rays of a packet, which share an origin, into an instance's space or a triangle's unit-triangle space (bvh: each of a leaf's 4-triangle groups costs its 4 triangles), and 2 steps per shaded ray (normal and texture-coordinate interpolation). Intersection unit: one cycle per ray-triangle (or ray-shape) test.",
    "Caches: direct mapped; traversal items 8 B (a kd node), list items 4 B, transformation items 12 B (a 4-value matrix row of 24-bit floats); an access looks up every item of the bytes it reads, once per packet. Addresses are those of lucent's own data: kd nodes 8 B, list entries 4 B, unit-triangle maps 40 B (SaarCOR: 36 B), instance matrices 48 B (SaarCOR: 36 B); the bvh's 8-wide nodes are a few hundred bytes each (every child's box), its leaves 4-triangle groups of 160 B.",
    "Memory: misses cost their items' bytes from external memory at 1 GB/s to the core. Shading bandwidth (not cached): per hit ray three vertex normals and texture coordinates (3 x 20 B) and per pixel a 4-byte frame-buffer write.",
];

/// The machine's parameters.
#[derive(Clone, Copy, Debug)]
pub struct Machine {
    /// Clock, Hz.
    pub clock_hz: f64,
    /// External memory bandwidth to the core, bytes a second.
    pub memory_bytes_s: f64,
    /// Cache sizes in bytes: traversal, list, transformation.
    pub cache_bytes: [u64; 3],
    /// Items per cache.
    pub cache_items: [u64; 3],
    /// Transformation steps per shaded ray.
    pub shade_steps: u64,
    /// Uncached shading bytes per hit ray.
    pub shade_bytes: u64,
}

impl Default for Machine {
    fn default() -> Self {
        Self {
            clock_hz: 90e6,
            memory_bytes_s: 1e9,
            cache_bytes: [4096, 2048, 6144],
            cache_items: [512; 3],
            shade_steps: 2,
            shade_bytes: 60,
        }
    }
}

/// Which index the rays traverse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Index {
    /// lucent's BVH (8-wide nodes over 4-triangle groups), packets of 4.
    Bvh,
    /// SaarCOR's kd-trees, packets of 4.
    Kd,
}

impl Index {
    /// Its name on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Bvh => "bvh",
            Self::Kd => "kd",
        }
    }
}

/// One thing a traversal read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Kind {
    Node,
    List,
    Transform,
    /// `n` triangles in one read.
    Tris(u32),
    Shape,
}

/// A recording [`Counters`]: every read with its kind, level and the instance it was made
/// under (a bottom-level node under two instances is two visits).
#[derive(Default)]
struct Recorder {
    context: usize,
    reads: Vec<(Kind, usize, u32, usize)>,
}

impl Counters for Recorder {
    fn node(&mut self) {}
    fn items(&mut self, _: u32) {}
    fn enter(&mut self, level: Level) {
        if level == Level::Top {
            self.context = 0;
        }
    }
    fn node_read(&mut self, addr: usize, bytes: usize) {
        self.reads.push((Kind::Node, addr, bytes as u32, self.context));
    }
    fn list_read(&mut self, addr: usize, bytes: usize) {
        self.reads.push((Kind::List, addr, bytes as u32, self.context));
    }
    fn transform(&mut self, addr: usize, bytes: usize) {
        self.context = addr;
        self.reads.push((Kind::Transform, addr, bytes as u32, 0));
    }
    fn triangles(&mut self, addr: usize, bytes: usize, n: u32) {
        self.reads.push((Kind::Tris(n), addr, bytes as u32, self.context));
    }
    fn shape(&mut self, addr: usize, bytes: usize) {
        self.reads.push((Kind::Shape, addr, bytes as u32, self.context));
    }
}

/// The work of one packet, ready for the units and caches.
#[derive(Default)]
struct PacketWork {
    trav: u64,
    list: u64,
    transf: u64,
    int: u64,
    hits: u64,
    /// (cache 0..3, address, bytes) in the order read, each item once.
    reads: Vec<(usize, u64, u64)>,
}

/// Turns a packet's recorded reads into unit work: repeated reads (the same item under
/// the same instance) are one read of the packet; the rays that made a triangle or
/// transform read are the rays it serves.
fn packet_work(reads: &[(Kind, usize, u32, usize)], hits: u64, m: &Machine) -> PacketWork {
    let mut w = PacketWork { hits, ..PacketWork::default() };
    let mut seen: HashMap<(Kind, usize, usize), u64> = HashMap::new();
    let mut order = Vec::new();
    for &(k, addr, bytes, ctx) in reads {
        let e = seen.entry((k, addr, ctx)).or_insert(0);
        if *e == 0 {
            order.push((k, addr, bytes));
        }
        *e += 1;
    }
    for (&(k, _, _), &rays) in &seen {
        match k {
            Kind::Node => w.trav += 1,
            Kind::List => w.list += 1,
            Kind::Transform => w.transf += rays + 1,
            Kind::Tris(n) => {
                w.transf += u64::from(n) * (rays + 1);
                w.int += u64::from(n) * rays;
            }
            Kind::Shape => {
                w.transf += rays + 1;
                w.int += rays;
            }
        }
    }
    w.transf += hits * m.shade_steps;
    for (k, addr, bytes) in order {
        let cache = match k {
            Kind::Node => 0,
            Kind::List => 1,
            _ => 2,
        };
        w.reads.push((cache, addr as u64, u64::from(bytes)));
    }
    w
}

/// What the model says of one frame.
#[derive(Clone, Debug, Default)]
pub struct FrameModel {
    /// Image size.
    pub size: (u32, u32),
    /// Index traversed.
    pub index: &'static str,
    /// Frames per second.
    pub fps: f64,
    /// Cycles of the frame.
    pub cycles: u64,
    /// Unit usage, percent: traversal, list, transformation, intersection.
    pub usage: [f64; 4],
    /// Unit busy cycles: traversal, list, transformation, intersection, memory.
    pub busy: [u64; 5],
    /// Cache hit rates, percent: traversal, list, transformation.
    pub hit: [f64; 3],
    /// External bandwidth at `fps`, MB/s: core (cache misses), shading, total.
    pub mb_s: [f64; 3],
    /// Hit rate (percent) against cache size for each cache: (KB, [trav, list, transf]).
    pub sweep: Vec<(u64, [f64; 3])>,
    /// Per pixel: traversal steps of its packet.
    pub heat_steps: Vec<f32>,
    /// Per pixel: cache misses of its packet (all three caches).
    pub heat_misses: Vec<f32>,
    /// Primary rays that hit.
    pub hit_rays: u64,
    /// Packets traced as packets (kd: coherent direction signs).
    pub packets: u64,
}

/// Cache sizes of the hit-rate sweep, KB.
pub const SWEEP_KB: [u64; 7] = [1, 2, 4, 8, 16, 32, 64];

/// The index a model traces.
pub enum Traced<'a> {
    /// lucent's two-level BVH.
    Bvh(&'a TwoLevel),
    /// The two-level kd index.
    Kd(&'a KdTwoLevel),
}

/// Models one frame of primary rays through `cam` at its size.
#[must_use]
pub fn model_frame(index: &Traced<'_>, cam: &Camera, m: &Machine) -> FrameModel {
    let (w, h) = cam.size();
    let mut caches: Vec<DirectMapped> = (0..3).map(|i| DirectMapped::new(m.cache_bytes[i], m.cache_items[i])).collect();
    let item = [8u64, 4, 12];
    let mut sweep: Vec<[DirectMapped; 3]> =
        SWEEP_KB.iter().map(|&kb| std::array::from_fn(|i| DirectMapped::new(kb * 1024, kb * 1024 / item[i]))).collect();
    let mut busy = [0u64; 4];
    let mut hit_rays = 0u64;
    let mut heat_steps = vec![0f32; (w * h) as usize];
    let mut heat_misses = vec![0f32; (w * h) as usize];
    let tiles_x = w.div_ceil(8);
    let tiles_y = h.div_ceil(8);
    // Tile rows are traced in parallel and fed to the caches in order.
    for ty in 0..tiles_y {
        let works: Vec<Vec<((u32, u32), PacketWork)>> = (0..tiles_x)
            .into_par_iter()
            .map(|tx| {
                let mut out = Vec::new();
                for py in (ty * 8..(ty * 8 + 8).min(h)).step_by(2) {
                    for px in (tx * 8..(tx * 8 + 8).min(w)).step_by(2) {
                        let pix = [(px, py), (px + 1, py), (px, py + 1), (px + 1, py + 1)];
                        let rays: [Ray; 4] = pix.map(|(x, y)| cam.ray(x as f32 + 0.5, y as f32 + 0.5));
                        let live: Vec<bool> = pix.iter().map(|&(x, y)| x < w && y < h).collect();
                        let mut rec = Recorder::default();
                        let hits: u64 = match index {
                            Traced::Kd(k) => {
                                let r = k.intersect4_with::<Exact, _>(&rays, &mut rec);
                                r.iter().zip(&live).filter(|(h, &l)| l && h.is_some()).count() as u64
                            }
                            Traced::Bvh(b) => {
                                let mut r = [None; 4];
                                b.intersect_packet_counted(&rays, &mut r, &mut rec);
                                r.iter().zip(&live).filter(|(h, &l)| l && h.is_some()).count() as u64
                            }
                        };
                        out.push(((px, py), packet_work(&rec.reads, hits, m)));
                    }
                }
                out
            })
            .collect();
        for ((px, py), pw) in works.into_iter().flatten() {
            busy[0] += pw.trav;
            busy[1] += pw.list;
            busy[2] += pw.transf;
            busy[3] += pw.int;
            hit_rays += pw.hits;
            let mut misses = 0;
            for &(c, addr, bytes) in &pw.reads {
                misses += caches[c].access(addr, bytes);
                for s in &mut sweep {
                    s[c].access(addr, bytes);
                }
            }
            for (x, y) in [(px, py), (px + 1, py), (px, py + 1), (px + 1, py + 1)] {
                if x < w && y < h {
                    heat_steps[(y * w + x) as usize] = pw.trav as f32;
                    heat_misses[(y * w + x) as usize] = misses as f32;
                }
            }
        }
    }
    let core_bytes: u64 = caches.iter().map(DirectMapped::miss_bytes).sum();
    let mem_cycles = (core_bytes as f64 / m.memory_bytes_s * m.clock_hz).ceil() as u64;
    let cycles = busy.iter().copied().chain([mem_cycles]).max().unwrap_or(0).max(1);
    let fps = m.clock_hz / cycles as f64;
    let shading_bytes = hit_rays * m.shade_bytes + u64::from(w) * u64::from(h) * 4;
    let (core, shading) = (core_bytes as f64 * fps / 1e6, shading_bytes as f64 * fps / 1e6);
    FrameModel {
        size: (w, h),
        index: match index {
            Traced::Bvh(_) => "bvh",
            Traced::Kd(_) => "kd",
        },
        fps,
        cycles,
        usage: busy.map(|b| 100.0 * b as f64 / cycles as f64),
        busy: [busy[0], busy[1], busy[2], busy[3], mem_cycles],
        hit: [caches[0].hit_rate(), caches[1].hit_rate(), caches[2].hit_rate()],
        mb_s: [core, shading, core + shading],
        sweep: SWEEP_KB.iter().zip(&sweep).map(|(&kb, s)| (kb, [s[0].hit_rate(), s[1].hit_rate(), s[2].hit_rate()])).collect(),
        heat_steps,
        heat_misses,
        hit_rays,
        packets: u64::from(w.div_ceil(2)) * u64::from(h.div_ceil(2)),
    }
}

/// The floating-point units of each of SaarCOR's units, as lucent's kernels spend them
/// per operation (Table 2's question asked of lucent's arithmetic): (unit, adds,
/// multiplies, divides/reciprocals, comparisons, what one operation is).
pub const FP_UNITS: [(&str, u32, u32, u32, u32, &str); 4] = [
    ("traversal", 1, 1, 0, 2, "kd step: t = (split - o) * 1/d, compared with the segment's ends"),
    ("list", 0, 0, 0, 0, "reads an object id, checks the mailbox (integer only)"),
    ("transformation", 9, 12, 0, 0, "3x4 matrix times a point (9 mul + 9 add) and a vector (3 more mul): 12 mul, 9 add"),
    ("intersection", 3, 3, 1, 5, "t = -o'z / d'z; u = o'x + t d'x, v = o'y + t d'y; u, v >= 0, u + v <= 1, t in range"),
];

#[cfg(test)]
mod tests {
    use super::*;

    /// A packet whose four rays read the same triangle costs 4+1 transformation steps and
    /// 4 intersections; two reads of one node under the same instance are one visit; a
    /// node under two instances is two.
    #[test]
    fn packet_work_by_hand() {
        let m = Machine { shade_steps: 2, ..Machine::default() };
        let reads = vec![
            (Kind::Node, 100, 8, 0),
            (Kind::Node, 100, 8, 0),
            (Kind::List, 200, 4, 0),
            (Kind::Tris(1), 300, 40, 0),
            (Kind::Tris(1), 300, 40, 0),
            (Kind::Tris(1), 300, 40, 0),
            (Kind::Tris(1), 300, 40, 0),
            (Kind::Transform, 400, 48, 0),
            (Kind::Node, 100, 8, 400),
        ];
        let w = packet_work(&reads, 3, &m);
        assert_eq!((w.trav, w.list, w.int), (2, 1, 4));
        assert_eq!(w.transf, 5 + 2 + 3 * 2);
        assert_eq!(w.reads.len(), 5);
    }
}

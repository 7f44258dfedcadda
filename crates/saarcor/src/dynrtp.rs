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
    "Rays: one primary ray through each pixel centre; packets are the 2x2 pixel quads, traced in 8x8-pixel tiles in row order.",
    "Threads: 64 (the prototype's), each holding one packet; a discrete-event simulation: a thread issues its packet's steps one after the other, each step reads its item through its cache (a miss waits for the memory: misses are served one after another at 1 GB/s, then 40 cycles of latency), waits for its unit (first come, first served; busy for the step's cycles) and has its result 20 cycles after the unit finishes. Neither latency is printed in the paper: these two reproduce its scaling statement on the 54-object Conference (`--objects 54`; the threads table gives the figures). The caches see the reads in the order the threads make them.",
    "Traversal unit: one cycle per node a packet visits (both indices walk the 4 rays as one packet: kd as SaarCOR does, the bvh with its interval test of a node's 8 children; packets whose rays disagree on direction signs go ray by ray, and each ray's nodes count). List unit: one cycle per object-list entry a packet reads.",
    "Transformation unit: n+1 steps (cycles) to carry n rays of a packet, which share an origin, into an instance's space or a triangle's unit-triangle space (bvh: each of a leaf's 4-triangle groups costs its 4 triangles); n+1 steps to make a packet's n primary rays from the camera's transformation (the paper's Section 2.2.2); 2 steps per shaded ray (normal and texture-coordinate interpolation). Intersection unit: one cycle per ray-triangle (or ray-shape) test.",
    "Caches: direct mapped; traversal items 8 B (a kd node), list items 4 B, transformation items 12 B (a 4-value matrix row of 24-bit floats); an access looks up every item of the bytes it reads, once per packet. Addresses: kd, a memory image of the scene as uploaded (the top tree's nodes and list, then each object's nodes, list and unit-triangle maps, then the instances' matrices, each array 64-byte aligned): kd nodes 8 B, list entries 4 B, unit-triangle maps 40 B (SaarCOR: 36 B), instance matrices 48 B (SaarCOR: 36 B); bvh, lucent's own arrays (8-wide nodes of a few hundred bytes each, 4-triangle groups of 160 B), their pages moved into one canonical layout (what the parallel build allocates where still moves its hit rates by about a tenth of a point from run to run).",
    "Memory: misses cost their items' bytes from external memory at 1 GB/s to the core. Shading bandwidth (not cached): 28 B per hit ray (the paper's figure with bilinear filtering) and per pixel a 4-byte frame-buffer write.",
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
    /// Uncached shading bytes per hit ray (the paper: 28 bytes a ray with bilinear
    /// texture filtering).
    pub shade_bytes: u64,
    /// Each intersection's result goes back through the traversal unit (the paper's
    /// path f), a cycle there per test step.
    pub results_via_traversal: bool,
    /// Primary rays are made by the transformation unit (the paper's Section 2.2.2: the
    /// camera's transformation maps each pixel's initial ray), n+1 steps for a packet's
    /// n rays, which share the camera's origin.
    pub generate_rays: bool,
    /// Threads of the pipeline: packets in flight (the prototype: 64).
    pub threads: u32,
    /// Cycles from a unit finishing a step to its result reaching the thread (the
    /// pipeline's depth after the first stage).
    pub unit_latency: u32,
    /// Cycles from a miss's bytes leaving memory to their arrival.
    pub memory_latency: u32,
}

/// [`Machine::unit_latency`] by default (not in the paper: see [`ASSUMPTIONS`]).
pub const UNIT_LATENCY: u32 = 20;
/// [`Machine::memory_latency`] by default (not in the paper: see [`ASSUMPTIONS`]).
pub const MEMORY_LATENCY: u32 = 40;

impl Default for Machine {
    fn default() -> Self {
        Self {
            clock_hz: 90e6,
            memory_bytes_s: 1e9,
            cache_bytes: [4096, 2048, 6144],
            cache_items: [512; 3],
            shade_steps: 2,
            shade_bytes: 28,
            generate_rays: true,
            results_via_traversal: false,
            threads: 64,
            unit_latency: UNIT_LATENCY,
            memory_latency: MEMORY_LATENCY,
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

/// What the model says of one frame.
#[derive(Clone, Debug, Default)]
pub struct FrameModel {
    /// Image size.
    pub size: (u32, u32),
    /// Index traversed.
    pub index: &'static str,
    /// Threads (packets in flight).
    pub threads: u32,
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
    /// Packets of the frame.
    pub packets: u64,
}

/// Thread counts of the scaling table (the paper: "almost linear up to 32 threads",
/// "about 10%" more at 64).
pub const THREAD_SWEEP: [u32; 9] = [1, 2, 4, 8, 16, 24, 32, 48, 64];

/// Cache sizes of the hit-rate sweep, KB.
pub const SWEEP_KB: [u64; 7] = [1, 2, 4, 8, 16, 32, 64];

/// The index a model traces.
pub enum Traced<'a> {
    /// lucent's two-level BVH.
    Bvh(&'a TwoLevel),
    /// The two-level kd index.
    Kd(&'a KdTwoLevel),
}

impl Traced<'_> {
    /// Its name in the report ("bvh", "kd").
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Bvh(_) => Index::Bvh.name(),
            Self::Kd(_) => Index::Kd.name(),
        }
    }
}

/// Cycles of a step as an [`Op`] holds them (saturating).
fn step_cycles(x: u64) -> u16 {
    u16::try_from(x).unwrap_or(u16::MAX)
}

/// One step of a packet: `cycles` on `unit` (0 traversal, 1 list, 2 transformation,
/// 3 intersection), after `bytes` at `addr` are read through cache `cache` (or no read:
/// [`NO_READ`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Op {
    addr: u64,
    bytes: u16,
    cycles: u16,
    unit: u8,
    cache: u8,
}

/// [`Op::cache`] of a step that reads nothing.
const NO_READ: u8 = 3;

/// Turns a packet's recorded reads into its steps in the order the packet made them:
/// repeated reads (the same item under the same instance) are one read of the packet, at
/// its first place; the rays that made a triangle or transform read are the rays it
/// serves.
fn packet_ops(reads: &[(Kind, usize, u32, usize)], out: &mut Vec<Op>) {
    let mut rays: HashMap<(Kind, usize, usize), u64> = HashMap::new();
    let mut order = Vec::new();
    for &(k, addr, bytes, ctx) in reads {
        let e = rays.entry((k, addr, ctx)).or_insert(0);
        if *e == 0 {
            order.push((k, addr, bytes, ctx));
        }
        *e += 1;
    }
    for (k, addr, bytes, ctx) in order {
        let n = rays[&(k, addr, ctx)];
        let read = |unit: u8, cache: u8, cycles: u64| Op {
            addr: addr as u64,
            bytes: u16::try_from(bytes).unwrap_or(u16::MAX),
            cycles: step_cycles(cycles),
            unit,
            cache,
        };
        match k {
            Kind::Node => out.push(read(0, 0, 1)),
            Kind::List => out.push(read(1, 1, 1)),
            Kind::Transform => out.push(read(2, 2, n + 1)),
            Kind::Tris(t) => {
                out.push(read(2, 2, u64::from(t) * (n + 1)));
                out.push(Op { addr: 0, bytes: 0, cycles: step_cycles(u64::from(t) * n), unit: 3, cache: NO_READ });
            }
            Kind::Shape => {
                out.push(read(2, 2, n + 1));
                out.push(Op { addr: 0, bytes: 0, cycles: step_cycles(n), unit: 3, cache: NO_READ });
            }
        }
    }
}

/// A packet's steps on machine `m`: its camera rays made (when the machine makes them on
/// the transformation unit), its traversal's steps (each intersection's result handed
/// back through the traversal unit when the machine says so), its hit rays' shading.
fn machine_ops(ops: &[Op], live: u64, hits: u64, m: &Machine, out: &mut Vec<Op>) {
    out.clear();
    if m.generate_rays && live > 0 {
        out.push(Op { addr: 0, bytes: 0, cycles: step_cycles(live + 1), unit: 2, cache: NO_READ });
    }
    for &o in ops {
        out.push(o);
        if m.results_via_traversal && o.unit == 3 {
            out.push(Op { addr: 0, bytes: 0, cycles: 1, unit: 0, cache: NO_READ });
        }
    }
    if hits > 0 && m.shade_steps > 0 {
        out.push(Op { addr: 0, bytes: 0, cycles: step_cycles(hits * m.shade_steps), unit: 2, cache: NO_READ });
    }
}

/// Moves the addresses read into a layout that does not depend on where this run's
/// allocator put the index: the touched pages fall into regions (runs with gaps under
/// 1 MB, an array or a few arrays allocated together), and region k starts at k x 4 GB,
/// keeping every address's offset from its region's first page. Address space layout
/// randomisation no longer moves a direct-mapped cache's conflicts (the raw addresses
/// changed the 6 KB cache's hit rate, its size no multiple of a page, by several points
/// between two runs); the kd index's addresses are its memory image's already, the bvh's
/// still depend on where its parallel build's allocations land (a tenth of a point).
fn canonical_addresses(ops: &mut [Op]) {
    let mut pages: Vec<u64> = ops.iter().filter(|o| o.cache != NO_READ).map(|o| o.addr >> 12).collect();
    pages.sort_unstable();
    pages.dedup();
    let mut starts: Vec<u64> = Vec::new();
    for (i, &p) in pages.iter().enumerate() {
        if i == 0 || p - pages[i - 1] > 256 {
            starts.push(p);
        }
    }
    for o in ops.iter_mut().filter(|o| o.cache != NO_READ) {
        let r = starts.partition_point(|&s| s <= o.addr >> 12).saturating_sub(1);
        if let Some(&s) = starts.get(r) {
            o.addr = ((r as u64) << 32) + (o.addr - (s << 12));
        }
    }
}

/// A packet of a trace: its first step, its top-left pixel, its rays and its hit rays.
type PacketRecord = (usize, (u32, u32), u64, u64);

/// The packets of one frame of primary rays, each as its steps in order: what the model's
/// units and caches are fed with, at any number of threads.
pub struct FrameTrace {
    size: (u32, u32),
    index: &'static str,
    ops: Vec<Op>,
    packets: Vec<PacketRecord>,
}

impl FrameTrace {
    /// Traces one frame of primary rays through `cam` at its size: packets are the 2x2
    /// pixel quads, in 8x8-pixel tiles in row order.
    #[must_use]
    pub fn new(index: &Traced<'_>, cam: &Camera) -> Self {
        let (w, h) = cam.size();
        let tiles: Vec<(u32, u32)> = (0..h.div_ceil(8)).flat_map(|ty| (0..w.div_ceil(8)).map(move |tx| (tx, ty))).collect();
        let per_tile: Vec<(Vec<Op>, Vec<PacketRecord>)> = tiles
            .par_iter()
            .map(|&(tx, ty)| {
                let (mut ops, mut packets) = (Vec::new(), Vec::new());
                for py in (ty * 8..(ty * 8 + 8).min(h)).step_by(2) {
                    for px in (tx * 8..(tx * 8 + 8).min(w)).step_by(2) {
                        let pix = [(px, py), (px + 1, py), (px, py + 1), (px + 1, py + 1)];
                        let rays: [Ray; 4] = pix.map(|(x, y)| cam.ray(x as f32 + 0.5, y as f32 + 0.5));
                        let live = pix.map(|(x, y)| x < w && y < h);
                        let mut rec = Recorder::default();
                        let found: [bool; 4] = match index {
                            Traced::Kd(k) => k.intersect4_with::<Exact, _>(&rays, &mut rec).map(|h| h.is_some()),
                            Traced::Bvh(b) => {
                                let mut r = [None; 4];
                                b.intersect_packet_counted(&rays, &mut r, &mut rec);
                                r.map(|h| h.is_some())
                            }
                        };
                        let hits = found.iter().zip(&live).filter(|(h, l)| **h && **l).count() as u64;
                        packets.push((ops.len(), (px, py), live.iter().filter(|l| **l).count() as u64, hits));
                        packet_ops(&rec.reads, &mut ops);
                    }
                }
                (ops, packets)
            })
            .collect();
        let mut t = Self {
            size: (w, h),
            index: index.name(),
            ops: Vec::with_capacity(per_tile.iter().map(|p| p.0.len()).sum()),
            packets: Vec::new(),
        };
        for (ops, packets) in per_tile {
            let base = t.ops.len();
            t.packets.extend(packets.into_iter().map(|(s, p, live, hits)| (base + s, p, live, hits)));
            t.ops.extend(ops);
        }
        canonical_addresses(&mut t.ops);
        t
    }

    fn packet_ops(&self, p: usize) -> &[Op] {
        let end = self.packets.get(p + 1).map_or(self.ops.len(), |q| q.0);
        &self.ops[self.packets[p].0..end]
    }
}

/// Models one frame of primary rays through `cam` at its size, on `m.threads` threads.
#[must_use]
pub fn model_frame(index: &Traced<'_>, cam: &Camera, m: &Machine) -> FrameModel {
    simulate(&FrameTrace::new(index, cam), m)
}

/// Runs a traced frame through the machine with `m.threads` packets in flight: a
/// discrete-event simulation. Each thread holds one packet and issues its steps one after
/// the other; a step first reads its item through its cache (a miss waits for the memory,
/// which serves misses one after another at the machine's bandwidth, plus
/// `memory_latency`), then waits for its unit (first come, first served; a unit starts
/// one step a cycle and is busy for the step's cycles), and its result is there
/// `unit_latency` cycles after the unit finishes. A thread whose packet is done takes the
/// next packet in tile order. The caches see the reads in the order the threads make them.
#[must_use]
pub fn simulate(t: &FrameTrace, m: &Machine) -> FrameModel {
    let order: Vec<usize> = (0..t.packets.len()).collect();
    simulate_in(t, m, &order)
}

/// [`simulate`] with the packets handed to the threads in scanline order (rows of 2x2
/// quads across the whole image) instead of 8x8-pixel tiles.
#[must_use]
pub fn simulate_in_rows(t: &FrameTrace, m: &Machine) -> FrameModel {
    let mut order: Vec<usize> = (0..t.packets.len()).collect();
    order.sort_by_key(|&p| (t.packets[p].1 .1, t.packets[p].1 .0));
    simulate_in(t, m, &order)
}

/// [`simulate`] with the packets dealt out from `strips` places of the image at once: the
/// tile order cut into that many equal parts, the next packet taken from each part in
/// turn, so the packets in flight lie far apart on the screen instead of side by side.
#[must_use]
pub fn simulate_in_strips(t: &FrameTrace, m: &Machine, strips: usize) -> FrameModel {
    let n = t.packets.len();
    let per = n.div_ceil(strips.max(1));
    let order: Vec<usize> = (0..per).flat_map(|i| (0..strips.max(1)).map(move |k| k * per + i)).filter(|&p| p < n).collect();
    simulate_in(t, m, &order)
}

fn simulate_in(t: &FrameTrace, m: &Machine, order: &[usize]) -> FrameModel {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let (w, h) = t.size;
    let mut caches: Vec<DirectMapped> = (0..3).map(|i| DirectMapped::new(m.cache_bytes[i], m.cache_items[i])).collect();
    let item = [8u64, 4, 12];
    let mut sweep: Vec<[DirectMapped; 3]> =
        SWEEP_KB.iter().map(|&kb| std::array::from_fn(|i| DirectMapped::new(kb * 1024, kb * 1024 / item[i]))).collect();
    let mut busy = [0u64; 4];
    let mut hit_rays = 0u64;
    let mut heat_steps = vec![0f32; (w * h) as usize];
    let mut heat_misses = vec![0f32; (w * h) as usize];
    let bytes_per_cycle = m.memory_bytes_s / m.clock_hz;
    // Per thread: (packet, next step, its misses so far).
    let threads = m.threads.max(1) as usize;
    let mut state: Vec<(usize, usize, u64)> = vec![(usize::MAX, 0, 0); threads];
    let mut bufs: Vec<Vec<Op>> = vec![Vec::new(); threads];
    let mut next_packet = 0usize;
    let mut unit_free = [0u64; 4];
    let mut mem_free = 0f64;
    let mut end = 0u64;
    let mut mem_bytes = 0u64;
    // Events: (time, thread, data ready).
    let mut heap: BinaryHeap<Reverse<(u64, u32, bool)>> = (0..threads as u32).map(|i| Reverse((0, i, false))).collect();
    while let Some(Reverse((now, th, ready))) = heap.pop() {
        let s = &mut state[th as usize];
        let buf = &mut bufs[th as usize];
        if s.0 == usize::MAX || s.1 >= buf.len() {
            // The packet is done (or none yet): record it, take the next one.
            if s.0 != usize::MAX {
                let (_, (px, py), _, hits) = t.packets[s.0];
                hit_rays += hits;
                let steps = t.packet_ops(s.0).iter().filter(|o| o.unit == 0).count() as f32;
                for (x, y) in [(px, py), (px + 1, py), (px, py + 1), (px + 1, py + 1)] {
                    if x < w && y < h {
                        heat_steps[(y * w + x) as usize] = steps;
                        heat_misses[(y * w + x) as usize] = s.2 as f32;
                    }
                }
                end = end.max(now);
            }
            let Some(&next) = order.get(next_packet) else {
                s.0 = usize::MAX;
                continue;
            };
            *s = (next, 0, 0);
            next_packet += 1;
            let (_, _, live, hits) = t.packets[s.0];
            machine_ops(t.packet_ops(s.0), live, hits, m, buf);
            if buf.is_empty() {
                heap.push(Reverse((now, th, false)));
                continue;
            }
        }
        let op = buf[s.1];
        if !ready && op.cache != NO_READ {
            let c = usize::from(op.cache);
            let missed = caches[c].access(op.addr, u64::from(op.bytes));
            for sw in &mut sweep {
                sw[c].access(op.addr, u64::from(op.bytes));
            }
            if missed > 0 {
                s.2 += missed;
                let bytes = missed * caches[c].item_bytes();
                mem_bytes += bytes;
                let start = mem_free.max(now as f64);
                mem_free = start + bytes as f64 / bytes_per_cycle;
                let arrive = (mem_free + f64::from(m.memory_latency)).ceil() as u64;
                heap.push(Reverse((arrive, th, true)));
                continue;
            }
        }
        let u = usize::from(op.unit);
        let start = unit_free[u].max(now);
        unit_free[u] = start + u64::from(op.cycles);
        busy[u] += u64::from(op.cycles);
        s.1 += 1;
        heap.push(Reverse((unit_free[u] + u64::from(m.unit_latency), th, false)));
    }
    let cycles = end.max(mem_free.ceil() as u64).max(1);
    let mem_cycles = (mem_bytes as f64 / bytes_per_cycle).ceil() as u64;
    let fps = m.clock_hz / cycles as f64;
    let shading_bytes = hit_rays * m.shade_bytes + u64::from(w) * u64::from(h) * 4;
    let core_bytes: u64 = caches.iter().map(DirectMapped::miss_bytes).sum();
    let (core, shading) = (core_bytes as f64 * fps / 1e6, shading_bytes as f64 * fps / 1e6);
    FrameModel {
        size: (w, h),
        index: t.index,
        threads: threads as u32,
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
        packets: t.packets.len() as u64,
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
    /// node under two instances is two; the steps keep the order of the first reads.
    #[test]
    fn packet_ops_by_hand() {
        let m = Machine { shade_steps: 2, generate_rays: false, ..Machine::default() };
        let mut ops = Vec::new();
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
        let mut recorded = Vec::new();
        packet_ops(&reads, &mut recorded);
        machine_ops(&recorded, 4, 3, &m, &mut ops);
        let steps: Vec<(u8, u16, u8)> = ops.iter().map(|o| (o.unit, o.cycles, o.cache)).collect();
        assert_eq!(steps, [(0, 1, 0), (1, 1, 1), (2, 5, 2), (3, 4, NO_READ), (2, 2, 2), (0, 1, 0), (2, 6, NO_READ)]);
        // Ray generation: a packet's 4 rays made in 4 + 1 steps of the transformation unit.
        machine_ops(&recorded, 4, 3, &Machine { generate_rays: true, ..m }, &mut ops);
        assert_eq!((ops[0].unit, ops[0].cycles, ops[0].cache), (2, 5, NO_READ));
        assert_eq!(ops.len(), 8);
        // Results through the traversal unit: a traversal cycle after the intersection.
        machine_ops(&recorded, 4, 3, &Machine { results_via_traversal: true, ..m }, &mut ops);
        assert_eq!((ops[4].unit, ops[4].cycles), (0, 1));
    }

    /// The simulation by hand: one thread, one packet of three steps that miss, on an
    /// otherwise idle machine, takes each step's memory time, latency, cycles and unit
    /// latency one after another; a second read of the same item hits.
    #[test]
    fn one_thread_by_hand() {
        let m = Machine { unit_latency: 3, memory_latency: 10, memory_bytes_s: 8.0 * 90e6, ..Machine::default() };
        let ops = vec![
            Op { addr: 0, bytes: 8, cycles: 1, unit: 0, cache: 0 },
            Op { addr: 0, bytes: 8, cycles: 1, unit: 0, cache: 0 },
            Op { addr: 64, bytes: 4, cycles: 1, unit: 1, cache: 1 },
            Op { addr: 0, bytes: 0, cycles: 4, unit: 3, cache: NO_READ },
        ];
        let t = FrameTrace { size: (2, 2), index: "kd", ops, packets: vec![(0, (0, 0), 0, 0)] };
        let f = simulate(&t, &Machine { threads: 1, ..m });
        // Node: 1 cycle of memory (8 B at 8 B/cycle) + 10, 1 + 3; the same node again:
        // hit, 1 + 3; list entry: its 4-byte item, 0.5 cycle of memory from cycle 19 + 10
        // (arriving at 29.5, rounded up to 30), 1 + 3; intersection 4 + 3.
        assert_eq!(f.cycles, 11 + 4 + 4 + 11 + 4 + 7);
        assert_eq!(f.busy[..4], [2, 1, 0, 4]);
        assert_eq!(f.hit[0], 50.0);
        assert_eq!(f.threads, 1);
    }
}

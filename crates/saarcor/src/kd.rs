//! SaarCOR's index: kd-trees at both levels, with mailboxed object lists.
//!
//! SaarCOR (Schmittler, Woop, Wagner, Paul and Slusallek, "Realtime Ray Tracing of Dynamic
//! Scenes on an FPGA Chip", Graphics Hardware 2004) traverses a kd-tree over the
//! instances of a scene and, inside each instance, a kd-tree over the object's
//! triangles; a leaf holds a list of object ids that its list unit reads one by one, with
//! a mailbox so that an object referenced by several leaves is tested once per ray. This
//! module builds the same structure so that the hardware study (`lucent report --index
//! kd`) can model the paper's machine on its own data structure:
//!
//! - **Build**: the surface area heuristic with the sweep over sorted split events of
//!   Wald and Havran, "On building fast kd-trees for ray tracing, and on doing that in
//!   O(N log N)" (RT 2006): start, end and planar events per axis, planar primitives put
//!   on the cheaper side, a bonus for cutting off empty space, Havran's depth limit
//!   `8 + 1.3 log2 N`. We sort the events at every node (O(N log² N), simpler than the
//!   paper's presorted merge and fast enough for a study tool), and clip primitives by
//!   their boxes, not by the exact triangle ("perfect splits" would tighten leaves).
//! - **Layout**: 8-byte nodes as SaarCOR's (axis and child, or list offset and count;
//!   the split plane), depth first (the left child follows its parent), 4-byte list
//!   entries, and per triangle the unit-triangle map of [`lucent_accel::triangle`].
//! - **Traversal**: single rays with a stack of (node, far t) (Havran's recursive
//!   traversal, TA_B^rec) and SaarCOR's packets of 4 rays with one stack and per-lane
//!   segments (Wald, Slusallek, Benthin and Wagner, "Interactive Rendering with Coherent
//!   Ray Tracing", EG 2001): a packet goes down one side when every live ray does,
//!   otherwise both. Packets whose rays differ in direction signs run as single rays.
//! - **Precision**: every traversal and intersection step rounds its results through a
//!   [`Precision`] (exact f32 by default), which is how the study emulates SaarCOR's
//!   24-bit floats and other formats.
//!
//! Every step reports to the [`Counters`] seam.

use glam::{Affine3A, Vec3};
use lucent_accel::triangle::{unit_triangle_hit, UnitTriangle, NEVER_HIT, ROTATION};
use lucent_accel::Geometry;
use lucent_accel::{Aabb, BuildError, Counters, Hit, Instance, Level, Ray, Shape, INVALID};
use lucent_render::World;

/// Rounding applied after every arithmetic step of the kd kernels (the precision
/// emulation of the hardware study). [`Exact`] leaves f32 as it is.
pub trait Precision {
    /// True for plain f32: the kernels then use the reference triangle test itself
    /// ([`lucent_accel::triangle::unit_triangle_hit`], fused products), so their hits equal the
    /// reference kernels' to the bit.
    const EXACT: bool = false;
    /// `x` rounded to the emulated format.
    fn r(x: f32) -> f32;
}

/// IEEE f32: no rounding beyond the hardware's.
#[derive(Clone, Copy, Debug, Default)]
pub struct Exact;

impl Precision for Exact {
    const EXACT: bool = true;
    #[inline(always)]
    fn r(x: f32) -> f32 {
        x
    }
}

/// An 8-byte node: `a` = axis (0-2) | right child << 2 for an inner node, or 3 | list
/// offset << 2 for a leaf; `b` = the split plane's bits, or the leaf's list length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct KdNode {
    a: u32,
    b: u32,
}

impl KdNode {
    fn inner(axis: usize, right: u32, split: f32) -> Self {
        Self { a: axis as u32 | (right << 2), b: split.to_bits() }
    }
    fn leaf(first: u32, count: u32) -> Self {
        Self { a: 3 | (first << 2), b: count }
    }
    /// Whether this is a leaf.
    #[must_use]
    pub fn is_leaf(self) -> bool {
        self.a & 3 == 3
    }
    fn axis(self) -> usize {
        (self.a & 3) as usize
    }
    fn right(self) -> u32 {
        self.a >> 2
    }
    fn split(self) -> f32 {
        f32::from_bits(self.b)
    }
    fn list(self) -> (u32, u32) {
        (self.a >> 2, self.b)
    }
}

/// Build parameters of the surface area heuristic.
#[derive(Clone, Copy, Debug)]
pub struct KdOptions {
    /// Cost of one traversal step.
    pub cost_traverse: f32,
    /// Cost of one primitive test.
    pub cost_intersect: f32,
    /// Factor on the cost of a split that cuts off empty space (Wald & Havran's λ).
    pub empty_bonus: f32,
    /// Depth limit; 0 means Havran's `8 + 1.3 log2 N`.
    pub max_depth: u32,
    /// Leaves of more items than this split on (at the cheapest plane) even where the
    /// heuristic would stop, while a split leaves both sides smaller; 0: the heuristic
    /// alone decides.
    pub max_leaf: usize,
    /// Split planes and costs from each triangle clipped to the node (Havran's perfect
    /// splits) instead of the triangle's box cut at the node's faces.
    pub perfect_splits: bool,
}

impl Default for KdOptions {
    fn default() -> Self {
        // Wald & Havran's K_T = 15, K_I = 20 (only their ratio matters), λ = 0.8, and
        // their perfect splits.
        Self { cost_traverse: 15.0, cost_intersect: 20.0, empty_bonus: 0.8, max_depth: 0, max_leaf: 0, perfect_splits: true }
    }
}

/// A kd-tree over items given by their boxes: nodes and the leaves' object lists.
#[derive(Clone, Debug, Default)]
pub struct KdTree {
    nodes: Vec<KdNode>,
    list: Vec<u32>,
    bounds: Aabb,
    /// Where its nodes are in the modelled machine's memory (its list follows them): the
    /// addresses its walks report, the same in every run (see [`KdTwoLevel::new`]).
    at: u64,
}

/// Statistics of a kd-tree.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KdStats {
    /// Nodes (inner and leaves).
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Empty leaves.
    pub empty_leaves: usize,
    /// Object-list entries (an item referenced by several leaves counts each time).
    pub list_entries: usize,
    /// Deepest leaf.
    pub depth: usize,
    /// Bytes of nodes and lists.
    pub bytes: usize,
}

#[derive(Clone, Copy)]
struct Event {
    pos: f32,
    /// 0 end, 1 planar, 2 start (the order at equal positions).
    kind: u8,
}

enum Tree {
    Leaf(Vec<u32>),
    Inner { axis: usize, split: f32, left: Box<Tree>, right: Box<Tree> },
}

impl KdTree {
    /// Builds a tree over items with boxes `boxes` (items with empty or non-finite boxes
    /// are left out: no ray can hit them).
    ///
    /// # Errors
    /// [`BuildError::TooLarge`] when the lists would not fit 30-bit offsets.
    pub fn build(boxes: &[Aabb], opts: KdOptions) -> Result<Self, BuildError> {
        Self::build_clipped(boxes, None, opts)
    }

    /// [`Self::build`] over triangles `tris` (their boxes `boxes`), whose splits clip
    /// the triangles to the nodes when `clip` is given.
    fn build_clipped(boxes: &[Aabb], clip: Clip<'_>, opts: KdOptions) -> Result<Self, BuildError> {
        let ids: Vec<u32> = (0..boxes.len() as u32).filter(|&i| !boxes[i as usize].is_empty() && boxes[i as usize].is_finite()).collect();
        let bounds = ids.iter().fold(Aabb::EMPTY, |b, &i| b.union(boxes[i as usize]));
        let n = ids.len().max(1) as f32;
        let depth = if opts.max_depth == 0 { (8.0 + 1.3 * n.log2()).round() as u32 } else { opts.max_depth }.min(MAX_DEPTH);
        let tree = if ids.is_empty() {
            Tree::Leaf(Vec::new())
        } else {
            let local = ids.iter().map(|&i| boxes[i as usize]).collect();
            build_node(ids, local, bounds, depth, &opts, clip)
        };
        let mut out = Self { nodes: Vec::new(), list: Vec::new(), bounds, at: 0 };
        out.flatten(&tree)?;
        Ok(out)
    }

    fn flatten(&mut self, t: &Tree) -> Result<(), BuildError> {
        const LIMIT: usize = 1 << 30;
        match t {
            Tree::Leaf(items) => {
                if self.list.len() + items.len() >= LIMIT {
                    return Err(BuildError::TooLarge(self.list.len()));
                }
                self.nodes.push(KdNode::leaf(self.list.len() as u32, items.len() as u32));
                self.list.extend_from_slice(items);
            }
            Tree::Inner { axis, split, left, right } => {
                let me = self.nodes.len();
                self.nodes.push(KdNode::leaf(0, 0));
                self.flatten(left)?;
                if self.nodes.len() >= LIMIT {
                    return Err(BuildError::TooLarge(self.nodes.len()));
                }
                self.nodes[me] = KdNode::inner(*axis, self.nodes.len() as u32, *split);
                self.flatten(right)?;
            }
        }
        Ok(())
    }

    /// The modelled address of node `i`.
    #[inline(always)]
    fn node_addr(&self, i: u32) -> usize {
        (self.at + u64::from(i) * std::mem::size_of::<KdNode>() as u64) as usize
    }

    /// The modelled address of its list: after its nodes, at a 64-byte boundary.
    #[inline(always)]
    fn list_at(&self) -> u64 {
        align(self.at + (self.nodes.len() * std::mem::size_of::<KdNode>()) as u64)
    }

    /// The modelled address of list entry `e`.
    #[inline(always)]
    fn list_addr(&self, e: u32) -> usize {
        (self.list_at() + u64::from(e) * 4) as usize
    }

    /// Places the tree at `at`; returns the first address after its nodes and list.
    fn place(&mut self, at: u64) -> u64 {
        self.at = at;
        align(self.list_at() + self.list.len() as u64 * 4)
    }

    /// The box of every item in the tree.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The nodes (depth first; the root first).
    #[must_use]
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// Node and list statistics.
    #[must_use]
    pub fn stats(&self) -> KdStats {
        let mut s = KdStats { nodes: self.nodes.len(), list_entries: self.list.len(), ..KdStats::default() };
        s.bytes = self.nodes.len() * std::mem::size_of::<KdNode>() + self.list.len() * 4;
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, d)) = stack.pop() {
            let Some(&n) = self.nodes.get(i) else { continue };
            if n.is_leaf() {
                s.leaves += 1;
                s.empty_leaves += usize::from(n.list().1 == 0);
                s.depth = s.depth.max(d);
            } else {
                stack.push((i + 1, d + 1));
                stack.push((n.right() as usize, d + 1));
            }
        }
        s
    }

    /// Checks the structure: children and lists in range, every item in `0..items`.
    ///
    /// # Errors
    /// What is wrong.
    pub fn validate(&self, items: usize) -> Result<(), String> {
        for (i, n) in self.nodes.iter().enumerate() {
            if n.is_leaf() {
                let (f, c) = n.list();
                let end = f as usize + c as usize;
                if end > self.list.len() {
                    return Err(format!("leaf {i}: list {f}..{end} beyond {}", self.list.len()));
                }
                if let Some(x) = self.list[f as usize..end].iter().find(|&&x| x as usize >= items) {
                    return Err(format!("leaf {i}: item {x} of {items}"));
                }
            } else if n.right() as usize <= i + 1 || n.right() as usize >= self.nodes.len() || !n.split().is_finite() {
                return Err(format!("node {i}: right child {} of {}", n.right(), self.nodes.len()));
            }
        }
        Ok(())
    }
}

/// The box's surface area (0 for an empty box).
fn area(b: &Aabb) -> f32 {
    if b.is_empty() {
        0.0
    } else {
        2.0 * b.half_area()
    }
}

fn split_box(b: Aabb, axis: usize, p: f32) -> (Aabb, Aabb) {
    let (mut l, mut r) = (b, b);
    l.max[axis] = p;
    r.min[axis] = p;
    (l, r)
}

/// The cheapest split of `ids` in `node` by SAH over sorted events: (cost, axis, plane,
/// planar items to the left).
fn find_split(local: &[Aabb], node: Aabb, o: &KdOptions) -> Option<(f32, usize, f32, bool)> {
    let sa = area(&node);
    if sa <= 0.0 || !sa.is_finite() {
        return None;
    }
    let n = local.len();
    let mut best: Option<(f32, usize, f32, bool)> = None;
    let mut ev: Vec<Event> = Vec::with_capacity(2 * n);
    for axis in 0..3 {
        if node.max[axis] <= node.min[axis] {
            continue;
        }
        ev.clear();
        for b in local {
            let (lo, hi) = (b.min[axis].max(node.min[axis]), b.max[axis].min(node.max[axis]));
            if lo == hi {
                ev.push(Event { pos: lo, kind: 1 });
            } else {
                ev.push(Event { pos: lo, kind: 2 });
                ev.push(Event { pos: hi, kind: 0 });
            }
        }
        ev.sort_unstable_by(|a, b| a.pos.total_cmp(&b.pos).then(a.kind.cmp(&b.kind)));
        let (mut nl, mut nr) = (0usize, n);
        let mut k = 0;
        while k < ev.len() {
            let p = ev[k].pos;
            let (mut pe, mut pp, mut ps) = (0, 0, 0);
            while k < ev.len() && ev[k].pos == p && ev[k].kind == 0 {
                pe += 1;
                k += 1;
            }
            while k < ev.len() && ev[k].pos == p && ev[k].kind == 1 {
                pp += 1;
                k += 1;
            }
            while k < ev.len() && ev[k].pos == p && ev[k].kind == 2 {
                ps += 1;
                k += 1;
            }
            nr -= pp + pe;
            if p > node.min[axis] && p < node.max[axis] {
                let (lb, rb) = split_box(node, axis, p);
                let (pl, pr) = (area(&lb) / sa, area(&rb) / sa);
                let cost = |l: usize, r: usize| {
                    let bonus = if l == 0 || r == 0 { o.empty_bonus } else { 1.0 };
                    bonus * (o.cost_traverse + o.cost_intersect * (pl * l as f32 + pr * r as f32))
                };
                let (cl, cr) = (cost(nl + pp, nr), cost(nl, nr + pp));
                let (c, left) = if cl <= cr { (cl, true) } else { (cr, false) };
                if best.is_none_or(|b| c < b.0) {
                    best = Some((c, axis, p, left));
                }
            }
            nl += ps + pp;
        }
    }
    best
}

/// The triangles a tree is built over, when its splits clip them (Havran's perfect
/// splits: an item's extent in a node is its triangle clipped to the node, not its box).
type Clip<'a> = Option<&'a [[Vec3; 3]]>;

/// `t` clipped to `b` (Sutherland and Hodgman against the box's six planes): the box of
/// what is left, empty when nothing is.
fn clipped_box(t: &[Vec3; 3], b: &Aabb) -> Aabb {
    let mut poly: Vec<Vec3> = t.to_vec();
    let mut next = Vec::with_capacity(9);
    for axis in 0..3 {
        for (plane, keep_above) in [(b.min[axis], true), (b.max[axis], false)] {
            next.clear();
            let inside = |p: &Vec3| if keep_above { p[axis] >= plane } else { p[axis] <= plane };
            for k in 0..poly.len() {
                let (a, c) = (poly[k], poly[(k + 1) % poly.len()]);
                if inside(&a) {
                    next.push(a);
                }
                if inside(&a) != inside(&c) {
                    let s = (plane - a[axis]) / (c[axis] - a[axis]);
                    let mut q = a + (c - a) * s;
                    q[axis] = plane;
                    next.push(q);
                }
            }
            std::mem::swap(&mut poly, &mut next);
            if poly.is_empty() {
                return Aabb::EMPTY;
            }
        }
    }
    let mut out = Aabb::from_points(&poly);
    // Rounding may step outside the node by an ulp: the node bounds it.
    for a in 0..3 {
        out.min[a] = out.min[a].max(b.min[a]);
        out.max[a] = out.max[a].min(b.max[a]);
    }
    out
}

fn build_node(ids: Vec<u32>, local: Vec<Aabb>, node: Aabb, depth: u32, o: &KdOptions, clip: Clip<'_>) -> Tree {
    let leaf_cost = o.cost_intersect * ids.len() as f32;
    if ids.len() <= 1 || depth == 0 {
        return Tree::Leaf(ids);
    }
    let Some((cost, axis, p, planar_left)) = find_split(&local, node, o) else { return Tree::Leaf(ids) };
    let forced = o.max_leaf > 0 && ids.len() > o.max_leaf;
    if cost >= leaf_cost && !forced {
        return Tree::Leaf(ids);
    }
    let (mut l, mut r) = (Vec::new(), Vec::new());
    let (mut lbx, mut rbx) = (Vec::new(), Vec::new());
    for (&i, &b) in ids.iter().zip(&local) {
        let (lo, hi) = (b.min[axis].max(node.min[axis]), b.max[axis].min(node.max[axis]));
        let (go_l, go_r) = if lo == p && hi == p { (planar_left, !planar_left) } else { (lo < p, hi > p) };
        if go_l {
            l.push(i);
            lbx.push(b);
        }
        if go_r {
            r.push(i);
            rbx.push(b);
        }
    }
    if forced && cost >= leaf_cost && (l.len() >= ids.len() || r.len() >= ids.len()) {
        return Tree::Leaf(ids);
    }
    drop(ids);
    let (lb, rb) = split_box(node, axis, p);
    // With perfect splits, each side's items are their triangles clipped to its box
    // (an item whose clipped triangle is empty there leaves that side).
    let reclip = |ids: Vec<u32>, bx: Vec<Aabb>, side: Aabb| -> (Vec<u32>, Vec<Aabb>) {
        let Some(tris) = clip else { return (ids, bx) };
        // Clipped to the side grown by a millionth of its size, so a triangle that only
        // touches it within rounding stays (a ray there must still find it).
        let pad = (side.max - side.min).max_element().max(f32::MIN_POSITIVE) * 1e-6;
        let grown = Aabb { min: side.min - Vec3::splat(pad), max: side.max + Vec3::splat(pad) };
        ids.into_iter()
            .filter_map(|i| {
                let c = clipped_box(&tris[i as usize], &grown);
                (!c.is_empty()).then_some((i, c))
            })
            .unzip()
    };
    let (l, lbx) = reclip(l, lbx, lb);
    let (r, rbx) = reclip(r, rbx, rb);
    let big = l.len() + r.len() > 4096;
    let (left, right) = if big {
        rayon::join(|| build_node(l, lbx, lb, depth - 1, o, clip), || build_node(r, rbx, rb, depth - 1, o, clip))
    } else {
        (build_node(l, lbx, lb, depth - 1, o, clip), build_node(r, rbx, rb, depth - 1, o, clip))
    };
    Tree::Inner { axis, split: p, left: Box::new(left), right: Box::new(right) }
}

/// A ray prepared for the kd kernels: origin, direction, reciprocal direction.
#[derive(Clone, Copy, Debug)]
struct KdRay {
    o: [f32; 3],
    d: [f32; 3],
    inv: [f32; 3],
}

impl KdRay {
    fn new<P: Precision>(org: Vec3, dir: Vec3) -> Self {
        let o = org.to_array().map(P::r);
        let d = dir.to_array().map(P::r);
        Self { o, d, inv: d.map(|x| P::r(1.0 / x)) }
    }
    /// The ray's entry and exit distances of box `b` (empty when `t0 > t1`).
    fn clip<P: Precision>(&self, b: &Aabb, tmin: f32, tmax: f32) -> (f32, f32) {
        let (mut t0, mut t1) = (tmin, tmax);
        for a in 0..3 {
            let n = P::r(P::r(b.min[a] - self.o[a]) * self.inv[a]);
            let f = P::r(P::r(b.max[a] - self.o[a]) * self.inv[a]);
            let (n, f) = if n <= f { (n, f) } else { (f, n) };
            // NaN (a ray in the box's face plane) leaves the interval as it is.
            if n > t0 {
                t0 = n;
            }
            if f < t1 {
                t1 = f;
            }
        }
        (t0, t1)
    }
    /// The distance to `node`'s plane (+inf for a ray in the plane) and whether the left
    /// child is the near one.
    #[inline(always)]
    fn plane<P: Precision>(&self, axis: usize, split: f32) -> (f32, bool) {
        let t = P::r(P::r(split - self.o[axis]) * self.inv[axis]);
        (if t.is_nan() { f32::INFINITY } else { t }, !self.d[axis].is_sign_negative())
    }
}

/// The unit-triangle test with every step rounded by `P` (with [`Exact`], the same
/// conditions as [`lucent_accel::triangle::unit_triangle_hit`], without fused products).
#[inline(always)]
fn unit_hit<P: Precision>(tri: &UnitTriangle, o: &[f32; 3], d: &[f32; 3], tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
    let r = ROTATION[tri.axis as usize & 3];
    let (oc, dc) = ([o[0], o[1], o[2], 0.0], [d[0], d[1], d[2], 0.0]);
    let m = tri.m.map(P::r);
    let mul = |a: f32, b: f32| P::r(a * b);
    let add = |a: f32, b: f32| P::r(a + b);
    let (o0, o1, o2) = (oc[r[0]], oc[r[1]], oc[r[2]]);
    let (d0, d1, d2) = (dc[r[0]], dc[r[1]], dc[r[2]]);
    let ox = add(add(mul(m[0], o1), mul(m[1], o2)), m[2]);
    let oy = add(add(mul(m[3], o1), mul(m[4], o2)), m[5]);
    let oz = add(add(add(mul(m[6], o1), mul(m[7], o2)), m[8]), o0);
    let dx = add(mul(m[0], d1), mul(m[1], d2));
    let dy = add(mul(m[3], d1), mul(m[4], d2));
    let dz = add(add(mul(m[6], d1), mul(m[7], d2)), d0);
    if dz == 0.0 || !dz.is_finite() {
        return None;
    }
    let t = P::r(-oz / dz);
    if !(t >= tmin && t < tmax) {
        return None;
    }
    let u = add(ox, mul(t, dx));
    let v = add(oy, mul(t, dy));
    (u >= 0.0 && v >= 0.0 && add(u, v) <= 1.0).then_some((t, u, v))
}

/// Deepest tree the build makes: a walk's stack holds at most one entry per level.
const MAX_DEPTH: u32 = 60;

/// `at` rounded up to a 64-byte boundary.
fn align(at: u64) -> u64 {
    at.div_ceil(64) * 64
}
/// Entries of a walk's stack (PERF: a fixed array; a `Vec` per ray cost an allocation).
const KD_STACK: usize = MAX_DEPTH as usize + 4;

/// A mailbox of the last objects tested by one ray (SaarCOR's list unit): direct mapped,
/// 16 entries, keyed by object id.
#[derive(Clone, Copy)]
struct Mailbox {
    ids: [u32; 16],
}

impl Mailbox {
    fn new() -> Self {
        Self { ids: [INVALID; 16] }
    }
    /// True when `id` was tested already; records it otherwise.
    #[inline(always)]
    fn seen(&mut self, id: u32) -> bool {
        let slot = &mut self.ids[id as usize & 15];
        if *slot == id {
            return true;
        }
        *slot = id;
        false
    }
}

/// What a kd leaf's objects are.
trait KdItems {
    /// Tests object `id` against `r` within `[tmin, hit.t)`, narrowing `hit` (with `ANY`,
    /// any hit will do: the caller only asks whether there is one).
    fn test<P: Precision, C: Counters, const ANY: bool>(&self, id: u32, r: &Ray, kr: &KdRay, hit: &mut Hit, c: &mut C);
    /// Tests object `id` against the rays of `lanes` of a packet. By default each ray on
    /// its own; the top level of a two-level index overrides it to carry the packet into
    /// the object and walk the object's tree with it.
    #[inline(always)]
    fn test4<P: Precision, C: Counters, const ANY: bool>(
        &self,
        id: u32,
        rays: &[Ray; 4],
        kr: &[KdRay; 4],
        lanes: u8,
        hits: &mut [Hit; 4],
        c: &mut C,
    ) {
        for l in 0..4 {
            if lanes & (1 << l) != 0 {
                self.test::<P, C, ANY>(id, &rays[l], &kr[l], &mut hits[l], c);
            }
        }
    }
}

/// Closest hit in `tree` over `items` (single ray; with `ANY` the first hit found); true
/// when `hit` was narrowed.
fn walk<P: Precision, C: Counters, I: KdItems, const ANY: bool>(tree: &KdTree, items: &I, r: &Ray, hit: &mut Hit, c: &mut C) -> bool {
    let kr = KdRay::new::<P>(r.org, r.dir);
    let (mut tn, mut tf) = kr.clip::<P>(&tree.bounds, r.tmin, hit.t);
    if tree.nodes.is_empty() || tn > tf {
        return false;
    }
    let before = hit.prim;
    hit.prim = INVALID;
    let mut mb = Mailbox::new();
    let mut stack = [(0u32, 0f32, 0f32); KD_STACK];
    let mut sp = 0usize;
    let mut cur = 0u32;
    loop {
        let node = tree.nodes[cur as usize];
        c.node();
        c.node_read(tree.node_addr(cur), std::mem::size_of::<KdNode>());
        if !node.is_leaf() {
            let (t, left_near) = kr.plane::<P>(node.axis(), node.split());
            let (near, far) = if left_near { (cur + 1, node.right()) } else { (node.right(), cur + 1) };
            // Near and far by the direction's sign: a plane behind the origin has t < 0 <= tn,
            // so the ray goes to the far side, which is then the side of its origin.
            if t > tf {
                cur = near;
            } else if t < tn {
                cur = far;
            } else {
                stack[sp] = (far, t, tf);
                sp += 1;
                cur = near;
                tf = t;
            }
            continue;
        }
        let (first, count) = node.list();
        c.items(count);
        for e in first..first + count {
            c.list_read(tree.list_addr(e), 4);
            let id = tree.list[e as usize];
            if mb.seen(id) {
                c.mailbox_hit();
                continue;
            }
            items.test::<P, C, ANY>(id, r, &kr, hit, c);
            if ANY && hit.prim != INVALID {
                return true;
            }
        }
        if hit.prim != INVALID && hit.t <= tf {
            break;
        }
        // The next stack entry whose segment still starts before the hit found.
        loop {
            if sp == 0 {
                return finish(hit, before);
            }
            sp -= 1;
            let (n, a, b) = stack[sp];
            (cur, tn, tf) = (n, a, b.min(hit.t));
            if tn <= tf {
                break;
            }
        }
    }
    finish(hit, before)
}

fn finish(hit: &mut Hit, before: u32) -> bool {
    if hit.prim == INVALID {
        hit.prim = before;
        false
    } else {
        true
    }
}

/// Closest hits (with `ANY`, any hits) of up to 4 rays in `tree` as one packet (rays whose
/// direction signs all agree; the caller falls back to single rays otherwise). `live`
/// marks the lanes to trace; returns the lanes whose hit was narrowed.
fn walk4<P: Precision, C: Counters, I: KdItems, const ANY: bool>(
    tree: &KdTree,
    items: &I,
    rays: &[Ray; 4],
    live: u8,
    hits: &mut [Hit; 4],
    c: &mut C,
) -> u8 {
    let kr = rays.map(|r| KdRay::new::<P>(r.org, r.dir));
    let mut tn = [0f32; 4];
    let mut tf = [0f32; 4];
    let mut active = 0u8;
    for l in 0..4 {
        if live & (1 << l) != 0 {
            (tn[l], tf[l]) = kr[l].clip::<P>(&tree.bounds, rays[l].tmin, hits[l].t);
            if tn[l] <= tf[l] {
                active |= 1 << l;
            }
        }
    }
    if tree.nodes.is_empty() || active == 0 {
        return 0;
    }
    let before = hits.map(|h| h.prim);
    for h in hits.iter_mut() {
        h.prim = INVALID;
    }
    let mut done = 0u8;
    let mut mb = [Mailbox::new(); 4];
    let mut stack = [(0u32, [0f32; 4], [0f32; 4], 0u8); KD_STACK];
    let mut sp = 0usize;
    let mut cur = 0u32;
    loop {
        let node = tree.nodes[cur as usize];
        c.node();
        c.node_read(tree.node_addr(cur), std::mem::size_of::<KdNode>());
        if !node.is_leaf() {
            let (mut go_near, mut go_far) = (0u8, 0u8);
            let mut tsplit = [0f32; 4];
            let mut left_near = true;
            for l in 0..4 {
                if active & (1 << l) == 0 {
                    continue;
                }
                let (t, ln) = kr[l].plane::<P>(node.axis(), node.split());
                left_near = ln;
                tsplit[l] = t;
                // As the single-ray walk: near only, far only, or both.
                if t > tf[l] {
                    go_near |= 1 << l;
                } else if t < tn[l] {
                    go_far |= 1 << l;
                } else {
                    go_near |= 1 << l;
                    go_far |= 1 << l;
                }
            }
            let (near, far) = if left_near { (cur + 1, node.right()) } else { (node.right(), cur + 1) };
            if go_near == 0 {
                cur = far;
                continue;
            }
            if go_far != 0 {
                // Lanes going both ways: [t, tf] later on the far side, [tn, t] now.
                let (mut ftn, ftf) = (tn, tf);
                for l in (0..4).filter(|l| go_far & go_near & (1 << l) != 0) {
                    ftn[l] = tsplit[l];
                    tf[l] = tsplit[l];
                }
                stack[sp] = (far, ftn, ftf, go_far);
                sp += 1;
            }
            active = go_near;
            cur = near;
            continue;
        }
        let (first, count) = node.list();
        c.items(count);
        for e in first..first + count {
            c.list_read(tree.list_addr(e), 4);
            let id = tree.list[e as usize];
            let mut lanes = 0u8;
            for (l, m) in mb.iter_mut().enumerate() {
                if active & !done & (1 << l) != 0 {
                    if m.seen(id) {
                        c.mailbox_hit();
                    } else {
                        lanes |= 1 << l;
                    }
                }
            }
            if lanes != 0 {
                items.test4::<P, C, ANY>(id, rays, &kr, lanes, hits, c);
            }
            if ANY {
                for (l, h) in hits.iter().enumerate() {
                    if h.prim != INVALID {
                        done |= 1 << l;
                    }
                }
                if active & !done == 0 {
                    break;
                }
            }
        }
        for l in 0..4 {
            if active & (1 << l) != 0 && hits[l].prim != INVALID && hits[l].t <= tf[l] {
                done |= 1 << l;
            }
        }
        // Next stack entry with a lane still searching within its segment.
        loop {
            if sp == 0 {
                return finish4(hits, before);
            }
            sp -= 1;
            let (n, a, b, m) = stack[sp];
            let mut m = m & !done;
            let mut bb = b;
            for l in 0..4 {
                bb[l] = b[l].min(hits[l].t);
                if a[l] > bb[l] {
                    m &= !(1 << l);
                }
            }
            if m != 0 {
                (cur, tn, tf, active) = (n, a, bb, m);
                break;
            }
        }
    }
}

fn finish4(hits: &mut [Hit; 4], before: [u32; 4]) -> u8 {
    let mut m = 0;
    for (l, h) in hits.iter_mut().enumerate() {
        if h.prim == INVALID {
            h.prim = before[l];
        } else {
            m |= 1 << l;
        }
    }
    m
}

/// Whether the four rays' direction signs agree on every axis (a packet SaarCOR can
/// traverse together).
fn coherent(rays: &[Ray; 4], live: u8) -> bool {
    let mut sign = None;
    for (l, r) in rays.iter().enumerate() {
        if live & (1 << l) == 0 {
            continue;
        }
        let s = [r.dir.x.is_sign_negative(), r.dir.y.is_sign_negative(), r.dir.z.is_sign_negative()];
        match sign {
            None => sign = Some(s),
            Some(t) if t != s => return false,
            _ => {}
        }
    }
    true
}

/// A triangle mesh under a kd-tree (the bottom level).
#[derive(Clone, Debug)]
pub struct KdMesh {
    tree: KdTree,
    tris: Vec<UnitTriangle>,
    /// The modelled address of its triangles' maps.
    tris_at: u64,
}

impl KdMesh {
    /// Builds the tree over the triangles `indices` of `positions`.
    ///
    /// # Errors
    /// [`BuildError`] when an index is out of range or the tree too large.
    pub fn build(positions: &[Vec3], indices: &[[u32; 3]], opts: KdOptions) -> Result<Self, BuildError> {
        let mut boxes = Vec::with_capacity(indices.len());
        let mut tris = Vec::with_capacity(indices.len());
        for (i, t) in indices.iter().enumerate() {
            let v = t.map(|k| positions.get(k as usize).copied());
            let [Some(a), Some(b), Some(c)] = v else {
                return Err(BuildError::IndexOutOfRange { tri: i, index: t.iter().copied().max().unwrap_or(0), vertices: positions.len() });
            };
            match UnitTriangle::new(a, b, c) {
                Some(m) => {
                    tris.push(m);
                    boxes.push(Aabb::from_points(&[a, b, c]));
                }
                None => {
                    tris.push(NEVER_HIT);
                    boxes.push(Aabb::EMPTY);
                }
            }
        }
        let clip: Vec<[Vec3; 3]> = if opts.perfect_splits {
            indices.iter().map(|t| t.map(|k| positions.get(k as usize).copied().unwrap_or(Vec3::ZERO))).collect()
        } else {
            Vec::new()
        };
        let tree = KdTree::build_clipped(&boxes, opts.perfect_splits.then_some(clip.as_slice()), opts)?;
        let mut m = Self { tree, tris, tris_at: 0 };
        m.tris_at = m.tree.place(0);
        Ok(m)
    }

    /// The tree.
    #[must_use]
    pub fn tree(&self) -> &KdTree {
        &self.tree
    }

    /// Number of triangles (each with its unit-triangle map).
    #[must_use]
    pub fn triangles(&self) -> usize {
        self.tris.len()
    }

    /// Bytes of the tree's nodes and lists and of the triangles' maps.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.tree.stats().bytes + std::mem::size_of_val(self.tris.as_slice())
    }

    /// Closest hit (single ray) with precision `P`, reporting to `c`.
    pub fn intersect_with<P: Precision, C: Counters>(&self, ray: &Ray, c: &mut C) -> Option<Hit> {
        let mut hit = Hit::none(ray.tmax);
        walk::<P, C, _, false>(&self.tree, self, ray, &mut hit, c).then_some(hit)
    }

    /// Closest hit (single ray, f32).
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_with::<Exact, ()>(ray, &mut ())
    }

    /// Whether anything lies within `[ray.tmin, ray.tmax)` (single ray, any hit), with
    /// precision `P`, reporting to `c`.
    pub fn occluded_with<P: Precision, C: Counters>(&self, ray: &Ray, c: &mut C) -> bool {
        walk::<P, C, _, true>(&self.tree, self, ray, &mut Hit::none(ray.tmax), c)
    }

    /// Closest hits of four rays as one SaarCOR packet (together when their direction
    /// signs agree, else ray by ray): the same answers as [`Self::intersect_with`].
    pub fn intersect4_with<P: Precision, C: Counters>(&self, rays: &[Ray; 4], c: &mut C) -> [Option<Hit>; 4] {
        if !coherent(rays, 0xF) {
            return rays.map(|r| self.intersect_with::<P, C>(&r, c));
        }
        let mut hits = rays.map(|r| Hit::none(r.tmax));
        walk4::<P, C, _, false>(&self.tree, self, rays, 0xF, &mut hits, c);
        hits.map(|h| h.is_hit().then_some(h))
    }

    /// Occlusion of four rays as one packet (as [`Self::intersect4_with`]).
    pub fn occluded4_with<P: Precision, C: Counters>(&self, rays: &[Ray; 4], c: &mut C) -> [bool; 4] {
        if !coherent(rays, 0xF) {
            return rays.map(|r| self.occluded_with::<P, C>(&r, c));
        }
        let mut hits = rays.map(|r| Hit::none(r.tmax));
        walk4::<P, C, _, true>(&self.tree, self, rays, 0xF, &mut hits, c);
        hits.map(|h| h.is_hit())
    }
}

impl KdItems for KdMesh {
    #[inline(always)]
    fn test<P: Precision, C: Counters, const ANY: bool>(&self, id: u32, r: &Ray, kr: &KdRay, hit: &mut Hit, c: &mut C) {
        let tri = &self.tris[id as usize];
        c.triangles(
            (self.tris_at + u64::from(id) * std::mem::size_of::<UnitTriangle>() as u64) as usize,
            std::mem::size_of::<UnitTriangle>(),
            1,
        );
        let h =
            if P::EXACT { unit_triangle_hit(tri, r.org, r.dir, r.tmin, hit.t) } else { unit_hit::<P>(tri, &kr.o, &kr.d, r.tmin, hit.t) };
        if let Some((t, u, v)) = h {
            *hit = Hit { t, u, v, prim: id, inst: hit.inst };
        }
    }
}

/// What an instance of a kd scene refers to.
#[derive(Clone, Debug)]
pub enum KdGeometry {
    /// A triangle mesh with its own kd-tree.
    Mesh(KdMesh),
    /// An analytic shape in canonical space.
    Shape(Shape),
}

/// A two-level kd index: a kd-tree over instances (mailboxed, since an instance's box
/// can reach several leaves), each instance a mesh with its own kd-tree or a shape.
#[derive(Clone, Debug)]
pub struct KdTwoLevel {
    top: KdTree,
    geometries: Vec<KdGeometry>,
    /// The modelled addresses of the shapes (by geometry) and of the instances' matrices.
    shape_at: Vec<u64>,
    inst_at: u64,
    instances: Vec<Instance>,
    /// Instances whose box is unbounded (planes): tested by every ray.
    unbounded: Vec<u32>,
}

impl KdTwoLevel {
    /// Builds the top-level tree over `instances` of `geometries`.
    ///
    /// # Errors
    /// [`BuildError`] when an instance names a missing geometry or the tree is too large.
    pub fn new(geometries: Vec<KdGeometry>, instances: Vec<Instance>, opts: KdOptions) -> Result<Self, BuildError> {
        let mut boxes = Vec::with_capacity(instances.len());
        let mut unbounded = Vec::new();
        for (i, inst) in instances.iter().enumerate() {
            let local = match geometries.get(inst.geometry as usize) {
                Some(KdGeometry::Mesh(m)) => m.tree.bounds,
                Some(KdGeometry::Shape(s)) => {
                    if !s.is_bounded() {
                        unbounded.push(i as u32);
                        boxes.push(Aabb::EMPTY);
                        continue;
                    }
                    s.bounds_local()
                }
                None => return Err(BuildError::NoSuchGeometry { inst: i, geom: inst.geometry, count: geometries.len() }),
            };
            boxes.push(if local.is_empty() { local } else { local.transformed(&inst.world_from_object) });
        }
        let mut top = KdTree::build(&boxes, opts)?;
        // The modelled memory image, as the scene would be uploaded: the top tree, then
        // each geometry's tree, list and triangle maps (or its shape), then the instances'
        // matrices, each array at a 64-byte boundary.
        let mut geometries = geometries;
        let mut at = top.place(0);
        let mut shape_at = vec![0; geometries.len()];
        for (g, geom) in geometries.iter_mut().enumerate() {
            match geom {
                KdGeometry::Mesh(m) => {
                    m.tris_at = m.tree.place(at);
                    at = align(m.tris_at + std::mem::size_of_val(m.tris.as_slice()) as u64);
                }
                KdGeometry::Shape(_) => {
                    shape_at[g] = at;
                    at = align(at + std::mem::size_of::<Shape>() as u64);
                }
            }
        }
        Ok(Self { top, geometries, shape_at, inst_at: at, instances, unbounded })
    }

    /// The top-level tree.
    #[must_use]
    pub fn top(&self) -> &KdTree {
        &self.top
    }

    /// The geometries.
    #[must_use]
    pub fn geometries(&self) -> &[KdGeometry] {
        &self.geometries
    }

    /// Bytes of the index: both levels' nodes and lists, and the meshes' triangle maps.
    #[must_use]
    pub fn bytes(&self) -> usize {
        let meshes = self.geometries.iter().map(|g| match g {
            KdGeometry::Mesh(m) => m.bytes(),
            KdGeometry::Shape(_) => 0,
        });
        self.top.stats().bytes + meshes.sum::<usize>()
    }

    /// Closest hit of one ray with precision `P`, reporting to `c`.
    pub fn intersect_with<P: Precision, C: Counters>(&self, ray: &Ray, c: &mut C) -> Option<Hit> {
        let hit = self.single::<P, C, false>(ray, c);
        hit.is_hit().then_some(hit)
    }

    /// Closest hit of one ray (f32).
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_with::<Exact, ()>(ray, &mut ())
    }

    /// Whether anything lies within `[ray.tmin, ray.tmax)` (any hit), with precision `P`,
    /// reporting to `c`.
    pub fn occluded_with<P: Precision, C: Counters>(&self, ray: &Ray, c: &mut C) -> bool {
        self.single::<P, C, true>(ray, c).is_hit()
    }

    /// Closest hits of four rays as one SaarCOR packet (`None` for a miss): together when
    /// their direction signs agree, else ray by ray; inside an instance the packet walks
    /// the object's tree together again when the carried rays' signs agree. The same
    /// answers as [`Self::intersect`].
    pub fn intersect4_with<P: Precision, C: Counters>(&self, rays: &[Ray; 4], c: &mut C) -> [Option<Hit>; 4] {
        if !coherent(rays, 0xF) {
            return rays.map(|r| self.intersect_with::<P, C>(&r, c));
        }
        self.packet::<P, C, false>(rays, c).map(|h| h.is_hit().then_some(h))
    }

    /// Occlusion of four rays as one packet (as [`Self::intersect4_with`]).
    pub fn occluded4_with<P: Precision, C: Counters>(&self, rays: &[Ray; 4], c: &mut C) -> [bool; 4] {
        if !coherent(rays, 0xF) {
            return rays.map(|r| self.occluded_with::<P, C>(&r, c));
        }
        self.packet::<P, C, true>(rays, c).map(|h| h.is_hit())
    }

    fn single<P: Precision, C: Counters, const ANY: bool>(&self, ray: &Ray, c: &mut C) -> Hit {
        let mut hit = Hit::none(ray.tmax);
        c.enter(Level::Top);
        let kr = KdRay::new::<P>(ray.org, ray.dir);
        for &i in &self.unbounded {
            self.test::<P, C, ANY>(i, ray, &kr, &mut hit, c);
            if ANY && hit.is_hit() {
                return hit;
            }
        }
        walk::<P, C, _, ANY>(&self.top, self, ray, &mut hit, c);
        hit
    }

    fn packet<P: Precision, C: Counters, const ANY: bool>(&self, rays: &[Ray; 4], c: &mut C) -> [Hit; 4] {
        let mut hits = rays.map(|r| Hit::none(r.tmax));
        c.enter(Level::Top);
        let kr = rays.map(|r| KdRay::new::<P>(r.org, r.dir));
        for &i in &self.unbounded {
            Top4(self).test4::<P, C, ANY>(i, rays, &kr, 0xF, &mut hits, c);
        }
        let live = (0..4).filter(|&l| !(ANY && hits[l].is_hit())).fold(0u8, |m, l| m | 1 << l);
        walk4::<P, C, _, ANY>(&self.top, &Top4(self), rays, live, &mut hits, c);
        hits
    }

    /// `r` in instance `inst`'s object space (each component rounded by `P`), counted as
    /// a transformation when it is one.
    #[inline(always)]
    fn local<P: Precision, C: Counters>(&self, id: u32, r: &Ray, c: &mut C) -> Ray {
        let inst = &self.instances[id as usize];
        if inst.is_identity() {
            return *r;
        }
        let size = std::mem::size_of::<Affine3A>();
        c.transform((self.inst_at + u64::from(id) * size as u64) as usize, size);
        let m = &inst.object_from_world;
        let round = |v: Vec3| Vec3::new(P::r(v.x), P::r(v.y), P::r(v.z));
        Ray { org: round(m.transform_point3(r.org)), dir: round(m.transform_vector3(r.dir)), tmin: r.tmin, tmax: r.tmax }
    }
}

impl KdItems for KdTwoLevel {
    #[inline(always)]
    fn test<P: Precision, C: Counters, const ANY: bool>(&self, id: u32, r: &Ray, _kr: &KdRay, hit: &mut Hit, c: &mut C) {
        let inst = &self.instances[id as usize];
        let local = self.local::<P, C>(id, r, c);
        match &self.geometries[inst.geometry as usize] {
            KdGeometry::Mesh(m) => {
                c.enter(Level::Bottom);
                let mut h = *hit;
                if walk::<P, C, _, ANY>(&m.tree, m, &Ray { tmax: hit.t, ..local }, &mut h, c) {
                    *hit = Hit { inst: id, ..h };
                }
                c.enter(Level::Top);
            }
            KdGeometry::Shape(s) => {
                c.shape(self.shape_at[inst.geometry as usize] as usize, std::mem::size_of::<Shape>());
                if let Some(h) = s.intersect_local(local.org, local.dir, local.tmin, hit.t) {
                    *hit = Hit { t: h.t, u: 0.0, v: 0.0, prim: h.part, inst: id };
                }
            }
        }
    }
}

/// The top level's items for a packet. As SaarCOR does, the packet's rays are carried
/// into the instance one by one (n transformations, which its model counts as n+1 steps
/// for rays sharing an origin) and the object's tree is walked by the packet together,
/// when the carried rays still agree on their direction signs (a mirroring instance can
/// break that; those rays go one by one).
struct Top4<'a>(&'a KdTwoLevel);

impl KdItems for Top4<'_> {
    #[inline(always)]
    fn test<P: Precision, C: Counters, const ANY: bool>(&self, id: u32, r: &Ray, kr: &KdRay, hit: &mut Hit, c: &mut C) {
        self.0.test::<P, C, ANY>(id, r, kr, hit, c);
    }

    #[inline(always)]
    fn test4<P: Precision, C: Counters, const ANY: bool>(
        &self,
        id: u32,
        rays: &[Ray; 4],
        kr: &[KdRay; 4],
        lanes: u8,
        hits: &mut [Hit; 4],
        c: &mut C,
    ) {
        let tl = self.0;
        let inst = &tl.instances[id as usize];
        let KdGeometry::Mesh(m) = &tl.geometries[inst.geometry as usize] else {
            for l in (0..4).filter(|l| lanes & (1 << l) != 0) {
                tl.test::<P, C, ANY>(id, &rays[l], &kr[l], &mut hits[l], c);
            }
            return;
        };
        let mut local = *rays;
        for l in (0..4).filter(|l| lanes & (1 << l) != 0) {
            local[l] = Ray { tmax: hits[l].t, ..tl.local::<P, C>(id, &rays[l], c) };
        }
        c.enter(Level::Bottom);
        if coherent(&local, lanes) {
            let mut h = *hits;
            let got = walk4::<P, C, _, ANY>(&m.tree, m, &local, lanes, &mut h, c);
            for l in (0..4).filter(|l| got & lanes & (1 << l) != 0) {
                hits[l] = Hit { inst: id, ..h[l] };
            }
        } else {
            for l in (0..4).filter(|l| lanes & (1 << l) != 0) {
                let mut h = hits[l];
                if walk::<P, C, _, ANY>(&m.tree, m, &local[l], &mut h, c) {
                    hits[l] = Hit { inst: id, ..h };
                }
            }
        }
        c.enter(Level::Top);
    }
}

/// The two-level kd index of `world`'s geometry: a kd-tree per mesh (the world's meshes,
/// in its geometry order), its shapes as they are, the same instances; hits carry the
/// same instance and primitive ids as the world's own index.
///
/// # Errors
/// When a tree cannot be built.
pub fn kd_of_world(world: &World) -> Result<KdTwoLevel, BuildError> {
    kd_of_world_with(world, KdOptions::default())
}

/// [`kd_of_world`] with the trees built by `opts`.
///
/// # Errors
/// When a tree cannot be built.
pub fn kd_of_world_with(world: &World, opts: KdOptions) -> Result<KdTwoLevel, BuildError> {
    let meshes = &world.scene().meshes;
    let geoms = world
        .accel()
        .geometries()
        .iter()
        .enumerate()
        .map(|(i, g)| match g {
            Geometry::Mesh(_) => {
                let m = meshes.get(i).ok_or(BuildError::TooLarge(i))?;
                KdMesh::build(&m.positions, &m.indices, opts).map(KdGeometry::Mesh)
            }
            Geometry::Shape(s) => Ok(KdGeometry::Shape(*s)),
        })
        .collect::<Result<Vec<_>, _>>()?;
    KdTwoLevel::new(geoms, world.accel().instances().to_vec(), opts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_accel::TraversalStats;
    use rand::{Rng, SeedableRng};

    fn soup(n: usize, seed: u64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let mut p = Vec::new();
        let mut idx = Vec::new();
        for i in 0..n {
            let c = Vec3::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0));
            for _ in 0..3 {
                p.push(c + Vec3::new(rng.random_range(-0.6..0.6), rng.random_range(-0.6..0.6), rng.random_range(-0.6..0.6)));
            }
            let b = 3 * i as u32;
            idx.push([b, b + 1, b + 2]);
        }
        (p, idx)
    }

    fn random_ray(rng: &mut rand_pcg::Pcg64) -> Ray {
        let o = Vec3::new(rng.random_range(-8.0..8.0), rng.random_range(-8.0..8.0), rng.random_range(-8.0..8.0));
        let d = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        Ray::new(o, d)
    }

    /// The kd-tree's closest hits equal brute force over every triangle with the same
    /// test (t to the bit; the primitive wherever no other triangle ties).
    #[test]
    fn kd_mesh_matches_brute_force() {
        for seed in 0..4 {
            let (p, idx) = soup(300 + 200 * seed as usize, seed);
            let kd = KdMesh::build(&p, &idx, KdOptions::default()).expect("test value");
            kd.tree.validate(idx.len()).expect("test value");
            let mut rng = rand_pcg::Pcg64::seed_from_u64(100 + seed);
            for _ in 0..2000 {
                let r = random_ray(&mut rng);
                let mut best: Option<(f32, u32)> = None;
                for (i, tri) in kd.tris.iter().enumerate() {
                    if let Some((t, _, _)) = unit_triangle_hit(tri, r.org, r.dir, r.tmin, best.map_or(r.tmax, |b| b.0)) {
                        best = Some((t, i as u32));
                    }
                }
                let got = kd.intersect(&r).map(|h| (h.t, h.prim));
                assert_eq!(got.map(|g| g.0.to_bits()), best.map(|b| b.0.to_bits()), "seed {seed} ray {r:?}");
                // Occlusion within a range that ends before, at or after the hit.
                for tmax in [0.5, 3.0, 8.0, f32::INFINITY] {
                    let want = best.is_some_and(|b| b.0 < tmax);
                    assert_eq!(kd.occluded_with::<Exact, ()>(&Ray { tmax, ..r }, &mut ()), want, "seed {seed} tmax {tmax}");
                }
            }
        }
    }

    /// Packets of four give the single rays' answers, coherent or not.
    #[test]
    fn kd_packets_match_single_rays() {
        let (p, idx) = soup(800, 9);
        let g =
            vec![KdGeometry::Mesh(KdMesh::build(&p, &idx, KdOptions::default()).expect("test value")), KdGeometry::Shape(Shape::Sphere)];
        let insts = vec![
            Instance::new(0, Affine3A::IDENTITY),
            Instance::new(0, Affine3A::from_rotation_translation(glam::Quat::from_rotation_y(0.7), Vec3::new(3.0, 1.0, 0.0))),
            Instance::new(1, Affine3A::from_scale_rotation_translation(Vec3::splat(2.0), glam::Quat::IDENTITY, Vec3::new(0.0, 6.0, 0.0))),
        ];
        let tl = KdTwoLevel::new(g, insts, KdOptions::default()).expect("test value");
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut packets = 0;
        for _ in 0..1500 {
            let o = Vec3::new(rng.random_range(-9.0..9.0), rng.random_range(-9.0..9.0), 12.0);
            let base = Vec3::new(rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5), -1.0);
            let rays = std::array::from_fn(|l| Ray::new(o, base + Vec3::new(0.02 * l as f32, -0.01 * l as f32, 0.0)));
            packets += usize::from(coherent(&rays, 0xF));
            let got = tl.intersect4_with::<Exact, ()>(&rays, &mut ());
            for l in 0..4 {
                assert_eq!(got[l], tl.intersect(&rays[l]), "lane {l}");
            }
            // Occlusion, two-level and in the mesh alone, packets and single rays, with
            // ranges that end before and after the hits.
            for tmax in [6.0, 14.0, f32::INFINITY] {
                let short = rays.map(|r| Ray { tmax, ..r });
                let occ = tl.occluded4_with::<Exact, ()>(&short, &mut ());
                let KdGeometry::Mesh(m) = &tl.geometries[0] else { unreachable!("mesh first") };
                let mocc = m.occluded4_with::<Exact, ()>(&short, &mut ());
                let mhit = m.intersect4_with::<Exact, ()>(&short, &mut ());
                for l in 0..4 {
                    assert_eq!(occ[l], tl.intersect(&short[l]).is_some(), "lane {l} tmax {tmax}");
                    assert_eq!(occ[l], tl.occluded_with::<Exact, ()>(&short[l], &mut ()), "lane {l} tmax {tmax}");
                    assert_eq!(mocc[l], m.intersect(&short[l]).is_some(), "mesh lane {l} tmax {tmax}");
                    assert_eq!(mhit[l], m.intersect(&short[l]), "mesh lane {l} tmax {tmax}");
                }
            }
        }
        assert!(packets > 1000);
    }

    /// Hand-counted work: one triangle in a one-leaf tree is one node and one list entry;
    /// through an instance, one transformation; a ray that misses the box reads nothing.
    #[test]
    fn counters_of_a_tiny_scene() {
        #[derive(Default)]
        struct Count {
            stats: TraversalStats,
            reads: usize,
            lists: usize,
            tris: u32,
            transforms: usize,
        }
        impl Counters for Count {
            fn node(&mut self) {
                self.stats.node();
            }
            fn items(&mut self, n: u32) {
                self.stats.items(n);
            }
            fn node_read(&mut self, _: usize, b: usize) {
                assert_eq!(b, 8);
                self.reads += 1;
            }
            fn list_read(&mut self, _: usize, _: usize) {
                self.lists += 1;
            }
            fn triangles(&mut self, _: usize, _: usize, n: u32) {
                self.tris += n;
            }
            fn transform(&mut self, _: usize, _: usize) {
                self.transforms += 1;
            }
        }
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let m = KdMesh::build(&p, &[[0, 1, 2]], KdOptions::default()).expect("test value");
        let mut c = Count::default();
        let h = m.intersect_with::<Exact, _>(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z), &mut c).expect("test value");
        assert_eq!((h.t, c.stats.nodes, c.reads, c.lists, c.tris), (1.0, 1, 1, 1, 1));
        let tl = KdTwoLevel::new(
            vec![KdGeometry::Mesh(m)],
            vec![Instance::new(0, Affine3A::from_translation(Vec3::new(5.0, 0.0, 0.0)))],
            KdOptions::default(),
        )
        .expect("test value");
        let mut c = Count::default();
        let h = tl.intersect_with::<Exact, _>(&Ray::new(Vec3::new(5.2, 0.2, 1.0), -Vec3::Z), &mut c).expect("test value");
        // Top: one leaf node and one list entry; bottom: one leaf node, one entry, one triangle.
        assert_eq!((h.inst, c.stats.nodes, c.lists, c.tris, c.transforms), (0, 2, 2, 1, 1));
        let mut c = Count::default();
        assert!(tl.intersect_with::<Exact, _>(&Ray::new(Vec3::new(-5.0, 0.2, 1.0), -Vec3::Z), &mut c).is_none());
        assert_eq!((c.stats.nodes, c.lists, c.tris), (0, 0, 0));
        // A packet of four into the instance: each level's node and list entry read once
        // for the packet, four transformations (one per ray) and four triangle tests.
        let rays: [Ray; 4] = std::array::from_fn(|l| Ray::new(Vec3::new(5.1 + 0.05 * l as f32, 0.2, 1.0), -Vec3::Z));
        let mut c = Count::default();
        let h = tl.intersect4_with::<Exact, _>(&rays, &mut c);
        assert!(h.iter().all(Option::is_some));
        assert_eq!((c.stats.nodes, c.lists, c.tris, c.transforms), (2, 2, 4, 4));
    }

    /// A mailbox skips the second reference of an object that straddles a split.
    #[test]
    fn mailbox_skips_repeated_objects() {
        let mut m = Mailbox::new();
        assert!(!m.seen(3));
        assert!(m.seen(3));
        assert!(!m.seen(19)); // same slot: replaces 3
        assert!(!m.seen(3));
    }
}

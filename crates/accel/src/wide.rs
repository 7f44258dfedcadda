//! Wide BVH nodes (4 or 8 children in SoA form) and the collapse of the binary BVH into them.
//!
//! The collapse picks the binary nodes that become wide nodes by dynamic programming over
//! the binary tree, for the least SAH cost of the wide tree (Ylitie, Karras & Laine 2017;
//! see [`collapse`]).

use crate::build::{BinNode, BinaryBvh};
use crate::geom::Aabb;

/// Child code of an empty slot (its box is inverted, so it is never entered).
pub const EMPTY: u32 = u32::MAX;
/// Flag bit of a leaf child code.
pub const LEAF: u32 = 1 << 31;
/// Bits of the first item index in a leaf code.
pub const FIRST_BITS: u32 = 27;
/// Most items in one leaf.
pub const MAX_LEAF_ITEMS: u32 = 16;

/// Bytes per unit of an inner child code. An inner node's code is its byte offset in the
/// node array divided by this, so a kernel finds the node at `base + code * 8`, one x86
/// addressing mode. PERF: with the node index as the code, every visit shifted and added
/// (`base + (code << 8)`) on the walk's dependent path between loading a child code and
/// loading its node; the pre-scaled code made single rays 0.5-1% faster on all scenes.
pub const CODE_UNIT: usize = 8;

/// Encodes a leaf over `count` (1..=16) items starting at `first`.
#[inline]
#[must_use]
pub fn leaf_code(first: u32, count: u32) -> Option<u32> {
    (first < (1 << FIRST_BITS) && (1..=MAX_LEAF_ITEMS).contains(&count)).then(|| LEAF | ((count - 1) << FIRST_BITS) | first)
}

/// Decodes a leaf code into `(first, count)`.
#[inline(always)]
#[must_use]
pub fn leaf_range(code: u32) -> (u32, u32) {
    (code & ((1 << FIRST_BITS) - 1), ((code >> FIRST_BITS) & 0xF) + 1)
}

/// A node with `W` children. `bounds[0..3]` are the lower x, y, z of each child,
/// `bounds[3..6]` the upper ones; `child` holds inner node codes ([`WideNode::code_of`]),
/// leaf codes or [`EMPTY`].
///
/// PERF: 224 bytes of data for W = 8 (seven 32-byte rows: one AVX register per row), padded to
/// 256 by 64-byte alignment so a node covers exactly four cache lines (not five); 128 for W = 4.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct WideNode<const W: usize> {
    /// Child boxes, SoA.
    pub bounds: [[f32; W]; 6],
    /// Child codes.
    pub child: [u32; W],
}

const _: () = assert!(std::mem::size_of::<WideNode<8>>() == 256);
const _: () = assert!(std::mem::size_of::<WideNode<4>>() == 128);
// The packet walk keeps a slot (< 8) in the low bits of its parent's code.
const _: () = assert!(WideNode::<8>::STRIDE >= 8);

impl<const W: usize> WideNode<W> {
    /// A node with no children.
    pub const EMPTY: Self = Self {
        bounds: [
            [f32::INFINITY; W],
            [f32::INFINITY; W],
            [f32::INFINITY; W],
            [f32::NEG_INFINITY; W],
            [f32::NEG_INFINITY; W],
            [f32::NEG_INFINITY; W],
        ],
        child: [EMPTY; W],
    };

    /// Code units per node (32 for W = 8, 16 for W = 4): inner codes are multiples of it.
    pub const STRIDE: u32 = (std::mem::size_of::<Self>() / CODE_UNIT) as u32;
    /// The most nodes one tree can have: inner codes stay below the leaf bit.
    pub const MAX_NODES: usize = (LEAF / Self::STRIDE) as usize;

    /// The child code of the node at `index` (which must be below [`Self::MAX_NODES`]).
    #[inline(always)]
    #[must_use]
    pub const fn code_of(index: usize) -> u32 {
        debug_assert!(index < Self::MAX_NODES);
        index as u32 * Self::STRIDE
    }

    /// The node index of inner child code `code`.
    #[inline(always)]
    #[must_use]
    pub const fn index_of(code: u32) -> usize {
        (code / Self::STRIDE) as usize
    }

    /// Sets child slot `i`.
    pub fn set(&mut self, i: usize, b: &Aabb, code: u32) {
        for k in 0..3 {
            self.bounds[k][i] = b.min[k];
            self.bounds[k + 3][i] = b.max[k];
        }
        self.child[i] = code;
    }

    /// The box of child slot `i`.
    #[must_use]
    pub fn child_bounds(&self, i: usize) -> Aabb {
        Aabb {
            min: glam::Vec3::new(self.bounds[0][i], self.bounds[1][i], self.bounds[2][i]),
            max: glam::Vec3::new(self.bounds[3][i], self.bounds[4][i], self.bounds[5][i]),
        }
    }
}

/// The node at inner child `code` of `nodes`.
///
/// # Safety
/// `code` must be an inner child code of a node of `nodes` (made by [`WideNode::code_of`]
/// from an index in range, as the collapses do).
#[inline(always)]
#[must_use]
pub unsafe fn node_at<const W: usize>(nodes: &[WideNode<W>], code: u32) -> &WideNode<W> {
    // SAFETY: the caller guarantees that `code * CODE_UNIT` is the byte offset of a node of
    // `nodes` (a multiple of the node size below the slice's length in bytes).
    unsafe { &*nodes.as_ptr().cast::<u8>().add(code as usize * CODE_UNIT).cast::<WideNode<W>>() }
}

/// Collapses a binary BVH into `W`-wide nodes (root at index 0, code 0), choosing which
/// binary nodes become wide nodes so that the wide tree's SAH cost is least (see
/// `WideCosts`); a leaf costs its blocks of `leaf_block` items. `make_leaf(first, count)`
/// receives each binary leaf's primitive range and returns its leaf code; `too_many()` is
/// the error when the tree needs more than [`WideNode::MAX_NODES`] nodes.
pub fn collapse<const W: usize, E>(
    nodes: &[BinNode],
    leaf_block: u32,
    make_leaf: &mut impl FnMut(u32, u32) -> Result<u32, E>,
    too_many: impl Fn() -> E + Copy,
) -> Result<Vec<WideNode<W>>, E> {
    let mut out = Vec::with_capacity(nodes.len() / (W / 2).max(1) + 1);
    let Some(root) = nodes.first() else {
        out.push(WideNode::EMPTY);
        return Ok(out);
    };
    if root.is_leaf() {
        let mut n = WideNode::EMPTY;
        n.set(0, &root.bounds, make_leaf(root.first, root.count)?);
        out.push(n);
        return Ok(out);
    }
    let costs = WideCosts::new::<W>(nodes, leaf_block);
    emit(nodes, &costs, 0, &mut out, make_leaf, too_many)?;
    Ok(out)
}

/// The least SAH costs of every binary subtree as part of a `W`-wide tree, after Ylitie,
/// Karras & Laine, "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide
/// BVHs" (HPG 2017), §4.1: `best[n][k - 1]` is the least cost of covering subtree `n` with
/// at most `k` child slots of its wide parent. One slot holds `n` itself: a leaf (its area
/// times its blocks) or a wide node (its area, plus its own subtree covered with `W`
/// slots); with more slots, an inner `n` may instead be opened and its two children share
/// them. Costs are in Embree's convention (a wide node and a block of leaf items cost 1
/// each at their box's area). PERF: the greedy collapse (open the largest child until
/// there are `W`) left wide trees 3-9% costlier on the shared scenes, with a third more
/// nodes. On the default (optimized) trees these trace diffuse single rays 0-4% faster,
/// every other kind and API within -2% and +6%; on plain `Quality::Sah` trees the
/// kitchen's packets lose 5-8% (measured against the greedy collapse, 1 thread).
struct WideCosts {
    best: Vec<[f32; 8]>,
}

impl WideCosts {
    fn new<const W: usize>(nodes: &[BinNode], leaf_block: u32) -> Self {
        const { assert!(W >= 2 && W <= 8) };
        let mut best = vec![[0f32; 8]; nodes.len()];
        // Children before parents: a depth-first walk that finishes a node after both
        // children (the nodes need not be in any order: reinsertion reuses slots).
        let mut stack: Vec<(u32, bool)> = Vec::with_capacity(2 * crate::build::MAX_DEPTH as usize + 2);
        stack.push((0, false));
        while let Some((i, children_done)) = stack.pop() {
            let n = &nodes[i as usize];
            if n.is_leaf() {
                best[i as usize] = [n.bounds.half_area() * n.count.div_ceil(leaf_block.max(1)) as f32; 8];
                continue;
            }
            if !children_done {
                stack.push((i, true));
                stack.push((n.right, false));
                stack.push((n.first, false));
                continue;
            }
            let split = Self::split::<W>(&best[n.first as usize], &best[n.right as usize]);
            let me = n.bounds.half_area() + split[W - 1];
            let mut b = [me; 8];
            for k in 2..=W {
                b[k - 1] = me.min(split[k - 1]);
            }
            best[i as usize] = b;
        }
        Self { best }
    }

    /// `out[k - 1]` (`k` ≥ 2): the least cost of covering two sibling subtrees with at most
    /// `k` slots between them.
    #[inline]
    fn split<const W: usize>(l: &[f32; 8], r: &[f32; 8]) -> [f32; 8] {
        let mut out = [f32::INFINITY; 8];
        for k in 2..=W {
            let mut m = f32::INFINITY;
            for j in 1..k {
                m = m.min(l[j - 1] + r[k - j - 1]);
            }
            out[k - 1] = m;
        }
        out
    }

    /// Appends to `kids` the at most `k` descendants of inner node `i` that take its slots
    /// in the least-cost cover (the choices `new` made, found again).
    fn frontier(&self, nodes: &[BinNode], i: u32, k: usize, kids: &mut [usize; 8], nk: &mut usize) {
        let n = &nodes[i as usize];
        let (l, r) = (&self.best[n.first as usize], &self.best[n.right as usize]);
        let mut j = 1;
        for jj in 2..k {
            if l[jj - 1] + r[k - jj - 1] < l[j - 1] + r[k - j - 1] {
                j = jj;
            }
        }
        for (c, m) in [(n.first, j), (n.right, k - j)] {
            let b = &self.best[c as usize];
            // Opened only when that is strictly cheaper than the child as one slot.
            if nodes[c as usize].is_leaf() || m < 2 || b[m - 1] >= b[0] {
                kids[*nk] = c as usize;
                *nk += 1;
            } else {
                self.frontier(nodes, c, m, kids, nk);
            }
        }
    }
}

fn emit<const W: usize, E>(
    nodes: &[BinNode],
    costs: &WideCosts,
    idx: usize,
    out: &mut Vec<WideNode<W>>,
    make_leaf: &mut impl FnMut(u32, u32) -> Result<u32, E>,
    too_many: impl Fn() -> E + Copy,
) -> Result<u32, E> {
    let slot = out.len();
    if slot >= WideNode::<W>::MAX_NODES {
        return Err(too_many());
    }
    out.push(WideNode::EMPTY);
    let mut kids = [0usize; 8];
    let mut nk = 0;
    costs.frontier(nodes, idx as u32, W, &mut kids, &mut nk);
    // In the binary tree's node order (depth first), so the wide tree meets its leaves in
    // the order their triangle groups are laid out (`MeshBvh::build` numbers them before
    // the collapse). PERF: single rays 3-5% faster on four of the five benchmark scenes
    // than with the children in the order the earlier greedy collapse opened them;
    // packets unchanged.
    kids[..nk].sort_unstable();
    for (i, &k) in kids[..nk].iter().enumerate() {
        let c = nodes[k];
        let code = if c.is_leaf() { make_leaf(c.first, c.count)? } else { emit(nodes, costs, k, out, make_leaf, too_many)? };
        // Set in place: a node built on the stack and stored at the end was a 256-byte
        // copy per node (a `memmove` call in the profile; builds within 1% either way).
        out[slot].set(i, &c.bounds, code);
    }
    Ok(WideNode::<W>::code_of(slot))
}

/// Collapses a binary BVH whose leaves hold at most `W` items each into `W`-wide nodes
/// where every item has a child slot of its own (a leaf of one item, `leaf_code(i, 1)`):
/// for top levels, whose items are instances, each with its own box test. Inner nodes
/// and multi-item leaves are opened largest surface area first while they fit; a leaf
/// that does not fit becomes a wide node of its items. `out` is cleared first and keeps its
/// memory. The error is the item count of a leaf with more than `W` items, or the node
/// count when the tree needs more than [`WideNode::MAX_NODES`] nodes.
pub fn collapse_spread<const W: usize>(bin: &BinaryBvh, out: &mut Vec<WideNode<W>>) -> Result<(), u32> {
    out.clear();
    let Some(root) = bin.nodes.first() else {
        out.push(WideNode::EMPTY);
        return Ok(());
    };
    if root.count as usize > W {
        return Err(root.count);
    }
    spread(bin, 0, out)?;
    Ok(())
}

fn spread<const W: usize>(bin: &BinaryBvh, idx: usize, out: &mut Vec<WideNode<W>>) -> Result<u32, u32> {
    /// A child slot: a binary node (inner, or a leaf not yet spread) or one item.
    #[derive(Clone, Copy)]
    enum Kid {
        Node(u32),
        Item(u32),
    }
    let slot = out.len();
    if slot >= WideNode::<W>::MAX_NODES {
        return Err(u32::try_from(slot).unwrap_or(u32::MAX));
    }
    out.push(WideNode::EMPTY);
    let mut kids = [Kid::Item(0); W];
    // Surface areas of openable kids, and the slots opening them adds (0: not openable).
    let mut area = [0.0f32; W];
    let mut adds = [0usize; W];
    let classify = |k: u32| -> (Kid, f32, usize) {
        let c = &bin.nodes[k as usize];
        match c.count {
            0 => (Kid::Node(k), c.bounds.half_area(), 1),
            1 => (Kid::Item(c.first), 0.0, 0),
            n => (Kid::Node(k), c.bounds.half_area(), n as usize - 1),
        }
    };
    let n = bin.nodes[idx];
    let mut nk;
    if n.is_leaf() {
        // A leaf that did not fit in its parent: its items, one slot each.
        nk = (n.count as usize).min(W);
        for (i, kid) in kids[..nk].iter_mut().enumerate() {
            *kid = Kid::Item(n.first + i as u32);
        }
    } else {
        nk = 0;
        for c in [n.first, n.right] {
            let (k, a, d) = classify(c);
            kids[nk] = k;
            area[nk] = a;
            adds[nk] = d;
            nk += 1;
        }
        loop {
            let mut best = usize::MAX;
            for i in 0..nk {
                if adds[i] > 0 && nk + adds[i] <= W && (best == usize::MAX || area[i] > area[best]) {
                    best = i;
                }
            }
            if best == usize::MAX {
                break;
            }
            let Kid::Node(k) = kids[best] else { break };
            let c = bin.nodes[k as usize];
            if c.is_leaf() {
                kids[best] = Kid::Item(c.first);
                adds[best] = 0;
                for j in 1..c.count {
                    kids[nk] = Kid::Item(c.first + j);
                    adds[nk] = 0;
                    nk += 1;
                }
            } else {
                for (s, ch) in [(best, c.first), (nk, c.right)] {
                    let (kk, a, d) = classify(ch);
                    kids[s] = kk;
                    area[s] = a;
                    adds[s] = d;
                }
                nk += 1;
            }
        }
    }
    let mut node = WideNode::EMPTY;
    for (i, kid) in kids[..nk].iter().enumerate() {
        match *kid {
            Kid::Item(p) => {
                let r = &bin.prims[p as usize];
                let code = leaf_code(p, 1).ok_or(p)?;
                node.set(i, &Aabb { min: r.min(), max: r.max() }, code);
            }
            Kid::Node(k) => {
                let c = &bin.nodes[k as usize];
                if c.count as usize > W {
                    return Err(c.count);
                }
                let code = spread(bin, k as usize, out)?;
                node.set(i, &c.bounds, code);
            }
        }
    }
    out[slot] = node;
    Ok(WideNode::<W>::code_of(slot))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::{build_binary, BuildConfig, PrimRef};
    use glam::Vec3;

    /// Every inner code of both collapses is a multiple of the stride whose node, found by
    /// address (`node_at`), is the node at its index, and none points at the root (index
    /// 0). Returns how many inner codes were checked.
    fn check_codes<const W: usize>(nodes: &[WideNode<W>]) -> usize {
        let mut inner = 0;
        for n in nodes {
            for &c in &n.child {
                if c == EMPTY || c & LEAF != 0 {
                    continue;
                }
                assert_eq!(c % WideNode::<W>::STRIDE, 0, "code {c}");
                let i = WideNode::<W>::index_of(c);
                assert!(i > 0 && i < nodes.len(), "code {c} -> index {i} of {}", nodes.len());
                assert_eq!(WideNode::<W>::code_of(i), c);
                // SAFETY: `c` was just checked to be the code of a node of `nodes`.
                let by_address = unsafe { node_at(nodes, c) };
                assert!(std::ptr::eq(by_address, &nodes[i]));
                inner += 1;
            }
        }
        inner
    }

    #[test]
    fn inner_codes_address_their_nodes() {
        assert_eq!(WideNode::<8>::STRIDE, 32);
        assert_eq!(WideNode::<4>::STRIDE, 16);
        assert!(WideNode::<8>::code_of(WideNode::<8>::MAX_NODES - 1) < LEAF);
        assert!(WideNode::<4>::code_of(WideNode::<4>::MAX_NODES - 1) < LEAF);
        // A 20×20×20 grid of small boxes: several levels of inner nodes in both widths.
        let prims: Vec<PrimRef> = (0..8000u32)
            .map(|i| {
                let p = Vec3::new((i % 20) as f32, (i / 20 % 20) as f32, (i / 400) as f32);
                PrimRef::new(Aabb { min: p, max: p + 0.5 }, i)
            })
            .collect();
        let bin = build_binary(prims.clone(), &BuildConfig::default());
        let leaf = &mut |first: u32, count: u32| leaf_code(first, count).ok_or(());
        let w8 = collapse::<8, _>(&bin.nodes, 4, leaf, || ()).expect("collapse");
        let w4 = collapse::<4, _>(&bin.nodes, 4, leaf, || ()).expect("collapse");
        assert!(check_codes(&w8) > 100 && check_codes(&w4) > 100);
        let one = build_binary(prims, &BuildConfig { max_leaf: 1, leaf_block: 1, ..BuildConfig::default() });
        let mut spread8 = Vec::new();
        collapse_spread::<8>(&one, &mut spread8).expect("spread");
        assert!(check_codes(&spread8) > 100);
    }

    /// The least cost over every way of cutting subtree `i` into at most `W` slots, by
    /// enumeration (exponential: small trees only). `leaf(i)` is a leaf's cost.
    fn brute_cost<const W: usize>(nodes: &[BinNode], i: usize, leaf: &dyn Fn(usize) -> f64) -> f64 {
        fn cuts(nodes: &[BinNode], i: usize, max: usize) -> Vec<Vec<usize>> {
            let mut all = vec![vec![i]];
            let n = &nodes[i];
            if !n.is_leaf() && max >= 2 {
                for a in cuts(nodes, n.first as usize, max - 1) {
                    for b in cuts(nodes, n.right as usize, max - a.len()) {
                        all.push([a.clone(), b].concat());
                    }
                }
            }
            all
        }
        let n = &nodes[i];
        let mut best = f64::INFINITY;
        for cut in cuts(nodes, n.first as usize, W - 1) {
            for rest in cuts(nodes, n.right as usize, W - cut.len()) {
                let c: f64 =
                    cut.iter().chain(&rest).map(|&k| if nodes[k].is_leaf() { leaf(k) } else { brute_cost::<W>(nodes, k, leaf) }).sum();
                best = best.min(c);
            }
        }
        f64::from(n.bounds.half_area()) + best
    }

    /// The SAH cost of a collapsed tree in the same convention (root box included).
    fn wide_cost<const W: usize>(out: &[WideNode<W>], root: &Aabb, leaf_block: u32) -> f64 {
        let mut c = f64::from(root.half_area());
        for n in out {
            for k in 0..W {
                let code = n.child[k];
                if code == EMPTY {
                    continue;
                }
                let a = f64::from(n.child_bounds(k).half_area());
                c += if code & LEAF != 0 { a * f64::from(leaf_range(code).1.div_ceil(leaf_block)) } else { a };
            }
        }
        c
    }

    /// The collapse finds the least-cost wide tree: random small trees, every cut tried.
    #[test]
    fn collapse_is_optimal_on_small_trees() {
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut opened = 0;
        for trial in 0..60 {
            let n = 6 + trial % 14;
            let prims: Vec<PrimRef> = (0..n as u32)
                .map(|i| {
                    let p = Vec3::new(rnd(), rnd(), rnd()) * 10.0;
                    let s = Vec3::new(rnd(), rnd(), rnd()) * (0.1 + 3.0 * rnd());
                    PrimRef::new(Aabb { min: p, max: p + s }, i)
                })
                .collect();
            let cfg = BuildConfig { max_leaf: 2, leaf_block: 1, cost_traverse: 0.2, ..BuildConfig::default() };
            let bin = build_binary(prims, &cfg);
            if bin.nodes[0].is_leaf() {
                continue;
            }
            for block in [1u32, 4] {
                let leaf = |k: usize| f64::from(bin.nodes[k].bounds.half_area()) * f64::from(bin.nodes[k].count.div_ceil(block));
                let code = &mut |first: u32, count: u32| leaf_code(first, count).ok_or(());
                let w4 = collapse::<4, _>(&bin.nodes, block, code, || ()).expect("collapse");
                let w8 = collapse::<8, _>(&bin.nodes, block, code, || ()).expect("collapse");
                let root = bin.nodes[0].bounds;
                for (got, want) in [
                    (wide_cost(&w4, &root, block), brute_cost::<4>(&bin.nodes, 0, &leaf)),
                    (wide_cost(&w8, &root, block), brute_cost::<8>(&bin.nodes, 0, &leaf)),
                ] {
                    assert!((got - want).abs() <= 1e-4 * want, "trial {trial}, block {block}: collapse {got}, best {want}");
                }
                opened += usize::from(w4.len() > 1) + usize::from(w8.len() > 1);
            }
        }
        assert!(opened > 50, "too few trees with several wide nodes: {opened}");
    }
}

//! Insertion-based optimization of a binary BVH.
//!
//! Bittner, Hapala & Havran, "Fast Insertion-Based Optimization of Bounding Volume
//! Hierarchies" (Computer Graphics Forum 2013): the subtrees whose boxes are most wasteful
//! are taken out of the tree and put back where they add the least surface area, found by
//! a branch-and-bound search from the root over the *induced cost* (the growth of every box
//! on the way down). Leaves move as whole subtrees, so the primitive order and every leaf's
//! range stay as the builder made them; only inner nodes change.
//!
//! The passes run in parallel after Meister & Bittner, "Parallel Reinsertion for Bounding
//! Volume Hierarchy Optimization" (Eurographics 2018): each pass searches the best place of
//! every candidate at once, on the tree as it is at the start of the pass (with the
//! candidate taken out: the boxes of its ancestors shrink, and the search uses the shrunk
//! boxes). The moves are then applied one by one, largest gain first, on the tree as the
//! earlier moves left it: a move that is no longer possible is skipped, and one that no
//! longer lowers the summed area is undone. (The paper locks the nodes a move rewires
//! instead; here that left four of five improving moves unapplied, as the most wasteful
//! nodes are near each other.) The result does not depend on the number of threads.
//!
//! Each pass takes 2% of the nodes, those with the largest `A(N) · A(N)/ΣA(children) ·
//! A(N)/min A(child)` (the 2013 paper's combined inefficiency measure); when a pass lowers
//! the SAH cost by less than 1%, the next one takes the following 2%. At most
//! [`MAX_PASSES`] passes.

use crate::build::{BinNode, BinaryBvh, BuildConfig, MAX_DEPTH};
use crate::geom::Aabb;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Most optimization passes. PERF: 8 gave the same single-ray speeds on the shared scenes
/// for 5-7% longer builds; 5 lost up to 1.6% (Sponza's diffuse rays).
pub const MAX_PASSES: usize = 6;
/// Share of the nodes reinserted per pass.
const BATCH: f64 = 0.02;
const NONE: u32 = u32::MAX;
/// Nodes per parallel task of the scoring.
const SCORE_CHUNK: usize = 4096;
/// Fewer candidates than this are searched on one thread (waking the pool costs more).
const PARALLEL_SEARCH_MIN: usize = 256;

fn area(b: &Aabb) -> f32 {
    let a = b.half_area();
    if a.is_finite() {
        a
    } else {
        0.0
    }
}

struct Tree<'a> {
    nodes: &'a mut [BinNode],
    parent: Vec<u32>,
    /// `area(nodes[i].bounds)`, kept up to date (0 for the slot a removal frees).
    areas: Vec<f32>,
    /// The change of the inner nodes' summed area since it was last reset.
    delta: f64,
}

/// A proposed move: `n` next to `x`, lowering the sum of the inner nodes' areas by `gain`.
#[derive(Clone, Copy)]
struct Move {
    gain: f32,
    n: u32,
    x: u32,
}

/// Buffers of one search, kept across searches.
#[derive(Default)]
struct Scratch {
    /// The candidate's ancestors (root first), their boxes without it, and those boxes' areas.
    path: Vec<(u32, Aabb, f32)>,
    heap: BinaryHeap<Item>,
}

/// A search front entry: induced cost, node, and the node's index in the candidate's
/// ancestor path (or `NONE` off the path). Smallest cost first.
#[derive(PartialEq)]
struct Item(f32, u32, u32);
impl Eq for Item {}
impl PartialOrd for Item {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Item {
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0)
    }
}

impl Tree<'_> {
    fn children(&self, i: u32) -> [u32; 2] {
        let n = &self.nodes[i as usize];
        [n.first, n.right]
    }

    fn set_bounds(&mut self, i: u32, b: Aabb) {
        self.nodes[i as usize].bounds = b;
        let a = area(&b);
        self.delta += f64::from(a) - f64::from(self.areas[i as usize]);
        self.areas[i as usize] = a;
    }

    /// Recomputes the boxes from `i` up to the root.
    fn refit_up(&mut self, mut i: u32) {
        while i != NONE {
            let [a, b] = self.children(i);
            self.set_bounds(i, self.nodes[a as usize].bounds.union(self.nodes[b as usize].bounds));
            i = self.parent[i as usize];
        }
    }

    fn replace_child(&mut self, p: u32, old: u32, new: u32) {
        let n = &mut self.nodes[p as usize];
        if n.first == old {
            n.first = new;
        } else {
            n.right = new;
        }
    }

    fn sibling(&self, n: u32) -> u32 {
        let [a, b] = self.children(self.parent[n as usize]);
        if a == n {
            b
        } else {
            a
        }
    }

    /// Takes `n` (not the root) out; returns the slot it frees: `n`'s parent, or, when
    /// that parent is the root (which stays at index 0), the sibling, whose contents move
    /// into the root.
    ///
    /// The second case is reached by undoing a move that put `n` beside the root: before
    /// it was handled, such an undo read the root's parent (`NONE`) and panicked
    /// (`../shared/scenes/regressions/reinsert_root.obj`).
    fn remove(&mut self, n: u32) -> u32 {
        let p = self.parent[n as usize];
        debug_assert!(p != NONE, "remove: {n} is the root");
        if p == 0 {
            let s = self.sibling(n);
            let node = self.nodes[s as usize];
            self.nodes[0] = node;
            if !node.is_leaf() {
                for c in self.children(0) {
                    self.parent[c as usize] = 0;
                }
            }
            self.set_bounds(0, node.bounds);
            self.delta -= f64::from(self.areas[s as usize]);
            self.areas[s as usize] = 0.0;
            self.parent[s as usize] = NONE;
            return s;
        }
        let g = self.parent[p as usize];
        let s = self.sibling(n);
        self.replace_child(g, p, s);
        self.parent[s as usize] = g;
        self.delta -= f64::from(self.areas[p as usize]);
        self.areas[p as usize] = 0.0;
        self.refit_up(g);
        p
    }

    /// Puts `n` next to `x`, using the free slot `slot` for the new inner node.
    fn insert(&mut self, n: u32, x: u32, slot: u32) {
        if x == 0 {
            // The root stays at index 0: its contents move to `slot`.
            let root = self.nodes[0];
            self.nodes[slot as usize] = root;
            self.set_bounds(slot, root.bounds);
            for c in self.children(slot) {
                self.parent[c as usize] = slot;
            }
            self.parent[slot as usize] = 0;
            let b = root.bounds.union(self.nodes[n as usize].bounds);
            self.nodes[0] = BinNode { bounds: b, first: slot, right: n, count: 0 };
            self.set_bounds(0, b);
            self.parent[n as usize] = 0;
            self.parent[0] = NONE;
            return;
        }
        let q = self.parent[x as usize];
        self.replace_child(q, x, slot);
        let b = self.nodes[x as usize].bounds.union(self.nodes[n as usize].bounds);
        self.nodes[slot as usize] = BinNode { bounds: b, first: x, right: n, count: 0 };
        self.set_bounds(slot, b);
        self.parent[slot as usize] = q;
        self.parent[x as usize] = slot;
        self.parent[n as usize] = slot;
        self.refit_up(q);
    }

    /// The best place for `n` in the tree as it would be with `n` taken out (branch and
    /// bound over induced cost), found without changing the tree, so many searches can run
    /// at once. `None` when no place is better than where `n` is.
    fn propose(&self, n: u32, scratch: &mut Scratch) -> Option<Move> {
        let Scratch { path, heap } = scratch;
        path.clear();
        heap.clear();
        let p = self.parent[n as usize];
        let s = self.sibling(n);
        // The ancestors of `p` with their boxes once `n` is gone, and what taking `n` out
        // saves: `p`'s area and the shrinking of every ancestor.
        let mut below = self.nodes[s as usize].bounds;
        let (mut child, mut g) = (p, self.parent[p as usize]);
        let mut saving = self.areas[p as usize];
        while g != NONE {
            let [a, b] = self.children(g);
            let other = if a == child { b } else { a };
            below = below.union(self.nodes[other as usize].bounds);
            let shrunk = area(&below);
            saving += self.areas[g as usize] - shrunk;
            path.push((g, below, shrunk));
            (child, g) = (g, self.parent[g as usize]);
        }
        path.reverse(); // root first
        let nb = self.nodes[n as usize].bounds;
        let an = area(&nb);
        // Putting `n` back where it was costs `saving`: only better places are searched.
        let mut best = (saving, NONE);
        heap.push(Item(0.0, 0, 0));
        while let Some(Item(ci, x, k)) = heap.pop() {
            if ci + an >= best.0 {
                break;
            }
            // Off the path (`k` is `NONE`) the stored box.
            let (xb, xa) = match path.get(k as usize) {
                Some(&(_, b, a)) => (b, a),
                None => (self.nodes[x as usize].bounds, self.areas[x as usize]),
            };
            let total = ci + area(&xb.union(nb));
            if total < best.0 {
                best = (total, x);
            }
            let child_ci = total - xa;
            if child_ci + an < best.0 && !self.nodes[x as usize].is_leaf() {
                for c in self.children(x) {
                    let item = if k == NONE {
                        Item(child_ci, c, NONE)
                    } else if c == p {
                        Item(child_ci, s, NONE) // `p` goes; `s` takes its place
                    } else if path.get(k as usize + 1).is_some_and(|&(q, ..)| q == c) {
                        Item(child_ci, c, k + 1)
                    } else {
                        Item(child_ci, c, NONE)
                    };
                    heap.push(item);
                }
            }
        }
        (best.1 != NONE && best.1 != s).then_some(Move { gain: saving - best.0, n, x: best.1 })
    }

    fn depth(&self) -> u32 {
        let mut max = 0;
        let mut stack = vec![(0u32, 0u32)];
        while let Some((i, d)) = stack.pop() {
            max = max.max(d);
            if !self.nodes[i as usize].is_leaf() {
                for c in self.children(i) {
                    stack.push((c, d + 1));
                }
            }
        }
        max
    }
}

/// Optimizes `bvh` in place; returns the SAH cost before and after. A result deeper than
/// the traversal stack allows is dropped (the tree is left as built).
pub fn optimize(bvh: &mut BinaryBvh, cfg: &BuildConfig) -> (f32, f32) {
    optimize_nodes(&mut bvh.nodes, cfg)
}

/// [`optimize`] on the nodes of a binary BVH (root first); the primitives are not needed.
pub fn optimize_nodes(nodes: &mut [BinNode], cfg: &BuildConfig) -> (f32, f32) {
    if nodes.len() < 7 {
        let c = BinaryBvh::cost_of(nodes, cfg);
        return (c, c);
    }
    let original = nodes.to_vec();
    let len = nodes.len();
    let mut parent = vec![NONE; len];
    for (i, n) in nodes.iter().enumerate() {
        if !n.is_leaf() {
            parent[n.first as usize] = i as u32;
            parent[n.right as usize] = i as u32;
        }
    }
    let areas = nodes.iter().map(|n| area(&n.bounds)).collect();
    let mut t = Tree { nodes, parent, areas, delta: 0.0 };
    // Moves keep the set of leaves, so the root's box stays as it is.
    let root_area = t.areas[0].max(f32::MIN_POSITIVE) as f64;
    let (block, traverse) = (cfg.leaf_block.max(1) as u32, cfg.cost_traverse as f64);
    let (mut before, mut cost) = (0.0f32, 0.0f32);
    let mut window = 0usize;
    let mut score = vec![0.0f32; len];
    let mut cand: Vec<(f32, u32)> = Vec::with_capacity(len);
    let mut moves: Vec<Option<Move>> = Vec::new();
    let mut list: Vec<Move> = Vec::new();
    let mut scratch = Scratch::default();
    for pass in 1..=MAX_PASSES as u32 + 1 {
        // Score every node (-inf for those that may not move: the root and its children)
        // and sum the tree's SAH cost on the way (`BinaryBvh::cost_of`'s sum, which a test
        // checks against; a separate walk per pass was an eighth of the optimization);
        // chunks in parallel, their sums in order.
        let now = {
            let (nodes, parent, areas) = (&*t.nodes, &t.parent, &t.areas);
            let sums: Vec<f64> = score
                .par_chunks_mut(SCORE_CHUNK)
                .enumerate()
                .map(|(c, out)| {
                    let mut sum = 0.0f64;
                    for (i, o) in (c * SCORE_CHUNK..).zip(out.iter_mut()) {
                        let n = &nodes[i];
                        let a = areas[i];
                        let (m, weight) = if n.is_leaf() {
                            (a, n.count.div_ceil(block) as f64)
                        } else {
                            let (l, r) = (areas[n.first as usize], areas[n.right as usize]);
                            let (s, min) = ((l + r).max(f32::MIN_POSITIVE), l.min(r).max(f32::MIN_POSITIVE));
                            (a * (a / s) * (a / min), traverse)
                        };
                        sum += a as f64 * weight;
                        *o = if parent[i] == 0 || parent[i] == NONE { f32::NEG_INFINITY } else { m };
                    }
                    sum
                })
                .collect();
            (sums.iter().sum::<f64>() / root_area) as f32
        };
        if pass == 1 {
            before = now;
        } else if (cost - now) < 0.01 * cost {
            window += 1;
        }
        cost = now;
        if pass as usize > MAX_PASSES {
            break;
        }
        // This pass's candidates: the window of the most wasteful nodes, ties by index.
        cand.clear();
        cand.extend(score.iter().zip(0u32..).filter(|(&m, _)| m > f32::NEG_INFINITY).map(|(&m, i)| (m, i)));
        let k = (cand.len() as f64 * BATCH).ceil() as usize;
        let (lo, hi) = ((window * k).min(cand.len()), ((window + 1) * k).min(cand.len()));
        if lo >= hi {
            break;
        }
        let order = |a: &(f32, u32), b: &(f32, u32)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
        if hi < cand.len() {
            cand.select_nth_unstable_by(hi, order);
        }
        let head = &mut cand[..hi];
        if lo > 0 {
            head.select_nth_unstable_by(lo, order);
        }
        let head = &head[lo..];
        let tree = &t;
        if head.len() >= PARALLEL_SEARCH_MIN {
            head.par_iter().with_min_len(16).map_init(Scratch::default, |sc, &(_, n)| tree.propose(n, sc)).collect_into_vec(&mut moves);
        } else {
            moves.clear();
            moves.extend(head.iter().map(|&(_, n)| tree.propose(n, &mut scratch)));
        }
        list.clear();
        list.extend(moves.iter().flatten());
        list.sort_unstable_by(|a, b| b.gain.total_cmp(&a.gain).then(a.n.cmp(&b.n)));
        for &Move { n, x, .. } in &list {
            // Earlier moves of the pass may have changed the tree: the move must still be
            // possible (`n` not a child of the root, `x` neither `n`'s parent nor its
            // sibling nor below `n`), and it is undone unless it still lowers the summed area.
            let (p, s) = (t.parent[n as usize], t.sibling(n));
            if p == 0 || x == p || x == s {
                continue;
            }
            let mut up = x;
            while up != NONE && up != n {
                up = t.parent[up as usize];
            }
            if up == n {
                continue;
            }
            t.delta = 0.0;
            let slot = t.remove(n);
            t.insert(n, x, slot);
            if t.delta >= 0.0 {
                let slot = t.remove(n);
                t.insert(n, s, slot);
            }
        }
    }
    if t.depth() > MAX_DEPTH {
        t.nodes.copy_from_slice(&original);
        return (before, before);
    }
    (before, cost)
}

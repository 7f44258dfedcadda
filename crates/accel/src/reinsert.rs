//! Insertion-based optimization of a binary BVH (`--quality high`).
//!
//! Bittner, Hapala & Havran, "Fast Insertion-Based Optimization of Bounding Volume
//! Hierarchies" (Computer Graphics Forum 2013): the subtrees whose boxes are most wasteful
//! are taken out of the tree one at a time and put back where they add the least surface
//! area, found by a branch-and-bound search from the root over the *induced cost* (the
//! growth of every box on the way down). Leaves move as whole subtrees, so the primitive
//! order and every leaf's range stay as the builder made them; only inner nodes change.
//!
//! Each pass reinserts 2% of the nodes, those with the largest `A(N) · A(N)/ΣA(children) ·
//! A(N)/min A(child)` (the paper's combined inefficiency measure); when a pass lowers the SAH
//! cost by less than 1%, the next one takes the following 2%. At most [`MAX_PASSES`] passes.

use crate::build::{BinNode, BinaryBvh, BuildConfig, MAX_DEPTH};
use crate::geom::Aabb;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Most optimization passes.
pub const MAX_PASSES: usize = 8;
/// Share of the nodes reinserted per pass.
const BATCH: f64 = 0.02;
const NONE: u32 = u32::MAX;

struct Tree<'a> {
    nodes: &'a mut [BinNode],
    parent: Vec<u32>,
}

fn area(b: &Aabb) -> f32 {
    let a = b.half_area();
    if a.is_finite() {
        a
    } else {
        0.0
    }
}

impl Tree<'_> {
    fn children(&self, i: u32) -> [u32; 2] {
        let n = &self.nodes[i as usize];
        [n.first, n.right]
    }

    /// Recomputes the boxes from `i` up to the root.
    fn refit_up(&mut self, mut i: u32) {
        while i != NONE {
            let [a, b] = self.children(i);
            self.nodes[i as usize].bounds = self.nodes[a as usize].bounds.union(self.nodes[b as usize].bounds);
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

    /// Takes `n` out (its parent must not be the root); returns the freed parent slot.
    fn remove(&mut self, n: u32) -> u32 {
        let p = self.parent[n as usize];
        let g = self.parent[p as usize];
        let [a, b] = self.children(p);
        let s = if a == n { b } else { a };
        self.replace_child(g, p, s);
        self.parent[s as usize] = g;
        self.refit_up(g);
        p
    }

    /// The node under which `n` adds the least area (branch and bound over induced cost).
    fn best_place(&self, n: u32) -> u32 {
        #[derive(PartialEq)]
        struct Item(f32, u32);
        impl Eq for Item {}
        impl PartialOrd for Item {
            fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
                Some(self.cmp(o))
            }
        }
        impl Ord for Item {
            // Smallest induced cost first.
            fn cmp(&self, o: &Self) -> Ordering {
                o.0.total_cmp(&self.0)
            }
        }
        let nb = self.nodes[n as usize].bounds;
        let an = area(&nb);
        let mut best = (f32::INFINITY, 0u32);
        let mut heap = BinaryHeap::new();
        heap.push(Item(0.0, 0));
        while let Some(Item(ci, x)) = heap.pop() {
            if ci + an >= best.0 {
                break;
            }
            let xb = self.nodes[x as usize].bounds;
            let direct = area(&xb.union(nb));
            let total = ci + direct;
            if total < best.0 {
                best = (total, x);
            }
            let child_ci = total - area(&xb);
            if child_ci + an < best.0 && !self.nodes[x as usize].is_leaf() {
                for c in self.children(x) {
                    heap.push(Item(child_ci, c));
                }
            }
        }
        best.1
    }

    /// Puts `n` next to `x`, using the free slot `slot` for the new inner node.
    fn insert(&mut self, n: u32, x: u32, slot: u32) {
        if x == 0 {
            // The root stays at index 0: its contents move to `slot`.
            self.nodes[slot as usize] = self.nodes[0];
            if !self.nodes[slot as usize].is_leaf() {
                for c in self.children(slot) {
                    self.parent[c as usize] = slot;
                }
            }
            self.parent[slot as usize] = 0;
            self.nodes[0] =
                BinNode { bounds: self.nodes[slot as usize].bounds.union(self.nodes[n as usize].bounds), first: slot, right: n, count: 0 };
            self.parent[n as usize] = 0;
            self.parent[0] = NONE;
            return;
        }
        let q = self.parent[x as usize];
        self.replace_child(q, x, slot);
        self.nodes[slot as usize] =
            BinNode { bounds: self.nodes[x as usize].bounds.union(self.nodes[n as usize].bounds), first: x, right: n, count: 0 };
        self.parent[slot as usize] = q;
        self.parent[x as usize] = slot;
        self.parent[n as usize] = slot;
        self.refit_up(q);
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
    let before = bvh.sah_cost(cfg);
    if bvh.nodes.len() < 7 {
        return (before, before);
    }
    let original = bvh.nodes.clone();
    let mut parent = vec![NONE; bvh.nodes.len()];
    for (i, n) in bvh.nodes.iter().enumerate() {
        if !n.is_leaf() {
            parent[n.first as usize] = i as u32;
            parent[n.right as usize] = i as u32;
        }
    }
    let mut cost = before;
    {
        let mut t = Tree { nodes: &mut bvh.nodes, parent };
        // Each pass takes the next most wasteful nodes when the last one gained little.
        let mut window = 0usize;
        let mut cand: Vec<(f32, u32)> = Vec::with_capacity(t.nodes.len());
        for _ in 0..MAX_PASSES {
            // Candidates: nodes whose parent is not the root, most wasteful first.
            // PERF: scored in one sequential loop into a buffer kept across passes, and
            // only the pass's window is sorted (after a selection): sorting every node
            // each pass was a third of the optimization, and a parallel scoring's
            // unindexed collect cost more than the scoring.
            cand.clear();
            for i in 1..t.nodes.len() as u32 {
                let p = t.parent[i as usize];
                if p == 0 || p == NONE {
                    continue;
                }
                let n = &t.nodes[i as usize];
                let a = area(&n.bounds);
                let m = if n.is_leaf() {
                    a
                } else {
                    let [l, r] = [area(&t.nodes[n.first as usize].bounds), area(&t.nodes[n.right as usize].bounds)];
                    let (sum, min) = ((l + r).max(f32::MIN_POSITIVE), l.min(r).max(f32::MIN_POSITIVE));
                    a * (a / sum) * (a / min)
                };
                cand.push((m, i));
            }
            let k = (cand.len() as f64 * BATCH).ceil() as usize;
            let (lo, hi) = ((window * k).min(cand.len()), ((window + 1) * k).min(cand.len()));
            if lo >= hi {
                break;
            }
            // Most wasteful first; ties by node index.
            let order = |a: &(f32, u32), b: &(f32, u32)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
            if hi < cand.len() {
                cand.select_nth_unstable_by(hi, order);
            }
            let head = &mut cand[..hi];
            if lo > 0 {
                head.select_nth_unstable_by(lo, order);
            }
            head[lo..].sort_unstable_by(order);
            for &(_, n) in &head[lo..] {
                // An earlier move may have made this node a child of the root.
                let p = t.parent[n as usize];
                if p == 0 || p == NONE {
                    continue;
                }
                let slot = t.remove(n);
                let x = t.best_place(n);
                t.insert(n, x, slot);
            }
            let now = BinaryBvh::cost_of(t.nodes, cfg);
            let gain = (cost - now) / cost.max(f32::MIN_POSITIVE);
            cost = now;
            if gain < 0.01 {
                window += 1;
            }
        }
        if t.depth() > MAX_DEPTH {
            bvh.nodes = original;
            return (before, before);
        }
    }
    (before, cost)
}

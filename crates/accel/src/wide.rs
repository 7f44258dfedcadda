//! Wide BVH nodes (4 or 8 children in SoA form) and the collapse of the binary BVH into them.
//!
//! The collapse repeatedly opens the child with the largest surface area until a node has
//! `W` children (the approach of Wald et al., "Getting Rid of Packets", RT 2008, and of
//! Embree's BVH4/BVH8 builders).

use crate::build::BinaryBvh;
use crate::geom::Aabb;

/// Child code of an empty slot (its box is inverted, so it is never entered).
pub const EMPTY: u32 = u32::MAX;
/// Flag bit of a leaf child code.
pub const LEAF: u32 = 1 << 31;
/// Bits of the first item index in a leaf code.
pub const FIRST_BITS: u32 = 27;
/// Most items in one leaf.
pub const MAX_LEAF_ITEMS: u32 = 16;

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
/// `bounds[3..6]` the upper ones; `child` holds inner node indices, leaf codes or [`EMPTY`].
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

/// Collapses a binary BVH into `W`-wide nodes (root at index 0). `make_leaf(first, count)`
/// receives each binary leaf's primitive range and returns its leaf code.
pub fn collapse<const W: usize, E>(bin: &BinaryBvh, make_leaf: &mut impl FnMut(u32, u32) -> Result<u32, E>) -> Result<Vec<WideNode<W>>, E> {
    let mut out = Vec::with_capacity(bin.nodes.len() / (W / 2).max(1) + 1);
    let Some(root) = bin.nodes.first() else {
        out.push(WideNode::EMPTY);
        return Ok(out);
    };
    if root.is_leaf() {
        let mut n = WideNode::EMPTY;
        n.set(0, &root.bounds, make_leaf(root.first, root.count)?);
        out.push(n);
        return Ok(out);
    }
    emit(bin, 0, &mut out, make_leaf)?;
    Ok(out)
}

fn emit<const W: usize, E>(
    bin: &BinaryBvh,
    idx: usize,
    out: &mut Vec<WideNode<W>>,
    make_leaf: &mut impl FnMut(u32, u32) -> Result<u32, E>,
) -> Result<u32, E> {
    let slot = out.len();
    out.push(WideNode::EMPTY);
    let n = &bin.nodes[idx];
    let mut kids = [0usize; W];
    kids[0] = n.first as usize;
    kids[1] = n.right as usize;
    let mut nk = 2;
    while nk < W {
        // Open the inner child with the largest surface area.
        let mut best = None;
        let mut best_area = -1.0f32;
        for (i, &k) in kids[..nk].iter().enumerate() {
            let c = &bin.nodes[k];
            if !c.is_leaf() && c.bounds.half_area() > best_area {
                best_area = c.bounds.half_area();
                best = Some(i);
            }
        }
        let Some(i) = best else { break };
        let c = bin.nodes[kids[i]];
        kids[i] = c.first as usize;
        kids[nk] = c.right as usize;
        nk += 1;
    }
    let mut node = WideNode::EMPTY;
    for (i, &k) in kids[..nk].iter().enumerate() {
        let c = bin.nodes[k];
        let code = if c.is_leaf() { make_leaf(c.first, c.count)? } else { emit(bin, k, out, make_leaf)? };
        node.set(i, &c.bounds, code);
    }
    out[slot] = node;
    Ok(slot as u32)
}

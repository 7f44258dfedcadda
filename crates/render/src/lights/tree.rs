//! A light tree: many lights chosen by their estimated contribution at the shading point
//! in time logarithmic in their number. Conty Estevez and Kulla 2018, "Importance sampling
//! of many lights with adaptive tree splitting" (their light BVH, without the adaptive
//! splitting), in the form pbrt-v4's `BVHLightSampler` gives it: a tree over the lights
//! (built binary, then collapsed to eight children a node), each node bounding its
//! lights' places, the cone of their normals and the total of their intensities; a
//! choice walks down from the root, taking each child with probability proportional to
//! its importance at the point ([`super::reach`]'s weight, the same measure the
//! few-lights choice weighs every light object with), so the probability of a light is
//! the product of the choices on its way; each light's node and each node's parent are
//! kept, so the density of a light met by a BSDF ray is found by the same products.
//!
//! Unbiased wherever the weights are: a node's weight is zero only where none of its
//! lights sends anything (behind all of them, or outside every spot's cone), since its
//! bounds hold every light's.

#[cfg(test)]
use super::reach::Lane;
use super::reach::{pick, Lanes, Reach, WIDTH};
use glam::Vec3;
use std::f32::consts::PI;

/// What a light, or a node over lights, covers: the bounds of its places, the cone of
/// its normals (unit `axis`, half-angle `theta_o`; a zero axis or `theta_o` = π: every
/// direction), the angle `theta_e` past that cone at which emission stops (π/2 for a
/// one-sided surface, a spot's falloff, π: never), and its intensity (luminance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Extent {
    pub lo: Vec3,
    pub hi: Vec3,
    pub axis: Vec3,
    pub theta_o: f32,
    pub theta_e: f32,
    pub intensity: f32,
}

impl Extent {
    /// Its reach: the sphere about its bounds with its cone and intensity.
    pub(crate) fn reach(&self) -> Reach {
        Reach::local(0.5 * (self.lo + self.hi), 0.5 * (self.hi - self.lo).length(), self.axis, self.theta_o, self.theta_e, self.intensity)
    }

    fn centroid(&self) -> Vec3 {
        0.5 * (self.lo + self.hi)
    }

    /// The smallest extent holding both (the cones' union as pbrt-v4's
    /// `DirectionCone::Union`).
    fn union(&self, o: &Self) -> Self {
        let (axis, theta_o) = cone_union((self.axis, self.theta_o), (o.axis, o.theta_o));
        Self {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            axis,
            theta_o,
            theta_e: self.theta_e.max(o.theta_e),
            intensity: self.intensity + o.intensity,
        }
    }

    /// The surface area of its bounds.
    fn area(&self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    /// The solid-angle measure of its cone of emission (Conty Estevez and Kulla's M_Ω):
    /// how widely it sends light.
    fn spread(&self) -> f32 {
        let (o, w) = (self.theta_o, (self.theta_o + self.theta_e).min(PI));
        let (so, co) = o.sin_cos();
        2.0 * PI * (1.0 - co) + 0.5 * PI * (2.0 * w * so - (o - 2.0 * w).cos() - 2.0 * o * so + co)
    }
}

/// The smallest cone holding two cones (unit axis and half-angle; a zero axis: every
/// direction).
fn cone_union(a: (Vec3, f32), b: (Vec3, f32)) -> (Vec3, f32) {
    let all = (Vec3::ZERO, PI);
    if a.0 == Vec3::ZERO || b.0 == Vec3::ZERO || a.1 >= PI || b.1 >= PI {
        return all;
    }
    // `a` the wider.
    let (a, b) = if b.1 > a.1 { (b, a) } else { (a, b) };
    let theta_d = lucent_accel::math::acos(a.0.dot(b.0).clamp(-1.0, 1.0));
    if (theta_d + b.1).min(PI) <= a.1 {
        return a;
    }
    let theta_o = 0.5 * (a.1 + theta_d + b.1);
    if theta_o >= PI {
        return all;
    }
    // Turn a's axis toward b's by θo − θa.
    let toward = b.0 - a.0 * a.0.dot(b.0);
    let Some(perp) = toward.try_normalize() else { return all };
    let (s, c) = (theta_o - a.1).sin_cos();
    let axis = (a.0 * c + perp * s).normalize_or_zero();
    if axis == Vec3::ZERO {
        all
    } else {
        (axis, theta_o)
    }
}

/// No leaf (an inner node).
const INNER: u32 = u32::MAX;
/// Past this depth of the binary build, nodes are split at the median, which halves them
/// (so no way is longer than [`MAX_DEPTH`]).
const MEDIAN_DEPTH: u32 = 36;
const MAX_DEPTH: usize = 72;
/// Buckets per axis of the split search.
const BUCKETS: usize = 12;
/// Children of a node of the tree that is walked: one lane loop weighs them all
/// ([`super::reach::Lanes`] at eight lanes).
const WIDE: usize = 8;
/// A child that is a light (its index in the build's list, in the low bits).
const LIGHT: u32 = 1 << 31;
/// The largest number below 1.
const ONE_MINUS: f32 = 1.0 - f32::EPSILON / 2.0;

/// A node of the binary tree that is built (then collapsed into [`Node`]s).
#[derive(Clone, Debug)]
struct Binary {
    ext: Extent,
    reach: Reach,
    kids: [u32; 2],
    /// The light of a leaf, else [`INNER`].
    leaf: u32,
}

/// A node of the tree that is walked: up to [`WIDE`] children, weighed together.
#[derive(Clone, Debug)]
struct Node {
    lanes: Lanes,
    /// Each child: a node's index, or [`LIGHT`] | a light's.
    kids: [u32; WIDE],
    count: u32,
}

/// A light tree (see the module's documentation): built binary by the surface area
/// orientation heuristic, walked eight children at a time.
#[derive(Clone, Debug)]
pub(crate) struct LightTree {
    nodes: Vec<Node>,
    /// Per node: its parent and its place there (the root's parent is [`INNER`]).
    parent: Vec<(u32, u32)>,
    /// Per light: its node and its place there.
    home: Vec<(u32, u32)>,
    /// What all its lights cover.
    whole: Extent,
}

impl LightTree {
    /// A tree over `lights` (each one's extent, and the reach it is weighed by); `None`
    /// when there are none. Lights are named by their index in `lights`.
    pub(crate) fn new(lights: &[(Extent, Reach)]) -> Option<Self> {
        if lights.is_empty() || lights.len() >= LIGHT as usize {
            return None;
        }
        let mut binary = Vec::with_capacity(2 * lights.len());
        let mut ids: Vec<u32> = (0..lights.len() as u32).collect();
        build(lights, &mut ids, 0, &mut binary);
        let mut t = Self { nodes: Vec::new(), parent: Vec::new(), home: vec![(INNER, 0); lights.len()], whole: binary[0].ext };
        if binary[0].leaf != INNER {
            // One light: a root with one child.
            let mut kids = [0; WIDE];
            kids[0] = LIGHT | binary[0].leaf;
            t.nodes.push(Node { lanes: Lanes::new(&[binary[0].reach]), kids, count: 1 });
            t.parent.push((INNER, 0));
            t.home[binary[0].leaf as usize] = (0, 0);
        } else {
            t.collapse(&binary, 0, (INNER, 0));
        }
        Some(t)
    }

    /// Adds the node over binary node `b` (an inner one) and its subtree; its index.
    fn collapse(&mut self, binary: &[Binary], b: usize, parent: (u32, u32)) -> u32 {
        // Open the widest-reaching inner child until there are WIDE children.
        let mut kids: Vec<usize> = binary[b].kids.iter().map(|&k| k as usize).collect();
        while kids.len() < WIDE {
            let open = kids.iter().enumerate().filter(|(_, &k)| binary[k].leaf == INNER).max_by(|a, b2| {
                let cost = |k: usize| binary[k].ext.intensity * binary[k].ext.area();
                cost(*a.1).total_cmp(&cost(*b2.1))
            });
            let Some((at, &k)) = open else { break };
            kids.splice(at..=at, binary[k].kids.iter().map(|&c| c as usize));
        }
        let me = self.nodes.len() as u32;
        let reaches: Vec<Reach> = kids.iter().map(|&k| binary[k].reach).collect();
        self.nodes.push(Node { lanes: Lanes::new(&reaches), kids: [0; WIDE], count: kids.len() as u32 });
        self.parent.push(parent);
        for (slot, &k) in kids.iter().enumerate() {
            let child = if binary[k].leaf == INNER {
                self.collapse(binary, k, (me, slot as u32))
            } else {
                self.home[binary[k].leaf as usize] = (me, slot as u32);
                LIGHT | binary[k].leaf
            };
            self.nodes[me as usize].kids[slot] = child;
        }
        me
    }

    /// The light `u` chooses from `p` (unit normal `n`, or zero: no surface) and the
    /// probability of that choice; `None` where no light reaches the point.
    #[inline]
    pub(crate) fn choose(&self, p: Vec3, n: Vec3, mut u: f32) -> Option<(usize, f32)> {
        let mut k = 0usize;
        let mut pmf = 1.0f32;
        let mut w = [0.0; WIDTH];
        loop {
            let node = self.nodes.get(k)?;
            let total = node.lanes.weights(p, n, &mut w);
            if !(total > 0.0 && total.is_finite()) {
                return None;
            }
            let (slot, p_slot, rest) = pick(&w[..node.count as usize], total, u);
            pmf *= p_slot;
            u = rest.clamp(0.0, ONE_MINUS);
            let kid = node.kids[slot];
            if kid & LIGHT != 0 {
                return Some(((kid & !LIGHT) as usize, pmf));
            }
            k = kid as usize;
        }
    }

    /// The probability with which [`LightTree::choose`] chooses light `light` from `p`
    /// (normal `n`): the same products, from the root down.
    #[inline]
    pub(crate) fn pmf(&self, light: usize, p: Vec3, n: Vec3) -> f32 {
        let Some(&(mut node, mut slot)) = self.home.get(light) else { return 0.0 };
        // The way up, then the products down it.
        let mut way = [(0u32, 0u32); MAX_DEPTH];
        let mut depth = 0;
        while node != INNER && depth < MAX_DEPTH {
            way[depth] = (node, slot);
            depth += 1;
            (node, slot) = self.parent[node as usize];
        }
        let mut pmf = 1.0f32;
        let mut w = [0.0; WIDTH];
        for &(node, slot) in way[..depth].iter().rev() {
            let total = self.nodes[node as usize].lanes.weights(p, n, &mut w);
            if !(total > 0.0 && total.is_finite()) {
                return 0.0;
            }
            pmf *= w[slot as usize] / total;
        }
        pmf
    }

    /// What all its lights cover (the root's extent).
    pub(crate) fn whole(&self) -> &Extent {
        &self.whole
    }

    /// How many nodes it has, and the most a light lies below the root.
    #[cfg(test)]
    fn shape(&self) -> (usize, usize) {
        let deepest = (0..self.home.len())
            .map(|l| {
                let (mut node, mut d) = (self.home[l].0, 0);
                while node != INNER {
                    node = self.parent[node as usize].0;
                    d += 1;
                }
                d
            })
            .max()
            .unwrap_or(0);
        (self.nodes.len(), deepest)
    }
}

/// Adds the binary subtree over `ids` to `out`; its index.
fn build(lights: &[(Extent, Reach)], ids: &mut [u32], depth: u32, out: &mut Vec<Binary>) -> u32 {
    let at = out.len() as u32;
    if let [one] = ids {
        let (ext, reach) = lights[*one as usize];
        out.push(Binary { ext, reach, kids: [INNER; 2], leaf: *one });
        return at;
    }
    let ext = |i: &u32| lights[*i as usize].0;
    let whole = ids.iter().map(ext).reduce(|a, b| a.union(&b)).expect("two or more lights");
    out.push(Binary { ext: whole, reach: whole.reach(), kids: [INNER; 2], leaf: INNER });
    let mid = if depth >= MEDIAN_DEPTH { None } else { split(lights, ids, &whole) };
    let mid = mid.unwrap_or_else(|| {
        // The median along the centroids' widest axis.
        let (lo, hi) = centroid_bounds(lights, ids);
        let axis = (hi - lo).max_position();
        let half = ids.len() / 2;
        ids.select_nth_unstable_by(half, |a, b| ext(a).centroid()[axis].total_cmp(&ext(b).centroid()[axis]));
        half
    });
    let (left, right) = ids.split_at_mut(mid);
    let a = build(lights, left, depth + 1, out);
    let b = build(lights, right, depth + 1, out);
    out[at as usize].kids = [a, b];
    at
}

/// The bounds of the centroids of lights `ids`.
fn centroid_bounds(lights: &[(Extent, Reach)], ids: &[u32]) -> (Vec3, Vec3) {
    ids.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &i| {
        let c = lights[i as usize].0.centroid();
        (lo.min(c), hi.max(c))
    })
}

/// Where to split `ids` (whose union is `whole`): buckets along each axis of their
/// centroids, the split of least cost by Conty Estevez and Kulla's surface area
/// orientation heuristic (each side's intensity × bounds area × emission spread, the
/// axis weighed against the bounds' widest). Reorders `ids` and returns the first index
/// of the second half; `None` when no bucket split separates them.
fn split(lights: &[(Extent, Reach)], ids: &mut [u32], whole: &Extent) -> Option<usize> {
    let ext = |i: u32| lights[i as usize].0;
    let (clo, chi) = centroid_bounds(lights, ids);
    // Light i's bucket along `axis` (whose centroids span `span`).
    let bucket =
        |i: u32, axis: usize, span: f32| (((ext(i).centroid()[axis] - clo[axis]) / span * BUCKETS as f32) as usize).min(BUCKETS - 1);
    let size = whole.hi - whole.lo;
    let widest = size.max_element();
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        let span = chi[axis] - clo[axis];
        if span <= 0.0 || !span.is_finite() {
            continue;
        }
        let mut buckets: [Option<Extent>; BUCKETS] = [None; BUCKETS];
        for &i in ids.iter() {
            let b = bucket(i, axis, span);
            buckets[b] = Some(buckets[b].map_or(ext(i), |e| e.union(&ext(i))));
        }
        let cost_of = |e: &Option<Extent>| e.map_or(0.0, |e| e.intensity * e.area().max(1e-12) * e.spread());
        // Costs of the buckets below each split and above it.
        let mut below = [0.0f32; BUCKETS];
        let mut acc: Option<Extent> = None;
        for (b, e) in buckets.iter().enumerate().take(BUCKETS - 1) {
            if let Some(e) = e {
                acc = Some(acc.map_or(*e, |a| a.union(e)));
            }
            below[b] = cost_of(&acc);
        }
        let mut acc: Option<Extent> = None;
        let reg = if size[axis] > 0.0 { widest / size[axis] } else { 1.0 };
        for b in (1..BUCKETS).rev() {
            if let Some(e) = &buckets[b] {
                acc = Some(acc.map_or(*e, |a| a.union(e)));
            }
            let cost = reg * (below[b - 1] + cost_of(&acc));
            if buckets[..b].iter().any(Option::is_some) && acc.is_some() && best.is_none_or(|(c, ..)| cost < c) && cost.is_finite() {
                best = Some((cost, axis, b));
            }
        }
    }
    let (_, axis, b) = best?;
    let span = chi[axis] - clo[axis];
    let mut mid = 0;
    for k in 0..ids.len() {
        if bucket(ids[k], axis, span) < b {
            ids.swap(k, mid);
            mid += 1;
        }
    }
    (mid > 0 && mid < ids.len()).then_some(mid)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut state = seed;
        move || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// Point lights, spots and one-sided patches scattered over a box.
    fn crowd(count: usize) -> Vec<(Extent, Reach)> {
        let mut r = rng(7);
        (0..count)
            .map(|i| {
                let c = Vec3::new(r() * 20.0 - 10.0, r() * 4.0, r() * 20.0 - 10.0);
                let intensity = 0.1 + r() * 3.0;
                let e = match i % 3 {
                    0 => Extent { lo: c, hi: c, axis: Vec3::ZERO, theta_o: PI, theta_e: PI, intensity },
                    1 => Extent { lo: c, hi: c, axis: -Vec3::Y, theta_o: 0.3, theta_e: 0.2, intensity },
                    _ => {
                        let axis = Vec3::new(r() - 0.5, -1.0, r() - 0.5).normalize();
                        Extent { lo: c - 0.2, hi: c + 0.2, axis, theta_o: 0.0, theta_e: 0.5 * PI, intensity }
                    }
                };
                (e, e.reach())
            })
            .collect()
    }

    #[test]
    fn cones_unite_to_a_cone_holding_both() {
        let mut r = rng(3);
        for _ in 0..2000 {
            let mut dir = || Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize_or(Vec3::Y);
            let (a, b) = ((dir(), 0.0f32), (dir(), 0.0f32));
            let (a, b) = ((a.0, a.1 + 1.4 * (a.0.x + 0.5).abs()), (b.0, b.1 + 1.4 * (b.0.z + 0.5).abs()));
            let (axis, theta) = cone_union(a, b);
            if axis == Vec3::ZERO {
                assert_eq!(theta, PI);
                continue;
            }
            for (c, t) in [a, b] {
                let between = lucent_accel::math::acos(axis.dot(c).clamp(-1.0, 1.0));
                assert!(between + t <= theta + 1e-3, "{a:?} {b:?} -> {axis} {theta}: {c} at {between} + {t}");
            }
        }
    }

    #[test]
    fn choices_follow_the_densities_the_walk_reports() {
        let lights = crowd(300);
        let tree = LightTree::new(&lights).expect("a tree");
        let (nodes, deepest) = tree.shape();
        assert!(nodes < lights.len() / 3 && deepest <= 6, "{nodes} nodes, {deepest} deep");
        let mut r = rng(11);
        for _ in 0..6 {
            let p = Vec3::new(r() * 24.0 - 12.0, r() * 3.0, r() * 24.0 - 12.0);
            let n = if r() < 0.3 { Vec3::ZERO } else { Vec3::new(r() - 0.5, 1.0, r() - 0.5).normalize() };
            let pmf: Vec<f32> = (0..lights.len()).map(|i| tree.pmf(i, p, n)).collect();
            // (Below 1 where a node's bounds reach p and none of its lights does: a
            // choice there finds no light.)
            let sum: f32 = pmf.iter().sum();
            assert!(sum < 1.0 + 1e-4 && sum > 0.5, "{p}: {sum}");
            // A light that sends nothing to p is never chosen; every other one can be.
            for (i, (_, reach)) in lights.iter().enumerate() {
                let alone = Lane::of(reach).weight(p, n);
                assert_eq!(pmf[i] > 0.0, alone > 0.0, "light {i} at {p}: pmf {} weight {alone}", pmf[i]);
            }
            let k = 200_000;
            let mut seen = vec![0u32; lights.len()];
            let mut none = 0;
            for j in 0..k {
                let Some((i, q)) = tree.choose(p, n, (j as f32 + 0.5) / k as f32) else {
                    none += 1;
                    continue;
                };
                assert_eq!(q.to_bits(), pmf[i].to_bits(), "{p}, light {i}");
                seen[i] += 1;
            }
            assert!((none as f32 / k as f32 - (1.0 - sum)).abs() < 1e-3, "{p}: {none} without a light, pmf sum {sum}");
            for (i, &c) in seen.iter().enumerate() {
                assert!((c as f32 / k as f32 - pmf[i]).abs() < 2e-4 + 0.02 * pmf[i], "{p}, light {i}: {c} of {k}, pmf {}", pmf[i]);
            }
        }
    }

    #[test]
    fn near_lights_are_chosen_more_often_than_far_ones() {
        // Two rows of equal point lights far apart: from beside one row, its lights take
        // nearly all of the choices.
        let lights: Vec<(Extent, Reach)> = (0..64)
            .map(|i| {
                let c = Vec3::new((i % 32) as f32 * 0.5, 1.0, if i < 32 { 0.0 } else { 100.0 });
                let e = Extent { lo: c, hi: c, axis: Vec3::ZERO, theta_o: PI, theta_e: PI, intensity: 1.0 };
                (e, e.reach())
            })
            .collect();
        let tree = LightTree::new(&lights).expect("a tree");
        let near: f32 = (0..32).map(|i| tree.pmf(i, Vec3::new(8.0, 0.0, 0.0), Vec3::Y)).sum();
        assert!(near > 0.99, "{near}");
    }

    #[test]
    fn equal_places_and_one_light_make_trees_too() {
        let c = Vec3::ONE;
        let e = Extent { lo: c, hi: c, axis: Vec3::ZERO, theta_o: PI, theta_e: PI, intensity: 1.0 };
        let same = vec![(e, e.reach()); 1000];
        let tree = LightTree::new(&same).expect("a tree");
        assert!(tree.shape().1 <= 11, "the median halves equal places");
        let sum: f32 = (0..same.len()).map(|i| tree.pmf(i, Vec3::ZERO, Vec3::Y)).sum();
        assert!((sum - 1.0).abs() < 1e-4);
        let one = LightTree::new(&same[..1]).expect("a tree");
        assert_eq!(one.choose(Vec3::ZERO, Vec3::Y, 0.7), Some((0, 1.0)));
        assert_eq!(one.pmf(0, Vec3::ZERO, Vec3::Y), 1.0);
        assert!(LightTree::new(&[]).is_none());
    }
}

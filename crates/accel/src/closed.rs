//! Closed meshes and the rays that find leaks in a triangle test: every ray starts inside
//! a closed surface and aims at one of its vertices or a point on one of its edges, where
//! neighbouring triangles meet, so it must hit something. A ray that meets nothing went
//! through a crack between two triangles that share the edge or vertex: a leak. The
//! watertight test (Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection", JCGT
//! 2013) must lose none; SaarCOR's unit-triangle test decides each triangle alone, in
//! its own rounded map, and may. `lucent bench leaks` counts both; `tests/leaks.rs` holds
//! the watertight test to zero.

use crate::geom::Ray;
use crate::mesh::MeshBvh;
use glam::{Quat, Vec3};
use std::collections::HashMap;

/// A closed triangle mesh (every edge shared by exactly two triangles, with the same two
/// vertex indices) and points inside it.
#[derive(Clone, Debug)]
pub struct ClosedMesh {
    /// What it is ("sphere", "torus", "box"), for reports.
    pub name: &'static str,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles.
    pub indices: Vec<[u32; 3]>,
    /// Where rays may start: for each vertex, a point inside the surface near it.
    inside: Vec<Vec3>,
}

impl ClosedMesh {
    /// An icosphere of radius 1: the icosahedron with each triangle split in four
    /// `levels` times (20·4^levels triangles), vertices pushed onto the sphere.
    #[must_use]
    pub fn sphere(levels: u32) -> Self {
        let t = (1.0 + 5f32.sqrt()) / 2.0;
        let mut p: Vec<Vec3> = [
            (-1.0, t, 0.0),
            (1.0, t, 0.0),
            (-1.0, -t, 0.0),
            (1.0, -t, 0.0),
            (0.0, -1.0, t),
            (0.0, 1.0, t),
            (0.0, -1.0, -t),
            (0.0, 1.0, -t),
            (t, 0.0, -1.0),
            (t, 0.0, 1.0),
            (-t, 0.0, -1.0),
            (-t, 0.0, 1.0),
        ]
        .iter()
        .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
        .collect();
        let mut idx: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
            let mut m = |a: u32, b: u32, p: &mut Vec<Vec3>| {
                *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                    (p.len() - 1) as u32
                })
            };
            idx = idx
                .iter()
                .flat_map(|&[a, b, c]| {
                    let (ab, bc, ca) = (m(a, b, &mut p), m(b, c, &mut p), m(c, a, &mut p));
                    [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
                })
                .collect();
        }
        let inside = p.iter().map(|&v| v * 0.5).collect();
        Self { name: "sphere", positions: p, indices: idx, inside }
    }

    /// A torus around the y axis (radii `major` and `minor`), `nu` × `nv` quads split in two.
    #[must_use]
    pub fn torus(nu: u32, nv: u32, major: f32, minor: f32) -> Self {
        let (nu, nv) = (nu.max(3), nv.max(3));
        let mut p = Vec::new();
        let mut inside = Vec::new();
        for i in 0..nu {
            let a = i as f32 / nu as f32 * std::f32::consts::TAU;
            let core = Vec3::new(a.cos(), 0.0, a.sin()) * major;
            for j in 0..nv {
                let b = j as f32 / nv as f32 * std::f32::consts::TAU;
                let out = Vec3::new(a.cos() * b.cos(), b.sin(), a.sin() * b.cos());
                p.push(core + out * minor);
                inside.push(core + out * minor * 0.3);
            }
        }
        let at = |i: u32, j: u32| (i % nu) * nv + (j % nv);
        let mut idx = Vec::new();
        for i in 0..nu {
            for j in 0..nv {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                idx.push([a, b, c]);
                idx.push([a, c, d]);
            }
        }
        Self { name: "torus", positions: p, indices: idx, inside }
    }

    /// The cube [-1, 1]³ with `k` × `k` quads on each face, the faces sharing the vertices
    /// of their common edges.
    #[must_use]
    pub fn cube(k: u32) -> Self {
        let k = k.max(1);
        let mut id: HashMap<[i32; 3], u32> = HashMap::new();
        let mut p = Vec::new();
        let mut vert = |g: [i32; 3], p: &mut Vec<Vec3>| {
            *id.entry(g).or_insert_with(|| {
                p.push(Vec3::new(g[0] as f32, g[1] as f32, g[2] as f32) * (2.0 / k as f32) - Vec3::ONE);
                (p.len() - 1) as u32
            })
        };
        let mut idx = Vec::new();
        let k = k as i32;
        for axis in 0..3 {
            for side in [0, k] {
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                for j in 0..k {
                    for i in 0..k {
                        let g = |di: i32, dj: i32| {
                            let mut g = [0; 3];
                            g[axis] = side;
                            g[u] = i + di;
                            g[v] = j + dj;
                            g
                        };
                        let q = [g(0, 0), g(1, 0), g(1, 1), g(0, 1)].map(|x| vert(x, &mut p));
                        // Outward winding on both sides (it does not change a hit).
                        if side == 0 {
                            idx.push([q[0], q[2], q[1]]);
                            idx.push([q[0], q[3], q[2]]);
                        } else {
                            idx.push([q[0], q[1], q[2]]);
                            idx.push([q[0], q[2], q[3]]);
                        }
                    }
                }
            }
        }
        let inside = p.iter().map(|&v| v * 0.5).collect();
        Self { name: "cube", positions: p, indices: idx, inside }
    }

    /// The same mesh turned by `rotation` (so no edge lies along an axis), scaled by `scale`
    /// and moved by `offset`.
    #[must_use]
    pub fn placed(mut self, rotation: Quat, scale: f32, offset: Vec3) -> Self {
        for v in self.positions.iter_mut().chain(self.inside.iter_mut()) {
            *v = rotation * *v * scale + offset;
        }
        self
    }

    /// Ray `i` of the seeded leak-finding set: from inside, near a random triangle, aimed at
    /// one of its corners (a third of the rays), a point on one of its edges (a third) or
    /// its edge's midpoint (a third).
    #[must_use]
    pub fn leak_ray(&self, seed: u64, i: u64) -> Ray {
        let h = splitmix(seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let tri = self.indices[(h % self.indices.len() as u64) as usize];
        let h2 = splitmix(h);
        let k = (h2 % 3) as usize;
        let (a, b) = (self.positions[tri[k] as usize], self.positions[tri[(k + 1) % 3] as usize]);
        let s = ((h2 >> 11) as f32) * (1.0 / (1u64 << 53) as f32);
        let target = match (h2 >> 2) % 3 {
            0 => a,
            1 => a + (b - a) * s,
            _ => (a + b) * 0.5,
        };
        let o = self.inside[tri[k] as usize];
        Ray::new(o, (target - o).normalize_or(Vec3::X))
    }

    /// Rays `range` of the seeded set that meet nothing in `bvh` (built over this mesh).
    #[must_use]
    pub fn count_leaks(&self, bvh: &MeshBvh, seed: u64, range: std::ops::Range<u64>) -> u64 {
        range.filter(|&i| bvh.intersect(&self.leak_ray(seed, i)).is_none()).count() as u64
    }
}

/// SplitMix64 (Steele, Lea & Flood 2014): a seeded stream without a dependency.
fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

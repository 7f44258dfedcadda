//! A scene read as one mesh, split into separate objects as SaarCOR's scenes had them:
//! its Conference is 282,805 triangles in 54 objects (chairs and other furniture movable
//! on their own), where the public copy is one triangle soup without groups.
//!
//! The split: triangles that share a vertex position are one piece (connected
//! components); pieces as large as the room (a box diagonal of at least a fifth of the
//! scene's: walls, floor, ceiling) make one object, the room; pieces whose boxes touch are
//! one object (a chair's seat, back and legs); then the two nearest objects (by the gap
//! between their boxes) merge until at most the wanted number remain. Objects that are
//! the same triangles moved (equal to within a millionth of the scene's size after
//! taking away their boxes' corners) become instances of one geometry.

use glam::{Affine3A, Vec3};
use lucent_scene::{Attr, Instance, Mesh, Scene};
use std::collections::HashMap;

/// What a split made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SplitStats {
    /// Connected pieces found.
    pub pieces: usize,
    /// Objects (instances) made.
    pub objects: usize,
    /// Distinct geometries among them.
    pub geometries: usize,
}

struct Dsu(Vec<u32>);

impl Dsu {
    fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }
    fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let p = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = p;
            x = p;
        }
        x
    }
    fn union(&mut self, a: u32, b: u32) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            self.0[b.max(a) as usize] = a.min(b);
        }
    }
}

#[derive(Clone, Copy)]
struct Bounds {
    lo: Vec3,
    hi: Vec3,
}

impl Bounds {
    const EMPTY: Self = Self { lo: Vec3::splat(f32::INFINITY), hi: Vec3::splat(f32::NEG_INFINITY) };
    fn grow(&mut self, p: Vec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }
    fn join(self, o: Self) -> Self {
        Self { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }
    fn diagonal(self) -> f32 {
        (self.hi - self.lo).max(Vec3::ZERO).length()
    }
    /// The gap between two boxes (0 when they touch or overlap).
    fn gap(self, o: Self) -> f32 {
        (self.lo - o.hi).max(o.lo - self.hi).max(Vec3::ZERO).length()
    }
}

/// Splits every mesh of `scene` that is drawn once, untransformed, into at most `target`
/// objects (see the module's notes); other meshes, shapes and the rest of the scene are
/// kept as they are.
#[must_use]
pub fn split_objects(scene: &Scene, target: usize) -> (Scene, SplitStats) {
    let mut out = Scene { meshes: Vec::new(), instances: Vec::new(), ..scene.clone() };
    let mut stats = SplitStats::default();
    let mut uses = vec![0usize; scene.meshes.len()];
    for inst in &scene.instances {
        if let lucent_scene::Geom::Mesh(m) = inst.geom {
            if let Some(u) = uses.get_mut(m as usize) {
                *u += 1;
            }
        }
    }
    // Meshes not split keep their instances (renumbered).
    let mut new_id = vec![u32::MAX; scene.meshes.len()];
    for inst in &scene.instances {
        match inst.geom {
            lucent_scene::Geom::Mesh(m) if uses[m as usize] == 1 && inst.world_from_object == Affine3A::IDENTITY => {
                let (meshes, placed, s) = split_mesh(&scene.meshes[m as usize], target.max(1));
                stats.pieces += s.pieces;
                stats.objects += s.objects;
                stats.geometries += s.geometries;
                let base = out.meshes.len() as u32;
                out.meshes.extend(meshes);
                for (g, t) in placed {
                    out.instances
                        .push(Instance { geom: lucent_scene::Geom::Mesh(base + g), world_from_object: Affine3A::from_translation(t) });
                }
            }
            lucent_scene::Geom::Mesh(m) => {
                if new_id[m as usize] == u32::MAX {
                    new_id[m as usize] = out.meshes.len() as u32;
                    out.meshes.push(scene.meshes[m as usize].clone());
                }
                out.instances.push(Instance { geom: lucent_scene::Geom::Mesh(new_id[m as usize]), ..*inst });
            }
            _ => out.instances.push(*inst),
        }
    }
    (out, stats)
}

/// One mesh's objects: the geometries (positions relative to their box's corner) and the
/// objects as (geometry, translation).
fn split_mesh(mesh: &Mesh, target: usize) -> (Vec<Mesh>, Vec<(u32, Vec3)>, SplitStats) {
    let tris = &mesh.indices;
    // Vertices welded by position, then pieces by shared vertices.
    let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
    let ids: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let n = weld.len() as u32;
            *weld.entry(p.to_array().map(f32::to_bits)).or_insert(n)
        })
        .collect();
    let mut dsu = Dsu::new(weld.len());
    for t in tris {
        let v = t.map(|i| ids.get(i as usize).copied().unwrap_or(0));
        dsu.union(v[0], v[1]);
        dsu.union(v[0], v[2]);
    }
    let mut piece_of_root: HashMap<u32, usize> = HashMap::new();
    let mut piece = Vec::with_capacity(tris.len());
    let mut bounds: Vec<Bounds> = Vec::new();
    for t in tris {
        let root = dsu.find(ids.get(t[0] as usize).copied().unwrap_or(0));
        let n = piece_of_root.len();
        let p = *piece_of_root.entry(root).or_insert(n);
        if p == bounds.len() {
            bounds.push(Bounds::EMPTY);
        }
        for &i in t {
            if let Some(&q) = mesh.positions.get(i as usize) {
                bounds[p].grow(q);
            }
        }
        piece.push(p);
    }
    let pieces = bounds.len();
    let scene_box = bounds.iter().fold(Bounds::EMPTY, |a, &b| a.join(b));
    let big = 0.2 * scene_box.diagonal();
    // Objects: the room (every piece as large as it), pieces whose boxes touch.
    let mut groups = Dsu::new(pieces);
    let room: Vec<usize> = (0..pieces).filter(|&p| bounds[p].diagonal() >= big).collect();
    for w in room.windows(2) {
        groups.union(w[0] as u32, w[1] as u32);
    }
    let small: Vec<usize> = (0..pieces).filter(|&p| bounds[p].diagonal() < big).collect();
    for (i, &a) in small.iter().enumerate() {
        for &b in &small[i + 1..] {
            if bounds[a].gap(bounds[b]) == 0.0 {
                groups.union(a as u32, b as u32);
            }
        }
    }
    // The objects' boxes; the room's never merges with furniture.
    let mut obj_of_root: HashMap<u32, usize> = HashMap::new();
    let mut obj_bounds: Vec<Bounds> = Vec::new();
    let mut is_room: Vec<bool> = Vec::new();
    let mut obj_of_piece = vec![0usize; pieces];
    for p in 0..pieces {
        let r = groups.find(p as u32);
        let n = obj_of_root.len();
        let o = *obj_of_root.entry(r).or_insert(n);
        if o == obj_bounds.len() {
            obj_bounds.push(Bounds::EMPTY);
            is_room.push(false);
        }
        obj_bounds[o] = obj_bounds[o].join(bounds[p]);
        is_room[o] |= bounds[p].diagonal() >= big;
        obj_of_piece[p] = o;
    }
    // Merge the nearest two until `target` remain (alive objects only).
    let mut alive: Vec<bool> = vec![true; obj_bounds.len()];
    let mut merged_into: Vec<usize> = (0..obj_bounds.len()).collect();
    let mut count = obj_bounds.len();
    while count > target {
        let mut best = (f32::INFINITY, 0, 0);
        for a in (0..obj_bounds.len()).filter(|&a| alive[a] && !is_room[a]) {
            for b in (a + 1..obj_bounds.len()).filter(|&b| alive[b] && !is_room[b]) {
                let g = obj_bounds[a].gap(obj_bounds[b]);
                if g < best.0 {
                    best = (g, a, b);
                }
            }
        }
        if !best.0.is_finite() {
            break;
        }
        let (_, a, b) = best;
        obj_bounds[a] = obj_bounds[a].join(obj_bounds[b]);
        alive[b] = false;
        merged_into[b] = a;
        count -= 1;
    }
    let final_of = |mut o: usize| {
        while merged_into[o] != o {
            o = merged_into[o];
        }
        o
    };
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); obj_bounds.len()];
    for (t, &p) in piece.iter().enumerate() {
        members[final_of(obj_of_piece[p])].push(t);
    }
    members.retain(|m| !m.is_empty());
    // Geometries: equal triangles moved are one geometry.
    let tol = 1e-6 * scene_box.diagonal().max(f32::MIN_POSITIVE);
    let corner = |m: &[usize]| {
        m.iter().flat_map(|&t| tris[t]).filter_map(|i| mesh.positions.get(i as usize)).fold(Vec3::splat(f32::INFINITY), |a, &p| a.min(p))
    };
    let mut geoms: Vec<(Vec<usize>, Vec3)> = Vec::new();
    let mut placed = Vec::new();
    for m in &members {
        let c = corner(m);
        let same = geoms.iter().position(|(g, gc)| {
            g.len() == m.len()
                && g.iter().zip(m).all(|(&a, &b)| {
                    tris[a].iter().zip(&tris[b]).all(|(&i, &j)| match (mesh.positions.get(i as usize), mesh.positions.get(j as usize)) {
                        (Some(&p), Some(&q)) => ((p - *gc) - (q - c)).abs().max_element() <= tol,
                        _ => false,
                    })
                })
        });
        match same {
            Some(g) => placed.push((g as u32, c)),
            None => {
                placed.push((geoms.len() as u32, c));
                geoms.push((m.clone(), c));
            }
        }
    }
    let meshes = geoms.iter().enumerate().map(|(k, (m, c))| sub_mesh(mesh, m, *c, k)).collect();
    let stats = SplitStats { pieces, objects: placed.len(), geometries: geoms.len() };
    (meshes, placed, stats)
}

/// The triangles `tris` of `mesh` as a mesh of their own, moved by `-corner`.
fn sub_mesh(mesh: &Mesh, tris: &[usize], corner: Vec3, k: usize) -> Mesh {
    let mut remap: HashMap<u32, u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut indices = Vec::with_capacity(tris.len());
    for &t in tris {
        indices.push(mesh.indices[t].map(|i| {
            *remap.entry(i).or_insert_with(|| {
                positions.push(mesh.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO) - corner);
                (positions.len() - 1) as u32
            })
        }));
    }
    Mesh {
        name: format!("{} object {k}", mesh.name),
        positions,
        indices,
        normals: corner_attr(&mesh.normals, mesh, tris),
        uvs: corner_attr(&mesh.uvs, mesh, tris),
        material: tris.iter().map(|&t| mesh.material.get(t).copied().unwrap_or(0)).collect(),
    }
}

/// A vertex attribute of triangles `tris` of `mesh`, three values a triangle (none when
/// the mesh has none).
fn corner_attr<T: Copy>(a: &Attr<T>, mesh: &Mesh, tris: &[usize]) -> Attr<T> {
    let mut values = Vec::new();
    let mut idx = Vec::new();
    for &t in tris {
        let Some(c) = a.corners(t, &mesh.indices[t]) else { return Attr { values: Vec::new(), indices: None } };
        let n = values.len() as u32;
        values.extend(c);
        idx.push([n, n + 1, n + 2]);
    }
    Attr { values, indices: Some(idx) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(at: Vec3, size: f32, positions: &mut Vec<Vec3>, indices: &mut Vec<[u32; 3]>) {
        let b = positions.len() as u32;
        for i in 0..8 {
            positions.push(at + size * Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32));
        }
        for f in [
            [0, 1, 3],
            [0, 3, 2],
            [4, 6, 7],
            [4, 7, 5],
            [0, 4, 5],
            [0, 5, 1],
            [2, 3, 7],
            [2, 7, 6],
            [0, 2, 6],
            [0, 6, 4],
            [1, 5, 7],
            [1, 7, 3],
        ] {
            indices.push(f.map(|i: u32| b + i));
        }
    }

    /// A floor as large as the room, two equal cubes far apart, a third cube touching a
    /// fourth smaller one: the room, two instances of one geometry, one object of two
    /// pieces; asked for two objects, the cubes merge into one beside the room.
    #[test]
    fn room_and_furniture() {
        let (mut p, mut i) = (Vec::new(), Vec::new());
        cube(Vec3::new(-50.0, -1.0, -50.0), 100.0, &mut p, &mut i);
        cube(Vec3::new(0.0, 0.0, 0.0), 1.0, &mut p, &mut i);
        cube(Vec3::new(10.0, 0.0, 0.0), 1.0, &mut p, &mut i);
        cube(Vec3::new(20.0, 0.0, 0.0), 1.0, &mut p, &mut i);
        cube(Vec3::new(21.0, 0.25, 0.25), 0.5, &mut p, &mut i);
        let mut scene = Scene::default();
        let n = i.len();
        scene.add_mesh(Mesh { positions: p, indices: i, material: vec![0; n], ..Default::default() });
        let (s, st) = split_objects(&scene, 54);
        assert_eq!(st, SplitStats { pieces: 5, objects: 4, geometries: 3 });
        assert_eq!(s.instances.len(), 4);
        assert_eq!(s.meshes.iter().map(|m| m.indices.len()).sum::<usize>() + 12, n);
        // Every triangle is where it was: the instances' world-space triangles are the
        // input's, as a set.
        let key = |v: Vec3| v.to_array().map(|x| (x * 1000.0).round() as i64);
        let mut want: Vec<_> = scene.meshes[0].indices.iter().map(|t| t.map(|j| key(scene.meshes[0].positions[j as usize]))).collect();
        let mut got = Vec::new();
        for inst in &s.instances {
            let lucent_scene::Geom::Mesh(g) = inst.geom else { panic!("a mesh") };
            let m = &s.meshes[g as usize];
            got.extend(m.indices.iter().map(|t| t.map(|j| key(inst.world_from_object.transform_point3(m.positions[j as usize])))));
        }
        want.sort_unstable();
        got.sort_unstable();
        assert_eq!(got, want);
        let (_, st) = split_objects(&scene, 2);
        assert_eq!((st.objects, st.geometries), (2, 2));
    }
}

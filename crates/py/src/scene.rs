//! `Scene`: geometry from numpy arrays or files, its edits, and the lazily built world the
//! queries and renders use.
//!
//! Ids: an instance keeps its id for its life (removing others does not renumber it); a
//! geometry id names a mesh or an analytic shape that instances draw. float64 input is
//! re-centred in float64 before the conversion to float32: each geometry keeps its own
//! shift (the centre of its vertices), and the scene one offset (the first float64
//! geometry's world centre) that rays and transforms are moved by, so coordinates far from
//! the origin keep their precision where the work happens.

use crate::arrays::{affines, ints, one_affine, shape_str, to_numpy, Floats};
use crate::errors::{guard, LucentError};
use glam::{Affine3A, DAffine3, DVec3, Vec2, Vec3};
use lucent_accel::{MeshOptions, Quality, TriangleTest};
use lucent_render::World;
use lucent_scene::{Attr, Geom, Instance, Material, Mesh, ShapeKind};
use pyo3::exceptions::{PyFileNotFoundError, PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::{RwLock, RwLockReadGuard, RwLockWriteGuard};

/// What a public geometry id stands for.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GeomEntry {
    /// The scene's geometry.
    pub geom: Geom,
    /// The shift its stored float32 vertices were taken by (object space).
    pub shift: DVec3,
}

/// The scene and what is built from it.
pub(crate) struct State {
    /// The scene while nothing is built (or after an edit that needs a new build).
    scene: Option<lucent_scene::Scene>,
    /// The built world (holding the scene).
    world: Option<World>,
    pub opts: MeshOptions,
    /// World offset: every world coordinate is stored minus this.
    pub offset: DVec3,
    /// Per instance (in the scene's order): its public id and geometry id.
    pub ids: Vec<i64>,
    pub inst_geom: Vec<i64>,
    next_id: i64,
    /// Public geometries.
    pub geoms: Vec<GeomEntry>,
}

impl State {
    fn new(scene: lucent_scene::Scene, opts: MeshOptions) -> Self {
        let mut geoms: Vec<GeomEntry> =
            (0..scene.meshes.len()).map(|m| GeomEntry { geom: Geom::Mesh(m as u32), shift: DVec3::ZERO }).collect();
        let mut inst_geom = Vec::with_capacity(scene.instances.len());
        for i in &scene.instances {
            match i.geom {
                Geom::Mesh(m) => inst_geom.push(i64::from(m)),
                g @ Geom::Shape { .. } => {
                    inst_geom.push(geoms.len() as i64);
                    geoms.push(GeomEntry { geom: g, shift: DVec3::ZERO });
                }
            }
        }
        let n = scene.instances.len();
        Self {
            scene: Some(scene),
            world: None,
            opts,
            offset: DVec3::ZERO,
            ids: (0..n as i64).collect(),
            inst_geom,
            next_id: n as i64,
            geoms,
        }
    }

    /// The scene as it stands.
    pub fn scene(&self) -> &lucent_scene::Scene {
        match (&self.world, &self.scene) {
            (Some(w), _) => w.scene(),
            (None, Some(s)) => s,
            // (One of the two is always there; an empty scene stands in.)
            (None, None) => empty_scene(),
        }
    }

    /// The scene to change (the built world, if any, is dropped: the next query builds).
    fn scene_mut(&mut self) -> &mut lucent_scene::Scene {
        if let Some(w) = self.world.take() {
            self.scene = Some(w.scene().clone());
        }
        self.scene.get_or_insert_with(Default::default)
    }

    /// The world, built if needed.
    pub fn build(&mut self) -> Result<&mut World, String> {
        if self.world.is_none() {
            let scene = self.scene.take().unwrap_or_default();
            match World::new(scene.clone(), self.opts) {
                Ok(w) => self.world = Some(w),
                Err(e) => {
                    self.scene = Some(scene);
                    return Err(e.to_string());
                }
            }
        }
        self.world.as_mut().ok_or_else(|| "no world".to_string())
    }

    /// The built world (after [`State::build`]).
    pub fn world(&self) -> Option<&World> {
        self.world.as_ref()
    }

    /// Internal index of public instance `id`.
    fn index_of(&self, id: i64) -> PyResult<usize> {
        // PERF: ids are mostly in order (removals only make gaps): a binary search.
        match self.ids.binary_search(&id) {
            Ok(i) => Ok(i),
            Err(_) => Err(PyIndexError::new_err(format!("instance {id}: no such instance (ids 0..{} were given out)", self.next_id))),
        }
    }

    fn geom(&self, id: i64) -> PyResult<GeomEntry> {
        usize::try_from(id)
            .ok()
            .and_then(|i| self.geoms.get(i))
            .copied()
            .ok_or_else(|| PyIndexError::new_err(format!("geometry {id}: no such geometry (there are {})", self.geoms.len())))
    }

    /// The float32 world-from-object map of an instance of `g` placed by `m` (user space).
    fn placed(&self, g: &GeomEntry, m: &DAffine3) -> Affine3A {
        // world − offset = L (stored + shift) + t − offset
        let t = m.matrix3 * g.shift + m.translation - self.offset;
        Affine3A::from_mat3_translation(m.matrix3.as_mat3(), t.as_vec3())
    }

    fn push_instance(&mut self, geom_id: i64, world_from_object: Affine3A) -> i64 {
        let g = self.geoms[geom_id as usize].geom;
        self.scene_mut().instances.push(Instance { geom: g, world_from_object });
        let id = self.next_id;
        self.next_id += 1;
        self.ids.push(id);
        self.inst_geom.push(geom_id);
        id
    }

    /// The index of `material` (added to the scene), or of the default one.
    fn material(&mut self, material: Option<Material>) -> u32 {
        match material {
            Some(mat) => {
                let sc = self.scene_mut();
                sc.materials.push(mat);
                (sc.materials.len() - 1) as u32
            }
            None => self.default_material(),
        }
    }

    fn default_material(&mut self) -> u32 {
        let s = self.scene_mut();
        if s.materials.is_empty() {
            s.materials.push(Material::default());
        }
        0
    }
}

fn empty_scene() -> &'static lucent_scene::Scene {
    static EMPTY: std::sync::OnceLock<lucent_scene::Scene> = std::sync::OnceLock::new();
    EMPTY.get_or_init(Default::default)
}

/// A scene for ray queries and rendering: meshes, analytic shapes and instances of them,
/// built from numpy arrays or read from a file (``lucent.load``). Queries build the
/// acceleration structure on first use; edits (``set_transforms``, ``update_vertices``,
/// ``remove``, ``set_time``) update it in place. Safe to query from many Python threads
/// at once; every call releases the GIL.
#[pyclass(frozen, module = "lucent._lucent", name = "Scene")]
pub struct Scene {
    pub(crate) state: RwLock<State>,
}

impl Scene {
    pub(crate) fn read(&self) -> RwLockReadGuard<'_, State> {
        self.state.read().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    pub(crate) fn write(&self) -> RwLockWriteGuard<'_, State> {
        self.state.write().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Runs `f` on the built world (building it first if an edit left it unbuilt), with
    /// the GIL released; the read lock is held while `f` runs.
    pub(crate) fn with_world<R: Send>(&self, py: Python<'_>, what: &str, f: impl FnOnce(&State, &World) -> R + Send) -> PyResult<R> {
        let r = py.detach(|| {
            guard(what, || {
                {
                    let s = self.read();
                    if let Some(w) = s.world() {
                        return Ok(f(&s, w));
                    }
                }
                let mut s = self.write();
                s.build()?;
                // (Downgraded, not dropped and taken again: an edit from another thread in
                // between would leave the world unbuilt.)
                let s = RwLockWriteGuard::downgrade(s);
                match s.world() {
                    Some(w) => Ok(f(&s, w)),
                    None => Err("the scene has no world after its build".to_string()),
                }
            })
        })?;
        r.map_err(|e| LucentError::new_err(format!("{what}: {e}")))
    }

    pub(crate) fn from_scene(scene: lucent_scene::Scene, opts: MeshOptions) -> Self {
        Self { state: RwLock::new(State::new(scene, opts)) }
    }

    /// Runs an edit with the write lock, the GIL released.
    fn edit<R: Send>(&self, py: Python<'_>, what: &str, f: impl FnOnce(&mut State) -> PyResult<R> + Send) -> PyResult<R> {
        py.detach(|| guard(what, || f(&mut self.write())))?
    }
}

/// Parses the build options.
fn mesh_options(quality: &str, triangle_test: &str) -> PyResult<MeshOptions> {
    let quality = match quality {
        "sah" => Quality::Sah,
        "high" => Quality::default(),
        "spatial" => Quality::Spatial,
        q => return Err(PyValueError::new_err(format!("quality: {q:?} is not one of 'sah', 'high', 'spatial'"))),
    };
    let test = match triangle_test {
        "unit" => TriangleTest::UnitTriangle,
        "watertight" => TriangleTest::Watertight,
        t => return Err(PyValueError::new_err(format!("triangle_test: {t:?} is not one of 'unit', 'watertight'"))),
    };
    Ok(MeshOptions { quality, test, ..MeshOptions::default() })
}

/// An RGB triple from a number or three numbers.
fn rgb(v: &Bound<'_, PyAny>, key: &str) -> PyResult<Vec3> {
    if let Ok(x) = v.extract::<f32>() {
        return Ok(Vec3::splat(x));
    }
    match v.extract::<Vec<f32>>() {
        Ok(c) if c.len() == 3 && c.iter().all(|x| x.is_finite()) => Ok(Vec3::new(c[0], c[1], c[2])),
        _ => Err(PyValueError::new_err(format!("material[{key:?}]: a number or three finite numbers were needed"))),
    }
}

/// A material from a dict of Phong-style terms (the keys Whitted's shading and the path
/// tracer's conversion read).
fn material_of(d: &Bound<'_, PyDict>) -> PyResult<Material> {
    let mut m = Material { name: "python".into(), ..Material::default() };
    for (k, v) in d.iter() {
        let key: String = k.extract().map_err(|_| PyValueError::new_err("material: keys must be strings"))?;
        let num = |v: &Bound<'_, PyAny>| -> PyResult<f32> {
            v.extract::<f32>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| PyValueError::new_err(format!("material[{key:?}]: a finite number was needed")))
        };
        match key.as_str() {
            "name" => m.name = v.extract()?,
            "diffuse" => m.diffuse = rgb(&v, &key)?,
            "specular" => m.specular = rgb(&v, &key)?,
            "emission" => m.emission = rgb(&v, &key)?,
            "reflect" => m.reflect = rgb(&v, &key)?,
            "transmit" => m.transmit = rgb(&v, &key)?,
            "ambient" => m.ambient = rgb(&v, &key)?,
            "shininess" => m.shininess = num(&v)?,
            "ior" => m.ior = num(&v)?,
            "fresnel" => m.fresnel = v.extract()?,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "material: unknown key {key:?} (known: name, diffuse, specular, shininess, emission, reflect, transmit, ambient, ior, fresnel)"
                )))
            }
        }
    }
    Ok(m)
}

/// Vertices as float32 after taking `shift` away (float64 math for float64 input).
fn positions(py: Python<'_>, v: &Floats<'_>, name: &str, shift: DVec3) -> PyResult<Vec<Vec3>> {
    v.rows(name, 3)?;
    let s = v.slice()?;
    // (Converted with the GIL released: a mesh of millions of vertices takes a while.)
    py.detach(|| {
        let n = s.len() / 3;
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let p = DVec3::new(s.get(3 * i), s.get(3 * i + 1), s.get(3 * i + 2));
            if !p.is_finite() {
                return Err(PyValueError::new_err(format!("{name}[{i}]: not finite ({p})")));
            }
            out.push((p - shift).as_vec3());
        }
        Ok(out)
    })
}

/// The centre of float64 vertices' bounds (zero for float32 input: stored as given).
fn centre(v: &Floats<'_>) -> PyResult<DVec3> {
    let s = v.slice()?;
    if !s.is_f64() || s.len() < 3 {
        return Ok(DVec3::ZERO);
    }
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for i in 0..s.len() / 3 {
        let p = DVec3::new(s.get(3 * i), s.get(3 * i + 1), s.get(3 * i + 2));
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let c = (lo + hi) * 0.5;
    Ok(if c.is_finite() { c } else { DVec3::ZERO })
}

fn shape_kind(kind: &str) -> PyResult<ShapeKind> {
    Ok(match kind {
        "sphere" => ShapeKind::Sphere,
        "cylinder" => ShapeKind::CappedCylinder,
        "tube" => ShapeKind::Tube,
        "cone" => ShapeKind::CappedCone,
        "box" => ShapeKind::Box,
        "disk" => ShapeKind::Disk,
        "infinite_cylinder" => ShapeKind::Cylinder,
        "infinite_cone" => ShapeKind::Cone,
        k => {
            return Err(PyValueError::new_err(format!(
                "kind: {k:?} is not one of 'sphere', 'cylinder', 'tube', 'cone', 'box', 'disk', 'infinite_cylinder', 'infinite_cone'"
            )))
        }
    })
}

#[pymethods]
impl Scene {
    #[new]
    #[pyo3(signature = (*, quality = "high", triangle_test = "unit"))]
    fn py_new(quality: &str, triangle_test: &str) -> PyResult<Self> {
        Ok(Self::from_scene(lucent_scene::Scene::default(), mesh_options(quality, triangle_test)?))
    }

    /// Adds a triangle mesh and one instance of it; returns the instance id (its
    /// geometry id is ``geometry_of(id)``).
    #[pyo3(signature = (vertices, faces, *, transform = None, normals = None, uvs = None, material = None, name = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_mesh(
        &self,
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        transform: Option<&Bound<'_, PyAny>>,
        normals: Option<&Bound<'_, PyAny>>,
        uvs: Option<&Bound<'_, PyAny>>,
        material: Option<&Bound<'_, PyDict>>,
        name: Option<String>,
    ) -> PyResult<i64> {
        let v = Floats::extract(vertices, "vertices")?;
        let (f, fshape) = ints(faces, "faces")?;
        if fshape.len() != 2 || fshape[1] != 3 {
            return Err(PyValueError::new_err(format!("faces: shape {} where (F, 3) was needed", shape_str(&fshape))));
        }
        let m = one_affine(transform, "transform")?;
        let shift = centre(&v)?;
        let pos = positions(py, &v, "vertices", shift)?;
        let nv = pos.len();
        let indices = py.detach(|| -> PyResult<Vec<[u32; 3]>> {
            let mut indices = Vec::with_capacity(f.len() / 3);
            for (k, t) in f.chunks_exact(3).enumerate() {
                let mut tri = [0u32; 3];
                for (c, &i) in t.iter().enumerate() {
                    tri[c] = u32::try_from(i)
                        .ok()
                        .filter(|&i| (i as usize) < nv)
                        .ok_or_else(|| PyIndexError::new_err(format!("faces[{k}, {c}]: vertex {i} out of range (0..{nv})")))?;
                }
                indices.push(tri);
            }
            Ok(indices)
        })?;
        let normals = match normals {
            Some(n) => {
                let n = Floats::extract(n, "normals")?;
                let p = positions(py, &n, "normals", DVec3::ZERO)?;
                if p.len() != nv {
                    return Err(PyValueError::new_err(format!("normals: {} rows for {nv} vertices", p.len())));
                }
                p
            }
            None => Vec::new(),
        };
        let uvs = match uvs {
            Some(u) => {
                let u = Floats::extract(u, "uvs")?;
                let lead = u.vectors("uvs", 2)?;
                if lead != [nv] {
                    return Err(PyValueError::new_err(format!("uvs: shape {} where ({nv}, 2) was needed", shape_str(u.shape()))));
                }
                let s = u.slice()?;
                (0..nv).map(|i| Vec2::new(s.get(2 * i) as f32, s.get(2 * i + 1) as f32)).collect()
            }
            None => Vec::new(),
        };
        let material = material.map(material_of).transpose()?;
        let nt = indices.len();
        self.edit(py, "add_mesh", move |s| {
            if s.geoms.is_empty() && s.scene().instances.is_empty() {
                s.offset = m.transform_point3(shift);
            }
            let mat = s.material(material);
            let sc = s.scene_mut();
            let mesh_index = sc.meshes.len() as u32;
            sc.meshes.push(Mesh {
                name: name.unwrap_or_else(|| format!("mesh {mesh_index}")),
                positions: pos,
                indices,
                normals: Attr { values: normals, indices: None },
                uvs: Attr { values: uvs, indices: None },
                material: vec![mat; nt],
            });
            let g = GeomEntry { geom: Geom::Mesh(mesh_index), shift };
            s.geoms.push(g);
            let gid = (s.geoms.len() - 1) as i64;
            let placed = s.placed(&g, &m);
            Ok(s.push_instance(gid, placed))
        })
    }

    /// Adds an analytic shape (``'sphere'``, ``'cylinder'``, ``'tube'``, ``'cone'``,
    /// ``'box'``, ``'disk'``, ``'infinite_cylinder'``, ``'infinite_cone'``, each in its
    /// canonical form: unit radius, z in [-1, 1]) placed by ``transform``, or a sphere by
    /// ``center`` and ``radius``; returns the instance id.
    #[pyo3(signature = (kind, *, transform = None, center = None, radius = None, material = None))]
    fn add_shape(
        &self,
        py: Python<'_>,
        kind: &str,
        transform: Option<&Bound<'_, PyAny>>,
        center: Option<[f64; 3]>,
        radius: Option<f64>,
        material: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<i64> {
        let k = shape_kind(kind)?;
        let mut m = one_affine(transform, "transform")?;
        if let Some(r) = radius {
            if !(r > 0.0 && r.is_finite()) {
                return Err(PyValueError::new_err(format!("radius: {r} is not a positive number")));
            }
            m *= DAffine3::from_scale(DVec3::splat(r));
        }
        if let Some(c) = center {
            let c = DVec3::from(c);
            if !c.is_finite() {
                return Err(PyValueError::new_err("center: not finite"));
            }
            m = DAffine3::from_translation(c) * m;
        }
        let material = material.map(material_of).transpose()?;
        self.edit(py, "add_shape", move |s| {
            if s.geoms.is_empty() && s.scene().instances.is_empty() {
                s.offset = m.translation;
            }
            let mat = s.material(material);
            let g = GeomEntry { geom: Geom::Shape { kind: k, material: mat }, shift: DVec3::ZERO };
            s.geoms.push(g);
            let gid = (s.geoms.len() - 1) as i64;
            let placed = s.placed(&g, &m);
            Ok(s.push_instance(gid, placed))
        })
    }

    /// Adds spheres (one geometry, an instance per sphere) from ``centers`` (N, 3) and
    /// ``radii`` (N,) or one radius; returns their instance ids.
    #[pyo3(signature = (centers, radii, *, material = None))]
    fn add_spheres<'py>(
        &self,
        py: Python<'py>,
        centers: &Bound<'py, PyAny>,
        radii: &Bound<'py, PyAny>,
        material: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, numpy::PyArrayDyn<i64>>> {
        let c = Floats::extract(centers, "centers")?;
        let n = c.rows("centers", 3)?;
        let r = Floats::extract(radii, "radii")?;
        let rs = r.slice()?;
        if !(rs.len() == 1 || (r.shape() == [n])) {
            return Err(PyValueError::new_err(format!("radii: shape {} where ({n},) or one number was needed", shape_str(r.shape()))));
        }
        let cs = c.slice()?;
        let mut maps = Vec::with_capacity(n);
        for i in 0..n {
            let p = DVec3::new(cs.get(3 * i), cs.get(3 * i + 1), cs.get(3 * i + 2));
            let rad = rs.get(if rs.len() == 1 { 0 } else { i });
            if !(p.is_finite() && rad > 0.0 && rad.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "sphere {i}: centre {p} radius {rad} (a finite centre and a positive radius were needed)"
                )));
            }
            maps.push(DAffine3::from_scale_rotation_translation(DVec3::splat(rad), glam::DQuat::IDENTITY, p));
        }
        let material = material.map(material_of).transpose()?;
        let ids = self.edit(py, "add_spheres", move |s| {
            if s.geoms.is_empty() && s.scene().instances.is_empty() {
                if let Some(m) = maps.first() {
                    s.offset = m.translation;
                }
            }
            let mat = s.material(material);
            let g = GeomEntry { geom: Geom::Shape { kind: ShapeKind::Sphere, material: mat }, shift: DVec3::ZERO };
            s.geoms.push(g);
            let gid = (s.geoms.len() - 1) as i64;
            Ok(maps.iter().map(|m| s.placed(&g, m)).collect::<Vec<_>>().into_iter().map(|a| s.push_instance(gid, a)).collect::<Vec<_>>())
        })?;
        to_numpy(py, ids, &[n])
    }

    /// Adds instances of geometry ``geometry`` placed by ``transforms`` (K, 4, 4)
    /// (world from object); returns their instance ids.
    fn add_instances<'py>(
        &self,
        py: Python<'py>,
        geometry: i64,
        transforms: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, numpy::PyArrayDyn<i64>>> {
        let (maps, lead) = affines(transforms, "transforms")?;
        let ids = self.edit(py, "add_instances", move |s| {
            let g = s.geom(geometry)?;
            let placed: Vec<Affine3A> = maps.iter().map(|m| s.placed(&g, m)).collect();
            Ok(placed.into_iter().map(|a| s.push_instance(geometry, a)).collect::<Vec<_>>())
        })?;
        to_numpy(py, ids, &lead)
    }

    /// Moves instances: ``transforms`` (K, 4, 4) for instance ids ``instances`` (K,).
    /// The top level is rebuilt once; the meshes are not touched.
    fn set_transforms(&self, py: Python<'_>, instances: &Bound<'_, PyAny>, transforms: &Bound<'_, PyAny>) -> PyResult<()> {
        let (ids, ishape) = ints(instances, "instances")?;
        let (maps, lead) = affines(transforms, "transforms")?;
        if maps.len() != ids.len() {
            return Err(PyValueError::new_err(format!(
                "transforms: {} matrices (shape {}) for {} instances (shape {})",
                maps.len(),
                shape_str(&with_44(&lead)),
                ids.len(),
                shape_str(&ishape)
            )));
        }
        self.edit(py, "set_transforms", move |s| {
            let mut moves = Vec::with_capacity(ids.len());
            for (&id, m) in ids.iter().zip(&maps) {
                let i = s.index_of(id)?;
                let g = s.geom(s.inst_geom[i])?;
                moves.push((i, s.placed(&g, m)));
            }
            match s.world.as_mut() {
                Some(w) => w.set_instance_transforms(&moves).map_err(|e| LucentError::new_err(format!("set_transforms: {e}"))),
                None => {
                    let sc = s.scene_mut();
                    for (i, a) in moves {
                        sc.instances[i].world_from_object = a;
                    }
                    Ok(())
                }
            }
        })
    }

    /// Replaces the vertices of mesh geometry ``geometry`` (same count): the mesh's tree
    /// is refit (or rebuilt when refitting would make it slow), every instance follows.
    fn update_vertices(&self, py: Python<'_>, geometry: i64, vertices: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = Floats::extract(vertices, "vertices")?;
        let g = self.read().geom(geometry)?;
        let Geom::Mesh(m) = g.geom else {
            return Err(PyValueError::new_err(format!("geometry {geometry}: an analytic shape has no vertices")));
        };
        let pos = positions(py, &v, "vertices", g.shift)?;
        self.edit(py, "update_vertices", move |s| {
            let have = s.scene().meshes.get(m as usize).map_or(0, |mesh| mesh.positions.len());
            if have != pos.len() {
                return Err(PyValueError::new_err(format!("vertices: {} rows for a mesh of {have} vertices", pos.len())));
            }
            match s.world.as_mut() {
                Some(w) => w.set_mesh_positions(m as usize, pos, None).map_err(|e| LucentError::new_err(format!("update_vertices: {e}"))),
                None => {
                    s.scene_mut().meshes[m as usize].positions = pos;
                    Ok(())
                }
            }
        })
    }

    /// Removes instances (by id); the others keep their ids.
    fn remove(&self, py: Python<'_>, instances: &Bound<'_, PyAny>) -> PyResult<()> {
        let (ids, _) = ints(instances, "instances")?;
        self.edit(py, "remove", move |s| {
            let mut keep = vec![true; s.ids.len()];
            for &id in &ids {
                keep[s.index_of(id)?] = false;
            }
            match s.world.as_mut() {
                Some(w) => w.retain_instances(&keep).map_err(|e| LucentError::new_err(format!("remove: {e}")))?,
                None => {
                    let sc = s.scene_mut();
                    let mut k = keep.iter();
                    sc.instances.retain(|_| k.next().copied().unwrap_or(true));
                }
            }
            let mut k = keep.iter();
            s.ids.retain(|_| k.next().copied().unwrap_or(true));
            let mut k = keep.iter();
            s.inst_geom.retain(|_| k.next().copied().unwrap_or(true));
            Ok(())
        })
    }

    /// Poses an animated scene (glTF animations) at time ``t`` seconds.
    fn set_time(&self, py: Python<'_>, t: f64) -> PyResult<()> {
        if !t.is_finite() {
            return Err(PyValueError::new_err(format!("t: {t} is not a finite time")));
        }
        self.edit(py, "set_time", move |s| {
            let w = s.build().map_err(LucentError::new_err)?;
            w.set_time(t as f32).map(|_| ()).map_err(|e| LucentError::new_err(format!("set_time: {e}")))
        })
    }

    /// Builds the acceleration structure now (queries build it on first use).
    fn commit(&self, py: Python<'_>) -> PyResult<()> {
        self.with_world(py, "commit", |_, _| ())
    }

    /// The geometry id instance ``instance`` draws.
    fn geometry_of(&self, instance: i64) -> PyResult<i64> {
        let s = self.read();
        let i = s.index_of(instance)?;
        Ok(s.inst_geom[i])
    }

    /// A mesh geometry's vertices (V, 3) and faces (F, 3) as stored (vertices in float64
    /// when they were given so).
    fn mesh_arrays<'py>(&self, py: Python<'py>, geometry: i64) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let s = self.read();
        let g = s.geom(geometry)?;
        let Geom::Mesh(m) = g.geom else {
            return Err(PyValueError::new_err(format!("geometry {geometry}: an analytic shape, not a mesh")));
        };
        let Some(mesh) = s.scene().meshes.get(m as usize) else {
            return Err(PyIndexError::new_err(format!("geometry {geometry}: no mesh")));
        };
        let faces: Vec<i32> = mesh.indices.iter().flat_map(|t| t.map(|i| i as i32)).collect();
        let f = to_numpy(py, faces, &[mesh.indices.len(), 3])?.into_any();
        let n = mesh.positions.len();
        let v = if g.shift == DVec3::ZERO {
            to_numpy(py, mesh.positions.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>(), &[n, 3])?.into_any()
        } else {
            to_numpy(py, mesh.positions.iter().flat_map(|p| (p.as_dvec3() + g.shift).to_array()).collect::<Vec<f64>>(), &[n, 3])?.into_any()
        };
        Ok((v, f))
    }

    /// Adds a light for rendering: ``'point'`` (``position``), ``'directional'``
    /// (``direction`` the light travels along) or ``'spot'`` (``position``,
    /// ``direction``, ``angle`` in degrees), of RGB ``color`` (intensity).
    #[pyo3(signature = (kind, *, color = (1.0, 1.0, 1.0), position = None, direction = None, angle = 30.0))]
    fn add_light(
        &self,
        py: Python<'_>,
        kind: &str,
        color: (f32, f32, f32),
        position: Option<[f64; 3]>,
        direction: Option<[f32; 3]>,
        angle: f32,
    ) -> PyResult<()> {
        use lucent_scene::LightKind;
        let offset = self.read().offset;
        let pos = || -> PyResult<Vec3> {
            let p = DVec3::from(position.ok_or_else(|| PyValueError::new_err(format!("a {kind} light needs position=")))?);
            Ok((p - offset).as_vec3())
        };
        let dir = || -> PyResult<Vec3> {
            let d = Vec3::from(direction.ok_or_else(|| PyValueError::new_err(format!("a {kind} light needs direction=")))?);
            d.try_normalize().ok_or_else(|| PyValueError::new_err("direction: not a finite, non-zero vector"))
        };
        let lk = match kind {
            "point" => LightKind::Point { position: pos()? },
            "directional" => LightKind::Directional { direction: dir()? },
            "spot" => {
                let half = (angle * 0.5).to_radians();
                LightKind::Spot { position: pos()?, direction: dir()?, inner: half * 0.8, outer: half }
            }
            k => return Err(PyValueError::new_err(format!("kind: {k:?} is not one of 'point', 'directional', 'spot'"))),
        };
        let c = Vec3::from(color);
        if !c.is_finite() {
            return Err(PyValueError::new_err("color: not finite"));
        }
        let inverse_square = kind != "directional";
        self.edit(py, "add_light", move |s| {
            s.scene_mut().lights.push(lucent_scene::Light { kind: lk, color: c, inverse_square });
            Ok(())
        })
    }

    /// World bounds (2, 3): the lowest and highest corner, float64.
    #[getter]
    fn bounds<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
        let s = self.read();
        let (lo, hi) = s.scene().bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let (lo, hi) = (lo.as_dvec3() + s.offset, hi.as_dvec3() + s.offset);
        to_numpy(py, vec![lo.x, lo.y, lo.z, hi.x, hi.y, hi.z], &[2, 3])
    }

    /// Number of instances.
    #[getter]
    fn num_instances(&self) -> usize {
        self.read().ids.len()
    }

    /// Number of geometries (meshes and shapes).
    #[getter]
    fn num_geometries(&self) -> usize {
        self.read().geoms.len()
    }

    /// Number of triangles over all meshes (each counted once, however often instanced).
    #[getter]
    fn num_triangles(&self) -> usize {
        self.read().scene().meshes.iter().map(|m| m.indices.len()).sum()
    }

    /// The instance ids in order (K,).
    #[getter]
    fn instance_ids<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArrayDyn<i64>>> {
        let ids = self.read().ids.clone();
        let n = ids.len();
        to_numpy(py, ids, &[n])
    }

    /// The instances' world-from-object maps (K, 4, 4), float64, in ``instance_ids`` order.
    #[getter]
    fn transforms<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
        let s = self.read();
        let mut v = Vec::with_capacity(s.ids.len() * 16);
        for (i, inst) in s.scene().instances.iter().enumerate() {
            let g = s.geoms.get(s.inst_geom[i] as usize).copied().unwrap_or(GeomEntry { geom: inst.geom, shift: DVec3::ZERO });
            let a = inst.world_from_object;
            let l = glam::DMat3::from_cols(a.matrix3.x_axis.as_dvec3(), a.matrix3.y_axis.as_dvec3(), a.matrix3.z_axis.as_dvec3());
            let t = DVec3::from(a.translation.as_dvec3()) + s.offset - l * g.shift;
            for r in 0..3 {
                v.extend([l.x_axis[r], l.y_axis[r], l.z_axis[r], t[r]]);
            }
            v.extend([0.0, 0.0, 0.0, 1.0]);
        }
        let n = v.len() / 16;
        to_numpy(py, v, &[n, 4, 4])
    }

    /// The camera the file describes, if any.
    #[getter]
    fn camera(&self) -> Option<crate::camera::Camera> {
        let s = self.read();
        let desc = s.scene().camera?;
        let (w, h) = s.scene().hints.map_or((640, 480), |h| (h.width, h.height));
        Some(crate::camera::Camera::from_desc(&desc, w, h, s.offset))
    }

    /// The camera ``render`` uses when given none: the file's, else one framing the
    /// scene, at the file's image size or ``width`` x ``height``.
    #[pyo3(signature = (width = None, height = None))]
    fn default_camera(&self, width: Option<u32>, height: Option<u32>) -> PyResult<crate::camera::Camera> {
        let s = self.read();
        let desc =
            lucent_render::setup::camera_desc(s.scene(), None, false).map_err(|e| LucentError::new_err(format!("default_camera: {e}")))?;
        let hints = s.scene().hints;
        let (w, h) = match (width, height, hints) {
            (Some(w), Some(h), _) => (w, h),
            (None, None, Some(hh)) => (hh.width, hh.height),
            (None, None, None) => (1024, 768),
            _ => return Err(PyValueError::new_err("give both width and height, or neither")),
        };
        let mut cam = crate::camera::Camera::from_desc(&desc, w, h, s.offset);
        if let Some(hh) = hints {
            cam = cam.with_hints(hh.clip, hh.lens);
        }
        Ok(cam)
    }

    fn __repr__(&self) -> String {
        let s = self.read();
        format!(
            "Scene({} instances, {} geometries, {} triangles, {})",
            s.ids.len(),
            s.geoms.len(),
            s.scene().meshes.iter().map(|m| m.indices.len()).sum::<usize>(),
            if s.world().is_some() { "built" } else { "not built yet" }
        )
    }
}

fn with_44(lead: &[usize]) -> Vec<usize> {
    let mut s = lead.to_vec();
    s.extend([4, 4]);
    s
}

/// Reads a scene file: OBJ (``.obj``, ``.obj.gz``), PLY, glTF (``.gltf``, ``.glb``) or
/// Mitsuba XML (``.xml``; ``defines`` are its ``$name`` parameters, as ``mitsuba -D``).
#[pyfunction]
#[pyo3(signature = (path, *, strict = false, quality = "high", triangle_test = "unit", **defines))]
pub fn load(
    py: Python<'_>,
    path: PathBuf,
    strict: bool,
    quality: &str,
    triangle_test: &str,
    defines: Option<&Bound<'_, PyDict>>,
) -> PyResult<Scene> {
    let opts = mesh_options(quality, triangle_test)?;
    let mut defs = Vec::new();
    if let Some(d) = defines {
        for (k, v) in d.iter() {
            defs.push((k.extract::<String>()?, v.str()?.extract::<String>()?));
        }
    }
    if !path.exists() {
        return Err(PyFileNotFoundError::new_err(format!("{}: no such file", path.display())));
    }
    let is_xml = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("xml"));
    if !defs.is_empty() && !is_xml {
        return Err(PyValueError::new_err(format!("{}: parameters ({}) only apply to Mitsuba XML scenes", path.display(), defs.len())));
    }
    let scene = py.detach(|| {
        guard("load", || {
            if is_xml {
                lucent_scene::load_mitsuba_with(&path, &defs)
            } else {
                lucent_scene::load_with(&path, &lucent_scene::LoadOptions { strict })
            }
        })
    })?;
    let scene = scene.map_err(|e| match &e {
        lucent_scene::ImportError::Io { cause, .. } if cause.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(e.to_string())
        }
        _ => LucentError::new_err(e.to_string()),
    })?;
    Ok(Scene::from_scene(scene, opts))
}

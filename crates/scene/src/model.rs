//! The scene as plain data: meshes, instances, materials, textures, lights, camera.

use crate::bsdf::{phong_to_alpha, Alpha, Bsdf, ColorTex, NormalMap, Sides};
use crate::camera::CameraDesc;
use crate::texture::Texture;
use glam::{Affine2, Affine3A, Vec2, Vec3};

/// A per-corner attribute: values, and per-triangle indices into them (`None`: the
/// triangle's position indices are used).
#[derive(Clone, Debug, Default)]
pub struct Attr<T> {
    /// Values.
    pub values: Vec<T>,
    /// Index triples per triangle, when they differ from the position indices.
    pub indices: Option<Vec<[u32; 3]>>,
}

impl<T: Copy> Attr<T> {
    /// The three values of triangle `tri`, if the attribute is present.
    #[must_use]
    pub fn corners(&self, tri: usize, pos_idx: &[u32; 3]) -> Option<[T; 3]> {
        if self.values.is_empty() {
            return None;
        }
        let idx = match &self.indices {
            Some(v) => v.get(tri)?,
            None => pos_idx,
        };
        Some([*self.values.get(idx[0] as usize)?, *self.values.get(idx[1] as usize)?, *self.values.get(idx[2] as usize)?])
    }
}

/// A triangle mesh in object space.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Name (from the file, for messages).
    pub name: String,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles (indices into `positions`), in file order.
    pub indices: Vec<[u32; 3]>,
    /// Shading normals (may be empty).
    pub normals: Attr<Vec3>,
    /// Texture coordinates, v = 0 at the bottom of the image (may be empty).
    pub uvs: Attr<Vec2>,
    /// Material per triangle (index into `Scene::materials`).
    pub material: Vec<u32>,
}

/// The kind of an analytic shape, in its canonical form (see `lucent_accel::Shape`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeKind {
    /// Unit sphere.
    Sphere,
    /// Infinite cylinder x²+y²=1 along z.
    Cylinder,
    /// Cylinder x²+y² ≤ 1, z in [-1, 1], capped.
    CappedCylinder,
    /// Infinite double cone x²+y² = z².
    Cone,
    /// Cone with apex at the origin, z in [0, 1], capped at z = 1.
    CappedCone,
    /// Box [-1, 1]³.
    Box,
    /// Unit disk in z = 0.
    Disk,
    /// Cylinder x²+y² = 1, z in [-1, 1], open at both ends (Mitsuba's `cylinder`).
    Tube,
}

/// What an instance draws.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Geom {
    /// Mesh `i` of `Scene::meshes` (materials per triangle).
    Mesh(u32),
    /// A shape with one material.
    Shape {
        /// Kind.
        kind: ShapeKind,
        /// Material index.
        material: u32,
    },
}

/// A placed geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// What is drawn.
    pub geom: Geom,
    /// Object to world.
    pub world_from_object: Affine3A,
}

/// A Phong-style material with the extra terms a Whitted tracer needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name.
    pub name: String,
    /// Ambient reflectance (MTL `Ka`).
    pub ambient: Vec3,
    /// Diffuse reflectance (MTL `Kd`, glTF base colour).
    pub diffuse: Vec3,
    /// Diffuse texture (multiplies `diffuse`).
    pub diffuse_tex: Option<u32>,
    /// Specular reflectance of highlights (MTL `Ks`).
    pub specular: Vec3,
    /// Phong exponent (MTL `Ns`).
    pub shininess: f32,
    /// Emitted radiance (MTL `Ke`).
    pub emission: Vec3,
    /// Mirror reflectance (MTL `illum` 3/5/7: `Ks`; glTF metallic).
    pub reflect: Vec3,
    /// Transmittance (MTL `1 - d` or `Tf`; glTF transmission).
    pub transmit: Vec3,
    /// Index of refraction.
    pub ior: f32,
    /// Reflectance follows Fresnel (dielectrics).
    pub fresnel: bool,
    /// The physically based model the path tracer uses, as the scene file gave it; `None`
    /// reads the Phong terms above ([`Bsdf::from_phong`]). See [`crate::bsdf`] for how
    /// each importer fills it.
    pub bsdf: Option<Bsdf>,
    /// How the back of the surface scatters (path tracer).
    pub sides: Sides,
    /// Texture multiplying `emission` (glTF `emissiveTexture`).
    pub emission_tex: Option<u32>,
    /// Tangent-space normal map.
    pub normal_map: Option<NormalMap>,
    /// Which parts of the surface exist.
    pub alpha: Alpha,
}

impl Material {
    /// Whether shading the material reads texture coordinates: a texture of its own
    /// (diffuse, emission, normal map) or one in its BSDF or its back's.
    #[must_use]
    pub fn uses_uv(&self) -> bool {
        self.diffuse_tex.is_some()
            || self.emission_tex.is_some()
            || self.normal_map.is_some()
            || self.bsdf.as_ref().is_some_and(Bsdf::uses_uv)
            || matches!(&self.sides, Sides::Back(b) if b.uses_uv())
    }

    /// The BSDF the path tracer uses: [`Material::bsdf`], or the Phong terms read as one.
    #[must_use]
    pub fn bsdf(&self) -> std::borrow::Cow<'_, Bsdf> {
        match &self.bsdf {
            Some(b) => std::borrow::Cow::Borrowed(b),
            None => std::borrow::Cow::Owned(Bsdf::from_phong(self)),
        }
    }

    /// A material with a physically based BSDF, its Whitted terms read from it
    /// ([`Bsdf::whitted_terms`]).
    #[must_use]
    pub fn physical(name: &str, bsdf: Bsdf) -> Self {
        let t = bsdf.whitted_terms();
        Self {
            name: name.into(),
            diffuse: t.diffuse,
            diffuse_tex: t.diffuse_tex,
            specular: t.specular,
            shininess: t.shininess,
            reflect: t.reflect,
            transmit: t.transmit,
            ior: t.ior,
            fresnel: t.fresnel,
            bsdf: Some(bsdf),
            ..Self::default()
        }
    }
}

impl Default for Material {
    fn default() -> Self {
        Self {
            name: "default".into(),
            ambient: Vec3::ZERO,
            diffuse: Vec3::splat(0.7),
            diffuse_tex: None,
            specular: Vec3::ZERO,
            shininess: 32.0,
            emission: Vec3::ZERO,
            reflect: Vec3::ZERO,
            transmit: Vec3::ZERO,
            ior: 1.5,
            fresnel: false,
            bsdf: None,
            sides: Sides::Both,
            emission_tex: None,
            normal_map: None,
            alpha: Alpha::Opaque,
        }
    }
}

/// A light's shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// At a point, in every direction.
    Point {
        /// Position.
        position: Vec3,
    },
    /// From infinitely far, along `direction` (the way the light travels).
    Directional {
        /// Direction of travel.
        direction: Vec3,
    },
    /// A cone from a point.
    Spot {
        /// Position.
        position: Vec3,
        /// Axis direction (the way the light travels).
        direction: Vec3,
        /// Full-intensity half angle (radians).
        inner: f32,
        /// Zero-intensity half angle (radians).
        outer: f32,
    },
}

/// A light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Shape.
    pub kind: LightKind,
    /// Linear RGB colour times intensity.
    pub color: Vec3,
    /// Intensity falls with the squared distance.
    pub inverse_square: bool,
}

/// Everything a renderer needs.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Meshes.
    pub meshes: Vec<Mesh>,
    /// Instances.
    pub instances: Vec<Instance>,
    /// Materials (index 0 exists whenever anything refers to materials).
    pub materials: Vec<Material>,
    /// Textures.
    pub textures: Vec<Texture>,
    /// Lights.
    pub lights: Vec<Light>,
    /// The scene's own camera.
    pub camera: Option<CameraDesc>,
    /// Ambient light colour.
    pub ambient: Vec3,
    /// Background colour of rays that escape.
    pub background: Vec3,
    /// Animation (glTF): what moves, and the nodes instances, camera and lights hang from.
    pub animation: Option<std::sync::Arc<crate::anim::SceneAnimation>>,
    /// Light from infinitely far in every direction (Mitsuba `constant`, `envmap`), for
    /// the path tracer; Whitted shows `background` where rays escape.
    pub environment: Option<Environment>,
    /// How the file says to render it (Mitsuba's film, sampler, sensor and integrator),
    /// unless the command line says otherwise.
    pub hints: Option<RenderHints>,
    /// The channels the file's film writes beyond R, G, B (Mitsuba's `aov` integrator and
    /// `pixel_format`), for an EXR output; `None`: the image alone.
    pub outputs: Option<Outputs>,
}

/// The channels of a Mitsuba film's EXR beyond R, G, B: the film's alpha, the image of the
/// integrator an `aov` integrator wraps (again, under its name, with alpha) and the `aov`
/// integrator's layers, in Mitsuba's order and names.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outputs {
    /// The film's `pixel_format` has alpha: `A` after `R`, `G`, `B`.
    pub alpha: bool,
    /// The name of the integrator an `aov` integrator wraps: its image as `name.R`,
    /// `.G`, `.B`, `.A`.
    pub inner: Option<String>,
    /// The layers: name and kind, in the file's order.
    pub aovs: Vec<(String, AovKind)>,
}

/// A layer of Mitsuba's `aov` integrator: a value of the first surface each camera ray
/// meets (zero where it meets none), averaged over a pixel's samples as the image is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AovKind {
    /// The diffuse reflectance (`.R`, `.G`, `.B`).
    Albedo,
    /// Distance along the ray (`.T`).
    Depth,
    /// World position (`.X`, `.Y`, `.Z`).
    Position,
    /// Texture coordinates (`.U`, `.V`).
    Uv,
    /// Geometric normal, as the surface is wound (`.X`, `.Y`, `.Z`).
    GeoNormal,
    /// Shading normal (`.X`, `.Y`, `.Z`).
    ShNormal,
    /// ∂p/∂u (`.X`, `.Y`, `.Z`).
    DpDu,
    /// ∂p/∂v (`.X`, `.Y`, `.Z`).
    DpDv,
    /// The primitive's index in its shape (`.I`).
    PrimIndex,
    /// The shape's index in the file's order, from 1 (`.I`; 0 where nothing is met).
    ShapeIndex,
    /// The fraction of the pixel's samples that meet a surface (or the environment):
    /// Mitsuba's alpha.
    Alpha,
}

impl AovKind {
    /// Every kind, in a fixed order (their numbers on the wire).
    pub const ALL: [AovKind; 11] = [
        Self::Albedo,
        Self::Depth,
        Self::Position,
        Self::Uv,
        Self::GeoNormal,
        Self::ShNormal,
        Self::DpDu,
        Self::DpDv,
        Self::PrimIndex,
        Self::ShapeIndex,
        Self::Alpha,
    ];

    /// The suffixes of its channels (Mitsuba's).
    #[must_use]
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            Self::Albedo => &["R", "G", "B"],
            Self::Depth => &["T"],
            Self::Uv => &["U", "V"],
            Self::Position | Self::GeoNormal | Self::ShNormal | Self::DpDu | Self::DpDv => &["X", "Y", "Z"],
            Self::PrimIndex | Self::ShapeIndex => &["I"],
            Self::Alpha => &["A"],
        }
    }

    /// The kind Mitsuba names `name` (`None`: not one lucent writes).
    #[must_use]
    pub fn named(name: &str) -> Option<Self> {
        Some(match name {
            "albedo" => Self::Albedo,
            "depth" => Self::Depth,
            "position" => Self::Position,
            "uv" => Self::Uv,
            "geo_normal" => Self::GeoNormal,
            "sh_normal" => Self::ShNormal,
            "dp_du" => Self::DpDu,
            "dp_dv" => Self::DpDv,
            "prim_index" => Self::PrimIndex,
            "shape_index" => Self::ShapeIndex,
            _ => return None,
        })
    }
}

/// How a scene file says it should be rendered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderHints {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Most path segments (`None`: unlimited).
    pub max_depth: Option<u32>,
    /// Depth from which Russian roulette may end paths.
    pub rr_depth: u32,
    /// Emitters seen directly from the camera show the background.
    pub hide_emitters: bool,
    /// A thin lens: aperture radius and focus distance.
    pub lens: Option<(f32, f32)>,
    /// Near and far clipping depths.
    pub clip: (f32, f32),
    /// The film's reconstruction filter.
    pub filter: PixelFilter,
    /// The window of the film that is rendered and written, as x, y, width, height in
    /// pixels (Mitsuba's `hdrfilm` `crop_offset_x`, `crop_offset_y`, `crop_width`,
    /// `crop_height`): the camera sees the whole film, the image is the window. `None`:
    /// the whole film.
    pub crop: Option<[u32; 4]>,
    /// Which strategies estimate the light at a surface (Mitsuba's `direct` integrator's
    /// `emitter_samples` and `bsdf_samples`, each read as present or not).
    pub strategies: Strategies,
}

/// The strategies a path tracer estimates the light at a surface with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Strategies {
    /// Light sampling and BSDF sampling, weighed by multiple importance sampling.
    #[default]
    Both,
    /// Light sampling only.
    Emitters,
    /// BSDF sampling only.
    Bsdf,
}

/// How a pixel weighs the image around it (the film's reconstruction filter, separable in
/// x and y; Mitsuba's `rfilter` plugins of the same names and defaults).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum PixelFilter {
    /// The pixel's own square (radius 0.5): every sample in it weighs the same.
    #[default]
    Box,
    /// `max(0, 1 − |x|/radius)` (Mitsuba's default radius: 1 pixel).
    Tent {
        /// Radius in pixels.
        radius: f32,
    },
    /// `exp(−x²/2σ²) − exp(−8)` out to 4σ (Mitsuba's default filter, σ = 0.5 pixel).
    Gaussian {
        /// Standard deviation σ in pixels.
        stddev: f32,
    },
    /// Mitchell and Netravali's cubic ("Reconstruction filters in computer graphics",
    /// 1988) of radius 2 (Mitsuba's `mitchell`, B = C = 1/3; its `catmullrom` is B = 0,
    /// C = 1/2). Negative lobes: samples carry signed weights.
    Mitchell {
        /// B.
        b: f32,
        /// C.
        c: f32,
    },
    /// The Lanczos-windowed sinc, `sinc(x) sinc(x/lobes)` out to `lobes` pixels (Mitsuba's
    /// `lanczos`, 3 lobes). Negative lobes: samples carry signed weights.
    Lanczos {
        /// Lobes (the radius in pixels).
        lobes: f32,
    },
}

impl PixelFilter {
    /// How far from a pixel's centre its samples reach, in pixels.
    #[must_use]
    pub fn radius(self) -> f32 {
        match self {
            Self::Box => 0.5,
            Self::Tent { radius } => radius,
            Self::Gaussian { stddev } => 4.0 * stddev,
            Self::Mitchell { .. } => 2.0,
            Self::Lanczos { lobes } => lobes,
        }
    }

    /// The filter's weight at `x` pixels from the centre (along one axis).
    #[must_use]
    pub fn eval(self, x: f32) -> f32 {
        let x = x.abs();
        if x > self.radius() {
            return 0.0;
        }
        match self {
            Self::Box => 1.0,
            Self::Tent { radius } => 1.0 - x / radius,
            Self::Gaussian { stddev } => ((-0.5 * x * x / (stddev * stddev)).exp() - (-8.0f32).exp()).max(0.0),
            Self::Mitchell { b, c } => {
                let (x2, x3) = (x * x, x * x * x);
                let v = if x < 1.0 {
                    (12.0 - 9.0 * b - 6.0 * c) * x3 + (-18.0 + 12.0 * b + 6.0 * c) * x2 + (6.0 - 2.0 * b)
                } else {
                    (-b - 6.0 * c) * x3 + (6.0 * b + 30.0 * c) * x2 + (-12.0 * b - 48.0 * c) * x + (8.0 * b + 24.0 * c)
                };
                v / 6.0
            }
            Self::Lanczos { lobes } => {
                if x < 1e-6 {
                    return 1.0;
                }
                let (a, b) = (std::f32::consts::PI * x, std::f32::consts::PI * x / lobes);
                a.sin() * b.sin() / (a * b)
            }
        }
    }

    /// Whether the filter has negative lobes (its samples carry signed weights).
    #[must_use]
    pub fn signed(self) -> bool {
        matches!(self, Self::Mitchell { .. } | Self::Lanczos { .. })
    }
}

/// A linear RGB image of floats (environment maps).
#[derive(Clone, Debug, PartialEq)]
pub struct HdrImage {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Texels, row 0 at the top.
    pub texels: Vec<Vec3>,
}

/// Light arriving from infinitely far: `scale` times the image's texel (an equirectangular
/// map, as Mitsuba's `envmap`: direction `d` in the map's frame `to_world⁻¹ d` looks up
/// u = atan2(d.x, −d.z) / 2π, v = acos(d.y) / π, v = 0 at the top row), or `scale` alone
/// without an image (Mitsuba's `constant`).
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// Radiance factor.
    pub scale: Vec3,
    /// The map, if any.
    pub image: Option<std::sync::Arc<HdrImage>>,
    /// The map's frame.
    pub to_world: Affine3A,
}

/// Ambient light for formats that do not say (OBJ, PLY, plain glTF): a modest fill so
/// faces turned away from every light are not pure black.
pub const DEFAULT_AMBIENT: Vec3 = Vec3::splat(0.1);

/// Counts for `lucent info`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SceneStats {
    /// Triangles over unique meshes.
    pub triangles: usize,
    /// Vertices over unique meshes.
    pub vertices: usize,
    /// Meshes.
    pub meshes: usize,
    /// Instances (mesh and shape).
    pub instances: usize,
    /// Triangles counted once per instance.
    pub instanced_triangles: usize,
    /// Materials.
    pub materials: usize,
    /// Textures.
    pub textures: usize,
    /// Lights.
    pub lights: usize,
}

impl Scene {
    /// Counts.
    #[must_use]
    pub fn stats(&self) -> SceneStats {
        SceneStats {
            triangles: self.meshes.iter().map(|m| m.indices.len()).sum(),
            vertices: self.meshes.iter().map(|m| m.positions.len()).sum(),
            meshes: self.meshes.len(),
            instances: self.instances.len(),
            instanced_triangles: self
                .instances
                .iter()
                .map(|i| if let Geom::Mesh(m) = i.geom { self.meshes.get(m as usize).map_or(0, |m| m.indices.len()) } else { 0 })
                .sum(),
            materials: self.materials.len(),
            textures: self.textures.len(),
            lights: self.lights.len(),
        }
    }

    /// World bounds of all mesh instances (shapes of finite size included); `None` when empty.
    #[must_use]
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut lo = Vec3::INFINITY;
        let mut hi = Vec3::NEG_INFINITY;
        // Exact (every vertex transformed) unless instancing multiplies the work: then each
        // instance contributes its mesh's box, transformed (a conservative bound).
        let work: usize = self
            .instances
            .iter()
            .map(|i| if let Geom::Mesh(m) = i.geom { self.meshes.get(m as usize).map_or(0, |x| x.positions.len()) } else { 8 })
            .sum();
        let boxes: Vec<Option<(Vec3, Vec3)>> = if work > 4_000_000 {
            self.meshes
                .iter()
                .map(|m| {
                    let f = m.positions.iter().filter(|p| p.is_finite());
                    let (a, b) = f.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
                    (a.cmple(b).all()).then_some((a, b))
                })
                .collect()
        } else {
            Vec::new()
        };
        for inst in &self.instances {
            match inst.geom {
                Geom::Mesh(m) if !boxes.is_empty() => {
                    let Some(Some((a, b))) = boxes.get(m as usize) else { continue };
                    for c in 0..8 {
                        let p = Vec3::new(
                            if c & 1 == 0 { a.x } else { b.x },
                            if c & 2 == 0 { a.y } else { b.y },
                            if c & 4 == 0 { a.z } else { b.z },
                        );
                        let w = inst.world_from_object.transform_point3(p);
                        if w.is_finite() {
                            lo = lo.min(w);
                            hi = hi.max(w);
                        }
                    }
                }
                Geom::Mesh(m) => {
                    let Some(mesh) = self.meshes.get(m as usize) else {
                        continue;
                    };
                    for p in &mesh.positions {
                        let w = inst.world_from_object.transform_point3(*p);
                        if w.is_finite() {
                            lo = lo.min(w);
                            hi = hi.max(w);
                        }
                    }
                }
                Geom::Shape { kind, .. } => {
                    if matches!(kind, ShapeKind::Cylinder | ShapeKind::Cone) {
                        continue;
                    }
                    for c in 0..8 {
                        let p = Vec3::new(
                            if c & 1 == 0 { -1.0 } else { 1.0 },
                            if c & 2 == 0 { -1.0 } else { 1.0 },
                            if c & 4 == 0 { -1.0 } else { 1.0 },
                        );
                        let w = inst.world_from_object.transform_point3(p);
                        lo = lo.min(w);
                        hi = hi.max(w);
                    }
                }
            }
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// Adds a mesh with an identity instance; returns the mesh index.
    pub fn add_mesh(&mut self, mesh: Mesh) -> u32 {
        let id = self.meshes.len() as u32;
        self.meshes.push(mesh);
        self.instances.push(Instance { geom: Geom::Mesh(id), world_from_object: Affine3A::IDENTITY });
        id
    }

    /// Bakes the meshes that one instance each draws into world space and merges them into
    /// one mesh, drawn by one identity instance, as Mitsuba gives Embree its shapes: a ray
    /// then walks one tree instead of entering an instance per object (the Cornell box's
    /// eight walls and boxes enclose every ray; the bunny and its floor traced the same
    /// rays 1.25 times faster merged). Where some meshes have normals or texture
    /// coordinates and others not, the others get what a renderer uses without them: each
    /// face's own normal at its three corners, and the corners' barycentric coordinates
    /// ((0, 0), (1, 0), (0, 1)) as texture coordinates. A scene that animates, and
    /// meshes drawn by several instances, are left as they are; meshes no instance draws
    /// stay too. Normals follow the inverse transpose; a mirroring transform swaps two
    /// corners of each triangle, so faces keep their side. Returns how many instances were
    /// merged away.
    pub fn merge_single_use_meshes(&mut self) -> usize {
        if self.animation.is_some() {
            return 0;
        }
        let mut uses = vec![0u32; self.meshes.len()];
        for i in &self.instances {
            if let Geom::Mesh(m) = i.geom {
                if let Some(u) = uses.get_mut(m as usize) {
                    *u += 1;
                }
            }
        }
        // Instances to merge.
        let group: Vec<usize> = (0..self.instances.len())
            .filter(|&k| {
                let i = &self.instances[k];
                matches!(i.geom, Geom::Mesh(m) if uses.get(m as usize) == Some(&1)) && i.world_from_object.is_finite()
            })
            .collect();
        if group.len() < 2 {
            return 0;
        }
        let mut removed = vec![false; self.instances.len()];
        let mut taken = vec![false; self.meshes.len()];
        let mut merged = 0;
        let mut out = Mesh { name: format!("{} merged meshes", group.len()), ..Mesh::default() };
        let (mut n_idx, mut uv_idx) = (Vec::new(), Vec::new());
        let mesh_of = |k: usize| match self.instances[k].geom {
            Geom::Mesh(m) => self.meshes.get(m as usize),
            Geom::Shape { .. } => None,
        };
        let with_normals = group.iter().any(|&k| mesh_of(k).is_some_and(|m| !m.normals.values.is_empty()));
        let with_uvs = group.iter().any(|&k| mesh_of(k).is_some_and(|m| !m.uvs.values.is_empty()));
        // (The barycentric corners, for meshes without texture coordinates.)
        let bary = if with_uvs {
            out.uvs.values.extend([Vec2::ZERO, Vec2::X, Vec2::Y]);
            0
        } else {
            u32::MAX
        };
        for &k in &group {
            let inst = &self.instances[k];
            let Geom::Mesh(m) = inst.geom else { continue };
            let mesh = std::mem::take(&mut self.meshes[m as usize]);
            taken[m as usize] = true;
            let t = inst.world_from_object;
            let normal_m = glam::Mat3::from(t.matrix3).inverse().transpose();
            let mirror = t.matrix3.determinant() < 0.0;
            let order = |c: [u32; 3]| if mirror { [c[0], c[2], c[1]] } else { c };
            let (p0, n0, u0) = (out.positions.len() as u32, out.normals.values.len() as u32, out.uvs.values.len() as u32);
            out.positions.extend(mesh.positions.iter().map(|&p| t.transform_point3(p)));
            out.normals.values.extend(mesh.normals.values.iter().map(|&n| (normal_m * n).normalize_or_zero()));
            out.uvs.values.extend(&mesh.uvs.values);
            for (tri, c) in mesh.indices.iter().enumerate() {
                let corners = order(c.map(|i| i + p0));
                out.indices.push(corners);
                if !mesh.normals.values.is_empty() {
                    let ni = mesh.normals.indices.as_ref().and_then(|v| v.get(tri)).unwrap_or(c);
                    n_idx.push(order(ni.map(|i| i + n0)));
                } else if with_normals {
                    // The face's own normal, in world space, on the side its (ordered)
                    // corners turn to.
                    let p = corners.map(|i| out.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
                    let k = out.normals.values.len() as u32;
                    out.normals.values.push((p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero());
                    n_idx.push([k, k, k]);
                }
                if !mesh.uvs.values.is_empty() {
                    let ui = mesh.uvs.indices.as_ref().and_then(|v| v.get(tri)).unwrap_or(c);
                    uv_idx.push(order(ui.map(|i| i + u0)));
                } else if with_uvs {
                    uv_idx.push(order([bary, bary + 1, bary + 2]));
                }
                out.material.push(mesh.material.get(tri).copied().unwrap_or(0));
            }
            removed[k] = true;
            merged += 1;
        }
        if !out.normals.values.is_empty() {
            out.normals.indices = Some(n_idx);
        }
        if !out.uvs.values.is_empty() {
            out.uvs.indices = Some(uv_idx);
        }
        merged -= 1;
        let id = self.meshes.len() as u32;
        self.meshes.push(out);
        self.instances.push(Instance { geom: Geom::Mesh(id), world_from_object: Affine3A::IDENTITY });
        removed.push(false);
        let mut k = 0;
        self.instances.retain(|_| {
            k += 1;
            !removed[k - 1]
        });
        // The merged meshes' old slots go; the others move up.
        taken.resize(self.meshes.len(), false);
        let mut new_index = Vec::with_capacity(self.meshes.len());
        let mut next = 0u32;
        for &t in &taken {
            new_index.push(next);
            next += u32::from(!t);
        }
        let mut k = 0;
        self.meshes.retain(|_| {
            k += 1;
            !taken[k - 1]
        });
        for i in &mut self.instances {
            if let Geom::Mesh(m) = &mut i.geom {
                *m = new_index[*m as usize];
            }
        }
        merged
    }
}

impl Bsdf {
    /// The BSDF of a material that has only Phong/Whitted terms (built-in and REND3R
    /// scenes, PLY), by the same reading as MTL: transmission makes a smooth dielectric of
    /// index `ior` (a thin sheet when `ior` ≤ 1); mirror reflection without a diffuse term
    /// a smooth conductor of reflectance `reflect`, with one a [`Bsdf::DiffuseGlossy`] of
    /// reflectance `reflect` and nearly no roughness (α = 10⁻³); otherwise the diffuse
    /// and specular terms as [`Bsdf::DiffuseGlossy`] with α from the exponent.
    #[must_use]
    pub fn from_phong(m: &Material) -> Self {
        let kd = match m.diffuse_tex {
            Some(tex) => ColorTex::Image { tex, scale: m.diffuse, to_uv: Affine2::IDENTITY },
            None => ColorTex::Const(m.diffuse),
        };
        if m.transmit.max_element() > 0.0 {
            return if m.ior > 1.0 {
                Self::Dielectric { eta: m.ior, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::Const(m.transmit), rough: None }
            } else {
                Self::ThinDielectric { eta: 1.5, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::Const(m.transmit) }
            };
        }
        if m.reflect.max_element() > 0.0 {
            if m.diffuse.max_element() <= 0.0 {
                return Self::Conductor { eta: Vec3::ZERO, k: Vec3::ONE, specular: ColorTex::Const(m.reflect), rough: None };
            }
            return Self::DiffuseGlossy { diffuse: kd, specular: m.reflect, alpha: 1e-3 };
        }
        if m.specular.max_element() > 0.0 {
            return Self::DiffuseGlossy { diffuse: kd, specular: m.specular, alpha: phong_to_alpha(m.shininess) };
        }
        Self::Diffuse { reflectance: kd }
    }
}

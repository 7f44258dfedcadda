"""lucent: ray queries on numpy arrays and rendering to numpy images.

Build a :class:`Scene` from arrays (``add_mesh``, ``add_shape``, ``add_spheres``,
``add_instances``) or read one with :func:`load` (OBJ, PLY, glTF, Mitsuba XML); ask it
about rays (``intersect``, ``occluded``, ``intersect_all``, ``count_hits``,
``trace_camera``); render it (:func:`render`, :class:`Renderer`). Every call releases the
GIL and runs on all cores (or ``threads=``); one scene may be queried from many Python
threads at once.

>>> import numpy as np, lucent
>>> scene = lucent.Scene()
>>> tri = scene.add_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
>>> hits = scene.intersect([0.2, 0.2, 1.0], [[0, 0, -1]])
>>> float(hits.t[0]), bool(hits.hit[0])
(1.0, True)
"""

from __future__ import annotations

import os
from typing import Any, Iterable, Optional, Sequence, Tuple, Union

import numpy as np

from . import _lucent
from ._lucent import Camera, LucentError, info, read_image, set_num_threads, write_image

__all__ = [
    "Scene",
    "Hits",
    "AllHits",
    "Camera",
    "Renderer",
    "LucentError",
    "load",
    "render",
    "denoise",
    "write_image",
    "read_image",
    "info",
    "set_num_threads",
]

__version__: str = _lucent.__version__

ArrayLike = Any

_ALL_FIELDS = ("t", "hit", "prim_id", "geom_id", "inst_id", "uv", "normal")


class Hits:
    """Closest hits of a batch of rays: one entry per ray, in the rays' leading shape.

    Fields (those asked for; ``None`` otherwise): ``t`` (float32, ``inf`` on a miss, in
    units of each direction's length), ``hit`` (bool), ``prim_id``, ``geom_id``,
    ``inst_id`` (int32, ``-1`` on a miss), ``uv`` (float32 (..., 2): barycentric weights of
    the triangle's vertices 1 and 2), ``normal`` (float32 (..., 3): unit geometric normal
    in world space, by the triangle's winding; zero on a miss), ``depth`` (``trace_camera``
    only: distance along the view axis).
    """

    __slots__ = ("_fields", "_origins", "_directions")

    def __init__(self, fields: dict, origins: Optional[np.ndarray] = None, directions: Optional[np.ndarray] = None):
        self._fields = fields
        self._origins = origins
        self._directions = directions

    def __getattr__(self, name: str) -> Any:
        if name in ("t", "hit", "prim_id", "geom_id", "inst_id", "uv", "normal", "depth"):
            return self._fields.get(name)
        raise AttributeError(name)

    @property
    def points(self) -> np.ndarray:
        """Hit points ``origin + t * direction`` in float64 (``nan`` on a miss)."""
        if self._directions is None or "t" not in self._fields:
            raise ValueError("points need the rays (intersect's hits) and the 't' field")
        t = np.where(np.isfinite(self._fields["t"]), self._fields["t"], np.nan).astype(np.float64)
        return np.asarray(self._origins, dtype=np.float64) + t[..., None] * np.asarray(self._directions, dtype=np.float64)

    def depth_along(self, camera: Camera) -> np.ndarray:
        """Distance of each hit along ``camera``'s view axis (z-depth), float32."""
        if self._directions is None or "t" not in self._fields:
            raise ValueError("depth needs the rays (intersect's hits) and the 't' field")
        f = np.asarray(camera.forward, dtype=np.float32)
        return (self._fields["t"] * (np.asarray(self._directions, dtype=np.float32) @ f)).astype(np.float32)

    def as_dict(self) -> dict:
        """The fields as a dict of arrays."""
        return dict(self._fields)

    def __repr__(self) -> str:
        t = self._fields.get("t")
        shape = None if t is None else t.shape
        return f"Hits(shape={shape}, fields={list(self._fields)})"


class AllHits:
    """Every hit of a batch of rays, flat and sorted by ``t`` within each ray.

    Ray ``i``'s hits are ``[splits[i]:splits[i + 1]]`` of ``t``, ``prim_id``, ``geom_id``,
    ``inst_id``, ``uv``; ``ray_index`` names the ray of each hit (rays numbered in the
    row-major order of their leading shape ``shape``).
    """

    __slots__ = ("ray_index", "splits", "t", "prim_id", "geom_id", "inst_id", "uv", "shape")

    def __init__(self, d: dict):
        self.ray_index: np.ndarray = d["ray_index"]
        self.splits: np.ndarray = d["splits"]
        self.t: np.ndarray = d["t"]
        self.prim_id: np.ndarray = d["prim_id"]
        self.geom_id: np.ndarray = d["geom_id"]
        self.inst_id: np.ndarray = d["inst_id"]
        self.uv: np.ndarray = d["uv"]
        self.shape: Tuple[int, ...] = tuple(d["shape"])

    def counts(self) -> np.ndarray:
        """Hits per ray, in the rays' leading shape (int64)."""
        return np.diff(self.splits).reshape(self.shape)

    def of(self, i: int) -> dict:
        """The hits of ray ``i`` (flat index) as a dict of arrays."""
        a, b = int(self.splits[i]), int(self.splits[i + 1])
        return {"t": self.t[a:b], "prim_id": self.prim_id[a:b], "geom_id": self.geom_id[a:b], "inst_id": self.inst_id[a:b], "uv": self.uv[a:b]}

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def __repr__(self) -> str:
        return f"AllHits({len(self)} hits over {self.splits.shape[0] - 1} rays)"


def _names(fields: Optional[Iterable[str]]) -> Optional[list]:
    if fields is None:
        return None
    if isinstance(fields, str):
        return [fields]
    return list(fields)


class Scene:
    """A scene for ray queries and rendering.

    ``quality``: ``'high'`` (default: SAH and tree optimisation), ``'sah'`` (fastest build)
    or ``'spatial'`` (spatial splits, for scenes of long thin triangles).
    ``triangle_test``: ``'unit'`` (lucent's unit-triangle test, fastest) or
    ``'watertight'`` (no ray slips between triangles that share an edge: use it for
    inside/outside tests by counting crossings, where a ray exactly through an edge of the
    unit test can pass between the two triangles).
    """

    __slots__ = ("_s",)

    def __init__(self, *, quality: str = "high", triangle_test: str = "unit", _native: Any = None):
        self._s = _native if _native is not None else _lucent.Scene(quality=quality, triangle_test=triangle_test)

    # building -------------------------------------------------------------------------
    def add_mesh(
        self,
        vertices: ArrayLike,
        faces: ArrayLike,
        *,
        transform: Optional[ArrayLike] = None,
        normals: Optional[ArrayLike] = None,
        uvs: Optional[ArrayLike] = None,
        material: Optional[dict] = None,
        name: Optional[str] = None,
    ) -> int:
        """Adds a triangle mesh, ``vertices`` (V, 3) and ``faces`` (F, 3), and one instance
        of it placed by ``transform`` (4, 4, world from object); returns the instance id.
        float64 vertices are re-centred in float64 before the conversion to float32.
        ``material``: a dict of ``diffuse``, ``specular``, ``shininess``, ``emission``,
        ``reflect``, ``transmit``, ``ior`` (for rendering)."""
        return self._s.add_mesh(vertices, faces, transform=transform, normals=normals, uvs=uvs, material=material, name=name)

    def add_shape(
        self,
        kind: str,
        *,
        transform: Optional[ArrayLike] = None,
        center: Optional[Sequence[float]] = None,
        radius: Optional[float] = None,
        material: Optional[dict] = None,
    ) -> int:
        """Adds an analytic shape (``'sphere'``, ``'cylinder'``, ``'tube'``, ``'cone'``,
        ``'box'``, ``'disk'``, ``'infinite_cylinder'``, ``'infinite_cone'``; unit size,
        z in [-1, 1]) placed by ``transform``, or scaled by ``radius`` and moved to
        ``center``; returns the instance id."""
        return self._s.add_shape(kind, transform=transform, center=center, radius=radius, material=material)

    def add_spheres(self, centers: ArrayLike, radii: ArrayLike, *, material: Optional[dict] = None) -> np.ndarray:
        """Adds spheres: ``centers`` (N, 3), ``radii`` (N,) or one number; returns their
        instance ids (one geometry shared)."""
        return self._s.add_spheres(centers, np.atleast_1d(np.asarray(radii)), material=material)

    def add_instances(self, geometry: int, transforms: ArrayLike) -> np.ndarray:
        """Adds instances of ``geometry`` placed by ``transforms`` (K, 4, 4); returns ids."""
        return self._s.add_instances(int(geometry), transforms)

    def add_light(
        self,
        kind: str,
        *,
        color: Sequence[float] = (1.0, 1.0, 1.0),
        position: Optional[Sequence[float]] = None,
        direction: Optional[Sequence[float]] = None,
        angle: float = 30.0,
    ) -> None:
        """Adds a ``'point'``, ``'directional'`` or ``'spot'`` light (for rendering)."""
        c = [float(x) for x in color]
        if len(c) != 3:
            raise ValueError(f"color: {len(c)} numbers where 3 were needed")
        self._s.add_light(kind, color=(c[0], c[1], c[2]), position=position, direction=direction, angle=angle)

    # edits ------------------------------------------------------------------------------
    def set_transforms(self, instances: ArrayLike, transforms: ArrayLike) -> None:
        """Moves instances (ids (K,)) to ``transforms`` (K, 4, 4): the top level is rebuilt
        once, meshes are untouched."""
        self._s.set_transforms(np.atleast_1d(np.asarray(instances)), transforms)

    def update_vertices(self, geometry: int, vertices: ArrayLike) -> None:
        """Replaces a mesh's vertices (same count); its tree is refit."""
        self._s.update_vertices(int(geometry), vertices)

    def remove(self, instances: ArrayLike) -> None:
        """Removes instances by id (the others keep theirs)."""
        self._s.remove(np.atleast_1d(np.asarray(instances)))

    def set_time(self, t: float) -> None:
        """Poses an animated (glTF) scene at ``t`` seconds."""
        self._s.set_time(float(t))

    def commit(self) -> None:
        """Builds the acceleration structure now (the first query would)."""
        self._s.commit()

    # facts ------------------------------------------------------------------------------
    def geometry_of(self, instance: int) -> int:
        """The geometry id an instance draws."""
        return self._s.geometry_of(int(instance))

    def mesh_arrays(self, geometry: int) -> Tuple[np.ndarray, np.ndarray]:
        """A mesh's vertices (V, 3) and faces (F, 3) int32."""
        return self._s.mesh_arrays(int(geometry))

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64: lowest and highest corner."""
        return self._s.bounds

    @property
    def num_instances(self) -> int:
        """Number of instances."""
        return self._s.num_instances

    @property
    def num_geometries(self) -> int:
        """Number of geometries (meshes and shapes)."""
        return self._s.num_geometries

    @property
    def num_triangles(self) -> int:
        """Triangles over all meshes (each once however often it is instanced)."""
        return self._s.num_triangles

    @property
    def instance_ids(self) -> np.ndarray:
        """Instance ids, in order."""
        return self._s.instance_ids

    @property
    def transforms(self) -> np.ndarray:
        """Instances' world-from-object maps (K, 4, 4) float64, in ``instance_ids`` order."""
        return self._s.transforms

    @property
    def camera(self) -> Optional[Camera]:
        """The camera the scene file describes, if any."""
        return self._s.camera

    def default_camera(self, width: Optional[int] = None, height: Optional[int] = None) -> Camera:
        """The camera ``render`` uses when given none: the file's, else one framing the
        scene (at the file's image size, or ``width`` x ``height``)."""
        return self._s.default_camera(width, height)

    # queries ----------------------------------------------------------------------------
    def intersect(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        *,
        tmin: Union[float, ArrayLike] = 0.0,
        tmax: Union[float, ArrayLike] = np.inf,
        fields: Optional[Iterable[str]] = None,
        coherent: Optional[bool] = None,
        out: Optional[Hits] = None,
        threads: Optional[int] = None,
    ) -> Hits:
        """Closest hits of rays ``origins`` (..., 3) (or one origin (3,)) and
        ``directions`` (..., 3) within [``tmin``, ``tmax``) (numbers or arrays of the rays'
        shape). ``fields``: which of ``t``, ``hit``, ``prim_id``, ``geom_id``, ``inst_id``,
        ``uv``, ``normal`` to compute (default: all). ``coherent``: True traces batches of
        64 rays (8 x 8 tiles of a 2-D shape) as packets, False ray by ray, None decides per
        batch. ``out``: a ``Hits`` from an earlier call of the same shape to write into."""
        d = self._s._intersect(
            origins,
            directions,
            tmin=tmin,
            tmax=tmax,
            fields=_names(fields),
            coherent=coherent,
            out=None if out is None else out._fields,
            threads=threads,
        )
        return Hits(d, origins, directions)

    def occluded(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        *,
        tmin: Union[float, ArrayLike] = 0.0,
        tmax: Union[float, ArrayLike] = np.inf,
        coherent: Optional[bool] = None,
        threads: Optional[int] = None,
    ) -> np.ndarray:
        """Whether anything blocks each ray within [``tmin``, ``tmax``) (bool array)."""
        return self._s.occluded(origins, directions, tmin=tmin, tmax=tmax, coherent=coherent, threads=threads)

    def intersect_all(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        *,
        tmin: Union[float, ArrayLike] = 0.0,
        tmax: Union[float, ArrayLike] = np.inf,
        max_hits: Optional[int] = None,
        threads: Optional[int] = None,
    ) -> AllHits:
        """Every surface each ray meets within [``tmin``, ``tmax``), sorted by ``t``
        (each triangle once, a shape at each crossing), at most ``max_hits`` per ray."""
        return AllHits(self._s._intersect_all(origins, directions, tmin=tmin, tmax=tmax, max_hits=max_hits, threads=threads))

    def count_hits(
        self,
        origins: ArrayLike,
        directions: ArrayLike,
        *,
        tmin: Union[float, ArrayLike] = 0.0,
        tmax: Union[float, ArrayLike] = np.inf,
        threads: Optional[int] = None,
    ) -> np.ndarray:
        """How many surfaces each ray meets within [``tmin``, ``tmax``) (int32 array)."""
        return self._s.count_hits(origins, directions, tmin=tmin, tmax=tmax, threads=threads)

    def trace_camera(self, camera: Camera, *, fields: Optional[Iterable[str]] = None, threads: Optional[int] = None) -> Hits:
        """A camera's pixel-centre rays, traced as 8 x 8 packets without ray arrays:
        (height, width) fields as ``intersect`` gives, plus ``depth`` along the view axis."""
        return Hits(self._s._trace_camera(camera, fields=_names(fields), threads=threads))

    def __repr__(self) -> str:
        return repr(self._s)


def load(
    path: Union[str, "os.PathLike[str]"],
    *,
    strict: bool = False,
    quality: str = "high",
    triangle_test: str = "unit",
    **defines: Union[str, float, int],
) -> Scene:
    """Reads a scene file: OBJ (``.obj``, ``.obj.gz``), PLY, glTF (``.gltf``, ``.glb``)
    or Mitsuba XML (``.xml``, with ``defines`` for its ``$name`` parameters). ``strict``:
    refuse a glTF file that breaks any rule of the specification. A missing file raises
    ``FileNotFoundError``; a broken one ``LucentError`` naming the place."""
    return Scene(_native=_lucent.load(os.fspath(path), strict=strict, quality=quality, triangle_test=triangle_test, **defines))


def render(
    scene: Scene,
    camera: Optional[Camera] = None,
    *,
    width: Optional[int] = None,
    height: Optional[int] = None,
    spp: Optional[int] = None,
    integrator: str = "path",
    max_depth: Optional[int] = None,
    seed: Optional[int] = None,
    aovs: Sequence[str] = (),
    denoise: bool = False,
    threads: Optional[int] = None,
) -> Union[np.ndarray, Tuple[np.ndarray, dict]]:
    """Renders ``scene`` to a float32 (H, W, 3) linear RGB image, the image
    ``lucent render`` makes for the same scene and settings. ``camera``: a ``Camera``,
    else the file's, else one framing the scene. ``integrator``: ``'path'``,
    ``'whitted'``, ``'vpl'``, ``'eye-light'``, ``'normals'``. ``aovs``: extra images
    (``'albedo'``, ``'normal'``, ``'depth'``, ``'prim_id'``, ``'inst_id'``, ``'geom_id'``),
    returned as ``(image, {name: array})``. ``denoise``: filter the image with its guides.
    Ctrl-C stops it between bands of rows."""
    names = list(aovs) if aovs else None
    return _lucent.render(
        scene._s,
        camera,
        width=width,
        height=height,
        spp=spp,
        integrator=integrator,
        max_depth=max_depth,
        seed=seed,
        aovs=names,
        denoise=denoise,
        threads=threads,
    )


def denoise(color: ArrayLike, *, albedo: ArrayLike, normal: ArrayLike, depth: ArrayLike, iterations: Optional[int] = None) -> np.ndarray:
    """Denoises a rendered image (H, W, 3) with its albedo and normal (H, W, 3) and depth
    (H, W) guides (what ``render(..., denoise=True)`` does)."""
    return _lucent.denoise(color, albedo=albedo, normal=normal, depth=depth, iterations=iterations)


class Renderer:
    """A progressive render: each ``step(spp)`` adds samples to every pixel, and
    ``image`` is the mean so far (for the path tracer, after n samples the image
    ``render`` makes with ``spp=n``, up to the rounding of the sums). Ctrl-C during a step leaves the image as it was before it.

    >>> r = lucent.Renderer(scene, camera)          # doctest: +SKIP
    >>> for _ in range(16): r.step(4)               # doctest: +SKIP
    """

    __slots__ = ("_r",)

    def __init__(
        self,
        scene: Scene,
        camera: Optional[Camera] = None,
        *,
        width: Optional[int] = None,
        height: Optional[int] = None,
        integrator: str = "path",
        max_depth: Optional[int] = None,
        seed: Optional[int] = None,
        threads: Optional[int] = None,
    ):
        self._r = _lucent.Renderer(
            scene._s, camera, width=width, height=height, integrator=integrator, max_depth=max_depth, seed=seed, threads=threads
        )

    def step(self, spp: int = 1) -> None:
        """Adds ``spp`` samples to every pixel."""
        self._r.step(int(spp))

    @property
    def image(self) -> np.ndarray:
        """The image so far, (H, W, 3) float32."""
        return self._r.image

    @property
    def spp(self) -> int:
        """Samples per pixel so far."""
        return self._r.spp

    def reset(self) -> None:
        """Starts over."""
        self._r.reset()

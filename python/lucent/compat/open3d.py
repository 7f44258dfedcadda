"""Open3D's ``RaycastingScene`` on lucent: switch with one import.

>>> from lucent.compat.open3d import RaycastingScene   # instead of open3d.t.geometry
>>> scene = RaycastingScene()
>>> gid = scene.add_triangles(vertices, triangles)     # doctest: +SKIP
>>> ans = scene.cast_rays(rays)                        # doctest: +SKIP
>>> ans["t_hit"].numpy()                               # doctest: +SKIP

The methods, arguments, dict keys, dtypes and miss values are Open3D's (0.20):
``t_hit`` float32 (``inf`` on a miss), ``geometry_ids`` and ``primitive_ids`` uint32
(``INVALID_ID`` on a miss), ``primitive_uvs`` float32 (..., 2), ``primitive_normals``
float32 (..., 3). Results are numpy arrays that also answer ``.numpy()`` (as Open3D's
tensors do), so code written for Open3D runs unchanged. Unlike Open3D, the GIL is
released during every query, and float64 input is accepted.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from .. import Scene

__all__ = ["RaycastingScene"]


class _Tensor(np.ndarray):
    """A numpy array with Open3D's ``Tensor.numpy()``."""

    def numpy(self) -> np.ndarray:
        return self.view(np.ndarray)


def _t(a: np.ndarray) -> _Tensor:
    return np.asarray(a).view(_Tensor)


def _split_rays(rays: Any, name: str = "rays") -> tuple:
    if hasattr(rays, "numpy") and not isinstance(rays, np.ndarray):
        rays = rays.numpy()
    r = np.asarray(rays)
    if r.ndim < 1 or r.shape[-1] != 6:
        raise ValueError(f"{name}: shape {r.shape} where (..., 6) [ox, oy, oz, dx, dy, dz] was needed")
    return r[..., 0:3], r[..., 3:6]


class RaycastingScene:
    """Open3D's ``open3d.t.geometry.RaycastingScene``: triangle meshes, ray queries."""

    INVALID_ID: int = 4294967295

    def __init__(self, nthreads: int = 0, device: Any = None):
        self._scene = Scene()
        self._nthreads = nthreads or None
        self._count = 0

    def add_triangles(self, vertex_positions: Any, triangle_indices: Any = None) -> int:
        """Adds a mesh (``vertex_positions`` (N, 3), ``triangle_indices`` (M, 3), or an
        Open3D ``TriangleMesh`` with ``.vertex.positions`` and ``.triangle.indices``);
        returns its geometry id (0, 1, ... in order)."""
        if triangle_indices is None:
            mesh = vertex_positions
            try:
                vertex_positions = mesh.vertex.positions
                triangle_indices = mesh.triangle.indices
            except AttributeError:
                raise TypeError("add_triangles: give vertex_positions and triangle_indices, or a tensor TriangleMesh") from None
        v = vertex_positions.numpy() if hasattr(vertex_positions, "numpy") else vertex_positions
        f = triangle_indices.numpy() if hasattr(triangle_indices, "numpy") else triangle_indices
        self._scene.add_mesh(v, np.asarray(f).astype(np.int64))
        gid = self._count
        self._count += 1
        return gid

    def _threads(self, nthreads: int) -> Optional[int]:
        return nthreads or self._nthreads

    def cast_rays(self, rays: Any, nthreads: int = 0) -> dict:
        """Closest hits: ``t_hit``, ``geometry_ids``, ``primitive_ids``,
        ``primitive_uvs``, ``primitive_normals``."""
        o, d = _split_rays(rays)
        h = self._scene.intersect(o, d, fields=("t", "prim_id", "geom_id", "uv", "normal"), threads=self._threads(nthreads))
        return {
            "t_hit": _t(h.t),
            "geometry_ids": _t(h.geom_id.astype(np.uint32)),
            "primitive_ids": _t(h.prim_id.astype(np.uint32)),
            "primitive_uvs": _t(h.uv),
            "primitive_normals": _t(h.normal),
        }

    def test_occlusions(self, rays: Any, tnear: float = 0.0, tfar: float = np.inf, nthreads: int = 0) -> _Tensor:
        """Whether anything blocks each ray within [``tnear``, ``tfar``)."""
        o, d = _split_rays(rays)
        return _t(self._scene.occluded(o, d, tmin=tnear, tmax=tfar, threads=self._threads(nthreads)))

    def count_intersections(self, rays: Any, nthreads: int = 0) -> _Tensor:
        """How many surfaces each ray meets (int32)."""
        o, d = _split_rays(rays)
        return _t(self._scene.count_hits(o, d, threads=self._threads(nthreads)))

    def list_intersections(self, rays: Any, nthreads: int = 0) -> dict:
        """Every hit: ``ray_splits`` (N + 1,), ``ray_ids``, ``geometry_ids``,
        ``primitive_ids`` (uint32), ``primitive_uvs``, ``t_hit``, sorted by ``t`` per ray."""
        o, d = _split_rays(rays)
        a = self._scene.intersect_all(o, d, threads=self._threads(nthreads))
        return {
            "ray_splits": _t(a.splits.astype(np.uint32)),
            "ray_ids": _t(a.ray_index.astype(np.uint32)),
            "geometry_ids": _t(a.geom_id.astype(np.uint32)),
            "primitive_ids": _t(a.prim_id.astype(np.uint32)),
            "primitive_uvs": _t(a.uv),
            "t_hit": _t(a.t),
        }

    @staticmethod
    def create_rays_pinhole(*args: Any, **kwargs: Any) -> _Tensor:
        """Rays (height, width, 6) of a pinhole camera, as Open3D makes them (directions
        not normalised: unit depth along the view axis). Either
        ``(intrinsic_matrix, extrinsic_matrix, width_px, height_px)`` or
        ``(fov_deg, center, eye, up, width_px, height_px)`` (``fov_deg`` across the width)."""
        names_k = ("intrinsic_matrix", "extrinsic_matrix", "width_px", "height_px")
        names_f = ("fov_deg", "center", "eye", "up", "width_px", "height_px")
        if "fov_deg" in kwargs or (len(args) == 6) or (len(args) >= 1 and np.ndim(np.asarray(_np(args[0]))) == 0):
            p = dict(zip(names_f, args))
            p.update(kwargs)
            fov, w, h = float(p["fov_deg"]), int(p["width_px"]), int(p["height_px"])
            eye = np.asarray(_np(p["eye"]), np.float64).reshape(3)
            center = np.asarray(_np(p["center"]), np.float64).reshape(3)
            up = np.asarray(_np(p["up"]), np.float64).reshape(3)
            f = 0.5 * w / np.tan(np.radians(fov) * 0.5)
            K = np.array([[f, 0, 0.5 * w], [0, f, 0.5 * h], [0, 0, 1]])
            z = center - eye
            z /= np.linalg.norm(z)
            x = np.cross(up, z)
            x /= np.linalg.norm(x)
            y = np.cross(z, x)
            R = np.stack([x, y, z])
            E = np.eye(4)
            E[:3, :3] = R
            E[:3, 3] = -R @ eye
        else:
            p = dict(zip(names_k, args))
            p.update(kwargs)
            K = np.asarray(_np(p["intrinsic_matrix"]), np.float64).reshape(3, 3)
            E = np.asarray(_np(p["extrinsic_matrix"]), np.float64).reshape(4, 4)
            w, h = int(p["width_px"]), int(p["height_px"])
        R, t = E[:3, :3], E[:3, 3]
        eye = -R.T @ t
        u, v = np.meshgrid(np.arange(w, dtype=np.float64) + 0.5, np.arange(h, dtype=np.float64) + 0.5)
        dc = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)
        dw = dc @ R
        out = np.empty((h, w, 6), np.float32)
        out[..., :3] = eye
        out[..., 3:] = dw
        return _t(out)


def _np(x: Any) -> Any:
    return x.numpy() if hasattr(x, "numpy") and not isinstance(x, np.ndarray) else x

"""trimesh's ``mesh.ray`` on lucent: switch with one line.

>>> import trimesh
>>> from lucent.compat.trimesh import RayMeshIntersector
>>> mesh = trimesh.creation.icosphere()                     # doctest: +SKIP
>>> mesh.ray = RayMeshIntersector(mesh)                     # doctest: +SKIP
>>> mesh.ray.intersects_location(origins, directions)        # doctest: +SKIP

The methods and return types are trimesh's (``trimesh.ray.ray_pyembree``): triangle
indices int64 (``-1`` on a miss), locations float64. Differences, both on purpose:
``intersects_any`` is a true any-hit query (trimesh's asks for the closest hit), and every
hit along a ray comes from one all-hits traversal (trimesh re-casts each ray from just
beyond its last hit, by an offset that can skip a surface close behind another or meet
one twice). Multiple hits are listed ray by ray, nearest first (trimesh lists first hits
of every ray, then second hits, ...). float64 meshes are re-centred in float64 before
the conversion to float32, as trimesh's ``scale_to_box`` tries to do for embreex.
"""

from __future__ import annotations

from typing import Any, Optional, Tuple

import numpy as np

from .. import Scene

__all__ = ["RayMeshIntersector"]


def _rays(ray_origins: Any, ray_directions: Any) -> Tuple[np.ndarray, np.ndarray]:
    o = np.asarray(ray_origins, dtype=np.float64)
    d = np.asarray(ray_directions, dtype=np.float64)
    if o.shape != d.shape:
        raise ValueError("Ray origin and direction don't match!")
    if o.ndim != 2 or o.shape[1] != 3:
        raise ValueError(f"ray_origins: shape {o.shape} where (n, 3) was needed")
    return o, d


class RayMeshIntersector:
    """trimesh's ``RayMeshIntersector`` over lucent (``geometry``: a ``trimesh.Trimesh``
    or anything with ``vertices`` (V, 3) and ``faces`` (F, 3)). The mesh is read once,
    when the intersector is made."""

    def __init__(self, geometry: Any, scale_to_box: bool = True):
        self.mesh = geometry
        self._scale_to_box = scale_to_box
        self._scene = Scene()
        self._scene.add_mesh(np.asarray(geometry.vertices, dtype=np.float64), np.asarray(geometry.faces, dtype=np.int64))
        self._closed: Optional[Scene] = None

    def intersects_first(self, ray_origins: Any, ray_directions: Any) -> np.ndarray:
        """Index of the first triangle each ray hits (int64, -1 on a miss)."""
        o, d = _rays(ray_origins, ray_directions)
        h = self._scene.intersect(o, d, fields=("prim_id",))
        return h.prim_id.astype(np.int64)

    def intersects_any(self, ray_origins: Any, ray_directions: Any) -> np.ndarray:
        """Whether each ray hits the mesh (bool)."""
        o, d = _rays(ray_origins, ray_directions)
        return self._scene.occluded(o, d)

    def intersects_id(
        self,
        ray_origins: Any,
        ray_directions: Any,
        multiple_hits: bool = True,
        max_hits: int = 100,
        return_locations: bool = False,
    ) -> tuple:
        """Triangles hit (``index_tri``, int64) and the ray of each (``index_ray``),
        every hit along a ray when ``multiple_hits`` (at most ``max_hits``), else the first;
        with ``return_locations``, the hit points (float64) too."""
        o, d = _rays(ray_origins, ray_directions)
        if multiple_hits:
            a = self._scene.intersect_all(o, d, max_hits=max_hits)
            tri = a.prim_id.astype(np.int64)
            ray = a.ray_index.astype(np.int64)
            t = a.t.astype(np.float64)
        else:
            h = self._scene.intersect(o, d, fields=("t", "hit", "prim_id"))
            ray = np.nonzero(h.hit)[0].astype(np.int64)
            tri = h.prim_id[ray].astype(np.int64)
            t = h.t[ray].astype(np.float64)
        if return_locations:
            loc = o[ray] + t[:, None] * d[ray]
            return tri, ray, loc
        return tri, ray

    def intersects_location(self, ray_origins: Any, ray_directions: Any, multiple_hits: bool = True) -> tuple:
        """Hit points (float64), the ray of each and the triangle of each."""
        tri, ray, loc = self.intersects_id(ray_origins, ray_directions, multiple_hits=multiple_hits, return_locations=True)
        return loc, ray, tri

    def contains_points(self, points: Any) -> np.ndarray:
        """Whether each point is inside the (closed) mesh: the parity of the surfaces a ray
        from it crosses, asked along two directions and a third where those disagree, with
        the watertight triangle test (no ray slips between triangles that share an edge,
        which would flip the parity)."""
        p = np.asarray(points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points: shape {p.shape} where (n, 3) was needed")
        dirs = np.array([[0.4395064455, 0.617598629942, 0.652231566745], [-0.5785, -0.3981, 0.7119], [0.1343, -0.9421, -0.3074]])
        if self._closed is None:
            self._closed = Scene(triangle_test="watertight")
            self._closed.add_mesh(np.asarray(self.mesh.vertices, dtype=np.float64), np.asarray(self.mesh.faces, dtype=np.int64))
        scene = self._closed
        odd = [(scene.count_hits(p, np.broadcast_to(dv, p.shape).copy()) % 2 == 1) for dv in dirs[:2]]
        inside = odd[0].copy()
        disagree = odd[0] != odd[1]
        if disagree.any():
            third = scene.count_hits(p[disagree], np.broadcast_to(dirs[2], (int(disagree.sum()), 3)).copy()) % 2 == 1
            # The majority of the three.
            inside[disagree] = third
        return inside

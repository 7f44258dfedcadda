"""Records what Open3D and trimesh answer on fixed rays, for the compat layers' tests
(python/tests/test_compat.py compares lucent.compat's answers with these; CI needs
neither library). Run in a venv with open3d-cpu, trimesh and embreex installed:

    python tools/python/record_compat.py [OUT.npz]

Geometry: the Stanford bunny (../shared/scenes/stanford/bunny.ply, as lucent reads it)
and a closed icosphere; rays: 4,000 random rays at the bunny, Open3D's pinhole rays of
both overloads, points in and around the icosphere.
"""

import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import trimesh

import lucent

here = Path(__file__).resolve().parent
root = here.parent.parent
out = Path(sys.argv[1]) if len(sys.argv) > 1 else root / "python/tests/data/compat.npz"

bunny = lucent.load(root.parent / "shared/scenes/stanford/bunny.ply")
V, F = bunny.mesh_arrays(0)
V = np.asarray(V, np.float32)
rng = np.random.default_rng(7)
lo, hi = bunny.bounds
c = 0.5 * (lo + hi)
n = 4000
org = (c + (rng.random((n, 3)) - 0.5) * 3 * (hi - lo)).astype(np.float32)
tgt = lo + rng.random((n, 3)) * (hi - lo)
dirs = (tgt - org).astype(np.float32)
rays = np.concatenate([org, dirs], axis=1)

s = o3d.t.geometry.RaycastingScene()
s.add_triangles(o3d.core.Tensor(V), o3d.core.Tensor(F.astype(np.uint32)))
cast = {k: v.numpy() for k, v in s.cast_rays(o3d.core.Tensor(rays)).items()}
occ = s.test_occlusions(o3d.core.Tensor(rays), tnear=0.0, tfar=0.9).numpy()
cnt = s.count_intersections(o3d.core.Tensor(rays)).numpy()
lst = {k: v.numpy() for k, v in s.list_intersections(o3d.core.Tensor(rays[:500])).items()}
K = np.array([[40.0, 0, 31.0], [0, 42.0, 23.5], [0, 0, 1]])
E = np.eye(4)
E[:3, 3] = [0.02, -0.1, 0.3]
pin_k = o3d.t.geometry.RaycastingScene.create_rays_pinhole(o3d.core.Tensor(K), o3d.core.Tensor(E), 64, 48).numpy()
pin_f = o3d.t.geometry.RaycastingScene.create_rays_pinhole(
    fov_deg=50, center=[-0.0168, 0.11, -0.0015], eye=[-0.0168, 0.11, 0.40], up=[0, 1, 0], width_px=64, height_px=48
).numpy()

mesh = trimesh.Trimesh(V.astype(np.float64), F)
tm_first = mesh.ray.intersects_first(org, dirs)
tm_any = mesh.ray.intersects_any(org, dirs)
tm_tri, tm_ray, tm_loc = mesh.ray.intersects_id(org[:500], dirs[:500], multiple_hits=True, return_locations=True)
ico = trimesh.creation.icosphere(subdivisions=3)
pts = rng.random((3000, 3)) * 2.4 - 1.2
tm_contains = ico.ray.contains_points(pts)

np.savez_compressed(
    out,
    rays=rays,
    o3d_t_hit=cast["t_hit"],
    o3d_geometry_ids=cast["geometry_ids"],
    o3d_primitive_ids=cast["primitive_ids"],
    o3d_primitive_uvs=cast["primitive_uvs"],
    o3d_primitive_normals=cast["primitive_normals"],
    o3d_occluded=occ,
    o3d_count=cnt,
    o3d_list_splits=lst["ray_splits"],
    o3d_list_ray_ids=lst["ray_ids"],
    o3d_list_primitive_ids=lst["primitive_ids"],
    o3d_list_t_hit=lst["t_hit"],
    pin_K=K,
    pin_E=E,
    o3d_pinhole_k=pin_k,
    o3d_pinhole_fov=pin_f,
    tm_first=tm_first,
    tm_any=tm_any,
    tm_id_tri=tm_tri,
    tm_id_ray=tm_ray,
    tm_id_loc=tm_loc,
    ico_vertices=ico.vertices,
    ico_faces=ico.faces,
    points=pts,
    tm_contains=tm_contains,
    versions=np.array([o3d.__version__, trimesh.__version__]),
)
print(f"wrote {out} (open3d {o3d.__version__}, trimesh {trimesh.__version__})")

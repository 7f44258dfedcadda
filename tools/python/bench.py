"""lucent's Python package against Open3D, embreex, trimesh and Mitsuba 3 on identical rays.

    python tools/python/bench.py [SCENE ...] [--threads 1,2] [--runs 5] [--dumps DIR]

The rays are the Embree harness's dumps (../shared/bench/compare.sh writes them to
/tmp/lucent-bench/dumps/SCENE/: mesh.bin and rays_{primary,shadow,diffuse}.bin), so every
library traces the same triangles and the same rays as `lucent bench rays` and Embree's
own harness. Each library runs in its own process with its own Python (the libraries'
venvs differ): LUCENT_PY (a Python with lucent installed, default `python3`), ANCHORS_PY
(open3d-cpu, trimesh, embreex), MITSUBA_PY (mitsuba 3.9.1, `tools/mitsuba/setup`);
a library whose Python is missing is left out.

Timed (median of --runs after one untimed warm-up): the call a user makes, including the
Python-side conversion of the rays into the library's input and of its answer into numpy:
  lucent      Scene.intersect(o, d, tmax=tfar, fields=("t", "prim_id")) / Scene.occluded
  lucent-all  Scene.intersect with every field (t, hit, ids, uv, normal: Open3D's set)
  open3d      RaycastingScene.cast_rays (N, 6) / test_occlusions (directions scaled so
              that tfar is 1: it takes one tfar for all rays), nthreads=T
  embreex     EmbreeScene.run(o, d, dists=tfar, output=1) / query="OCCLUDED"; one thread
              per call, so T threads are T Python threads over T slices
  trimesh     mesh.ray (RayMeshIntersector over embreex): intersects_first (triangle ids;
              trimesh takes no tfar) / intersects_any (no tfar either: answers differ)
  mitsuba     llvm_ad_rgb: Scene.ray_intersect_preliminary / ray_test, dr.set_thread_count(T)

Answers are compared with lucent's: hit-mask agreement and |dt| percentiles (relative).
Prints a table and the ratio of lucent to the fastest other library per ray kind at the
highest thread count; writes every figure to --json (default /tmp/lucent-python-bench.json).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

KINDS = ("primary", "shadow", "diffuse")


# ------------------------------------------------------------------------------ dumps --
def read_mesh(path: Path):
    b = path.read_bytes()
    if b[:8] != b"RTBMESH1":
        raise SystemExit(f"{path}: not a mesh dump")
    nv, nt = np.frombuffer(b, np.uint32, 2, 8)
    v = np.frombuffer(b, np.float32, int(nv) * 3, 16).reshape(-1, 3)
    f = np.frombuffer(b, np.uint32, int(nt) * 3, 16 + int(nv) * 12).reshape(-1, 3)
    return v.copy(), f.copy()


def read_rays(path: Path):
    """Valid rays of a dump in its order: origins, directions (N, 3) and tfar (N,)."""
    b = path.read_bytes()
    if b[:8] != b"RTBRAYS1":
        raise SystemExit(f"{path}: not a ray dump")
    nb = int(np.frombuffer(b, np.uint32, 1, 16)[0])
    blocks = np.frombuffer(b, np.uint32, nb * 72, 24).reshape(nb, 9, 8)
    f = blocks[:, :7].view(np.float32)
    valid = blocks[:, 7].view(np.int32) != 0
    o = np.stack([f[:, 0], f[:, 1], f[:, 2]], axis=-1)[valid]
    d = np.stack([f[:, 3], f[:, 4], f[:, 5]], axis=-1)[valid]
    return np.ascontiguousarray(o), np.ascontiguousarray(d), np.ascontiguousarray(f[:, 6][valid])


def closed_sphere(nu=256, nv=128):
    """A closed UV sphere (shared vertices, poles fanned): 2 nu (nv - 1) triangles."""
    th = np.linspace(0, np.pi, nv + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    v = np.concatenate([[[0, 1, 0]], ring, [[0, -1, 0]]]).astype(np.float32)
    f = []
    idx = lambda i, j: 1 + i * nu + (j % nu)
    for j in range(nu):
        f.append([0, idx(0, j + 1), idx(0, j)])
        f.append([len(v) - 1, idx(nv - 2, j), idx(nv - 2, j + 1)])
    for i in range(nv - 2):
        for j in range(nu):
            a, b, c, d = idx(i, j), idx(i, j + 1), idx(i + 1, j), idx(i + 1, j + 1)
            f += [[a, b, d], [a, d, c]]
    return v, np.array(f, np.uint32)


def leak_rays(v, f, n=1_000_000, seed=3):
    """Rays from points inside straight at vertices and edge midpoints (where triangles
    meet: where a test that is not watertight lets rays through)."""
    rng = np.random.default_rng(seed)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    targets = np.concatenate([v, 0.5 * (v[e[:, 0]] + v[e[:, 1]])]).astype(np.float64)
    pick = targets[rng.integers(0, len(targets), n)]
    o = (rng.random((n, 3)) - 0.5) * 0.5
    return o.astype(np.float32), (pick - o).astype(np.float32), np.full(n, np.inf, np.float32)


# ----------------------------------------------------------------------------- workers --
def time_it(fn, runs):
    fn()  # warm-up (builds lazily, JIT compiles)
    ts = []
    out = None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), out


def worker(lib, dump, kind, threads, runs, out_path):
    if kind == "leaks":
        v, f = closed_sphere()
        o, d, tfar = leak_rays(v, f)
    else:
        v, f = read_mesh(dump / "mesh.bin")
        o, d, tfar = read_rays(dump / f"rays_{kind}.bin")
    shadow = kind == "shadow"
    t0 = time.perf_counter()
    if lib in ("lucent", "lucent-all", "lucent-watertight"):
        import lucent

        s = lucent.Scene(triangle_test="watertight" if lib == "lucent-watertight" else "unit")
        s.add_mesh(v, f.astype(np.int64))
        s.commit()
        build = time.perf_counter() - t0
        fields = ("t", "prim_id") if lib == "lucent" else ("t", "hit", "prim_id", "geom_id", "inst_id", "uv", "normal")
        if shadow:
            fn = lambda: s.occluded(o, d, tmax=tfar, threads=threads)
        else:
            fn = lambda: s.intersect(o, d, tmax=tfar, fields=fields, threads=threads).t
    elif lib == "open3d":
        import open3d as o3d

        s = o3d.t.geometry.RaycastingScene(nthreads=threads)
        s.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f))
        s.cast_rays(o3d.core.Tensor(np.zeros((1, 6), np.float32)))  # builds
        build = time.perf_counter() - t0
        if shadow:

            def fn():
                r = np.concatenate([o, d * tfar[:, None]], axis=1)
                return s.test_occlusions(o3d.core.Tensor(r), tnear=0.0, tfar=1.0, nthreads=threads).numpy()

        else:

            def fn():
                r = np.concatenate([o, d], axis=1)
                t = s.cast_rays(o3d.core.Tensor(r), nthreads=threads)["t_hit"].numpy()
                return np.where(t < tfar, t, np.inf).astype(np.float32)

    elif lib == "embreex":
        from concurrent.futures import ThreadPoolExecutor

        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        s = rtcore_scene.EmbreeScene()
        TriangleMesh(s, v[f])
        s.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
        build = time.perf_counter() - t0
        pool = ThreadPoolExecutor(threads)
        parts = np.array_split(np.arange(len(o)), threads)

        def one(ix):
            oo, dd, tt = o[ix], d[ix], tfar[ix]
            if shadow:
                r = s.run(oo, dd, dists=tt, query="OCCLUDED")
                return np.asarray(r) != -1
            r = s.run(oo, dd, dists=tt, output=1)
            return np.where(np.asarray(r["primID"]) != -1, np.asarray(r["tfar"]), np.inf).astype(np.float32)

        fn = lambda: np.concatenate(list(pool.map(one, parts)))
    elif lib == "trimesh":
        import trimesh
        from concurrent.futures import ThreadPoolExecutor

        mesh = trimesh.Trimesh(v.astype(np.float64), f, process=False)
        mesh.ray.intersects_first(np.zeros((1, 3)), np.ones((1, 3)))
        build = time.perf_counter() - t0
        pool = ThreadPoolExecutor(threads)
        parts = np.array_split(np.arange(len(o)), threads)
        if shadow:
            fn = lambda: np.concatenate(list(pool.map(lambda ix: mesh.ray.intersects_any(o[ix], d[ix]), parts)))
        else:
            fn = lambda: np.concatenate(list(pool.map(lambda ix: mesh.ray.intersects_first(o[ix], d[ix]), parts)))
    elif lib == "mitsuba":
        import drjit as dr
        import mitsuba as mi

        mi.set_variant("llvm_ad_rgb")
        dr.set_thread_count(threads)
        m = mi.Mesh("m", len(v), len(f))
        p = mi.traverse(m)
        p["vertex_positions"] = dr.ravel(mi.Point3f(v[:, 0], v[:, 1], v[:, 2]))
        p["faces"] = dr.ravel(mi.Vector3u(f[:, 0], f[:, 1], f[:, 2]))
        p.update()
        s = mi.load_dict({"type": "scene", "m": m})
        build = time.perf_counter() - t0
        coherent = kind == "primary"

        def fn():
            ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
            ray.maxt = mi.Float(tfar)
            if shadow:
                hit = s.ray_test(ray, coherent=coherent)
                return hit.numpy()
            pi = s.ray_intersect_preliminary(ray, coherent=coherent)
            t = pi.t.numpy()
            return np.where(np.isfinite(t) & (t < tfar), t, np.inf).astype(np.float32)

    else:
        raise SystemExit(f"unknown library {lib}")
    sec, ans = time_it(fn, runs)
    np.savez(out_path, answer=np.asarray(ans), seconds=sec, build=build, rays=len(o))


# ------------------------------------------------------------------------------ driver --
def pythons():
    here = Path(__file__).resolve()
    root = here.parents[2]
    cand = {
        "lucent": os.environ.get("LUCENT_PY", sys.executable),
        "anchors": os.environ.get("ANCHORS_PY", str(root.parent / "pyanchors/bin/python")),
        "mitsuba": os.environ.get("MITSUBA_PY", str(root.parent / "mitsuba-venv/bin/python")),
    }
    return {k: v for k, v in cand.items() if v and (Path(v).exists() or shutil.which(v))}


LIB_PY = {"lucent": "lucent", "lucent-all": "lucent", "lucent-watertight": "lucent", "open3d": "anchors", "embreex": "anchors", "trimesh": "anchors", "mitsuba": "mitsuba"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", default=["bunny", "conference", "sponza", "kitchen", "museum"])
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--dumps", default="/tmp/lucent-bench/dumps")
    ap.add_argument("--libs", default="lucent,lucent-all,open3d,embreex,trimesh,mitsuba")
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--json", default="/tmp/lucent-python-bench.json")
    ap.add_argument("--leaks", action="store_true", help="count rays that slip through a closed mesh's shared edges and vertices instead")
    ap.add_argument("--worker", nargs=6, metavar=("LIB", "DUMP", "KIND", "THREADS", "RUNS", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        lib, dump, kind, threads, runs, out = a.worker
        worker(lib, Path(dump), kind, int(threads), int(runs), out)
        return
    py = pythons()
    if a.leaks:
        tmp = Path(tempfile.mkdtemp(prefix="lucent-pybench-"))
        print("rays from inside a closed sphere (65,024 triangles) at its vertices and edge midpoints:")
        for lib in ["lucent", "lucent-watertight", "open3d", "embreex", "mitsuba"]:
            if LIB_PY[lib] not in py:
                continue
            out = tmp / f"leaks-{lib}.npz"
            cmd = [py[LIB_PY[lib]], str(Path(__file__).resolve()), "--worker", lib, "-", "leaks", "2", "1", str(out)]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                print(f"  {lib}: failed: {r.stderr.strip().splitlines()[-1:]}")
                continue
            z = np.load(out)
            ans = z["answer"]
            missed = int(np.sum(~np.isfinite(ans))) if ans.dtype != np.bool_ else int(np.sum(~ans))
            print(f"  {lib:18s} {missed:7d} of {int(z['rays'])} rays leaked")
        return
    libs = [l for l in a.libs.split(",") if LIB_PY[l] in py]
    threads = [int(t) for t in a.threads.split(",")]
    rows = []
    tmp = Path(tempfile.mkdtemp(prefix="lucent-pybench-"))
    for scene in a.scenes:
        dump = Path(a.dumps) / scene
        if not (dump / "mesh.bin").exists():
            print(f"{scene}: no dump in {dump} (run ../shared/bench/compare.sh {scene} first)", file=sys.stderr)
            continue
        for kind in a.kinds.split(","):
            for t in threads:
                ref = None
                for lib in libs:
                    out = tmp / f"{scene}-{kind}-{t}-{lib}.npz"
                    cmd = [py[LIB_PY[lib]], str(Path(__file__).resolve()), "--worker", lib, str(dump), kind, str(t), str(a.runs), str(out)]
                    r = subprocess.run(cmd, capture_output=True, text=True)
                    if r.returncode != 0:
                        print(f"{scene} {kind} {lib} x{t}: failed: {r.stderr.strip().splitlines()[-1:]}", file=sys.stderr)
                        continue
                    z = np.load(out)
                    ans = z["answer"]
                    row = dict(scene=scene, kind=kind, threads=t, lib=lib, rays=int(z["rays"]), seconds=float(z["seconds"]),
                               mrays=float(z["rays"]) / float(z["seconds"]) / 1e6, build_s=float(z["build"]))
                    if lib == "lucent":
                        ref = ans
                    if ref is not None and lib != "lucent":
                        if ans.dtype == np.bool_ or ref.dtype == np.bool_:
                            hm_got, hm_ref = ans.astype(bool), ref.astype(bool)
                        elif lib == "trimesh":
                            hm_got, hm_ref = ans >= 0, np.isfinite(ref)
                        else:
                            hm_got, hm_ref = np.isfinite(ans), np.isfinite(ref)
                        row["hit_agree"] = float(np.mean(hm_got == hm_ref))
                        if ans.dtype != np.bool_ and lib != "trimesh":
                            both = hm_got & hm_ref
                            rel = np.abs(ans[both] - ref[both]) / np.maximum(np.abs(ref[both]), 1e-30)
                            if rel.size:
                                row["dt_p50"], row["dt_p99"], row["dt_p999"] = (float(np.quantile(rel, q)) for q in (0.5, 0.99, 0.999))
                    rows.append(row)
                    extra = ""
                    if "hit_agree" in row:
                        extra = f"  hits agree {100 * row['hit_agree']:.3f}%"
                        if "dt_p99" in row:
                            extra += f"  |dt|/t p50 {row['dt_p50']:.1e} p99 {row['dt_p99']:.1e} p99.9 {row['dt_p999']:.1e}"
                    print(f"{scene:10s} {kind:8s} x{t} {lib:10s} {row['mrays']:8.2f} Mrays/s ({row['rays']} rays){extra}", flush=True)
    Path(a.json).write_text(json.dumps(rows, indent=1))
    top = max(threads)
    print(f"\nlucent / fastest other library at {top} threads (Mrays/s, medians of {a.runs}):")
    for scene in a.scenes:
        for kind in a.kinds.split(","):
            sel = [r for r in rows if r["scene"] == scene and r["kind"] == kind and r["threads"] == top]
            mine = [r for r in sel if r["lib"] == "lucent"]
            others = [r for r in sel if not r["lib"].startswith("lucent")]
            if mine and others:
                best = max(others, key=lambda r: r["mrays"])
                print(f"  {scene:10s} {kind:8s} {mine[0]['mrays'] / best['mrays']:5.2f}x  (lucent {mine[0]['mrays']:.2f}, {best['lib']} {best['mrays']:.2f})")
    print(f"figures: {a.json}")


if __name__ == "__main__":
    main()

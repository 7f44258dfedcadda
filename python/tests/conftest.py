"""Shared fixtures: the shared scenes beside the repository, the CLI binary."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared"
SCENES = SHARED / "scenes"
DATA = Path(__file__).resolve().parent / "data"


def lucent_bin():
    """The lucent CLI (LUCENT_BIN, else target/ci or target/release, else PATH)."""
    env = os.environ.get("LUCENT_BIN")
    if env:
        return env
    for p in (ROOT / "target/ci/lucent", ROOT / "target/release/lucent"):
        if p.exists():
            return str(p)
    return shutil.which("lucent")


@pytest.fixture(scope="session")
def bunny():
    import lucent

    return lucent.load(SCENES / "stanford/bunny.ply")


@pytest.fixture(scope="session")
def bunny_rays():
    """4,000 seeded rays at the bunny from around it."""
    rng = np.random.default_rng(11)
    lo = np.array([-0.0947, 0.0330, -0.0619])
    hi = np.array([0.0610, 0.1873, 0.0588])
    c = 0.5 * (lo + hi)
    o = c + (rng.random((4000, 3)) - 0.5) * 3 * (hi - lo)
    d = lo + rng.random((4000, 3)) * (hi - lo) - o
    return o.astype(np.float32), d.astype(np.float32)


def brute_force(V, F, o, d, tmin=0.0, tmax=np.inf):
    """Closest hits by testing every triangle (Moller-Trumbore in float64): t, prim."""
    V = np.asarray(V, np.float64)
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    e1, e2 = b - a, c - a
    ts = np.full(len(o), np.inf)
    prims = np.full(len(o), -1)
    for i in range(len(o)):
        oi, di = o[i].astype(np.float64), d[i].astype(np.float64)
        p = np.cross(di, e2)
        det = np.einsum("ij,ij->i", e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = oi - a
            u = np.einsum("ij,ij->i", s, p) * inv
            q = np.cross(s, e1)
            v = (q @ di) * inv
            t = np.einsum("ij,ij->i", e2, q) * inv
        ok = (np.abs(det) > 1e-30) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= tmin) & (t < tmax)
        if ok.any():
            k = np.argmin(np.where(ok, t, np.inf))
            ts[i], prims[i] = t[k], k
    return ts, prims

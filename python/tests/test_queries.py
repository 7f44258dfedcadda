"""Ray queries: closed-form answers, a brute-force reference on the Stanford bunny, the
packet and single-ray paths against each other, every field and shape, edits, float64."""

import numpy as np
import pytest

import lucent
from conftest import SCENES, brute_force

TRI_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
TRI_F = np.array([[0, 1, 2]])


def tri_scene(**kw):
    s = lucent.Scene(**kw)
    s.add_mesh(TRI_V, TRI_F)
    return s


def test_one_triangle_closed_form():
    s = tri_scene()
    h = s.intersect([0.2, 0.3, 2.0], [[0, 0, -1], [0, 0, 1], [0, 0, -2]])
    assert h.t.dtype == np.float32 and h.prim_id.dtype == np.int32 and h.hit.dtype == np.bool_
    np.testing.assert_array_equal(h.hit, [True, False, True])
    np.testing.assert_allclose(h.t, [2.0, np.inf, 1.0], rtol=1e-6)  # t in units of |d|
    np.testing.assert_array_equal(h.prim_id, [0, -1, 0])
    np.testing.assert_array_equal(h.geom_id, [0, -1, 0])
    np.testing.assert_array_equal(h.inst_id, [0, -1, 0])
    np.testing.assert_allclose(h.uv[0], [0.2, 0.3], atol=1e-6)  # weights of v1, v2
    np.testing.assert_array_equal(h.uv[1], [0, 0])
    np.testing.assert_allclose(h.normal[0], [0, 0, 1], atol=1e-7)  # by the winding
    np.testing.assert_array_equal(h.normal[1], [0, 0, 0])
    np.testing.assert_allclose(h.points[0], [0.2, 0.3, 0.0], atol=1e-6)
    assert np.isnan(h.points[1]).all()


def test_watertight_test_answers_the_same_on_a_triangle():
    s = tri_scene(triangle_test="watertight")
    h = s.intersect([0.25, 0.25, 1.0], [0, 0, -1])
    assert h.t.shape == () and float(h.t) == pytest.approx(1.0)


def test_bunny_against_brute_force(bunny, bunny_rays):
    o, d = bunny_rays
    o, d = o[:600], d[:600]
    V, F = bunny.mesh_arrays(0)
    want_t, want_p = brute_force(V, F, o, d)
    h = bunny.intersect(o, d)
    both = np.isfinite(want_t) & h.hit
    # Hit or miss differs only for rays grazing an edge (a handful at most).
    assert (np.isfinite(want_t) != h.hit).sum() <= 3
    assert both.sum() > 200
    np.testing.assert_allclose(h.t[both], want_t[both], rtol=2e-5)
    same = h.prim_id[both] == want_p[both]
    assert same.mean() > 0.99
    # A shared edge's two triangles at the same t are both right.
    assert np.allclose(h.t[both][~same], want_t[both][~same], rtol=1e-5)


def test_packets_and_single_rays_agree(bunny):
    cam = lucent.Camera.look_at([-0.0168, 0.11, 0.40], [-0.0168, 0.11, -0.0015], fov=30, fov_axis="y", width=96, height=72)
    o, d = cam.rays()
    a = bunny.intersect(o, d, coherent=True)
    b = bunny.intersect(o, d, coherent=False)
    c = bunny.intersect(o, d)
    assert a.hit.mean() > 0.2
    np.testing.assert_array_equal(a.hit, b.hit)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(c.t, b.t)
    np.testing.assert_array_equal(a.prim_id[a.hit], b.prim_id[b.hit])
    # The camera's own trace: the same rays as packets, with depth along the view axis.
    tc = bunny.trace_camera(cam)
    np.testing.assert_array_equal(tc.t, a.t)
    f = np.asarray(cam.forward)
    np.testing.assert_allclose(tc.depth[tc.hit], (a.t * (d @ f))[a.hit], rtol=1e-6)
    assert np.isinf(tc.depth[~tc.hit]).all()
    np.testing.assert_allclose(a.depth_along(cam)[a.hit], tc.depth[tc.hit], rtol=1e-6)
    # One origin for all rays (broadcast) gives the same.
    e = bunny.intersect(o[0, 0], d)
    np.testing.assert_array_equal(e.t, a.t)


def test_occluded_count_and_all_hits_agree(bunny, bunny_rays):
    o, d = bunny_rays
    h = bunny.intersect(o, d)
    occ = bunny.occluded(o, d)
    np.testing.assert_array_equal(occ, h.hit)
    # Per-ray tmax just short of the closest hit: nothing in between.
    short = np.where(h.hit, h.t * 0.999, np.inf).astype(np.float32)
    assert not bunny.occluded(o, d, tmax=short)[h.hit].any()
    counts = bunny.count_hits(o, d)
    assert counts.dtype == np.int32
    a = bunny.intersect_all(o, d)
    np.testing.assert_array_equal(a.counts(), counts)
    np.testing.assert_array_equal(counts > 0, h.hit)
    assert counts.max() >= 4  # the bunny is crossed several times by some rays
    for i in np.nonzero(counts > 1)[0][:200]:
        hi = a.of(i)
        assert np.all(np.diff(hi["t"]) >= 0)
        assert hi["t"][0] == h.t[i]
        assert len(set(hi["prim_id"].tolist())) == len(hi["prim_id"])
    np.testing.assert_array_equal(a.ray_index, np.repeat(np.arange(len(o)), counts))
    capped = bunny.intersect_all(o, d, max_hits=2)
    np.testing.assert_array_equal(capped.counts(), np.minimum(counts, 2))
    # tmin past the first hit: the second becomes the closest.
    two = np.nonzero(counts >= 2)[0][:50]
    nxt = bunny.intersect(o[two], d[two], tmin=(h.t[two] * 1.0001).astype(np.float32))
    np.testing.assert_array_equal(nxt.t, a.t[a.splits[two] + 1])


def test_leading_shapes_and_dtypes():
    s = tri_scene()
    d = np.zeros((2, 3, 4, 3))
    d[..., 2] = -1
    h = s.intersect(np.array([0.1, 0.1, 1.0]), d)
    assert h.t.shape == (2, 3, 4) and h.uv.shape == (2, 3, 4, 2) and h.normal.shape == (2, 3, 4, 3)
    assert s.occluded([0.1, 0.1, 1.0], d).shape == (2, 3, 4)
    assert s.count_hits([0.1, 0.1, 1.0], d).shape == (2, 3, 4)
    assert s.intersect_all([0.1, 0.1, 1.0], d).counts().shape == (2, 3, 4)
    one = s.intersect([0.1, 0.1, 1.0], [0, 0, -1])
    assert one.t.shape == ()
    # Lists, ints and non-contiguous arrays are converted once.
    big = np.zeros((10, 6))
    big[:, 0:3] = [0.1, 0.1, 1]
    big[:, 5] = -1
    h2 = s.intersect(big[:, 0:3], big[:, 3:6])
    assert h2.hit.all()
    h3 = s.intersect([[0, 0, 1]], [[0, 0, -1]])  # an int list; the corner vertex
    assert h3.t.shape == (1,)


def test_fields_and_out_buffers(bunny, bunny_rays):
    o, d = bunny_rays
    h = bunny.intersect(o, d, fields=("t",))
    assert h.prim_id is None and h.t is not None
    with pytest.raises(ValueError, match="unknown field"):
        bunny.intersect(o, d, fields=("t", "colour"))
    first = bunny.intersect(o, d, fields=("t", "prim_id"))
    again = bunny.intersect(o[::-1].copy(), d[::-1].copy(), fields=("t", "prim_id"), out=first)
    assert again.t is first.t  # written in place
    np.testing.assert_array_equal(again.t, h.t[::-1])


def test_float64_far_from_the_origin_keeps_its_hits():
    # A unit grid of triangles 1e7 away: float32 spacing there is 1 (the grid would be lost).
    far = np.array([1.0e7, -2.0e7, 3.0e7])
    n = 20
    xs, ys = np.meshgrid(np.arange(n + 1) * 0.01, np.arange(n + 1) * 0.01)
    V = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1) + far
    F = []
    for y in range(n):
        for x in range(n):
            a = y * (n + 1) + x
            F += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    s = lucent.Scene()
    s.add_mesh(V, np.array(F))
    rng = np.random.default_rng(3)
    p = far + np.c_[rng.random((500, 2)) * 0.2, np.ones(500)]
    h = s.intersect(p, np.array([0, 0, -1.0]))
    assert h.hit.all()
    np.testing.assert_allclose(h.t, 1.0, atol=1e-5)
    # The hit triangle is the one under the point (cell of the grid).
    cell = np.floor((p[:, :2] - far[:2]) / 0.01).astype(int)
    np.testing.assert_array_equal(h.prim_id // 2, cell[:, 1] * n + cell[:, 0])
    pts = h.points
    np.testing.assert_allclose(pts[:, :2], p[:, :2], atol=1e-6)
    np.testing.assert_allclose(s.bounds[0], far, atol=1e-6)


def test_shapes_and_spheres():
    s = lucent.Scene()
    sph = s.add_shape("sphere", center=[0, 0, -5], radius=2)
    ids = s.add_spheres([[10, 0, -5], [20, 0, -5]], [1, 3])
    h = s.intersect([[0, 0, 0], [10, 0, 0], [20, 0, 0]], [0, 0, -1])
    np.testing.assert_allclose(h.t, [3, 4, 2], rtol=1e-5)
    np.testing.assert_array_equal(h.inst_id, [sph, ids[0], ids[1]])
    assert s.geometry_of(ids[0]) == s.geometry_of(ids[1]) != s.geometry_of(sph)
    np.testing.assert_allclose(h.normal, [[0, 0, 1]] * 3, atol=1e-5)
    # A sphere is crossed twice.
    a = s.intersect_all([0, 0, 0], [0, 0, -1])
    np.testing.assert_allclose(a.t, [3, 7], rtol=1e-5)
    box = lucent.Scene()
    box.add_shape("box", transform=np.diag([1.0, 2.0, 3.0, 1.0]))
    hb = box.intersect([[5, 0, 0], [0, 5, 0], [0, 0, 5]], [[-1, 0, 0], [0, -1, 0], [0, 0, -1]])
    np.testing.assert_allclose(hb.t, [4, 3, 2], rtol=1e-5)


def test_instances_move_without_a_rebuild_of_meshes():
    s = tri_scene()
    g = s.geometry_of(0)
    m = np.tile(np.eye(4), (3, 1, 1))
    m[:, 0, 3] = [10, 20, 30]
    ids = s.add_instances(g, m)
    np.testing.assert_array_equal(ids, [1, 2, 3])
    o = np.array([[0.2, 0.2, 1], [10.2, 0.2, 1], [20.2, 0.2, 1], [30.2, 0.2, 1]])
    h = s.intersect(o, [0, 0, -1])
    np.testing.assert_array_equal(h.inst_id, [0, 1, 2, 3])
    # Move instance 2 up by 5 in z: its ray now meets it at t = 1 - 5 (behind): a miss.
    m2 = m[1].copy()
    m2[2, 3] = -0.5
    s.set_transforms([2], m2[None])
    h = s.intersect(o, [0, 0, -1])
    np.testing.assert_allclose(h.t, [1, 1, 1.5, 1], rtol=1e-6)
    np.testing.assert_allclose(s.transforms[2], m2)
    # Remove instance 1: the others keep their ids.
    s.remove([1])
    h = s.intersect(o, [0, 0, -1])
    np.testing.assert_array_equal(h.inst_id, [0, -1, 2, 3])
    np.testing.assert_array_equal(s.instance_ids, [0, 2, 3])
    # Replace the vertices: every instance follows.
    s.update_vertices(g, TRI_V * 2)
    h = s.intersect(o + [0.5, 0.5, 0], [0, 0, -1])
    np.testing.assert_array_equal(h.hit, [True, False, True, True])
    # Same answers as a scene built afresh as it now stands.
    fresh = lucent.Scene()
    fresh.add_mesh(TRI_V * 2, TRI_F)
    fresh.add_instances(0, np.stack([m2, m[2]]))
    want = fresh.intersect(o + [0.5, 0.5, 0], [0, 0, -1])
    np.testing.assert_array_equal(h.t, want.t)


def test_animated_gltf_moves_with_time():
    s = lucent.load(SCENES / "gltf_animated/BoxAnimated.glb")
    lo, hi = s.bounds
    c = 0.5 * (lo + hi)
    cam = lucent.Camera.look_at(c + [0, 0, 4 * np.linalg.norm(hi - lo)], c, width=64, height=64)
    s.set_time(0.0)
    a = s.trace_camera(cam, fields=("t",)).t
    s.set_time(1.5)
    b = s.trace_camera(cam, fields=("t",)).t
    s.set_time(0.0)
    c0 = s.trace_camera(cam, fields=("t",)).t
    assert np.isfinite(a).sum() > 50
    assert not np.array_equal(a, b)
    np.testing.assert_array_equal(a, c0)


def test_every_file_kind_loads():
    from conftest import ROOT

    for path, kw in [
        (SCENES / "cornell_box/cornell_box.obj", {}),
        (SCENES / "stanford/bunny.ply", {}),
        (SCENES / "gltf_animated/CesiumMan.glb", {}),
        (ROOT / "tools/mitsuba/scenes/cornell_box.xml", {}),
    ]:
        s = lucent.load(path, **kw)
        assert s.num_triangles > 10, path
        lo, hi = s.bounds
        c = 0.5 * (lo + hi)
        assert s.intersect(c + [0, 0, 10 * np.linalg.norm(hi - lo)], [0, 0, -1]).t.shape == ()


def test_watertight_rays_do_not_leak_through_shared_edges():
    from conftest import DATA

    z = np.load(DATA / "compat.npz")
    V, F = z["ico_vertices"], z["ico_faces"]
    s = lucent.Scene(triangle_test="watertight")
    s.add_mesh(V, F)
    # From inside, straight at every vertex and every edge's midpoint (where two or more
    # triangles meet), and from points off the centre.
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    targets = np.concatenate([V, 0.5 * (V[edges[:, 0]] + V[edges[:, 1]])])
    rng = np.random.default_rng(5)
    for origin in [np.zeros(3), *(rng.random((4, 3)) - 0.5) * 0.8]:
        d = targets - origin
        h = s.intersect(origin, d, fields=("hit",))
        assert h.hit.all(), f"{(~h.hit).sum()} of {len(d)} rays leaked from {origin}"
        assert s.count_hits(origin, d).min() >= 1

"""Rendering to numpy: the CLI's images bit for bit, AOVs, the denoiser, the progressive
renderer, Ctrl-C, image files."""

import os
import signal
import subprocess
import threading

import numpy as np
import pytest

import lucent
from conftest import ROOT, SCENES, lucent_bin

CORNELL = SCENES / "cornell_box_original/CornellBox-Original.obj"
SIZE = (64, 48)


def cli_image(tmp_path, args):
    exe = lucent_bin()
    if exe is None:
        pytest.skip("no lucent binary (build it: cargo build --profile ci -p lucent)")
    out = tmp_path / "cli.exr"
    subprocess.run([exe, "render", *args, "-o", str(out)], check=True, capture_output=True)
    return lucent.read_image(out)


def same_through_exr(tmp_path, img):
    """An image as it reads back from an EXR (the CLI's output went through one)."""
    p = tmp_path / "py.exr"
    lucent.write_image(p, img)
    return lucent.read_image(p)


@pytest.mark.parametrize(
    "integrator, spp, extra",
    [("path", 4, []), ("whitted", 1, []), ("vpl", 1, []), ("path", 2, ["--camera", "0,1,3.9,0,1,0,0,1,0,40"])],
)
def test_render_is_the_cli_image_bit_for_bit(tmp_path, integrator, spp, extra):
    scene = lucent.load(CORNELL)
    cam = None
    if extra:
        v = [float(x) for x in extra[1].split(",")]
        cam = lucent.Camera.look_at(v[0:3], v[3:6], v[6:9], fov=v[9], fov_axis="y", width=SIZE[0], height=SIZE[1])
    img = lucent.render(scene, cam, width=SIZE[0], height=SIZE[1], spp=spp, integrator=integrator)
    assert img.shape == (SIZE[1], SIZE[0], 3) and img.dtype == np.float32
    assert img.mean() > 0.01
    want = cli_image(tmp_path, [str(CORNELL), "--size", f"{SIZE[0]}x{SIZE[1]}", "--spp", str(spp), "--integrator", integrator, *extra])
    got = same_through_exr(tmp_path, img)
    assert np.array_equal(got, want), f"{integrator}: max difference {np.abs(got - want).max()}"


def test_denoised_render_is_the_cli_image_bit_for_bit(tmp_path):
    """Denoised path tracing from 4 samples per pixel (the regression over the samples'
    halves) gives `lucent render --denoise`'s image, and keeps the raw image's mean."""
    scene = lucent.load(CORNELL)
    img = lucent.render(scene, width=SIZE[0], height=SIZE[1], spp=4, denoise=True)
    raw = lucent.render(scene, width=SIZE[0], height=SIZE[1], spp=4)
    want = cli_image(tmp_path, [str(CORNELL), "--size", f"{SIZE[0]}x{SIZE[1]}", "--spp", "4", "--denoise"])
    got = same_through_exr(tmp_path, img)
    assert np.array_equal(got, want), f"max difference {np.abs(got - want).max()}"
    assert abs(img.mean() / raw.mean() - 1) < 0.01
    # Smoother than the raw samples: neighbouring pixels differ less.
    rough = lambda a: float(np.abs(np.diff(a, axis=1)).mean())
    assert rough(img) < 0.7 * rough(raw)


def test_aovs_and_denoise(tmp_path):
    scene = lucent.load(CORNELL)
    img, aov = lucent.render(scene, width=64, height=48, spp=2, aovs=("albedo", "normal", "depth", "prim_id", "inst_id", "geom_id"))
    assert aov["albedo"].shape == (48, 64, 3) and aov["depth"].shape == (48, 64)
    assert aov["prim_id"].dtype == np.int32 and (aov["prim_id"] >= 0).mean() > 0.2
    # The id image is what tracing the pixel centres finds.
    cam = scene.default_camera(64, 48)
    tc = scene.trace_camera(cam, fields=("prim_id", "inst_id"))
    np.testing.assert_array_equal(aov["prim_id"], tc.prim_id)
    np.testing.assert_array_equal(aov["inst_id"], tc.inst_id)
    # Denoising brings a 2-sample image closer to a 64-sample one.
    ref = lucent.render(scene, width=64, height=48, spp=64)
    den = lucent.render(scene, width=64, height=48, spp=2, denoise=True)
    err = lambda a: float(np.mean((a - ref) ** 2 / (ref**2 + 1e-2)))
    assert err(den) < 0.5 * err(img)
    den2 = lucent.denoise(img, albedo=aov["albedo"], normal=aov["normal"], depth=aov["depth"])
    np.testing.assert_array_equal(den2, den)
    with pytest.raises(ValueError, match="albedo: shape"):
        lucent.denoise(img, albedo=aov["albedo"][:10], normal=aov["normal"], depth=aov["depth"])
    with pytest.raises(ValueError, match="aovs: unknown AOV"):
        lucent.render(scene, width=8, height=8, aovs=("colour",))
    with pytest.raises(ValueError, match="integrator"):
        lucent.render(scene, width=8, height=8, integrator="bidir")


def test_progressive_steps_reach_the_render():
    scene = lucent.load(CORNELL)
    r = lucent.Renderer(scene, width=32, height=24)
    assert r.spp == 0
    r.step(4)
    assert r.spp == 4
    np.testing.assert_array_equal(r.image, lucent.render(scene, width=32, height=24, spp=4))
    r.step(2)
    r.step(2)
    assert r.spp == 8
    # Steps take the samples one render of as many takes (the sums only rounded apart).
    r2 = lucent.Renderer(scene, width=32, height=24)
    r2.step(3)
    r2.step(5)
    np.testing.assert_allclose(r2.image, lucent.render(scene, width=32, height=24, spp=8), rtol=0, atol=1e-6)
    ref = lucent.render(scene, width=32, height=24, spp=64)
    e8 = float(np.mean((r.image - ref) ** 2))
    r.reset()
    r.step(1)
    e1 = float(np.mean((r.image - ref) ** 2))
    assert e8 < e1


def test_ctrl_c_stops_a_render_between_bands():
    scene = lucent.load(CORNELL)
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    import time

    start = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        lucent.render(scene, width=512, height=512, spp=4096)
    assert time.perf_counter() - start < 20
    timer.cancel()


def test_calibrated_camera_renders_what_it_traces():
    scene = lucent.load(CORNELL)
    K = np.array([[50.0, 0, 30.0], [0, 50.0, 26.0], [0, 0, 1]])
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])  # x right, y down, z forward = -z world
    pose[:3, 3] = [0, 1, 3.9]
    cam = lucent.Camera.from_intrinsics(K, pose=pose, width=64, height=48)
    ext = np.linalg.inv(pose)
    cam2 = lucent.Camera.from_intrinsics(K, extrinsic=ext, width=64, height=48)
    o, d = cam.rays()
    o2, d2 = cam2.rays()
    np.testing.assert_allclose(d, d2, atol=1e-6)
    # Pixel (x, y) looks along ((x + .5 - cx) / fx, (y + .5 - cy) / fy, 1) in the camera.
    want = np.array([(10 + 0.5 - 30) / 50, -(20 + 0.5 - 26) / 50, -1.0])
    np.testing.assert_allclose(d[20, 10], want / np.linalg.norm(want), atol=1e-6)
    img, aov = lucent.render(scene, cam, spp=1, integrator="whitted", aovs=("prim_id",))
    assert img.shape == (48, 64, 3)
    np.testing.assert_array_equal(aov["prim_id"], scene.trace_camera(cam, fields=("prim_id",)).prim_id)


def test_images_write_and_read(tmp_path):
    img = np.random.default_rng(1).random((12, 16, 3)).astype(np.float32)
    lucent.write_image(tmp_path / "a.exr", img)
    np.testing.assert_array_equal(lucent.read_image(tmp_path / "a.exr"), img)
    lucent.write_image(tmp_path / "a.png", img)
    back = lucent.read_image(tmp_path / "a.png")
    assert back.shape == img.shape
    with pytest.raises(FileNotFoundError):
        lucent.read_image(tmp_path / "none.exr")
    with pytest.raises(ValueError, match="image: shape"):
        lucent.write_image(tmp_path / "b.exr", img[..., :2])


def test_readme_examples_run(tmp_path):
    """The README's Python section, run as written (its code blocks, in order)."""
    text = (ROOT / "README.md").read_text()
    start = text.index("<!-- python-examples -->")
    end = text.index("<!-- /python-examples -->")
    blocks = [b.split("```", 1)[0] for b in text[start:end].split("```python")[1:]]
    assert len(blocks) >= 3
    env = {"__name__": "readme", "SHARED": str(ROOT.parent / "shared")}
    cwd = os.getcwd()
    try:
        os.chdir(tmp_path)
        for b in blocks:
            exec(compile(b, "README.md", "exec"), env)
    finally:
        os.chdir(cwd)


def test_a_scene_from_arrays_renders_with_its_materials_and_lights():
    s = lucent.Scene()
    s.add_mesh([[-5, 0, -5], [5, 0, -5], [5, 0, 5], [-5, 0, 5]], [[0, 2, 1], [0, 3, 2]], material={"diffuse": [0.8, 0.1, 0.1]})
    s.add_shape("sphere", center=[0, 1, 0], radius=1, material={"diffuse": 0.7})
    s.add_light("point", position=[0, 4, 3], color=[30, 30, 30])
    cam = lucent.Camera.look_at([0, 2, 6], [0, 1, 0], width=48, height=36)
    img = lucent.render(s, cam, spp=1, integrator="whitted")
    floor = img[-3, 24]
    assert floor[0] > 3 * floor[1] > 0  # the red floor, lit
    path = lucent.render(s, cam, spp=4, integrator="path")
    assert path[-3, 24, 0] > path[-3, 24, 1]


def test_the_stubs_type_check():
    api = pytest.importorskip("mypy.api")
    out, err, code = api.run(["--ignore-missing-imports", "-p", "lucent"])
    assert code == 0, out + err


def test_a_crop_window_is_the_cli_image(tmp_path):
    """A Mitsuba film's crop window: the image (and its AOVs) is the window, as the CLI writes it."""
    path = ROOT / "crates/render/tests/data/mitsuba/crop_window/scene.xml"
    scene = lucent.load(path)
    img, aovs = lucent.render(scene, spp=3, aovs=["depth", "prim_id"])
    assert img.shape == (36, 40, 3) and aovs["depth"].shape == (36, 40) and aovs["prim_id"].shape == (36, 40)
    want = cli_image(tmp_path, [str(path), "--spp", "3"])
    assert np.array_equal(same_through_exr(tmp_path, img), want)
    # Given a size, the whole film.
    assert lucent.render(scene, width=96, height=64, spp=1).shape == (64, 96, 3)

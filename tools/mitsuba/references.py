"""Makes the reference data of lucent's Mitsuba tests (crates/render/tests/mitsuba.rs):
for each scene of tools/mitsuba/scenes (or those named), Mitsuba 3's render at 4096
samples per pixel (seed 100), and Mitsuba's own relMSE against it at 64 and 1024 samples:
its median over 16 seeds (64) and 4 seeds (1024), since one render's relMSE swings several
fold with its few brightest pixels; the bar lucent must meet is 1.1x the median. Writes, per scene, into
crates/render/tests/data/mitsuba/<scene>/: scene.xml (and the files it needs),
reference_4096spp.exr and mitsuba.json (the relMSEs and Mitsuba's timings, second render).

    tools/mitsuba/python tools/mitsuba/references.py [SCENE ...]

relMSE = mean((x - ref)^2 / (ref^2 + 0.01)) over pixels and channels (issue 34).
"""
import json
import os
import shutil
import sys
import time

import mitsuba as mi
import plain

mi.set_variant("llvm_ad_rgb")
import drjit as dr  # noqa: E402
import numpy as np  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
OUT = os.path.join(ROOT, "crates", "render", "tests", "data", "mitsuba")
SCENES = ["cornell_box", "materials", "envmap", "bunny", "sponza", "lamps", "crop_window", "serialized", "filter_gaussian", "filter_lanczos", "filter_mitchell", "uv_conventions", "normalmap", "blendbsdf", "bumpmap", "mask", "crop_gaussian", "uv_shapes", "rough_checker", "anisotropic", "principled", "plaza", "hall"]
# Files a scene reads beside it.
EXTRA = {
    "envmap": ["sky.exr"],
    "serialized": [
        "matpreview_plane_interior.serialized",
        "rectangle_normals_uv.serialized",
        "rectangle_uv.serialized",
        "rectangle_normals.serialized",
    ],
    "uv_conventions": ["uv_quad.png", "uv_rect.obj", "uv_rect.ply", "rectangle_uv.serialized"],
    "normalmap": ["normalmap_bumps.png"],
    "blendbsdf": ["blend_weight.png"],
    "bumpmap": ["bumpmap_height.png"],
    "mask": ["blend_weight.png"],
    "uv_shapes": ["uv_quad.png"],
}


def rel_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))


def render(scene, spp, seed):
    t = time.time()
    img = mi.render(scene, spp=spp, seed=seed)
    dr.eval(img)
    dr.sync_thread()
    return np.array(img)[..., :3], time.time() - t


def main():
    names = sys.argv[1:] or SCENES
    for name in names:
        src = os.path.join(HERE, "scenes", name + ".xml")
        scene = mi.load_file(src, **plain.defines(src, {}))
        ref, t_ref = render(scene, 4096, 100)
        out = {"scene": name, "reference_spp": 4096, "reference_seed": 100}
        for spp, seeds in ((64, 16), (1024, 4)):
            render(scene, spp, 1000)  # first render: JIT compilation
            errors, times = [], []
            for seed in range(seeds):
                img, t = render(scene, spp, seed)
                errors.append(rel_mse(img, ref))
                times.append(t)
            out[f"relmse_{spp}"] = float(np.median(errors))
            out[f"relmse_{spp}_all"] = errors
            out[f"seconds_{spp}"] = float(np.median(times))
            out[f"samples_per_second_{spp}"] = img.shape[0] * img.shape[1] * spp / float(np.median(times))
        d = os.path.join(OUT, name)
        os.makedirs(d, exist_ok=True)
        shutil.copy(src, os.path.join(d, "scene.xml"))
        for f in EXTRA.get(name, []):
            shutil.copy(os.path.join(HERE, "scenes", f), os.path.join(d, f))
        mi.Bitmap(ref).write(os.path.join(d, "reference_4096spp.exr"))
        with open(os.path.join(d, "mitsuba.json"), "w") as f:
            json.dump(out, f, indent=1)
        print(name, {k: v for k, v in out.items() if k.startswith("relmse") or k.startswith("seconds")}, f"reference {t_ref:.1f} s")


if __name__ == "__main__":
    main()

"""Mitsuba 3's `aov` integrator on tools/mitsuba/scenes/aov.xml, for lucent's test of its
layers (crates/render/tests/layers.rs): the layers (not the noisy image) at 1024 samples per
pixel, seed 0, as half floats, with the scene, into crates/render/tests/data/mitsuba/aov/.

    tools/mitsuba/python tools/mitsuba/aov_reference.py
"""
import os
import shutil

import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
import numpy as np  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "..", "crates", "render", "tests", "data", "mitsuba", "aov")


def main():
    src = os.path.join(HERE, "scenes", "aov.xml")
    scene = mi.load_file(src)
    mi.render(scene, spp=1024, seed=0)
    bmp = scene.sensors()[0].film().bitmap()
    a = np.array(bmp)
    st = bmp.struct_()
    names = [st[i].name for i in range(len(st))]
    keep = [i for i, n in enumerate(names) if "." in n and not n.startswith("my_image.") or n == "A"]
    out = mi.Bitmap(a[..., keep].astype(np.float16), mi.Bitmap.PixelFormat.MultiChannel, [names[i] for i in keep])
    os.makedirs(OUT, exist_ok=True)
    out.write(os.path.join(OUT, "layers_1024spp.exr"))
    shutil.copy(src, os.path.join(OUT, "scene.xml"))
    shutil.copy(os.path.join(HERE, "scenes", "uv_rect.obj"), os.path.join(OUT, "uv_rect.obj"))
    print([names[i] for i in keep])


if __name__ == "__main__":
    main()

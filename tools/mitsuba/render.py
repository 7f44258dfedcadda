"""Renders a Mitsuba 3 scene with the llvm_ad_rgb variant and writes a linear EXR.

    tools/mitsuba/python tools/mitsuba/render.py SCENE.xml OUT.exr [--spp N] [--seed S] [-D NAME=VALUE ...]
    tools/mitsuba/python tools/mitsuba/render.py cornell OUT.exr   (Mitsuba's cornell_box())

Prints the seconds of the first render (with JIT compilation) and of a second one (what
issue 34's speed comparison uses), and samples per second of the second.
"""
import argparse
import time

import mitsuba as mi
import plain

mi.set_variant("llvm_ad_rgb")
import drjit as dr  # noqa: E402  (after the variant is chosen)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", help="a Mitsuba XML file, or 'cornell' for mi.cornell_box()")
    ap.add_argument("out", help="the EXR to write")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("-D", dest="defines", action="append", default=[], help="a scene parameter NAME=VALUE")
    a = ap.parse_args()
    defines = dict(d.split("=", 1) for d in a.defines)
    scene = mi.load_dict(mi.cornell_box()) if a.scene == "cornell" else mi.load_file(a.scene, **plain.defines(a.scene, defines))
    times = []
    for run in range(2):
        t = time.time()
        img = mi.render(scene, spp=a.spp, seed=a.seed + run)
        dr.eval(img)
        dr.sync_thread()
        times.append(time.time() - t)
    film = scene.sensors()[0].film().size()
    mi.util.write_bitmap(a.out, img)
    print(f"first {times[0]:.3f} s, second {times[1]:.3f} s, "
          f"{film[0] * film[1] * a.spp / times[1]:.3e} samples/s ({film[0]}x{film[1]}, {a.spp} spp)")


if __name__ == "__main__":
    main()

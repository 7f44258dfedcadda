"""lucent against Mitsuba 3 on the Mitsuba project's own scenes: the documentation scenes
of mitsuba-renderer/mitsuba-data (docs/scenes/*.xml, most of them its material-preview
scene with one plugin each) and its scenes/ folder, rendered by both at a reduced size.

    tools/mitsuba/python tools/mitsuba/docs_scenes.py MITSUBA_DATA LUCENT_BINARY OUT.tsv [NAME ...]

MITSUBA_DATA is a checkout of mitsuba-data (`git clone
https://github.com/mitsuba-renderer/mitsuba-data`), LUCENT_BINARY a release build of
`lucent`. The scenes are copied to target/mitsuba-docs/ with their films cut to 160 x 120
(both renderers read the same files). Per scene: whether Mitsuba's llvm_ad_rgb renders it
(polarized, spectral-only and volume scenes it refuses), the warnings lucent prints while
loading (what it leaves out or reads otherwise), Mitsuba's reference (512 samples a
pixel), relMSE at 64 samples of both against it (one seed each,
lucent's one render), and the render times (Mitsuba's second render; lucent's whole
command, loading included). relMSE = mean((x - ref)^2 / (ref^2 + 0.01)).
"""
import glob
import os
import re
import shutil
import subprocess
import sys
import time

import mitsuba as mi
import numpy as np
from references import rel_mse, render  # (sets the variant: llvm_ad_rgb)

HERE = os.path.dirname(os.path.abspath(__file__))
WORK = os.path.join(HERE, "..", "..", "target", "mitsuba-docs")
SIZE = (160, 120)
REF_SPP = 512
SEEDS = 1


def shrink(path):
    """Films cut to SIZE (keeping the aspect of the common 4:3 films; other films scaled to
    the same width)."""
    text = open(path).read()
    w = re.search(r'name="width"\s+value="(\d+)"', text)
    h = re.search(r'name="height"\s+value="(\d+)"', text)
    if not (w and h):
        return
    W, H = int(w.group(1)), int(h.group(1))
    nw, nh = SIZE[0], max(1, round(SIZE[0] * H / W))
    text = re.sub(r'(name="width"\s+value=")\d+"', rf'\g<1>{nw}"', text)
    text = re.sub(r'(name="height"\s+value=")\d+"', rf'\g<1>{nh}"', text)
    open(path, "w").write(text)


def mitsuba_render(path, spp, seed):
    return render(mi.load_file(path, spp=spp), spp, seed)


def main():
    data, binary, out = sys.argv[1:4]
    names = sys.argv[4:]
    if os.path.exists(WORK):
        shutil.rmtree(WORK)
    shutil.copytree(os.path.join(data, "docs", "scenes"), os.path.join(WORK, "docs", "scenes"))
    shutil.copytree(os.path.join(data, "common"), os.path.join(WORK, "common"))
    shutil.copytree(os.path.join(data, "scenes"), os.path.join(WORK, "scenes"))
    for f in glob.glob(os.path.join(WORK, "**", "*.xml"), recursive=True):
        shrink(f)
    scenes = sorted(glob.glob(os.path.join(WORK, "docs", "scenes", "*.xml")) + glob.glob(os.path.join(WORK, "scenes", "*", "*.xml")))
    rows = ["scene\tmitsuba\tlucent_warnings\trelmse_mitsuba_64\trelmse_lucent_64\tratio\tseconds_mitsuba_64\tseconds_lucent_64"]
    for path in scenes:
        name = os.path.relpath(path, WORK)
        if names and not any(n in name for n in names):
            continue
        # (The sampler scenes differ from each other only in Mitsuba's sampler; the
        # polarized ones need its polarized variants.)
        if not names and any(k in name for k in ("sampler_", "stokes", "polarize", "measured")):
            continue
        try:
            ref, _ = mitsuba_render(path, REF_SPP, 100)
            mitsuba_render(path, 64, 1000)  # (compiles)
            runs = [mitsuba_render(path, 64, s) for s in range(SEEDS)]
            e_m = float(np.median([rel_mse(x, ref) for x, _ in runs]))
            t_m = float(np.median([t for _, t in runs]))
            status = "renders"
        except Exception as e:  # noqa: BLE001
            rows.append(f"{name}\trefused: {str(e).splitlines()[0][:80]}\t\t\t\t\t\t")
            print(rows[-1], flush=True)
            continue
        exr = os.path.join(WORK, "lucent.exr")
        t = time.time()
        # (Scenes that read `$spp` get it as Mitsuba did.)
        p = subprocess.run([binary, "render", path, "-D", "spp=64", "--spp", "64", "--no-denoise", "-o", exr], capture_output=True, text=True)
        t_l = time.time() - t
        warnings = "; ".join(sorted({re.sub(r"^.*?: ", "", l.strip())[:70] for l in p.stderr.splitlines() if "WARN" in l}))
        if p.returncode != 0:
            rows.append(f"{name}\t{status}\tfails: {p.stderr.strip().splitlines()[-1][:100]}\t{e_m:.5f}\t\t\t{t_m:.2f}\t")
        else:
            img = np.array(mi.Bitmap(exr))[..., :3]
            if img.shape != ref.shape:
                rows.append(f"{name}\t{status}\tsize {img.shape} vs {ref.shape}\t{e_m:.5f}\t\t\t{t_m:.2f}\t{t_l:.2f}")
            else:
                e_l = rel_mse(img, ref)
                rows.append(f"{name}\t{status}\t{warnings}\t{e_m:.5f}\t{e_l:.5f}\t{e_l / e_m:.2f}\t{t_m:.2f}\t{t_l:.2f}")
        print(rows[-1], flush=True)
    open(out, "w").write("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()

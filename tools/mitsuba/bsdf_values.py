"""Evaluates Mitsuba 3's BSDF plugins at fixed direction pairs, for lucent's BSDF test
(crates/render/tests/bsdf.rs) to compare against without Mitsuba.

    tools/mitsuba/python tools/mitsuba/bsdf_values.py OUT.json

For each BSDF (a Mitsuba dict, written out in the JSON beside its values): `eval` at 64
pairs (wo toward the viewer, wi toward the light, local frame, both hemispheres; Mitsuba
calls them si.wi and wo) and `pdf` there, and for delta lobes the direction, weight and probability that
`sample` returns for the lobe-choice numbers 0.001 and 0.999 at 16 viewing directions.
"""
import json
import sys

import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
import drjit as dr  # noqa: E402
import numpy as np  # noqa: E402

BSDFS = {
    "diffuse": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.5, 0.2]}},
    "conductor_au": {"type": "conductor", "material": "Au"},
    "conductor_none_tinted": {"type": "conductor", "specular_reflectance": {"type": "rgb", "value": [0.9, 0.6, 0.3]}},
    "roughconductor_cu_ggx": {"type": "roughconductor", "material": "Cu", "distribution": "ggx", "alpha": 0.3},
    "roughconductor_al_beckmann": {"type": "roughconductor", "material": "Al", "distribution": "beckmann", "alpha": 0.2},
    "dielectric": {"type": "dielectric"},
    "dielectric_water": {"type": "dielectric", "int_ior": "water", "ext_ior": "air"},
    "roughdielectric_ggx": {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3, "int_ior": 1.5, "ext_ior": 1.0},
    "roughdielectric_beckmann": {"type": "roughdielectric", "distribution": "beckmann", "alpha": 0.1, "int_ior": 1.33, "ext_ior": 1.0},
    "thindielectric": {"type": "thindielectric", "int_ior": 1.5, "ext_ior": 1.0},
    "plastic": {"type": "plastic", "diffuse_reflectance": {"type": "rgb", "value": [0.3, 0.5, 0.7]}},
    "plastic_nonlinear": {"type": "plastic", "diffuse_reflectance": {"type": "rgb", "value": [0.8, 0.2, 0.1]}, "nonlinear": True, "int_ior": 1.7},
    "roughplastic_ggx": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.2, "diffuse_reflectance": {"type": "rgb", "value": [0.2, 0.6, 0.4]}},
    "roughplastic_beckmann": {"type": "roughplastic", "diffuse_reflectance": {"type": "rgb", "value": [0.6, 0.3, 0.2]}, "nonlinear": True},
    "roughconductor_al_aniso_ggx": {"type": "roughconductor", "material": "Al", "distribution": "ggx", "alpha_u": 0.05, "alpha_v": 0.3},
    "roughconductor_cu_aniso_beckmann": {"type": "roughconductor", "material": "Cu", "distribution": "beckmann", "alpha_u": 0.4, "alpha_v": 0.1},
    "roughdielectric_aniso_ggx": {"type": "roughdielectric", "distribution": "ggx", "alpha_u": 0.1, "alpha_v": 0.35, "int_ior": 1.5, "ext_ior": 1.0},
    "principled_default": {"type": "principled"},
    "principled_reflective": {
        "type": "principled", "base_color": {"type": "rgb", "value": [0.8, 0.5, 0.3]}, "roughness": 0.5, "anisotropic": 0.5,
        "metallic": 0.3, "spec_tint": 0.4, "sheen": 0.5, "sheen_tint": 0.5, "flatness": 0.3, "clearcoat": 0.8, "clearcoat_gloss": 0.6,
    },
    "principled_transmissive": {
        "type": "principled", "base_color": {"type": "rgb", "value": [0.9, 0.8, 0.6]}, "roughness": 0.3, "metallic": 0.2,
        "spec_trans": 0.7, "eta": 1.4, "spec_tint": 0.3, "clearcoat": 0.5,
    },
}


def directions(rng, n, lower):
    """Unit vectors, a share of them in the lower hemisphere."""
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2]) * np.where(rng.random(n) < lower, -1, 1)
    return v


def spectra(x, n):
    """A Mitsuba spectrum (possibly a broadcast literal) as an n x 3 list."""
    a = np.array(mi.Color3f(x), dtype=float).reshape(3, -1)
    return np.nan_to_num(np.broadcast_to(a, (3, n))).T.tolist()


def interaction(wo):
    si = dr.zeros(mi.SurfaceInteraction3f, len(wo))
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(si.n)
    si.uv = mi.Point2f(0.5, 0.5)
    si.wi = mi.Vector3f(wo[:, 0], wo[:, 1], wo[:, 2])
    return si


def main():
    rng = np.random.default_rng(7)
    wo = directions(rng, 64, 0.25)
    wi = directions(rng, 64, 0.4)
    # A few exact mirror and straight-through pairs are irrelevant for glossy lobes; the
    # random ones cover both hemispheres.
    ctx = mi.BSDFContext()
    out = {"pairs": {"wo": wo.tolist(), "wi": wi.tolist()}, "bsdfs": {}}
    for name, d in BSDFS.items():
        b = mi.load_dict(d)
        entry = {"dict": d}
        si = interaction(wo)
        v = b.eval(ctx, si, mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2]))
        entry["eval"] = spectra(v, len(wo))
        entry["pdf"] = np.nan_to_num(np.array(b.pdf(ctx, si, mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2])), dtype=float)).tolist()
        # Delta lobes through sample(): lobe choices 0.001 and 0.999.
        vw = directions(rng, 16, 0.3)
        samples = []
        for u in (0.001, 0.999):
            si = interaction(vw)
            bs, weight = b.sample(ctx, si, mi.Float(np.full(16, u)), mi.Point2f(np.full(16, 0.37), np.full(16, 0.61)))
            samples.append({
                "u": u,
                "wo": vw.tolist(),
                "wi": np.nan_to_num(np.array(bs.wo)).T.tolist(),
                "weight": spectra(weight, 16),
                "pdf": np.nan_to_num(np.broadcast_to(np.array(bs.pdf, dtype=float).reshape(-1), (16,))).tolist(),
                "delta": [bool(x) for x in np.array(mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta))],
            })
        entry["samples"] = samples
        out["bsdfs"][name] = entry
    with open(sys.argv[1], "w") as f:
        json.dump(out, f, indent=0)
    print(f"{len(BSDFS)} BSDFs written to {sys.argv[1]}")


if __name__ == "__main__":
    main()

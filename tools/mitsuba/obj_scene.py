"""Writes a Mitsuba 3 scene of an OBJ file as lucent reads it, for reference renders.

    python3 tools/mitsuba/obj_scene.py SCENE.obj OUT_DIR --camera EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV
        [--size WxH] [--spp N]

Splits the OBJ by material into one OBJ per material (Mitsuba's obj loader gives a file one
BSDF) and writes OUT_DIR/scene.xml: a `diffuse` BSDF of each material's Kd, an `area`
emitter of its emission (Ke, or, as lucent's MTL reader does, an ambient Ka above 1 when
there is no Ke), a `perspective` sensor with the camera's vertical field of view, an
`hdrfilm` with a box filter (lucent's pixel samples are uniform over the pixel and weigh
the same), and the `path` integrator with Mitsuba's defaults (max_depth -1, rr_depth 5),
as lucent's `--integrator path`. Only diffuse and emitting materials are written (what the
path tracer reads of an MTL file today); other MTL terms are ignored.
"""
import argparse
import os


def parse_mtl(path):
    mats, cur = {}, None
    for line in open(path):
        t = line.split()
        if not t:
            continue
        if t[0] == "newmtl":
            cur = mats.setdefault(t[1], {"Kd": (0.7, 0.7, 0.7), "Ke": None, "Ka": (0.0, 0.0, 0.0)})
        elif cur is not None and t[0] in ("Kd", "Ke", "Ka"):
            cur[t[0]] = tuple(float(x) for x in t[1:4])
    return mats


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("obj")
    ap.add_argument("out")
    ap.add_argument("--camera", required=True)
    ap.add_argument("--size", default="256x256")
    ap.add_argument("--spp", type=int, default=64)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    verts, faces, mtllib, mat = [], {}, None, "default"
    for line in open(a.obj):
        t = line.split()
        if not t:
            continue
        if t[0] == "v":
            verts.append(t[1:4])
        elif t[0] == "mtllib":
            mtllib = os.path.join(os.path.dirname(a.obj), t[1])
        elif t[0] == "usemtl":
            mat = t[1]
        elif t[0] == "f":
            idx = [int(v.split("/")[0]) for v in t[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            # Fans, as lucent triangulates polygons.
            for k in range(1, len(idx) - 1):
                faces.setdefault(mat, []).append((idx[0], idx[k], idx[k + 1]))
    mats = parse_mtl(mtllib) if mtllib else {}
    cam = [float(x) for x in a.camera.split(",")]
    w, h = (int(x) for x in a.size.lower().split("x"))
    shapes = []
    for name, tris in faces.items():
        used = sorted({i for t in tris for i in t})
        remap = {old: new + 1 for new, old in enumerate(used)}
        fn = f"{name}.obj"
        with open(os.path.join(a.out, fn), "w") as f:
            for i in used:
                f.write("v " + " ".join(verts[i]) + "\n")
            for t in tris:
                f.write("f " + " ".join(str(remap[i]) for i in t) + "\n")
        m = mats.get(name, {"Kd": (0.7, 0.7, 0.7), "Ke": None, "Ka": (0, 0, 0)})
        ke = m["Ke"] if m["Ke"] is not None else (m["Ka"] if max(m["Ka"]) > 1.0 else None)
        rgb = lambda c: ", ".join(f"{x:g}" for x in c)  # noqa: E731
        emitter = f'\n        <emitter type="area"><rgb name="radiance" value="{rgb(ke)}"/></emitter>' if ke and max(ke) > 0 else ""
        shapes.append(
            f'    <shape type="obj">\n        <string name="filename" value="{fn}"/>\n'
            f'        <boolean name="face_normals" value="true"/>\n'
            f'        <bsdf type="diffuse"><rgb name="reflectance" value="{rgb(m["Kd"])}"/></bsdf>{emitter}\n    </shape>'
        )
    xml = f"""<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="-1"/><integer name="rr_depth" value="5"/></integrator>
    <sensor type="perspective">
        <string name="fov_axis" value="y"/>
        <float name="fov" value="{cam[9]:g}"/>
        <transform name="to_world">
            <lookat origin="{cam[0]:g}, {cam[1]:g}, {cam[2]:g}" target="{cam[3]:g}, {cam[4]:g}, {cam[5]:g}" up="{cam[6]:g}, {cam[7]:g}, {cam[8]:g}"/>
        </transform>
        <sampler type="independent"><integer name="sample_count" value="{a.spp}"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="{w}"/><integer name="height" value="{h}"/>
            <rfilter type="box"/>
            <string name="pixel_format" value="rgb"/>
        </film>
    </sensor>
{chr(10).join(shapes)}
</scene>
"""
    open(os.path.join(a.out, "scene.xml"), "w").write(xml)
    print(f"wrote {a.out}/scene.xml with {len(shapes)} shapes")


if __name__ == "__main__":
    main()

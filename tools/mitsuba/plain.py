"""Mitsuba reads no gzip: the shared scenes a scene names through `$scenes` (the `scenes`
parameter), with every `.gz` file among them unzipped, in a folder of their own.

    defines = plain.defines(xml_path, defines)   # then mi.load_file(xml_path, **defines)

OBJ files lose their vertex normals (see `flat_obj`). The copy keeps each file's name (an unzipped `sponza.obj.gz` is plain OBJ text; Mitsuba's
OBJ reader does not look at the name), under target/mitsuba-plain/, made once.
"""
import gzip
import os
import re

HERE = os.path.dirname(os.path.abspath(__file__))
CACHE = os.path.join(HERE, "..", "..", "target", "mitsuba-plain")


def flat_obj(data):
    """An OBJ without its vertex normals (Mitsuba refuses files with normals that are not
    of unit length, as Sponza's 218 of 39,999; the scenes that read such a file ask for
    face normals, as lucent does then too)."""
    out = []
    for line in data.split(b"\n"):
        t = line.split()
        if t[:1] == [b"vn"]:
            continue
        if t[:1] == [b"f"]:
            line = b"f " + b" ".join(b"/".join(v.split(b"/")[:2]) for v in t[1:])
        out.append(line)
    return b"\n".join(out)


def defines(xml, given):
    text = open(xml).read()
    names = re.findall(r'value="\$scenes/([^"]+)"', text)
    if not names:
        return given
    out = dict(given)
    src = out.get("scenes")
    if src is None:
        m = re.search(r'<default name="scenes" value="([^"]+)"', text)
        src = os.path.join(os.path.dirname(os.path.abspath(xml)), m.group(1)) if m else None
    if src is None or not any(n.endswith(".gz") for n in names):
        return given
    for n in names:
        dst = os.path.join(CACHE, n)
        if os.path.exists(dst):
            continue
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        if n.endswith(".gz"):
            with gzip.open(os.path.join(src, n), "rb") as f:
                data = f.read()
            if n.endswith(".obj.gz"):
                data = flat_obj(data)
            with open(dst + ".part", "wb") as g:
                g.write(data)
            os.replace(dst + ".part", dst)
        else:
            os.symlink(os.path.abspath(os.path.join(src, n)), dst)
    out["scenes"] = os.path.abspath(CACHE)
    return out

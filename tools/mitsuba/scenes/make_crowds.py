"""Writes two scenes of many lights (the light tree's, issue 58 part 3), with a fixed seed:

- plaza.xml (tuned on): a square at night between two rows of houses, 60 sphere lamps of
  warm and cold colours on a grid of heights, 24 point lights, a dim sky; 84 lights.
- hall.xml (held out: written with plaza.xml, rendered and compared only once the tree
  was settled on plaza): a long hall with 36 ceiling panels facing down, 12 disk lamps on
  the walls facing in, 10 spot lights aimed at the floor and 3 boxes; 58 lights, no sky.

    python3 tools/mitsuba/scenes/make_crowds.py
"""
import os
import random

HERE = os.path.dirname(os.path.abspath(__file__))

HEAD = """<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="6"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="{fov}"/>
        <transform name="to_world"><lookat origin="{origin}" target="{target}" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="64"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/><rfilter type="box"/></film>
    </sensor>
    <bsdf type="diffuse" id="ground"><rgb name="reflectance" value="0.45, 0.42, 0.4"/></bsdf>
    <bsdf type="diffuse" id="wall"><rgb name="reflectance" value="0.6, 0.55, 0.5"/></bsdf>
    <bsdf type="roughplastic" id="plastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/><rgb name="diffuse_reflectance" value="0.2, 0.3, 0.5"/></bsdf>
"""


def box(lo, hi, bsdf):
    c = [(a + b) / 2 for a, b in zip(lo, hi)]
    s = [(b - a) / 2 for a, b in zip(lo, hi)]
    return (f'    <shape type="cube"><transform name="to_world"><scale x="{s[0]:.4f}" y="{s[1]:.4f}" z="{s[2]:.4f}"/>'
            f'<translate x="{c[0]:.4f}" y="{c[1]:.4f}" z="{c[2]:.4f}"/></transform><ref id="{bsdf}"/></shape>\n')


def colour(r, scale):
    warm = r.random() < 0.6
    base = (1.0, 0.75, 0.45) if warm else (0.55, 0.7, 1.0)
    k = scale * (0.4 + 1.6 * r.random())
    return ", ".join(f"{k * c:.4f}" for c in base)


def plaza():
    r = random.Random(58)
    out = HEAD.format(fov=55, origin="0, 2.2, 14", target="0, 1.2, 0", w=96, h=64)
    out += '    <emitter type="constant"><rgb name="radiance" value="0.004, 0.005, 0.012"/></emitter>\n'
    out += ('    <shape type="rectangle"><transform name="to_world"><scale value="30"/><rotate x="1" angle="-90"/></transform>'
            '<ref id="ground"/></shape>\n')
    for side in (-1, 1):
        for k in range(5):
            z = -12 + k * 5.2
            height = 3 + 4 * r.random()
            out += box((side * 9 - 2.5, 0, z - 2.2), (side * 9 + 2.5, height, z + 2.2), "wall")
    out += '    <shape type="sphere"><point name="center" x="-1.5" y="1" z="3"/><float name="radius" value="1"/><ref id="plastic"/></shape>\n'
    out += box((1.0, 0, -1.0), (3.0, 1.6, 1.0), "wall")
    for i in range(60):
        x, z = -6 + 12 * r.random(), -12 + 22 * r.random()
        y = 0.4 + 3.5 * r.random()
        rad = 0.05 + 0.1 * r.random()
        out += (f'    <shape type="sphere"><point name="center" x="{x:.4f}" y="{y:.4f}" z="{z:.4f}"/><float name="radius" value="{rad:.4f}"/>'
                f'<bsdf type="diffuse"/><emitter type="area"><rgb name="radiance" value="{colour(r, 0.5 / (rad * rad))}"/></emitter></shape>\n')
    for i in range(24):
        x, z = -8 + 16 * r.random(), -14 + 26 * r.random()
        y = 2 + 5 * r.random()
        out += f'    <emitter type="point"><point name="position" x="{x:.4f}" y="{y:.4f}" z="{z:.4f}"/><rgb name="intensity" value="{colour(r, 1.2)}"/></emitter>\n'
    return out + "</scene>\n"


def hall():
    r = random.Random(59)
    out = HEAD.format(fov=60, origin="0, 1.7, 17", target="0, 1.4, 0", w=96, h=64)
    length, half, height = 36.0, 3.0, 4.0
    out += box((-half - 0.2, -0.2, -length / 2), (half + 0.2, 0.0, length / 2), "ground")
    out += box((-half - 0.2, height, -length / 2), (half + 0.2, height + 0.2, length / 2), "wall")
    out += box((-half - 0.2, 0, -length / 2), (-half, height, length / 2), "wall")
    out += box((half, 0, -length / 2), (half + 0.2, height, length / 2), "wall")
    out += box((-half, 0, -length / 2 - 0.2), (half, height, -length / 2), "wall")
    for k in range(3):
        z = -10 + 8 * k + 2 * r.random()
        x = -1.5 + 3 * r.random()
        out += box((x - 0.6, 0, z - 0.6), (x + 0.6, 1.2 + r.random(), z + 0.6), "plastic" if k == 1 else "wall")
    for k in range(12):
        for side in (-1, 0, 1):
            z = -length / 2 + 1.5 + k * 2.9
            x = side * 1.8
            out += (f'    <shape type="rectangle"><transform name="to_world"><scale x="0.35" y="0.25" z="1"/><rotate x="1" angle="90"/>'
                    f'<translate x="{x:.4f}" y="{height - 0.01:.4f}" z="{z:.4f}"/></transform><bsdf type="diffuse"/>'
                    f'<emitter type="area"><rgb name="radiance" value="{colour(r, 3.0)}"/></emitter></shape>\n')
    for k in range(12):
        side = -1 if k % 2 else 1
        z = -length / 2 + 2 + k * 2.8
        out += (f'    <shape type="disk"><transform name="to_world"><scale value="0.15"/><rotate y="1" angle="{-90 * side}"/>'
                f'<translate x="{side * (half - 0.01):.4f}" y="2.2" z="{z:.4f}"/></transform><bsdf type="diffuse"/>'
                f'<emitter type="area"><rgb name="radiance" value="{colour(r, 20.0)}"/></emitter></shape>\n')
    for k in range(10):
        z = -length / 2 + 3 + k * 3.3
        x = -2 + 4 * r.random()
        out += (f'    <emitter type="spot"><transform name="to_world"><lookat origin="{x:.4f}, {height - 0.3:.4f}, {z:.4f}" '
                f'target="{x + r.random() - 0.5:.4f}, 0, {z + r.random() - 0.5:.4f}" up="0, 0, 1"/></transform>'
                f'<float name="cutoff_angle" value="25"/><float name="beam_width" value="15"/>'
                f'<rgb name="intensity" value="{colour(r, 6.0)}"/></emitter>\n')
    return out + "</scene>\n"


if __name__ == "__main__":
    for name, text in (("plaza", plaza()), ("hall", hall())):
        with open(os.path.join(HERE, name + ".xml"), "w") as f:
            f.write(text)
        print(name, text.count("<emitter"), "lights")

"""Writes sky.exr: a 64 x 32 equirectangular sky (a blue gradient, a warm horizon, a sun
of 300 near 35 degrees of elevation) for the envmap reference scene.

    tools/mitsuba/python tools/mitsuba/scenes/make_sky.py
"""
import os

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
w, h = 64, 32
v = (np.arange(h) + 0.5) / h
u = (np.arange(w) + 0.5) / w
theta = v[:, None] * np.pi
phi = u[None, :] * 2 * np.pi
up = np.cos(theta)
img = np.zeros((h, w, 3), np.float32)
sky = np.clip(up, 0, 1)
img[...] = (0.25 + 0.55 * sky)[..., None] * np.array([0.45, 0.6, 1.0]) + (1 - np.abs(up))[..., None] ** 8 * np.array([0.9, 0.6, 0.3])
img[np.broadcast_to(up < 0, (h, w))] *= 0.3
sun_t, sun_p = np.radians(90 - 35), np.radians(120)
d = np.sin(theta) * np.sin(sun_t) * np.cos(phi - sun_p) + np.cos(theta) * np.cos(sun_t)
img[d > np.cos(np.radians(6))] = [300, 280, 240]
mi.Bitmap(img).write(os.path.join(os.path.dirname(__file__), "sky.exr"))
print("wrote sky.exr", img.shape, img.mean())

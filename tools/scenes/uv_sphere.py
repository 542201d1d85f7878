#!/usr/bin/env python3
"""Writes a UV sphere as OBJ with exact unit `vn` normals (for scenes/room/ball.obj).

usage: uv_sphere.py CX CY CZ RADIUS RINGS SEGMENTS > ball.obj
"""
import math
import sys

cx, cy, cz, radius = (float(a) for a in sys.argv[1:5])
rings, segments = int(sys.argv[5]), int(sys.argv[6])
print(f"# UV sphere: centre ({cx}, {cy}, {cz}), radius {radius}, {rings} x {segments}")
for r in range(rings + 1):
    theta = math.pi * r / rings
    for s in range(segments + 1):
        phi = 2 * math.pi * s / segments
        n = (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
        print(f"v {cx + radius * n[0]:.9g} {cy + radius * n[1]:.9g} {cz + radius * n[2]:.9g}")
        print(f"vn {n[0]:.9g} {n[1]:.9g} {n[2]:.9g}")
idx = lambda r, s: r * (segments + 1) + s + 1
for r in range(rings):
    for s in range(segments):
        a, b, c, d = idx(r, s), idx(r, s + 1), idx(r + 1, s + 1), idx(r + 1, s)
        print(f"f {a}//{a} {b}//{b} {c}//{c}")
        print(f"f {a}//{a} {c}//{c} {d}//{d}")

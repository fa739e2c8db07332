#!/usr/bin/env python3
"""Writes tree.ply, the sparse tree of docs/rendering.md ("Splats of sparse
subtrees"): a trunk, a ground grid and a canopy of 400 leaves (discs of 3 cm,
40 points each) scattered in a sphere of 0.9 m. The pictures:

  python3 sparse_tree.py > tree.ply
  printf 'treecut-camera-path 1\\n0 3.2 -3.2 1.9 0 0 1.5 0 0 1 40\\n1 3.2 -3.2 1.9 0 0 1.5 0 0 1 40\\n' > tree.campath
  treecut render tree.ply --path tree.campath --mode hq --unlit --points 3000 \\
      --frames 1 --sync --width 480 --height 360 --out tree
"""
import math
import random
import sys

random.seed(3)
points = []
for _ in range(6000):  # the trunk: a cylinder of radius 0.08, 1.5 high
    a = random.random() * 2 * math.pi
    points.append((0.08 * math.cos(a), 0.08 * math.sin(a), random.random() * 1.5,
                   math.cos(a), math.sin(a), 0.0, 110, 80, 50))
for _ in range(400):  # the leaves
    while True:
        c = [random.uniform(-1, 1) for _ in range(3)]
        if sum(x * x for x in c) <= 1:
            break
    c = [0.9 * c[0], 0.9 * c[1], 2.1 + 0.9 * c[2]]
    n = [random.gauss(0, 1) for _ in range(3)]
    length = math.sqrt(sum(x * x for x in n))
    n = [x / length for x in n]
    t = [1, 0, 0] if abs(n[0]) < 0.9 else [0, 1, 0]
    u = [n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]]
    length = math.sqrt(sum(x * x for x in u))
    u = [x / length for x in u]
    v = [n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]]
    green = random.randint(120, 200)
    for _ in range(40):
        r, a = 0.03 * math.sqrt(random.random()), random.random() * 2 * math.pi
        p = [c[i] + r * math.cos(a) * u[i] + r * math.sin(a) * v[i] for i in range(3)]
        points.append((*p, *n, 60, green, 40))
for i in range(100):  # the ground: a grid 0.04 apart
    for j in range(100):
        points.append((-2 + 0.04 * i, -2 + 0.04 * j, 0.0, 0.0, 0.0, 1.0, 120, 110, 90))

out = sys.stdout
out.write("ply\nformat ascii 1.0\nelement vertex %d\n" % len(points))
for name in ("x", "y", "z", "nx", "ny", "nz"):
    out.write("property float %s\n" % name)
out.write("property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n")
for p in points:
    out.write("%.5f %.5f %.5f %.4f %.4f %.4f %d %d %d\n" % p)

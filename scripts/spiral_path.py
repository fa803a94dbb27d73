#!/usr/bin/env python3
"""Writes a long spiral NURBS path file for `ncd replay`: an Archimedean spiral from r = 100 mm
inwards at 0.1 mm pitch, 16 control points per turn, z waving +-2 mm, cubic with integer knots
(the same path as geometry/spiral.cpp). 950 turns last about 51 minutes at 6000 mm/min.

usage: scripts/spiral_path.py TURNS > spiral.json
"""
import json
import math
import sys

turns = int(sys.argv[1]) if len(sys.argv) > 1 else 950
if not 1 <= turns <= 999:
    sys.exit("spiral_path.py: TURNS must be 1..999")
per_turn, degree = 16, 3
n = turns * per_turn + 1
points = []
for i in range(n):
    th = 2 * math.pi * i / per_turn
    r = 100.0 - 0.1 * i / per_turn
    points.append([round(r * math.cos(th), 6), round(r * math.sin(th), 6),
                   round(2.0 * math.sin(0.05 * th), 6)])
inner = n - degree - 1
knots = [0] * (degree + 1) + list(range(1, inner + 1)) + [inner + 1] * (degree + 1)
json.dump({"nurbs": {"degree": degree, "knots": knots, "points": points}}, sys.stdout)

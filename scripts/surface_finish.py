#!/usr/bin/env python3
"""Writes examples/surface-finish.ngc: a CAM-style 3D finishing raster (issue 34).

The surface is tests/common/shape_bound.hpp's Surface,
    z = f(x, y) = 2 sin(x/5) cos(y/4) + 0.5 sin((x + y)/7),
finished by passes along +x and -x over x in [0, 30] mm at y = 0, 0.5, ..., 3 (7 passes), a
point every 0.025 mm of x written to 3 decimals as a metric CAM post does (only the words that
change), each pass joined to the next by a 0.5 mm step-over in y (one G1), F2000 under G64 P0.01
(no Q: the machine's default fit of dense runs, docs/planner.md section 3d). The tool comes
down 5 mm at the feed onto the surface at the origin (f(0, 0) = 0) and retracts 5 mm in Z at
the end. The bound of its shape is tests/common/shape_bound.hpp's surface_finish_bound_s (the
plunge, surface_limit's 7 passes, the retract):
bench/dense_bound_bench.cpp, tests/motion/dense_bound_test.cpp.

    python3 scripts/surface_finish.py > examples/surface-finish.ngc
"""
import math

LENGTH_MM, STEP_MM, STEP_OVER_MM, PASSES, FEED = 30.0, 0.025, 0.5, 7, 2000


def f(x, y):
    return 2.0 * math.sin(x / 5.0) * math.cos(y / 4.0) + 0.5 * math.sin((x + y) / 7.0)


def fmt(v):
    s = f"{v:.3f}"
    return "0.000" if s == "-0.000" else s


def main():
    out = [
        "(surface-finish.ngc: a CAM-style 3D finishing raster, written by scripts/surface_finish.py)",
        "(z = 2 sin x/5 cos y/4 + 0.5 sin [x+y]/7; 7 passes of 30 mm, 0.025 mm steps, 3 decimals)",
        "G21 G90 G17 G94",
        "G64 P0.01",
        "G0 X0.000 Y0.000 Z5.000",
        "S10000 M3",
        f"G1 Z0.000 F{FEED}",
    ]
    last = {"X": "0.000", "Y": "0.000", "Z": "0.000"}
    points = int(round(LENGTH_MM / STEP_MM))
    for k in range(PASSES):
        y = STEP_OVER_MM * k
        for i in range(points + 1):
            x = STEP_MM * i if k % 2 == 0 else LENGTH_MM - STEP_MM * i
            words = {"X": fmt(x), "Y": fmt(y), "Z": fmt(f(x, y))}
            changed = [f"{a}{v}" for a, v in words.items() if last[a] != v]
            last = words
            if changed:
                out.append("G1 " + " ".join(changed) if i == 0 and k == 0 else " ".join(changed))
    out += ["G0 Z5.000", "M5", "M2"]
    print("\n".join(out))


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Median `ncd chamfer` computation time (the JSON's elapsed_ms, wall clock) of the four holes of
scripts/snapshot.py (experiment 3, lateral, eccentric, cone), for several ncd binaries measured in
one run, interleaved so that load on the machine falls on all of them alike.

    scripts/chamfer_time.py RUNS NAME=NCD [NAME=NCD ...]

A binary that refuses a hole (an old one without the generalised flags) shows "refused".
"""
import json
import os
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import snapshot  # noqa: E402


def main():
    if len(sys.argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    runs = int(sys.argv[1])
    bins = dict(a.split("=", 1) for a in sys.argv[2:])
    times = {}
    for _ in range(runs):
        for hole, args in snapshot.HOLES.items():
            for name, ncd in bins.items():
                p = subprocess.run([ncd, "chamfer"] + args + ["--format", "json"],
                                   capture_output=True, text=True)
                cell = times.setdefault((hole, name), [])
                if p.returncode == 0:
                    cell.append(json.loads(p.stdout)["elapsed_ms"])
    for hole in snapshot.HOLES:
        cells = []
        for name in bins:
            t = times[(hole, name)]
            cells.append("%s %s" % (name, "%.3f ms" % statistics.median(t) if t else "refused"))
        print("%-10s %s" % (hole, "   ".join(cells)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

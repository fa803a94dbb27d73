#!/usr/bin/env python3
"""CPU time of LinuxCNC's rs274 and of `ncd check` on the same program, side by side in one run
(docs/ngc-interpreter.md, "Speed"). Medians of 5 runs each, user + system CPU of the child.

usage: scripts/ngc_cpu_vs_rs274.py [NCD] [PROGRAM]
  NCD      the ncd executable (default build/release/app/ncd)
  PROGRAM  an .ngc file (default: a generated 40 000-line program of dense G1, about 0.78 MB)
"""
import math
import os
import resource
import subprocess
import sys
import tempfile


def dense_program(path, lines=40000):
    out = ["G21 G90 G17 G94 F1200", "G0 X0 Y0 Z0"]
    for i in range(lines):
        t, r = i * 0.01, 10 + 0.001 * i
        out.append("G1 X%.3f Y%.3f" % (r * math.cos(t), r * math.sin(t)))
    out.append("M2")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def cpu(cmd, stdin=None, n=5):
    times = []
    for _ in range(n):
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run(cmd, input=stdin, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        times.append((r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime))
    times.sort()
    return times[len(times) // 2]


def main():
    ncd = sys.argv[1] if len(sys.argv) > 1 else "build/release/app/ncd"
    if len(sys.argv) > 2:
        program = sys.argv[2]
    else:
        program = os.path.join(tempfile.mkdtemp(), "dense40k.ngc")
        dense_program(program)
    a = cpu(["rs274", "-g", program, "/dev/null"], stdin=b"\n\n\n")
    b = cpu([ncd, "check", program])
    c = cpu([ncd, "check", "--summary", program])
    print("program %s (%d bytes)" % (program, os.path.getsize(program)))
    print("rs274 -g             median CPU %.3f s" % a)
    print("ncd check            median CPU %.3f s  (%.2f of rs274)" % (b, b / a))
    print("ncd check --summary  median CPU %.3f s  (%.2f of rs274)" % (c, c / a))


if __name__ == "__main__":
    main()

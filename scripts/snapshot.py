#!/usr/bin/env python3
"""Records what ncd does on a fixed set of runs, and compares two such records byte for byte,
wall-clock fields aside: the check that a refactoring changed no behaviour.

    scripts/snapshot.py record NCD OUTDIR    run the set with the executable NCD into OUTDIR
    scripts/snapshot.py compare A B          compare two records; exit 1 on any difference

The set: `ncd replay` of every tests/ngc program (setpoints, report, --blocks; refused ones
keep their exit status and message), `ncd chamfer` JSON and NGC for the README's holes,
`ncd check` of LinuxCNC's samples (where installed), `ncd simulate` fig13-15 (reports), and
`ncd teach` and `ncd robot` on the examples. The demo's files are compared when both records
hold an out_demo folder (copy out/demo there after `make demo`).

Wall-clock fields, which no refactoring keeps: JSON keys naming elapsed or step times, rates
per second and wall-clock timestamps; in text, the figures of WALL_TEXT ("in 0.04 s", "(6.7e+07 /s)", "median
5328 ns").
"""
import json
import os
import re
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAMPLES = "/usr/share/linuxcnc/ncfiles"
WALL_KEY = re.compile(r"(elapsed|_ms$|_ns$|^seconds$|per_s$|wall|timestamp|started|finished|"
                      r"step_time|lookahead_sampling|first_window)")
# Wall-clock figures inside text lines: "in 0.04 s", "(6.68e+07 /s)", "computed in 0.586 ms",
# "median 5328 ns", "125371 periods/s".
WALL_TEXT = re.compile(r"(in|computed in|median|p99|max)\s+[0-9.]+(e[+-]?[0-9]+)?\s*(ms|ns|us|s)\b"
                       r"|[0-9.]+(e[+-]?[0-9]+)?\s*(/s|periods/s)\b")

HOLES = {
    "exp3": ["--pipe-radius", "18", "--drill-radius", "13", "--ball-radius", "3", "--width",
             "0.7", "--tolerance", "0.01", "--rod-radius", "1.8", "--non-knife-angle", "93",
             "--edge", "inner", "--side", "upper"],
    "lateral": ["--pipe-radius", "18", "--pipe-thickness", "3", "--drill-radius", "13",
                "--ball-radius", "3", "--width", "0.7", "--drill-tilt-deg", "45",
                "--eccentricity", "2", "--pipe-half-angle-deg", "5"],
    "eccentric": ["--pipe-radius", "18", "--pipe-thickness", "3", "--drill-radius", "13",
                  "--ball-radius", "3", "--width", "0.7", "--rod-radius", "1.8",
                  "--non-knife-angle", "93", "--eccentricity", "3"],
    "cone": ["--pipe-radius", "18", "--pipe-thickness", "3", "--drill-radius", "13",
             "--ball-radius", "3", "--width", "0.7", "--rod-radius", "1.8",
             "--non-knife-angle", "93", "--pipe-half-angle-deg", "5"],
}


def run(ncd, args, out_dir, name):
    """Runs ncd ARGS in out_dir; keeps its exit status, stdout and stderr as files."""
    p = subprocess.run([ncd] + args, cwd=out_dir, capture_output=True, timeout=900)
    with open(os.path.join(out_dir, name + ".status"), "w") as f:
        f.write("%d\n" % p.returncode)
    with open(os.path.join(out_dir, name + ".stdout"), "wb") as f:
        f.write(p.stdout)
    with open(os.path.join(out_dir, name + ".stderr"), "wb") as f:
        f.write(p.stderr)


def record(ncd, out):
    ncd = os.path.abspath(ncd)
    os.makedirs(out, exist_ok=True)
    machine = os.path.join(ROOT, "config", "chamfer-exp3.toml")
    ngc_dir = os.path.join(ROOT, "tests", "ngc")
    for prog in sorted(os.listdir(ngc_dir)):
        if not prog.endswith(".ngc"):
            continue
        stem = prog[:-4]
        d = os.path.join(out, "replay", stem)
        os.makedirs(d, exist_ok=True)
        run(ncd, ["replay", os.path.join(ngc_dir, prog), "--machine", machine, "-q",
                  "--setpoints", "sp.csv", "--report", "report.json", "--blocks", "blocks.ngc"],
            d, "replay")
    for hole, args in HOLES.items():
        d = os.path.join(out, "chamfer", hole)
        os.makedirs(d, exist_ok=True)
        run(ncd, ["chamfer"] + args + ["--format", "json", "-o", "hole.json"], d, "json")
        run(ncd, ["chamfer"] + args + ["--format", "ngc", "--feed", "300", "--spindle", "3000",
                                       "--machine", machine, "-o", "hole.ngc", "-q"], d, "ngc")
    if os.path.isdir(SAMPLES):
        d = os.path.join(out, "check")
        os.makedirs(d, exist_ok=True)
        for prog in sorted(os.listdir(SAMPLES)):
            if prog.endswith(".ngc"):
                run(ncd, ["check", os.path.join(SAMPLES, prog)], d, prog[:-4])
    for case in ("fig13", "fig14", "fig15"):
        d = os.path.join(out, "simulate", case)
        os.makedirs(d, exist_ok=True)
        run(ncd, ["simulate", "--case", case, "--report", "report.json"], d, "simulate")
    ex = os.path.join(ROOT, "examples")
    d = os.path.join(out, "teach")
    os.makedirs(d, exist_ok=True)
    run(ncd, ["teach", os.path.join(ex, "teach-burr.txt"), "--frame-points",
              os.path.join(ex, "teach-burr-frame.txt"), "--tool-diameter", "10", "--depth", "0.2",
              "--feed", "300", "--spindle", "2000", "--truncate", "-o", "burr.ngc"], d, "teach")
    d = os.path.join(out, "robot")
    os.makedirs(d, exist_ok=True)
    run(ncd, ["robot", "--cylinder-radius", "30", "--hole-radius", "15", "-o", "robot.json"],
        d, "robot")


def scrub_json(v):
    if isinstance(v, dict):
        return {k: ("<wall>" if WALL_KEY.search(k) else scrub_json(x)) for k, x in v.items()}
    if isinstance(v, list):
        return [scrub_json(x) for x in v]
    return v


def normal(path):
    data = open(path, "rb").read()
    if path.endswith(".json"):
        try:
            return json.dumps(scrub_json(json.loads(data)), sort_keys=True, indent=1).encode()
        except ValueError:
            pass
    if path.endswith((".stdout", ".stderr", ".ngc", ".txt")):
        return WALL_TEXT.sub("<wall>", data.decode("utf-8", "replace")).encode()
    return data


def files(root):
    out = set()
    for d, _, names in os.walk(root):
        for n in names:
            out.add(os.path.relpath(os.path.join(d, n), root))
    return out


def compare(a, b):
    fa, fb = files(a), files(b)
    if not (os.path.isdir(os.path.join(a, "out_demo")) and os.path.isdir(os.path.join(b, "out_demo"))):
        fa = {f for f in fa if not f.startswith("out_demo")}
        fb = {f for f in fb if not f.startswith("out_demo")}
    diffs = 0
    for f in sorted(fa ^ fb):
        print("only in %s: %s" % (a if f in fa else b, f))
        diffs += 1
    for f in sorted(fa & fb):
        if normal(os.path.join(a, f)) != normal(os.path.join(b, f)):
            print("differs: %s" % f)
            diffs += 1
    print("%d files compared, %d differ" % (len(fa & fb), diffs))
    return 1 if diffs else 0


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "record":
        if os.path.exists(sys.argv[3]):
            shutil.rmtree(sys.argv[3])
        record(sys.argv[2], sys.argv[3])
        return 0
    if len(sys.argv) == 4 and sys.argv[1] == "compare":
        return compare(sys.argv[2], sys.argv[3])
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())

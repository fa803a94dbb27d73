#!/usr/bin/env python3
"""Checks that every #include of the project's sources follows the layering of
docs/architecture.md ("Layout"): a folder includes its own headers and those of the folders it
stands on, never one above it or beside it. The libraries' links (each folder's CMakeLists.txt)
follow the same rule; this check also catches a header-only use that no link would.

    scripts/check_layers.py [ROOT]     exit 0 when the rule holds, 1 with the offending lines

A test of the suite (Layers.EveryIncludeFollowsTheLayering) runs it.
"""
import os
import re
import sys

# What each folder may include, besides itself.
BELOW = {
    "core": [],
    "geometry": ["core"],
    "gcode": ["geometry", "core"],
    "cam": ["gcode", "geometry", "core"],
    "feed": ["geometry", "core"],
    "surface": ["core"],
    "motion": ["feed", "geometry", "core"],
    "link": ["motion", "feed", "cam", "gcode", "geometry", "core"],
    "sim": ["link", "motion", "feed", "cam", "gcode", "geometry", "core"],
    "service": ["link", "motion", "feed", "cam", "gcode", "geometry", "core"],
    "api": ["service", "link", "motion", "feed", "cam", "gcode", "geometry", "core"],
    "app": ["api", "service", "sim", "link", "surface", "motion", "feed", "cam", "gcode",
            "geometry", "core"],
}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([a-z_]+)/[^"]+"')


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(
        os.path.dirname(os.path.abspath(__file__)))
    bad = []
    files = 0
    for folder, allowed in BELOW.items():
        for dirpath, _, names in os.walk(os.path.join(root, folder)):
            for name in sorted(names):
                if not name.endswith((".cpp", ".hpp")):
                    continue
                path = os.path.join(dirpath, name)
                files += 1
                with open(path, encoding="utf-8") as f:
                    for number, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if m and m.group(1) != folder and m.group(1) not in allowed:
                            rel = os.path.relpath(path, root)
                            bad.append(f"{rel}:{number}: {folder}/ includes {m.group(1)}/ "
                                       f"({line.strip()}); {folder}/ stands on "
                                       f"{', '.join(allowed) or 'nothing'}")
    for b in bad:
        print(b)
    if files == 0:
        print(f"no source found under {root}: give the repository's root")
        return 1
    print(f"{files} files, {len(bad)} include(s) against the layering")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

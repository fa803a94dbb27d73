#!/usr/bin/env python3
"""Sizes of the source tree, for the layout's rule (docs/architecture.md, "Layout": no file over
about 800 lines and no function over about 100 unless its top comment says why: a comment
just above it that says "on purpose", and why).

    scripts/size_report.py [ROOT] [--top N]

Prints the lines per folder (code and tests), the N longest files and the N longest functions.
Functions are found by their braces: a '{' at namespace or class level whose text since the last
';', '{' or '}' ends in a parameter list (not a control statement, an initialiser or a type
body). A lambda counts with the function it is in. This is a scanner, not a parser: good for
ranking, within a line or two of what a compiler would say.
"""
import os
import re
import sys

FOLDERS = ["core", "geometry", "gcode", "cam", "feed", "surface", "motion", "link", "sim",
           "service", "api", "app", "bench", "tests",
           # the layout before the move
           "toolpath", "interpolator", "comms", "fleet"]
TYPE_BODY = re.compile(r"\b(namespace|class|struct|union|enum)\b[^()]*$|\bextern\s+\"C\"\s*$")
CONTROL = re.compile(r"\b(if|for|while|switch|catch|do|else|try)\s*(\(.*)?$")


def strip(text):
    """The text with comments and string/char literals blanked, newlines kept."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(" " * (min(j + 1, n) - i))
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def functions(path):
    code = strip(open(path, encoding="utf-8", errors="replace").read())
    stack = []  # (kind, start line, name)
    found = []
    last = 0
    line = 1
    for i, c in enumerate(code):
        if c == "\n":
            line += 1
        elif c in ";{}":
            head = code[last:i]
            last = i + 1
            if c == "{":
                inside_fn = any(k == "fn" for k, _, _ in stack)
                h = " ".join(head.split())
                if inside_fn:
                    stack.append(("blk", line, ""))
                elif TYPE_BODY.search(h) or not h.endswith((")", "const", "noexcept", "override",
                                                             "final")) and ")" not in h:
                    stack.append(("type", line, ""))
                elif CONTROL.search(h) or "=" in h.split("(")[0]:
                    stack.append(("blk", line, ""))
                else:
                    m = re.search(r"([~\w:]+|operator\S+)\s*\(", h)
                    stack.append(("fn", line, m.group(1) if m else "?"))
            elif c == "}" and stack:
                kind, start, name = stack.pop()
                if kind == "fn":
                    found.append((line - start + 1, name, start))
    return found


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    top = int(sys.argv[sys.argv.index("--top") + 1]) if "--top" in sys.argv else 10
    if "--top" in sys.argv:
        args = [a for a in args if a != str(top)]
    root = args[0] if args else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    files, fns = [], []
    print("lines per folder (.cpp and .hpp):")
    for folder in FOLDERS:
        total = 0
        for dirpath, _, names in os.walk(os.path.join(root, folder)):
            if "/corpus" in dirpath:
                continue
            for name in names:
                if name.endswith((".cpp", ".hpp")):
                    p = os.path.join(dirpath, name)
                    n = sum(1 for _ in open(p, encoding="utf-8", errors="replace"))
                    total += n
                    rel = os.path.relpath(p, root)
                    files.append((n, rel))
                    if not rel.startswith("tests/"):
                        raw = open(p, encoding="utf-8", errors="replace").read().split("\n")
                        for n_, fn, s in functions(p):
                            # "on purpose" in the comment just above: the function says why
                            why = any("on purpose" in l for l in raw[max(0, s - 6):s])
                            fns.append((n_, f"{rel}:{s} {fn}" + (" (says why)" if why else "")))
        if total:
            print(f"  {folder + '/':14s} {total:6d}")
    print(f"longest files (of {len(files)}):")
    for n, rel in sorted(files, reverse=True)[:top]:
        print(f"  {n:6d}  {rel}")
    print(f"longest functions outside tests/ (of {len(fns)}):")
    for n, where in sorted(fns, reverse=True)[:top]:
        print(f"  {n:6d}  {where}")
    over = [f for f in fns if f[0] > 100]
    unexplained = [f for f in over if not f[1].endswith("(says why)")]
    print(f"functions over 100 lines: {len(over)} ({len(unexplained)} without a comment saying "
          f"why); files over 800 lines outside tests/: "
          f"{sum(1 for n, r in files if n > 800 and not r.startswith('tests/'))}")


if __name__ == "__main__":
    main()

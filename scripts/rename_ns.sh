#!/bin/bash
# Rename ncd's namespaces after its folders (namespace = folder), issue 31.
#   rename_ns.sh DIR [PHASE...]    PHASE: app comms toolpath (default: all three, in that order)
# DIR is a checkout of ncd (a worktree); the rewrite is done in place, then clang-format runs on
# every changed file. Re-runnable on any later main: the symbol -> namespace map is derived
# from the headers' declarations. The engine is rename_ns.py beside this script.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
[ $# -ge 1 ] && [ -d "$1" ] || { echo "usage: rename_ns.sh DIR [app] [comms] [toolpath]" >&2; exit 2; }
exec python3 "$here/rename_ns.py" "$@"

#!/usr/bin/env bash
# Installs the independent references the test suite checks ncd against, if any are missing:
#   linuxcnc-uspace  LinuxCNC's standalone interpreter `rs274` and its sample programs, the judge of
#                    every G-code ncd reads or writes (without it those suites are skipped, saying so)
#   stress-ng        background load for the tests that must hold on a busy machine
# Run as root (or with sudo available). `make test` does not need them; CI installs them first.
set -euo pipefail
pkgs=(linuxcnc-uspace stress-ng)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "ncd: installing the test judges: ${missing[*]}"
if [ "$(id -u)" -eq 0 ]; then
  as_root=()
elif command -v sudo >/dev/null 2>&1; then
  as_root=(sudo)
else
  echo "ncd: not root and no sudo; install them with: apt-get install ${missing[*]}" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
"${as_root[@]}" apt-get update -qq
# No recommends: linuxcnc-uspace recommends a real-time kernel and GUI toolkits rs274 does not use.
"${as_root[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"

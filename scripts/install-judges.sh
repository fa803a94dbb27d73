#!/usr/bin/env bash
# Installs the independent references the test suite checks ncd against, with the build packages:
#   linuxcnc-uspace  LinuxCNC's standalone interpreter `rs274` and its sample programs, the judge of
#                    every G-code ncd reads or writes (without it those suites are skipped, saying so)
#   stress-ng        background load for the tests that must hold on a busy machine
# install-deps.sh installs without recommends: linuxcnc-uspace recommends a real-time kernel and
# GUI toolkits that rs274 does not use. CI runs this before `make test`.
exec "$(dirname "$0")/install-deps.sh" linuxcnc-uspace stress-ng

#!/bin/bash
# The ASan walk (docs/testing.md): every LinuxCNC sample and every tests/ngc program through
# `ncd replay -q` of the sanitizer tree, whole or with EXTRA=--path-only; a report is a line
# AddressSanitizer / "runtime error:" / LeakSanitizer on stderr or an exit other than 0 (walked) or 2 (refused with a message).
# Usage: scripts/asan_walk.sh build/debug/app/ncd   (EXTRA=--path-only for the path alone)
NCD=$(realpath "$1"); SRC=$(cd "$(dirname "$0")/.." && pwd); out=${TMPDIR:-/tmp}/ncd_asan_walk${EXTRA// /}; rm -rf $out; mkdir -p $out
printf 'T1 P1 Z75.5 D0.25\nT2 P2 Z-0.25 D0.5\nT3 P3 Z28.575 D0.125\nT4 P4 Z19.05 D0.375\nT5 P5 Z50 D0.1\nT7 P7 Z60 D0.2\nT10 P10 Z100 D0.3\nT20 P20 Z50.8 D1\n' > $out/tools.tbl
n=0; bad=0; declare -A st
for f in /usr/share/linuxcnc/ncfiles/*.ngc $SRC/tests/ngc/*.ngc; do
  n=$((n+1)); b=$(basename $f .ngc)
  (cd $out && ASAN_OPTIONS=detect_leaks=1 timeout 600 $NCD replay "$f" -q $EXTRA --setpoints $out/$b.csv > $out/$b.out 2> $out/$b.err); rc=$?
  st[$rc]=$((${st[$rc]:-0}+1))
  if grep -qE "AddressSanitizer|runtime error:|LeakSanitizer" $out/$b.err || { [ $rc -ne 0 ] && [ $rc -ne 2 ]; }; then
    bad=$((bad+1)); echo "REPORT $b rc=$rc ($out/$b.err)"
  fi
done
echo "programs $n, reports $bad, exit codes: $(for k in "${!st[@]}"; do echo -n "$k:${st[$k]} "; done)"
[ $bad -eq 0 ]

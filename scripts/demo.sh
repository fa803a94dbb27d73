#!/usr/bin/env bash
# `make demo`: the paper's experiment 3 (Sato et al. 2016, §5.4): the inner upper edge of a
# 26 mm hole in a pipe of 36 mm bore, chamfered 0.7 mm wide by a 6 mm ball whose non-knife cap
# (2β = 93°) must not touch the hole, so α is adjusted by Algorithm 1.
set -euo pipefail
ncd=${1:-build/release/app/ncd}
out=out/demo
mkdir -p "$out"
geometry=(--pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01
          --rod-radius 1.8 --non-knife-angle 93 --edge inner --side upper)

echo "== ncd demo: paper 000, experiment 3 =="
echo
"$ncd" chamfer "${geometry[@]}" --format json -o "$out/exp3.json" --plot "$out/exp3.svg" 2>&1
"$ncd" chamfer "${geometry[@]}" --format csv -o "$out/exp3.csv" -q
"$ncd" chamfer "${geometry[@]}" --format ngc --feed 300 --spindle 3000 -o "$out/exp3.ngc" -q
echo "  wrote             $out/exp3.csv"
echo "  wrote             $out/exp3.ngc"
echo
echo "For comparison, experiment 2 (the same cutter with alpha = 1, Algorithm 1 off):"
"$ncd" chamfer "${geometry[@]}" --no-avoid --format json -o "$out/exp2.json" 2>&1 | grep -E "rod check|alpha"
echo
echo "The NC program (first lines of $out/exp3.ngc):"
head -n 20 "$out/exp3.ngc" | sed 's/^/  /'
echo "  ..."
echo
echo "Open $out/exp3.svg for the checks of the paper's Fig. 14 (alpha, 1/|k_e|, -e_z, CL radius)."

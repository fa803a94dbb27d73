#!/usr/bin/env bash
# `make demo`: the main job of ncd end to end, on the paper's experiment 3 (Sato et al. 2016,
# §5.4): the inner upper edge of a 26 mm hole in a pipe of 36 mm bore, chamfered 0.7 mm wide by
# a 6 mm ball whose non-knife cap (2β = 93°) must not touch the hole, so α is adjusted by
# Algorithm 1.
#
#   1. generate the chamfer path (paper 000);
#   2. plan and walk it at 4 ms with the roughness-bounded feed (paper 004) and encode the
#      setpoints into NC blocks that fit the link;
#   3. start a simulated controller on a pseudo-terminal (19 200 baud, 7E2, XON/XOFF, 256-byte
#      buffer) and drip-feed the blocks to it; it executes them in real time (about 20 s).
set -euo pipefail
ncd=${1:-build/release/app/ncd}
out=out/demo
mkdir -p "$out"
rm -f "$out/cnc" "$out"/*.journal
geometry=(--pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01
          --rod-radius 1.8 --non-knife-angle 93 --edge inner --side upper)
line=(--baud 19200 --frame 7E2 --flow xonxoff --protocol drip)

echo "== ncd demo: chamfer a drilled hole, walk it at 4 ms, stream it over RS-232 =="
echo
echo "-- 1. the chamfer path (paper 000, experiment 3) --"
"$ncd" chamfer "${geometry[@]}" --format json -o "$out/exp3.json" --plot "$out/exp3.svg" 2>&1
"$ncd" chamfer "${geometry[@]}" --format ngc --feed 300 --spindle 3000 -o "$out/exp3.ngc" -q
echo "  wrote             $out/exp3.ngc (the path as a plain NC program, for reference)"
echo
echo "-- 2. plan and walk it at 4 ms, roughness-bounded feed; encode blocks for the link --"
"$ncd" replay "$out/exp3.json" --machine config/chamfer-exp3.toml \
  --setpoints "$out/setpoints.csv" --report "$out/replay.json" --plot "$out/feed.svg" \
  --blocks "$out/exp3-dnc.ngc" 2>&1
echo
echo "-- 3. stream it to a simulated controller: 19200 baud 7E2, XON/XOFF, drip feed --"
"$ncd" sim-controller --link "$out/cnc" "${line[@]}" --buffer 256 --log "$out/controller.json" \
  --exit-at-end >"$out/controller.out" 2>"$out/controller.err" &
sim=$!
trap 'kill $sim 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -e "$out/cnc" ] && break; sleep 0.05; done
"$ncd" stream "$out/exp3-dnc.ngc" --port "$out/cnc" "${line[@]}" --report "$out/stream.json" -q 2>&1 |
  sed 's/^/  /'
wait $sim
trap - EXIT
sed "s/^/  /" "$out/controller.out" "$out/controller.err"
echo
sent=$(grep -o '"program_sha256": *"[0-9a-f]*"' "$out/stream.json" | grep -o '[0-9a-f]\{64\}')
got=$(grep -o '"program_sha256": *"[0-9a-f]*"' "$out/controller.json" | grep -o '[0-9a-f]\{64\}')
if [ "$sent" = "$got" ]; then
  echo "The controller received the program byte for byte (sha256 $got)."
else
  echo "MISMATCH: sent sha256 $sent, the controller has $got" >&2
  exit 1
fi
echo
echo "Files in $out:"
echo "  exp3.svg          the checks of the paper's Fig. 14 (alpha, 1/|k_e|, -e_z, CL radius)"
echo "  feed.svg          planned feed, its limit, roughness, and the feed written in the blocks"
echo "  setpoints.csv     every 4 ms setpoint;  replay.json  the walk's report in numbers"
echo "  exp3-dnc.ngc      the blocks sent;      stream.json  the sender's report"
echo "  controller.json   the controller's log: blocks, checksum, underruns, buffer, moves"

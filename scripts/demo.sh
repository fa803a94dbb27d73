#!/usr/bin/env bash
# `make demo`: the main job of ncd end to end, on the paper's experiment 3 (Sato et al. 2016,
# §5.4): the inner upper edge of a 26 mm hole in a pipe of 36 mm bore, chamfered 0.7 mm wide by
# a 6 mm ball whose non-knife cap (2β = 93°) must not touch the hole, so α is adjusted by
# Algorithm 1.
#
#   1. generate the chamfer path (paper 000);
#   2. make it a whole program (docs/whole-program.md: preamble, tool, spindle at speed, the
#      clearance plane, the approach down the drill axis, the cut, the retract, M5, M2), plan
#      and walk it at 4 ms with the roughness-bounded feed (paper 004) and encode the setpoints
#      and the events into NC blocks that fit the link;
#   3. start a simulated controller on a pseudo-terminal (19 200 baud, 7E2, XON/XOFF, 256-byte
#      buffer) and drip-feed the blocks to it; it executes them in real time (about 35 s).
# NCD_DEMO_OUT sets the folder (default out/demo; the suite's Demo.RunsEndToEnd uses its own).
set -euo pipefail
ncd=${1:-build/release/app/ncd}
out=${NCD_DEMO_OUT:-out/demo}
mkdir -p "$out"
rm -f "$out/cnc" "$out"/*.journal
geometry=(--pipe-radius 18 --drill-radius 13 --ball-radius 3 --width 0.7 --tolerance 0.01
          --rod-radius 1.8 --non-knife-angle 93 --edge inner --side upper)
line=(--baud 19200 --frame 7E2 --flow xonxoff --protocol drip --dialect iso)

echo "== ncd demo: chamfer a drilled hole, walk it at 4 ms, stream it over RS-232 =="
echo
echo "-- 1. the chamfer path (paper 000, experiment 3) --"
"$ncd" chamfer "${geometry[@]}" --format json -o "$out/exp3.json" --plot "$out/exp3.svg" 2>&1
"$ncd" chamfer "${geometry[@]}" --format ngc --feed 300 --spindle 3000 \
  --machine config/chamfer-exp3.toml -o "$out/exp3.ngc" -q
echo "  wrote             $out/exp3.ngc (the path as a plain NC program, for reference)"
echo
echo "-- 2. the whole program: plan and walk it at 4 ms, roughness-bounded feed; encode blocks --"
"$ncd" replay "$out/exp3.json" --machine config/chamfer-exp3.toml \
  --setpoints "$out/setpoints.csv" --report "$out/replay.json" --plot "$out/feed.svg" \
  --blocks "$out/exp3-dnc.ngc" 2>&1
# The order a machinist checks before loading it: spindle at speed, then the clearance plane and
# the approach, and only then the first cutting move; the same programmed point as exp3.ngc.
# Blocks only: the header's comments name the moves too ("(approach: ... G1 down ...)").
first_cut=$(grep -nE '^[^(]*G1([^0-9]|$)' "$out/exp3-dnc.ngc" | head -1 | cut -d: -f1)
spindle=$(grep -nE '^[^(]*M3S' "$out/exp3-dnc.ngc" | head -1 | cut -d: -f1)
clearance=$(grep -nE '^[^(]*G0Z' "$out/exp3-dnc.ngc" | head -1 | cut -d: -f1)
if [ -z "$spindle" ] || [ -z "$clearance" ] || [ "$spindle" -ge "$first_cut" ] ||
  [ "$clearance" -ge "$first_cut" ]; then
  echo "the streamed program cuts before the spindle runs or before the approach" >&2
  exit 1
fi
point=$(grep -o 'programmed point: ball [A-Z]*' "$out/exp3-dnc.ngc")
grep -q "$point" "$out/exp3.ngc" || { echo "the programs drive different points" >&2; exit 1; }
echo "  program           $(grep -c . "$out/exp3-dnc.ngc") lines: M3 on line $spindle, G0 to the" \
  "clearance plane on line $clearance, first G1 on line $first_cut; $point, as exp3.ngc"
echo "  its events        $(grep -v '^(' "$out/exp3-dnc.ngc" | grep -oE '(M[0-9]+(S[0-9.]+)?|G4P[0-9.]+|T[0-9]+M6(G43H[0-9]+)?)' | tr '\n' ' ')"
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
echo "-- 4. what the controller executed (its log, $out/controller.json) --"
python3 - "$out/controller.json" <<'PY'
import json, sys
log = json.load(open(sys.argv[1]))
events = log.get("events")
if events:
    for e in events:
        print("  " + json.dumps(e))
else:
    print("  (this simulated controller logs no events yet; its log holds: "
          + ", ".join(sorted(log.keys())) + ")")
for key in ("alarms", "blocks_executed", "dwell_s", "program_end_executed", "underruns"):
    if key in log:
        v = log[key]
        print("  %-16s %s" % (key, len(v) if isinstance(v, list) else v))
PY
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

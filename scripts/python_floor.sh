#!/usr/bin/env bash
# A Python plant's lockstep rate beside the binding's floor, interleaved (the machine's load
# drifts; quote medians of one session): config/external/external_motor.toml as shipped (the DC
# motor in Python, config/plants/motor_plant.py), the same scenario with the plant replaced by
# config/plants/floor_plant.py, which computes nothing (the floor when both sides poll), and that
# with `timing.spin_us = 0` (the floor when every sample waits on an iceoryx2 event, the
# event-woken Python<->Rust round trip). Prints one line per run:
#   plant samples_per_s us_per_sample      (plant: motor, floor or floor-event)
# Needs the evoloop_plant package importable (`pip install ./python`, or PYTHONPATH).
# Usage: scripts/python_floor.sh [-n RUNS] [-d SECONDS] [BIN]
set -euo pipefail
runs=5 duration=60
while getopts n:d: o; do
  case $o in n) runs=$OPTARG ;; d) duration=$OPTARG ;; *) exit 2 ;; esac
done
shift $((OPTIND - 1))
bin=${1:-}
# A BIN given is taken from where the script was started; the rest from the repository's root.
case $bin in "" | /*) ;; *) bin="$PWD/$bin" ;; esac
cd "$(dirname "$0")/.."
bin=${bin:-target/release/evoloop}
scenario=config/external/external_motor.toml
tmp=$(mktemp -d)
# The floor's scenario beside the shipped one, so that its relative command path resolves.
floor="$(dirname "$scenario")/.floor-$$.toml"
event="$(dirname "$scenario")/.floor-event-$$.toml"
trap 'rm -rf "$tmp" "$floor" "$event"' EXIT
sed 's|"../plants/motor_plant.py"|"../plants/floor_plant.py"|' "$scenario" > "$floor"
sed 's|^spin_us = .*|spin_us = 0|' "$floor" > "$event"
grep -q floor_plant.py "$floor" || { echo "$scenario: no motor_plant.py command to replace" >&2; exit 1; }
grep -q '^spin_us = 0' "$event" || { echo "$scenario: no timing.spin_us to set" >&2; exit 1; }
for i in $(seq "$runs"); do
  for plant in motor floor floor-event; do
    file=$scenario
    [ $plant = floor ] && file=$floor
    [ $plant = floor-event ] && file=$event
    out=$("$bin" run "$file" --duration "$duration" --out "$tmp/run" --quiet 2>&1) ||
      { echo "$plant: the run failed:" >&2; tail -5 <<<"$out" >&2; exit 1; }
    line=$(grep 'samples/s' <<<"$out") || { echo "$plant: the run printed no rate" >&2; exit 1; }
    rate=$(sed -E 's/.*\(([0-9]+) samples\/s\).*/\1/' <<<"$line")
    echo "$plant $rate $(awk -v r="$rate" 'BEGIN { printf "%.1f", 1e6 / r }')"
    rm -rf "$tmp/run"
  done
done

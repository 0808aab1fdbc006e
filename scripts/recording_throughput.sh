#!/usr/bin/env bash
# Lockstep throughput with run.mcap on and off, for one or more evoloop binaries, interleaved
# (the machine's load drifts; quote medians of one session). Prints one line per run:
#   binary scenario recording samples_per_s bytes_per_cycle
# Usage: scripts/recording_throughput.sh [-n RUNS] [-d SECONDS] [-s SCENARIO] BIN [BIN ...]
set -euo pipefail
runs=5 duration=120 scenario=config/two_mass/two_mass.toml
while getopts n:d:s: o; do
  case $o in n) runs=$OPTARG ;; d) duration=$OPTARG ;; s) scenario=$OPTARG ;; *) exit 2 ;; esac
done
shift $((OPTIND - 1))
[ $# -ge 1 ] || { echo "usage: $0 [-n RUNS] [-d SECONDS] [-s SCENARIO] BIN [BIN ...]" >&2; exit 2; }
tmp=$(mktemp -d)
# The same scenario with the recording off (its [output] table gains `mcap = false`), beside it
# so that relative paths in it (a robot file) still resolve.
off="$(dirname "$scenario")/.recording-off-$$.toml"
trap 'rm -rf "$tmp" "$off"' EXIT
awk '{ print } /^\[output\]/ { print "mcap = false" }' "$scenario" > "$off"
grep -q '^mcap = false' "$off" || printf '\n[output]\nmcap = false\n' >> "$off"
for i in $(seq "$runs"); do
  for bin in "$@"; do
    for rec in on off; do
      file=$scenario; [ $rec = off ] && file=$off
      line=$("$bin" run "$file" --duration "$duration" --out "$tmp/run" --quiet 2>&1 | grep 'samples/s' || true)
      rate=$(sed -E 's/.*\(([0-9]+) samples\/s\).*/\1/' <<<"$line")
      samples=$(sed -E 's/^evoloop: ([0-9]+) samples.*/\1/' <<<"$line")
      bytes=0
      [ $rec = on ] && bytes=$(( $(stat -c %s "$tmp/run/run.mcap") / samples ))
      echo "$bin $(basename "$scenario" .toml) $rec $rate $bytes"
      rm -rf "$tmp/run"
    done
  done
done

#!/bin/sh
# The regression reference of every shipped scenario: each config/PLANT/*.toml (config/*.toml in
# a checkout from before 2026-12-06, when the scenarios lay flat) that is a run scenario (not a
# `tune` experiment, not a robot file) runs in lockstep with its own seed, and the md5 of its run.csv is
# printed as a table. Compare two checkouts by running this with each one's binary:
#
#   scripts/lockstep_md5.sh [BIN] [CONFIG_DIR] > md5.txt
#
# BIN defaults to target/release/evoloop, CONFIG_DIR to config. The runs go to a temporary
# directory that is removed afterwards.
set -eu
bin=${1:-target/release/evoloop}
configs=${2:-config}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
printf '%-34s %s\n' scenario "run.csv md5"
ran=0
for f in "$configs"/*.toml "$configs"/*/*.toml; do
    [ -f "$f" ] || continue # a pattern that matched nothing
    name=$(basename "$f" .toml)
    case "$f" in */robots/*) continue ;; esac # a robot, not a scenario
    if grep -q '^experiment *=' "$f"; then
        continue # a `evoloop tune` experiment, not a run
    fi
    if grep -q '^kind = "external"' "$f"; then
        continue # a plant of the user's own (tests/python_plant.rs checks its run)
    fi
    ran=$((ran + 1))
    if "$bin" run "$f" --mode lockstep --quiet --out "$out/$name" >"$out/$name.log" 2>&1; then
        printf '%-34s %s\n' "$name" "$(md5sum <"$out/$name/run.csv" | cut -d' ' -f1)"
    else
        printf '%-34s %s\n' "$name" "FAILED (exit $?): $(tail -n 1 "$out/$name.log")"
    fi
done
if [ "$ran" -eq 0 ]; then
    echo "no scenario found in $configs" >&2
    exit 1
fi

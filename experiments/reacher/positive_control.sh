#!/usr/bin/env bash
# Issue 14's Markovian positive control: task "blue" (touch the blue ball; its machine has
# two states, so a reward over the fingertip's position alone expresses it). Every IRL
# algorithm on the committed "blue" expert's 16 demonstrations, 3 seeds, SMIRL's schedule for
# every algorithm (config.toml, the standard profile; config_uniform.toml, figure 7 before
# issue 14, and controls/*.toml are in the old layout: the binary of 2207e5a; or CONFIG), into experiments/reacher/runs/blue<SUFFIX>, the baselines' jobs first; wall
# time to runs/blue<SUFFIX>.time (one line per invocation, appended). A baseline's failure on the paper's tasks means something
# only if it solves this one. Rerunning skips finished jobs.
# Usage: experiments/reacher/positive_control.sh [CONFIG] [SUFFIX] [ALGOS]
#   ALGOS: default "maxent fkl rkl js smirl smirl-smooth"
#   (REACHER_BIN=<binary> runs another build, e.g. a copy during a long sweep; JOBS=<n>;
#   SEEDS="0" runs only those of the three prepared seeds)
set -euo pipefail
cd "$(dirname "$0")/../.."
CONFIG=${1:-experiments/reacher/config.toml}
SUFFIX=${2:-}
ALGOS=${3:-maxent fkl rkl js smirl smirl-smooth}
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
out=experiments/reacher/runs/blue$SUFFIX
start=$(date +%s)
[ -f "$out/prepare.json" ] || "$BIN" prepare --task blue --algo all --seeds 3 --config "$CONFIG" \
  --out "$out" --quiet
for a in $ALGOS; do for s in ${SEEDS:-0 1 2}; do echo "$a $s"; done; done |
  xargs -P "${JOBS:-2}" -L 1 sh -c '"$0" job --run "$1" --algo "$2" --seed "$3" --quiet > /dev/null' "$BIN" "$out"
"$BIN" aggregate "$out" --partial | tee "$out.log"
echo "wall_secs $(( $(date +%s) - start )) task blue algos $ALGOS seeds ${SEEDS:-0 1 2} config $CONFIG" >> "$out.time"

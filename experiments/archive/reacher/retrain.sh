#!/usr/bin/env bash
# The learned rewards re-optimised: for each finished job of the run directories given, a
# fresh SAC agent trained on the job's final learned reward (held fixed) with the job's own SAC
# settings and budget, judged on the ground truth at 5 evenly spaced points
# (`reacher retrain`, src/pipeline/reacher_irl/retrain.rs) -> <run>/retrain/<algo>_seed<S>_sac<K>.csv.
# Then `python3 experiments/reacher/retrain_table.py --write RUN...` collects the last points into
# experiments/reacher/retrain.csv (tracked) and `python3 experiments/reacher/retrain_table.py`
# prints the table.
# The protocol (fresh agent, the job's budget, SAC seed 1000, 5 evaluations) is fixed in the
# command's defaults; SAC_SEED=<k> repeats it with another agent seed.
# Usage: experiments/reacher/retrain.sh "ALGOS" RUN_DIR...
#   e.g. experiments/reacher/retrain.sh "smirl smirl-smooth" experiments/reacher/runs/composite
#   REACHER_BIN=<binary>; JOBS=<n> (default 1); finished tables are skipped.
set -euo pipefail
cd "$(dirname "$0")/../.."
ALGOS=$1
shift
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
SAC_SEED=${SAC_SEED:-1000}
for run in "$@"; do
  for algo in $ALGOS; do
    for job in "$run"/jobs/"$algo"_seed*.json; do
      [ -f "$job" ] || continue
      seed=${job##*_seed}
      seed=${seed%.json}
      [ -f "$run/retrain/${algo}_seed${seed}_sac${SAC_SEED}.csv" ] && continue
      echo "$run $algo $seed"
    done
  done
done | while read -r run algo seed; do echo "$run $algo $seed $SAC_SEED"; done |
  xargs -P "${JOBS:-1}" -L 1 sh -c \
    '"$0" retrain --run "$1" --algo "$2" --seed "$3" --sac-seed "$4" > /dev/null && echo "retrained $1 $2 $3 (SAC seed $4)"' \
    "$BIN"

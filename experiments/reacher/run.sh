#!/usr/bin/env bash
# Figure 7 of the paper: ReacherDelivery tasks x IRL algorithms x seeds, ground-truth success
# per IRL iteration. Usage:
#   experiments/reacher/run.sh [TASKS] [ALGOS] [SEEDS] [CONFIG]
# defaults: "or sequential if composite", "all", 3, experiments/reacher/config.toml (the
# standard profile; config_scripted.toml, in the old layout, needs the binary of 2207e5a).
# One run directory per task under
# experiments/reacher/runs/<task>; wall times go to experiments/reacher/runs/<task>.time.
# REACHER_BIN runs another build of the binary (e.g. a copy, so that rebuilding the checkout
# during a long sweep does not change the binary between tasks).
set -euo pipefail
cd "$(dirname "$0")/../.."
TASKS=${1:-"or sequential if composite"}
ALGOS=${2:-all}
SEEDS=${3:-3}
CONFIG=${4:-experiments/reacher/config.toml}
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
for task in $TASKS; do
  start=$(date +%s)
  "$BIN" --task "$task" --algo "$ALGOS" --seeds "$SEEDS" --config "$CONFIG" \
    --out "experiments/reacher/runs/$task" --force --quiet | tee "experiments/reacher/runs/$task.log"
  echo "wall_secs $(( $(date +%s) - start )) task $task algos $ALGOS seeds $SEEDS config $CONFIG" \
    > "experiments/reacher/runs/$task.time"
done

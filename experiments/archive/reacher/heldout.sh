#!/usr/bin/env bash
# Held-out check of a config chosen on seeds 0-2: SMIRL on OR, Sequential, IF and Composite
# with base seed BASE (new demonstrations, new learned machine) and SAC seeds BASE, BASE+1,
# BASE+2. TASKS="if composite" restricts the tasks; REACHER_BIN runs another build of the
# binary (see run.sh).
# Usage: experiments/reacher/heldout.sh [CONFIG] [PREFIX] [BASE]
#   defaults: experiments/reacher/config.toml, no prefix, 3 -> experiments/reacher/heldout/<PREFIX><task>
# (the replay ablation: heldout.sh experiments/reacher/ablations/replay_100k.toml replay_100k-)
set -euo pipefail
cd "$(dirname "$0")/../.."
CONFIG=${1:-experiments/reacher/config.toml}
PREFIX=${2:-}
BASE=${3:-3}
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
mkdir -p experiments/reacher/heldout
for task in ${TASKS:-or sequential if composite}; do
  "$BIN" --task "$task" --algo smirl --seed "$BASE" --seeds 3 \
    --config "$CONFIG" --out "experiments/reacher/heldout/$PREFIX$task" --force --quiet \
    > "experiments/reacher/heldout/$PREFIX$task.log"
done

#!/usr/bin/env bash
# Held-out check of a config chosen on seeds 0-2: SMIRL on OR, Sequential and IF with base
# seed BASE (new demonstrations, new learned machine) and SAC seeds BASE, BASE+1, BASE+2.
# Usage: experiments/reacher/heldout.sh [CONFIG] [PREFIX] [BASE]
#   defaults: experiments/reacher/config.toml, no prefix, 3 -> experiments/reacher/heldout/<PREFIX><task>
# (the replay ablation: heldout.sh experiments/reacher/ablations/replay_100k.toml replay_100k-)
set -euo pipefail
cd "$(dirname "$0")/../.."
CONFIG=${1:-experiments/reacher/config.toml}
PREFIX=${2:-}
BASE=${3:-3}
cargo build --release --bin reacher
mkdir -p experiments/reacher/heldout
for task in or sequential if; do
  ./target/release/reacher --task "$task" --algo smirl --seed "$BASE" --seeds 3 \
    --config "$CONFIG" --out "experiments/reacher/heldout/$PREFIX$task" --quiet \
    > "experiments/reacher/heldout/$PREFIX$task.log"
done

#!/usr/bin/env bash
# Held-out check of the default config (chosen on seeds 0-2): SMIRL on OR, Sequential and IF
# with base seed 3 (new demonstrations, new learned machine) and SAC seeds 3, 4, 5.
# Usage: experiments/reacher/heldout.sh   -> experiments/reacher/heldout/<task>
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin reacher
mkdir -p experiments/reacher/heldout
for task in or sequential if; do
  ./target/release/reacher --task "$task" --algo smirl --seed 3 --seeds 3 \
    --config experiments/reacher/config.toml --out "experiments/reacher/heldout/$task" --quiet \
    > "experiments/reacher/heldout/$task.log"
done

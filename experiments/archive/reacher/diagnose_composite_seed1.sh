#!/usr/bin/env bash
# Composite's normal-branch failure, seed 1 of figure 7 (experiments/reacher/runs/composite):
# reruns that SMIRL job with every episode logged, in a temporary copy of the run directory
# (same demonstrations, machine and config but log_every_nth_episode = 1; the metrics equal the
# committed job's), and writes per-iteration branch successes of the stochastic rollouts and
# the mean-action evaluations to diagnostics/composite_seed1_branches.txt.
# Usage: experiments/reacher/diagnose_composite_seed1.sh   (REACHER_BIN=<binary> for another build)
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
run=$(mktemp -d)/composite
mkdir -p "$run"
src=experiments/reacher/runs/composite
cp -r "$src/prepare.json" "$src/expert_data.bin" "$src/run.json" "$src/rm" "$run/"
sed 's/^log_every_nth_episode = .*/log_every_nth_episode = 1/' "$src/config.toml" > "$run/config.toml"
"$BIN" job --run "$run" --algo smirl --seed 1 --quiet
out=experiments/reacher/diagnostics/composite_seed1_branches.txt
{
  echo "# experiments/reacher/diagnose_composite_seed1.sh: Composite, smirl, seed 1, every episode logged"
  python3 experiments/reacher/branches_per_iteration.py "$run/logs/smirl_seed1.mcap"
} > "$out"
echo "wrote $out (the job's run directory: $run)"

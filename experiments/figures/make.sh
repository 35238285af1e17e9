#!/usr/bin/env bash
# Draws the paper's figures 4, 5 (Office Gridworld) and 7 (ReacherDelivery) as small multiples
# into experiments/figures/: each algorithm in its own colour in every panel, the legend beside
# the panels, on IF and Composite each branch (normal solid, cancel dashed).
# Figure 7 reads the committed run data (experiments/reacher/figure7_curves.py); figures 4 and 5
# rerun the Office runs behind experiments/office/results.md (10 seeds from base 0, the
# committed config; about two minutes) into a temporary directory, unless OFFICE_RUNS names a
# directory holding them (t0 … t4, as experiments/office/run.sh writes).
# Usage: experiments/figures/make.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin reacher --bin office
BIN=target/release/reacher
OUT=experiments/figures
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 experiments/reacher/figure7_curves.py > "$tmp/figure7.csv"
"$BIN" figure --data "$tmp/figure7.csv" --out "$OUT/figure7.svg" --force --y-range 0,1 \
  --title "Figure 7: ReacherDelivery, success of each IRL iteration's policy (base seed 0; smirl and smirl-paper 6 SAC seeds, baselines 3)"
if [ -z "${OFFICE_RUNS:-}" ]; then
  OFFICE_RUNS=$tmp/office
  for t in 0 1 2 3 4; do
    target/release/office --task "$t" --algo all --seeds 10 --seed 0 \
      --config experiments/office/config.toml --out "$OFFICE_RUNS/t$t" > /dev/null
  done
fi
python3 experiments/office/figure_curves.py "$OFFICE_RUNS" 0 > "$tmp/figure4.csv"
"$BIN" figure --data "$tmp/figure4.csv" --out "$OUT/figure4.svg" --force --y-range -0.05,1.05 \
  --columns 1 --x-label "IRL step" --y-label "ground-truth return (success)" \
  --title "Figure 4: Office Gridworld, single-step task (10 seeds)"
python3 experiments/office/figure_curves.py "$OFFICE_RUNS" 1 2 3 4 > "$tmp/figure5.csv"
"$BIN" figure --data "$tmp/figure5.csv" --out "$OUT/figure5.svg" --force --y-range -0.05,1.05 \
  --x-label "IRL step" --y-label "ground-truth return (success)" \
  --title "Figure 5: Office Gridworld, multi-step tasks (10 seeds)"
ls -l "$OUT"/figure{4,5,7}.svg

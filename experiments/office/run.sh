#!/usr/bin/env bash
# Reproduces the Office Gridworld results (paper figures 4 and 5): every task, every
# algorithm, several seeds. Writes experiments/office/runs<TAG>/t<N>/ (metrics, learned RMs
# and weights, success.svg; not tracked) and runs<TAG>/summary.csv (the five summaries in one
# file, tracked), copies the plots to experiments/office/fig<TAG>_t<N>.svg, and writes the
# results table experiments/office/results<TAG>.md (table by table.sh).
#
# Usage: [CONFIG=experiments/office/config.toml] [TAG=] experiments/office/run.sh [SEEDS] [BASE_SEED]
set -euo pipefail
cd "$(dirname "$0")/../.."
SEEDS="${1:-5}"
BASE="${2:-0}"
HERE=experiments/office
CONFIG="${CONFIG:-$HERE/config.toml}"
TAG="${TAG:-}"
cargo build --release --bin office
BIN=target/release/office
RUNS="$HERE/runs$TAG"
mkdir -p "$RUNS"
for t in 0 1 2 3 4; do
  "$BIN" --task "$t" --algo all --seeds "$SEEDS" --seed "$BASE" --config "$CONFIG" \
    --out "$RUNS/t$t" --force
  cp "$RUNS/t$t/success.svg" "$HERE/fig${TAG}_t$t.svg"
done
# The five summaries in one file, the only per-run file tracked (experiments/README.md); the
# same bytes as `python3 experiments/consolidate.py` writes.
{ head -n 1 "$RUNS/t0/summary.csv"; for t in 0 1 2 3 4; do tail -n +2 "$RUNS/t$t/summary.csv"; done; } > "$RUNS/summary.csv"

CMD="${TAG:+TAG=$TAG }${CONFIG:+CONFIG=$CONFIG }experiments/office/run.sh $SEEDS $BASE"
{
  echo "# Office Gridworld results${TAG:+ ($TAG)}"
  echo
  echo "Made by \`$CMD\` at commit \`$(git rev-parse --short HEAD)\`"
  echo "on $(nproc) cores (shared with other jobs); $SEEDS seeds (base seed $BASE) per task and algorithm."
  echo
  echo "- final success: ground-truth success of the policy after the last IRL step (mean ± std"
  echo "  over seeds); for apprenticeship also the expected success of the projection method's"
  echo "  mixture policy (mean over seeds)."
  echo "- time: wall-clock seconds of one complete run (demonstrations, RM learning, IRL to"
  echo "  convergence or step limit, evaluation after every step): median over seeds [min, max];"
  echo "  ratio = median / the 10 s target (SMIRL)."
  echo "- RM states per seed, and in how many seeds the learned machine refines the perfect one"
  echo "  along the demonstrations."
  echo
  "$HERE/table.sh" "$TAG"
  echo
  echo "Plots: \`fig${TAG}_t0.svg\` … \`fig${TAG}_t4.svg\` (ground-truth return per IRL step, mean ± std)."
} > "$HERE/results$TAG.md"
cat "$HERE/results$TAG.md"

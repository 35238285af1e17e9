#!/usr/bin/env bash
# Reproduces the Office Gridworld results (paper figures 4 and 5): every task, every
# algorithm, several seeds. Writes experiments/office/runs<TAG>/t<N>/ (metrics, learned RMs
# and weights, success.svg), copies the plots to experiments/office/fig<TAG>_t<N>.svg, and
# writes the results table experiments/office/results<TAG>.md.
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
  echo "| task | algorithm | final success | mixture success | IRL steps (mean) | converged | time s median [min, max] | ratio to 10 s | RM states | refines perfect RM |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
  for t in 0 1 2 3 4; do
    for a in smirl maxent apprenticeship; do
      awk -F, -v a="$a" -v t="$t" '
        NR > 1 && $2 == a {
          n++; s += $4; ss += $4 * $4; steps += $5; times[n] = $12; conv += ($6 == "true")
          mix += $13
          if ($7 != "") { states = states (states == "" ? "" : " ") $7 }
          if ($8 != "") { ref += ($8 == "true") }
        }
        END {
          if (n == 0) exit
          mean = s / n; var = ss / n - mean * mean; if (var < 0) var = 0
          # median of times (insertion sort; n is small)
          for (i = 2; i <= n; i++) { v = times[i]; j = i - 1
            while (j > 0 && times[j] > v) { times[j + 1] = times[j]; j-- } times[j + 1] = v }
          med = (n % 2) ? times[(n + 1) / 2] : (times[n / 2] + times[n / 2 + 1]) / 2
          ratio = (a == "smirl") ? sprintf("%.3f", med / 10) : "-"
          refs = (a == "smirl") ? sprintf("%d/%d", ref, n) : "-"
          mixs = (a == "apprenticeship") ? sprintf("%.2f", mix / n) : "-"
          if (states == "") states = "-"
          printf "| %s | %s | %.2f ± %.2f | %s | %.1f | %d/%d | %.2f [%.2f, %.2f] | %s | %s | %s |\n", \
            t, a, mean, sqrt(var), mixs, steps / n, conv, n, med, times[1], times[n], ratio, states, refs
        }' "$RUNS/t$t/summary.csv"
    done
  done
  echo
  echo "Plots: \`fig${TAG}_t0.svg\` … \`fig${TAG}_t4.svg\` (ground-truth return per IRL step, mean ± std)."
} > "$HERE/results$TAG.md"
cat "$HERE/results$TAG.md"

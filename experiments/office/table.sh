#!/usr/bin/env bash
# The results table of one Office experiment (the table of results<TAG>.md) from
# runs<TAG>/summary.csv, the five tasks' runs<TAG>/t<N>/summary.csv in one file (first column
# `task`; written by run.sh and by `python3 experiments/consolidate.py`, the only per-run file of
# an Office experiment that is tracked: experiments/README.md).
# Usage: experiments/office/table.sh [TAG]      e.g. experiments/office/table.sh _seeds100
set -euo pipefail
SUMMARY="$(dirname "$0")/runs${1:-}/summary.csv"
echo "| task | algorithm | final success | mixture success | IRL steps (mean) | converged | time s median [min, max] | ratio to 10 s | RM states | refines perfect RM |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for t in 0 1 2 3 4; do
  for a in smirl maxent apprenticeship; do
    awk -F, -v a="$a" -v t="$t" '
      NR > 1 && $1 == t && $2 == a {
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
      }' "$SUMMARY"
  done
done

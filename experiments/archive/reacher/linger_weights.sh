#!/usr/bin/env bash
# Writes experiments/reacher/linger_weights.md: the lingering trap of the rewards whose fresh
# agents fail (results_figure7.md), from the jobs' reward traces on disk (linger_weights.py).
set -euo pipefail
cd "$(dirname "$0")"
{
  echo "| run | algorithm | seed | learned-machine state | touched ball, final weight | next ball, final weight | data gradient on the touched ball < 0, last iterations |"
  echo "|---|---|---|---|---|---|---|"
  python3 linger_weights.py runs/composite smirl 0 1 r b 9          # state 1: after red
  python3 linger_weights.py heldout/if smirl 3 2 b r 9              # state 2: after blue
  python3 linger_weights.py heldout/seeds6-if smirl 6 2 b r 9       # state 2: after blue or cancel
} > linger_weights.md
cat linger_weights.md

#!/usr/bin/env bash
# Builds experiments/reacher/results.md from the run directories (every number from a script):
# the prose of results_header.md, the figure-7 table (results.py), the held-out table
# (heldout.py), the partial-progress tables of OR and Sequential (progress.py) and the
# earlier sessions' notes (results_notes.md).
set -euo pipefail
cd "$(dirname "$0")"
{
  cat results_header.md
  python3 results.py
  python3 heldout.py
  for t in or sequential; do
    printf '\n## Partial progress: %s (`python3 progress.py runs/%s`)\n\n' "$t" "$t"
    python3 progress.py "runs/$t"
  done
  echo
  cat results_notes.md
} > results.md

#!/usr/bin/env bash
# The size of what experiments/ tracks, against its budget (experiments/README.md, "Budget"):
# prints the number of tracked files and their bytes, and exits 1 above 520 files or 7.8 MB
# (7 800 000 bytes). Also reports, without failing, tracked files that experiments/.gitignore
# ignores (force-added) and consolidated files older than their run directories on disk.
# Usage: experiments/lean_check.sh      (from anywhere in the repository)
set -euo pipefail
cd "$(dirname "$0")/.."
MAX_FILES=520
MAX_BYTES=7800000
files=$(git ls-files experiments | wc -l)
# Summed per file (xargs may split a long list over several `du -c` calls, each with its own total).
bytes=$(git ls-files -z experiments | xargs -0 -r stat --format=%s | awk '{s += $1} END {print s + 0}')
echo "experiments/: $files tracked files (budget $MAX_FILES), $bytes bytes (budget $MAX_BYTES)"
git ls-files -z experiments | xargs -0 -r stat --format='%s %n' | sort -rn | head -5 | sed 's/^/  largest: /'
forced=$(git ls-files -ci --exclude-standard experiments | wc -l)
if [ "$forced" -gt 0 ]; then
  echo "note: $forced tracked files match experiments/.gitignore (git ls-files -ci --exclude-standard experiments)"
fi
if ! python3 experiments/consolidate.py --check > /tmp/lean_check.$$ 2>&1; then
  echo "note: consolidated files differ from the run directories on disk (python3 experiments/consolidate.py):"
  sed 's/^/  /' /tmp/lean_check.$$
fi
rm -f /tmp/lean_check.$$
status=0
[ "$files" -le "$MAX_FILES" ] || { echo "over budget: $files files > $MAX_FILES"; status=1; }
[ "$bytes" -le "$MAX_BYTES" ] || { echo "over budget: $bytes bytes > $MAX_BYTES"; status=1; }
[ "$status" = 0 ] && echo "within budget"
exit "$status"

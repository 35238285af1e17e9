#!/usr/bin/env bash
# Whole-pipeline identity check of a `reacher` binary against a reference hash list: runs
# `--quick --algo all --seeds 1 --seed 0` on the five shipped tasks and hashes every
# metrics.csv and rewards/* file; with REF given (a path from where the script is called),
# diffs the list against REF's hash lines (its `#` comment lines aside).
#
#   nice -n 10 experiments/env/quick_hashes.sh BIN OUTDIR [REF]
set -euo pipefail
HERE=$(dirname "$(realpath "$0")")
BIN=$(realpath "$1")
OUT=$2
REF=${3:+$(realpath "$3")}
mkdir -p "$OUT"
cd "$OUT"
for t in or sequential if composite blue; do
    /usr/bin/time -f "%e s $t" "$BIN" --task "$t" --quick --algo all --seeds 1 --seed 0 --quiet \
        --out "quick-$t" > "log-quick-$t.txt" 2>&1
done
find . -name metrics.csv -o -path '*/rewards/*' -type f | sort | xargs sha256sum > hashes.txt
cat hashes.txt
if [ -n "$REF" ]; then
    "$HERE/compare_hashes.sh" hashes.txt "$REF"
fi

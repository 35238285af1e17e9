#!/usr/bin/env bash
# Whole-pipeline identity check of a `reacher` binary on one full-profile job: SMIRL on
# Composite with the expert's demonstrations and the standard schedule (`--seeds 1 --seed 0`),
# then the hashes of metrics.csv and rewards/*; with REF given (a path from where the script is
# called), diffs the list against REF's hash lines (its `#` comment lines aside). The job uses
# the binary's built-in profile and experts, so it reads nothing from the working directory.
#
#   experiments/env/full_job_hashes.sh BIN OUTDIR [REF]
set -euo pipefail
HERE=$(dirname "$(realpath "$0")")
BIN=$(realpath "$1")
OUT=$(realpath -m "$2")
REF=${3:+$(realpath "$3")}
if [ -e "$OUT" ]; then echo "$OUT exists: give a new directory" >&2; exit 2; fi
mkdir -p "$OUT"
/usr/bin/time -f "%e s wall, %U s user" "$BIN" --task composite --algo smirl --seeds 1 --seed 0 \
    --quiet --out "$OUT/full-smirl-composite" > "$OUT/log.txt" 2>&1
cd "$OUT"
find full-smirl-composite -name metrics.csv -o -path '*/rewards/*' -type f | sort \
    | xargs sha256sum > hashes.txt
cat hashes.txt
if [ -n "$REF" ]; then
    "$HERE/compare_hashes.sh" hashes.txt "$REF"
fi

#!/usr/bin/env bash
# Compares a sha256sum list with a reference list (the reference's `#` comment lines aside) and
# says whether they are identical, or prints the difference. Used by quick_hashes.sh and
# full_job_hashes.sh.
#
#   experiments/env/compare_hashes.sh HASHES REF
set -euo pipefail
if grep -v '^#' "$2" | diff "$1" - > /dev/null; then
    echo "identical to $2 ($(wc -l < "$1") files)"
else
    echo "DIFFERENT from $2:"
    grep -v '^#' "$2" | diff "$1" - || true
fi

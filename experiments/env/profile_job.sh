#!/usr/bin/env bash
# Where one IRL job's CPU time goes: ALGO (default fkl) on Composite with the standard schedule
# cut to ITERS (default 30) IRL iterations and no final phase, sampled by `perf record` (Debian:
# linux-perf), and its samples summed by what the symbol belongs to: MuJoCo (mj_*, mju_*, and
# libc's memmove/memset, which MuJoCo's array copies call), the matrix products
# (matrixmultiply's kernel and packing), the networks' own code (smirl::nn), the KDE, and the
# rest. Prints the groups' shares and the 20 heaviest symbols. Work files go to $WORK (default
# target/profile_job).
#
#   experiments/env/profile_job.sh REACHER_BIN [ITERS]
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=$(realpath "$1")
ITERS=${2:-30}
WORK=${WORK:-target/profile_job}
ALGO=${ALGO:-fkl}
# WORK is this script's own: it deletes run directories inside it, so it refuses a directory
# it did not make (the marker file says it did).
if [ -e "$WORK" ] && [ ! -e "$WORK/.made_by_profile_job.sh" ]; then
    echo "profile_job.sh: $WORK exists and was not made by this script; set WORK to a new directory" >&2
    exit 2
fi
mkdir -p "$WORK"
touch "$WORK/.made_by_profile_job.sh"
"$BIN" --task composite --print-config \
    | sed -e "s/^irl_iterations = 800$/irl_iterations = $ITERS/" \
        -e 's/^sac_steps = 20000$/sac_steps = 0/' \
        -e 's/^checkpoints = 4$/checkpoints = 0/' > "$WORK/job.toml"
rm -rf "$WORK/run"
"$BIN" prepare --task composite --config "$WORK/job.toml" --algo "$ALGO" --quiet \
    --out "$WORK/run" > /dev/null
perf record -q -F 999 -o "$WORK/perf.data" \
    "$BIN" job --run "$WORK/run" --algo "$ALGO" --seed 0 --quiet > /dev/null 2>&1
perf report -i "$WORK/perf.data" --no-children --sort dso,symbol --stdio 2>/dev/null \
    | sed -n -E 's/^ +([0-9.]+)%  ([^ ]+) +\[.\] (.*[^ ]) +- +- *$/\1\t\2\t\3/p' > "$WORK/symbols.txt"
echo "# $ALGO, composite, standard schedule with $ITERS IRL iterations, no final phase; $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg)"
echo "# binary: $("$BIN" --version)"
echo "# share of the job's samples by what the code belongs to"
awk -F '\t' '{
    if ($2 ~ /^libmujoco/) g = "MuJoCo"
    else if ($2 ~ /^libc/ && $3 ~ /^__(memmove|memset|memcpy)/) g = "libc memmove/memset (called by MuJoCo for the most part)"
    else if ($3 ~ /^matrixmultiply::/) g = "matrix products (matrixmultiply kernel and packing)"
    else if ($3 ~ /^smirl::irl::kde::/) g = "KDE"
    else if ($3 ~ /^smirl::nn::/) g = "networks and Adam (smirl::nn)"
    else if ($2 ~ /^libm/) g = "libm (exp, tanh, sincos, log1p)"
    else g = "the rest"
    share[g] += $1
} END { for (g in share) printf "%6.2f%%  %s\n", share[g], g }' "$WORK/symbols.txt" | sort -rn
echo "# the 20 heaviest symbols"
head -20 "$WORK/symbols.txt" | awk -F '\t' '{printf "%6.2f%%  %s  %s\n", $1, $2, substr($3, 1, 100)}'

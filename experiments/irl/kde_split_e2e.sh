#!/usr/bin/env bash
# One fkl-product job (Sequential, base 0, SAC seed 0) cut to 300 of its 800 IRL iterations,
# run with each of two reacher binaries one after the other: the end-to-end effect of a KDE
# change. Wall seconds go to stdout.
#   experiments/irl/kde_split_e2e.sh OLD_REACHER NEW_REACHER OUT_DIR
# OUT_DIR must not exist; it receives the config and one run directory per binary.
set -euo pipefail
if [ $# -ne 3 ]; then
    echo "usage: $0 OLD_REACHER NEW_REACHER OUT_DIR" >&2
    exit 2
fi
old=$1 new=$2 out=$3
if [ -e "$out" ]; then
    echo "$out exists: give a new directory" >&2
    exit 2
fi
mkdir -p "$out"
sed 's/^irl_iterations = 800$/irl_iterations = 300/' experiments/reacher/config.toml > "$out/config.toml"
grep -q '^irl_iterations = 300$' "$out/config.toml"
for which in old new; do
    bin=$old
    [ "$which" = new ] && bin=$new
    "$bin" prepare --task sequential --algo fkl-product --seeds 1 --seed 0 \
        --config "$out/config.toml" --out "$out/$which" --quiet > /dev/null
    start=$(date +%s.%N)
    "$bin" job --run "$out/$which" --algo fkl-product --seed 0 --quiet > /dev/null
    end=$(date +%s.%N)
    echo "$which $("$bin" --version) wall_secs $(echo "$end - $start" | bc)"
done

#!/usr/bin/env bash
# f-IRL's own Reacher experiment (ReacherDraw), issue 14's positive control of the f-IRL and
# MaxEnt baselines: each algorithm matches a fingertip density (gaussian, mixture) with
# f-IRL's settings (src/pipeline/reacher_draw.rs, DrawConfig::default), into
# experiments/reacher_draw/runs/<target>/<algo>_seed<seed>/ (config.toml, metrics.csv,
# summary.json, density.png); a finished run is skipped. Then results.md via summarise.py.
# Usage: experiments/reacher_draw/run.sh [TARGETS] [ALGOS] [SEEDS]
#   defaults: "gaussian mixture", "fkl rkl js maxent", "0"
#   REACHER_BIN=<binary> runs another build (e.g. a copy during a long sweep); JOBS=<n> at once.
set -euo pipefail
cd "$(dirname "$0")/../.."
TARGETS=${1:-"gaussian mixture"}
ALGOS=${2:-"fkl rkl js maxent"}
SEEDS=${3:-0}
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
OUT=experiments/reacher_draw/runs
mkdir -p "$OUT"
for t in $TARGETS; do for a in $ALGOS; do for s in $SEEDS; do
  [ -f "$OUT/$t/${a}_seed$s/summary.json" ] || echo "$t $a $s"
done; done; done |
  xargs -P "${JOBS:-2}" -L 1 sh -c 'mkdir -p "$0/$2" && "$1" draw --target "$2" --algo "$3" --seed "$4" --out "$0/$2/$3_seed$4" --force --quiet' "$OUT" "$BIN" 2>&1 |
  tee -a "$OUT/run.log"
python3 experiments/reacher_draw/summarise.py > experiments/reacher_draw/results.md

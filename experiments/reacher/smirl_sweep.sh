#!/usr/bin/env bash
# SMIRL on OR, Sequential, IF and Composite with one config: per task one run directory with
# demonstrations and learned machine from base seed BASE and SAC seeds BASE, BASE+1, BASE+2.
# SMIRL's own rows of figure 7 and its held-out checks (issue 13):
#
#   experiments/reacher/smirl_sweep.sh 'experiments/reacher/runs/{task}-final' 0     (with the final policy;
#     runs/{task}-shaped: the same IRL loops, made before it)
#   experiments/reacher/smirl_sweep.sh 'experiments/reacher/heldout/final-{task}' 3
#   experiments/reacher/smirl_sweep.sh 'experiments/reacher/heldout/final-seeds6-{task}' 6
#   experiments/reacher/smirl_sweep.sh 'experiments/reacher/heldout/final-seeds9-{task}' 9
#
# Base seed 0 gives figure 7's demonstrations and machines (those of runs/<task>-schedules,
# whose baseline rows it completes: the baselines read none of SMIRL's settings). {task} in
# OUT is replaced by the task. A directory the program did not write is never replaced
# (`--force` replaces only its own output). Then `python3 experiments/consolidate.py` for the
# held-out rows, `python3 experiments/reacher/figure7.py RUN...` for tables.
# Environment: ALGOS (default "smirl,smirl-smooth"), TASKS (default all four), CONFIG
# (default experiments/reacher/config.toml, the standard profile), REACHER_BIN (another build,
# e.g. a copy, so that rebuilding the checkout during the sweep does not change the binary).
# SAC_SEEDS (e.g. "3 4 5"): SAC seeds other than BASE..BASE+2 on BASE's demonstrations and
# machine — more tuning seeds on base 0 — run as `prepare`, one `job` per seed (JOBS at once,
# default 2) and `aggregate --partial`; the plan counts seeds from BASE, so the run's
# prepare.json lists seeds the sweep did not run.
#
#   SAC_SEEDS="3 4 5" ALGOS=smirl experiments/reacher/smirl_sweep.sh 'experiments/reacher/ablations/runs/standard-seeds3to5-{task}' 0
#
# MACHINE=task: CONFIG with `[smirl] machine = "task"` (a copy in a temporary file): SMIRL reads
# the task's own machine instead of LRM's — an oracle for diagnosis, not the method.
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${1:?usage: smirl_sweep.sh OUT [BASE], OUT with the text {task\}}
BASE=${2:-0}
ALGOS=${ALGOS:-smirl,smirl-smooth}
CONFIG=${CONFIG:-experiments/reacher/config.toml}
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
if [ -n "${SAC_SEEDS:-}" ]; then
  for seed in $SAC_SEEDS; do
    case $seed in '' | *[!0-9]*) echo "SAC_SEEDS: '$seed' is not a seed (a non-negative integer)" >&2; exit 2 ;; esac
  done
  last=$(printf '%s\n' $SAC_SEEDS | sort -n | tail -1)
  if [ "$last" -lt "$BASE" ]; then echo "SAC_SEEDS must be >= BASE ($BASE)" >&2; exit 2; fi
fi
case ${MACHINE:-learned} in
  learned) ;;
  task)
    task_config=$(mktemp)
    trap 'rm -f "$task_config"' EXIT
    sed '/^\[smirl\]$/,/^\[/ s/^machine = .*/machine = "task"/' "$CONFIG" > "$task_config"
    grep -q '^machine = "task"$' "$task_config" || { echo "MACHINE=task: $CONFIG has no [smirl] machine key" >&2; exit 2; }
    CONFIG=$task_config ;;
  *) echo "MACHINE: '$MACHINE' is neither 'learned' nor 'task'" >&2; exit 2 ;;
esac
for task in ${TASKS:-or sequential if composite}; do
  out=${OUT//\{task\}/$task}
  mkdir -p "$(dirname "$out")"
  if [ -n "${SAC_SEEDS:-}" ]; then
    "$BIN" prepare --task "$task" --algo "$ALGOS" --seed "$BASE" --seeds $((last - BASE + 1)) \
      --config "$CONFIG" --out "$out" --force --quiet > "$out.log"
    for algo in ${ALGOS//,/ }; do for seed in $SAC_SEEDS; do echo "$algo $seed"; done; done |
      xargs -P "${JOBS:-2}" -L 1 sh -c '"$0" job --run "$1" --algo "$2" --seed "$3" --quiet' "$BIN" "$out" >> "$out.log"
    "$BIN" aggregate "$out" --partial >> "$out.log"
    continue
  fi
  "$BIN" --task "$task" --algo "$ALGOS" --seed "$BASE" --seeds 3 --config "$CONFIG" \
    --out "$out" --force --quiet > "$out.log"
done

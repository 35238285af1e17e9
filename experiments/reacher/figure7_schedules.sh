#!/usr/bin/env bash
# Figure 7 with each baseline on the schedule of its positive control (issue 14):
# experiments/reacher/config.toml (the standard profile), every algorithm, SAC seeds BASE..BASE+2, into
# experiments/reacher/runs/<task>-schedules (BASE = 0, the figure's demonstrations and learned
# machines; another BASE gives held-out demonstrations and machines, into
# experiments/reacher/heldout/schedules-seed<BASE>-<task>).
#
# The jobs run through `reacher prepare` / `reacher job` / `reacher aggregate`, JOBS at a time
# (default 2 = the cores), in this order so that a cut-short sweep leaves whole seeds:
# seed-major, then fkl, js, maxent, smirl, smirl-smooth, then rkl last (it fails its positive
# control, so its numbers count least). A finished job is skipped, so rerunning resumes.
# Wall time per job is in each jobs/<algo>_seed<S>.json (`wall_secs`) and the summary table;
# the sweep's own goes to experiments/reacher/runs/figure7_schedules-base<BASE>.time.
#
# Usage: experiments/reacher/figure7_schedules.sh [TASKS] [ALGOS] [BASE]
#   defaults: "or sequential if composite", "fkl js maxent smirl smirl-smooth rkl", 0
#   CONFIG=<file> (default experiments/reacher/config.toml; the runs of issue 14 used what is now
#   config_unshaped.toml, whose baseline settings are the same);
#   SUFFIX=<name> (default "schedules") names the run directories runs/<task>-<name> and
#   heldout/<name>-seed<BASE>-<task>, e.g. SUFFIX=rkl_expert for rkl with demonstrations in its
#   covariance batch (README, "Positive controls");
#   REACHER_BIN=<binary> runs another build (e.g. a copy, so that rebuilding the checkout
#   during the sweep does not change the binary); JOBS=<n>; SEEDS="0 1 2" (offsets from BASE).
set -euo pipefail
cd "$(dirname "$0")/../.."
TASKS=${1:-"or sequential if composite"}
ALGOS=${2:-"fkl js maxent smirl smirl-smooth rkl"}
BASE=${3:-0}
CONFIG=${CONFIG:-experiments/reacher/config.toml}
SUFFIX=${SUFFIX:-schedules}
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}

run_dir() {
  if [ "$BASE" = 0 ]; then
    echo "experiments/reacher/runs/$1-$SUFFIX"
  else
    echo "experiments/reacher/heldout/$SUFFIX-seed$BASE-$1"
  fi
}

start=$(date +%s)
mkdir -p experiments/reacher/heldout
for task in $TASKS; do
  out=$(run_dir "$task")
  [ -f "$out/prepare.json" ] || "$BIN" prepare --task "$task" --algo all --seed "$BASE" \
    --seeds 3 --config "$CONFIG" --out "$out" --quiet
done
for offset in ${SEEDS:-0 1 2}; do
  for algo in $ALGOS; do
    [ "$algo" = rkl ] && continue
    for task in $TASKS; do echo "$(run_dir "$task") $algo $((BASE + offset))"; done
  done
done > /tmp/figure7_schedules.$$
case " $ALGOS " in
  *" rkl "*) for offset in ${SEEDS:-0 1 2}; do for task in $TASKS; do
      echo "$(run_dir "$task") rkl $((BASE + offset))"; done; done >> /tmp/figure7_schedules.$$ ;;
esac
xargs -P "${JOBS:-2}" -L 1 sh -c \
  '"$0" job --run "$1" --algo "$2" --seed "$3" --quiet > /dev/null && echo "done $1 $2 $3 $(date +%T)"' \
  "$BIN" < /tmp/figure7_schedules.$$
rm -f /tmp/figure7_schedules.$$
for task in $TASKS; do
  out=$(run_dir "$task")
  "$BIN" aggregate "$out" --partial | tee "$out.log"
done
echo "wall_secs $(( $(date +%s) - start )) tasks $TASKS algos $ALGOS base $BASE config $CONFIG" \
  >> "experiments/reacher/runs/figure7_schedules-base$BASE.time"

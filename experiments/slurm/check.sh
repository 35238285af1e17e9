#!/usr/bin/env bash
# Checks the Slurm path end to end on this machine (as root): brings up the local cluster
# (setup_local_cluster.sh), submits a --quick sweep (tasks or, if x smirl, maxent x 2 seeds) with
# figure.sh, waits for it, runs the same sweep in one process per task (`reacher --task ...`), and
# compares each task's metrics.csv with cmp. Prints both wall times and the largest number of
# array elements that ran at once (from the Slurm job-completion log; should be nproc).
# --kill-test: also submits a fresh sweep of task `or`, scancels one running array element,
# resubmits with `figure.sh --resume`, and checks metrics.csv is still identical.
# Usage: experiments/slurm/check.sh [--kill-test]
#   REACHER_BIN (default target/release/reacher, relative to the repo root); WAIT_MINUTES (60).
# Exits non-zero on any mismatch; runs are left in a temp dir under /tmp (printed).
set -euo pipefail
cd "$(dirname "$0")/../.."
here=experiments/slurm
bin=$(realpath "${REACHER_BIN:-target/release/reacher}")
[ -x "$bin" ] || { echo "no binary $bin (cargo build --release --bin reacher)" >&2; exit 1; }
export REACHER_BIN=$bin
tasks="or if"; algos=smirl,maxent; seeds=2; opts=(--seed 0 --quick)

"$here/setup_local_cluster.sh" >/dev/null
jobcomp=$(scontrol show config | awk '$1 == "JobCompLoc" {print $3}')
tmp=$(mktemp -d /tmp/reacher-slurm.XXXXXX)
echo "runs in $tmp"

wait_jobs() {   # ids of the lines figure.sh printed (fields 3, 5, 7) -> waits until none is queued
  local ids deadline=$(( $(date +%s) + ${WAIT_MINUTES:-60} * 60 ))
  ids=$(awk '{printf "%s%s,%s,%s", (NR > 1 ? "," : ""), $3, $5, $7}' <<<"$1" | sed 's/-,//g')
  while [ -n "$(squeue -h -j "$ids" 2>/dev/null)" ]; do
    if [ "$(date +%s)" -ge "$deadline" ]; then
      echo "timed out; cancelling $ids" >&2; scancel ${ids//,/ }; exit 1
    fi
    sleep 2
  done
}
failed_jobs() {  # job-completion log lines after line $1 whose state is not COMPLETED
  tail -n "+$(($1 + 1))" "$jobcomp" | grep -v 'JobState=COMPLETED' | sed 's/^/not completed: /' || true
}

# --- the sweep on Slurm ---
n0=$(cat "$jobcomp" 2>/dev/null | wc -l)
t0=$(date +%s)
sweep=$("$here/figure.sh" "$tmp/slurm" "$tasks" "$algos" "$seeds" "${opts[@]}")
echo "$sweep"
wait_jobs "$sweep"
t_slurm=$(( $(date +%s) - t0 ))
failed_jobs "$n0"

# --- the same sweep, one process per task ---
t0=$(date +%s)
for task in $tasks; do
  "$bin" --task "$task" --algo "$algos" --seeds "$seeds" "${opts[@]}" --out "$tmp/one/$task" --quiet
done
t_one=$(( $(date +%s) - t0 ))

status=0
for task in $tasks; do
  cmp "$tmp/slurm/$task/metrics.csv" "$tmp/one/$task/metrics.csv" && echo "$task: metrics.csv identical" || status=1
done
echo "wall time: slurm sweep ${t_slurm}s (+-2s), one-process sweep ${t_one}s"

# Largest number of this sweep's array elements running at once: +1 at each start, -1 at each
# end (ends first when equal, times are whole seconds).
arrays=" $(awk '{printf "%s ", $5}' <<<"$sweep")"
conc=$(tail -n "+$((n0 + 1))" "$jobcomp" | tr ' ' '\n' | awk -F= -v arrays="$arrays" '
  $1 == "StartTime" {s = $2} $1 == "EndTime" {e = $2}
  $1 == "ArrayJobId" && index(arrays, " " $2 " ") {print s, 1; print e, 0}' |
  sort | awk '{n += $2 ? 1 : -1; if (n > m) m = n} END {print m + 0}')
echo "max array elements running at once: $conc (nproc $(nproc))"
[ "$conc" -le "$(nproc)" ] || { echo "more elements than cores ran at once" >&2; status=1; }

# --- optional: kill one array element, resubmit, nothing lost ---
if [ "${1:-}" = --kill-test ]; then
  n0=$(wc -l < "$jobcomp")
  run=$("$here/figure.sh" "$tmp/kill" or "$algos" "$seeds" "${opts[@]}")
  array=$(awk '{print $5}' <<<"$run")
  until victim=$(squeue -h -j "$array" -t RUNNING -o %i | head -n1); [ -n "$victim" ]; do
    [ -n "$(squeue -h -j "$array" 2>/dev/null)" ] || { echo "kill test: array ended before any element was seen running" >&2; exit 1; }
    sleep 1
  done
  sleep 2; scancel "$victim"; echo "cancelled $victim"
  wait_jobs "$run"
  failed_jobs "$n0"
  wait_jobs "$("$here/figure.sh" --resume "$tmp/kill" or "$algos" "$seeds")"
  cmp "$tmp/kill/or/metrics.csv" "$tmp/slurm/or/metrics.csv" && echo "kill test: metrics.csv identical" || status=1
fi
exit "$status"

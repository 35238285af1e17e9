#!/usr/bin/env bash
# Submits a reacher sweep to Slurm: per task, one `reacher prepare` job, then a job array with one
# 1-CPU element per (algorithm, seed) running `reacher job`, then `reacher aggregate` - each step
# starts only if the one before succeeded (a failure cancels the rest of that task's chain).
# Usage: experiments/slurm/figure.sh [--resume] RUNS_ROOT "TASKS" "ALGOS" SEEDS [prepare options]
#   e.g. experiments/slurm/figure.sh /shared/runs "or if" "smirl,maxent" 5 --seed 0 --quick
#   TASKS, ALGOS: lists separated by spaces or commas; prepare options (--seed S, --quick,
#   --config FILE) are passed to `reacher prepare` as they are.
#   --resume: skip prepare (run dirs exist), resubmit array + aggregate; finished jobs are no-ops.
# Run dir of a task: RUNS_ROOT/<task> (must be on a filesystem all nodes share); Slurm logs:
# RUNS_ROOT/slurm-logs/. The binary is $REACHER_BIN (default `reacher` on the nodes' PATH).
# Prints one line per task: "<task> prepare <id> array <id> aggregate <id>".
set -euo pipefail

resume=0; [ "${1:-}" = --resume ] && { resume=1; shift; }
[ $# -ge 4 ] || { sed -n '2,12s/^# \{0,1\}//p' "$0" >&2; exit 2; }
root=$(realpath -m "$1"); tasks=${2//,/ }; algos=$(echo ${3//,/ } | tr ' ' ,); seeds=$4; shift 4
bin=${REACHER_BIN:-reacher}
[[ $bin == */* ]] && bin=$(realpath "$bin")     # jobs may run in another directory
k=$(( $(echo "${algos//,/ }" | wc -w) * seeds ))
logs=$root/slurm-logs
mkdir -p "$logs"

submit() { sbatch --parsable --kill-on-invalid-dep=yes --cpus-per-task=1 "$@"; }
for task in $tasks; do
  dir=$root/$task
  dep=()
  if [ "$resume" = 0 ]; then
    prep=$(submit -J "prepare-$task" -o "$logs/prepare-$task-%j.out" <<EOF
#!/bin/bash
set -euo pipefail
out=\$($(printf '%q ' "$bin" prepare --task "$task" --algo "$algos" --seeds "$seeds" "$@" --out "$dir"))
echo "\$out"
grep -qx 'jobs: $k' <<<"\$out" || { echo "expected 'jobs: $k'" >&2; exit 1; }
EOF
)
    dep=(-d "afterok:$prep")
  else
    prep=-
  fi
  array=$(submit -J "job-$task" --array="0-$((k - 1))" "${dep[@]}" -o "$logs/job-$task-%A_%a.out" <<EOF
#!/bin/bash
exec $(printf '%q ' "$bin" job --run "$dir") --index "\$SLURM_ARRAY_TASK_ID"
EOF
)
  agg=$(submit -J "aggregate-$task" -d "afterok:$array" -o "$logs/aggregate-$task-%j.out" <<EOF
#!/bin/bash
exec $(printf '%q ' "$bin" aggregate "$dir")
EOF
)
  echo "$task prepare $prep array $array aggregate $agg"
done

#!/usr/bin/env bash
# Builds experiments/reacher/results.md — figure 7 at base seed 0, and the baselines at other
# bases — from the committed run data; no experiment is rerun. In order:
#   results_intro.md            what the tables are
#   figure7.py                  figure 7: smirl and smirl-paper (ablations/runs/fold-seeds0to5-*),
#                               the baselines (runs/<task>-schedules, runs/<task>-rkl_expert) and
#                               their runs at other bases (heldout/schedules-*, heldout/rkl_expert-*)
#   choice.py                   what SMIRL's final choice adds: the loop's own policy, the reported
#                               one, a random candidate and the oracle best
# The tables of the method before the fold (the clock standard) are frozen in
# experiments/archive/reacher/results-247fca5.md, the earlier standards' in results-df9c858.md.
set -euo pipefail
cd "$(dirname "$0")"
# Written beside results.md and moved over it only when every script succeeded, so a failing
# script leaves the previous results.md whole.
out=$(mktemp results.md.XXXXXX)
trap 'rm -f "$out"' EXIT
# heldout_tables PREFIX HEADING: figure7.py's tables of the held-out runs heldout/<PREFIX><B>-<task>
# (each directory's tracked run.json; the metrics from the consolidated file) under HEADING,
# every base B; nothing when there are none.
heldout_tables() {
  local runs
  runs=$(ls -d "heldout/$1"*-*/ 2>/dev/null || true)
  if [ -n "$runs" ]; then
    printf '\n%s\n' "$2"
    python3 figure7.py $runs
  fi
}
tasks="or sequential if composite"
{
  cat results_intro.md
  printf '\n## Figure 7: smirl and smirl-paper (base seed 0, SAC seeds 0-5; the build of 54b1417)\n'
  printf '\n`SAC_SEEDS="0 1 2 3 4 5" ALGOS=smirl,smirl-paper REACHER_BIN=<build of 54b1417> experiments/reacher/smirl_sweep.sh '"'"'experiments/reacher/ablations/runs/fold-seeds0to5-{task}'"'"' 0`; table: `python3 experiments/reacher/figure7.py ablations/runs/fold-seeds0to5-<task>`\n'
  python3 figure7.py $(for t in $tasks; do echo "ablations/runs/fold-seeds0to5-$t"; done)
  printf '\n## Figure 7: the baselines (base seed 0, SAC seeds 0-2; before the fair comparison, run layout of 2207e5a)\n'
  printf '\nmaxent, fkl, js: `CONFIG=experiments/reacher/config_unshaped.toml experiments/reacher/figure7_schedules.sh` (the baselines read none of the keys in which config_unshaped.toml differs from config.toml); rkl: `... SUFFIX=rkl_expert experiments/reacher/figure7_schedules.sh "or sequential if composite" rkl`; table: `python3 experiments/reacher/figure7.py --algos maxent,fkl,js runs/<task>-schedules` and `python3 experiments/reacher/figure7.py runs/<task>-rkl_expert`. "final end ball": the share of final evaluation episodes that touch a ball that can end the task; "best iteration": the best success of any of the 800 iterations.\n'
  python3 figure7.py --algos maxent,fkl,js $(for t in $tasks; do echo "runs/$t-schedules"; done)
  python3 figure7.py $(for t in $tasks; do echo "runs/$t-rkl_expert"; done)
  heldout_tables schedules-seed '### The baselines at other bases (base seed B, SAC seed B; `CONFIG=experiments/reacher/config_unshaped.toml SEEDS=0 experiments/reacher/figure7_schedules.sh TASKS ALGOS B`; `python3 experiments/reacher/figure7.py heldout/schedules-seed<B>-<task>`)'
  heldout_tables schedules-js-seed '### js at base 3 on OR and Composite (`CONFIG=experiments/reacher/config_unshaped.toml SUFFIX=schedules-js SEEDS=0 experiments/reacher/figure7_schedules.sh "or composite" js 3`)'
  heldout_tables rkl_expert-seed '### rkl at other bases (`CONFIG=experiments/reacher/config_unshaped.toml SUFFIX=rkl_expert SEEDS=0 experiments/reacher/figure7_schedules.sh TASKS rkl B`)'
  printf '\n## What the final choice adds: smirl at base seed 0, SAC seeds 0-5 (`python3 experiments/reacher/choice.py`)\n\n'
  python3 choice.py
} > "$out"
chmod 644 "$out"
mv "$out" results.md

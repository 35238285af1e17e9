#!/usr/bin/env bash
# Builds experiments/reacher/results.md — the current method's tables — from the committed run
# data; no experiment is rerun (`reacher prepare`, well under a second per machine, tells which
# run is the standard's job at a base). In order:
#   results_intro.md            what the tables are
#   figure7.py                  figure 7: SMIRL at base 0 (ablations/runs/clock-*), the baselines
#                               (runs/<task>-schedules, runs/<task>-rkl_expert) and their held-out
#                               runs (heldout/schedules-*, heldout/rkl_expert-*)
#   choice.py                   what SMIRL's final choice adds: the loop's own policy, the reported
#                               one, a random candidate and the oracle best
#   standard_heldout.py         SMIRL at the other bases (development data), job by job
#   clock.py, clock_frozen.py   the last mechanism adopted (the agent's clock) against the method
#                               without it, and its control
# REACHER_BIN names the binary (default target/release/reacher). The earlier standards' tables
# are frozen in experiments/archive/reacher/results-df9c858.md.
set -euo pipefail
# REACHER_BIN as given from the caller's directory (before the cd below); the default is the
# checkout's build.
bin=${REACHER_BIN:-$(dirname "$0")/../../target/release/reacher}
case $bin in /*) ;; */*) bin=$PWD/$bin ;; esac
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
  printf '\n## Figure 7: SMIRL (base seed 0, SAC seeds 0-5; smirl-smooth: Composite, seed 0)\n'
  printf '\n`SAC_SEEDS="0 1 2 3 4 5" ALGOS=smirl experiments/reacher/smirl_sweep.sh '"'"'experiments/reacher/ablations/runs/clock-seeds0to5-{task}'"'"' 0`; table: `python3 experiments/reacher/figure7.py ablations/runs/clock-seeds0to5-<task> ablations/runs/clock-smooth-seed0-composite`\n'
  python3 figure7.py $(for t in $tasks; do echo "ablations/runs/clock-seeds0to5-$t"; done) ablations/runs/clock-smooth-seed0-composite
  printf '\n## Figure 7: the baselines (base seed 0, SAC seeds 0-2)\n'
  printf '\nmaxent, fkl, js: `CONFIG=experiments/reacher/config_unshaped.toml experiments/reacher/figure7_schedules.sh` (the baselines read none of the keys in which config_unshaped.toml differs from config.toml); rkl: `... SUFFIX=rkl_expert experiments/reacher/figure7_schedules.sh "or sequential if composite" rkl`; table: `python3 experiments/reacher/figure7.py --algos maxent,fkl,js runs/<task>-schedules` and `python3 experiments/reacher/figure7.py runs/<task>-rkl_expert`. "final end ball": the share of final evaluation episodes that touch a ball that can end the task; "best iteration": the best success of any of the 800 iterations.\n'
  python3 figure7.py --algos maxent,fkl,js $(for t in $tasks; do echo "runs/$t-schedules"; done)
  python3 figure7.py $(for t in $tasks; do echo "runs/$t-rkl_expert"; done)
  heldout_tables schedules-seed '### The baselines at other bases (base seed B, SAC seed B; `CONFIG=experiments/reacher/config_unshaped.toml SEEDS=0 experiments/reacher/figure7_schedules.sh TASKS ALGOS B`; `python3 experiments/reacher/figure7.py heldout/schedules-seed<B>-<task>`)'
  heldout_tables schedules-js-seed '### js at base 3 on OR and Composite (`CONFIG=experiments/reacher/config_unshaped.toml SUFFIX=schedules-js SEEDS=0 experiments/reacher/figure7_schedules.sh "or composite" js 3`)'
  heldout_tables rkl_expert-seed '### rkl at other bases (`CONFIG=experiments/reacher/config_unshaped.toml SUFFIX=rkl_expert SEEDS=0 experiments/reacher/figure7_schedules.sh TASKS rkl B`)'
  printf '\n## What the final choice adds (`python3 experiments/reacher/choice.py`)\n\n'
  python3 choice.py
  printf '\n## SMIRL at the other bases: development data (`python3 experiments/reacher/standard_heldout.py`; runs by `python3 experiments/reacher/clock.py --run`, `--run-rest`, `--run-fresh`)\n\n'
  python3 standard_heldout.py "$bin"
  printf '\n## Ablation: the agent'"'"'s clock against the method without it, job for job (`ablations/clock.toml`, its rule in the file; `python3 experiments/reacher/clock.py`)\n\n'
  python3 clock.py "$bin"
  printf '\n## Its control: the clock frozen, on the seven jobs the clock gained (`ablations/clock_frozen.toml`; `python3 experiments/reacher/clock_frozen.py`)\n\n'
  python3 clock_frozen.py "$bin"
} > "$out"
chmod 644 "$out"
mv "$out" results.md

#!/usr/bin/env bash
# Builds experiments/reacher/results.md from the run directories (every number from a script):
# SMIRL's settings of issue 13 (results_smirl.md's prose, figure7.py's tables of
# runs/<task>-shaped and, for SMIRL's final policy, of runs/<task>-final (the standards before
# event-gated visits) and of the current and previous standards' tuning runs, standard_heldout.py's tables
# of the current (the clock, the jobs run so far) and the reset-agent one, reset_agent.py's comparison of the reset agent
# with the cut-entries standard before it, clock.py's comparison of a clock for the agent with the
# reset agent (once it has run), clock_frozen.py's control of the clock, standard_heldout.py's of that one (selection cut reading entries), the touches one, the previous (initial events), the fallback-starts, the replay-all
# and the commuted-events standard's held-out jobs, selection_cut.py's comparison of the selection
# cut with the previous standard, ablation_heldout.py's comparisons of fallback starts, initial events and the sink of
# unseen touches with the replay-all standard, smirl_settings.py's
# table of every setting tried and the held-out runs, half_plateaus.py's OR plateaus, which
# prepares machines with REACHER_BIN, default target/release/reacher),
# figure 7 — every algorithm on its own schedule — (results_figure7.md's prose,
# figure7.py's tables of runs/<task>-schedules and the held-out heldout/schedules-seed<B>-<task>
# (js's OR and Composite in heldout/schedules-js-seed3-<task>),
# rkl's runs/<task>-rkl_expert and heldout/rkl_expert-seed<B>-<task>,
# progress.py's per-seed partial progress, retrain_table.py's learned rewards re-optimised,
# fresh_agent_screen.py's offline screen of a fresh agent as a final-policy candidate,
# retrain_agents.py's fresh agents with other SAC settings on fixed rewards),
# then the earlier material: the prose of results_header.md, the table of every run
# directory (results.py), the held-out table (heldout.py), the partial-progress tables of
# the uniform-schedule OR and Sequential runs (progress.py) and the earlier sessions' notes
# (results_notes.md).
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
{
  cat results_smirl.md
  printf '\n### SMIRL in figure 7 (`python3 experiments/reacher/figure7.py runs/<task>-shaped`)\n'
  python3 figure7.py runs/or-shaped runs/sequential-shaped runs/if-shaped runs/composite-shaped
  printf '\n### SMIRL'"'"'s final policy on figure 7'"'"'s seeds, the standard of *SMIRL'"'"'s final policy* (before event stutter and event-gated visits; `python3 experiments/reacher/figure7.py --final-only runs/<task>-final`)\n'
  python3 figure7.py --final-only runs/or-final runs/sequential-final runs/if-final runs/composite-final
  printf '\n### SMIRL'"'"'s final policy under the standard before the selection cut (initial events, fallback starts, a replay buffer of 200 000; base 0, SAC seeds 0-5, figure 7'"'"'s are 0-2; the current standard'"'"'s cut changes one choice, Composite seed 3'"'"'s, to another candidate at 1.00 / 1.00: the selection-cut table below; Sequential'"'"'s is the only base-0 machine either changes, so OR, IF and Composite are the replay-all runs; `python3 experiments/reacher/figure7.py --final-only ablations/runs/replay_all-seeds0to5-{or,if,composite} ablations/runs/initial_events-seeds0to5-sequential`)\n'
  python3 figure7.py --final-only ablations/runs/replay_all-seeds0to5-or ablations/runs/initial_events-seeds0to5-sequential \
    ablations/runs/replay_all-seeds0to5-if ablations/runs/replay_all-seeds0to5-composite
  printf '\n### SMIRL'"'"'s final policy under the fallback-starts standard (base 0, SAC seeds 0-5; `python3 experiments/reacher/figure7.py --final-only ablations/runs/replay_all-seeds0to5-{or,if,composite} ablations/runs/fallback_starts-seeds0to5-sequential`)\n'
  python3 figure7.py --final-only ablations/runs/replay_all-seeds0to5-or ablations/runs/fallback_starts-seeds0to5-sequential \
    ablations/runs/replay_all-seeds0to5-if ablations/runs/replay_all-seeds0to5-composite
  printf '\n### SMIRL'"'"'s final policy under the replay-all standard (a replay buffer of 200 000, no fallback starts; `python3 experiments/reacher/figure7.py --final-only ablations/runs/replay_all-seeds0to5-<task>`)\n'
  python3 figure7.py --final-only ablations/runs/replay_all-seeds0to5-or ablations/runs/replay_all-seeds0to5-sequential \
    ablations/runs/replay_all-seeds0to5-if ablations/runs/replay_all-seeds0to5-composite
  printf '\n### SMIRL'"'"'s final policy under the commuted-events standard (a replay buffer of 100 000; base 0, SAC seeds 0-5, figure 7'"'"'s are 0-2; OR, Sequential and IF are the runs of unpredicted events, whose base-0 machines commuted events leave unchanged; `python3 experiments/reacher/figure7.py --final-only ablations/runs/unpredicted_events-seeds0to5-{or,sequential,if} ablations/runs/commute_events-seeds0to5-composite`)\n'
  python3 figure7.py --final-only ablations/runs/unpredicted_events-seeds0to5-or ablations/runs/unpredicted_events-seeds0to5-sequential \
    ablations/runs/unpredicted_events-seeds0to5-if ablations/runs/commute_events-seeds0to5-composite
  printf '\n### SMIRL held out under the current standard (the agent'"'"'s clock and the reset agent; the selection cut, touches read as entries; initial events and fallback starts in LRM, a replay buffer of 200 000; only the jobs run with the clock so far, fresh bases 700 and 703 among them; `python3 experiments/reacher/standard_heldout.py`)\n\n'
  python3 standard_heldout.py "$bin"
  printf '\n### SMIRL held out under the reset-agent standard (the one before the clock; the jobs rerun with the reset agent; `python3 experiments/reacher/standard_heldout.py --reset-agent`)\n\n'
  python3 standard_heldout.py --reset-agent "$bin"
  printf '\n### The reset agent against the cut-entries standard before it, job for job (`ablations/reset_agent.toml`, adopted; the jobs run so far, that standard'"'"'s misses first, then the tuning jobs, then the other held-out jobs; `python3 experiments/reacher/reset_agent.py`)\n\n'
  python3 reset_agent.py "$bin"
  if ls -d heldout/clock-seeds*-*/ ablations/runs/clock-seeds0to5-*/ > /dev/null 2>&1; then
    printf '\n### A clock for the agent against the reset-agent standard, job for job (`ablations/clock.toml`, adopted by its rule; the jobs run so far: the standard'"'"'s IF and Composite misses first, then the tuning jobs, then the other held-out jobs; `python3 experiments/reacher/clock.py`)\n\n'
    python3 clock.py "$bin"
  fi
  if ls -d heldout/clock_frozen-seeds*-*/ > /dev/null 2>&1; then
    printf '\n### The clock frozen, its control, on the seven held-out jobs the clock gained (`ablations/clock_frozen.toml`: the same input width and networks, the entry held at 1; its reading fixed before the runs; `python3 experiments/reacher/clock_frozen.py`)\n\n'
    python3 clock_frozen.py "$bin"
  fi
  printf '\n### SMIRL held out under the cut-entries standard (the standard before the reset agent: every held-out base with a job of it; `python3 experiments/reacher/standard_heldout.py --cut-entries`)\n\n'
  python3 standard_heldout.py --cut-entries "$bin"
  printf '\n### The selection cut, touches read as labels and as entries, against the previous standard, job for job (`ablations/selection_cut.toml`, `ablations/selection_cut_entries.toml`, both adopted in turn; only the jobs whose candidates lie on both sides of 0.9 can change, and only they ran; `python3 experiments/reacher/selection_cut.py`)\n\n'
  python3 selection_cut.py "$bin"
  printf '\n### SMIRL held out under the selection cut reading touches as labels (`python3 experiments/reacher/standard_heldout.py --touches`)\n\n'
  python3 standard_heldout.py --touches "$bin"
  printf '\n### LRM'"'"'s fallback starts, then initial events, against the replay-all standard, job for job (`ablations/fallback_starts.toml`, `ablations/initial_events.toml`, both adopted; `python3 experiments/reacher/ablation_heldout.py fallback_starts initial_events`; where a column has no run its machine is the column before'"'"'s; the bases whose machines they change: `lrm_fallback.md`, `lrm_initial_events.md`)\n\n'
  python3 ablation_heldout.py fallback_starts initial_events
  printf '\n### SMIRL held out under the previous standard (initial events and fallback starts, the choice by the full learned return; `python3 experiments/reacher/standard_heldout.py --previous`)\n\n'
  python3 standard_heldout.py --previous "$bin"
  printf '\n### SMIRL held out under the fallback standard (fallback starts, no initial events; `python3 experiments/reacher/standard_heldout.py --fallback`)\n\n'
  python3 standard_heldout.py --fallback "$bin"
  printf '\n### SMIRL held out under the replay-all standard (a replay buffer of 200 000, neither; `python3 experiments/reacher/standard_heldout.py --replay-all`)\n\n'
  python3 standard_heldout.py --replay-all "$bin"
  printf '\n### The sink of unseen touches against the replay-all standard, job for job (`ablations/unseen_touch_sink.toml`, `ablations/sink_after_events.toml`; neither adopted; `python3 experiments/reacher/ablation_heldout.py unseen_touch_sink sink_after_events`)\n\n'
  python3 ablation_heldout.py unseen_touch_sink sink_after_events
  printf '\n### SMIRL held out under the commuted-events standard (a replay buffer of 100 000; `python3 experiments/reacher/standard_heldout.py --commuted`)\n\n'
  python3 standard_heldout.py --commuted "$bin"
  printf '\n### SMIRL'"'"'s final policy before commuted events (LRM not asked to predict the cancel; base 0, SAC seeds 0-5; `python3 experiments/reacher/figure7.py --final-only ablations/runs/unpredicted_events-seeds0to5-<task>`)\n'
  python3 figure7.py --final-only ablations/runs/unpredicted_events-seeds0to5-or ablations/runs/unpredicted_events-seeds0to5-sequential \
    ablations/runs/unpredicted_events-seeds0to5-if ablations/runs/unpredicted_events-seeds0to5-composite
  printf '\n### SMIRL'"'"'s final policy under an earlier standard (event-gated visits, LRM predicting the cancel; base 0, SAC seeds 0-5; `python3 experiments/reacher/figure7.py --final-only ablations/runs/event_gated_visits-seeds0to5-<task>`)\n'
  python3 figure7.py --final-only ablations/runs/event_gated_visits-seeds0to5-or ablations/runs/event_gated_visits-seeds0to5-sequential \
    ablations/runs/event_gated_visits-seeds0to5-if ablations/runs/event_gated_visits-seeds0to5-composite
  printf '\n### Every SMIRL setting tried, and held out (`python3 experiments/reacher/smirl_settings.py`)\n\n'
  python3 smirl_settings.py
  printf '\n### Half plateaus of SMIRL'"'"'s OR jobs, held out (`python3 experiments/reacher/half_plateaus.py --heldout`)\n\n'
  python3 half_plateaus.py --heldout "$bin"
  printf '\n### Half plateaus of SMIRL'"'"'s OR jobs at bases 36-42, LRM predicting the cancel and not (`python3 experiments/reacher/half_plateaus.py --fresh`)\n\n'
  python3 half_plateaus.py --fresh "$bin"
  printf '\n### Half plateaus on the tuning seeds, LRM predicting the cancel and not (`python3 experiments/reacher/half_plateaus.py --tuning`)\n\n'
  python3 half_plateaus.py --tuning "$bin"
  printf '\n### Learned machines with and without LRM predicting the cancel, and with commuted events, bases 0-45 (`python3 experiments/reacher/half_plateaus.py --machines`)\n\n'
  python3 half_plateaus.py --machines "$bin"
  echo
  cat results_figure7.md
  printf '\n### Figure 7 tables (`python3 experiments/reacher/figure7.py runs/<task>-schedules`)\n'
  python3 figure7.py runs/or-schedules runs/sequential-schedules runs/if-schedules runs/composite-schedules
  heldout_tables schedules-seed '### Held-out demonstrations and machines (base seed B, SAC seed B; `CONFIG=experiments/reacher/config_unshaped.toml SEEDS=0 experiments/reacher/figure7_schedules.sh TASKS ALGOS B`; `python3 experiments/reacher/figure7.py heldout/schedules-seed<B>-<task>`)'
  heldout_tables schedules-js-seed '### js held out on OR and Composite (base seed 3, SAC seed 3: the tasks the held-out table above has no js job on; `CONFIG=experiments/reacher/config_unshaped.toml SUFFIX=schedules-js SEEDS=0 experiments/reacher/figure7_schedules.sh "or composite" js 3`; `python3 experiments/reacher/figure7.py heldout/schedules-js-seed3-<task>`)'
  for t in or sequential if composite; do
    printf '\n#### Partial progress per seed: %s (`python3 progress.py runs/%s-schedules`)\n\n' "$t" "$t"
    python3 progress.py "runs/$t-schedules"
  done
  rkl=$(ls -d runs/*-rkl_expert/ 2>/dev/null || true)
  if [ -n "$rkl" ]; then
    printf '\n### rkl with demonstrations in its covariance batch (its schedule since issue 14'"'"'s control; `CONFIG=experiments/reacher/config_unshaped.toml SUFFIX=rkl_expert experiments/reacher/figure7_schedules.sh TASKS rkl`; `python3 experiments/reacher/figure7.py runs/<task>-rkl_expert`)\n'
    python3 figure7.py $rkl
  fi
  heldout_tables rkl_expert-seed '### rkl held out (base seed B, SAC seed B; `CONFIG=experiments/reacher/config_unshaped.toml SUFFIX=rkl_expert SEEDS=0 experiments/reacher/figure7_schedules.sh TASKS rkl B`; `python3 experiments/reacher/figure7.py heldout/rkl_expert-seed<B>-<task>`)'
  printf '\n### The learned rewards re-optimised (`python3 experiments/reacher/retrain_table.py`)\n\n'
  python3 retrain_table.py
  printf '\n### A fresh agent as one more final-policy candidate, screened offline (`python3 experiments/reacher/fresh_agent_screen.py`)\n\n'
  python3 fresh_agent_screen.py
  printf '\n### Fresh agents with other settings on fixed learned rewards (`experiments/reacher/retrain_agents.sh`; `python3 experiments/reacher/retrain_agents.py`)\n\n'
  python3 retrain_agents.py
  echo
  cat results_header.md
  python3 results.py
  python3 heldout.py
  for t in or sequential; do
    printf '\n## Partial progress: %s (`python3 progress.py runs/%s`)\n\n' "$t" "$t"
    python3 progress.py "runs/$t"
  done
  echo
  cat results_notes.md
} > "$out"
chmod 644 "$out"
mv "$out" results.md

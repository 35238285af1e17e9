#!/usr/bin/env bash
# Figure 7 and held-out seeds with the learned machines' tree guards (lrm_guards = "tree",
# issue 13): prepares every run directory with all six algorithms, then runs the jobs
# two at a time in priority order (SMIRL first, then held-out SMIRL, then smirl-smooth, then
# the baselines, which do not read the machine), and aggregates what has finished.
# A finished job is not rerun, so the script can be restarted; stop it any time and
# aggregate with `reacher aggregate DIR --partial`.
# Usage: experiments/reacher/rerun_guards.sh   (REACHER_BIN=<binary> to use another build,
#        JOBS=<n> parallel jobs, default 2)
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
CONFIG=experiments/reacher/config_uniform.toml
R=experiments/reacher
prep() { # dir task base-seed algos
  [ -f "$1/prepare.json" ] || "$BIN" prepare --task "$2" --seed "$3" --seeds 3 --algo "$4" \
    --config "$CONFIG" --out "$1" --quiet
}
for t in if composite or sequential; do prep "$R/runs/$t" "$t" 0 all; done
for t in if composite; do
  prep "$R/heldout/$t" "$t" 3 smirl
  prep "$R/heldout/seeds6-$t" "$t" 6 smirl
done
{
  for t in if composite; do for s in 0 1 2; do echo "$R/runs/$t smirl $s"; done; done
  for t in if composite; do
    for s in 3 4 5; do echo "$R/heldout/$t smirl $s"; done
    for s in 6 7 8; do echo "$R/heldout/seeds6-$t smirl $s"; done
  done
  for t in or sequential; do for s in 0 1 2; do echo "$R/runs/$t smirl $s"; done; done
  for t in if composite or sequential; do for s in 0 1 2; do echo "$R/runs/$t smirl-smooth $s"; done; done
  # Baselines (they do not read the machine): OR and Sequential first, whose rkl and js
  # jobs were never run before.
  for t in or sequential if composite; do
    for a in maxent fkl rkl js; do for s in 0 1 2; do echo "$R/runs/$t $a $s"; done; done
  done
} | xargs -P "${JOBS:-2}" -L 1 sh -c '"$0" job --run "$1" --algo "$2" --seed "$3" --quiet > /dev/null 2>> "$1/jobs.err" || echo "failed: $*" >&2' "$BIN"
for d in $R/runs/if $R/runs/composite $R/runs/or $R/runs/sequential $R/heldout/if $R/heldout/seeds6-if $R/heldout/composite $R/heldout/seeds6-composite; do
  "$BIN" aggregate "$d" --partial > /dev/null
done

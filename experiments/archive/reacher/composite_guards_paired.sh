#!/usr/bin/env bash
# Paired check for issue 13: does reading unseen label sets by a tree (lrm_guards = "tree")
# cost Composite's normal branch, or is figure 7's drop (seeds 1-2) seed variance? Same
# demonstrations and learned-machine search as figure 7 (base seed 0), SMIRL, SAC seeds 3-8
# (figure 7 has 0-2), once with tree guards and once with exact guards.
# Usage: experiments/reacher/composite_guards_paired.sh   (REACHER_BIN=<binary>, JOBS=<n>)
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher; fi
BIN=${REACHER_BIN:-./target/release/reacher}
D=experiments/reacher/diagnostics
EXACT=$(mktemp --suffix=.toml)
sed 's/^lrm_guards = .*/lrm_guards = "exact"/' experiments/reacher/config_uniform.toml > "$EXACT"
for g in tree exact; do
  config=experiments/reacher/config_uniform.toml
  [ "$g" = exact ] && config=$EXACT
  [ -f "$D/composite_guards_$g/prepare.json" ] || "$BIN" prepare --task composite --algo smirl --seed 0 --seeds 9 \
    --config "$config" --out "$D/composite_guards_$g" --quiet
done
rm -f "$EXACT"
for s in 3 4 5 6 7 8; do for g in tree exact; do echo "$D/composite_guards_$g smirl $s"; done; done |
  xargs -P "${JOBS:-2}" -L 1 sh -c '"$0" job --run "$1" --algo "$2" --seed "$3" --quiet > /dev/null' "$BIN"
for g in tree exact; do "$BIN" aggregate "$D/composite_guards_$g" --partial > /dev/null; done

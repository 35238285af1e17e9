#!/usr/bin/env bash
# LRM's mechanisms ablated on the development range, without SAC (issue 54, item 1): for each
# paper task and each development base seed, the machine LRM learns from the demonstrations of
# `reacher prepare --task T --seed B` under the standard learner, with each mechanism off alone,
# under smirl-paper's learner, and with the three mechanisms that fail the fold rule off together
# (src/bin/lrm_ablation.rs); experiments/lrm/ablation.py makes the table. The base list is the
# whole declared development range, fixed before any result. ablation_before_fold.md is this
# script's table at commit 66f0e44 (with fallback starts), on which the fold was decided
# (its rows: ablation_before_fold.csv.gz).
# Usage: nice -n 10 experiments/lrm/ablation.sh   (about 10 CPU-seconds, one thread)
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin lrm_ablation >&2
BASES=0,3-105,153,219,246,282,372,546,549,700,703
out=experiments/lrm/ablation.csv.gz
partial=experiments/lrm/ablation.csv.partial
rm -f "$partial"
./target/release/lrm_ablation --tasks or,sequential,if,composite --bases "$BASES" --out "$partial"
gzip -n -9 -c "$partial" > "$out"
rm "$partial"
python3 experiments/lrm/ablation.py "$out" experiments/lrm/ablation.md

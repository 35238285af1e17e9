#!/usr/bin/env bash
# Rebuilds tests/fuzz_corpus/ from a real `--quick` run (the fuzzers' seed files: its
# demonstration log and an f-IRL training log, both several chunks; expert_data.bin; a reward
# network; SMIRL's linear reward; two job records; prepare.json; the run's config).
# Usage: experiments/fuzz/make_corpus.sh [RUN_DIR]   (default: a fresh run in target/fuzz-quick-or)
set -euo pipefail
cd "$(dirname "$0")/../.."
run=${1:-target/fuzz-quick-or}
if [ ! -f "$run/prepare.json" ]; then
  cargo run --release --bin reacher -- --task or --quick --algo all --seeds 1 --seed 0 --out "$run" --quiet
fi
c=tests/fuzz_corpus
mkdir -p "$c"
cp "$run/logs/demos.mcap" "$run/logs/fkl_seed0.mcap" "$run/expert_data.bin" "$run/prepare.json" "$run/config.toml" "$c/"
cp "$run/rewards/maxent_seed0.bin" "$c/reward_maxent_seed0.bin"
cp "$run/rewards/smirl_seed0.json" "$c/reward_smirl_seed0.json"
cp "$run/jobs/smirl_seed0.json" "$c/job_smirl_seed0.json"
cp "$run/jobs/fkl_seed0.json" "$c/job_fkl_seed0.json"

#!/usr/bin/env bash
# Long pass of the mutation fuzzers (tests/fuzz.rs): 10^6 reward-machine files, 10^6 configs
# (each parsed as IRL-run, expert, SAC and Office config) and 10^5 MCAP logs, under a 4 GiB
# address-space limit so that an unbounded allocation aborts instead of swapping.
# Usage: experiments/fuzz/long_pass.sh > experiments/fuzz/long_pass.txt
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo test --release --test fuzz --no-run 2>/dev/null
echo "# experiments/fuzz/long_pass.sh ($(git rev-parse --short HEAD), $(date -u +%F))"
(
  ulimit -v 4194304
  FUZZ_TEXT_ITERS=${FUZZ_TEXT_ITERS:-1000000} FUZZ_MCAP_ITERS=${FUZZ_MCAP_ITERS:-100000} \
    cargo test --release --test fuzz -- --nocapture --test-threads 1 2>&1 |
    grep -E "inputs in|test result|panicked"
)

#!/usr/bin/env bash
# Long pass of the supervised mutation fuzzers (tests/fuzz.rs): 10^6 reward-machine files,
# 10^6 configs (each read as IRL-run, expert, SAC, Office and ReacherDraw config), 10^5 logs
# with CRCs and 10^5 without (record-aware mutations; downstream commands on every accepted
# log), 10^5 logs with well-formed wrong field values (replay, render and the offline-RM traces
# on each), 10^5 of each binary/JSON run file, all under a 4 GiB address-space limit so that an
# unbounded allocation aborts (and the supervisor saves the input) instead of swapping.
# Prints inputs, throughput and findings per target; findings are saved in
# target/fuzz-findings/. Usage: nice -n 10 experiments/fuzz/long_pass.sh > experiments/fuzz/long_pass.txt
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo test --release --test fuzz --no-run 2>/dev/null
echo "# experiments/fuzz/long_pass.sh ($(git rev-parse --short HEAD), $(date -u +%F)); ulimit -v 4194304"
(
  ulimit -v 4194304
  FUZZ_TEXT_ITERS=${FUZZ_TEXT_ITERS:-1000000} FUZZ_MCAP_ITERS=${FUZZ_MCAP_ITERS:-100000} \
    FUZZ_BIN_ITERS=${FUZZ_BIN_ITERS:-100000} \
    cargo test --release --test fuzz 2>&1 | grep --line-buffered -E "selftest|inputs in|findings|input [0-9]+:"
)

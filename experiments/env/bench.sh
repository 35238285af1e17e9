#!/usr/bin/env bash
# ReacherDelivery steps/s on the model it steps (the shipped scene without its balls) vs the raw
# mj_step loop on that model and vs the environment on the whole shipped scene and on the first
# model (assets/reacher_delivery_v1.xml); writes experiments/env/bench.txt.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin env_bench
{
    echo "# command: cargo run --release --bin env_bench -- --reps 11 --steps 20000"
    echo "# machine: $(nproc) cores, $(date -u +%Y-%m-%d), load average $(cut -d" " -f1-3 /proc/loadavg)"
    ./target/release/env_bench --reps 11 --steps 20000
} > experiments/env/bench.txt
cat experiments/env/bench.txt

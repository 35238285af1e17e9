#!/usr/bin/env bash
# Lockstep rollouts vs one-at-a-time rollouts vs the environment alone (lockstep_bench), and
# the shipped model's env steps/s vs a raw mj_step loop on it (env_bench), in one run; writes
# experiments/env/lockstep_bench.txt. Both print medians of interleaved repetitions.
#
#   nice -n 10 experiments/env/lockstep_bench.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin lockstep_bench --bin env_bench
OUT=experiments/env/lockstep_bench.txt
{
    echo "# command: nice -n 10 experiments/env/lockstep_bench.sh"
    echo "# machine: $(nproc) cores, $(date -u +%Y-%m-%d), load average $(cut -d' ' -f1-3 /proc/loadavg)"
    echo "## ./target/release/lockstep_bench --reps 7 --episodes 150 --batches 1,8,32,150 --threads 2"
    ./target/release/lockstep_bench --reps 7 --episodes 150 --batches 1,8,32,150 --threads 2
    echo "## ./target/release/env_bench --reps 7 --steps 20000"
    ./target/release/env_bench --reps 7 --steps 20000
    echo "# load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
} > "$OUT"
cat "$OUT"

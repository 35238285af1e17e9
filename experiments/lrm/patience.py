#!/usr/bin/env python3
"""LRM's patience (a start ends after that many steps without improving its best) against
longer patience: the learned machine's cost and the search's time per task.

Runs `lrm_bench` once per (round, patience), the patience values interleaved within each round
so that a change in the machine's load falls on all of them alike, and reports per task (with
and without rewards) the cost at each patience and the median time over the rounds, with the
time of each patience as a share of the longest's.

    cargo build --release --bin lrm_bench
    python3 experiments/lrm/patience.py target/release/lrm_bench --rounds 3 > experiments/lrm/patience.md
"""

import argparse
import statistics
import subprocess
import sys


def bench(binary, patience, only):
    """{(task, rew): (seconds, cost)} and the bench's header line of one run."""
    cmd = [binary, "--reps", "1", "--patience", str(patience), "--only", only]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    rows, header = {}, ""
    for line in out.splitlines():
        if line.startswith("lrm_bench:"):
            header = line
        parts = line.split()
        if len(parts) >= 4 and parts[1] in ("y", "n") and not line.startswith("task"):
            rows[(parts[0], parts[1])] = (float(parts[2]), float(parts[3]))
    return rows, header


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("binary")
    p.add_argument("--patience", default="5,10,20", help="comma-separated; the last is the reference")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--only", default="office_", help="lrm_bench --only (a task name prefix)")
    args = p.parse_args()
    values = [int(v) for v in args.patience.split(",")]
    times, costs, header = {}, {}, ""
    for _ in range(args.rounds):
        for v in values:
            rows, header = bench(args.binary, v, args.only)
            for key, (secs, cost) in rows.items():
                times.setdefault((key, v), []).append(secs)
                costs.setdefault((key, v), set()).add(cost)
    tasks = sorted({key for key, _ in times})
    ref = values[-1]
    print(f"# LRM patience: cost and time (`python3 experiments/lrm/patience.py {args.binary} "
          f"--patience {args.patience} --rounds {args.rounds} --only {args.only}`)\n")
    print(f"Bench: {header.split(': ', 1)[-1]}; one run per (round, patience), interleaved; "
          f"time is the median over {args.rounds} rounds, share is of patience {ref}'s. The cost "
          "is the same in every round (the search is seeded).\n")
    print("| task | rewards | " + " | ".join(f"cost, patience {v}" for v in values) + " | "
          + " | ".join(f"s, patience {v}" for v in values) + " | "
          + " | ".join(f"share, patience {v}" for v in values[:-1]) + " |")
    print("|---" * (1 + 1 + 3 * len(values) - 1) + "|")
    shares = {v: [] for v in values[:-1]}
    for key in tasks:
        cost = []
        for v in values:
            c = costs[(key, v)]
            if len(c) != 1:
                sys.exit(f"patience: {key} at patience {v} gave different costs over rounds: {sorted(c)}")
            cost.append(f"{c.pop():.1f}")
        med = {v: statistics.median(times[(key, v)]) for v in values}
        for v in values[:-1]:
            shares[v].append(med[v] / med[ref])
        print(f"| {key[0]} | {key[1]} | " + " | ".join(cost) + " | "
              + " | ".join(f"{med[v]:.3f}" for v in values) + " | "
              + " | ".join(f"{med[v] / med[ref]:.2f}" for v in values[:-1]) + " |")
    print()
    for v in values[:-1]:
        print(f"- patience {v}: median share of patience {ref}'s time over the {len(tasks)} rows "
              f"{statistics.median(shares[v]):.2f}")


if __name__ == "__main__":
    main()

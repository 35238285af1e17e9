#!/usr/bin/env python3
"""The lingering trap in SMIRL's learned rewards (results_figure7.md, issue 13): for a job, the
final weights of one learned-machine state on two labels — the ball just touched and the next
one — and how often the data gradient on the touched ball was negative (agent below expert)
over the last iterations. Reads <run>/rewards/<algo>_seed<S>.trace.csv (written by
`reacher job`, not tracked: rerun the job to get it).

Usage: python3 experiments/reacher/linger_weights.py RUN ALGO SEED STATE TOUCHED NEXT [LAST]
  e.g. python3 experiments/reacher/linger_weights.py experiments/reacher/runs/composite smirl 0 1 r b 9
The table in experiments/reacher/linger_weights.md is written by linger_weights.sh."""
import csv
import sys


def main(run, algo, seed, state, touched, nxt, last="9"):
    rows = list(csv.DictReader(open(f"{run}/rewards/{algo}_seed{seed}.trace.csv")))
    final = max(int(r["iteration"]) for r in rows)
    first = final - int(last) + 1
    w = {r["feature"]: float(r["weight"]) for r in rows
         if int(r["iteration"]) == final and r["rm_state"] == state}
    negative = sum(1 for r in rows if r["rm_state"] == state and r["feature"] == touched
                   and int(r["iteration"]) >= first and float(r["data_gradient"]) < 0)
    print(f"| {run} | {algo} | {seed} | {state} | {touched} {w[touched]:.2f} | {nxt} {w[nxt]:.2f} "
          f"| {negative} of {last} |")


if __name__ == "__main__":
    main(*sys.argv[1:])

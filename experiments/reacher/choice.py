#!/usr/bin/env python3
"""What SMIRL's final choice adds at base seed 0 (development data), per task: the jobs that reach
0.9 on the ground truth (IF and Composite: on both branches) with

  loop      the loop's own policy (candidate 0: the co-trained policy after the last iteration)
  reported  the policy the job reports (the candidate of highest learned return)
  random    a candidate drawn uniformly (expected count: the jobs' shares of solving candidates)
  oracle    the best candidate by ground truth (no method can report it: an upper bound)

over SMIRL's figure-7 jobs (SAC seeds 0-5: ablations/runs/fold-seeds0to5-<task>). Markdown on
standard output, from the consolidated final_policy.csv. The preregistered evaluations report
the same columns on fresh bases (experiments/protocol/table.py).

Usage: python3 experiments/reacher/choice.py
"""
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import rundata  # noqa: E402

TASKS = ["or", "sequential", "if", "composite"]
SOLVED = 0.9


def jobs(parent, pattern):
    """{task: [candidate rows of one job]} of the runs under `parent` whose name matches."""
    out = {t: [] for t in TASKS}
    for run, rows in rundata.consolidated(os.path.join(HERE, parent), "final_policy.csv").items():
        m = re.fullmatch(pattern, run)
        if not m:
            continue
        by_job = {}
        for r in rows:
            by_job.setdefault((r["algo"], r["seed"]), []).append(r)
        for (algo, _), cands in sorted(by_job.items()):
            if algo == "smirl":
                out[m.group(1)].append(sorted(cands, key=lambda r: int(r["candidate"])))
    return out


def counts(cands_per_job):
    solved = lambda r: float(r["success_rate"]) >= SOLVED
    loop = sum(solved(c[0]) for c in cands_per_job)
    reported = sum(solved(rundata.chosen(c)) for c in cands_per_job)
    random = sum(sum(map(solved, c)) / len(c) for c in cands_per_job)
    oracle = sum(any(map(solved, c)) for c in cands_per_job)
    return loop, reported, random, oracle


def main():
    print("| task | jobs | loop's own policy | reported policy | random candidate (expected) | best candidate (oracle) | candidates per job |")
    print("|---|---|---|---|---|---|---|")
    per_task = jobs("ablations/runs", r"fold-seeds0to5-(\w+)")
    for task in TASKS:
        js = per_task[task]
        if not js:
            continue
        loop, reported, random, oracle = counts(js)
        sizes = sorted({len(c) for c in js})
        print(f"| {task} | {len(js)} | {loop} | {reported} | {random:.1f} | {oracle} | "
              f"{', '.join(map(str, sizes))} |")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The pass decisions of eval2's positive controls (experiments/protocol/eval2-controls.md), read
from the protocol's job table alone (`table.py eval2-controls` writes
`experiments/protocol/eval2-controls/jobs.csv`).

Rules, as that protocol fixed them before its first job: a job's score is its reported policy's
success on the lower branch of its final set (the final phase's choice; the loop's own policy for
an algorithm without a final phase); a failed job scores 0. An arm passes `blue` when it scores
>= 0.9 in at least 2 of its 3 SAC seeds; the product controls also need `or` (seed 0) at >= 0.9.
The rehearsal has no pass rule and is listed per job.

Usage: python3 experiments/reacher/controls/pass_eval2.py [JOBS_CSV]
"""

import csv
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT = os.path.join(HERE, "..", "..", "protocol", "eval2-controls", "jobs.csv")
SOLVED = 0.9
# (task, jobs planned, solved jobs needed) for every control an arm takes.
BLUE = ("blue", 3, 2)
OR = ("or", 1, 1)
PRODUCT = {"maxent-product", "fkl-product"}


def reported(row):
    """The reported policy's lower-branch score; 0 for a job that did not end `done`."""
    if row["status"] != "done":
        return 0.0
    value = row["chosen"] if row["chosen"] not in ("", "-") else row["loop"]
    return float(value)


def unit(row):
    """The control's name for a job's arm: the one-state arm is `smirl` with another config."""
    return "one-state" if row["arm"] == "blue-one-state" else row["algo"]


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else DEFAULT
    rows = list(csv.DictReader(open(path)))
    print(f"Source: `{os.path.relpath(path)}`.\n")
    print("| task | arm | seed | loop's own | chosen | reported | wall (s) |")
    print("|---|---|---|---|---|---|---|")
    for r in sorted(rows, key=lambda r: (r["arm"] != "rehearsal", r["task"], unit(r), int(r["seed"]))):
        shown = r["status"] if r["status"] != "done" else f"{reported(r):.2f}"
        print(f"| {r['task']} | {unit(r)} | {r['seed']} | {r['loop']} | {r['chosen']} | {shown} | {r['wall_secs']} |")

    scores = {}
    for r in rows:
        if r["arm"] == "rehearsal":
            continue
        scores.setdefault((unit(r), r["task"]), []).append(reported(r))
    print("\n| arm | blue solved | or solved | control |")
    print("|---|---|---|---|")
    for arm in sorted({a for a, _ in scores}):
        verdicts, cells = [], []
        for task, planned, needed in [BLUE] + ([OR] if arm in PRODUCT else []):
            got = scores.get((arm, task), [])
            solved = sum(s >= SOLVED for s in got)
            missing = planned - len(got)
            cells.append(f"{solved} of {len(got)}" + (f" ({missing} not run)" if missing else ""))
            verdicts.append("incomplete" if missing else ("pass" if solved >= needed else "FAIL"))
        if arm not in PRODUCT:
            cells.append("—")
        verdict = "incomplete" if "incomplete" in verdicts else ("FAIL" if "FAIL" in verdicts else "pass")
        print(f"| {arm} | {cells[0]} | {cells[1]} | {verdict} |")


if __name__ == "__main__":
    main()

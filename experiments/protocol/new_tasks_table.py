#!/usr/bin/env python3
"""The tasks of one pool of a finished preregistered evaluation, branch by branch: each task's
expert beside every arm that ran on it (exploratory, from table.py's jobs.csv; it computes no
primary or secondary figure).

Usage:
    python3 experiments/protocol/new_tasks_table.py NAME [--pool new] [--experts DIR]

Reads the pool's tasks from `[analysis] pools` of `experiments/protocol/NAME.toml`, the jobs
from `experiments/protocol/NAME/jobs.csv` and each task's expert summary
`DIR/summary_<task>.json` (default `experiments/experts/new_tasks`, written by
`experiments/experts/train_new_tasks.sh`); writes `experiments/protocol/NAME/<pool>_tasks.md`.

Per task, the expert's success per branch (normal, event: an episode is in the event's branch
when the event came while it still changed the perfect machine's course) with its stochastic
and its mean-action policy. Per task and unit (arm, algorithm): the jobs, those solved by the
reported policy (the final phase's choice, or the loop's own for an algorithm without one) and
by the loop's own policy, and the reported policy's mean success per branch over the jobs. A
failed job scores 0 on every branch, as in table.py. Solved: the lower branch at 0.9 or more.
"""

import argparse
import csv
import json
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
import run as protocol  # noqa: E402
from diagnose import number  # noqa: E402

SOLVED = 0.9
BRANCHES = ("normal", "event")


def branch_rates(text):
    return [float(x) for x in text.split()] if text else []


def expert_cells(path):
    """`normal, event` success of the stochastic and the mean-action expert ("-" without a file)."""
    if not os.path.isfile(path):
        return "-", "-"
    with open(path) as fh:
        s = json.load(fh)

    def cell(mode):
        b = s.get(f"branches_{mode}")
        if not b:
            return f"{s[f'success_{mode}']:.2f}"
        return ", ".join(f"{k}/{e} ({k / e:.2f})" if e else "-" for e, k in zip(b["episodes"], b["successes"]))
    return cell("stochastic"), cell("mean")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name")
    p.add_argument("--pool", default="new")
    p.add_argument("--experts", default="experiments/experts/new_tasks")
    args = p.parse_args()
    _, _, plan = protocol.load(args.name)
    tasks = plan.get("analysis", {}).get("pools", {}).get(args.pool)
    if not tasks:
        sys.exit(f"new_tasks_table: experiments/protocol/{args.name}.toml has no [analysis] pools.{args.pool}")
    jobs_path = os.path.join(protocol.state_dir(args.name), "jobs.csv")
    if not os.path.isfile(jobs_path):
        sys.exit(f"new_tasks_table: {protocol.rel(jobs_path)} does not exist: run table.py {args.name} first")
    with open(jobs_path, newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["task"] in tasks]
    units = []
    for r in rows:
        if (r["arm"], r["algo"]) not in units:
            units.append((r["arm"], r["algo"]))
    experts = os.path.join(protocol.ROOT, args.experts)
    command = f"python3 experiments/protocol/new_tasks_table.py {args.name} --pool {args.pool}"
    if args.experts != p.get_default("experts"):
        command += f" --experts {args.experts}"
    out = [f"# {args.name}: the {args.pool} tasks branch by branch (exploratory)", "",
           f"`{command}`, from jobs.csv and the "
           f"experts' summaries in `{args.experts}/`. Branches: normal, event (one value: a task without an event "
           "that changes its course). A failed job scores 0 on every branch. Solved: lower branch >= 0.9.", "",
           "## Experts", "", "| task | expert, stochastic | expert, mean action |", "|---|---|---|"]
    for task in tasks:
        stochastic, mean = expert_cells(os.path.join(experts, f"summary_{task}.json"))
        out.append(f"| {task} | {stochastic} | {mean} |")
    out += ["", "## Every arm", "",
            "| task | arm | algo | jobs | failed | solved, reported | solved, loop's own | reported, mean per branch |",
            "|---|---|---|---|---|---|---|---|"]
    for task in tasks:
        for arm, algo in units:
            cell = [r for r in rows if r["task"] == task and (r["arm"], r["algo"]) == (arm, algo)]
            if not cell:
                continue
            failed = sum(r["status"] != "done" for r in cell)
            reported_solved = loop_solved = 0
            per_branch = []
            for r in cell:
                if r["status"] != "done":
                    per_branch.append(None)
                    continue
                chosen = number(r["chosen"])
                reported = number(r["loop"]) if chosen is None else chosen
                reported_solved += reported >= SOLVED
                loop_solved += number(r["loop"]) >= SOLVED
                per_branch.append(branch_rates(r["loop_branches"] if chosen is None else r["chosen_branches"]))
            width = max((len(b) for b in per_branch if b is not None), default=1)
            sums = [0.0] * width
            for b in per_branch:
                for i in range(width):
                    sums[i] += 0.0 if b is None or i >= len(b) else b[i]
            means = [s / len(cell) for s in sums]
            branches = ", ".join(f"{BRANCHES[i]} {m:.2f}" for i, m in enumerate(means)) if width > 1 else f"{means[0]:.2f}"
            out.append(f"| {task} | {arm} | {algo} | {len(cell)} | {failed} | {reported_solved}/{len(cell)} | "
                       f"{loop_solved}/{len(cell)} | {branches} |")
    path = os.path.join(protocol.state_dir(args.name), f"{args.pool}_tasks.md")
    with open(path + ".tmp", "w") as fh:
        fh.write("\n".join(out) + "\n")
    os.replace(path + ".tmp", path)
    print(f"wrote {protocol.rel(path)}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The tables of a preregistered evaluation, from its run directories: every job as it came out,
and per (task, arm) the summary its protocol names.

Usage:
    python3 experiments/protocol/table.py NAME [--partial]

Reads `experiments/protocol/NAME.toml` and the jobs `experiments/protocol/run.py` ran under
`runs/protocol/NAME/`; writes `experiments/protocol/NAME/jobs.csv` (one row per job) and
`experiments/protocol/NAME/summary.md`. Without `--partial` it refuses while a job is missing.

Per job, three policies: the loop's own (its last IRL iteration's evaluation), the chosen one
(the job's reported policy: the final phase's choice by learned return where the algorithm has
a final phase, else the loop's own) and a random pick among the final phase's candidates (the
job records it). A policy's score is its success on the lower branch (the branch it does worse
on; a task without branches has one). A job is solved when that score is at least 0.9.

The summary, per (task, arm) and policy: solved jobs / jobs, and the mean score with a 95 %
bootstrap interval that resamples base seeds (the SAC seeds of one base share its
demonstrations and learned machine, so a base is the unit that varies independently): 10 000
resamples, percentile interval, generator seeded 0.
"""

import argparse
import csv
import json
import os
import random
import sys

sys.path.insert(0, os.path.dirname(__file__))
import run as protocol  # noqa: E402

SOLVED = 0.9
RESAMPLES = 10_000


def lower_branch(evaluated):
    """(lower-branch success, per-branch successes) of an evaluation row or candidate."""
    branches = evaluated.get("branches")
    if not branches:
        return evaluated["success_rate"], [evaluated["success_rate"]]
    rates = [s / e for s, e in zip(branches["successes"], branches["episodes"]) if e > 0]
    return min(rates) if rates else float("nan"), rates


def policies(record):
    """(loop, chosen, random pick), each (lower-branch score, per-branch rates) or None."""
    last = record["rows"][-1]
    loop = lower_branch(last)
    final = record.get("final_policy")
    if not final:
        return loop, loop, None
    cands = final["candidates"]
    chosen = lower_branch(cands[final["chosen"]])
    pick = final.get("random_pick")
    picked = lower_branch(cands[pick]) if pick is not None else None
    return loop, chosen, picked


def bootstrap(by_base, rng):
    bases = sorted(by_base)
    if not bases:
        return float("nan"), float("nan"), float("nan")

    def mean_of(sample):
        xs = [x for b in sample for x in by_base[b]]
        return sum(xs) / len(xs)

    means = sorted(mean_of([rng.choice(bases) for _ in bases]) for _ in range(RESAMPLES))
    return mean_of(bases), means[int(0.025 * RESAMPLES)], means[int(0.975 * RESAMPLES) - 1]


def fmt(x):
    return "-" if x is None or x != x else f"{x:.2f}"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name")
    p.add_argument("--partial", action="store_true")
    args = p.parse_args()
    _, _, plan = protocol.load(args.name)
    runs, jobs = protocol.plan_runs(args.name, plan)
    rows = []
    missing = 0
    for j in jobs:
        r = runs[j["run"]]
        path = os.path.join(r["dir"], "jobs", f"{j['algo']}_seed{j['seed']}.json")
        if not os.path.isfile(path):
            missing += 1
            continue
        with open(path) as fh:
            record = json.load(fh)
        loop, chosen, picked = policies(record)
        rows.append({
            "arm": j["arm"], "task": protocol.task_label(r["task"]), "base": r["base"],
            "algo": j["algo"], "seed": j["seed"],
            "loop": loop[0], "chosen": chosen[0], "random_pick": picked[0] if picked else None,
            "chosen_branches": " ".join(f"{x:.2f}" for x in chosen[1]),
            "wall_secs": round(record.get("wall_secs", float("nan"))),
        })
    if missing and not args.partial:
        sys.exit(f"table: {missing} of {len(jobs)} jobs are missing (--partial for the finished ones)")
    out = os.path.join(protocol.ROOT, "experiments", "protocol", args.name)
    os.makedirs(out, exist_ok=True)
    fields = ["arm", "task", "base", "algo", "seed", "loop", "chosen", "random_pick", "chosen_branches", "wall_secs"]
    with open(os.path.join(out, "jobs.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        for row in rows:
            w.writerow({k: (fmt(v) if isinstance(v, float) or v is None and k == "random_pick" else v) for k, v in row.items()})
    rng = random.Random(0)
    lines = [
        f"# Protocol {args.name}: summary ({len(rows)} of {len(jobs)} jobs)",
        "",
        f"`python3 experiments/protocol/table.py {args.name}{' --partial' if args.partial else ''}`; "
        "every job is in jobs.csv. Score: success on the lower branch; solved: score >= 0.9; "
        "mean with a 95 % bootstrap interval over base seeds.",
        "",
        "| task | arm | jobs | solved (chosen) | chosen mean [95 %] | loop's own mean [95 %] | random pick mean [95 %] | solved (loop) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    keys = []
    for row in rows:
        k = (row["task"], row["arm"])
        if k not in keys:
            keys.append(k)
    for task, arm in keys:
        group = [r for r in rows if r["task"] == task and r["arm"] == arm]
        cells = []
        for policy in ("chosen", "loop", "random_pick"):
            by_base = {}
            for r in group:
                if r[policy] is not None:
                    by_base.setdefault(r["base"], []).append(r[policy])
            m, lo, hi = bootstrap(by_base, rng)
            cells.append(f"{fmt(m)} [{fmt(lo)}, {fmt(hi)}]" if by_base else "-")
        solved = sum(r["chosen"] >= SOLVED for r in group)
        solved_loop = sum(r["loop"] >= SOLVED for r in group)
        lines.append(f"| {task} | {arm} | {len(group)} | {solved}/{len(group)} | {cells[0]} | {cells[1]} | {cells[2]} | {solved_loop}/{len(group)} |")
    with open(os.path.join(out, "summary.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

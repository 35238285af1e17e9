#!/usr/bin/env python3
"""The tables of a preregistered evaluation, from its committed ledger: every job as it came
out, and per (task, arm) the summary its protocol names.

Usage:
    python3 experiments/protocol/table.py NAME [--partial]

Reads `experiments/protocol/NAME.toml` and the ledger `run.py` keeps beside the lock,
`experiments/protocol/NAME/ledger.jsonl` (each finished job's `done` entry carries what this
script reads of its job file: no run directory is needed); writes
`experiments/protocol/NAME/jobs.csv` (one row per job) and `experiments/protocol/NAME/summary.md`.
Without `--partial` it refuses while a planned job has neither finished nor failed. Where a job
file is still on disk (the session that ran it), a file whose sha256 differs from the one the
ledger recorded is refused; a job the ledger records that the plan does not name is listed, not
counted.

Per job, three policies, each scored on the job's final set (its own episodes, 50 per branch
at the standard config: `final_set_episodes` in src/pipeline/reacher_irl/evaluation.rs, never
seen by training or the choice): the loop's own (its policy after the last IRL iteration); the
chosen one (the final phase's choice by learned return, for an algorithm with a final phase; an
algorithm without one has no chosen policy but the loop's own, and the table says so); and a
random pick among the final phase's candidates, as its expected score (the mean over the
candidates: no draw). A policy's score is its success on the lower branch (the branch it does
worse on; a task without branches has one). A job is solved when that score is at least 0.9; a failed job
(the ledger's record of an error exit) counts as unsolved with score 0.

The summary, per (task, arm) and policy: solved jobs / jobs with a 95 % Wilson interval, and
the mean score with a 95 % bootstrap interval that resamples base seeds (the SAC seeds of one
base share its demonstrations and learned machine, so a base is the unit that varies
independently): 10 000 resamples, percentile interval, a generator seeded by the cell's name;
with fewer than 2 bases there is no interval. And the paired difference chosen − loop's own,
per base, with its bootstrap interval.
"""

import argparse
import csv
import hashlib
import math
import os
import random
import sys

sys.path.insert(0, os.path.dirname(__file__))
import run as protocol  # noqa: E402

SOLVED = 0.9
RESAMPLES = 10_000


def lower_branch(score, where):
    """(lower-branch success, per-branch successes) of a final-set score as the ledger keeps it
    (`run.score_of`)."""
    if not score:
        sys.exit(f"table: {where}: no final-set evaluation (a job file of a binary without it)")
    if len(score) == 1:
        rates = [score[0]]
    else:
        rates = [s / e for e, s in (score[1:3], score[3:5]) if e > 0]
    if not rates or any(r != r for r in rates):
        sys.exit(f"table: {where}: no success rate in {score}")
    return min(rates), rates


def policies(fields, where):
    """(loop, chosen or None, random pick's expected score or None) of a job's ledger fields;
    loop and chosen are (lower-branch score, per-branch rates)."""
    loop = lower_branch(fields.get("loop"), where)
    if "candidates" not in fields:
        return loop, None, None
    cands = [lower_branch(c, f"{where}, candidate {i}") for i, c in enumerate(fields["candidates"])]
    chosen = cands[fields["chosen"]]
    expected = sum(c[0] for c in cands) / len(cands)
    return loop, chosen, expected


def rng_for(*names):
    return random.Random(hashlib.sha256(" ".join(map(str, names)).encode()).digest())


def bootstrap(by_base, rng):
    """(mean, low, high) of the per-job values grouped by base; no interval below 2 bases."""
    bases = sorted(by_base)
    if not bases:
        return None

    def mean_of(sample):
        xs = [x for b in sample for x in by_base[b]]
        return sum(xs) / len(xs)

    m = mean_of(bases)
    if len(bases) < 2:
        return m, None, None
    means = sorted(mean_of([rng.choice(bases) for _ in bases]) for _ in range(RESAMPLES))
    return m, means[int(0.025 * RESAMPLES)], means[int(0.975 * RESAMPLES) - 1]


def wilson(k, n, z=1.959964):
    if n == 0:
        return None
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def f2(x):
    return "-" if x is None else f"{x:.2f}"


def interval(b):
    if b is None:
        return "-"
    m, lo, hi = b
    return f"{m:.2f}" if lo is None else f"{m:.2f} [{lo:.2f}, {hi:.2f}]"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name")
    p.add_argument("--partial", action="store_true")
    args = p.parse_args()
    _, _, plan = protocol.load(args.name)
    runs, jobs = protocol.plan_runs(args.name, plan)
    ledger = protocol.read_ledger(args.name)
    finished = {}
    for e in ledger:
        if e.get("event") not in ("done", "failed"):
            continue
        key = protocol.job_key(e)
        before = finished.get(key)
        if before and (before["event"], before.get("sha256")) != (e["event"], e.get("sha256")):
            sys.exit(f"table: {key} is recorded twice with different outcomes ({before['event']} "
                     f"{before.get('sha256')}, {e['event']} {e.get('sha256')})")
        finished[key] = e
    rows, missing, planned = [], 0, set()
    for j in jobs:
        r = runs[j["run"]]
        key = (protocol.rel(r["dir"]), j["algo"], j["seed"])
        planned.add(key)
        row = {"arm": j["arm"], "task": protocol.task_label(r["task"]), "base": r["base"], "algo": j["algo"], "seed": j["seed"]}
        e = finished.get(key)
        if e is None:
            missing += 1
            continue
        if e["event"] == "failed":
            rows.append({**row, "status": "failed", "loop": 0.0, "chosen": None, "random_pick": None,
                         "loop_branches": "", "chosen_branches": "", "wall_secs": None})
            continue
        path = protocol.job_file(r["dir"], j["algo"], j["seed"])
        if os.path.isfile(path) and protocol.sha256_of(path) != e["sha256"]:
            sys.exit(f"table: {path} is not the file the ledger recorded when the job finished")
        loop, chosen, expected = policies(e["job"], f"{key[0]} {j['algo']} seed {j['seed']}")
        wall = e["job"].get("wall_secs")
        rows.append({**row, "status": "done", "loop": loop[0], "chosen": chosen[0] if chosen else None,
                     "random_pick": expected,
                     "loop_branches": " ".join(f"{x:.2f}" for x in loop[1]),
                     "chosen_branches": " ".join(f"{x:.2f}" for x in chosen[1]) if chosen else "",
                     "wall_secs": round(wall) if isinstance(wall, (int, float)) and wall == wall else None})
    if missing and not args.partial:
        sys.exit(f"table: {missing} of {len(jobs)} jobs are missing (--partial for the finished ones)")
    unplanned = [f"{d} {a} seed {s}" for d, a, s in finished if (d, a, s) not in planned]
    out = os.path.join(protocol.ROOT, "experiments", "protocol", args.name)
    os.makedirs(out, exist_ok=True)
    fields = ["arm", "task", "base", "algo", "seed", "status", "loop", "chosen", "random_pick",
              "loop_branches", "chosen_branches", "wall_secs"]
    with open(os.path.join(out, "jobs.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        for row in rows:
            w.writerow({k: (f2(v) if k in ("loop", "chosen", "random_pick") else ("-" if v is None else v)) for k, v in row.items()})
    lines = [
        f"# Protocol {args.name}: summary ({len(rows)} of {len(jobs)} jobs"
        + (f"; {missing} not run yet" if missing else "") + ")",
        "",
        f"`python3 experiments/protocol/table.py {args.name}{' --partial' if args.partial else ''}`; "
        "every job is in jobs.csv. Score: success on the lower branch, on the job's final set; solved: score >= 0.9 "
        "(95 % Wilson interval); means with 95 % bootstrap intervals over base seeds; random "
        "pick: the expected score of a uniform pick among the final phase's candidates; "
        "chosen − loop: paired by job, bootstrapped over bases. `-`: the algorithm has no final phase.",
        "",
        "| task | arm | jobs (bases) | failed | solved, chosen | chosen mean | solved, loop's own | loop's own mean | random pick mean | chosen − loop |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    keys = []
    for row in rows:
        if (row["task"], row["arm"]) not in keys:
            keys.append((row["task"], row["arm"]))
    for task, arm in keys:
        group = [r for r in rows if r["task"] == task and r["arm"] == arm]
        n = len(group)
        bases = len({r["base"] for r in group})

        def cell(policy, extra=None):
            by_base = {}
            for r in group:
                v = r[policy] if extra is None else extra(r)
                if v is not None:
                    by_base.setdefault(r["base"], []).append(v)
            return interval(bootstrap(by_base, rng_for(args.name, task, arm, policy, extra is not None)))

        def solved(policy):
            vals = [r[policy] for r in group if r[policy] is not None or r["status"] == "failed"]
            if not vals:
                return "-"
            k = sum(v is not None and v >= SOLVED for v in vals)
            lo, hi = wilson(k, len(vals))
            return f"{k}/{len(vals)} [{lo:.2f}, {hi:.2f}]"

        has_final = any(r["chosen"] is not None for r in group)
        diff = cell("chosen", lambda r: None if r["chosen"] is None else r["chosen"] - r["loop"]) if has_final else "-"
        lines.append(
            f"| {task} | {arm} | {n} ({bases}) | {sum(r['status'] == 'failed' for r in group)} | "
            f"{solved('chosen') if has_final else '-'} | {cell('chosen') if has_final else '-'} | "
            f"{solved('loop')} | {cell('loop')} | {cell('random_pick') if has_final else '-'} | {diff} |"
        )
    if unplanned:
        lines += ["", "Jobs the ledger records that the plan does not name (not counted):", ""]
        lines += [f"- {u}" for u in sorted(unplanned)]
    with open(os.path.join(out, "summary.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

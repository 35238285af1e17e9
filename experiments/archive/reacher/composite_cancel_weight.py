#!/usr/bin/env python3
"""Composite, SMIRL: does the cancel's learned weight in the "red or green touched, no cancel"
state predict the normal branch's failure? (Hypothesis: a positive weight on `c`, an event
the agent cannot cause, makes waiting at red look worth it, since the cancel also moves the
machine past blue.) For every Composite run directory with per-branch metrics: the learned
state reached from the initial state on red/green without the cancel, SMIRL's final weights
there (rewards/smirl_seed<S>.trace.csv) and the final normal/cancel success.

The reward traces and most of those run directories are not tracked (experiments/README.md), so
the table is printed from composite_cancel_weight.csv, one row per (job, feature) of that
state's final weights, written from the run directories on disk by `--consolidate` (it was
written from every Composite SMIRL trace of figure 7, the held-out and ablation runs and
diagnostics/composite_guards_{tree,exact}). `--from-runs` prints the table from the run
directories instead, without the CSV.
Usage: python3 experiments/reacher/composite_cancel_weight.py [--consolidate | --from-runs]"""
import csv
import glob
import os
import re
import sys

BASE = os.path.join(os.path.dirname(os.path.abspath(__file__)))
CONSOLIDATED = os.path.join(BASE, "composite_cancel_weight.csv")
FIELDS = ["run", "seed", "success_normal", "success_cancel", "rm_state", "feature", "weight"]


def from_runs():
    """The CSV's rows from the run directories under BASE (traces in path order)."""
    for trace in sorted(glob.glob(os.path.join(BASE, "**/rewards/smirl_seed*.trace.csv"), recursive=True)):
        run = os.path.dirname(os.path.dirname(trace))
        if "composite" not in run:
            continue
        learned = open(os.path.join(run, "rm/learned.txt")).read()
        rows = list(csv.DictReader(open(os.path.join(run, "metrics.csv"))))
        seed = re.search(r"_seed(\d+)", trace).group(1)
        rows = [r for r in rows if r["algo"] == "smirl" and r["seed"] == seed]
        if not rows or not rows[-1].get("success_normal"):
            continue  # runs of the first cancel schedule have no branches
        init = re.search(r"initial: (\d+)", learned).group(1)
        after_ball = [t for f, t, g in re.findall(r"\((\d+), (\d+), '([^']*)'", learned)
                      if f == init and ("!c" in g or "c" not in g) and ("r" in g or "g" in g)]
        weights = list(csv.DictReader(open(trace)))
        last = max(int(r["iteration"]) for r in weights)
        for r in weights:
            if int(r["iteration"]) == last and r["rm_state"] == after_ball[0]:
                yield {"run": os.path.relpath(run, BASE), "seed": seed,
                       "success_normal": rows[-1]["success_normal"],
                       "success_cancel": rows[-1]["success_cancel"],
                       "rm_state": r["rm_state"], "feature": r["feature"], "weight": r["weight"]}


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else None
    if mode not in (None, "--consolidate", "--from-runs"):
        sys.exit(__doc__)
    if mode == "--consolidate":
        with open(CONSOLIDATED, "w", newline="") as f:
            w = csv.DictWriter(f, FIELDS, lineterminator="\n")
            w.writeheader()
            w.writerows(from_runs())
        return
    rows = from_runs() if mode == "--from-runs" else csv.DictReader(open(CONSOLIDATED))
    jobs = {}
    for r in rows:
        jobs.setdefault((r["run"], r["seed"]), []).append(r)
    seen = set()
    print("| run | seed | final normal / cancel | w_c | w_b | w_r | w_g |")
    print("|---|---|---|---|---|---|---|")
    for (run, seed), rs in jobs.items():
        w = {r["feature"]: float(r["weight"]) for r in rs}
        final = f"{float(rs[0]['success_normal']):.2f} / {float(rs[0]['success_cancel']):.2f}"
        key = (final, tuple(sorted(w.items())))
        if key in seen:
            continue  # the same job committed under two names
        seen.add(key)
        print(f"| {run} | {seed} | {final} | " + " | ".join(f"{w[f]:+.2f}" for f in "cbrg") + " |")


if __name__ == "__main__":
    main()

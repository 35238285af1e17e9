#!/usr/bin/env python3
"""Composite, SMIRL: does the cancel's learned weight in the "red or green touched, no cancel"
state predict the normal branch's failure? (Hypothesis: a positive weight on `c`, an event
the agent cannot cause, makes waiting at red look worth it, since the cancel also moves the
machine past blue.) For every committed Composite run directory with per-branch metrics: the
learned state reached from the initial state on red/green without the cancel, SMIRL's final
weights there (rewards/smirl_seed<S>.trace.csv) and the final normal/cancel success.
Usage: python3 experiments/reacher/composite_cancel_weight.py"""
import csv
import glob
import os
import re

BASE = os.path.join(os.path.dirname(os.path.abspath(__file__)))
seen = set()
print("| run | seed | final normal / cancel | w_c | w_b | w_r | w_g |")
print("|---|---|---|---|---|---|---|")
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
    w = {r["feature"]: float(r["weight"]) for r in weights
         if int(r["iteration"]) == last and r["rm_state"] == after_ball[0]}
    final = f"{float(rows[-1]['success_normal']):.2f} / {float(rows[-1]['success_cancel']):.2f}"
    key = (final, tuple(sorted(w.items())))
    if key in seen:
        continue  # the same job committed under two names
    seen.add(key)
    print(f"| {os.path.relpath(run, BASE)} | {seed} | {final} | "
          + " | ".join(f"{w[f]:+.2f}" for f in "cbrg") + " |")

#!/usr/bin/env python3
"""Partial progress of a run directory's jobs (metrics.csv columns `progress`, `final_ball`):
per algorithm and seed, the final iteration's success, sub-goal fraction and end-ball rate,
and their means over the last five iterations. Jobs run before the metric existed are left out.
Reads metrics.csv, metrics.csv.gz or the run's rows of a consolidated file (rundata.py).
Usage: python3 experiments/reacher/progress.py experiments/reacher/runs/<task>"""
import sys

import rundata

d = sys.argv[1]
rows = rundata.metrics(d)
print("| algorithm | seed | final success | final sub-goals done | final end ball touched | sub-goals, last 5 | end ball, last 5 |")
print("|---|---|---|---|---|---|---|")
algos = []
for r in rows:
    if r["algo"] not in algos:
        algos.append(r["algo"])
for a in algos:
    seeds = sorted({r["seed"] for r in rows if r["algo"] == a}, key=int)
    for s in seeds:
        rs = [r for r in rows if r["algo"] == a and r["seed"] == s]
        if not all(r.get("progress") for r in rs):
            continue
        p = [float(r["progress"]) for r in rs]
        f = [float(r["final_ball"]) for r in rs]
        print("| %s | %s | %.2f | %.2f | %.2f | %.2f | %.2f |" % (
            a, s, float(rs[-1]["success_rate"]), p[-1], f[-1], sum(p[-5:]) / 5, sum(f[-5:]) / 5))

#!/usr/bin/env python3
"""Table of the SMIRL ablations (experiments/reacher/ablations/runs/*) next to the baseline
figure-7 runs (experiments/reacher/runs/<task>), read from their summary.csv files."""
import csv, os
here = os.path.dirname(os.path.abspath(__file__))
runs = os.path.join(here, "runs")

def final(path):
    return {r["algo"]: "%s ± %s" % (r["final_success_mean"], r["final_success_std"])
            for r in csv.DictReader(open(os.path.join(path, "summary.csv")))}

print("| ablation | task | algorithm | final success, ablation | final success, default config |")
print("|---|---|---|---|---|")
for name in sorted(os.listdir(runs)):
    d = os.path.join(runs, name)
    if not os.path.isdir(d) or name.endswith(".partial"):
        continue
    ablation, task = name.split("-", 1)
    base = final(os.path.join(here, "..", "runs", task))
    for algo, value in final(d).items():
        print("| %s | %s | %s | %s | %s |" % (ablation, task, algo, value, base.get(algo, "-")))

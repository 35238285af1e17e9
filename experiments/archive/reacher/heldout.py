#!/usr/bin/env python3
"""Table of the held-out SMIRL runs (experiments/reacher/heldout/*, written by heldout.sh):
final success per seed, mean ± std, and the mean over seeds and the last five iterations,
read from each run directory's metrics.csv, or for the runs not on disk from the consolidated
heldout/metrics.csv.gz (rundata.py); for IF and Composite also each branch's final success per
seed (normal / cancel; the headline is the lower of the two).
Usage: python3 experiments/reacher/heldout.py"""
import os, statistics

import rundata

here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "heldout")
order = ["or", "sequential", "if", "composite"]
print("\n## Held-out runs (`heldout.sh`; table by `python3 heldout.py`)\n")
print("| run | task | algorithm | seeds | final success per seed | final success (mean ± std) | mean success, last 5 iterations | final normal / cancel branch per seed |")
print("|---|---|---|---|---|---|---|---|")
names = rundata.runs(here, "metrics.csv")
def key(n):
    prefix, _, task = n.rpartition("-")
    return (prefix, order.index(task) if task in order else 9)
for name in sorted(names, key=key):
    prefix, _, task = name.rpartition("-")
    curves, branches = {}, {}
    for r in rundata.metrics(os.path.join(here, name)):
        curves.setdefault(r["algo"], {}).setdefault(int(r["seed"]), []).append(float(r["success_rate"]))
        # Older runs (before per-branch evaluation) have no branch columns.
        if r.get("success_normal"):
            branches.setdefault(r["algo"], {})[int(r["seed"])] = "%.2f / %.2f" % (
                float(r["success_normal"] or 0), float(r["success_cancel"] or 0))
    for algo, seeds in sorted(curves.items()):
        finals = [c[-1] for _, c in sorted(seeds.items())]
        last = [x for c in seeds.values() for x in c[-5:]]
        per_branch = ", ".join(branches[algo][s] for s in sorted(seeds)) if algo in branches else "–"
        print("| %s | %s | %s | %s | %s | %.2f ± %.2f | %.2f | %s |" % (
            prefix or "default", task, algo, ", ".join(str(s) for s in sorted(seeds)),
            ", ".join("%.2f" % f for f in finals), statistics.mean(finals),
            statistics.pstdev(finals), sum(last) / len(last), per_branch))

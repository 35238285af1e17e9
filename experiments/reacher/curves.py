#!/usr/bin/env python3
"""Per-seed ground-truth success of every IRL iteration, one line per (algorithm, seed), from a
run directory's metrics.csv (or metrics.csv.gz, or its rows of a consolidated file: rundata.py).
Usage: python3 experiments/reacher/curves.py RUN_DIR [ALGO ...]"""
import sys

import rundata

if len(sys.argv) < 2:
    sys.exit(__doc__)
run = sys.argv[1]
only = set(sys.argv[2:])
curves = {}
for r in rundata.metrics(run):
    if only and r["algo"] not in only:
        continue
    curves.setdefault((r["algo"], int(r["seed"])), []).append(float(r["success_rate"]))
for (algo, seed), values in sorted(curves.items()):
    print("%-13s seed %d  %s" % (algo, seed, " ".join("%.2f" % v for v in values)))

#!/usr/bin/env python3
"""Builds experiments/reacher/results.md from the run directories' summary.csv, run.json,
metrics.csv (or metrics.csv.gz) and .time files (numbers come from the runs, never typed by hand)."""
import json, os, sys

import rundata

here = os.path.dirname(os.path.abspath(__file__))
runs = os.path.join(here, "runs")
rows = []
order = ["or", "sequential", "if", "composite"]
# runs/<task>-final are not committed (their IRL loops are runs/<task>-shaped's, byte for byte;
# their final policies are in figure7.py's tables), so they are left out here too: the same
# results.md from a clone as from the machine that ran them.
names = sorted((n for n in os.listdir(runs) if os.path.isdir(os.path.join(runs, n))
                and not n.endswith(".partial") and not n.endswith("-final")),
               key=lambda n: (order.index(n.split("-")[0]) if n.split("-")[0] in order else 9, n))
for task in names:
    d = os.path.join(runs, task)
    if not os.path.isfile(os.path.join(d, "summary.csv")):
        continue
    info = json.load(open(os.path.join(d, "run.json")))
    wall = open(os.path.join(runs, task + ".time")).read().split()[1] if os.path.exists(os.path.join(runs, task + ".time")) else "?"
    rm = info["summary"].get("rm") or {}
    # Peak of the seed-mean success over IRL iterations (IRL runs can reach the task and drift away).
    curves = {}
    for m in rundata.metrics(d):
        curves.setdefault(m["algo"], {}).setdefault(int(m["iteration"]), []).append(float(m["success_rate"]))
    for r in rundata.summary(d):
        it = curves.get(r["algo"], {})
        peak = max(it.items(), key=lambda kv: sum(kv[1]) / len(kv[1])) if it else (0, [0])
        peak_txt = "%.2f (iter %d)" % (sum(peak[1]) / len(peak[1]), peak[0])
        # Mean over seeds and the last five iterations: does the policy stay solved?
        last = [x for k in sorted(it)[-5:] for x in it[k]]
        last_txt = "%.2f" % (sum(last) / len(last)) if last else "-"
        job = [j for j in info["jobs"] if j["algo"] == r["algo"]]
        # IF and Composite: final success on each branch (runs before per-branch evaluation: -).
        if r.get("final_success_normal_mean"):
            branch_txt = "%s ± %s / %s ± %s" % (r["final_success_normal_mean"], r["final_success_normal_std"],
                                                r["final_success_cancel_mean"], r["final_success_cancel_std"])
        else:
            branch_txt = "-"
        rows.append((task, r["algo"], r["seeds"], r["final_success_mean"], r["final_success_std"], branch_txt,
                     peak_txt, last_txt, r["final_return_mean"], r["final_return_std"],
                     "%.0f" % (sum(j["wall_secs"] for j in job) / max(len(job), 1)), wall,
                     "%s / %s" % (rm.get("learned_states", "-"), rm.get("refines_perfect", "-")),
                     info["demo_source"], info["git_commit"][:7]))
out = ["| task | algorithm | seeds | final success (mean ± std) | final normal / cancel branch | peak mean success | mean success, last 5 iterations | final task return | job wall (s) | task run wall (s) | learned RM states / refines | demos | commit |",
       "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
for t in rows:
    out.append("| %s | %s | %s | %s ± %s | %s | %s | %s | %s ± %s | %s | %s | %s | %s | %s |" % t)
sys.stdout.write("\n".join(out) + "\n")

#!/usr/bin/env python3
"""Table of the SMIRL ablations (experiments/reacher/ablations/runs/*) next to the runs they
change one setting of, read from their summary.csv files: paper_sac and demos_32 against the
figure-7 runs with the default config (experiments/reacher/runs/<task>); no_crm, crm_lr_decay and replay_100k
against paper_sac (the default they were run against); shaping, lr_decay and no_l2 against
no_crm; issue 13's shaping_crm, shaping_2 and label_entries against the standard profile
before shaping (runs/<task>-schedules), shaped_lr_decay against today's (runs/<task>-shaped)
(see run.sh). The ablation runs' summaries are the consolidated runs/summary.csv (a
run directory on disk wins: rundata.py)."""
import os, sys
here = os.path.dirname(os.path.abspath(__file__))
runs = os.path.join(here, "runs")
sys.path.insert(0, os.path.dirname(here))
import rundata  # noqa: E402

def final(path):
    return {r["algo"]: "%s ± %s" % (r["final_success_mean"], r["final_success_std"])
            for r in rundata.summary(path)}

def reference(ablation, task):
    if ablation in ("shaping_crm", "shaping_2", "label_entries"):
        return "unshaped", os.path.join(here, "..", "runs", task + "-schedules")
    if ablation == "shaped_lr_decay":
        return "default", os.path.join(here, "..", "runs", task + "-shaped")
    if ablation in ("paper_sac", "demos_32"):
        return "default", os.path.join(here, "..", "runs", task)
    if ablation in ("no_crm", "crm_lr_decay", "replay_100k"):
        return "paper_sac", os.path.join(runs, "paper_sac-" + task)
    return "no_crm", os.path.join(runs, "no_crm-" + task)

print("| ablation | task | algorithm | final success, ablation | reference | final success, reference |")
print("|---|---|---|---|---|---|")
for name in sorted(rundata.runs(runs, "summary.csv")):
    d = os.path.join(runs, name)
    ablation, task = name.split("-", 1)
    ref_name, ref_dir = reference(ablation, task)
    try:
        base = final(ref_dir)
    except FileNotFoundError:
        base = {}
    for algo, value in final(d).items():
        print("| %s | %s | %s | %s | %s | %s |"
              % (ablation, task, algo, value, ref_name, base.get(algo, "-")))

#!/usr/bin/env python3
"""Table of the SMIRL ablations (experiments/reacher/ablations/runs/*) next to the runs they
change one setting of, read from their summary.csv files: paper_sac and demos_32 against the
figure-7 runs with the default config (experiments/reacher/runs/<task>); no_crm, crm_lr_decay and replay_100k
against paper_sac (the default they were run against); shaping, lr_decay and no_l2 against
no_crm (see run.sh)."""
import csv, os
here = os.path.dirname(os.path.abspath(__file__))
runs = os.path.join(here, "runs")

def final(path):
    return {r["algo"]: "%s ± %s" % (r["final_success_mean"], r["final_success_std"])
            for r in csv.DictReader(open(os.path.join(path, "summary.csv")))}

def reference(ablation, task):
    if ablation in ("paper_sac", "demos_32"):
        return "default", os.path.join(here, "..", "runs", task)
    if ablation in ("no_crm", "crm_lr_decay", "replay_100k"):
        return "paper_sac", os.path.join(runs, "paper_sac-" + task)
    return "no_crm", os.path.join(runs, "no_crm-" + task)

print("| ablation | task | algorithm | final success, ablation | reference | final success, reference |")
print("|---|---|---|---|---|---|")
for name in sorted(os.listdir(runs)):
    d = os.path.join(runs, name)
    if not os.path.isdir(d) or name.endswith(".partial"):
        continue
    ablation, task = name.split("-", 1)
    ref_name, ref_dir = reference(ablation, task)
    base = final(ref_dir) if os.path.isdir(ref_dir) else {}
    for algo, value in final(d).items():
        print("| %s | %s | %s | %s | %s | %s |"
              % (ablation, task, algo, value, ref_name, base.get(algo, "-")))

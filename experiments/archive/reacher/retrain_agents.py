"""Fresh agents with other settings on fixed learned rewards (experiments/reacher/retrain_agents.sh).

`python3 experiments/reacher/retrain_agents.py --write` collects every evaluation of the tables
<run>/retrain/smirl_seed<S>_sac<K>_<setting>.csv (not tracked) of the runs retrain_agents.sh
names into experiments/reacher/retrain_agents.csv (tracked). Without --write it prints, from that
file, per reward and setting the 15 evaluations as a strip (`#` solved: >= 0.9 on every branch;
a digit: the lower branch's tenths; `.` below 0.1), how many are solved, whether the task is kept
(solved at each of the last three) and the last learned return; then per setting the totals over
the tuning rewards and the rule of retrain_agents.sh (a setting is worth an IRL-loop ablation iff
it solves more evaluations than `job` in total and keeps the task in at least as many rewards).
"""
import csv
import glob
import os
import re
import sys

here = os.path.dirname(os.path.abspath(__file__))
root = os.path.dirname(os.path.dirname(here))
CSV = os.path.join(here, "retrain_agents.csv")
SETTINGS = ["job", "lr3e-4", "no_shaping", "replay_all"]
FIELDS = ["run", "seed", "sac_seed", "setting", "env_steps", "success_rate", "success_normal",
          "success_cancel", "learned_return"]
RUNS = ["ablations/runs/unpredicted_events-seeds0to5-if",
        "ablations/runs/unpredicted_events-seeds0to5-sequential",
        "ablations/runs/unpredicted_events-seeds0to5-or",
        "ablations/runs/commute_events-seeds0to5-composite",
        "heldout/commute-seeds3-composite", "heldout/commute-seeds27-composite",
        "heldout/commute-seeds30-composite", "heldout/commute-seeds36-composite",
        "heldout/commute-seeds39-composite"]
KEEP = 3


def collect():
    rows = []
    for run in RUNS:
        for path in sorted(glob.glob(os.path.join(here, run, "retrain", "smirl_seed*_sac*_*.csv"))):
            m = re.match(r"smirl_seed(\d+)_sac(\d+)_([A-Za-z0-9_-]+)\.csv$", os.path.basename(path))
            if not m or m.group(3) not in SETTINGS:
                continue
            seed, sac, setting = m.groups()
            with open(path, newline="") as f:
                for r in csv.DictReader(f):
                    rows.append({"run": run, "seed": seed, "sac_seed": sac, "setting": setting,
                                 **{k: r[k] for k in FIELDS[4:]}})
    rows.sort(key=lambda r: (RUNS.index(r["run"]), int(r["seed"]), int(r["sac_seed"]),
                             SETTINGS.index(r["setting"]), int(r["env_steps"])))
    with open(CSV, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def lower(r):
    """The headline success: the lower branch on IF and Composite."""
    rates = [r["success_normal"], r["success_cancel"]]
    return min(float(x) for x in rates) if all(rates) else float(r["success_rate"])


def strip(points):
    out = ""
    for p in points:
        s = lower(p)
        out += "#" if s >= 0.9 else ("." if s < 0.1 else str(int(s * 10)))
    return out


def table():
    with open(CSV, newline="") as f:
        rows = list(csv.DictReader(f))
    curves = {}
    for r in rows:
        curves.setdefault((r["run"], r["seed"], r["sac_seed"], r["setting"]), []).append(r)
    print("A fresh SAC agent (seed 1000, 150 000 steps) on a finished job's final reward, held fixed,")
    print("judged every 10 000 steps: `#` solved (>= 0.9 on every branch), a digit the lower branch's")
    print("tenths, `.` below 0.1; kept: solved at each of the last three. Settings")
    print("(experiments/reacher/retrain_agents/): job = the job's own; lr3e-4 = SAC lr 3e-4 (1e-3);")
    print("no_shaping = smirl_shaping 0 (1); replay_all = replay 200 000 (100 000).\n")
    print("| reward (run, job seed) | setting | 15 evaluations | solved | kept | last learned return |")
    print("|---|---|---|---|---|---|")
    totals = {}
    for (run, seed, sac, setting), points in curves.items():
        solved = sum(lower(p) >= 0.9 for p in points)
        kept = all(lower(p) >= 0.9 for p in points[-KEEP:])
        group = "held out" if run.startswith("heldout") else "tuning"
        t = totals.setdefault((group, setting), [0, 0, 0, 0])
        t[0] += solved
        t[1] += kept
        t[2] += len(points)
        t[3] += 1
        print(f"| {run} {seed} | {setting} | `{strip(points)}` | {solved} | {'yes' if kept else 'no'} "
              f"| {float(points[-1]['learned_return']):.0f} |")
    print("\n| rewards | setting | evaluations solved | rewards kept | worth an IRL-loop ablation |")
    print("|---|---|---|---|---|")
    for (group, setting), (solved, kept, n, rewards) in sorted(
            totals.items(), key=lambda kv: (kv[0][0] != "tuning", SETTINGS.index(kv[0][1]))):
        ref = totals.get((group, "job"))
        if setting == "job" or group != "tuning" or ref is None:
            verdict = "(reference)" if setting == "job" else ""
        else:
            verdict = "yes" if solved > ref[0] and kept >= ref[1] else "no"
        print(f"| {group} ({rewards}) | {setting} | {solved} of {n} | {kept} of {rewards} | {verdict} |")


if __name__ == "__main__":
    if sys.argv[1:] == ["--write"]:
        collect()
    elif sys.argv[1:]:
        sys.exit("usage: retrain_agents.py [--write]")
    else:
        table()

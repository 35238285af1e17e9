"""The learned rewards re-optimised (experiments/reacher/retrain.sh, `reacher retrain`).

`python3 experiments/reacher/retrain_table.py --write RUN_DIR...` collects, for every retrained
job of the run directories, the job's own final evaluation (the policy that learned along with
the reward; metrics.csv) and the last evaluation of the fresh SAC agent trained on the job's
final reward (<run>/retrain/<algo>_seed<S>_sac<K>[_zero<U>...].csv, not tracked) into
experiments/reacher/retrain.csv (tracked; rows of runs not given are kept).
`python3 experiments/reacher/retrain_table.py` prints two markdown tables from retrain.csv:
every fresh agent, and per job over its fresh agents (SAC seeds) the share that solve the task
(>= 0.9 on every branch) and the ground truth of the agent with the highest learned return —
the choice a user without the ground truth would make. Success is the ground truth's; for IF
and Composite each branch (normal / cancel), and the headline is the lower.
"""
import csv
import glob
import os
import re
import sys

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
import rundata  # noqa: E402

CSV = os.path.join(here, "retrain.csv")
FIELDS = ["run", "algo", "seed", "sac_seed", "retrain_steps",
          "own_success", "own_normal", "own_cancel",
          "retrained_success", "retrained_normal", "retrained_cancel",
          "retrained_progress", "retrained_final_ball", "retrained_learned_return",
          "zeroed_states"]
ORDER = ["or", "sequential", "if", "composite", "blue"]


def rel(run):
    return os.path.relpath(os.path.abspath(run), here)


def collect(run):
    try:
        metrics = rundata.table(run, "metrics.csv")
    except FileNotFoundError:
        metrics = []
    out = []
    for path in sorted(glob.glob(os.path.join(run, "retrain", "*.csv"))):
        m = re.match(r"(.+)_seed(\d+)_sac(\d+)(?:_zero([\d-]+))?\.csv$", os.path.basename(path))
        if not m:
            continue
        algo, seed, sac, zeroed = m.groups()
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows:
            continue
        last = rows[-1]
        own = [r for r in metrics if r["algo"] == algo and r["seed"] == seed]
        o = max(own, key=lambda r: int(r["iteration"])) if own else {}
        out.append({
            "run": rel(run), "algo": algo, "seed": seed, "sac_seed": sac,
            "retrain_steps": last["env_steps"],
            "own_success": o.get("success_rate", ""), "own_normal": o.get("success_normal", ""),
            "own_cancel": o.get("success_cancel", ""),
            "retrained_success": last["success_rate"], "retrained_normal": last["success_normal"],
            "retrained_cancel": last["success_cancel"], "retrained_progress": last["progress"],
            "retrained_final_ball": last["final_ball"],
            "retrained_learned_return": last.get("learned_return", ""),
            "zeroed_states": (zeroed or "").replace("-", " "),
        })
    return out


def key(r):
    task = os.path.basename(r["run"]).split("-")[-1] if "heldout" in r["run"] else os.path.basename(r["run"]).split("-")[0]
    return (ORDER.index(task) if task in ORDER else 9, r["run"], r["algo"], int(r["seed"]),
            r.get("zeroed_states") or "", int(r["sac_seed"]))


def read():
    if not os.path.exists(CSV):
        return []
    with open(CSV, newline="") as f:
        return list(csv.DictReader(f))


def write(runs):
    given = {rel(r) for r in runs}
    rows = [r for r in read() if r["run"] not in given]
    for run in runs:
        rows.extend(collect(run))
    rows.sort(key=key)
    with open(CSV, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def fmt(x):
    return "" if x in ("", None) else f"{float(x):.2f}"


def cell(success, normal, cancel):
    if normal not in ("", None) and cancel not in ("", None):
        return f"{fmt(normal)} / {fmt(cancel)}"
    return fmt(success)


def solved(r, prefix):
    return float(r[prefix + "success"]) >= 0.9


def table():
    rows = read()
    jobs = {}
    for r in rows:
        jobs.setdefault((r["run"], r["algo"], r["seed"], r.get("zeroed_states") or ""), []).append(r)
    print("Per job: the job's own final policy, and its fresh agents (one per SAC seed) on the")
    print("final reward — how many solve the task (>= 0.9 on every branch), and the ground truth of")
    print("the one with the highest learned return. `reacher retrain --zero-state U` rows train on")
    print("the final reward with the weights of learned states U set to 0 (\"seed 25, zeroed 7\").\n")
    print("| run | algorithm | seed | job's own policy, final | fresh agents solving | agent of highest learned return | its learned return |")
    print("|---|---|---|---|---|---|---|")
    for (run, algo, seed, zeroed), rs in jobs.items():
        if zeroed:
            seed = f"{seed}, zeroed {zeroed}"
        own = cell(rs[0]["own_success"], rs[0]["own_normal"], rs[0]["own_cancel"])
        n = sum(solved(r, "retrained_") for r in rs)
        scored = [r for r in rs if r["retrained_learned_return"] != ""]
        if scored:
            best = max(scored, key=lambda r: float(r["retrained_learned_return"]))
            pick = cell(best["retrained_success"], best["retrained_normal"], best["retrained_cancel"])
            ret = f"{float(best['retrained_learned_return']):.1f} (SAC seed {best['sac_seed']})"
        else:
            pick, ret = "", ""
        print(f"| {run} | {algo} | {seed} | {own} | {n} of {len(rs)} | {pick} | {ret} |")
    print("\nEvery fresh agent:\n")
    print("| run | algorithm | seed | SAC seed | fresh agent, final | learned return | retrain steps |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        lr = r["retrained_learned_return"]
        seed = r["seed"] + (f", zeroed {r['zeroed_states']}" if r.get("zeroed_states") else "")
        print(f"| {r['run']} | {r['algo']} | {seed} | {r['sac_seed']} "
              f"| {cell(r['retrained_success'], r['retrained_normal'], r['retrained_cancel'])} "
              f"| {'' if lr == '' else f'{float(lr):.1f}'} | {r['retrain_steps']} |")


def fresh_candidate():
    """SMIRL's final-policy choice if the fresh agent (SAC seed 1000, no zeroed state) were one
    more candidate, chosen by the same learned return: for every retrained job whose final-policy
    candidates are on record. A simulation from the tables: the fresh agent's learned return is
    scored on its evaluation episodes, the candidates' on their selection episodes (the same
    reward and protocol: mean action, every episode to the time limit, 20 episodes)."""
    print("\nThe final policy with the fresh agent as one more candidate (SAC seed 1000; chosen,")
    print("as the job's own, by the highest learned return):\n")
    print("| run | algorithm | seed | reported policy (learned return) | fresh agent (learned return) | choice with the fresh agent |")
    print("|---|---|---|---|---|---|")
    for f in read():
        if f["sac_seed"] != "1000" or f.get("zeroed_states") or not f["retrained_learned_return"]:
            continue
        run, algo, seed = f["run"], f["algo"], int(f["seed"])
        candidates = rundata.final_policy(os.path.join(here, run)).get((algo, seed))
        if not candidates:
            continue
        c = rundata.chosen(candidates)
        own = cell(c["success_rate"], c["success_normal"], c["success_cancel"])
        new = cell(f["retrained_success"], f["retrained_normal"], f["retrained_cancel"])
        lc, lf = float(c["learned_return"]), float(f["retrained_learned_return"])
        pick = f"fresh agent, {new}" if lf > lc else f"reported policy, {own}"
        print(f"| {run} | {algo} | {seed} | {own} ({lc:.1f}) | {new} ({lf:.1f}) | {pick} |")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--write"]:
        write(sys.argv[2:])
    else:
        table()
        fresh_candidate()

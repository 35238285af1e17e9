#!/usr/bin/env python3
"""The evaluation's positive controls on development base 0 (experiments/protocol/eval1*.md):
every arm on `blue` (three SAC seeds) and the product controls on `or` (one); maxent and fkl ran
`or` too, reported beside the controls but not one of them (`or`'s order, red or green and then
blue, is not a function of the fingertip their reward reads). Reads the job files of the control run directories, keeps what the
table needs in `eval_controls.csv` (one row per job: the final-set scores of the loop's own
policy and of every final-phase candidate, the choice, the wall time), and prints the table of
`results-eval1.md` from that file alone.

A job's score is its lower branch's success on the final set (50 episodes per branch, a seed
stream nothing trains or selects on). An arm passes a control when its reported policy (the
final phase's choice; the loop's own for smirl-paper, which has no final phase) scores >= 0.9 in
at least 2 of its 3 jobs on blue, and (product controls) in its one job on or.

Usage: python3 experiments/reacher/controls/eval_controls.py [--add RUN_DIR:ARM ...]
  --add reads RUN_DIR/jobs/*.json into the CSV under the arm's name, or each job under its
  algorithm's name when ARM is `auto` (replacing rows of the same task, arm and seed); without
  it, the table of the CSV is printed.
"""

import csv
import glob
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
CSV = os.path.join(HERE, "eval_controls.csv")
COLUMNS = ["task", "arm", "algo", "seed", "loop", "chosen", "candidates", "wall_secs", "version"]
SOLVED = 0.9
# Jobs each control plans per arm (SAC seeds of base 0), and how many must be solved.
PLANNED = {"blue": (3, 2), "or": (1, 1)}
# The arms `or` is a control of: those whose reward reads the learned machine's state.
OR_CONTROL_ARMS = {"maxent-product", "fkl-product"}


def score(evaluated):
    """Lower-branch success and per-branch rates of a final-set evaluation."""
    if evaluated is None:
        return None
    b = evaluated.get("branches")
    if not b:
        return [evaluated["success_rate"]]
    return [s / e for e, s in zip(b["episodes"], b["successes"]) if e > 0]


def rows_of(run_dir, arm):
    prep = json.load(open(os.path.join(run_dir, "prepare.json")))
    task = prep.get("task", os.path.basename(run_dir))
    if isinstance(task, dict):
        task = task.get("name", os.path.basename(run_dir))
    version = prep.get("git_commit", "")[:7]
    for path in sorted(glob.glob(os.path.join(run_dir, "jobs", "*.json"))):
        rec = json.load(open(path))
        final = rec.get("final_policy")
        yield {
            "task": task,
            "arm": rec["algo"] if arm == "auto" else arm,
            "algo": rec["algo"],
            "seed": rec["seed"],
            "loop": json.dumps(score(rec.get("loop_final_set"))),
            "chosen": "" if not final else final["chosen"],
            "candidates": "" if not final else json.dumps([score(c.get("final_set")) for c in final["candidates"]]),
            "wall_secs": round(rec.get("wall_secs", 0.0)),
            "version": version,
        }


def read_csv():
    if not os.path.exists(CSV):
        return []
    with open(CSV, newline="") as f:
        return list(csv.DictReader(f))


def add(specs):
    rows = read_csv()
    for spec in specs:
        run_dir, _, arm = spec.rpartition(":")
        if not run_dir:
            sys.exit(f"eval_controls: --add takes RUN_DIR:ARM, got {spec}")
        for new in rows_of(run_dir, arm):
            key = (new["task"], new["arm"], str(new["seed"]))
            rows = [r for r in rows if (r["task"], r["arm"], r["seed"]) != key] + [new]
    rows.sort(key=lambda r: (r["task"], r["arm"], int(r["seed"])))
    with open(CSV, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in COLUMNS})


def fmt(x):
    return "—" if x is None else f"{x:.2f}"


def table():
    rows = read_csv()
    print("| task | arm | seed | loop's own | chosen (per branch) | random pick | best candidate | reported | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    verdict = {}
    for r in rows:
        loop = json.loads(r["loop"])
        loop_low = min(loop) if loop else None
        if r["candidates"]:
            cands = [min(c) for c in json.loads(r["candidates"])]
            chosen_rates = json.loads(r["candidates"])[int(r["chosen"])]
            chosen = min(chosen_rates)
            pick = sum(cands) / len(cands)
            best = max(cands)
            reported = chosen
            per_branch = " / ".join(f"{x:.2f}" for x in chosen_rates)
            chosen_txt = f"{chosen:.2f} ({per_branch})" if len(chosen_rates) > 1 else f"{chosen:.2f}"
        else:
            chosen_txt, pick, best, reported = "—", None, None, loop_low
        print(f"| {r['task']} | {r['arm']} | {r['seed']} | {fmt(loop_low)} | {chosen_txt} | {fmt(pick)} | {fmt(best)} | {fmt(reported)} | {r['wall_secs']} |")
        verdict.setdefault((r["task"], r["arm"]), []).append(reported is not None and reported >= SOLVED)
    print()
    print("| task | arm | reported policy solved | control |")
    print("|---|---|---|---|")
    for (task, arm), ok in sorted(verdict.items()):
        planned, need = PLANNED.get(task, (len(ok), len(ok)))
        if task == "or" and arm not in OR_CONTROL_ARMS:
            old = "pass" if sum(ok) >= need else "FAIL"
            verdict_txt = f"{old} under 24d2403's rule; not a control since the amendment in eval1.md"
        elif sum(ok) >= need:
            verdict_txt = f"pass (needs {need} of {planned})"
        elif sum(ok) + planned - len(ok) < need:
            verdict_txt = f"FAIL (needs {need} of {planned})"
        else:
            verdict_txt = f"not decided: {len(ok)} of {planned} jobs run"
        print(f"| {task} | {arm} | {sum(ok)} of {len(ok)} | {verdict_txt} |")


def main():
    args = sys.argv[1:]
    if args and args[0] == "--add":
        add(args[1:])
    elif args:
        sys.exit(__doc__)
    else:
        table()


if __name__ == "__main__":
    main()

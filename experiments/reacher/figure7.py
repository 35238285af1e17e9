"""Figure 7 with every algorithm on its own schedule (experiments/reacher/figure7_schedules.sh,
config.toml): one table per run directory given, one row per algorithm, over its
finished seeds — the final ground-truth success (IF and Composite: the lower branch, and each
branch), the mean success over the last quarter of the IRL iterations (the policies of
SMIRL's iterations 16-20, of the baselines' 601-800), the best success any iteration's policy
reached (an upper bound, read off the ground truth, on what choosing among a job's policies
could report), the partial progress the paper's figure
credits (sub-goals completed along the perfect machine, a ball that can end the task touched)
at the end, and the median wall time per job. For SMIRL jobs with a final-policy phase
(final_policy.csv: SAC on the final reward held fixed, the candidate of highest learned return
reported), a second table: that policy's success per seed (and per branch), beside the
co-trained policy's and the phase's last checkpoint's. Markdown on standard output; numbers
from the runs' metrics.csv(.gz), final_policy.csv and run.json.

Usage: python3 experiments/reacher/figure7.py [--final-only] [--algos A,B] RUN_DIR...
  --final-only  only the final-policy tables (for runs whose IRL loops another table shows)
  --algos A,B   only these algorithms' rows
A run without run.json (the consolidated ablation runs) shows no wall time.
"""
import json
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rundata  # noqa: E402

ORDER = ["smirl", "smirl-paper", "smirl-smooth", "maxent", "fkl", "js", "rkl"]


def ms(xs):
    if not xs:
        return "-"
    if len(xs) == 1:
        return f"{xs[0]:.2f}"
    return f"{statistics.mean(xs):.2f} ± {statistics.pstdev(xs):.2f}"


def per_seed(xs):
    return ", ".join(f"{x:.2f}" for x in xs)


def print_head(before, branch_column, after):
    """A markdown table's header and rule; the branch column only for IF and Composite."""
    columns = before + ([branch_column] if branch_column else []) + after
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))


def algorithms(jobs):
    """The algorithms of {(algo, seed): ...} in figure 7's order."""
    return sorted({a for a, _ in jobs}, key=lambda a: ORDER.index(a) if a in ORDER else 9)


def main(runs, final_only=False, only=None):
    for run in runs:
        if final_only:
            print(f"\n**{os.path.basename(os.path.normpath(run))}**")
            final_policies(run, only)
            continue
        rows = [r for r in rundata.table(run, "metrics.csv") if only is None or r["algo"] in only]
        info_path = os.path.join(run, "run.json")
        info = json.load(open(info_path)) if os.path.exists(info_path) else {}
        walls = {}
        for j in info.get("jobs", []):
            walls.setdefault(j["algo"], []).append(j["wall_secs"])
        jobs = {}
        for r in rows:
            jobs.setdefault((r["algo"], int(r["seed"])), []).append(r)
        branches = any(r.get("success_normal", "") != "" for r in rows)
        print(f"\n**{os.path.basename(os.path.normpath(run))}**\n")
        print_head(["algorithm", "seeds", "final success", "per seed"],
                   "final normal / cancel" if branches else None,
                   ["last quarter", "best iteration per seed", "final sub-goals", "final end ball",
                    "wall per job (s)"])
        for algo in algorithms(jobs):
            seeds = sorted(s for a, s in jobs if a == algo)
            final, normal, cancel, quarter, best, prog, ball = [], [], [], [], [], [], []
            for s in seeds:
                it = sorted(jobs[(algo, s)], key=lambda r: int(r["iteration"]))
                last = it[-1]
                final.append(float(last["success_rate"]))
                if branches:
                    normal.append(float(last["success_normal"]))
                    cancel.append(float(last["success_cancel"]))
                quarter.append(rundata.last_quarter(it))
                best.append(max(float(r["success_rate"]) for r in it if int(r["iteration"]) > 0))
                prog.append(float(last["progress"]) if last.get("progress") else float("nan"))
                ball.append(float(last["final_ball"]) if last.get("final_ball") else float("nan"))
            line = f"| {algo} | {len(seeds)} | {ms(final)} | {per_seed(final)} |"
            if branches:
                line += f" {ms(normal)} / {ms(cancel)} |"
            wall = walls.get(algo, [])
            wall_txt = f"{statistics.median(wall):.0f}" if wall else "-"
            line += f" {ms(quarter)} | {per_seed(best)} | {ms(prog)} | {ms(ball)} | {wall_txt} |"
            print(line)
        final_policies(run, only)


def final_policies(run, only=None):
    """The table of the run's final-policy phases, if it has any (from final_policy.csv, or
    the consolidated rows of its parent directory)."""
    jobs = {k: v for k, v in rundata.final_policy(run).items() if only is None or k[0] in only}
    if not jobs:
        return
    branches = any(r.get("success_normal", "") != "" for c in jobs.values() for r in c)
    print("\nFinal policy (`final_policy.csv`): the reported policy (highest learned return), the"
          " co-trained one (candidate 0, the last iteration's) and the phase's last checkpoint.\n")
    print_head(["algorithm", "seeds", "reported policy", "per seed"],
               "reported normal / cancel per seed" if branches else None,
               ["co-trained per seed", "last checkpoint per seed", "candidate reported per seed"])
    for algo in algorithms(jobs):
        seeds = sorted(s for a, s in jobs if a == algo)
        cands = [jobs[(algo, s)] for s in seeds]
        picked = [rundata.chosen(c) for c in cands]
        reported = [float(c["success_rate"]) for c in picked]
        line = f"| {algo} | {len(seeds)} | {ms(reported)} | {per_seed(reported)} |"
        if branches:
            line += " " + ", ".join(f"{float(c['success_normal']):.2f} / {float(c['success_cancel']):.2f}"
                                    for c in picked) + " |"
        line += f" {per_seed([float(c[0]['success_rate']) for c in cands])} |"
        line += f" {per_seed([float(c[-1]['success_rate']) for c in cands])} |"
        line += " " + ", ".join(c["candidate"] for c in picked) + " |"
        print(line)


if __name__ == "__main__":
    args = sys.argv[1:]
    final_only = "--final-only" in args
    args = [a for a in args if a != "--final-only"]
    only = None
    if "--algos" in args:
        i = args.index("--algos")
        if i + 1 >= len(args):
            sys.exit(__doc__)
        only = set(args[i + 1].split(","))
        del args[i:i + 2]
    main(args, final_only, only)

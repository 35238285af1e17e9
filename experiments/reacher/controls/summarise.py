#!/usr/bin/env python3
"""The Markovian positive control "blue" (touch the blue ball; issue 14): per run directory
experiments/reacher/runs/blue<suffix> (one per schedule tried), algorithm and seed, the final
iteration's success, the mean over the last five iterations, the best iteration, the
iteration-by-iteration success as a strip (one digit per iteration, 9 = 0.9 or more) and the
job's wall time (`wall_secs` of the job in run.json, as in jobs/<algo>_seed<S>.json; two jobs
shared the 2-core machine at a time). Reads metrics.csv or metrics.csv.gz (rundata.py).
Usage: python3 experiments/reacher/controls/summarise.py > experiments/reacher/controls/results.md
       python3 experiments/reacher/controls/summarise.py --fair RUN_DIR...   (results-fair.md's
       tables: see `fair`)"""
import glob
import io
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import rundata  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "runs")
CONFIGS = {
    "blue": "experiments/reacher/config_uniform.toml (SMIRL's schedule for every algorithm, figure 7 before issue 14: 20 x 5 000 SAC steps, 20 trajectories, 5 reward steps, bandwidth 0.02)",
    "blue-bandwidth_0.1": "experiments/reacher/controls/bandwidth_0.1.toml (figure 7's, KDE bandwidth 0.1)",
    "blue-firl_schedule": "experiments/reacher/controls/firl_schedule.toml (500 x 200 SAC steps, 100 trajectories, 2 reward steps)",
    "blue-firl_reacherdraw": "experiments/reacher/controls/firl_reacherdraw.toml (f-IRL's ReacherDraw settings: 30-step episodes, 800 x 300 SAC steps, 1 000 trajectories, 2 reward steps, SAC lr 3e-3, alpha 1 fixed, replay 12 000)",
    "blue-firl_reacherdraw_bw0.05": "experiments/reacher/controls/firl_reacherdraw_bw0.05.toml (f-IRL's ReacherDraw settings, KDE bandwidth 0.05: the expert's discs overlap)",
    "blue-firl_reacherdraw_bw0.1": "experiments/reacher/controls/firl_reacherdraw_bw0.1.toml (f-IRL's ReacherDraw settings, KDE bandwidth 0.1)",
    "blue-firl_reacherdraw_alpha0.1": "experiments/reacher/controls/firl_reacherdraw_alpha0.1.toml (f-IRL's ReacherDraw settings, SAC temperature 0.1 fixed instead of 1)",
    "blue-firl_reacherdraw_disc": "experiments/reacher/controls/firl_reacherdraw_disc.toml (f-IRL's ReacherDraw settings, density ratio from a discriminator instead of two KDEs)",
    "blue-firl_reacherdraw_gauss": "experiments/reacher/controls/firl_reacherdraw_gauss.toml (f-IRL's ReacherDraw settings, the demonstrations' density a Gaussian KDE with no zeros instead of the Epanechnikov KDE)",
    "blue-firl_reacherdraw_expert": "experiments/reacher/controls/firl_reacherdraw_expert.toml (f-IRL's ReacherDraw settings with the demonstrations in the covariance batch, as f-IRL's code for demonstrations has them: 1 000 drawn per reward step beside the 1 000 agent trajectories)",
    "blue-firl_reacherdraw_T100": "experiments/reacher/controls/firl_reacherdraw_T100.toml (the same at figure 7's horizon: 100-step episodes, 300 trajectories = the same 30 000 states per KDE)",
}
FAIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fair-blue")


def fair(runs):
    """results-fair.md's tables (`--fair RUN_DIR...`): each run directory's metrics.csv and
    final_policy.csv rows replace those of the same algorithms in fair-blue/ (metrics.csv.gz,
    written as `gzip -n -9`; final_policy.csv), then per algorithm and seed of fair-blue/ the
    loop's own, the chosen and the randomly picked policy's success (the last metrics row) with
    the chosen and picked candidate (final_policy.csv) and, for the runs given, the job's wall
    time (run.json)."""
    import csv
    import gzip
    walls = {}
    for run in runs:
        algos = {r["algo"] for r in rundata.metrics(run)}
        for name, packed in (("metrics.csv", True), ("final_policy.csv", False)):
            path = os.path.join(FAIR, name + (".gz" if packed else ""))
            old = rundata.table(FAIR, name)
            new = rundata.table(run, name)
            header = list(old[0].keys()) if old else list(new[0].keys())
            header += [k for k in new[0].keys() if k not in header]
            rows = [r for r in old if r["algo"] not in algos] + new
            text = io.StringIO()
            w = csv.DictWriter(text, header, lineterminator="\n", restval="")
            w.writeheader()
            w.writerows(rows)
            data = text.getvalue().encode()
            if packed:
                with open(path, "wb") as f, gzip.GzipFile(fileobj=f, mode="wb", compresslevel=9, mtime=0, filename="") as g:
                    g.write(data)
            else:
                with open(path, "wb") as f:
                    f.write(data)
        for j in json.load(open(os.path.join(run, "run.json")))["jobs"]:
            walls[(j["algo"], str(j["seed"]))] = j["wall_secs"]
    rows = rundata.metrics(FAIR)
    cands = rundata.table(FAIR, "final_policy.csv")
    print("| algorithm | seed | loop's own policy (last iteration) | chosen (highest learned return) | random pick | wall (s) |")
    print("|---|---|---|---|---|---|")
    for a in dict.fromkeys(r["algo"] for r in rows):
        for s in sorted({r["seed"] for r in rows if r["algo"] == a}, key=int):
            last = [r for r in rows if r["algo"] == a and r["seed"] == s][-1]
            cs = [c for c in cands if c["algo"] == a and c["seed"] == s]
            steps = lambda c: f"{int(c['env_steps']):,}".replace(",", " ")
            which = lambda col: next((f"{c['agent']}, {steps(c)} steps" for c in cs if c[col] == "1"), "")
            wall = walls.get((a, s))
            print(f"| {a} | {s} | {float(last['success_rate']):.2f} (iteration {last['iteration']}) "
                  f"| {float(last['chosen_success_rate']):.2f} ({which('chosen')}) "
                  f"| {float(last['random_success_rate']):.2f} ({which('random')}) "
                  f"| {'—' if wall is None else f'{wall:.0f}'} |")


if sys.argv[1:2] == ["--fair"]:
    fair(sys.argv[2:])
    sys.exit(0)
print("# Positive control \"blue\": touch the blue ball (issue 14)\n")
print("Generated by `python3 experiments/reacher/controls/summarise.py` from `experiments/reacher/runs/blue*/metrics.csv`,")
print("written by `experiments/reacher/positive_control.sh [CONFIG] [SUFFIX] [ALGOS]` (commands in experiments/README.md;")
print("the account: experiments/archive/README-research-log.md, part B). Success: ground truth (blue touched), mean action, 20 evaluation episodes.")
print("Code: every job's numbers come from the tree of f94f899 (task `blue`) or later, whose IRL code is")
print("unchanged since; jobs run from 7e962d1 on also fill `expert_support` (blank in the others).")
print("The `blue-firl_reacherdraw_disc` jobs ran a build of the discriminator change before it was committed")
print("(their records name 2281c6a, its parent); its code is that of 17a775d.")
print("The `blue-firl_reacherdraw_expert*` jobs ran 9d0ed40's build (demonstrations in f-IRL's covariance batch,")
print("`firl_expert_trajectories`; with it 0 the code computes what it computed before, bit for bit).\n")
for d in sorted(glob.glob(os.path.join(ROOT, "blue*"))):
    name = os.path.basename(d)
    if not rundata.has(d, "metrics.csv"):
        continue
    rows = rundata.metrics(d)
    walls = {}
    if os.path.isfile(os.path.join(d, "run.json")):
        walls = {(j["algo"], str(j["seed"])): j["wall_secs"]
                 for j in json.load(open(os.path.join(d, "run.json")))["jobs"]}
    print(f"## `runs/{name}`: {CONFIGS.get(name, '')}\n")
    print("| algorithm | seed | final success | mean of last 5 | best iteration | success per iteration | wall (s) |")
    print("|---|---|---|---|---|---|---|")
    algos = []
    for r in rows:
        if r["algo"] not in algos:
            algos.append(r["algo"])
    for a in algos:
        for s in sorted({r["seed"] for r in rows if r["algo"] == a}, key=int):
            rs = [r for r in rows if r["algo"] == a and r["seed"] == s]
            succ = [float(r["success_rate"]) for r in rs]
            step = max(1, len(succ) // 40)
            strip = "".join(str(min(9, int(x * 10))) for x in succ[::step])
            wall = walls.get((a, s), float("nan"))
            print(f"| {a} | {s} | {succ[-1]:.2f} | {sum(succ[-5:]) / 5:.2f} | {max(succ):.2f} | `{strip}` | {wall:.0f} |")
    print()

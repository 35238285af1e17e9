#!/usr/bin/env python3
"""The selection cut (issue 13; ablations/selection_cut.toml, `smirl_selection_cut = true`)
and its reading of touches as entries (ablations/selection_cut_entries.toml,
`smirl_selection_cut_entries = true`): which jobs they can change, running them, and what
they changed.

The cut changes only the number the final phase's choice reads; the IRL loop, the final
phase's SAC steps and every candidate's ground-truth evaluation are the standard's. So a job
whose candidates all reach 0.9 (on each branch) is solved under any choice, one whose
candidates all miss is missed under any, and only the standard's jobs with candidates on both
sides of 0.9 are run — tuning (base 0, SAC seeds 0-5) and held
out, the current standard's jobs as standard_heldout.py finds them.

Usage: python3 experiments/reacher/selection_cut.py [--list | --run [--entries]] [REACHER_BIN]
  --list  the jobs that can change, one per line: scope (tuning/heldout), task, base, SAC seed,
          the previous standard's run
  --run   run them with the cut (skipping those already done): per (task, base) `reacher
          prepare` with the ablation's config into ablations/runs/selection_cut-seeds0to5-<task>
          (tuning) or heldout/selection-cut-seeds<B>-<task>, `reacher job` two at a time, then
          `reacher aggregate --partial`; tuning first, then the held-out jobs. With --entries,
          the same with ablations/selection_cut_entries.toml into selection_cut_entries-… and
          selection-cut-entries-…
  (none)  the table for results.md: per job the previous standard's reported policy and each
          variant's, a check that every candidate is the previous standard's (all columns but
          cut_return and chosen equal), and the totals over every job of the standard
REACHER_BIN defaults to target/release/reacher (used for `prepare`, and by --run).
"""
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rundata  # noqa: E402
import standard_heldout  # noqa: E402

HERE = standard_heldout.HERE
# Variant: (config, tuning run prefix, held-out run prefix).
VARIANTS = {
    "touches": ("selection_cut.toml", "selection_cut", "selection-cut"),
    "entries": ("selection_cut_entries.toml", "selection_cut_entries", "selection-cut-entries"),
}
ABLATION_RUNS = os.path.join(HERE, "ablations", "runs")
# The standard's tuning jobs: base 0's machines of OR, IF and Composite are the replay-all
# standard's (fallback starts and initial events change none of them); Sequential's changed.
TUNING = {"or": "replay_all-seeds0to5-or", "sequential": "initial_events-seeds0to5-sequential",
          "if": "replay_all-seeds0to5-if", "composite": "replay_all-seeds0to5-composite"}
SOLVED = standard_heldout.SOLVED
# Columns that must match the standard's candidate for the rerun to be the standard's job.
SAME = ["candidate", "env_steps", "learned_return", "success_rate", "success_normal",
        "success_cancel", "progress", "final_ball"]


def standard_jobs(binary):
    """[(scope, task, base, seed, standard run dir, its candidate rows)] of every job of the
    current standard (tuning and held out)."""
    jobs = []
    for task, name in TUNING.items():
        run = os.path.join(ABLATION_RUNS, name)
        for (algo, seed), cands in sorted(rundata.final_policy(run).items()):
            if algo == "smirl":
                jobs.append(("tuning", task, 0, seed, run, cands))
    found = standard_heldout.held_out_runs(standard_heldout.PREVIOUS[1])
    with tempfile.TemporaryDirectory() as tmp:
        for task in standard_heldout.TASKS:
            for base in sorted(b for t, b in found if t == task):
                name, _ = standard_heldout.standard_run(binary, tmp, standard_heldout.PREVIOUS,
                                                        task, base, found[(task, base)])
                if name is None:
                    continue
                run = os.path.join(standard_heldout.HELDOUT, name)
                for (algo, seed), cands in sorted(rundata.final_policy(run).items()):
                    if algo == "smirl":
                        jobs.append(("heldout", task, base, seed, run, cands))
    return jobs


can_change = standard_heldout.decided_by_choice


def cut_run(variant, scope, task, base):
    _, tuning, heldout = VARIANTS[variant]
    if scope == "tuning":
        return os.path.join(ABLATION_RUNS, f"{tuning}-seeds0to5-{task}")
    return os.path.join(standard_heldout.HELDOUT, f"{heldout}-seeds{base}-{task}")


def cut_candidates(variant, scope, task, base, seed):
    """A variant's run's candidate rows of one job, or None when it has not run."""
    try:
        return rundata.final_policy(cut_run(variant, scope, task, base)).get(("smirl", seed))
    except FileNotFoundError:
        return None


def prepare_run(binary, scope, task, base, config, out):
    """`reacher prepare` of a job's run with `config` into `out`, unless it exists: SAC seeds
    0-5 at a tuning base, B..B+2 at a held-out one."""
    if not os.path.isdir(out):
        seeds = "6" if scope == "tuning" else "3"
        subprocess.run([binary, "prepare", "--task", task, "--algo", "smirl", "--seed", str(base),
                        "--seeds", seeds, "--config", config, "--out", out, "--quiet"],
                       check=True, stdout=subprocess.DEVNULL)


def run_all(binary, jobs, variant):
    config = os.path.join(HERE, "ablations", VARIANTS[variant][0])
    cut_run_of = lambda s, t, b: cut_run(variant, s, t, b)
    todo = [(s, t, b, seed) for s, t, b, seed, _, cands in jobs
            if can_change(cands) and cut_candidates(variant, s, t, b, seed) is None]
    runs = {}
    for s, t, b, seed in todo:
        runs.setdefault((s, t, b), []).append(seed)
    for (s, t, b) in runs:
        prepare_run(binary, s, t, b, config, cut_run_of(s, t, b))

    def job(item):
        s, t, b, seed = item
        with open(cut_run_of(s, t, b) + f".seed{seed}.log", "w") as log:
            subprocess.run([binary, "job", "--run", cut_run_of(s, t, b), "--algo", "smirl",
                            "--seed", str(seed), "--quiet"], check=True, stdout=log)
        print(f"done: {variant} {s} {t} {b} seed {seed}", flush=True)

    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(job, todo))
    for (s, t, b) in runs:
        subprocess.run([binary, "aggregate", cut_run_of(s, t, b), "--partial"], check=True,
                       stdout=subprocess.DEVNULL)


def rate(c, task):
    text = f"{float(c['success_rate']):.2f}"
    if task in ("if", "composite"):
        text += f" ({float(c['success_normal']):.2f}/{float(c['success_cancel']):.2f})"
    return text


def table(jobs):
    variants = list(VARIANTS)
    lines = ["| scope | task | base | SAC seed | previous standard's reported policy | "
             + " | ".join(f"cut, {v}" for v in variants) + " | candidates the standard's |",
             "|---|---|---|---|---|" + "---|" * len(variants) + "---|"]
    totals = {}
    mark = lambda rows, task: f"{rate(rundata.chosen(rows), task)} (candidate {rundata.chosen(rows)['candidate']})"
    for scope, task, base, seed, _, cands in jobs:
        t = totals.setdefault((scope, task), {"jobs": 0, "previous": 0, **{v: 0 for v in variants},
                                              **{v + " not run": 0 for v in variants}})
        std_ok = float(rundata.chosen(cands)["success_rate"]) >= SOLVED
        t["jobs"] += 1
        t["previous"] += std_ok
        if not can_change(cands):
            for v in variants:
                t[v] += std_ok
            continue
        cells, same = [], True
        for v in variants:
            cut = cut_candidates(v, scope, task, base, seed)
            if cut is None:
                cells.append("not run")
                t[v + " not run"] += 1
                continue
            same &= len(cut) == len(cands) and all(
                a[k] == b[k] for a, b in zip(cut, cands) for k in SAME)
            t[v] += float(rundata.chosen(cut)["success_rate"]) >= SOLVED
            cells.append(mark(cut, task))
        lines.append(f"| {scope} | {task} | {base} | {seed} | {mark(cands, task)} | "
                     + " | ".join(cells) + f" | {'yes' if same else '**no**'} |")

    def total(t, v):
        missing = t[v + " not run"]
        return f"{t[v]}" + (f" ({missing} not run)" if missing else "")
    out = "\n".join(lines) + "\n\nJobs solved (both branches ≥ 0.9) of all the previous standard's, previous → " \
        + " → ".join(f"cut ({v})" for v in variants) + ": " + "; ".join(
            f"{scope} {task} {t['previous']} → " + " → ".join(total(t, v) for v in variants)
            + f" of {t['jobs']}" for (scope, task), t in totals.items()) + ".\n"
    return out


def main(argv):
    mode, variant = None, "touches"
    if argv and argv[0] in ("--list", "--run"):
        mode, argv = argv[0], argv[1:]
    if mode == "--run" and argv and argv[0] == "--entries":
        variant, argv = "entries", argv[1:]
    if argv and argv[0].startswith("-"):
        sys.exit(__doc__)
    binary = argv[0] if argv else os.path.join(HERE, "..", "..", "target", "release", "reacher")
    if not os.path.isfile(binary):
        sys.exit(f"selection_cut.py: {binary}: no such program (cargo build --release)")
    jobs = standard_jobs(binary)
    # Tuning first; then the jobs whose reported policy misses, then the rest.
    jobs.sort(key=lambda j: (j[0] != "tuning",
                             float(rundata.chosen(j[5])["success_rate"]) >= SOLVED))
    if mode == "--list":
        for scope, task, base, seed, run, cands in jobs:
            if can_change(cands):
                print(scope, task, base, seed, os.path.relpath(run, HERE))
    elif mode == "--run":
        run_all(binary, jobs, variant)
    else:
        print(table(jobs), end="")


if __name__ == "__main__":
    main(sys.argv[1:])

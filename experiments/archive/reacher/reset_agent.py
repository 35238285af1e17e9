#!/usr/bin/env python3
"""The reset agent (issue 13; ablations/reset_agent.toml, `smirl_final_reset_steps = 20000`):
running it and what it changed against the standard before it (the selection cut reading
touches as entries: the cut-entries standard).

The loop, the co-trained agent's final phase and its five candidates are the standard's bit
for bit (checked per job: every column but `chosen`); the reset agent's four checkpoints join
them, so any job can change — a solved one by a reset candidate of higher selection return
that fails. Every job is run, in this order: the cut-entries standard's misses (held out), the
tuning jobs (base 0, SAC seeds 0-5, every task: the rule's), then the other held-out jobs, IF
and Composite first, base by base (so that a sweep cut short covers both alike).

Usage: python3 experiments/reacher/reset_agent.py [--list | --run] [REACHER_BIN]
  --list  the jobs in that order: scope, task, base, SAC seed, the cut-entries standard's outcome
  --run   run them (skipping those already done): per (task, base) `reacher prepare` with the
          ablation's config into ablations/runs/reset_agent-seeds0to5-<task> (tuning) or
          heldout/reset-agent-seeds<B>-<task>, `reacher job` two at a time, `reacher aggregate
          --partial` after each job
  (none)  the table for results.md: per job run, the cut-entries standard's reported policy and
          the reset agent's, which agent's candidate was chosen, whether the first candidates
          are the standard's; totals over the jobs run
REACHER_BIN defaults to target/release/reacher (used for `prepare`, and by --run).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import job_reruns  # noqa: E402
import rundata  # noqa: E402
import selection_cut  # noqa: E402
import standard_heldout  # noqa: E402

HERE = standard_heldout.HERE
CONFIG = os.path.join(HERE, "ablations", "reset_agent.toml")
SOLVED = standard_heldout.SOLVED
# Columns that must match the standard's candidate (the selection cut's run where it ran).
SAME = selection_cut.SAME + ["cut_return"]


RERUNS = job_reruns.Reruns(CONFIG, "reset_agent", "reset-agent", "reset agent")
reset_candidates = RERUNS.candidates


def current_jobs(binary):
    """[(scope, task, base, seed, the cut-entries standard's candidate rows)]: the selection cut's
    (as entries) run where it ran, else the previous standard's rows (whose choice the cut
    could not change)."""
    jobs = []
    for scope, task, base, seed, _, cands in selection_cut.standard_jobs(binary):
        cut = selection_cut.cut_candidates("entries", scope, task, base, seed)
        jobs.append((scope, task, base, seed, cut if cut is not None else cands))
    return jobs


def solved(rows):
    return float(rundata.chosen(rows)["success_rate"]) >= SOLVED


def ordered(jobs):
    missed_bases = {(t, b) for s, t, b, _, rows in jobs if s == "heldout" and not solved(rows)}

    def key(j):
        scope, task, base, _, rows = j
        if scope == "heldout" and not solved(rows):
            return (0, task not in ("if", "composite"), 0)
        if scope == "tuning":
            return (1, 0, 0)
        return (2, (task, base) not in missed_bases, task not in ("if", "composite"), base)
    return sorted(jobs, key=key)


def table(jobs):
    lines = ["| scope | task | base | SAC seed | cut-entries standard's reported policy | "
             "with the reset agent (chosen: agent, candidate) | first candidates the standard's |",
             "|---|---|---|---|---|---|---|"]
    totals = {}
    for scope, task, base, seed, rows in jobs:
        reset = reset_candidates(scope, task, base, seed)
        if reset is None:
            continue
        t = totals.setdefault((scope, task), [0, 0, 0])
        t[0] += 1
        t[1] += solved(rows)
        t[2] += solved(reset)
        # cut_return only where the standard's run has it (the cut's reruns).
        same = len(reset) > len(rows) and all(
            a.get(k) == b.get(k) for a, b in zip(reset, rows) for k in SAME
            if k != "cut_return" or b.get(k))
        chosen = rundata.chosen(reset)
        lines.append(
            f"| {scope} | {task} | {base} | {seed} | {selection_cut.rate(rundata.chosen(rows), task)} | "
            f"{selection_cut.rate(chosen, task)} ({chosen.get('agent', 'co-trained')}, "
            f"{chosen['candidate']}) | {'yes' if same else '**no**'} |")
    return "\n".join(lines) + "\n\nJobs solved (every branch ≥ 0.9) among those run, cut-entries " \
        "standard → with the reset agent: " + "; ".join(
            f"{scope} {task} {t[1]} → {t[2]} of {t[0]}"
            for (scope, task), t in sorted(totals.items())) + ".\n"


def main(argv):
    mode = None
    if argv and argv[0] in ("--list", "--run"):
        mode, argv = argv[0], argv[1:]
    if argv and argv[0].startswith("-"):
        sys.exit(__doc__)
    binary = argv[0] if argv else os.path.join(HERE, "..", "..", "target", "release", "reacher")
    if not os.path.isfile(binary):
        sys.exit(f"reset_agent.py: {binary}: no such program (cargo build --release)")
    jobs = ordered(current_jobs(binary))
    if mode == "--list":
        for scope, task, base, seed, rows in jobs:
            print(scope, task, base, seed, "solved" if solved(rows) else "missed")
    elif mode == "--run":
        RERUNS.run(binary, jobs)
    else:
        print(table(jobs), end="")


if __name__ == "__main__":
    main(sys.argv[1:])

#!/usr/bin/env python3
"""A clock for SMIRL's agent (issue 13; ablations/clock.toml, `smirl_clock = true`) against the
reset-agent standard (config.toml), job for job.

The standard's outcome of a job is its reset-agent rerun (reset_agent.py); jobs the standard has
not run are left out. The clock changes what the agent sees from the first iteration on, so no
job is the standard's bit for bit. The rule (in clock.toml): (a) 24 of 24 tuning jobs and (b) on
the held-out IF and Composite jobs run under both, at least two more solved than the standard.
Order: the standard's IF and Composite held-out misses, the tuning jobs (base 0, SAC seeds 0-5,
every task), then the other held-out jobs, IF and Composite first, base by base.

Rest: the held-out jobs of the cut-entries standard the reset agent never reran (scope `rest`;
Composite first, then Sequential and OR base by base, so that a sweep cut short covers both),
run with the clock as held-out checks of the standard it became; rule (b) does not read them,
and their standard's column is empty.

Fresh bases: IF and Composite at base seeds no run has used (FRESH_BASES, SAC seeds B..B+2),
run with the clock only, are the held-out check of what the rule adopts; they are listed after
the rest, their standard's column empty.

Usage: python3 experiments/reacher/clock.py [--list | --run | --run-rest | --run-fresh] [REACHER_BIN]
  --list  the jobs in that order: scope, task, base, SAC seed, the standard's outcome
  --run   run them (skipping those already done): per (task, base), when its first job comes
          up, `reacher prepare` with clock.toml into ablations/runs/clock-seeds0to5-<task> (tuning) or
          heldout/clock-seeds<B>-<task>, `reacher job` two at a time, `reacher aggregate
          --partial` after each job
  --run-rest  the same for the rest (run dirs as the held-out jobs')
  --run-fresh  the same for the fresh bases' jobs (scope `fresh`, run dirs
          heldout/clock-seeds<B>-<task>)
  (none)  the table for results.md: per job run, the standard's reported policy and the
          clock's; totals over the jobs run and rule (b)'s count
REACHER_BIN defaults to target/release/reacher (used for `prepare`, and by --run).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import job_reruns  # noqa: E402
import rundata  # noqa: E402
import reset_agent  # noqa: E402
import selection_cut  # noqa: E402
import standard_heldout  # noqa: E402

HERE = standard_heldout.HERE
CONFIG = os.path.join(HERE, "ablations", "clock.toml")
CONDITIONAL = ("if", "composite")
# IF and Composite bases no run had used when the rule was applied (every held-out run before
# is at base 549 or lower).
FRESH_BASES = [700, 703]


def fresh_jobs():
    return [("fresh", task, base, base + k, None)
            for base in FRESH_BASES for task in CONDITIONAL for k in range(3)]


RERUNS = job_reruns.Reruns(CONFIG, "clock", "clock", "clock")
clock_candidates = RERUNS.candidates


def rest_jobs(binary):
    """[(scope `rest`, task, base, seed, None)]: the held-out jobs the reset agent never reran."""
    rest = [("rest", task, base, seed, None)
            for scope, task, base, seed, _ in reset_agent.current_jobs(binary)
            if scope == "heldout" and reset_agent.reset_candidates(scope, task, base, seed) is None]
    return sorted(rest, key=lambda j: (j[1] != "composite", j[2], j[1], j[3]))


def standard_jobs(binary):
    """[(scope, task, base, seed, the standard's candidate rows)] of the jobs the standard ran."""
    jobs = []
    for scope, task, base, seed, _ in reset_agent.current_jobs(binary):
        rows = reset_agent.reset_candidates(scope, task, base, seed)
        if rows is not None:
            jobs.append((scope, task, base, seed, rows))
    return jobs


def ordered(jobs):
    solved = reset_agent.solved

    def key(j):
        scope, task, base, _, rows = j
        if scope == "heldout" and task in CONDITIONAL and not solved(rows):
            return (0, 0, 0)
        if scope == "tuning":
            return (1, 0, 0)
        return (2, task not in CONDITIONAL, base)
    return sorted(jobs, key=key)


def table(jobs):
    solved = reset_agent.solved
    lines = ["| scope | task | base | SAC seed | standard's reported policy | "
             "with the clock (chosen: agent, candidate) |",
             "|---|---|---|---|---|---|"]
    totals = {}
    gained = lost = 0
    for scope, task, base, seed, rows in jobs:
        clock = clock_candidates(scope, task, base, seed)
        if clock is None:
            continue
        t = totals.setdefault((scope, task), [0, 0, 0])
        t[0] += 1
        t[1] += rows is not None and solved(rows)
        t[2] += solved(clock)
        if scope == "heldout" and task in CONDITIONAL:
            gained += solved(clock) and not solved(rows)
            lost += solved(rows) and not solved(clock)
        chosen = rundata.chosen(clock)
        standard = "" if rows is None else selection_cut.rate(rundata.chosen(rows), task)
        lines.append(
            f"| {scope} | {task} | {base} | {seed} | {standard} | "
            f"{selection_cut.rate(chosen, task)} ({chosen.get('agent', 'co-trained')}, "
            f"{chosen['candidate']}) |")
    return "\n".join(lines) + "\n\nJobs solved (every branch ≥ 0.9) among those run, standard " \
        "→ with the clock: " + "; ".join(
            f"{scope} {task} {t[1] if scope not in ('rest', 'fresh') else '-'} → {t[2]} of {t[0]}"
            for (scope, task), t in sorted(totals.items())) + \
        f". Held-out IF and Composite: {gained} gained, {lost} lost (rule (b): gained − lost ≥ 2).\n"


def main(argv):
    mode = None
    if argv and argv[0] in ("--list", "--run", "--run-rest", "--run-fresh"):
        mode, argv = argv[0], argv[1:]
    if argv and argv[0].startswith("-"):
        sys.exit(__doc__)
    binary = argv[0] if argv else os.path.join(HERE, "..", "..", "target", "release", "reacher")
    if not os.path.isfile(binary):
        sys.exit(f"clock.py: {binary}: no such program (cargo build --release)")
    jobs = ordered(standard_jobs(binary)) + rest_jobs(binary) + fresh_jobs()
    if mode == "--list":
        for scope, task, base, seed, rows in jobs:
            outcome = "-" if rows is None else "solved" if reset_agent.solved(rows) else "missed"
            print(scope, task, base, seed, outcome)
    elif mode == "--run":
        RERUNS.run(binary, [j for j in jobs if j[0] != "fresh"])
    elif mode == "--run-rest":
        RERUNS.run(binary, rest_jobs(binary))
    elif mode == "--run-fresh":
        RERUNS.run(binary, fresh_jobs())
    else:
        print(table(jobs), end="")


if __name__ == "__main__":
    main(sys.argv[1:])

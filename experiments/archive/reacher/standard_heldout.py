#!/usr/bin/env python3
"""SMIRL's held-out check under the current standard (issue 13), in one table: per task and
held-out base seed B, the reported policy of each SAC seed B, B+1, B+2, from whichever run is
the standard's job there. The current standard (config.toml) has the agent's clock
(ablations/clock.toml); its jobs are its own runs, heldout/clock-seedsB-<task> (the fresh bases
700 and 703 among them), and only those: the clock changes every job from its first
iteration, so a job not rerun with it is no job of the current standard's, and the table covers
the jobs run so far. With --reset-agent, the same for the standard before it (the reset agent,
ablations/reset_agent.toml, its runs heldout/reset-agent-seedsB-<task>). With --cut-entries,
the same for the one before that (the selection cut reading touches as entries,
ablations/selection_cut_entries.toml). With --touches, the same for the selection cut
reading touches as labels (ablations/selection_cut.toml, the standard for one stop before it read them as
entries); with --previous, for the standard before the cut (initial events and fallback starts,
choosing by the full learned return: ablations/initial_events.toml); with --fallback, for the one before it (fallback starts without initial events,
ablations/fallback_starts.toml); with --replay-all, for the one before that
(ablations/replay_all.toml); with --commuted, for the one before that (commuted events with a
100 000-transition replay buffer, ablations/commute_events.toml).

Usage: python3 experiments/reacher/standard_heldout.py [--reset-agent | --cut-entries | --touches | --previous | --fallback | --replay-all | --commuted] [REACHER_BIN]
  (REACHER_BIN defaults to target/release/reacher; it only runs `reacher prepare`, well under a
  second per machine. make_results.sh puts the tables in results.md.)

Which run is a standard's job at base B:
  1. Its own runs: heldout/initial-events-seedsB-<task> (ablations/initial_events.toml) for
     the previous standard; heldout/fallback-starts-seedsB-<task> (ablations/fallback_starts.toml)
     for the fallback one; heldout/replay-all-seedsB-<task> (ablations/replay_all.toml) for the
     replay-all one; heldout/commute-seedsB-<task> (ablations/commute_events.toml) for the
     commuted-events one.
  2. Else a run of an earlier setting whose config differs from the standard's only in LRM
     keys, when `reacher prepare` learns, at B, the same machine under that config as under
     the standard's. LRM runs in `prepare` alone and a job reads the machine from
     rm/learned.txt, so such a job is that standard's, seed for seed. For the previous
     standard: fallback-starts, then replay-all runs; for the fallback one: replay-all runs
     (the same binary's code for everything after `prepare`). For the commuted-events
     standard: heldout/unpredicted-seedsB-<task> (ablations/unpredicted_events.toml: no
     commuted events), then heldout/event-gated-seedsB-<task> (ablations/event_gated_visits.toml:
     also predicting the cancel) — from their commit, d6fce19, to commuted events `git log --
     src` touches LRM, config keys and the commands' refusal of unfinished runs only. The
     replay-all standard's SAC keeps a larger buffer than any setting before it, so only its
     own runs are its jobs.
  3. The cut-entries standard (the previous one with the selection cut reading touches as
     entries, ablations/selection_cut_entries.toml) and the touches one
     (ablations/selection_cut.toml) train exactly as the previous one and only choose
     differently, so their jobs are the previous standard's, SAC seed by SAC seed, with the
     choice of heldout/selection-cut-entries-seedsB-<task> (selection-cut-seedsB-<task>) where
     that run has the seed. They have every job whose candidates lie on both sides of 0.9
     (selection_cut.py --run [--entries]); in any other job every candidate is solved, or none
     is, under either choice — its cell shows the previous choice, marked °.
  A base where no run qualifies is left out of the table and listed below it, with the runs
  that exist there but learned another machine.

A job counts as solved when its reported policy (the final policy's chosen candidate) reaches
0.9 on the ground truth — for IF and Composite on each branch (the lower branch rate).
"""
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rundata  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
HELDOUT = os.path.join(HERE, "heldout")
# Per standard: its config, (run name prefix, config) of its own runs first (config None),
# then of earlier settings that differ from it only in how LRM learns the machine, and the
# prefix of runs that only choose differently among the same jobs' candidates (or None).
PREVIOUS = ("ablations/initial_events.toml",
            [("initial-events", None), ("fallback-starts", "ablations/fallback_starts.toml"),
             ("replay-all", "ablations/replay_all.toml")], None)
CURRENT = ("config.toml", [("clock", None)], None)
RESET_AGENT = ("ablations/reset_agent.toml", [("reset-agent", None)], None)
CUT_ENTRIES = ("ablations/selection_cut_entries.toml",
               [("initial-events", "ablations/initial_events.toml"),
                ("fallback-starts", "ablations/fallback_starts.toml"),
                ("replay-all", "ablations/replay_all.toml")], "selection-cut-entries")
TOUCHES = ("ablations/selection_cut.toml", CUT_ENTRIES[1], "selection-cut")
FALLBACK = ("ablations/fallback_starts.toml",
            [("fallback-starts", None), ("replay-all", "ablations/replay_all.toml")], None)
REPLAY_ALL = ("ablations/replay_all.toml", [("replay-all", None)], None)
COMMUTED = ("ablations/commute_events.toml",
            [("commute", None),
             ("unpredicted", "ablations/unpredicted_events.toml"),
             ("event-gated", "ablations/event_gated_visits.toml")], None)
TASKS = ["or", "sequential", "if", "composite"]
SOLVED = 0.9


def prepare(binary, task, base, config, tmp):
    """The text of the machine `reacher prepare` learns for `task` at `base` under `config`."""
    out = os.path.join(tmp, f"{task}-{base}-{os.path.basename(config)}")
    if not os.path.isdir(out):
        subprocess.run([binary, "prepare", "--task", task, "--algo", "smirl", "--seed", str(base),
                        "--seeds", "1", "--config", os.path.join(HERE, config), "--out", out,
                        "--quiet"], check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(out, "rm", "learned.txt")) as f:
        return f.read()


def held_out_runs(settings):
    """{(task, base): {setting: run name}} of the held-out runs with a final policy."""
    found = {}
    for name in rundata.runs(HELDOUT, "final_policy.csv"):
        m = re.fullmatch(r"(.+)-seeds(\d+)-(or|sequential|if|composite)", name)
        if m and m[1] in dict(settings):
            found.setdefault((m[3], int(m[2])), {})[m[1]] = name
    return found


def standard_run(binary, tmp, standard, task, base, runs):
    """(run name, setting) of the standard's job at `base`, or (None, [settings whose machine
    differs])."""
    config_file, settings, _ = standard
    differs = []
    for setting, config in settings:
        name = runs.get(setting)
        if name is None:
            continue
        if config is None:
            return name, setting
        if prepare(binary, task, base, config, tmp) == prepare(binary, task, base, config_file, tmp):
            return name, setting
        differs.append(setting)
    return None, differs


def cell(task, candidates):
    """'1.00 (1.00/1.00)' of one job's reported policy and whether it is solved."""
    c = rundata.chosen(candidates)
    rate = float(c["success_rate"])
    text = f"{rate:.2f}"
    if task in ("if", "composite"):
        text += f" ({float(c['success_normal']):.2f}/{float(c['success_cancel']):.2f})"
    return text, rate >= SOLVED


def jobs_of(standard, task, base, name):
    """{SAC seed: candidate rows} of the standard's SMIRL jobs at `base` from its run `name`,
    and the seeds whose choice no run of the standard's own made (see the module doc, 3)."""
    jobs = {s: c for (a, s), c in rundata.final_policy(os.path.join(HELDOUT, name)).items()
            if a == "smirl"}
    chooser = standard[2]
    if chooser is None:
        return jobs, set()
    own = os.path.join(HELDOUT, f"{chooser}-seeds{base}-{task}")
    try:
        chosen = {s: c for (a, s), c in rundata.final_policy(own).items() if a == "smirl"}
    except FileNotFoundError:
        chosen = {}
    jobs.update(chosen)
    return jobs, set(jobs) - set(chosen)


def decided_by_choice(candidates):
    """Whether the choice decides a job: candidates on both sides of 0.9."""
    rates = [float(c["success_rate"]) for c in candidates]
    return min(rates) < SOLVED <= max(rates)


def table(binary, standard):
    found = held_out_runs(standard[1])
    lines = ["| task | base | run (setting) | reported policy per SAC seed (IF, Composite: normal/cancel) | solved |",
             "|---|---|---|---|---|"]
    totals, missing, marked, not_run = {}, {}, False, []
    with tempfile.TemporaryDirectory() as tmp:
        for task in TASKS:
            for base in sorted(b for t, b in found if t == task):
                name, setting = standard_run(binary, tmp, standard, task, base, found[(task, base)])
                if name is None:
                    missing.setdefault(task, []).append(f"{base} ({', '.join(setting)})")
                    continue
                jobs, earlier = jobs_of(standard, task, base, name)
                # A job whose choice decides it and that the standard's chooser has not run
                # yet is no job of the standard's.
                undecided = {s for s in earlier if decided_by_choice(jobs[s])}
                for s in undecided:
                    not_run.append(f"{task} {base} seed {s}")
                    del jobs[s]
                cells = [cell(task, jobs[s]) for s in sorted(jobs)]
                texts = [text + ("°" if s in earlier else "") for s, (text, _) in zip(sorted(jobs), cells)]
                marked |= bool(earlier - undecided)
                solved = sum(ok for _, ok in cells)
                done, total = totals.get(task, (0, 0))
                totals[task] = (done + solved, total + len(cells))
                lines.append(f"| {task} | {base} | {name} ({setting}) | "
                             f"{', '.join(texts)} | {solved}/{len(cells)} |")
    out = "\n".join(lines) + "\n\n"
    out += "Jobs solved per task: " + "; ".join(
        f"{t} {totals[t][0]} of {totals[t][1]}" for t in TASKS if t in totals) + ".\n"
    if marked:
        out += ("\n° The choice of the run named, made before the selection cut: every candidate "
                "of the job is solved, or none is, so the job is solved or missed under either "
                "choice (the rates shown are the earlier choice's).\n")
    if not_run:
        out += ("\nJobs whose candidates lie on both sides of 0.9 and that the standard's "
                f"chooser has not run, left out: {', '.join(not_run)}.\n")
    if missing:
        out += ("\nHeld-out bases whose runs are not the standard's job (the setting of each run "
                "there, which learns another machine): "
                + "; ".join(f"{t} {', '.join(missing[t])}" for t in TASKS if t in missing) + ".\n")
    return out


def main(argv):
    standard = CURRENT
    named = {"--reset-agent": RESET_AGENT, "--cut-entries": CUT_ENTRIES, "--touches": TOUCHES, "--previous": PREVIOUS, "--fallback": FALLBACK, "--replay-all": REPLAY_ALL,
             "--commuted": COMMUTED}
    if argv and argv[0] in named:
        standard, argv = named[argv[0]], argv[1:]
    if argv and argv[0].startswith("-"):
        sys.exit(__doc__)
    binary = argv[0] if argv else os.path.join(HERE, "..", "..", "target", "release", "reacher")
    if not os.path.isfile(binary):
        sys.exit(f"standard_heldout.py: {binary}: no such program (cargo build --release, or pass REACHER_BIN)")
    print(table(binary, standard), end="")


if __name__ == "__main__":
    main(sys.argv[1:])

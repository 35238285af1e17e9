#!/usr/bin/env python3
"""Where does an OR job sit at about half success, and does its learned machine split the task
by the cancel?

Usage: python3 experiments/reacher/half_plateaus.py RUN_DIR...
       python3 experiments/reacher/half_plateaus.py --heldout [REACHER_BIN]
         (OR held out at bases 3-33, the runs of the two standards before unpredicted events
         (`final-…`, `event-gated-…`); each base's machine from `reacher prepare` with
         ablations/event_gated_visits.toml, well under a second, the one their sweeps learned;
         make_results.sh puts it in results.md. REACHER_BIN defaults to
         target/release/reacher.)
       python3 experiments/reacher/half_plateaus.py --fresh [REACHER_BIN]
         (OR at bases 36-42, run after everything else: event-gated visits' runs and
         unpredicted events', each machine prepared with its own config.)
       python3 experiments/reacher/half_plateaus.py --tuning [REACHER_BIN]
         (OR and Sequential at the tuning seeds, base 0, SAC seeds 0-5: event-gated visits'
         runs and unpredicted events' (the standard since), each machine prepared with its
         own config.)
       python3 experiments/reacher/half_plateaus.py --machines [REACHER_BIN]
         (machines only, no job: every task at bases 0-45 under event-gated visits (LRM
         predicting the cancel), under unpredicted events and under unpredicted and commuted
         events (ablations/commute_events.toml), prepared the same way; per task and setting
         the bases whose machine splits red by the cancel and, for IF and Composite, the bases
         with cancel holes (cancel_probe.py's probe).)

OR's perfect machine ignores the cancel, but a learned machine may keep "red touched" before
and after a cancel in two states, each with its own reward weights. A policy that has lost the
no-cancel copy and kept the other succeeds in exactly the evaluation episodes whose cancel
fires, about half of them (`reacher replay <run>/logs/smirl_seed<S>.mcap`: failing episodes
touch nothing, `labels []`). This script only counts, from each job's ground-truth success per
IRL iteration (metrics.csv, on disk or in the consolidated heldout/metrics.csv.gz):

  solved    iterations with success >= 0.9
  half      iterations with success in [0.40, 0.60] after the first solved one
  last      success of the last iteration
  reported  success of the reported final policy (final_policy.csv, the chosen candidate)

and, where the run's machine is on disk (rm/learned.txt), its state count and whether it
splits: red touched alone on step 5 ends in another state than the same touch with a cancel
on step 2 (before it) or on step 7 (after it). The last lines count per setting (the run name
without its `-seeds<B>` part).
"""
import collections
import os
import re
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cancel_probe  # noqa: E402
import rundata  # noqa: E402

SOLVED = 0.9
HALF = (0.40, 0.60)
HERE = os.path.dirname(os.path.abspath(__file__))
BASES = range(3, 34, 3)
# The previous standard's OR runs (event stutter changed no OR machine, so these are its jobs)
# and the standard's.
HELDOUT = ([os.path.join(HERE, "heldout", "final-or")]
           + [os.path.join(HERE, "heldout", f"final-seeds{b}-or") for b in BASES if b != 3]
           + [os.path.join(HERE, "heldout", f"event-gated-seeds{b}-or") for b in BASES])
# LRM predicting the cancel (every standard before unpredicted events: neither event stutter
# nor event-gated visits changed an OR machine) and not predicting it (the standard since).
PREDICTED = "ablations/event_gated_visits.toml"
UNPREDICTED = "ablations/unpredicted_events.toml"
# Unpredicted and commuted events (the standard since): --machines only.
COMMUTED = "ablations/commute_events.toml"
# --tuning: (run, task, base, its config) at base 0.
TUNING = [(os.path.join(HERE, "ablations", "runs", f"{name}-seeds0to5-{task}"), task, 0, config)
          for task in ("or", "sequential")
          for name, config in (("event_gated_visits", PREDICTED), ("unpredicted_events", UNPREDICTED))]
# --fresh: (run, task, base, its config) at the bases run last.
FRESH = [(os.path.join(HERE, "heldout", f"{name}-seeds{b}-or"), "or", b, config)
         for name, config in (("event-gated", PREDICTED), ("unpredicted", UNPREDICTED))
         for b in (36, 39, 42)]
# --machines: the bases and settings whose machines it compares.
MACHINE_BASES = range(0, 46, 3)
MACHINE_SETTINGS = [("cancel predicted (event-gated visits)", PREDICTED),
                    ("unpredicted events (the previous standard)", UNPREDICTED),
                    ("unpredicted and commuted events (the standard)", COMMUTED)]
HEADER = """`final-…` and `event-gated-…` are the jobs of the two standards before unpredicted events
(the script's doc says what each column counts). The machine columns are each base's OR
machine, prepared afresh with LRM predicting the cancel: the same at a base under both (neither
change touches an OR machine).

"""


def machine(run):
    """(learned states, splits red by the cancel) of run/rm/learned.txt, None when it is not on
    disk: red touched alone on step 5 ends in another state when a cancel fires on step 2 or
    on step 7."""
    path = os.path.join(run, "rm", "learned.txt")
    if not os.path.isfile(path):
        return None
    learned = cancel_probe.load_machine(path)
    states = 1 + max([u for e in learned[1] for u in e[:2]] + [0])
    plain = [""] * 12
    plain[4] = "r"
    after = cancel_probe.end_state(learned, plain)
    # A cancel on step 2 (before red) or on step 7 (after it).
    split = False
    for step in (1, 6):
        cancelled = list(plain)
        cancelled[step] = "c"
        split |= cancel_probe.end_state(learned, cancelled) != after
    return states, split


def reported(run, seed):
    try:
        rows = rundata.table(run, "final_policy.csv")
    except FileNotFoundError:
        return None
    chosen = [r for r in rows if r["algo"] == "smirl" and r["seed"] == seed and r["chosen"] == "1"]
    return float(chosen[0]["success_rate"]) if chosen else None


def setting(run):
    name = os.path.basename(os.path.normpath(run))
    parts = name.split("-")
    return "-".join(p for p in parts if not p.startswith("seeds"))


def base_seed(run):
    m = re.search(r"seeds(\d+)", os.path.basename(os.path.normpath(run)))
    return int(m[1]) if m else 3


def prepare(binary, task, base, config, out):
    """`reacher prepare` of `task` at `base` with `config` (relative to this directory) into
    `out`: the demonstrations and learned machine of every sweep with them."""
    subprocess.run([binary, "prepare", "--task", task, "--algo", "smirl", "--seed", str(base),
                    "--seeds", "1", "--config", os.path.join(HERE, config), "--out", out,
                    "--quiet"], check=True, stdout=subprocess.DEVNULL)
    return out


def prepared_machines(binary, tmp):
    """{base: its OR machine's prepared run directory} for the held-out bases."""
    return {b: prepare(binary, "or", b, PREDICTED, os.path.join(tmp, f"or-{b}")) for b in BASES}


def machines_table(binary, tmp):
    """Per task and setting: learned states, the bases whose machine splits red by the cancel,
    and (IF, Composite) the bases with cancel holes, over MACHINE_BASES; markdown."""
    lines = ["| task | setting | learned states | splits red by the cancel | with cancel holes |",
             "|---|---|---|---|---|"]
    for task in ["or", "sequential", "if", "composite"]:
        for name, config in MACHINE_SETTINGS:
            states, splits, holed = [], [], []
            for b in MACHINE_BASES:
                out = prepare(binary, task, b, config, os.path.join(tmp, f"{len(lines)}-{b}"))
                n, split = machine(out)
                states.append(n)
                if split:
                    splits.append(b)
                if task in ("if", "composite") and cancel_probe.probe(out)[2]:
                    holed.append(b)
            count = lambda bases: f"{len(bases)} of {len(MACHINE_BASES)}" + (f": {' '.join(map(str, bases))}" if bases else "")
            lines.append(f"| {task} | {name} | {min(states)}–{max(states)} | {count(splits)} | "
                         f"{count(holed) if task in ('if', 'composite') else '–'} |")
    return "\n".join(lines) + "\n"


def main(argv):
    if argv and argv[0] in ("--heldout", "--fresh", "--tuning", "--machines"):
        binary = argv[1] if len(argv) > 1 else os.path.join(HERE, "..", "..", "target", "release", "reacher")
        if not os.path.isfile(binary):
            sys.exit(f"half_plateaus.py: {binary}: no such program (cargo build --release, or pass REACHER_BIN)")
        if argv[0] == "--machines":
            with tempfile.TemporaryDirectory() as tmp:
                print(machines_table(binary, tmp), end="")
            return
        if argv[0] in ("--tuning", "--fresh"):
            runs = TUNING if argv[0] == "--tuning" else FRESH
            with tempfile.TemporaryDirectory() as tmp:
                machines = {run: machine(prepare(binary, task, base, config,
                                                 os.path.join(tmp, os.path.basename(run))))
                            for run, task, base, config in runs}
                print(report([run for run, *_ in runs], machines.get), end="")
            return
        with tempfile.TemporaryDirectory() as tmp:
            machines = prepared_machines(binary, tmp)
            out = report(HELDOUT, lambda run: machine(machines[base_seed(run)]))
        print(HEADER + out, end="")
        return
    if not argv or argv[0].startswith("-"):
        sys.exit(__doc__)
    print(report(argv, machine), end="")


def report(runs, machine_of):
    """The per-job table and the per-setting counts of `runs`, as markdown."""
    lines = ["| run | seed | learned states | splits red by the cancel | solved | half | last | reported |",
             "|---|---|---|---|---|---|---|---|"]
    totals = collections.OrderedDict()
    for run in runs:
        rows = [r for r in rundata.metrics(run) if r["algo"] == "smirl"]
        shape = machine_of(run)
        for seed in sorted({r["seed"] for r in rows}, key=int):
            success = [float(r["success_rate"]) for r in
                       sorted((r for r in rows if r["seed"] == seed), key=lambda r: int(r["iteration"]))]
            first = next((i for i, s in enumerate(success) if s >= SOLVED), len(success))
            solved = sum(s >= SOLVED for s in success)
            half = sum(HALF[0] <= s <= HALF[1] for s in success[first:])
            final = reported(run, seed)
            t = totals.setdefault(setting(run), [0, 0, 0, 0, 0])
            t[0] += 1
            t[1] += half > 0
            t[2] += HALF[0] <= success[-1] <= HALF[1]
            t[3] += final is not None and HALF[0] <= final <= HALF[1]
            t[4] += final is not None and final < SOLVED
            lines.append(f"| {os.path.basename(os.path.normpath(run))} | {seed} | "
                         f"{shape[0] if shape else '–'} | "
                         f"{('yes' if shape[1] else 'no') if shape else '–'} | {solved} | {half} | "
                         f"{success[-1]:.2f} | {'–' if final is None else f'{final:.2f}'} |")
    lines.append("")
    lines.append("| setting | jobs | with a half plateau | last iteration on one | reported policy on one | reported < 0.9 |")
    lines.append("|---|---|---|---|---|---|")
    for name, (jobs, any_half, last_half, reported_half, failed) in totals.items():
        lines.append(f"| {name} | {jobs} | {any_half} | {last_half} | {reported_half} | {failed} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main(sys.argv[1:])

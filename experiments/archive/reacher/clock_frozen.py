#!/usr/bin/env python3
"""The clock's control (issue 13; ablations/clock_frozen.toml, `smirl_clock_frozen = true`): the
seven held-out IF and Composite jobs the clock solved and the reset-agent standard missed, run
with the clock's entry held at 1 — the same input width and networks, no time.

The reading, fixed in clock_frozen.toml before the runs: 5 or more of 7 solved frozen, the
clock's gain is not shown to be its time; 2 or fewer, the time solved them; 3 or 4, undecided.

Usage: python3 experiments/reacher/clock_frozen.py [--run] [REACHER_BIN]
  --run   run the jobs not yet run (run dirs heldout/clock_frozen-seeds<B>-<task>), two at a time
  (none)  the table for results.md: per job, the reset-agent standard's reported policy, the
          clock's and the frozen clock's; the count solved and the reading
REACHER_BIN defaults to target/release/reacher.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import clock  # noqa: E402
import job_reruns  # noqa: E402
import rundata  # noqa: E402
import reset_agent  # noqa: E402
import selection_cut  # noqa: E402

CONFIG = os.path.join(clock.HERE, "ablations", "clock_frozen.toml")
# (task, base, SAC seed): the held-out jobs the clock gained over the reset-agent standard
# (clock.py's table, 7 gained and 0 lost), named in clock_frozen.toml before its runs.
GAINED = [("if", 3, 5), ("if", 78, 78), ("composite", 3, 3), ("composite", 6, 6),
          ("composite", 27, 29), ("composite", 30, 30), ("composite", 39, 40)]
RERUNS = job_reruns.Reruns(CONFIG, "clock_frozen", "clock_frozen", "clock frozen")


def table():
    solved = reset_agent.solved
    lines = ["| task | base | SAC seed | reset-agent standard | with the clock | "
             "with the clock frozen (chosen: agent, candidate) |", "|---|---|---|---|---|---|"]
    run = frozen_solved = 0
    for task, base, seed in GAINED:
        frozen = RERUNS.candidates("heldout", task, base, seed)
        if frozen is None:
            continue
        run += 1
        frozen_solved += solved(frozen)
        cells = [selection_cut.rate(rundata.chosen(rows), task) for rows in
                 (reset_agent.reset_candidates("heldout", task, base, seed),
                  clock.clock_candidates("heldout", task, base, seed))]
        chosen = rundata.chosen(frozen)
        lines.append(f"| {task} | {base} | {seed} | {cells[0]} | {cells[1]} | "
                     f"{selection_cut.rate(chosen, task)} "
                     f"({chosen.get('agent', 'co-trained')}, {chosen['candidate']}) |")
    if run < len(GAINED):
        reading = f"not yet read ({run} of {len(GAINED)} run)"
    elif frozen_solved >= 5:
        reading = "the clock's gain is not shown to be its time"
    elif frozen_solved <= 2:
        reading = "the time solved them"
    else:
        reading = "undecided"
    return "\n".join(lines) + (f"\n\nSolved with the clock frozen: {frozen_solved} of {run} "
                               f"(with the clock: {run} of {run}). Reading: {reading}.\n")


def main(argv):
    run = bool(argv) and argv[0] == "--run"
    argv = argv[1:] if run else argv
    if argv and argv[0].startswith("-"):
        sys.exit(__doc__)
    binary = argv[0] if argv else os.path.join(clock.HERE, "..", "..", "target", "release",
                                               "reacher")
    if run:
        if not os.path.isfile(binary):
            sys.exit(f"clock_frozen.py: {binary}: no such program (cargo build --release)")
        RERUNS.run(binary, [("heldout", t, b, s) for t, b, s in GAINED])
    else:
        print(table(), end="")


if __name__ == "__main__":
    main(sys.argv[1:])

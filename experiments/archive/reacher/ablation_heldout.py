#!/usr/bin/env python3
"""Ablations of SMIRL's settings against the replay-all standard (ablations/replay_all.toml, the
standard before fallback starts), job for job. Per task and base seed B where a run of any named
setting exists under heldout/ (heldout/<prefix>-seedsB-<task>), the reported policy of each SAC
seed B, B+1, B+2 under the standard and each setting ("-": no run); then the tuning jobs (base
0, SAC seeds 0-5: ablations/runs/<name>-seeds0to5-<task>), for the tasks a setting ran. A
setting whose machine or jobs are the standard's at a base was not rerun there. A job counts as
solved when its reported policy reaches 0.9 (IF and Composite: on each branch). Markdown on
standard output.

Settings, by their config's name in ablations/: unseen_touch_sink and sink_after_events (the
sink of unseen touches, runs unseen-sink-* and sink-after-events-*), fallback_starts (LRM's
fallback starts, runs fallback-starts-*), initial_events (with them, initial events, runs
initial-events-*).

Usage: python3 experiments/reacher/ablation_heldout.py NAME..."""
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import rundata  # noqa: E402
from standard_heldout import cell  # noqa: E402

TASKS = ["or", "sequential", "if", "composite"]
# (column, held-out run prefix, tuning run prefix)
STANDARD = ("replay-all standard", "replay-all", "replay_all")
KNOWN = {"unseen_touch_sink": ("sink everywhere", "unseen-sink", "unseen_touch_sink"),
         "sink_after_events": ("sink after events", "sink-after-events", "sink_after_events"),
         "fallback_starts": ("fallback starts", "fallback-starts", "fallback_starts"),
         "initial_events": ("initial events", "initial-events", "initial_events")}


def jobs_cell(run_dir, task, totals, key):
    """'1.00 (1.00/1.00), ... (k/n)' of the run's SMIRL jobs, '-' when it has none."""
    jobs = rundata.final_policy(run_dir)
    cells = [cell(task, jobs[("smirl", s)]) for a, s in sorted(jobs) if a == "smirl"]
    if not cells:
        return "-"
    solved = sum(ok for _, ok in cells)
    done, total = totals.get(key, (0, 0))
    totals[key] = (done + solved, total + len(cells))
    return f"{', '.join(t for t, _ in cells)} ({solved}/{len(cells)})"


def table(title, settings, rows, totals):
    head = "| task | base | " + " | ".join(c for c, _, _ in settings) + " |"
    out = [title, "", head, "|---|---|" + "---|" * len(settings)] + rows + [""]
    parts = []
    for t in TASKS:
        got = [f"{c} {totals[(t, c)][0]} of {totals[(t, c)][1]}" for c, _, _ in settings
               if (t, c) in totals]
        if got:
            parts.append(f"{t}: " + ", ".join(got))
    out.append("Solved, over the jobs shown: " + "; ".join(parts) + ".")
    return "\n".join(out) + "\n"


def main():
    names = sys.argv[1:]
    if not names or any(n not in KNOWN for n in names):
        sys.exit(__doc__)
    settings = [STANDARD] + [KNOWN[n] for n in names]
    heldout = os.path.join(HERE, "heldout")
    prefixes = "|".join(re.escape(p) for _, p, _ in settings[1:])
    found = set()
    for name in rundata.runs(heldout, "final_policy.csv"):
        m = re.fullmatch(rf"(?:{prefixes})-seeds(\d+)-(or|sequential|if|composite)", name)
        if m:
            found.add((m[2], int(m[1])))
    rows, totals = [], {}
    for task in TASKS:
        for base in sorted(b for t, b in found if t == task):
            cells = [jobs_cell(os.path.join(heldout, f"{p}-seeds{base}-{task}"), task, totals,
                               (task, c)) for c, p, _ in settings]
            rows.append(f"| {task} | {base} | " + " | ".join(cells) + " |")
    print(table("Held out (reported policy per SAC seed; IF, Composite: normal/cancel)",
                settings, rows, totals))
    rows, totals = [], {}
    ablations = os.path.join(HERE, "ablations", "runs")
    for task in TASKS:
        counted = {}
        cells = [jobs_cell(os.path.join(ablations, f"{p}-seeds0to5-{task}"), task, counted,
                           (task, c)) for c, _, p in settings]
        if any(c != "-" for c in cells[1:]):
            rows.append(f"| {task} | 0 (SAC seeds 0-5) | " + " | ".join(cells) + " |")
            totals.update(counted)
    print(table("Tuning (base 0, SAC seeds 0-5)", settings, rows, totals), end="")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Every start of a protocol's jobs and how each ended, from its ledger; no score.

    python3 experiments/protocol/job_history.py NAME [--failed | --cut]

One row per start: the job (run directory, algorithm, seed), the start's time and attempt, and its
end: `done`; `failed` with the ledger's reason; `killed` by a signal run.py passed on (the job
reruns); or `cut`: no end entry before the next session's first entry, so the session ended under
it (a machine that kills its processes at a session's end gives run.py no signal to record). The
last session's open starts are `running`. A job failed without a start of its own (its prepare
failed, or it had used its three starts) gets a row with no start.

`--failed` keeps the jobs whose last outcome is `failed`; `--cut` the jobs with a start that a
session's end cut. It reads only the ledger's events, so it can run while a protocol is blinded:
the failed jobs' table beside a protocol's results, and which jobs are on a second or third start.
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import run as protocol  # noqa: E402

ENDS = ("done", "failed", "killed")


def history(entries):
    """[row] in ledger order, each {dir, algo, seed, start, attempt, end, outcome, why}."""
    rows, open_starts, session_at = [], {}, None
    for e in entries:
        event = e.get("event")
        if event == "session":
            for row in open_starts.values():
                row["outcome"] = "cut"
                row["why"] = f"the session that began at {session_at} ended under it; the next began at {e.get('at')}"
            open_starts = {}
            session_at = e.get("at")
        elif event == "start":
            row = {"dir": e["dir"], "algo": e["algo"], "seed": e["seed"], "start": e.get("at"),
                   "attempt": e.get("attempt"), "end": None, "outcome": "running", "why": ""}
            open_starts[protocol.job_key(e)] = row
            rows.append(row)
        elif event in ENDS:
            row = open_starts.pop(protocol.job_key(e), None)
            if row is None:
                row = {"dir": e["dir"], "algo": e["algo"], "seed": e["seed"], "start": None,
                       "attempt": None}
                rows.append(row)
            row["end"] = e.get("at")
            row["outcome"] = event
            row["why"] = e.get("why", f"signal {e['signal']}" if event == "killed" else "")
    return rows


def select(rows, failed, cut):
    """The rows of the jobs `--failed` or `--cut` keeps (all rows of each kept job)."""
    if not (failed or cut):
        return rows
    last, any_cut = {}, set()
    for r in rows:
        key = protocol.job_key(r)
        last[key] = r["outcome"]
        if r["outcome"] == "cut":
            any_cut.add(key)
    keep = {k for k, o in last.items() if o == "failed"} if failed else any_cut
    return [r for r in rows if protocol.job_key(r) in keep]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--failed", action="store_true", help="only jobs whose last outcome is failed")
    which.add_argument("--cut", action="store_true", help="only jobs with a start a session's end cut")
    args = p.parse_args()
    path = protocol.ledger_path(args.name)
    if not os.path.isfile(path):
        sys.exit(f"job_history: {protocol.rel(path)} does not exist: no ledger for {args.name}")
    rows = select(history(protocol.read_ledger(args.name)), args.failed, args.cut)
    print("| run directory | algorithm | seed | start (UTC) | attempt | end (UTC) | outcome | why |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        cells = [os.path.basename(r["dir"]), r["algo"], r["seed"], r["start"] or "—",
                 r["attempt"] if r["attempt"] is not None else "—", r["end"] or "—", r["outcome"], r["why"]]
        print("| " + " | ".join(str(c) for c in cells) + " |")
    print(f"\n{len(rows)} starts or outcomes of {len({protocol.job_key(r) for r in rows})} jobs")


if __name__ == "__main__":
    main()

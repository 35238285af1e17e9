#!/usr/bin/env python3
"""Writes the committed (lean) forms of run results from the run directories on disk
(experiments/README.md says what is tracked and why). Deterministic: the same run directories
give the same bytes. Run it after a sweep, before `git add`:

    python3 experiments/consolidate.py

It writes
  reacher/heldout/metrics.csv.gz       every held-out run's metrics.csv (heldout/<run>/) in one
                                       file, with a first column `run`
  reacher/heldout/final_policy.csv.gz  every held-out run's final_policy.csv (SMIRL's
                                       final-policy phase) the same way
  reacher/runs/final_policy.csv        every reacher/runs/<run>/final_policy.csv, the same way
  reacher/ablations/runs/summary.csv   every ablation run's summary.csv, with a first column `run`
  reacher/ablations/runs/metrics.csv.gz  every ablation run's metrics.csv since issue 13 (the
                                       earlier ones were not kept), the same way
  reacher/ablations/runs/final_policy.csv  every ablation run's final_policy.csv, the same way
  office/runs<TAG>/summary.csv         the five tasks' runs<TAG>/t<N>/summary.csv of each Office
                                       experiment (their first column is already `task`)
  <run>/metrics.csv.gz                 `gzip -n -9` of <run>/metrics.csv for the long runs in
                                       reacher/runs/: blue-firl*, *-schedules, *-rkl_expert (f-IRL's schedule,
                                       800 IRL iterations per job)

A consolidated file keeps the rows of the runs that are not on disk (a clone has only the
consolidated file) and replaces those of the runs that are; runs are sorted by name, each
run's rows in its file's order; the header is the union of the runs' columns in order of first
appearance (a column a run did not have is empty, as the programs leave a column blank for
jobs run before it existed). experiments/reacher/rundata.py reads them back.
Usage: python3 experiments/consolidate.py [--check] [--exclude GLOB]...
  --check    write nothing; exit 1 if a file would change (experiments/lean_check.sh runs it)
  --exclude  neither read nor write the run directories (and files) matching GLOB, relative to
             experiments/ (e.g. 'reacher/runs/*-schedules'): runs a sweep is still writing"""
import csv
import fnmatch
import glob
import gzip
import io
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
LONG_RUNS = ["reacher/runs/blue-firl*", "reacher/runs/*-schedules", "reacher/runs/*-rkl_expert"]


def read_csv(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rt", newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        return header, list(reader)


def merged(target, sources):
    """Text of the consolidated CSV `target`: its current rows for runs not in `sources`
    ({run: path of its CSV}), the sources' rows for the others."""
    runs = {}
    if os.path.isfile(target):
        header, rows = read_csv(target)
        for row in rows:
            runs.setdefault(row[0], (header[1:], []))[1].append(row[1:])
    for run, path in sources.items():
        runs[run] = read_csv(path)
    columns = []
    for header, _ in runs.values():
        columns += [c for c in header if c not in columns]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["run"] + columns)
    for run in sorted(runs):
        header, rows = runs[run]
        for row in rows:
            cell = dict(zip(header, row))
            w.writerow([run] + [cell.get(c, "") for c in columns])
    return out.getvalue()


def gzip_bytes(data):
    return subprocess.run(["gzip", "-n", "-9", "-c"], input=data, capture_output=True, check=True).stdout


def outputs(excluded):
    """(path, bytes) of every file this script writes; `excluded(path)`: leave it alone (an
    output), or do not read it (a run directory)."""
    def sources(parent, name):
        return {n: os.path.join(parent, n, name) for n in sorted(os.listdir(parent))
                if os.path.isfile(os.path.join(parent, n, name)) and not n.endswith(".partial")
                and not excluded(os.path.join(parent, n))}
    heldout = os.path.join(HERE, "reacher/heldout")
    target = os.path.join(heldout, "metrics.csv.gz")
    yield target, gzip_bytes(merged(target, sources(heldout, "metrics.csv")).encode())
    target = os.path.join(heldout, "final_policy.csv.gz")
    yield target, gzip_bytes(merged(target, sources(heldout, "final_policy.csv")).encode())
    runs = os.path.join(HERE, "reacher/runs")
    target = os.path.join(runs, "final_policy.csv")
    yield target, merged(target, sources(runs, "final_policy.csv")).encode()
    ablations = os.path.join(HERE, "reacher/ablations/runs")
    target = os.path.join(ablations, "summary.csv")
    yield target, merged(target, sources(ablations, "summary.csv")).encode()
    target = os.path.join(ablations, "metrics.csv.gz")
    yield target, gzip_bytes(merged(target, sources(ablations, "metrics.csv")).encode())
    target = os.path.join(ablations, "final_policy.csv")
    yield target, merged(target, sources(ablations, "final_policy.csv")).encode()
    for runs in sorted(glob.glob(os.path.join(HERE, "office/runs*/"))):
        tasks = sorted(glob.glob(os.path.join(runs, "t[0-9]/summary.csv")))
        target = os.path.join(runs, "summary.csv")
        if tasks:
            text = open(tasks[0]).readline()
            for t in tasks:
                text += "".join(open(t).readlines()[1:])
            yield target, text.encode()
    for pattern in LONG_RUNS:
        for run in sorted(glob.glob(os.path.join(HERE, pattern))):
            if excluded(run):
                continue
            plain = os.path.join(run, "metrics.csv")
            if os.path.isfile(plain):
                yield plain + ".gz", gzip_bytes(open(plain, "rb").read())


def main():
    args, check, exclude = sys.argv[1:], False, []
    while args:
        if args[0] == "--check":
            check, args = True, args[1:]
        elif args[0] == "--exclude" and len(args) > 1:
            exclude, args = exclude + [args[1]], args[2:]
        else:
            sys.exit(__doc__)
    def excluded(path):
        rel = os.path.relpath(path, HERE)
        return any(fnmatch.fnmatch(rel, p) or fnmatch.fnmatch(os.path.dirname(rel), p) for p in exclude)

    changed = []
    for path, data in list(outputs(excluded)):
        rel = os.path.relpath(path, HERE)
        if excluded(path):
            continue
        if os.path.isfile(path) and open(path, "rb").read() == data:
            continue
        changed.append(rel)
        if not check:
            with open(path + ".tmp", "wb") as f:
                f.write(data)
            os.replace(path + ".tmp", path)
    for p in changed:
        print(("would change " if check else "wrote ") + "experiments/" + p)
    sys.exit(1 if check and changed else 0)


if __name__ == "__main__":
    main()

"""Reads a run directory's tables the same way whether the run is on disk in full or only in
its committed (lean) form (experiments/README.md): `<run>/<name>` (what the programs write),
else `<run>/<name>.gz` (a long run's committed copy, `gzip -n -9`), else the rows of that run
in the consolidated file of its parent directory, `<parent>/<name>` or `<parent>/<name>.gz`,
whose first column `run` names the run directory (written by experiments/consolidate.py:
heldout/metrics.csv.gz, ablations/runs/summary.csv). A run directory on disk always wins over
the consolidated rows. Rows are dicts of the CSV's text fields, as csv.DictReader gives them;
a consolidated file holds the union of its runs' columns, a column a run did not have is ''."""
import csv
import gzip
import io
import os


def _open(path):
    if path.endswith(".gz"):
        return io.TextIOWrapper(gzip.open(path), encoding="utf-8", newline="")
    return open(path, newline="")


def _first(paths):
    return next((p for p in paths if os.path.isfile(p)), None)


def consolidated(parent, name):
    """{run: [rows]} of the consolidated file `<parent>/<name>[.gz]` ({} when there is none),
    runs in file order."""
    path = _first([os.path.join(parent, name), os.path.join(parent, name + ".gz")])
    runs = {}
    if path:
        with _open(path) as f:
            for r in csv.DictReader(f):
                runs.setdefault(r.pop("run"), []).append(r)
    return runs


def table(run_dir, name):
    """The rows of `<run_dir>/<name>` (see the module doc); FileNotFoundError when neither the
    run directory nor its parent's consolidated file has them."""
    run_dir = os.path.normpath(run_dir)
    path = _first([os.path.join(run_dir, name), os.path.join(run_dir, name + ".gz")])
    if path:
        with _open(path) as f:
            return list(csv.DictReader(f))
    parent, run = os.path.split(run_dir)
    rows = consolidated(parent, name).get(run)
    if rows is None:
        raise FileNotFoundError(f"{run_dir}/{name}: neither the run's file nor a consolidated row")
    return rows


def has(run_dir, name):
    """Whether `table(run_dir, name)` finds the run's own file (not the consolidated rows)."""
    return _first([os.path.join(run_dir, name), os.path.join(run_dir, name + ".gz")]) is not None


def runs(parent, name):
    """Names of the run directories under `parent` that have `name`: on disk (ending in
    `.partial` excluded) or in the consolidated file; unsorted."""
    names = set(consolidated(parent, name))
    if os.path.isdir(parent):
        names.update(n for n in os.listdir(parent)
                     if not n.endswith(".partial") and has(os.path.join(parent, n), name))
    return list(names)


def metrics(run_dir):
    return table(run_dir, "metrics.csv")


def summary(run_dir):
    return table(run_dir, "summary.csv")


def last_quarter(job_rows):
    """Mean ground-truth success of one job over the last quarter of its IRL iterations: the
    iterations k > n - n // 4 of a job with iterations 0..n (iteration 0 is the untrained policy)."""
    n = max(int(r["iteration"]) for r in job_rows)
    tail = [float(r["success_rate"]) for r in job_rows if int(r["iteration"]) > n - n // 4]
    return sum(tail) / len(tail)


def final_policy(run_dir):
    """{(algo, seed): candidate rows in order} of the run's final-policy phase
    (`final_policy.csv`, SMIRL with `smirl_final_sac_steps` > 0; candidate 0 is the co-trained
    policy, the reported one has chosen = 1); {} for a run without one."""
    try:
        rows = table(run_dir, "final_policy.csv")
    except FileNotFoundError:
        return {}
    jobs = {}
    for r in rows:
        jobs.setdefault((r["algo"], int(r["seed"])), []).append(r)
    return jobs


def chosen(candidates):
    """The reported candidate of one job's final-policy phase."""
    return next(r for r in candidates if r["chosen"] == "1")

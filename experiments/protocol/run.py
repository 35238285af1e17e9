#!/usr/bin/env python3
"""Runs a preregistered evaluation job by job, resumably, from its committed protocol.

A protocol is two committed files: `experiments/protocol/<name>.md` (what is measured and why,
for people) and `experiments/protocol/<name>.toml` (the same plan for this script):

    commit = "<40 hex digits>"        # the frozen method; every job's binary must be built from it
    config = "experiments/reacher/config.toml"
    bases = [5000, 5010, ...]          # base seeds never used before the protocol's commit

    [[arm]]                            # one or more
    name = "smirl"                     # the arm's name in the tables
    tasks = ["or", "sequential"]       # shipped names or task-file paths
    algos = ["smirl"]
    n_bases = 10                       # the first n_bases of `bases`
    seeds = 3                          # SAC seeds B, B+1, ... of each base B
    config = "..."                     # optional: this arm's config instead of the protocol's

Usage:
    python3 experiments/protocol/run.py check NAME [--bin REACHER]
    python3 experiments/protocol/run.py run NAME [--bin REACHER] [--until HH:MM] [--max-jobs N]
    python3 experiments/protocol/run.py status NAME

`check` refuses to go on unless both files are committed and unchanged, the binary was built
from the frozen commit (the commit `reacher prepare` records), no run directory of the
protocol exists yet, and no seed of it appears in a run directory under runs/ or in a committed
CSV under experiments/. `run` prepares each (arm config, task, base) run directory under
`runs/protocol/<name>/` and runs its missing jobs one at a time in the protocol's order (a
finished job is never rerun, so an interrupted run resumes where it stopped); `--until` starts
no job after that time of day (UTC), so a session can end between jobs. `status` counts the
finished jobs. The tables come from `experiments/protocol/table.py`.
"""

import argparse
import csv
import datetime
import gzip
import hashlib
import json
import os
import subprocess
import sys
import tomllib

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def fail(msg):
    print(f"protocol: {msg}", file=sys.stderr)
    sys.exit(2)


def git(*args):
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)


def load(name):
    md = f"experiments/protocol/{name}.md"
    spec = f"experiments/protocol/{name}.toml"
    for f in (md, spec):
        if not os.path.isfile(os.path.join(ROOT, f)):
            fail(f"{f} does not exist")
    try:
        with open(os.path.join(ROOT, spec), "rb") as fh:
            plan = tomllib.load(fh)
    except tomllib.TOMLDecodeError as e:
        fail(f"{spec}: {e}")
    for key in ("commit", "config", "bases", "arm"):
        if key not in plan:
            fail(f"{spec}: missing key `{key}`")
    commit = plan["commit"]
    if not (isinstance(commit, str) and len(commit) == 40 and all(c in "0123456789abcdef" for c in commit)):
        fail(f"{spec}: `commit` must be a full 40-digit commit, got {commit!r}")
    bases = plan["bases"]
    if not bases or len(set(bases)) != len(bases) or not all(isinstance(b, int) and b >= 0 for b in bases):
        fail(f"{spec}: `bases` must be distinct non-negative integers")
    for i, arm in enumerate(plan["arm"]):
        for key in ("name", "tasks", "algos", "n_bases", "seeds"):
            if key not in arm:
                fail(f"{spec}: arm {i + 1} is missing `{key}`")
        if not 1 <= arm["n_bases"] <= len(bases):
            fail(f"{spec}: arm {arm['name']}: n_bases must be in 1..={len(bases)}")
        if not 1 <= arm["seeds"] <= 16:
            fail(f"{spec}: arm {arm['name']}: seeds must be in 1..=16")
    return md, spec, plan


def committed_unchanged(path):
    if git("ls-files", "--error-unmatch", path).returncode != 0:
        return False
    return git("diff", "--quiet", "HEAD", "--", path).returncode == 0


def run_key(config):
    """A short name for a config file's contents (arms with their own config get their own run
    directories)."""
    with open(os.path.join(ROOT, config), "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()[:8]


def task_label(task):
    return os.path.splitext(os.path.basename(task))[0]


def plan_runs(name, plan):
    """Every run directory (config, task, base, algos, seeds) and job (run, algo, seed), in the
    order they run: base by base, so that a partial evaluation covers every task and arm."""
    runs = {}
    jobs = []
    for j, base in enumerate(plan["bases"]):
        for arm in plan["arm"]:
            if j >= arm["n_bases"]:
                continue
            config = arm.get("config", plan["config"])
            for task in arm["tasks"]:
                key = (config, task, base)
                d = os.path.join(
                    ROOT, "runs", "protocol", name, f"{task_label(task)}-b{base}-{run_key(config)}"
                )
                r = runs.setdefault(key, {"dir": d, "config": config, "task": task, "base": base, "algos": [], "seeds": 0})
                for algo in arm["algos"]:
                    if algo not in r["algos"]:
                        r["algos"].append(algo)
                    for s in range(arm["seeds"]):
                        jobs.append({"arm": arm["name"], "run": key, "algo": algo, "seed": base + s})
                r["seeds"] = max(r["seeds"], arm["seeds"])
    return runs, jobs


def recorded_commit(run_dir):
    with open(os.path.join(run_dir, "prepare.json")) as fh:
        return json.load(fh).get("git_commit")


def job_done(run_dir, algo, seed):
    return os.path.isfile(os.path.join(run_dir, "jobs", f"{algo}_seed{seed}.json"))


def used_seeds(skip):
    """Every seed a run directory under runs/ (outside `skip`) or a committed CSV under
    experiments/ (its `seed` column) records."""
    seen = {}
    for top, dirs, files in os.walk(os.path.join(ROOT, "runs")):
        if os.path.abspath(top).startswith(skip):
            dirs[:] = []
            continue
        if "prepare.json" in files:
            with open(os.path.join(top, "prepare.json")) as fh:
                for s in json.load(fh).get("seeds", []):
                    seen.setdefault(s, top)
    for f in git("ls-files", "experiments").stdout.split():
        if not (f.endswith(".csv") or f.endswith(".csv.gz")):
            continue
        opener = gzip.open if f.endswith(".gz") else open
        with opener(os.path.join(ROOT, f), "rt", newline="") as fh:
            rows = csv.reader(fh)
            header = next(rows, [])
            if "seed" not in header:
                continue
            k = header.index("seed")
            for row in rows:
                if k < len(row) and row[k].isdigit():
                    seen.setdefault(int(row[k]), f)
    return seen


def check(name, binary, before_run):
    md, spec, plan = load(name)
    for f in (md, spec):
        if not committed_unchanged(f):
            fail(f"{f} is not committed, or differs from HEAD: a protocol is committed before it runs")
    if git("merge-base", "--is-ancestor", plan["commit"], "HEAD").returncode != 0:
        fail(f"the frozen commit {plan['commit']} is not an ancestor of HEAD")
    if not os.access(binary, os.X_OK):
        fail(f"{binary}: no executable (build the frozen commit: see {md})")
    runs, jobs = plan_runs(name, plan)
    if before_run:
        existing = [r["dir"] for r in runs.values() if os.path.exists(r["dir"])]
        if existing:
            fail(f"{existing[0]} exists already: `check` is for before the first job")
        seen = used_seeds(os.path.join(ROOT, "runs", "protocol", name))
        clash = sorted({j["seed"] for j in jobs} & set(seen))
        if clash:
            fail(f"seed {clash[0]} of the protocol was used before: {seen[clash[0]]}")
    return plan, runs, jobs


def prepare(binary, r, commit):
    if os.path.isfile(os.path.join(r["dir"], "prepare.json")):
        got = recorded_commit(r["dir"])
        if got != commit:
            fail(f"{r['dir']} was prepared by {got}, not the frozen commit {commit}")
        return
    os.makedirs(os.path.dirname(r["dir"]), exist_ok=True)
    cmd = [
        binary, "prepare", "--task", r["task"], "--algo", ",".join(r["algos"]),
        "--seeds", str(r["seeds"]), "--seed", str(r["base"]), "--config", r["config"],
        "--out", r["dir"], "--quiet",
    ]
    print("+", " ".join(cmd), flush=True)
    if subprocess.run(cmd, cwd=ROOT).returncode != 0:
        fail(f"prepare failed for {r['dir']}")
    got = recorded_commit(r["dir"])
    if got != commit:
        fail(f"{binary} is built from {got}, not the frozen commit {commit} ({r['dir']} is left for inspection)")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("command", choices=["check", "run", "status"])
    p.add_argument("name")
    p.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "reacher"))
    p.add_argument("--until", help="start no job after this UTC time of day, HH:MM")
    p.add_argument("--max-jobs", type=int, default=None)
    args = p.parse_args()
    if args.command == "status":
        _, _, plan = load(args.name)
        runs, jobs = plan_runs(args.name, plan)
        done = sum(job_done(runs[j["run"]]["dir"], j["algo"], j["seed"]) for j in jobs)
        print(f"{done} of {len(jobs)} jobs finished")
        return
    plan, runs, jobs = check(args.name, args.bin, before_run=args.command == "check")
    if args.command == "check":
        print(f"protocol {args.name}: {len(runs)} run directories, {len(jobs)} jobs; ready")
        return
    until = None
    if args.until:
        h, m = (int(x) for x in args.until.split(":"))
        now = datetime.datetime.now(datetime.timezone.utc)
        until = now.replace(hour=h, minute=m, second=0, microsecond=0)
        if until <= now:
            until += datetime.timedelta(days=1)
    started = 0
    for j in jobs:
        r = runs[j["run"]]
        if os.path.isdir(r["dir"]) and job_done(r["dir"], j["algo"], j["seed"]):
            continue
        if until and datetime.datetime.now(datetime.timezone.utc) >= until:
            print(f"stopping before {j['algo']} seed {j['seed']} of {r['dir']}: --until {args.until}")
            break
        if args.max_jobs is not None and started >= args.max_jobs:
            break
        prepare(args.bin, r, plan["commit"])
        cmd = [args.bin, "job", "--run", r["dir"], "--algo", j["algo"], "--seed", str(j["seed"]), "--quiet"]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd, cwd=ROOT).returncode != 0:
            fail(f"job {j['algo']} seed {j['seed']} of {r['dir']} failed")
        started += 1
    done = sum(job_done(runs[j["run"]]["dir"], j["algo"], j["seed"]) for j in jobs if os.path.isdir(runs[j["run"]]["dir"]))
    print(f"{done} of {len(jobs)} jobs finished")


if __name__ == "__main__":
    main()

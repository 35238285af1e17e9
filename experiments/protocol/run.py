#!/usr/bin/env python3
"""Runs a preregistered evaluation job by job, resumably, from its committed protocol.

A protocol is two committed files: `experiments/protocol/<name>.md` (what is measured and why,
for people) and `experiments/protocol/<name>.toml` (the same plan for this script):

    commit = "<40 hex digits>"        # the frozen method; every job's binary is built from it
    config = "experiments/reacher/config.toml"
    bases = [...]                      # from `run.py draw-bases NAME`: never used before

    [[arm]]                            # one or more
    name = "smirl"                     # the arm's name in the tables
    tasks = ["or", "sequential"]       # shipped names or task-file paths
    algos = ["smirl"]
    n_bases = 10                       # the first n_bases of `bases`
    seeds = 3                          # SAC seeds B, B+1, ... of each base B
    config = "..."                     # optional: this arm's config instead of the protocol's

Usage:
    python3 experiments/protocol/run.py draw-bases NAME [--n 10] [--spacing 10]
    python3 experiments/protocol/run.py check NAME [--bin REACHER]
    python3 experiments/protocol/run.py run NAME [--bin REACHER] [--until HH:MM] [--max-jobs N]
    python3 experiments/protocol/run.py status NAME

`draw-bases` draws base seeds from a generator seeded by the protocol's name and the current
commit, so nobody picks them. `check`, once, before the first job: both protocol files are
committed and clean; the method's sources, the configs and the task files are the same at HEAD
as at the frozen commit; the binary says (`--version`) it was built from the frozen commit with
no local change; no seed of the protocol appears in any run directory on this machine
(`prepare.json` under /work, /tmp and the checkout's runs/) or in any version of any CSV
git has ever held (columns `seed` and `sac_seed`). It then writes the lock,
`experiments/protocol/<name>/lock.json` (the files' blob ids, the frozen commit, the binary's
`--version`), to be committed before the first `run`; a second `check` is refused while a lock
exists.

The protocol's state lives in git, not in run directories: an evaluation runs over several
sessions, each on a fresh checkout where runs/ is empty. `run` refuses without a committed lock,
or when the protocol files, the configs or the task files differ from what was locked, or when
the binary's `--version` does not name the frozen commit (without `-dirty`); it then prepares
each (config, task, base) run directory under `runs/protocol/<name>/` as needed (`prepare` is
deterministic, so a fresh checkout prepares the same directory again) and runs, one at a time,
base by base, every job the ledger does not record as finished. The ledger,
`experiments/protocol/<name>/ledger.jsonl`, is append-only and committed after each session:
every session's binary (its sha256 and `--version`), every job's start and end; a job's `done`
entry carries the job file's sha256 and everything `table.py` reads from it (`JOB_FIELDS`), so
the tables need no run directory. A job is finished when the ledger records it done or failed;
a job file present in runs/ without that entry is run again (`reacher job` returns its record
without training). A job that exits with an error is recorded as failed and never retried; a
job killed by a signal (a session ending) is rerun next time. `--until` starts no job after
that time of day (UTC).

The frozen binary on a fresh checkout: build it from a worktree at the frozen commit,
    git worktree add ../frozen <commit> && (cd ../frozen && cargo build --release)
    python3 experiments/protocol/run.py run NAME --bin ../frozen/target/release/reacher
Its sha256 is not the identity: the release profile keeps line tables, which name the
directory it was built in, so the same commit built in another checkout has other bytes. The
lock holds the commit, the binary's `--version` names it (and marks a build with local changes
`-dirty`), and the ledger records each session's sha256 for the record. The tables come from
`experiments/protocol/table.py`.
"""

import argparse
import csv
import datetime
import gzip
import hashlib
import io
import json
import os
import random
import subprocess
import sys
import tomllib

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
# Sources of the method: a protocol's HEAD must not differ from its frozen commit in these.
METHOD_PATHS = ["src", "assets", "mujoco-sys", "build.rs", "Cargo.toml", "Cargo.lock"]
# Where run directories of this machine are looked for (besides the checkout's runs/).
SEARCH_ROOTS = ["/work", "/tmp"]


def fail(msg):
    print(f"protocol: {msg}", file=sys.stderr)
    sys.exit(2)


def git(*args, text=True):
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=text)


def paths(name):
    return f"experiments/protocol/{name}.md", f"experiments/protocol/{name}.toml"


def run_root(name):
    """Where the run directories go: not committed, lost between sessions."""
    return os.path.join(ROOT, "runs", "protocol", name)


def state_dir(name):
    """Where the lock and the ledger go: committed (beside table.py's jobs.csv, summary.md)."""
    return os.path.join(ROOT, "experiments", "protocol", name)


def lock_path(name):
    return os.path.join(state_dir(name), "lock.json")


def ledger_path(name):
    return os.path.join(state_dir(name), "ledger.jsonl")


def rel(path):
    """A path as the ledger names it: relative to the checkout, which moves between sessions."""
    return os.path.relpath(path, ROOT)


def load(name):
    md, spec = paths(name)
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
    labels = {}
    for i, arm in enumerate(plan["arm"]):
        for key in ("name", "tasks", "algos", "n_bases", "seeds"):
            if key not in arm:
                fail(f"{spec}: arm {i + 1} is missing `{key}`")
        if not 1 <= arm["n_bases"] <= len(bases):
            fail(f"{spec}: arm {arm['name']}: n_bases must be in 1..={len(bases)}")
        if not 1 <= arm["seeds"] <= 16:
            fail(f"{spec}: arm {arm['name']}: seeds must be in 1..=16")
        for task in arm["tasks"]:
            other = labels.setdefault(task_label(task), task)
            if other != task:
                fail(f"{spec}: tasks {other} and {task} have the same name")
    ordered = sorted(bases)
    widest = max(arm["seeds"] for arm in plan["arm"])
    if any(b - a < widest for a, b in zip(ordered, ordered[1:])):
        fail(f"{spec}: bases closer than {widest} apart share SAC seeds")
    return md, spec, plan


def task_label(task):
    return os.path.splitext(os.path.basename(task))[0]


def configs_and_tasks(plan):
    files = {plan["config"]}
    for arm in plan["arm"]:
        files.add(arm.get("config", plan["config"]))
        files.update(t for t in arm["tasks"] if t.endswith(".toml"))
    return sorted(files)


def content_key(path):
    """A short name for a file's contents (arms with their own config get their own run
    directories)."""
    with open(os.path.join(ROOT, path), "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()[:8]


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
                d = os.path.join(run_root(name), f"{task_label(task)}-b{base}-{content_key(config)}")
                r = runs.setdefault(key, {"dir": d, "config": config, "task": task, "base": base, "algos": [], "seeds": 0})
                for algo in arm["algos"]:
                    if algo not in r["algos"]:
                        r["algos"].append(algo)
                    for s in range(arm["seeds"]):
                        jobs.append({"arm": arm["name"], "run": key, "algo": algo, "seed": base + s})
                r["seeds"] = max(r["seeds"], arm["seeds"])
    return runs, jobs


def job_file(run_dir, algo, seed):
    return os.path.join(run_dir, "jobs", f"{algo}_seed{seed}.json")


def sha256_of(path):
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def blob(path):
    return git("rev-parse", f"HEAD:{path}").stdout.strip()


def binary_version(binary):
    """(the binary's `--version` line, the commit it names)."""
    if not os.access(binary, os.X_OK):
        fail(f"{binary}: no executable (build the frozen commit)")
    out = subprocess.run([binary, "--version"], capture_output=True, text=True).stdout.strip()
    if "(commit " not in out:
        fail(f"{binary} --version names no commit: {out!r}")
    return out, out.split("(commit ", 1)[1].split(")", 1)[0]


# What a job's `done` entry keeps of its job file: the final-set scores (success, and per
# branch episodes and successes) of the loop's final policy and of every final-phase candidate,
# which one was chosen, and the wall time.


def score_of(evaluated):
    """[success_rate] or [success_rate, episodes_normal, successes_normal, episodes_cancel,
    successes_cancel] of a final-set evaluation (`None` stays `None`)."""
    if evaluated is None:
        return None
    b = evaluated.get("branches")
    if not b:
        return [evaluated["success_rate"]]
    return [evaluated["success_rate"], b["episodes"][0], b["successes"][0], b["episodes"][1], b["successes"][1]]


def job_fields(record):
    """The compact summary of a job file that the ledger keeps (JOB_FIELDS)."""
    final = record.get("final_policy")
    out = {"loop": score_of(record.get("loop_final_set")), "wall_secs": record.get("wall_secs")}
    if final:
        out["chosen"] = final["chosen"]
        out["candidates"] = [score_of(c.get("final_set")) for c in final["candidates"]]
    return out


JOB_FIELDS = ("loop", "wall_secs", "chosen", "candidates")


# Seeds used before ---------------------------------------------------------------------------


def seeds_in_csv(text):
    rows = csv.reader(io.StringIO(text))
    header = next(rows, [])
    cols = [k for k, h in enumerate(header) if h in ("seed", "sac_seed")]
    out = set()
    for row in rows:
        for k in cols:
            if k < len(row) and row[k].isdigit():
                out.add(int(row[k]))
    return out


def used_seeds(skip):
    """Every seed a run directory on this machine (outside `skip`) or any version of a CSV in
    git's history records, with where it was seen."""
    seen = {}
    roots = [os.path.join(ROOT, "runs"), *SEARCH_ROOTS]
    for root in roots:
        for top, dirs, files in os.walk(root):
            dirs[:] = [d for d in dirs if d not in (".git", "target", "node_modules", ".mirror", ".library")]
            if os.path.commonpath([os.path.abspath(top), skip]) == skip:
                dirs[:] = []
                continue
            if "prepare.json" in files:
                try:
                    with open(os.path.join(top, "prepare.json")) as fh:
                        for s in json.load(fh).get("seeds", []):
                            seen.setdefault(s, top)
                except (OSError, ValueError):
                    pass
    log = git("log", "--all", "--raw", "--no-abbrev", "--format=", "--", "*.csv", "*.csv.gz").stdout
    blobs = {}
    for line in log.splitlines():
        parts = line.split()
        if len(parts) >= 6 and not parts[3].startswith("0000000"):
            blobs.setdefault(parts[3], parts[-1])
    for sha, path in blobs.items():
        data = git("cat-file", "blob", sha, text=False).stdout
        if path.endswith(".gz"):
            try:
                data = gzip.decompress(data)
            except OSError:
                continue
        for s in seeds_in_csv(data.decode("utf-8", "replace")):
            seen.setdefault(s, f"{path} (blob {sha[:10]})")
    return seen


# Commands ------------------------------------------------------------------------------------


def draw_bases(name, n, spacing):
    head = git("rev-parse", "HEAD").stdout.strip()
    rng = random.Random(hashlib.sha256(f"{name} {head}".encode()).digest())
    # Blocks of `spacing` seeds in [10 000, 1 000 000): far from every range run by hand.
    blocks = rng.sample(range(10_000 // spacing, 1_000_000 // spacing), n)
    bases = [b * spacing for b in blocks]
    print(f"# drawn by `run.py draw-bases {name} --n {n} --spacing {spacing}` at {head}")
    print(f"bases = {bases}")


def check(name, binary):
    md, spec, plan = load(name)
    if os.path.exists(lock_path(name)) or git("cat-file", "-e", f"HEAD:{rel(lock_path(name))}").returncode == 0:
        fail(f"{rel(lock_path(name))} exists: `check` runs once, before the first job")
    if os.path.exists(ledger_path(name)):
        fail(f"{rel(ledger_path(name))} exists: `check` runs before the first job")
    for f in (md, spec):
        if git("ls-files", "--error-unmatch", f).returncode != 0 or git("diff", "--quiet", "HEAD", "--", f).returncode != 0:
            fail(f"{f} is not committed, or differs from HEAD: a protocol is committed before it runs")
    frozen = plan["commit"]
    if git("merge-base", "--is-ancestor", frozen, "HEAD").returncode != 0:
        fail(f"the frozen commit {frozen} is not an ancestor of HEAD")
    inputs = METHOD_PATHS + configs_and_tasks(plan)
    if git("diff", "--quiet", frozen, "HEAD", "--", *inputs).returncode != 0:
        fail(f"HEAD differs from the frozen commit in the method or its inputs (`git diff {frozen[:10]} HEAD -- {' '.join(inputs)}`)")
    if git("diff", "--quiet", "HEAD", "--", *inputs).returncode != 0:
        fail("the checkout has uncommitted changes in the method or its inputs")
    version, built = binary_version(binary)
    if built != frozen:
        fail(f"{binary} is built from {built}, not the frozen commit {frozen}")
    runs, jobs = plan_runs(name, plan)
    existing = [r["dir"] for r in runs.values() if os.path.exists(r["dir"])]
    if existing:
        fail(f"{existing[0]} exists already: nothing of a protocol runs before its check")
    seen = used_seeds(run_root(name))
    clash = sorted({j["seed"] for j in jobs} & set(seen))
    if clash:
        fail(f"seed {clash[0]} of the protocol was used before: {seen[clash[0]]}")
    os.makedirs(state_dir(name), exist_ok=True)
    lock = {
        "md_blob": blob(md), "toml_blob": blob(spec), "head": git("rev-parse", "HEAD").stdout.strip(),
        "frozen": frozen, "binary_version": version, "binary_sha256": sha256_of(binary),
        "inputs": {f: blob(f) for f in configs_and_tasks(plan)},
        "checked_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "jobs": len(jobs),
    }
    with open(lock_path(name), "x") as fh:
        json.dump(lock, fh, indent=1)
    print(f"protocol {name}: {len(runs)} run directories, {len(jobs)} jobs; locked in "
          f"{rel(lock_path(name))}: commit it before the first `run`")


def read_lock(name):
    path = rel(lock_path(name))
    if not os.path.isfile(lock_path(name)):
        fail(f"{path} does not exist: run `run.py check {name}` first")
    if git("ls-files", "--error-unmatch", path).returncode != 0 or git("diff", "--quiet", "HEAD", "--", path).returncode != 0:
        fail(f"{path} is not committed, or differs from HEAD: commit the lock before the first `run`")
    with open(lock_path(name)) as fh:
        return json.load(fh)


def ledger(name, entry):
    entry["at"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    with open(ledger_path(name), "a") as fh:
        fh.write(json.dumps(entry, separators=(",", ":")) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def read_ledger(name):
    path = ledger_path(name)
    if not os.path.isfile(path):
        return []
    entries = []
    with open(path) as fh:
        for n, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                entries.append(json.loads(line))
            except ValueError as e:
                if line.endswith("\n"):
                    fail(f"{rel(path)} line {n}: {e}")
                # A last line cut off by a session that died mid-write: its job was not done.
    return entries


def job_key(e):
    return e["dir"], e["algo"], e["seed"]


def finished_jobs(name):
    """{(run directory relative to the checkout, algo, seed): the ledger's `done` or `failed`
    entry}: the jobs that are not run again."""
    out = {}
    for e in read_ledger(name):
        if e.get("event") in ("done", "failed"):
            out[job_key(e)] = e
    return out


def prepare(binary, r, name, frozen):
    if os.path.isfile(os.path.join(r["dir"], "prepare.json")):
        return
    cmd = [
        binary, "prepare", "--task", r["task"], "--algo", ",".join(r["algos"]),
        "--seeds", str(r["seeds"]), "--seed", str(r["base"]), "--config", r["config"],
        "--out", r["dir"], "--quiet",
    ]
    print("+", " ".join(cmd), flush=True)
    ledger(name, {"event": "prepare", "dir": rel(r["dir"])})
    if subprocess.run(cmd, cwd=ROOT).returncode != 0:
        fail(f"prepare failed for {r['dir']}")
    with open(os.path.join(r["dir"], "prepare.json")) as fh:
        got = json.load(fh).get("git_commit")
    if got != frozen:
        fail(f"{r['dir']} was prepared by {got}, not the frozen commit {frozen}")


def run(name, binary, until, max_jobs):
    md, spec, plan = load(name)
    lock = read_lock(name)
    if (blob(md), blob(spec)) != (lock["md_blob"], lock["toml_blob"]) or git("diff", "--quiet", "HEAD", "--", md, spec).returncode != 0:
        fail(f"{md} or {spec} changed after the protocol was locked")
    inputs = configs_and_tasks(plan)
    if {f: blob(f) for f in inputs} != lock["inputs"] or git("diff", "--quiet", "HEAD", "--", *inputs).returncode != 0:
        fail(f"a config or task file of the protocol changed after it was locked ({' '.join(inputs)})")
    version, built = binary_version(binary)
    if built != lock["frozen"]:
        fail(f"{binary} is built from {built}, not the frozen commit {lock['frozen']} (see run.py's docs)")
    runs, jobs = plan_runs(name, plan)
    finished = finished_jobs(name)
    ledger(name, {"event": "session", "binary_sha256": sha256_of(binary), "binary_version": version})
    started = 0
    for j in jobs:
        r = runs[j["run"]]
        if (rel(r["dir"]), j["algo"], j["seed"]) in finished:
            continue
        if until and datetime.datetime.now(datetime.timezone.utc) >= until:
            print(f"stopping before {j['algo']} seed {j['seed']} of {r['dir']}: --until")
            break
        if max_jobs is not None and started >= max_jobs:
            break
        prepare(binary, r, name, plan["commit"])
        cmd = [binary, "job", "--run", r["dir"], "--algo", j["algo"], "--seed", str(j["seed"]), "--quiet"]
        print("+", " ".join(cmd), flush=True)
        entry = {"dir": rel(r["dir"]), "algo": j["algo"], "seed": j["seed"]}
        ledger(name, {"event": "start", **entry})
        code = subprocess.run(cmd, cwd=ROOT).returncode
        if code < 0:
            ledger(name, {"event": "killed", "signal": -code, **entry})
            fail(f"job {j['algo']} seed {j['seed']} of {r['dir']} was killed by signal {-code}; it reruns next time")
        if code != 0:
            ledger(name, {"event": "failed", "exit": code, **entry})
            print(f"job {j['algo']} seed {j['seed']} of {r['dir']} failed (exit {code}): recorded, not retried")
        else:
            path = job_file(r["dir"], j["algo"], j["seed"])
            with open(path, "rb") as fh:
                data = fh.read()
            fields = job_fields(json.loads(data))
            ledger(name, {"event": "done", "sha256": hashlib.sha256(data).hexdigest(), "job": fields, **entry})
        started += 1
    status(name)
    print(f"commit {rel(ledger_path(name))}: the next session resumes from it")


def status(name):
    _, _, plan = load(name)
    runs, jobs = plan_runs(name, plan)
    finished = finished_jobs(name)
    states = [finished.get((rel(runs[j["run"]]["dir"]), j["algo"], j["seed"]), {}).get("event") for j in jobs]
    print(f"{states.count('done')} of {len(jobs)} jobs done, {states.count('failed')} failed")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("command", choices=["draw-bases", "check", "run", "status"])
    p.add_argument("name")
    p.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "reacher"))
    p.add_argument("--until", help="start no job after this UTC time of day, HH:MM")
    p.add_argument("--max-jobs", type=int, default=None)
    p.add_argument("--n", type=int, default=10, help="draw-bases: how many")
    p.add_argument("--spacing", type=int, default=10, help="draw-bases: seeds per base block")
    args = p.parse_args()
    if args.command == "draw-bases":
        draw_bases(args.name, args.n, args.spacing)
    elif args.command == "check":
        check(args.name, args.bin)
    elif args.command == "status":
        status(args.name)
    else:
        until = None
        if args.until:
            h, m = (int(x) for x in args.until.split(":"))
            now = datetime.datetime.now(datetime.timezone.utc)
            until = now.replace(hour=h, minute=m, second=0, microsecond=0)
            if until <= now:
                until += datetime.timedelta(days=1)
        run(args.name, args.bin, until, args.max_jobs)


if __name__ == "__main__":
    main()

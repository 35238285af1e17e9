#!/usr/bin/env python3
"""Runs a preregistered evaluation job by job, resumably, from its committed protocol.

A protocol is two committed files: `experiments/protocol/<name>.md` (what is measured and why,
for people) and `experiments/protocol/<name>.toml` (the same plan for this script):

    commit = "<40 hex digits>"        # the frozen method; every job's binary is built from it
    config = "experiments/reacher/config.toml"
    bases = [...]                      # from `run.py draw-bases NAME`: never used before
    development = false                # optional: true marks a rehearsal on development seeds
    timeout_secs = { smirl = 3600 }    # every algorithm of the plan: a job running longer is
                                       # killed and counts as failed

    [[arm]]                            # one or more
    name = "smirl"                     # the arm's name in the tables
    tasks = ["or", "sequential"]       # shipped names or task-file paths
    algos = ["smirl"]
    n_bases = 10                       # the first n_bases of `bases`
    seeds = 3                          # SAC seeds B, B+1, ... of each base B
    tier = 1                           # optional, 1 (default), 2 or 3: the order of the plan
    config = "..."                     # optional: this arm's config instead of the protocol's

    [analysis]                         # optional; what table.py labels primary and secondary
    primary = "smirl:smirl"            # ARM:ALGO (or a list): P1, its chosen policy on every task
    paper = "smirl-paper:smirl-paper"  # the same: P2, primary's chosen minus this one's loop's own
    pools = { paper = ["or", "sequential", "if", "composite"] }   # P2 pooled over these tasks
    secondary = [["smirl:smirl", "baselines:maxent"]]             # paired comparisons
    control_failed = ["baselines:maxent"]  # optional: units that failed a positive control;
                                           # their secondary comparisons are not called

Usage:
    python3 experiments/protocol/run.py draw-bases NAME [--n 10] [--spacing 10]
    python3 experiments/protocol/run.py check NAME [--bin REACHER]
    python3 experiments/protocol/run.py run NAME [--bin REACHER] [--until HH:MM] [--max-jobs N]
                                                 [--parallel N]
    python3 experiments/protocol/run.py status NAME

`draw-bases` draws base seeds from a generator seeded by the protocol's name and the current
commit, so nobody picks them. `check`, once, before the first job: both protocol files are
committed and clean; the method's sources, the configs and the task files are the same at HEAD
as at the frozen commit; the binary says (`--version`) it was built from the frozen commit with
no local change; no SAC seed of a planned job (B..B+seeds-1 of each base B) appears in any run
directory on this machine (`prepare.json` under /work, /tmp and the checkout's runs/) or in any
version of any CSV git has ever held (columns `seed` and `sac_seed`). A protocol marked
`development = true` (a dress rehearsal on development seeds) skips that last check and says so;
any other protocol refuses a base below 10 000 (every seed below it is development data).
The files a task file makes a job read at run time (`task_reads`: its machine, its scene, and
every file git tracks in and below its directory and its scene's, such as its experts) are held
to the same rule; `check` refuses an untracked file among them (ignored ones too), a task file at
the checkout's root, a machine or scene outside the checkout, a scene file naming a file outside
its own directory, a symbolic link, and a task without a committed expert when a config makes
demonstrations with the expert. `check` then writes the lock,
`experiments/protocol/<name>/lock.json` (the blob ids of the protocol files, of run.py and
table.py, of the configs and task files and of their `task_reads`, the frozen commit, the
binary's `--version` and sha256, `rustc --version` and the MuJoCo library the binary loads), to
be committed before the first `run`; a second `check` is refused while a lock exists.

The protocol's state lives in git, not in run directories: an evaluation runs over several
sessions, each on a fresh checkout where runs/ is empty. `run` refuses without a committed lock,
or when the protocol files, run.py, table.py, the configs, the task files or what they make a
job read differ from what was locked (or a lock holds no `task_reads`), or when the binary's
`--version` does not name the frozen commit (without `-dirty`). It
runs the plan tier by tier (an arm's `tier`, 1 first), base by base within a tier, every job the
ledger does not record as finished, `--parallel N` at a time (default 1); with N > 1 each job
runs on one thread (the run directory's `threads` is set to 1: a job's results do not depend on
its thread count, tests/lockstep.rs), otherwise with the config's. It prepares each (config,
task, base) run directory under `runs/protocol/<name>/` when a job first needs it, named
`<task>-b<base>-<key>`, the key the first 8 hex digits of the sha256 of the config as the lock
holds it (so that status, table.py and diagnose.py find a protocol's directories after its
config changes on a later commit).

The ledger, `experiments/protocol/<name>/ledger.jsonl`, is append-only and committed after each
session: every session's binary (its sha256 and `--version`), every prepare and every job's start
and end. A prepare's `prepared` entry holds the sha256 of the learned machines
(`rm/learned*.txt`) and the annotated demonstrations (`expert_data*.bin`) and the number of
demonstrations kept; a later session that prepares the directory again (a fresh checkout) and
gets other bytes is refused (`prepare_failed`), and so is a prepare that exits with an error:
either is recorded once, every unfinished job of that run directory is recorded failed, and the
plan goes on. The first prepare of a directory also appends its learned machines to
`experiments/protocol/<name>/machines.txt` (committed with the ledger: they are what tells a
wrong machine from a failed RL once the run directories are gone). A job's `done` entry carries
the job file's sha256 and everything `table.py` reads from it (`JOB_FIELDS`), so the tables need
no run directory.

A job is finished when the ledger records it done or failed. A job that exits with an error, is
killed by a signal other than SIGTERM, SIGINT or SIGHUP, or runs longer than its algorithm's
`timeout_secs` is recorded as failed and never retried. A job killed by SIGTERM, SIGINT or SIGHUP
(a session ending) is recorded `killed` and rerun by a later session, at most twice: a job is
started at most three times (every `start` entry counts, also one whose session died without an
end entry), and its third kill records it failed. Reruns are harmless: a job is seeded and its
results depend neither on scheduling nor on its thread count. After a kill the session starts no
further job, waits for the running ones and exits 2. run.py itself passes SIGTERM, SIGINT and
SIGHUP on to its running jobs. `--until` starts no job after that time of day (UTC).

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
import re
import signal
import subprocess
import sys
import time
import tomllib

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
# Sources of the method: a protocol's HEAD must not differ from its frozen commit in these.
METHOD_PATHS = ["src", "assets", "mujoco-sys", "build.rs", "Cargo.toml", "Cargo.lock"]
# What produces the numbers from the runs: locked, and `run` and table.py refuse a change.
SCRIPTS = ["experiments/protocol/run.py", "experiments/protocol/table.py"]
# Where run directories of this machine are looked for (besides the checkout's runs/).
SEARCH_ROOTS = ["/work", "/tmp"]
# Every seed below this is development data; an evaluation's bases are drawn above it.
DEVELOPMENT_BELOW = 10_000
# A session's end: a job killed by one of these is rerun, the others count as failures.
RERUN_SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)
# A job is started at most this many times (the first run and two reruns after kills).
MAX_STARTS = 3
TIERS = (1, 2, 3)
# The tasks built into the binary; any other task of a plan is the path of a task file.
SHIPPED_TASKS = ("or", "sequential", "if", "composite", "blue")


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


def machines_path(name):
    return os.path.join(state_dir(name), "machines.txt")


def rel(path):
    """A path as the ledger names it: relative to the checkout, which moves between sessions."""
    return os.path.relpath(path, ROOT)


def unit_of(text, spec, what):
    """An "ARM:ALGO" reference of [analysis] as (arm, algo)."""
    if not isinstance(text, str) or text.count(":") != 1:
        fail(f"{spec}: [analysis] {what}: expected \"ARM:ALGO\", got {text!r}")
    return tuple(text.split(":"))


def units_of(refs):
    """[analysis] primary or paper: one "ARM:ALGO" or a list of them (one algorithm split over
    arms, such as paper and new tasks at different sizes)."""
    return [] if refs is None else ([refs] if isinstance(refs, str) else list(refs))


def load(name):
    md, spec = paths(name)
    for f in (md, spec):
        if not os.path.isfile(os.path.join(ROOT, f)):
            fail(f"{f} does not exist")
    plan = load_toml(spec)
    for key in ("commit", "config", "bases", "arm", "timeout_secs"):
        if key not in plan:
            fail(f"{spec}: missing key `{key}`")
    commit = plan["commit"]
    if not (isinstance(commit, str) and len(commit) == 40 and all(c in "0123456789abcdef" for c in commit)):
        fail(f"{spec}: `commit` must be a full 40-digit commit, got {commit!r}")
    if not isinstance(plan.get("development", False), bool):
        fail(f"{spec}: `development` must be true or false")
    bases = plan["bases"]
    if not bases or len(set(bases)) != len(bases) or not all(isinstance(b, int) and b >= 0 for b in bases):
        fail(f"{spec}: `bases` must be distinct non-negative integers")
    if not plan.get("development", False) and min(bases) < DEVELOPMENT_BELOW:
        fail(f"{spec}: base {min(bases)} is development data (every seed below {DEVELOPMENT_BELOW}); "
             "a rehearsal on it says `development = true`")
    labels = {}
    units = set()
    for i, arm in enumerate(plan["arm"]):
        for key in ("name", "tasks", "algos", "n_bases", "seeds"):
            if key not in arm:
                fail(f"{spec}: arm {i + 1} is missing `{key}`")
        if not 1 <= arm["n_bases"] <= len(bases):
            fail(f"{spec}: arm {arm['name']}: n_bases must be in 1..={len(bases)}")
        if not 1 <= arm["seeds"] <= 16:
            fail(f"{spec}: arm {arm['name']}: seeds must be in 1..=16")
        if arm.get("tier", 1) not in TIERS:
            fail(f"{spec}: arm {arm['name']}: tier must be 1, 2 or 3")
        for task in arm["tasks"]:
            other = labels.setdefault(task_label(task), task)
            if other != task:
                fail(f"{spec}: tasks {other} and {task} have the same name")
        for algo in arm["algos"]:
            t = plan["timeout_secs"].get(algo)
            if not (isinstance(t, (int, float)) and t > 0):
                fail(f"{spec}: timeout_secs has no positive entry for algorithm {algo} (arm {arm['name']})")
            if (arm["name"], algo) in units:
                fail(f"{spec}: arm {arm['name']} with algorithm {algo} twice")
            units.add((arm["name"], algo))
    ordered = sorted(bases)
    widest = max(arm["seeds"] for arm in plan["arm"])
    if any(b - a < widest for a, b in zip(ordered, ordered[1:])):
        fail(f"{spec}: bases closer than {widest} apart share SAC seeds")
    analysis = plan.get("analysis")
    if analysis is not None:
        refs = [(k, ref) for k in ("primary", "paper", "control_failed") for ref in units_of(analysis.get(k))]
        for k, pair in enumerate(analysis.get("secondary", [])):
            if not (isinstance(pair, list) and len(pair) == 2):
                fail(f"{spec}: [analysis] secondary {k + 1}: expected [\"ARM:ALGO\", \"ARM:ALGO\"]")
            refs += [(f"secondary {k + 1}", p) for p in pair]
        for what, ref in refs:
            if ref is None:
                continue
            if unit_of(ref, spec, what) not in units:
                fail(f"{spec}: [analysis] {what}: no arm with that algorithm: {ref}")
        for pool, tasks in analysis.get("pools", {}).items():
            unknown = [t for t in tasks if t not in labels]
            if unknown:
                fail(f"{spec}: [analysis] pools.{pool}: no task {unknown[0]} in the plan")
    return md, spec, plan


def task_label(task):
    return os.path.splitext(os.path.basename(task))[0]


def configs_and_tasks(plan):
    files = {plan["config"]}
    for arm in plan["arm"]:
        files.add(arm.get("config", plan["config"]))
    return sorted(files | set(task_files(plan)))


def task_files(plan):
    """The plan's task files: every task but a shipped one (built into the binary), as
    `reacher --task` reads any other name as a path."""
    return sorted({t for arm in plan["arm"] for t in arm["tasks"] if t not in SHIPPED_TASKS})


def git_out(*args, text=True):
    """git's output; a git error ends the script (an empty answer is not read as "no files")."""
    o = git(*args, text=text)
    if o.returncode != 0:
        err = o.stderr if text else o.stderr.decode("utf-8", "replace")
        fail(f"git {' '.join(args)}: {err.strip()}")
    return o.stdout


def in_repository(path):
    """A relative, normalised path that stays inside the checkout."""
    return not os.path.isabs(path) and path != ".." and not path.startswith("../")


# Attributes by which an MJCF file names another file or the directory of its assets.
SCENE_FILE_ATTRIBUTE = re.compile(
    r"""\b(file|meshdir|texturedir|file(?:right|left|up|down|front|back))\s*=\s*(?:"([^"]*)"|'([^']*)')""")


# The limits reacher puts on the same files (config_text::MAX_TEXT_FILE_BYTES and
# scene_xml::MAX_SCENE_BYTES): a file above them fails every job, so check refuses it first.
MAX_TEXT_FILE_BYTES = 1 << 20
MAX_SCENE_BYTES = 16 << 20


def read_bounded(path, limit):
    """The bytes of a checkout file of at most `limit` bytes; a larger one ends the script,
    naming the file and the limit, before anything is read."""
    full = os.path.join(ROOT, path)
    try:
        size = os.path.getsize(full)
        if size > limit:
            fail(f"{path}: {size} bytes, above the limit of {limit} bytes for this kind of file")
        with open(full, "rb") as fh:
            return fh.read(limit + 1)
    except OSError as e:
        fail(f"{path}: {e}")


def load_toml(path):
    """A checkout TOML file of at most MAX_TEXT_FILE_BYTES, parsed; errors name the file."""
    try:
        return tomllib.loads(read_bounded(path, MAX_TEXT_FILE_BYTES).decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        fail(f"{path}: {e}")


def scene_reads_outside(xml_path):
    """The first file or asset directory an MJCF file names outside its own directory, if any."""
    text = read_bounded(xml_path, MAX_SCENE_BYTES).decode("utf-8", errors="replace")
    here = os.path.dirname(xml_path)
    for m in SCENE_FILE_ATTRIBUTE.finditer(text):
        value = m.group(2) if m.group(2) is not None else m.group(3)
        inside = os.path.normpath(os.path.join(here, value))
        if os.path.isabs(value) or not (inside == here or inside.startswith(here + "/")):
            return f'{m.group(1)}="{value}"'
    return None


def task_reads(plan):
    """What the plan's task files make a job read from the checkout at run time: each task
    file's machine and scene, and every file git tracks in and below the task file's directory
    and its scene's (the experts in `experts/` beside the task file, the files a scene includes
    or names as assets). Refused, so that nothing a job reads escapes the lock: a task file in
    the checkout's root, a machine or scene outside the checkout, a scene file that names a file
    or asset directory outside its own directory, a symbolic link among them (git would hold its
    target's name, not its bytes), and a task without a committed expert when a config of the
    plan makes demonstrations with the expert (a job would train one)."""
    reads, dirs = set(), set()
    needs_expert = demos_from_expert(plan)
    for task in task_files(plan):
        here = os.path.dirname(os.path.normpath(task))
        if not in_repository(os.path.normpath(task)) or not here:
            fail(f"{task}: a protocol's task file lies in a directory of the checkout, not at its "
                 "root or outside it (every file in and below its directory is locked with it)")
        dirs.add(here)
        named = load_toml(task)
        for key in ("scene", "machine"):
            value = named.get(key)
            if not isinstance(value, str) or (key == "scene" and value == "builtin"):
                continue
            path = os.path.normpath(os.path.join(here, value))
            if os.path.isabs(value) or not in_repository(path) or not os.path.dirname(path):
                fail(f"{task}: `{key} = {value!r}` is outside the checkout's directories: a protocol "
                     "locks only files in them")
            reads.add(path)
            if key == "scene":
                dirs.add(os.path.dirname(path))
        stem = task_label(task)
        experts = git_out("ls-files", "-z", "--", os.path.join(here, "experts")).split("\0")
        if needs_expert and not any(
                re.fullmatch(rf"expert_{re.escape(stem)}-[0-9a-f]+\.policy", os.path.basename(f)) for f in experts if f):
            fail(f"{task}: no committed expert ({here}/experts/expert_{stem}-<hash>.policy): a job "
                 f"would train one; train it with `reacher expert --task {task}` and commit it")
    listed = git_out("ls-files", "-s", "-z", "--", *sorted(dirs)) if dirs else ""
    for line in listed.split("\0"):
        if not line:
            continue
        mode, path = line.split(" ", 1)[0], line.split("\t", 1)[1]
        if mode == "120000":
            fail(f"{path} is a symbolic link beside a task file of the protocol: git would lock "
                 "its target's name, not its bytes")
        reads.add(path)
    for path in sorted(reads):
        if os.path.islink(os.path.join(ROOT, path)):
            fail(f"{path} is a symbolic link a task file of the protocol names: git would lock "
                 "its target's name, not its bytes")
        if path.endswith(".xml") and os.path.isfile(os.path.join(ROOT, path)):
            outside = scene_reads_outside(path)
            if outside:
                fail(f"{path} names {outside}, outside its own directory: a protocol locks only "
                     "what a scene reads in and below its directory")
    return sorted(reads - set(configs_and_tasks(plan)))


def demos_from_expert(plan):
    """Whether a config of the plan makes its demonstrations with the task's expert."""
    for config in {plan["config"], *(arm.get("config", plan["config"]) for arm in plan["arm"])}:
        if load_toml(config).get("demo_source", "expert") != "scripted":
            return True
    return False


def untracked_in(paths):
    """Files git does not track in and below the directories of `paths`, ignored ones too (such
    as an expert trained on this machine, which a job would read in place of none)."""
    dirs = sorted({os.path.dirname(p) for p in paths})
    if not dirs:
        return []
    out = git_out("ls-files", "-z", "--others", "--", *dirs)
    return [f for f in out.split("\0") if f]


def inputs_changed(plan, lock):
    """The first locked input (config, task file, or what a task file makes a job read) that
    differs from the lock, committed or not, or an untracked file beside them; None when none.
    A lock without `task_reads` (written by an older run.py) is compared on its inputs only."""
    inputs = configs_and_tasks(plan)
    locked = dict(lock["inputs"])
    now = {f: blob(f) for f in inputs}
    if "task_reads" in lock:
        reads = task_reads(plan)
        locked.update(lock["task_reads"])
        now.update({f: blob(f) for f in reads})
        inputs = inputs + reads
        untracked = untracked_in(task_files(plan) + reads)
        if untracked:
            return f"{untracked[0]} (not committed)"
    for f in sorted(set(now) | set(locked)):
        if now.get(f) != locked.get(f):
            return f
    dirty = [f for f in git_out("diff", "-z", "--name-only", "HEAD", "--", *inputs).split("\0") if f] if inputs else []
    return dirty[0] if dirty else None


def content_key(path, lock=None):
    """A short name for a config's contents (arms with their own config get their own run
    directories). With a lock it is the contents the lock holds, so that a protocol's run
    directories keep their names when the config changes on a later commit."""
    locked = (lock or {}).get("inputs", {}).get(path)
    if locked:
        data = git_out("cat-file", "blob", locked, text=False)
    else:
        with open(os.path.join(ROOT, path), "rb") as fh:
            data = fh.read()
    return hashlib.sha256(data).hexdigest()[:8]


def plan_runs(name, plan, lock=None):
    """Every run directory (config, task, base, algos, seeds) and job (run, algo, seed, arm,
    tier), in the order they run: tier by tier, base by base within a tier, so that a plan cut
    by time loses the later tiers first and covers every arm of a tier on the same bases.
    Directories are named by the configs the lock holds, when there is one."""
    runs = {}
    jobs = []
    for tier in TIERS:
        for j, base in enumerate(plan["bases"]):
            for arm in plan["arm"]:
                if j >= arm["n_bases"] or arm.get("tier", 1) != tier:
                    continue
                config = arm.get("config", plan["config"])
                for task in arm["tasks"]:
                    key = (config, task, base)
                    d = os.path.join(run_root(name), f"{task_label(task)}-b{base}-{content_key(config, lock)}")
                    r = runs.setdefault(key, {"dir": d, "config": config, "task": task, "base": base, "algos": [], "seeds": 0})
                    for algo in arm["algos"]:
                        if algo not in r["algos"]:
                            r["algos"].append(algo)
                        for s in range(arm["seeds"]):
                            jobs.append({"arm": arm["name"], "run": key, "algo": algo, "seed": base + s, "tier": tier})
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
    """The blob id of the file at HEAD, or None when HEAD has no such file."""
    o = git("rev-parse", "--verify", "--quiet", f"HEAD:{path}")
    return o.stdout.strip() if o.returncode == 0 else None


def worktree_blob(path):
    """The blob id of the file as it is in the checkout (committed or not)."""
    return git("hash-object", "--", path).stdout.strip()


def binary_version(binary):
    """(the binary's `--version` line, the commit it names)."""
    if not os.access(binary, os.X_OK):
        fail(f"{binary}: no executable (build the frozen commit)")
    out = subprocess.run([binary, "--version"], capture_output=True, text=True).stdout.strip()
    if "(commit " not in out:
        fail(f"{binary} --version names no commit: {out!r}")
    return out, out.split("(commit ", 1)[1].split(")", 1)[0]


def command_line(*cmd):
    try:
        o = subprocess.run(list(cmd), capture_output=True, text=True)
    except OSError as e:
        return f"not available ({e.strerror})"
    return (o.stdout.strip() or o.stderr.strip() or f"exit {o.returncode}") if o.returncode == 0 else f"exit {o.returncode}"


def mujoco_version(binary):
    """The MuJoCo library the binary loads (from `ldd`) and the Debian package that holds it."""
    libs = [line.strip() for line in command_line("ldd", binary).splitlines() if "mujoco" in line]
    if not libs:
        return "no libmujoco in `ldd` of the binary"
    out = libs[0].split(" (0x", 1)[0]  # without its load address, which changes every run
    path = libs[0].split("=>", 1)[1].split("(", 1)[0].strip() if "=>" in libs[0] else ""
    # dpkg names a merged-/usr library by its /usr path.
    for candidate in ([path, "/usr" + path] if path.startswith("/lib") else [path]) if path else []:
        owner = command_line("dpkg", "-S", candidate)
        if ": " in owner and not owner.startswith("exit"):
            pkg = owner.split(": ", 1)[0]
            return out + f"; dpkg {pkg} {command_line('dpkg-query', '-W', '-f=${Version}', pkg)}"
    return out


def scripts_changed(lock):
    """The scripts (run.py, table.py) whose checkout differs from the blob the lock holds."""
    return [f for f in SCRIPTS if worktree_blob(f) != lock.get("scripts", {}).get(f)]


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


def prepare_facts(run_dir):
    """What the ledger keeps of a prepared run directory: the sha256 of its learned machines
    and annotated demonstrations, and the demonstrations kept of those generated."""
    files = {}
    for sub, pattern in (("rm", r"learned.*\.txt"), ("", r"expert_data.*\.bin")):
        d = os.path.join(run_dir, sub)
        for f in sorted(os.listdir(d)) if os.path.isdir(d) else []:
            if re.fullmatch(pattern, f):
                files[os.path.join(sub, f) if sub else f] = sha256_of(os.path.join(d, f))
    with open(os.path.join(run_dir, "prepare.json")) as fh:
        prepared = json.load(fh)
    return {"files": files, "demos_kept": prepared.get("demos_kept"),
            "demos_generated": prepared.get("demos_generated")}


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
    blocks = rng.sample(range(DEVELOPMENT_BELOW // spacing, 1_000_000 // spacing), n)
    bases = [b * spacing for b in blocks]
    print(f"# drawn by `run.py draw-bases {name} --n {n} --spacing {spacing}` at {head}")
    print(f"bases = {bases}")


def check(name, binary):
    md, spec, plan = load(name)
    if os.path.exists(lock_path(name)) or git("cat-file", "-e", f"HEAD:{rel(lock_path(name))}").returncode == 0:
        fail(f"{rel(lock_path(name))} exists: `check` runs once, before the first job")
    if os.path.exists(ledger_path(name)):
        fail(f"{rel(ledger_path(name))} exists: `check` runs before the first job")
    for f in (md, spec, *SCRIPTS):
        if git("ls-files", "--error-unmatch", f).returncode != 0 or git("diff", "--quiet", "HEAD", "--", f).returncode != 0:
            fail(f"{f} is not committed, or differs from HEAD: a protocol and its scripts are committed before it runs")
    frozen = plan["commit"]
    if git("merge-base", "--is-ancestor", frozen, "HEAD").returncode != 0:
        fail(f"the frozen commit {frozen} is not an ancestor of HEAD")
    reads = task_reads(plan)
    untracked = untracked_in(task_files(plan) + reads)
    if untracked:
        fail(f"{untracked[0]} is in the directory of a task file or scene of the protocol but not "
             "committed: a job could read it (commit it or move it away)")
    missing = [f for f in configs_and_tasks(plan) + reads if blob(f) is None]
    if missing:
        fail(f"{missing[0]} is read by the protocol's jobs but not committed")
    inputs = METHOD_PATHS + configs_and_tasks(plan) + reads
    moved = [f for f in git_out("diff", "-z", "--name-only", frozen, "HEAD", "--", *inputs).split("\0") if f]
    if moved:
        fail(f"HEAD differs from the frozen commit in the method or its inputs: {moved[0]} "
             f"(`git diff {frozen[:10]} HEAD -- {moved[0]}`)")
    if git("diff", "--quiet", "HEAD", "--", *inputs).returncode != 0:
        fail("the checkout has uncommitted changes in the method or its inputs")
    version, built = binary_version(binary)
    if built != frozen:
        fail(f"{binary} is built from {built}, not the frozen commit {frozen}")
    runs, jobs = plan_runs(name, plan)
    existing = [r["dir"] for r in runs.values() if os.path.exists(r["dir"])]
    if existing:
        fail(f"{existing[0]} exists already: nothing of a protocol runs before its check")
    if plan.get("development", False):
        print(f"protocol {name} is a development protocol (`development = true`): the check that "
              "its seeds were never used is skipped")
    else:
        seen = used_seeds(run_root(name))
        clash = sorted({j["seed"] for j in jobs} & set(seen))
        if clash:
            fail(f"seed {clash[0]} of the protocol was used before: {seen[clash[0]]}")
    os.makedirs(state_dir(name), exist_ok=True)
    lock = {
        "md_blob": blob(md), "toml_blob": blob(spec), "head": git("rev-parse", "HEAD").stdout.strip(),
        "frozen": frozen, "binary_version": version, "binary_sha256": sha256_of(binary),
        "scripts": {f: blob(f) for f in SCRIPTS},
        "rustc": command_line("rustc", "--version"),
        "mujoco": mujoco_version(binary),
        "development": plan.get("development", False),
        "inputs": {f: blob(f) for f in configs_and_tasks(plan)},
        "task_reads": {f: blob(f) for f in reads},
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


def finished_jobs(name, entries=None):
    """{(run directory relative to the checkout, algo, seed): the ledger's `done` or `failed`
    entry}: the jobs that are not run again."""
    out = {}
    for e in read_ledger(name) if entries is None else entries:
        if e.get("event") in ("done", "failed"):
            out[job_key(e)] = e
    return out


class Session:
    """One `run`: the plan, the ledger's state and the jobs running now."""

    def __init__(self, name, plan, binary, parallel):
        self.name, self.plan, self.binary, self.parallel = name, plan, binary, parallel
        entries = read_ledger(name)
        self.finished = finished_jobs(name, entries)
        self.starts = {}
        self.prepared = {}
        self.refused = set()
        for e in entries:
            if e.get("event") == "start":
                self.starts[job_key(e)] = self.starts.get(job_key(e), 0) + 1
            elif e.get("event") == "prepared":
                self.prepared.setdefault(e["dir"], e)
            elif e.get("event") == "prepare_failed":
                self.refused.add(e["dir"])
        self.checked = set()
        self.running = {}
        self.stop = None

    def fail_dir(self, r, jobs, why, **details):
        """A run directory that cannot be used: recorded once, its unfinished jobs failed."""
        d = rel(r["dir"])
        if d not in self.refused:
            ledger(self.name, {"event": "prepare_failed", "dir": d, "why": why, **details})
            self.refused.add(d)
        for j in jobs:
            key = (d, j["algo"], j["seed"])
            if j["run"] == (r["config"], r["task"], r["base"]) and key not in self.finished:
                e = {"event": "failed", "why": "prepare", "dir": d, "algo": j["algo"], "seed": j["seed"]}
                ledger(self.name, e)
                self.finished[key] = e
        print(f"run directory {d}: {why}; its unfinished jobs are recorded failed", flush=True)

    def ready(self, r, jobs):
        """Prepares the run directory if needed and checks it against the ledger: True when its
        jobs may run."""
        d = rel(r["dir"])
        if d in self.refused:
            self.fail_dir(r, jobs, "prepare failed or was refused before")
            return False
        if d in self.checked:
            return True
        if not os.path.isfile(os.path.join(r["dir"], "prepare.json")):
            cmd = [
                self.binary, "prepare", "--task", r["task"], "--algo", ",".join(r["algos"]),
                "--seeds", str(r["seeds"]), "--seed", str(r["base"]), "--config", r["config"],
                "--out", r["dir"], "--quiet",
            ]
            print("+", " ".join(cmd), flush=True)
            ledger(self.name, {"event": "prepare", "dir": d})
            code = subprocess.run(cmd, cwd=ROOT).returncode
            if code < 0 and -code in RERUN_SIGNALS:
                self.stop = f"prepare of {d} was killed by signal {-code}"
                return False
            if code != 0:
                self.fail_dir(r, jobs, f"prepare exited with {code}", exit=code)
                return False
        with open(os.path.join(r["dir"], "prepare.json")) as fh:
            got = json.load(fh).get("git_commit")
        if got != self.plan["commit"]:
            fail(f"{r['dir']} was prepared by {got}, not the frozen commit {self.plan['commit']}")
        facts = prepare_facts(r["dir"])
        first = self.prepared.get(d)
        if first is None:
            e = {"event": "prepared", "dir": d, **facts}
            ledger(self.name, e)
            self.prepared[d] = e
            self.keep_machines(r, facts)
        elif {k: first.get(k) for k in facts} != facts:
            self.fail_dir(r, jobs, "prepared again with other bytes than the ledger records", got=facts)
            return False
        self.checked.add(d)
        return True

    def keep_machines(self, r, facts):
        """The learned machines of a run directory, appended to machines.txt (committed)."""
        with open(machines_path(self.name), "a") as fh:
            for f, sha in facts["files"].items():
                if f.endswith(".txt"):
                    with open(os.path.join(r["dir"], f)) as src:
                        text = src.read()
                    fh.write(f"== {os.path.basename(r['dir'])}/{f} sha256 {sha}\n{text}")
                    if not text.endswith("\n"):
                        fh.write("\n")

    def set_threads(self, r):
        """A job's thread count comes from its run directory's config: 1 when jobs run side by
        side, else the protocol config's (its results do not depend on it)."""
        path = os.path.join(r["dir"], "config.toml")
        with open(path) as fh:
            text = fh.read()
        if self.parallel > 1:
            want = 1
        else:
            with open(os.path.join(ROOT, r["config"]), "rb") as fh:
                want = tomllib.load(fh).get("threads", 1)
        new, n = re.subn(r"(?m)^threads = \d+$", f"threads = {want}", text, count=1)
        if n == 1 and new != text:
            with open(path + ".tmp", "w") as fh:
                fh.write(new)
            os.replace(path + ".tmp", path)
        return want

    def start(self, j, r):
        cmd = [self.binary, "job", "--run", r["dir"], "--algo", j["algo"], "--seed", str(j["seed"]), "--quiet"]
        threads = self.set_threads(r)
        print("+", " ".join(cmd), flush=True)
        entry = {"dir": rel(r["dir"]), "algo": j["algo"], "seed": j["seed"]}
        key = job_key(entry)
        self.starts[key] = self.starts.get(key, 0) + 1
        ledger(self.name, {"event": "start", "threads": threads, "attempt": self.starts[key], **entry})
        proc = subprocess.Popen(cmd, cwd=ROOT, start_new_session=True)
        limit = self.plan["timeout_secs"][j["algo"]]
        self.running[proc] = {"entry": entry, "r": r, "j": j, "deadline": time.monotonic() + limit,
                              "limit": limit, "timed_out": False}

    def end(self, proc, code):
        info = self.running.pop(proc)
        entry, r, j = info["entry"], info["r"], info["j"]
        key = job_key(entry)
        what = f"job {j['algo']} seed {j['seed']} of {r['dir']}"
        if info["timed_out"]:
            e = {"event": "failed", "why": "timeout", "timeout_secs": info["limit"], **entry}
            print(f"{what} ran longer than {info['limit']} s: killed, recorded failed", flush=True)
        elif code < 0 and -code in RERUN_SIGNALS:
            if self.starts[key] < MAX_STARTS:
                ledger(self.name, {"event": "killed", "signal": -code, **entry})
                self.stop = self.stop or f"{what} was killed by signal {-code}; it reruns next time"
                return
            e = {"event": "failed", "why": f"killed by signal {-code} on its start {self.starts[key]} of {MAX_STARTS}",
                 "signal": -code, **entry}
            self.stop = self.stop or f"{what} was killed by signal {-code} a third time: recorded failed"
        elif code < 0:
            e = {"event": "failed", "why": f"killed by signal {-code}", "signal": -code, **entry}
            print(f"{what} was killed by signal {-code}: recorded failed, not retried", flush=True)
        elif code != 0:
            e = {"event": "failed", "why": "error exit", "exit": code, **entry}
            print(f"{what} failed (exit {code}): recorded, not retried", flush=True)
        else:
            path = job_file(r["dir"], j["algo"], j["seed"])
            with open(path, "rb") as fh:
                data = fh.read()
            e = {"event": "done", "sha256": hashlib.sha256(data).hexdigest(), "job": job_fields(json.loads(data)), **entry}
        ledger(self.name, e)
        self.finished[key] = e

    def wait(self):
        """Until one running job ends; kills a job past its timeout."""
        while True:
            for proc in list(self.running):
                code = proc.poll()
                if code is not None:
                    self.end(proc, code)
                    return
                info = self.running[proc]
                if not info["timed_out"] and time.monotonic() > info["deadline"]:
                    info["timed_out"] = True
                    os.killpg(proc.pid, signal.SIGKILL)
            time.sleep(0.2)

    def on_signal(self, signum, _frame):
        self.stop = self.stop or f"run.py received signal {signum}"
        for proc in self.running:
            try:
                os.killpg(proc.pid, signum)
            except ProcessLookupError:
                pass


def run(name, binary, until, max_jobs, parallel):
    md, spec, plan = load(name)
    lock = read_lock(name)
    if (blob(md), blob(spec)) != (lock["md_blob"], lock["toml_blob"]) or git("diff", "--quiet", "HEAD", "--", md, spec).returncode != 0:
        fail(f"{md} or {spec} changed after the protocol was locked")
    changed = scripts_changed(lock)
    if changed:
        fail(f"{' and '.join(changed)} changed after the protocol was locked (the lock's blob ids)")
    if "task_reads" not in lock:
        fail(f"{rel(lock_path(name))} holds no `task_reads`: it was written by an older run.py, "
             "whose lock left the files task files name unchecked; run it with that run.py")
    changed = inputs_changed(plan, lock)
    if changed:
        fail(f"{changed}, a config or task file of the protocol or a file a task file makes a job "
             "read (its machine, scene, experts or a file beside them), changed after the "
             "protocol was locked")
    version, built = binary_version(binary)
    if built != lock["frozen"]:
        fail(f"{binary} is built from {built}, not the frozen commit {lock['frozen']} (see run.py's docs)")
    if parallel < 1:
        fail("--parallel must be at least 1")
    runs, jobs = plan_runs(name, plan, lock)
    s = Session(name, plan, binary, parallel)
    ledger(name, {"event": "session", "binary_sha256": sha256_of(binary), "binary_version": version,
                  "parallel": parallel})
    for sig in RERUN_SIGNALS:
        signal.signal(sig, s.on_signal)
    started = 0
    pending = iter(jobs)
    while True:
        while not s.stop and len(s.running) < parallel:
            j = next(pending, None)
            if j is None:
                break
            r = runs[j["run"]]
            key = (rel(r["dir"]), j["algo"], j["seed"])
            if key in s.finished:
                continue
            if until and datetime.datetime.now(datetime.timezone.utc) >= until:
                s.stop = f"stopping before {j['algo']} seed {j['seed']} of {r['dir']}: --until"
                break
            if max_jobs is not None and started >= max_jobs:
                s.stop = "--max-jobs"
                break
            if s.starts.get(key, 0) >= MAX_STARTS:
                e = {"event": "failed", "why": f"started {MAX_STARTS} times without finishing",
                     "dir": key[0], "algo": j["algo"], "seed": j["seed"]}
                ledger(name, e)
                s.finished[key] = e
                continue
            if not s.ready(r, jobs):
                continue
            s.start(j, r)
            started += 1
        if not s.running:
            break
        s.wait()
    status(name)
    print(f"commit {rel(ledger_path(name))} and {rel(machines_path(name))}: the next session resumes from them")
    if s.stop and s.stop not in ("--max-jobs",) and not s.stop.startswith("stopping before"):
        fail(s.stop)
    if s.stop and s.stop.startswith("stopping before"):
        print(s.stop)


def lock_if_any(name):
    """The protocol's lock as the checkout holds it, or None before `check`."""
    if not os.path.isfile(lock_path(name)):
        return None
    with open(lock_path(name)) as fh:
        return json.load(fh)


def status(name):
    _, _, plan = load(name)
    runs, jobs = plan_runs(name, plan, lock_if_any(name))
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
    p.add_argument("--parallel", type=int, default=1, help="run: jobs at once (each on one thread when > 1)")
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
        run(args.name, args.bin, until, args.max_jobs, args.parallel)


if __name__ == "__main__":
    main()

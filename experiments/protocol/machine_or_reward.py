#!/usr/bin/env python3
"""SMIRL's missed jobs of a finished evaluation asked again: the learned machine, or the reward
learned on it? Exploratory, after diagnose.py; it writes no ledger, table or diagnosis.md.

Usage:
    python3 experiments/protocol/machine_or_reward.py NAME --bin REACHER [--units ARM:ALGO,...]
        [--fresh-seeds 1000,1001,1002] [--parallel N] [--replace]

diagnose.py calls a job's cause from one fresh SAC agent, and its machine test (does the learned
machine refine the task's along the demonstrations) says no on nearly every machine, solved ones
too. This script asks two other questions of every missed job diagnose.py calls "agent" or
"fresh fails" (a SMIRL unit's, `--units`, by default the protocol's `[analysis] primary`), and
of control jobs that were solved:

1. **Fresh agents**: how many of the SAC seeds `--fresh-seeds` solve when trained from scratch
   on the job's final learned reward (`reacher retrain`; solved: the last evaluation's lower
   branch at least 0.9). Seed 1000 is diagnose.py's and its table is read, not retrained.
   Every table, seed 1000's too, is read only when it is of the job's own retraining: it has
   5 rows (RETRAIN_EVALUATIONS, `reacher retrain`'s default) and its last env_steps is at
   least the run's sac_steps_per_iteration × irl_iterations (config.toml) and less than that
   plus its `[env] max_steps` (the retraining plays the episode in progress to its end before
   the last evaluation); another one (a retraining with other `--steps` or `--evaluations`)
   is foreign and the job is not read. diagnose.py reads seed 1000's table without this
   check, so it is made first: a job whose table is foreign gets the cause "not reproduced"
   instead of diagnose.py's and is not asked.
2. **The task's machine**: the same job — task, base, SAC seed, demonstrations, config — with
   `[smirl] machine = "task"`: SMIRL learns its reward on the task's own machine instead of
   LRM's (an oracle, for diagnosis only). Its run directory is
   `runs/protocol/NAME-task-machine/<the job's run directory's name>`; the demonstrations must
   be the job's: `reacher replay` of both demonstration logs gives the same episode lines
   (seed, steps, return, labels; the run record differs, since it holds the config). A
   missing log or other lines: the row says so and the job is not read. The new machine
   changes the observation, so the SAC seed draws other networks: this is one draw on the
   task's machine, not the job replayed.

Controls: per task, the first solved job of a unit in a run directory that also holds a job
asked about here (the same demonstrations and learned machine, another SAC seed), else the
task's first solved job. They say how often these questions come out "solved" where the job
was.

Beside them, the machine test itself: over every run directory of the units (a lost one
prepared again and checked against the ledger; prepares are cheap), how many learned machines
refine the task's and the share of demonstration steps that are ambiguous, where every job was
solved and where one missed; and whether the task's own machine refines in the task-machine
run directories (a test that works must say yes there).

Each missed job has a row: one whose cause is "not reproduced" (its run directory or job does
not give the ledger's, or seed 1000's table is foreign) is not asked and reads "not read", with
why. Each asked job gets one reading from the two answers, neither ranked above the other:
- **training draw**: a fresh agent solves, SMIRL on the task's machine does not (its chosen
  policy's lower branch below 0.9): the learned reward leads there;
- **learned machine**: SMIRL on the task's machine solves, no fresh agent does;
- **both**: both solve: this job does not tell the machine from the draw;
- **neither**: neither solves: the machine alone does not explain the miss.
The two answers are not measured alike: a fresh agent is judged at the end of its training on
the ground truth's evaluation episodes (20 per branch at the standard config), up to three
draws of which one solving counts; SMIRL on the task's machine on its final set (50 per branch)
after its final phase's choice, one draw. So "training draw" has more chances than "learned
machine". A job diagnose.py calls "agent" has seed 1000 solving, so it reads "training draw" or
"both" by construction: the per-task readings count the "fresh fails" jobs only.

Writes `experiments/protocol/NAME/machine_or_reward.md` (its header names the arguments and
the blob of the script as it started); it refuses at start, before any work, to replace one
whose header line is another (other arguments or another blob) unless `--replace` is given.
Under `runs/protocol/NAME/` it prepares again every lost run directory of
the units and checks it against the ledger, runs again a lost job it asks about (kept as
`jobs/<algo>_seed<k>.diagnose.json`, checked the same way, as diagnose.py does), and adds the
fresh agents' tables (`retrain/`) and sets the threads line of config.toml; under
`runs/protocol/NAME-task-machine/` it creates the task-machine run directories. It replaces
nothing it did not create and never writes the ledger or the tables.
"""

import argparse
import concurrent.futures
import csv
import hashlib
import json
import os
import re
import statistics
import subprocess
import sys
import tomllib

sys.path.insert(0, os.path.dirname(__file__))
import diagnose  # noqa: E402
import run as protocol  # noqa: E402
import table  # noqa: E402

SOLVED = diagnose.SOLVED
ASKED = ("agent", "fresh fails, coarse machine", "fresh fails, refining machine")
READINGS = ("training draw", "learned machine", "both", "neither", "not read")
FRESH_FAILS = ("fresh fails, coarse machine", "fresh fails, refining machine")
# `reacher retrain --evaluations`' default: the rows of a job's own retraining table.
RETRAIN_EVALUATIONS = 5


def fail(msg):
    print(f"machine_or_reward: {msg}", file=sys.stderr)
    sys.exit(2)


def seeds_of(text):
    try:
        seeds = [int(s) for s in text.split(",")]
    except ValueError:
        fail(f"--fresh-seeds: expected comma-separated integers, got {text!r}")
    if not seeds or len(set(seeds)) != len(seeds) or any(s < 0 for s in seeds):
        fail(f"--fresh-seeds: expected distinct non-negative seeds, got {text!r}")
    if diagnose.RETRAIN_SAC_SEED not in seeds:
        fail(f"--fresh-seeds must hold diagnose.py's seed {diagnose.RETRAIN_SAC_SEED}: its causes rest on it")
    return seeds


def own_steps(r, algo):
    """The SAC steps of the job's own retraining, sac_steps_per_iteration × irl_iterations of
    the run's config.toml (`[schedule.<algo>]`'s where it sets them), and its `[env]
    max_steps`; or None, None and why not."""
    path = os.path.join(r["dir"], "config.toml")
    with open(path, "rb") as fh:
        config = tomllib.load(fh)
    own = {**config, **config.get("schedule", {}).get(algo, {})}
    if not all(isinstance(own.get(k), int) for k in ("sac_steps_per_iteration", "irl_iterations")):
        return None, None, f"{protocol.rel(path)} has no integer sac_steps_per_iteration and irl_iterations"
    max_steps = config.get("env", {}).get("max_steps")
    if not isinstance(max_steps, int) or max_steps < 1:
        return None, None, f"{protocol.rel(path)} has no positive integer [env] max_steps"
    return own["sac_steps_per_iteration"] * own["irl_iterations"], max_steps, None


def foreign_table_why(path, steps, max_steps):
    """None when the retraining table at `path` is of the job's own retraining, else why it is
    foreign: what differs. Its own has RETRAIN_EVALUATIONS rows, and its last env_steps is in
    [steps, steps + max_steps): `reacher retrain` trains `steps` SAC steps, then plays the
    episode in progress to its end (at most max_steps steps long, so fewer than max_steps more)
    before its last evaluation. The last row is `steps` itself only when an episode ends there,
    as when every episode runs max_steps steps and max_steps divides `steps`."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    differs = []
    last = rows[-1].get("env_steps") if rows else None
    try:
        own = steps <= int(last) < steps + max_steps
    except (TypeError, ValueError):
        own = False
    if not own:
        differs.append(f"last env_steps {last}, not in [{steps}, {steps + max_steps}) "
                       "(sac_steps_per_iteration × irl_iterations, plus less than [env] max_steps)")
    if len(rows) != RETRAIN_EVALUATIONS:
        differs.append(f"{len(rows)} evaluations, not {RETRAIN_EVALUATIONS}")
    return (f"foreign retraining table {protocol.rel(path)}: " + "; ".join(differs)) if differs else None


def retrain_table(r, row, sac_seed):
    """The path of the job's retraining table at `sac_seed` (as `reacher retrain` names it)."""
    return os.path.join(r["dir"], "retrain", f"{row['algo']}_seed{int(row['seed'])}_sac{sac_seed}.csv")


def diagnose_table_why(r, row):
    """None when diagnose.py's retraining table of the job (at its SAC seed) does not exist or
    is the job's own, else why it cannot be read (diagnose.py does not check it)."""
    path = retrain_table(r, row, diagnose.RETRAIN_SAC_SEED)
    if not os.path.isfile(path):
        return None
    steps, max_steps, why = own_steps(r, row["algo"])
    return why or foreign_table_why(path, steps, max_steps)


def first_cause(binary, r, row, done, threads):
    """diagnose.py's first cause of a missed job, or "not reproduced" and why when the seed-1000
    table it would read is foreign. (A table diagnose.py writes here is its own retraining's,
    and fresh_agent checks it again when the job is asked.)"""
    why = diagnose_table_why(r, row)
    if why:
        return {"cause": "not reproduced", "note": why}
    return diagnose.diagnose(binary, r, row, done, threads)


def fresh_agent(binary, r, row, sac_seed):
    """The last evaluation's lower branch of a fresh agent at `sac_seed` on the job's final
    learned reward (None and why when the retraining fails or its table is foreign)."""
    algo, seed = row["algo"], int(row["seed"])
    steps, max_steps, why = own_steps(r, algo)
    if why:
        return None, why
    out = retrain_table(r, row, sac_seed)
    if not os.path.isfile(out):
        cmd = [binary, "retrain", "--run", r["dir"], "--algo", algo, "--seed", str(seed),
               "--sac-seed", str(sac_seed)]
        print("+", " ".join(cmd), flush=True)
        code = subprocess.run(cmd, cwd=protocol.ROOT, stdout=subprocess.DEVNULL).returncode
        if code != 0 or not os.path.isfile(out):
            return None, f"retrain at SAC seed {sac_seed} exited with {code}"
    why = foreign_table_why(out, steps, max_steps)
    if why:
        return None, why
    last, _ = diagnose.lower_of_retrain(out)
    return last, None


def task_machine_dir(name, r):
    return os.path.join(protocol.run_root(name) + "-task-machine", os.path.basename(r["dir"]))


def task_machine_config(r, path):
    """The job's config with `machine = "learned"` made `"task"`, written to `path`."""
    with open(os.path.join(r["dir"], "config.toml")) as fh:
        text = fh.read()
    new, n = re.subn(r'(?m)^machine = "learned"$', 'machine = "task"', text)
    if n != 1:
        return f"{protocol.rel(r['dir'])}/config.toml has {n} lines `machine = \"learned\"`, not one"
    with open(path + ".tmp", "w") as fh:
        fh.write(new)
    os.replace(path + ".tmp", path)
    return None


def demo_episodes(binary, run_dir):
    """The episode lines `reacher replay` prints for the run's demonstration log (seed, steps,
    return, labels of each), or None and why not."""
    path = os.path.join(run_dir, "logs", "demos.mcap")
    if not os.path.isfile(path):
        return None, f"{protocol.rel(path)} does not exist"
    out = subprocess.run([binary, "replay", path], cwd=protocol.ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        return None, f"`reacher replay {protocol.rel(path)}` exited with {out.returncode}"
    return [line for line in out.stdout.splitlines() if line.startswith("episode")], None


def prepare_task_machine(binary, name, r):
    """None when the task-machine run directory of `r` is prepared on the job's demonstrations,
    else why not."""
    d = task_machine_dir(name, r)
    if not os.path.isfile(os.path.join(d, "prepare.json")):
        if os.path.exists(d):
            return f"{protocol.rel(d)} exists without prepare.json: not overwritten"
        os.makedirs(os.path.dirname(d), exist_ok=True)
        config = d + ".config.toml"
        why = task_machine_config(r, config)
        if why:
            return why
        cmd = [binary, "prepare", "--task", r["task"], "--algo", "smirl", "--seeds", str(r["seeds"]),
               "--seed", str(r["base"]), "--config", config, "--out", d, "--quiet"]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd, cwd=protocol.ROOT).returncode != 0:
            return "prepare with the task's machine failed"
    (mine, why), (theirs, their_why) = demo_episodes(binary, d), demo_episodes(binary, r["dir"])
    if why or their_why:
        return why or their_why
    if not mine or mine != theirs:
        return "the task machine's run has other demonstrations than the job's"
    return None


def task_machine_job(binary, name, r, row):
    """(loop, chosen) lower branches of SMIRL on the task's machine (None and why on failure)."""
    d = task_machine_dir(name, r)
    seed = int(row["seed"])
    path = protocol.job_file(d, "smirl", seed)
    if not os.path.isfile(path):
        cmd = [binary, "job", "--run", d, "--algo", "smirl", "--seed", str(seed), "--quiet"]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd, cwd=protocol.ROOT).returncode != 0 or not os.path.isfile(path):
            return None, "the job on the task's machine failed"
    with open(path) as fh:
        fields = protocol.job_fields(json.load(fh))
    where = protocol.rel(path)
    loop = table.lower_branch(fields["loop"], where)[0]
    if "chosen" in fields:
        chosen = table.lower_branch(fields["candidates"][fields["chosen"]], where)[0]
    else:
        chosen = loop
    return (loop, chosen), None


def ask(binary, name, r, row, first, seeds, done, task_why):
    """One job's row: its fresh agents, SMIRL on the task's machine and the reading."""
    out = {"first": first, "fresh": [], "task": None, "reading": None, "note": ""}
    why = diagnose.ensure_job(binary, r, row, done)
    if why:
        out["reading"], out["note"] = "not read", why
        return out
    for s in seeds:
        last, why = fresh_agent(binary, r, row, s)
        if why:
            out["reading"], out["note"] = "not read", why
            return out
        out["fresh"].append(last)
    if task_why:
        out["reading"], out["note"] = "not read", task_why
        return out
    out["task"], why = task_machine_job(binary, name, r, row)
    if why:
        out["reading"], out["note"] = "not read", why
        return out
    fresh, task = any(v >= SOLVED for v in out["fresh"]), out["task"][1] >= SOLVED
    out["reading"] = {(True, False): "training draw", (False, True): "learned machine",
                      (True, True): "both", (False, False): "neither"}[(fresh, task)]
    return out


def controls_of(rows, asked_rows, dirs, units):
    """Per task, the first solved job of a unit in a run directory holding an asked job, else
    the task's first solved job."""
    asked_dirs = {diagnose.run_of(dirs, row)["dir"] for row in asked_rows}
    out = []
    for task in dict.fromkeys(row["task"] for row in asked_rows):
        solved = [row for row in rows if row["task"] == task and (row["arm"], row["algo"]) in units
                  and row["status"] == "done" and (diagnose.reported(row) or 0.0) >= SOLVED]
        near = [row for row in solved if diagnose.run_of(dirs, row)["dir"] in asked_dirs]
        if near or solved:
            out.append((near or solved)[0])
    return out


def main():
    blob = script_blob()
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name")
    p.add_argument("--bin", required=True)
    p.add_argument("--units", help="ARM:ALGO,... (default: the protocol's [analysis] primary)")
    p.add_argument("--fresh-seeds", default="1000,1001,1002")
    p.add_argument("--parallel", type=int, default=1)
    p.add_argument("--replace", action="store_true",
                   help="replace a machine_or_reward.md written with other arguments or by another blob")
    args = p.parse_args()
    name = args.name
    seeds = seeds_of(args.fresh_seeds)
    if args.parallel < 1:
        fail("--parallel must be at least 1")
    _, _, plan = protocol.load(name)
    version = protocol.binary_version(args.bin)
    if plan["commit"] not in version or "dirty" in version:
        fail(f"{args.bin} is not the frozen commit's binary: {version}")
    refs = args.units.split(",") if args.units else protocol.units_of(plan.get("analysis", {}).get("primary"))
    units = {protocol.unit_of(ref, "--units", "units") for ref in refs}
    if not units:
        fail("no units: give --units ARM:ALGO,...")
    if any(algo != "smirl" for _, algo in units):
        fail("the task's machine is SMIRL's: give SMIRL units only")
    header = written_by(name, refs, seeds, args, blob)
    path = md_path(name)
    if os.path.isfile(path) and not args.replace:
        with open(path) as fh:
            theirs = next((line for line in fh.read().splitlines() if line.startswith("Written by ")), None)
        if theirs != header:
            fail(f"{protocol.rel(path)} was written with other arguments or by another script blob: "
                 "--replace replaces it")
    rows = diagnose.read_jobs(name)
    dirs = diagnose.run_dirs(name, plan, protocol.lock_if_any(name))
    if len(rows) != len(dirs):
        fail(f"jobs.csv has {len(rows)} rows, the plan {len(dirs)} jobs: ask of a finished plan only")
    ledger = protocol.read_ledger(name)
    done = protocol.finished_jobs(name, ledger)
    prepared = {}
    for e in ledger:
        if e.get("event") == "prepared":
            prepared.setdefault(e["dir"], e)
    threads = 1 if args.parallel > 1 else 2

    # diagnose.py's first cause of each missed job (its retraining tables are read, once
    # checked as this script's own reading checks them).
    missed = [row for row in rows if (row["arm"], row["algo"]) in units and row["status"] == "done"
              and (diagnose.reported(row) or 0.0) < SOLVED and (diagnose.number(row["oracle"]) or 0.0) < SOLVED]
    refused = {}
    for row in missed:
        r = diagnose.run_of(dirs, row)
        if r["dir"] not in refused:
            refused[r["dir"]] = diagnose.ensure_prepared(args.bin, r, prepared)
    firsts = []
    for row in missed:
        r = diagnose.run_of(dirs, row)
        first = {"cause": "not reproduced", "note": refused[r["dir"]]} if refused[r["dir"]] else \
            first_cause(args.bin, r, row, done, threads)
        firsts.append(first)
    asked = [(row, f["cause"]) for row, f in zip(missed, firsts) if f["cause"] in ASKED]
    # The others ("not reproduced") are shown, not asked.
    unasked = [(row, f) for row, f in zip(missed, firsts) if f["cause"] not in ASKED]
    controls = controls_of(rows, [row for row, _ in asked], dirs, units)
    for row in controls:
        r = diagnose.run_of(dirs, row)
        if r["dir"] not in refused:
            refused[r["dir"]] = diagnose.ensure_prepared(args.bin, r, prepared)
    targets = asked + [(row, "solved (control)") for row in controls]
    task_why = {}
    for row, _ in targets:
        r = diagnose.run_of(dirs, row)
        if r["dir"] not in task_why:
            task_why[r["dir"]] = refused[r["dir"]] or prepare_task_machine(args.bin, name, r)
    # Threads set here, before the jobs run side by side (two workers never rewrite one file).
    for row, _ in targets:
        r = diagnose.run_of(dirs, row)
        if not refused[r["dir"]]:
            diagnose.set_threads(r["dir"], threads)
            if not task_why[r["dir"]]:
                diagnose.set_threads(task_machine_dir(name, r), threads)
    results = [None] * len(targets)
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.parallel) as pool:
        futures = {}
        for i, (row, first) in enumerate(targets):
            r = diagnose.run_of(dirs, row)
            if refused[r["dir"]]:
                results[i] = {"first": first, "fresh": [], "task": None, "reading": "not read",
                              "note": refused[r["dir"]]}
            else:
                futures[pool.submit(ask, args.bin, name, r, row, first, seeds, done,
                                    task_why[r["dir"]])] = i
        for f in concurrent.futures.as_completed(futures):
            results[futures[f]] = f.result()
    test = machine_test(args.bin, name, rows, units, dirs, prepared, {diagnose.run_of(dirs, row)["dir"]
                                                                     for row, _ in targets})
    targets += [(row, f["cause"]) for row, f in unasked]
    results += [{"first": f["cause"], "fresh": [], "task": None, "reading": "not read", "note": f["note"]}
                for _, f in unasked]
    write(name, header, seeds, targets, results, test)


def rm_facts(run_dir):
    """prepare.json's facts of the learned machine SMIRL uses."""
    with open(os.path.join(run_dir, "prepare.json")) as fh:
        return json.load(fh)["rm"]


def machine_test(binary, name, rows, units, dirs, prepared, asked_dirs):
    """Lines on the refinement test over every run directory of the units and over the task's
    own machine."""
    groups = {}
    for row in rows:
        if (row["arm"], row["algo"]) in units:
            r = diagnose.run_of(dirs, row)
            g = groups.setdefault(r["dir"], {"r": r, "solved": True})
            g["solved"] &= row["status"] == "done" and (diagnose.reported(row) or 0.0) >= SOLVED
    out = {"every job solved": [], "a job missed": [], "not reproduced": 0}
    for d, g in groups.items():
        if diagnose.ensure_prepared(binary, g["r"], prepared):
            out["not reproduced"] += 1
            continue
        facts = rm_facts(d)
        out["every job solved" if g["solved"] else "a job missed"].append(
            (facts["refines_perfect"], facts["ambiguous_steps"] / max(1, facts["total_steps"])))
    task = [rm_facts(task_machine_dir(name, {"dir": d}))["refines_perfect"] for d in sorted(asked_dirs)
            if os.path.isfile(os.path.join(task_machine_dir(name, {"dir": d}), "prepare.json"))]
    return out, task


def script_blob():
    """The git blob id of this script as it is read (at start: what the file's header names)."""
    with open(__file__, "rb") as fh:
        data = fh.read()
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def md_path(name):
    return os.path.join(protocol.state_dir(name), "machine_or_reward.md")


def written_by(name, refs, seeds, args, blob):
    """The file's header line: the arguments, the script's blob and the units."""
    given = (f" --units {args.units}" if args.units else "") + f" --fresh-seeds {','.join(map(str, seeds))}"
    return (f"Written by `python3 experiments/protocol/machine_or_reward.py {name} --bin REACHER{given}` "
            f"(script blob {blob[:12]}) after diagnose.py; the questions, the readings and why "
            "the two answers are not measured alike: the script's docstring. Units: "
            + ", ".join(f"`{r}`" for r in refs) + ".")


def write(name, header, seeds, targets, results, test):
    lines = [
        f"# {name}: the learned machine, or the reward learned on it? (exploratory)",
        "",
        header,
        "",
        "| diagnose.py's cause | jobs | a fresh agent solves | every fresh agent solves "
        "| SMIRL on the task's machine solves | not read |",
        "|---|---|---|---|---|---|",
    ]
    for first in dict.fromkeys(f for _, f in targets):
        here = [res for (_, f), res in zip(targets, results) if f == first]
        fresh = [res["fresh"] for res in here if len(res["fresh"]) == len(seeds)]
        task = [res["task"] for res in here if res["task"]]
        lines.append(f"| {first} | {len(here)} | {sum(any(v >= SOLVED for v in f) for f in fresh)} of {len(fresh)} | "
                     f"{sum(all(v >= SOLVED for v in f) for f in fresh)} of {len(fresh)} | "
                     f"{sum(t[1] >= SOLVED for t in task)} of {len(task)} | "
                     f"{sum(res['reading'] == 'not read' for res in here)} |")
    lines += ["", "Readings of the jobs diagnose.py calls \"fresh fails\":", "",
              "| task | asked | " + " | ".join(READINGS) + " |", "|---|---|" + "---|" * len(READINGS)]
    asked = [(row, res) for (row, f), res in zip(targets, results) if f in FRESH_FAILS]
    for task in dict.fromkeys(row["task"] for row, _ in asked):
        here = [res["reading"] for row, res in asked if row["task"] == task]
        lines.append(f"| {task} | {len(here)} | " + " | ".join(str(here.count(x)) for x in READINGS) + " |")
    every = [res["reading"] for _, res in asked]
    lines.append(f"| all | {len(every)} | " + " | ".join(str(every.count(x)) for x in READINGS) + " |")
    lines += ["", "| arm | task | base | seed | chosen | diagnose.py's cause | fresh agents (last, per seed) "
              "| solved | task's machine (loop, chosen) | reading | note |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for (row, first), res in zip(targets, results):
        fresh = ", ".join(f"{v:.2f}" for v in res["fresh"])
        solved = f"{sum(v >= SOLVED for v in res['fresh'])} of {len(res['fresh'])}" if res["fresh"] else ""
        task = f"{res['task'][0]:.2f}, {res['task'][1]:.2f}" if res["task"] else ""
        # A control was solved: the readings are of misses.
        reading = res["reading"] if first in ASKED or res["reading"] == "not read" else ""
        lines.append(f"| {row['arm']} | {row['task']} | {row['base']} | {row['seed']} | {row['chosen']} | {first} | "
                     f"{fresh} | {solved} | {task} | {reading} | {res['note']} |")
    groups, task = test
    lines += ["", "The refinement test (does the learned machine refine the task's along the demonstrations; "
              "ambiguous: the share of demonstration steps whose learned state is also seen with another task "
              "state), over every run directory of the units:", "",
              "| run directories | count | learned machine refines | ambiguous share: min | median | max |",
              "|---|---|---|---|---|---|"]
    for group in ("every job solved", "a job missed"):
        facts = groups[group]
        shares = sorted(share for _, share in facts)
        if shares:
            lines.append(f"| {group} | {len(facts)} | {sum(r for r, _ in facts)} | {shares[0]:.2f} | "
                         f"{statistics.median(shares):.2f} | {shares[-1]:.2f} |")
        else:
            lines.append(f"| {group} | 0 | | | | |")
    if groups["not reproduced"]:
        lines.append(f"| not reproduced | {groups['not reproduced']} | | | | |")
    lines += ["", f"SMIRL's machine under `machine = \"task\"` (the task's own) refines the task's in {sum(task)} of "
              f"{len(task)} task-machine run directories."]
    path = md_path(name)
    with open(path + ".tmp", "w") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(path + ".tmp", path)
    n = {kind: sum(f == kind for _, f in targets) for kind in ("solved (control)", "not reproduced")}
    print(f"wrote {protocol.rel(path)}: {sum(f in ASKED for _, f in targets)} jobs asked, "
          f"{n['not reproduced']} not reproduced, {n['solved (control)']} controls", flush=True)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Why each missed job of a finished preregistered evaluation missed: the choice, the agent, the
learned machine or the learned reward. Exploratory, after the tables; it changes no number of
them and no job's outcome.

Usage:
    python3 experiments/protocol/diagnose.py NAME --bin REACHER [--units ARM:ALGO,...] [--parallel N]

Reads `experiments/protocol/NAME/jobs.csv` (table.py's, so only after the whole plan finished)
and writes `experiments/protocol/NAME/diagnosis.md`. The jobs diagnosed are the missed ones
(reported policy below 0.9, or failed) of the units `--units` names, by default the protocol's
`[analysis] primary`. Each gets the first cause of this list that applies:

1. **failed**: the job failed (table.py's `why`); it has no policy to diagnose.
2. **choice**: a candidate of the final phase solved the final set (the oracle best candidate
   is at least 0.9): the choice by learned return took another.
3. **agent**: a fresh SAC agent trained on the job's final learned reward (`reacher retrain`,
   its SAC seed RETRAIN_SAC_SEED, the job's own number of steps, judged at the end on the
   ground truth's own evaluation episodes, 20 per branch at the standard config) solves the
   task: the reward leads there; the job's agent and its candidates did not get there.
4. **fresh fails, coarse machine**: a fresh agent on the learned reward does not solve the task
   either, and the learned machine the algorithm uses does not refine the task's perfect
   machine along the job's own demonstrations (`rm/report.txt`, smirl-paper's
   `rm/report_paper.txt`): one learned state stands for task states a reward may have to tell
   apart. The machine is a suspect, not a finding: a machine that does not refine may still
   carry what the task needs.
5. **fresh fails, refining machine**: the same, where the machine refines the task's (or the
   algorithm has none): the learned weights are the suspect.

One fresh agent per job: "agent" means that one seed solved, not that every seed would, and a
"fresh fails" job may be one seed's failure.

Beside the causes, per task, the file counts how often the refinement test says yes over the run
directories on disk, also where every job was solved: a test that is no everywhere does not
tell the machine from the weights.

Run directories are not committed. A missing one is prepared again with the frozen binary and
the command `run.py` used (so the configs, the task files and what they name must be the ones
the lock holds; it refuses otherwise), and must give the bytes the ledger's `prepared` entry records; a
missing job file is made again by `reacher job`, kept as `jobs/<algo>_seed<k>.diagnose.json`
(so table.py still finds only the ledger's bytes under the job's own name), and must give the
ledger's job fields (wall time aside). Either mismatch is reported as "not reproduced" and that
job is not diagnosed further.
A retraining table already in the run directory is read, not retrained. Nothing here writes the
ledger or the tables.
"""

import argparse
import concurrent.futures
import csv
import json
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
import run as protocol  # noqa: E402

SOLVED = 0.9
RETRAIN_SAC_SEED = 1000
CAUSES = ("failed", "choice", "agent", "fresh fails, coarse machine", "fresh fails, refining machine",
          "not reproduced")
REFINES = re.compile(r"refines the perfect machine along the (\d+) demonstrations: (true|false)"
                     r"(?: \((\d+) of (\d+) steps ambiguous\))?")
# The report of the learned machine each algorithm uses: smirl-paper learns its own (LRM as the
# paper has it); the product controls use SMIRL's.
MACHINE_REPORT = {"smirl": "report.txt", "smirl-paper": "report_paper.txt",
                  "maxent-product": "report.txt", "fkl-product": "report.txt"}
STATES = re.compile(r"learned machine: (\d+) states \((\d+) reachable\); perfect machine: (\d+) states")


def fail(msg):
    print(f"diagnose: {msg}", file=sys.stderr)
    sys.exit(2)


def number(text):
    """A jobs.csv score: None for an empty cell or "-" (no such policy)."""
    return None if text in ("", "-", None) else float(text)


def reported(row):
    """The reported policy's score: the chosen one, or the loop's own without a final phase."""
    chosen = number(row["chosen"])
    return number(row["loop"]) if chosen is None else chosen


def read_jobs(name):
    path = os.path.join(protocol.state_dir(name), "jobs.csv")
    if not os.path.isfile(path):
        fail(f"{protocol.rel(path)} does not exist: run `table.py {name}` when the plan has finished")
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def run_dirs(name, plan, lock):
    """{(arm, task, base, algo, seed): run.py's plan entry of the job's run directory}."""
    runs, jobs = protocol.plan_runs(name, plan, lock)
    out = {}
    for j in jobs:
        r = runs[j["run"]]
        out[(j["arm"], protocol.task_label(r["task"]), r["base"], j["algo"], j["seed"])] = r
    return out


def run_of(dirs, row):
    return dirs[(row["arm"], row["task"], int(row["base"]), row["algo"], int(row["seed"]))]


def set_threads(run_dir, threads):
    path = os.path.join(run_dir, "config.toml")
    with open(path) as fh:
        text = fh.read()
    new = re.sub(r"(?m)^threads = \d+$", f"threads = {threads}", text, count=1)
    if new != text:
        with open(path + ".tmp", "w") as fh:
            fh.write(new)
        os.replace(path + ".tmp", path)


def ensure_prepared(binary, r, prepared):
    """None when the run directory holds what the ledger recorded, else why not."""
    d = protocol.rel(r["dir"])
    if not os.path.isfile(os.path.join(r["dir"], "prepare.json")):
        cmd = [binary, "prepare", "--task", r["task"], "--algo", ",".join(r["algos"]),
               "--seeds", str(r["seeds"]), "--seed", str(r["base"]), "--config", r["config"],
               "--out", r["dir"], "--quiet"]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd, cwd=protocol.ROOT).returncode != 0:
            return "prepare failed"
    facts = protocol.prepare_facts(r["dir"])
    first = prepared.get(d)
    if first is None or {k: first.get(k) for k in facts} != facts:
        return "prepared with other bytes than the ledger records"
    return None


def without_wall(fields):
    return {k: v for k, v in fields.items() if k != "wall_secs"}


def ensure_job(binary, r, row, done):
    """None when the job file gives the ledger's job fields (wall time aside), else why not."""
    algo, seed = row["algo"], int(row["seed"])
    path = protocol.job_file(r["dir"], algo, seed)
    # A job run again here keeps its file under another name: its wall time differs from the
    # ledger's, and table.py refuses a job file whose hash is not the ledger's.
    again = path[: -len(".json")] + ".diagnose.json"
    if not os.path.isfile(path) and not os.path.isfile(again):
        cmd = [binary, "job", "--run", r["dir"], "--algo", algo, "--seed", str(seed), "--quiet"]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd, cwd=protocol.ROOT).returncode != 0:
            return "job failed when run again"
        os.replace(path, again)
    with open(path if os.path.isfile(path) else again) as fh:
        got = protocol.job_fields(json.load(fh))
    entry = done.get((protocol.rel(r["dir"]), algo, seed))
    if entry is None or entry.get("event") != "done" or without_wall(got) != without_wall(entry["job"]):
        return "job run again gave other results than the ledger records"
    return None


def lower_of_retrain(path):
    """The last evaluation's lower branch (or success rate without branches) and the best such
    value over the evaluations, from a retraining table."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        return None, None

    def lower(row):
        branches = [number(row.get(k)) for k in ("success_normal", "success_cancel")]
        branches = [b for b in branches if b is not None]
        return min(branches) if branches else number(row["success_rate"])
    values = [lower(row) for row in rows]
    return values[-1], max(values)


def retrain(binary, r, row):
    algo, seed = row["algo"], int(row["seed"])
    out = os.path.join(r["dir"], "retrain", f"{algo}_seed{seed}_sac{RETRAIN_SAC_SEED}.csv")
    if not os.path.isfile(out):
        cmd = [binary, "retrain", "--run", r["dir"], "--algo", algo, "--seed", str(seed),
               "--sac-seed", str(RETRAIN_SAC_SEED)]
        print("+", " ".join(cmd), flush=True)
        code = subprocess.run(cmd, cwd=protocol.ROOT, stdout=subprocess.DEVNULL).returncode
        if code != 0 or not os.path.isfile(out):
            return None, None, f"retrain exited with {code}"
    last, best = lower_of_retrain(out)
    return last, best, None


def machine_facts(r, algo):
    """The learned machine's states and whether it refines the perfect one, from the report of
    the machine `algo` uses (none for an algorithm without one)."""
    report = MACHINE_REPORT.get(algo)
    path = os.path.join(r["dir"], "rm", report) if report else None
    if path is None or not os.path.isfile(path):
        return {}
    with open(path) as fh:
        text = fh.read()
    out = {}
    m = REFINES.search(text)
    if m:
        out["refines"] = m.group(2) == "true"
        out["ambiguous"] = f"{m.group(3)} of {m.group(4)}" if m.group(3) else "0"
    m = STATES.search(text)
    if m:
        out["states"] = f"{m.group(1)} / {m.group(3)}"
    return out


def diagnose(binary, r, row, done, threads):
    """The diagnosis of one missed job (a dict of table columns)."""
    out = {"cause": None, "retrain": "", "retrain_best": "", "note": ""}
    if row["status"] != "done":
        out["cause"] = "failed"
        out["note"] = row.get("why", "")
        return out
    if (number(row["oracle"]) or 0.0) >= SOLVED:
        out["cause"] = "choice"
        return out
    why = ensure_job(binary, r, row, done)
    if why:
        out["cause"], out["note"] = "not reproduced", why
        return out
    set_threads(r["dir"], threads)
    last, best, why = retrain(binary, r, row)
    if why:
        out["cause"], out["note"] = "not reproduced", why
        return out
    out["retrain"], out["retrain_best"] = f"{last:.2f}", f"{best:.2f}"
    facts = machine_facts(r, row["algo"])
    if last >= SOLVED:
        out["cause"] = "agent"
    elif facts.get("refines") is False:
        out["cause"] = "fresh fails, coarse machine"
    elif facts.get("refines") is True or row["algo"] not in MACHINE_REPORT:
        out["cause"] = "fresh fails, refining machine"
    else:
        out["cause"], out["note"] = "not reproduced", f"no refinement line in rm/{MACHINE_REPORT[row['algo']]}"
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name")
    p.add_argument("--bin", required=True)
    p.add_argument("--units", help="ARM:ALGO,... (default: the protocol's [analysis] primary)")
    p.add_argument("--parallel", type=int, default=1)
    args = p.parse_args()
    name = args.name
    _, _, plan = protocol.load(name)
    version = protocol.binary_version(args.bin)
    if plan["commit"] not in version or "dirty" in version:
        fail(f"{args.bin} is not the frozen commit's binary: {version}")
    refs = args.units.split(",") if args.units else protocol.units_of(plan.get("analysis", {}).get("primary"))
    units = {protocol.unit_of(ref, "--units", "units") for ref in refs}
    if not units:
        fail("no units: give --units ARM:ALGO,...")
    lock = protocol.lock_if_any(name)
    if lock is None:
        fail(f"{protocol.rel(protocol.lock_path(name))} does not exist: no locked protocol")
    changed = protocol.inputs_changed(plan, lock)
    if changed:
        fail(f"{changed} differs from what the lock holds: a run directory prepared again here "
             "would not be the protocol's; diagnose in a worktree of a commit whose configs and "
             f"task files are the lock's, such as its head ({lock.get('head', '')[:12]}), with this "
             "checkout's ledger.jsonl and jobs.csv copied into it")
    rows = read_jobs(name)
    dirs = run_dirs(name, plan, lock)
    if len(rows) != len(dirs):
        fail(f"jobs.csv has {len(rows)} rows, the plan {len(dirs)} jobs: diagnose a finished plan only")
    ledger = protocol.read_ledger(name)
    done = protocol.finished_jobs(name, ledger)
    prepared = {}
    for e in ledger:
        if e.get("event") == "prepared":
            prepared.setdefault(e["dir"], e)
    missed = [row for row in rows if (row["arm"], row["algo"]) in units
              and (row["status"] != "done" or (reported(row) or 0.0) < SOLVED)]
    # Prepares first, one run directory at a time; then the jobs side by side.
    refused = {}
    for row in missed:
        if row["status"] == "done" and (number(row["oracle"]) or 0.0) < SOLVED:
            r = run_of(dirs, row)
            if r["dir"] not in refused:
                refused[r["dir"]] = ensure_prepared(args.bin, r, prepared)
    threads = 1 if args.parallel > 1 else 2
    results = [None] * len(missed)
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.parallel)) as pool:
        futures = {}
        for i, row in enumerate(missed):
            r = run_of(dirs, row)
            if refused.get(r["dir"]):
                results[i] = {"cause": "not reproduced", "retrain": "", "retrain_best": "",
                              "note": refused[r["dir"]]}
            else:
                futures[pool.submit(diagnose, args.bin, r, row, done, threads)] = i
        for f in concurrent.futures.as_completed(futures):
            results[futures[f]] = f.result()
    write(name, refs, missed, results, dirs, refinement_check(rows, units, dirs))


def refinement_check(rows, units, dirs):
    """How often the refinement test says yes at all: over the units' run directories on disk
    (rebuilt above or left from the run), the learned machines that refine the perfect one, and
    the same among run directories where every job of the units was solved."""
    by_dir = {}
    for row in rows:
        if (row["arm"], row["algo"]) in units:
            r = run_of(dirs, row)
            facts = machine_facts(r, row["algo"])
            if "refines" in facts:
                entry = by_dir.setdefault(r["dir"], {"refines": facts["refines"], "all_solved": True})
                entry["all_solved"] &= row["status"] == "done" and (reported(row) or 0.0) >= SOLVED
    solved = [e for e in by_dir.values() if e["all_solved"]]
    return (f"Refinement test on the run directories on disk: {sum(e['refines'] for e in by_dir.values())} of "
            f"{len(by_dir)} learned machines refine the perfect one; {sum(e['refines'] for e in solved)} of the "
            f"{len(solved)} where every job was solved.")


def write(name, refs, missed, results, dirs, refinement):
    counts = {}
    for res in results:
        counts[res["cause"]] = counts.get(res["cause"], 0) + 1
    lines = [
        f"# {name}: why the missed jobs missed (exploratory)",
        "",
        f"Written by `python3 experiments/protocol/diagnose.py {name} --bin REACHER` from `jobs.csv` "
        "(the causes and their order: the script's docstring). Units: " + ", ".join(f"`{r}`" for r in refs) + ".",
        "",
        "| cause | jobs |",
        "|---|---|",
    ]
    causes = [c for c in CAUSES if counts.get(c)]
    lines += [f"| {cause} | {counts[cause]} |" for cause in causes]
    lines += ["", "| task | missed | " + " | ".join(causes) + " |", "|---|---|" + "---|" * len(causes)]
    for task in dict.fromkeys(row["task"] for row in missed):
        here = [res["cause"] for row, res in zip(missed, results) if row["task"] == task]
        lines.append(f"| {task} | {len(here)} | " + " | ".join(str(here.count(c)) for c in causes) + " |")
    lines += ["", f"{len(missed)} missed jobs. {refinement}", "",
              "| arm | task | base | seed | loop | chosen | oracle | cause | fresh agent (last, best) "
              "| machine states (learned / perfect) | refines along the demonstrations | note |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row, res in zip(missed, results):
        r = run_of(dirs, row)
        facts = machine_facts(r, row["algo"])
        refines = "" if "refines" not in facts else (
            "yes" if facts["refines"] else f"no ({facts['ambiguous']} steps ambiguous)")
        fresh = f"{res['retrain']}, {res['retrain_best']}" if res["retrain"] else ""
        lines.append(f"| {row['arm']} | {row['task']} | {row['base']} | {row['seed']} | {row['loop']} | "
                     f"{row['chosen']} | {row['oracle']} | {res['cause']} | {fresh} | {facts.get('states', '')} | "
                     f"{refines} | {res['note']} |")
    path = os.path.join(protocol.state_dir(name), "diagnosis.md")
    with open(path + ".tmp", "w") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(path + ".tmp", path)
    print(f"wrote {protocol.rel(path)}: {len(missed)} missed jobs", flush=True)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""SMIRL's mechanisms outside LRM ablated on the development range (plan.md, fixed before any run).

    python3 experiments/reacher/mechanisms/ablation.py run --stage 1|2|together [--until HH:MM]
        [--parallel 2] [--bin-dir DIR]
    python3 experiments/reacher/mechanisms/ablation.py table [--out DIR]

`run` prepares one run directory per (task, base) of the stage under runs/mechanisms/ and runs
its jobs (plan.md), two at a time by default, bases outer. The ablation outlives its run
directories, which a fresh checkout does not have: its ledger, `ledger.jsonl.gz` beside this
script (commit it at the end of each session), records the binary's version, every start, every
failure and each finished job's record less its per-iteration rows. A job the ledger records
done is not run again, so the command resumes on any checkout; a job that exits with an error,
runs past 60 minutes or is killed three times is recorded failed and not run again (a job killed
by a signal, as at the end of a session, runs again; every start counts). `--until` (UTC) starts
no job after that time. `--ledger PATH` reads and writes another ledger.
`--stage together` runs, on every pair of the completed stages, one job with every mechanism
that goes turned off together (the table's reading). The binaries of --bin-dir (`reacher`,
`smirl_ablation`) must be built at the commit that last changed plan.md, not dirty.

`table` reads every record of the ledger into jobs.csv (one row per policy read) and writes ablation.md by
the rule of plan.md (`--out DIR`: both files there instead of beside this script).
"""
import argparse
import csv
import datetime
import gzip
import json
import os
import random
import re
import subprocess
import sys
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
HERE = os.path.dirname(os.path.abspath(__file__))
LEDGER = os.path.join(HERE, "ledger.jsonl.gz")
TASKS = ["or", "sequential", "if", "composite"]
STAGES = {1: [10, 20, 30, 40, 50, 60], 2: [70, 80, 90, 100, 153, 219]}
CONFIG = "experiments/reacher/config.toml"
# Mechanisms in smirl_ablation's order; the first four need a run of their own.
MECHANISMS = ["clock", "counterfactual_states", "event_gated_visits", "shaping", "final_phase",
              "reset_agent", "selection_cut"]
RUN_MECHANISMS = MECHANISMS[:4]
READ_MECHANISMS = MECHANISMS[4:]
RUN_JOBS = ["standard", "second_draw"] + [f"without_{m}" for m in RUN_MECHANISMS]
SOLVED = 0.9
RESAMPLES = 10_000
TIMEOUT_SECS = 3600
MAX_STARTS = 3
MAX_LEFT_OUT = 2


def run_dir(runs, task, base):
    return os.path.join(runs, f"{task}-b{base}")


def ablation_name(mechanisms):
    return "+".join(m for m in MECHANISMS if m in mechanisms)


def raw_record_path(runs, task, base, job):
    """The record a job writes in its run directory; `job`: standard, second_draw, or a tuple
    of mechanisms off."""
    d = run_dir(runs, task, base)
    if job == "standard":
        return os.path.join(d, "jobs", f"smirl_seed{base}.json")
    if job == "second_draw":
        return os.path.join(d, "jobs", f"smirl_seed{base + 1}.json")
    return os.path.join(d, "ablation", ablation_name(job), "jobs", f"smirl_seed{base}.json")


# The ledger --------------------------------------------------------------------------------------

def read_ledger():
    """Every event of the ledger, in order (none before the first session)."""
    if not os.path.exists(LEDGER):
        return []
    with gzip.open(LEDGER, "rt") as fh:
        return [json.loads(line) for line in fh if line.strip()]


def append(event):
    """Adds one event; the file is written whole to a temporary name and renamed, so an
    interrupted write leaves the previous ledger."""
    lines = [json.dumps(e, sort_keys=True) for e in read_ledger() + [event]]
    partial = LEDGER + ".partial"
    with open(partial, "wb") as raw:
        with gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as fh:
            fh.write(("\n".join(lines) + "\n").encode())
    os.replace(partial, LEDGER)


def key_of(e):
    return (e["task"], int(e["base"]), e["job"])


def read_failed():
    """The failed jobs: {(task, base, job key)} (a failed prepare as job key `prepare`)."""
    return {key_of(e) for e in read_ledger() if e["event"] == "failed"}


def read_records():
    """{(task, base, job key): record} of the finished jobs."""
    return {key_of(e): e["record"] for e in read_ledger() if e["event"] == "done"}


def fail(task, base, job, why):
    append({"event": "failed", "task": task, "base": base, "job": job, "why": why})


def keep_record(runs, task, base, job):
    """Records a finished job: its record less the per-iteration rows (all the table reads: the
    final phase's candidates, the loop's own final set, the wall time)."""
    with open(raw_record_path(runs, task, base, job)) as fh:
        record = json.load(fh)
    kept = {k: record.get(k) for k in ("algo", "seed", "final_policy", "loop_final_set", "wall_secs")}
    append({"event": "done", "task": task, "base": base, "job": job_key(job), "record": kept})


def job_key(job):
    return job if isinstance(job, str) else "without_" + ablation_name(job)


def parse_job(name):
    if name in ("standard", "second_draw"):
        return name
    return tuple(m for m in MECHANISMS if m in name.removeprefix("without_").split("+"))


# Running ---------------------------------------------------------------------------------------

def config_for(runs):
    """The standard config with `threads = 1`, whatever --parallel is (a job's results do not
    depend on it, and every session then prepares with the same file), written once into the
    runs directory."""
    with open(os.path.join(ROOT, CONFIG)) as fh:
        text = fh.read()
    text, n = re.subn(r"(?m)^threads = \d+$", "threads = 1", text, count=1)
    if n != 1:
        sys.exit(f"ablation: {CONFIG} has no `threads = N` line")
    path = os.path.join(runs, "config.toml")
    if os.path.exists(path):
        with open(path) as fh:
            if fh.read() != text:
                sys.exit(f"ablation: {path} differs from {CONFIG} with `threads = 1`: "
                         "the config changed since the first session")
    else:
        with open(path, "w") as fh:
            fh.write(text)
    return path


def check_binaries(bins):
    """Both binaries of the plan's commit, clean; the version recorded once."""
    plan_commit = subprocess.run(["git", "log", "-1", "--format=%H", "--", "experiments/reacher/mechanisms/plan.md"],
                                 cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
    versions = {b: subprocess.run([p, "--version"], capture_output=True, text=True, check=True).stdout.strip()
                for b, p in bins.items()}
    if len(set(versions.values())) != 1:
        sys.exit(f"ablation: the binaries differ: {versions}")
    got = versions["reacher"]
    if not plan_commit or f"(commit {plan_commit})" not in got:
        sys.exit(f"ablation: the binaries are `{got}`; the plan needs a clean build of the commit that "
                 f"last changed plan.md ({plan_commit or 'none: commit plan.md first'})")
    want = recorded_version()
    if want is None:
        append({"event": "version", "version": got})
    elif want != got:
        sys.exit(f"ablation: the binaries are `{got}`, but the jobs of {LEDGER} were run by `{want}`")
    return got


def recorded_version():
    return next((e["version"] for e in read_ledger() if e["event"] == "version"), None)


def pair_failed(failed, task, base, job):
    return (task, base, job_key(job)) in failed or (task, base, "prepare") in failed


def prepare(bins, runs, config, task, base):
    """True when the pair's run directory is prepared; a failed prepare is recorded."""
    d = run_dir(runs, task, base)
    if os.path.isfile(os.path.join(d, "prepare.json")):
        return True
    cmd = [bins["reacher"], "prepare", "--task", task, "--algo", "smirl", "--seeds", "2",
           "--seed", str(base), "--config", config, "--out", d, "--quiet"]
    print("+", " ".join(cmd), flush=True)
    code = subprocess.run(cmd, cwd=ROOT).returncode
    if code < 0:
        sys.exit(f"ablation: prepare of {d} was killed by signal {-code}; run again")
    if code != 0:
        fail(task, base, "prepare", f"exit {code}")
        return False
    return True


def planned_jobs(stage):
    if stage in STAGES:
        return [(t, b, j) for b in STAGES[stage] for t in TASKS for j in map(parse_job, RUN_JOBS)]
    together = read_together()
    if together is None:
        sys.exit("ablation: --stage together needs the table's reading of a complete stage; run `table` first")
    if not together:
        sys.exit("ablation: no mechanism goes: nothing to run together")
    if not any(m in RUN_MECHANISMS for m in together):
        sys.exit("ablation: the mechanisms that go are read from the standard job: nothing to run together")
    bases = [b for s in completed_stages() for b in STAGES[s]]
    return [(t, b, tuple(together)) for b in bases for t in TASKS]


def run(args):
    runs = os.path.join(ROOT, args.runs)
    bin_dir = os.path.abspath(args.bin_dir)
    bins = {b: os.path.join(bin_dir, b) for b in ("reacher", "smirl_ablation")}
    for b in bins.values():
        if not os.access(b, os.X_OK):
            sys.exit(f"ablation: no binary {b} (cargo build --release --bin reacher --bin smirl_ablation)")
    os.makedirs(runs, exist_ok=True)
    print("binary:", check_binaries(bins), flush=True)
    config = config_for(runs)
    until = None
    if args.until:
        h, m = (int(x) for x in args.until.split(":"))
        now = datetime.datetime.now(datetime.timezone.utc)
        until = now.replace(hour=h, minute=m, second=0, microsecond=0)
        if until <= now:
            until += datetime.timedelta(days=1)
    stage = args.stage if args.stage == "together" else int(args.stage)
    plan = planned_jobs(stage)

    # A job that finished while its session was ending, before the ledger recorded it.
    done = read_records()
    for t, b, j in plan:
        if (t, b, job_key(j)) not in done and os.path.isfile(raw_record_path(runs, t, b, j)):
            keep_record(runs, t, b, j)

    def open_jobs():
        failed, done = read_failed(), read_records()
        return [(t, b, j) for t, b, j in plan
                if (t, b, job_key(j)) not in done and not pair_failed(failed, t, b, j)]

    todo = open_jobs()
    print(f"stage {stage}: {len(todo)} of {len(plan)} jobs to run", flush=True)
    starts = {}
    for e in read_ledger():
        if e["event"] == "start":
            starts[key_of(e)] = starts.get(key_of(e), 0) + 1
    running = []
    while todo or running:
        for p, key, log, began in list(running):
            timed_out = p.poll() is None and time.time() - began > TIMEOUT_SECS
            if timed_out:
                p.kill()
                p.wait()
            if p.poll() is None:
                continue
            running.remove((p, key, log, began))
            log.close()
            t, b, j = key
            if timed_out:
                state = "FAILED (timeout)"
                fail(t, b, job_key(j), "timeout")
            elif p.returncode > 0:
                state = f"FAILED (exit {p.returncode})"
                fail(t, b, job_key(j), f"exit {p.returncode}")
            elif p.returncode < 0 and starts.get((t, b, job_key(j)), 0) >= MAX_STARTS:
                state = f"FAILED (killed, start {MAX_STARTS})"
                fail(t, b, job_key(j), f"killed {-p.returncode}")
            elif p.returncode == 0:
                keep_record(runs, t, b, j)
                state = "done"
            else:
                state = f"killed ({p.returncode}), runs again"
            print(f"{state}: {t} {b} {job_key(j)}", flush=True)
        late = until is not None and datetime.datetime.now(datetime.timezone.utc) >= until
        while todo and len(running) < args.parallel and not late:
            task, base, job = todo.pop(0)
            if not prepare(bins, runs, config, task, base):
                todo = [x for x in todo if (x[0], x[1]) != (task, base)]
                continue
            d = run_dir(runs, task, base)
            if job in ("standard", "second_draw"):
                seed = base if job == "standard" else base + 1
                cmd = [bins["reacher"], "job", "--run", d, "--algo", "smirl", "--seed", str(seed), "--quiet"]
            else:
                cmd = [bins["smirl_ablation"], "--run", d, "--seed", str(base), "--without", ",".join(job)]
            key = (task, base, job_key(job))
            starts[key] = starts.get(key, 0) + 1
            append({"event": "start", "task": task, "base": base, "job": key[2]})
            log = open(os.path.join(d, f"{job_key(job)}.log"), "a")
            print("+", " ".join(cmd), flush=True)
            running.append((subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT),
                            (task, base, job), log, time.time()))
        if late and not running:
            break
        time.sleep(2)
    print(f"stage {stage}: {len(open_jobs())} jobs left", flush=True)


# Reading ---------------------------------------------------------------------------------------

def lower_branch(score):
    """Success on the lower branch of a final-set evaluation (a branch without episodes is
    ignored; a task without branches has one), as eval1 scores it."""
    b = score.get("branches")
    if not b:
        return score["success_rate"]
    return min(s / e for e, s in zip(b["episodes"], b["successes"]) if e > 0)


def first_best(values):
    """The first index of the highest value, as the final phase chooses (a NaN, JSON null, is
    never highest)."""
    best = None
    for i, v in enumerate(values):
        if v is not None and v == v and (best is None or v > values[best]):
            best = i
    return 0 if best is None else best


def read_policy(record, off):
    """The score of the policy a job reports with the read mechanisms in `off` turned off."""
    final = record.get("final_policy")
    if "final_phase" in off or not final:
        return lower_branch(record["loop_final_set"])
    cands = final["candidates"]
    keep = [i for i, c in enumerate(cands)
            if "reset_agent" not in off or c.get("agent", "co-trained") == "co-trained"]
    value = [cands[i]["learned_return"] if "selection_cut" in off
             else cands[i].get("cut_return", cands[i]["learned_return"]) for i in keep]
    return lower_branch(cands[keep[first_best(value)]]["final_set"])


def policies_of(job, record, where, together=None):
    """(policy name, score) read from one job record; from the standard job also the
    mechanisms that go together when all of them are read mechanisms."""
    if job == "second_draw":
        return [("second_draw", read_policy(record, ()))]
    if job == "standard":
        chosen = record["final_policy"]["chosen"]
        if lower_branch(record["final_policy"]["candidates"][chosen]["final_set"]) != read_policy(record, ()):
            sys.exit(f"ablation: {where}: the record's choice is not the rule's (first of highest selection return)")
        cands = record["final_policy"]["candidates"]
        out = ([("standard", read_policy(record, ()))]
               + [(f"without_{m}", read_policy(record, (m,))) for m in READ_MECHANISMS]
               + [("random_candidate", sum(lower_branch(c["final_set"]) for c in cands) / len(cands))])
        if together and len(together) > 1 and all(m in READ_MECHANISMS for m in together):
            out.append((job_key(tuple(together)), read_policy(record, tuple(together))))
        return out
    read_off = tuple(m for m in job if m in READ_MECHANISMS)
    return [(job_key(job), read_policy(record, read_off))]


def collect(together):
    """Rows (task, base, policy, score, wall_secs) of every job record of every stage; a failed
    job gives rows with an empty score."""
    rows = []
    failed, records = read_failed(), read_records()
    run_together = together and any(m in RUN_MECHANISMS for m in together)
    jobs = list(map(parse_job, RUN_JOBS)) + ([tuple(together)] if run_together else [])
    for stage, bases in STAGES.items():
        for base in bases:
            for task in TASKS:
                for job in jobs:
                    record = records.get((task, base, job_key(job)))
                    if record is not None:
                        where = f"{LEDGER}: {task} {base} {job_key(job)}"
                        for policy, score in policies_of(job, record, where, together):
                            rows.append({"stage": stage, "task": task, "base": base, "policy": policy,
                                         "score": f"{score:.4f}", "wall_secs": f"{record['wall_secs']:.0f}"})
                    elif pair_failed(failed, task, base, job):
                        names = [job_key(job)] + ([f"without_{m}" for m in READ_MECHANISMS] + ["random_candidate"]
                                                  if job == "standard" else [])
                        rows += [{"stage": stage, "task": task, "base": base, "policy": n, "score": "",
                                  "wall_secs": "failed"} for n in names]
    return rows


def completed_stages():
    """The stages whose every planned job has a record or failed, in order, without a gap."""
    failed, records = read_failed(), read_records()
    done = []
    for stage, bases in STAGES.items():
        if all((t, b, job_key(j)) in records or pair_failed(failed, t, b, j)
               for b in bases for t in TASKS for j in map(parse_job, RUN_JOBS)):
            done.append(stage)
        else:
            break
    return done


def bootstrap(values_by_unit, name):
    """95 % percentile interval of the mean over units, resampling units."""
    rng = random.Random(name)
    units = list(values_by_unit)
    n = len(units)
    means = sorted(sum(values_by_unit[units[rng.randrange(n)]] for _ in range(n)) / n
                   for _ in range(RESAMPLES))
    return means[int(0.025 * RESAMPLES)], means[int(0.975 * RESAMPLES) - 1]


def compare(scores, on, off, bases, name):
    """Paired reading of policy `off` against `on` on the pairs of `bases` that have both."""
    wanted = [(t, b) for b in bases for t in TASKS]
    pairs = [k for k in wanted if scores.get(k, {}).get(on) is not None
             and scores.get(k, {}).get(off) is not None]
    if not pairs:
        return None
    a = {k: scores[k][on] for k in pairs}
    z = {k: scores[k][off] for k in pairs}
    diff = {k: a[k] - z[k] for k in pairs}
    per_base = {}
    for (t, b), d in diff.items():
        per_base.setdefault(b, []).append(d)
    per_base = {b: sum(v) / len(v) for b, v in per_base.items()}
    lo, hi = bootstrap(per_base, name)
    plo, phi = bootstrap(diff, name + "/pairs")
    return {"pairs": pairs, "left_out": [k for k in wanted if k not in pairs],
            "on": sum(a[k] >= SOLVED for k in pairs), "off": sum(z[k] >= SOLVED for k in pairs),
            "lost": [k for k in pairs if a[k] >= SOLVED > z[k]],
            "gained": [k for k in pairs if z[k] >= SOLVED > a[k]],
            "mean": sum(diff.values()) / len(diff), "lo": lo, "hi": hi, "plo": plo, "phi": phi}


def readings(scores, stages):
    """{mechanism: (reading, stage read at, comparison)} by the plan's rule on the completed
    stages; a comparison missing more than MAX_LEFT_OUT pairs of its stage is not read."""
    out = {}
    for m in MECHANISMS:
        for i, stage in enumerate(stages):
            bases = [b for s in stages[:i + 1] for b in STAGES[s]]
            c = compare(scores, "standard", f"without_{m}", bases, m)
            if c is None or len(c["left_out"]) > MAX_LEFT_OUT * (i + 1):
                out[m] = ("not read: too many pairs left out", stage, c)
                break
            if c["lo"] > 0:
                out[m] = ("pays", stage, c)
                break
            if c["hi"] < 0:
                out[m] = ("costs", stage, c)
                break
            last = stage == max(STAGES)
            out[m] = ("does not show it pays" if last else "not resolved", stage, c)
            if last:
                break
    return out


def goes(reading):
    return reading in ("costs", "does not show it pays")


def read_together():
    """The mechanisms that go by the readings of the completed stages, or None before stage 1
    is complete or while a mechanism is not resolved and stage 2 is not."""
    stages = completed_stages()
    if not stages:
        return None
    rows = collect(None)
    r = readings(scores_of(rows), stages)
    if any(v[0] == "not resolved" for v in r.values()):
        return None
    return [m for m in MECHANISMS if goes(r[m][0])]


def scores_of(rows):
    scores = {}
    for row in rows:
        scores.setdefault((row["task"], int(row["base"])), {})[row["policy"]] = (
            float(row["score"]) if row["score"] != "" else None)
    return scores


def names(keys):
    return ", ".join(f"{t} {b}" for t, b in keys) if keys else "-"


def table(args):
    together = read_together()
    rows = collect(together)
    out = os.path.abspath(args.out) if args.out else HERE
    with open(os.path.join(out, "jobs.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, ["stage", "task", "base", "policy", "score", "wall_secs"], lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    scores = scores_of(rows)
    stages = completed_stages()
    version = recorded_version() or "unknown"
    lines = [
        "# SMIRL's mechanisms outside LRM on the development range",
        "",
        f"Made by `python3 experiments/reacher/mechanisms/ablation.py table` from the job records in "
        f"its ledger `ledger.jsonl.gz` (plan and rule: [plan.md](plan.md)); every row is in `jobs.csv`. Binary: "
        f"{version}. Tasks {', '.join(TASKS)}. Score: success on the lower branch of the job's final "
        f"set; solved at ≥ {SOLVED}. Difference: on − off, mean over pairs; 95 % bootstrap interval "
        f"over bases ({RESAMPLES} resamples; the interval over (task, base) pairs beside it, not read).",
        "",
        f"Completed stages: {', '.join(map(str, stages)) or 'none'} "
        f"(stage 1: bases {', '.join(map(str, STAGES[1]))}; stage 2: {', '.join(map(str, STAGES[2]))}).",
        "",
    ]
    if not stages:
        have = {(t, b) for (t, b), v in scores.items() if v.get("standard") is not None}
        lines += [f"**Stage 1 is not complete** ({len(have)} of {len(TASKS) * len(STAGES[1])} pairs have a "
                  "standard job): nothing is read.", ""]
    header = ["| mechanism off | stage | pairs | solved on | solved off | lost | gained | mean difference "
              "[95 % over bases] | [over pairs] | reading |", "|---|---|---|---|---|---|---|---|---|---|"]

    def row(label, stage, c, reading):
        return (f"| {label} | {stage} | {len(c['pairs'])} | {c['on']} | {c['off']} | {len(c['lost'])} | "
                f"{len(c['gained'])} | {c['mean']:+.3f} [{c['lo']:+.3f}, {c['hi']:+.3f}] | "
                f"[{c['plo']:+.3f}, {c['phi']:+.3f}] | {reading} |")

    if stages:
        all_bases = [b for s in stages for b in STAGES[s]]
        r = readings(scores, stages)
        lines += header
        c = compare(scores, "standard", "second_draw", all_bases, "second_draw")
        if c:
            lines.append(row("none: a second draw (SAC seed B + 1)", max(stages), c, "descriptive"))
        for m in MECHANISMS:
            reading, stage, c = r[m]
            if c:
                lines.append(row(m, stage, c, reading))
        c = compare(scores, "standard", "random_candidate", all_bases, "random_candidate")
        if c:
            lines.append(row("the choice (a random candidate instead; not a mechanism)", max(stages), c, "-"))
        if together is not None:
            key = "without_" + ablation_name(together) if together else None
            c = key and compare(scores, "standard", key, all_bases, "together")
            if not together:
                lines += ["", "Together: no mechanism goes."]
            elif not c or len(c["left_out"]) > MAX_LEFT_OUT * len(stages):
                lines += ["", f"Together ({', '.join(together)} off at once): not run yet "
                          "(`ablation.py run --stage together`), or too many pairs left out."]
            else:
                verdict = ("they pay as a group and stay" if c["lo"] > 0 else "they go")
                lines += ["", header[0], header[1],
                          row(f"together: {', '.join(together)}", max(stages), c, verdict)]
        lines += ["", "Per task (solved on / off; lost and gained, by base):", "",
                  "| mechanism off | " + " | ".join(TASKS) + " |", "|---|" + "---|" * len(TASKS)]
        for label, off in [("second draw", "second_draw")] + [(m, f"without_{m}") for m in MECHANISMS]:
            cells = []
            for t in TASKS:
                sub = {k: v for k, v in scores.items() if k[0] == t}
                c = compare(sub, "standard", off, all_bases, f"{off}-{t}")
                cells.append("-" if c is None else
                             f"{c['on']}/{c['off']} of {len(c['pairs'])}; lost "
                             f"{','.join(str(b) for _, b in c['lost']) or '-'}; gained "
                             f"{','.join(str(b) for _, b in c['gained']) or '-'}")
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
    failed = sorted(read_failed())
    lines += ["", f"Failed (left out of the comparisons that need them): "
              f"{', '.join(f'{t} {b} {j}' for t, b, j in failed) or 'none'}."]
    with open(os.path.join(out, "ablation.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


def main():
    global LEDGER
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("command", choices=["run", "table"])
    p.add_argument("--stage", choices=["1", "2", "together"], help="run: which jobs")
    p.add_argument("--until", help="run: UTC HH:MM after which no job starts")
    p.add_argument("--parallel", type=int, default=2)
    p.add_argument("--bin-dir", default=os.path.join(ROOT, "target", "release"))
    p.add_argument("--runs", default="runs/mechanisms", help="run: where the run directories go")
    p.add_argument("--ledger", help=f"the ledger to read and write (default: {os.path.relpath(LEDGER, ROOT)})")
    p.add_argument("--out", help="table: directory for jobs.csv and ablation.md (default: beside this script)")
    args = p.parse_args()
    if args.ledger:
        LEDGER = os.path.abspath(args.ledger)
    if args.parallel < 1:
        sys.exit("ablation: --parallel must be at least 1")
    if args.command == "run":
        if not args.stage:
            sys.exit("ablation: run needs --stage 1, 2 or together")
        run(args)
    else:
        table(args)


if __name__ == "__main__":
    main()

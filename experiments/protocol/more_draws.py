#!/usr/bin/env python3
"""More SAC draws for machine_or_reward.py's readings: is a "learned machine" reading the
machine, or one unlucky draw? Exploratory, on spent bases; it writes no ledger or table.

Usage:
    python3 experiments/protocol/more_draws.py NAME --bin REACHER --jobs TASK:BASE,... \
        [--extra 2] [--parallel N]

machine_or_reward.py compares one job of SMIRL on its learned machine with one job on the
task's own machine (`[smirl] machine = "task"`), each a single SAC draw. For every TASK:BASE
(TASK as the run directory names it) this script prepares, under
`runs/protocol/NAME-more-draws/`, the job's run directory again with `--seeds 1+EXTRA` — once
with the job's config (the learned machine) and once with machine_or_reward.py's task-machine
config — checks that the learned machine and the annotated demonstrations are the bytes of the
original run directories (another prepare would be another question, and the job is not read),
and runs SMIRL at the EXTRA SAC seeds after the base (B+1, …). The base's own seed is read from
the original job files (`runs/protocol/NAME/…`, or diagnose.py's rerun of a lost one, which it
checked against the ledger; `runs/protocol/NAME-task-machine/…`), not rerun. It prints, per job, the chosen policy's lower-branch success of every draw on each
machine, and how many of them solve (>= 0.9).

Run from a checkout whose configs and task files are the protocol's (the run directories'
names carry the config's hash), with the binary the protocol ran.
"""

import argparse
import concurrent.futures
import glob
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import diagnose  # noqa: E402
import run as protocol  # noqa: E402
import table  # noqa: E402

SOLVED = 0.9
CHECKED = ("rm/learned.txt", "expert_data.bin")


def original_dir(root, task, base):
    found = sorted(glob.glob(os.path.join(root, f"{task}-b{base}-*")))
    found = [d for d in found if os.path.isdir(d)]
    if len(found) != 1:
        sys.exit(f"more_draws: {len(found)} run directories {root}/{task}-b{base}-*, not one")
    return found[0]


def chosen_score(path):
    """The reported policy's lower branch: the final phase's choice, else the loop's own."""
    with open(path) as fh:
        loop, chosen, _, _ = table.policies(protocol.job_fields(json.load(fh)), path)
    return (chosen or loop)[0]


def prepare(binary, original, out, extra, threads):
    """Prepare `out` like `original` with 1 + extra seeds; None, or why it is not read."""
    with open(os.path.join(original, "prepare.json")) as fh:
        prepared = json.load(fh)
    config = os.path.join(original, "config.toml")
    if not os.path.isfile(os.path.join(out, "prepare.json")):
        if os.path.exists(out):
            return f"{out} exists without prepare.json: not overwritten"
        os.makedirs(os.path.dirname(out), exist_ok=True)
        cmd = [binary, "prepare", "--task", prepared["task"], "--algo", "smirl", "--seeds",
               str(1 + extra), "--seed", str(prepared["seed"]), "--config", config, "--out", out,
               "--quiet"]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd, cwd=protocol.ROOT).returncode != 0:
            return "prepare failed"
        diagnose.set_threads(out, threads)
    for f in CHECKED:
        if protocol.sha256_of(os.path.join(out, f)) != protocol.sha256_of(os.path.join(original, f)):
            return f"{f} differs from {protocol.rel(original)}'s"
    return None


def job(binary, run_dir, seed):
    path = protocol.job_file(run_dir, "smirl", seed)
    if not os.path.isfile(path):
        cmd = [binary, "job", "--run", run_dir, "--algo", "smirl", "--seed", str(seed), "--quiet"]
        print("+", " ".join(cmd), flush=True)
        if subprocess.run(cmd, cwd=protocol.ROOT).returncode != 0 or not os.path.isfile(path):
            return None
    return chosen_score(path)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("name")
    p.add_argument("--bin", required=True)
    p.add_argument("--jobs", required=True, help="TASK:BASE,...")
    p.add_argument("--extra", type=int, default=2)
    p.add_argument("--parallel", type=int, default=1)
    args = p.parse_args()
    if not 1 <= args.extra <= 9:
        sys.exit("more_draws: --extra must be 1..9")
    root = protocol.run_root(args.name)
    plan, rows = [], []
    for item in args.jobs.split(","):
        task, _, base = item.partition(":")
        if not base.isdigit():
            sys.exit(f"more_draws: --jobs item {item!r} is not TASK:BASE")
        base = int(base)
        learned = original_dir(root, task, base)
        task_machine = os.path.join(root + "-task-machine", os.path.basename(learned))
        row = {"task": task, "base": base, "why": "", "draws": {}}
        for machine, original in (("learned", learned), ("task", task_machine)):
            out = os.path.join(root + "-more-draws", machine, os.path.basename(learned))
            why = prepare(args.bin, original, out, args.extra, 1 if args.parallel > 1 else 2)
            if why:
                row["why"] = f"{machine}: {why}"
                break
            first = protocol.job_file(original, "smirl", base)
            if not os.path.isfile(first):
                # diagnose.py's rerun of a job whose file was lost, checked against the ledger.
                first = first[: -len(".json")] + ".diagnose.json"
            row["draws"][machine] = [chosen_score(first)] + [None] * args.extra
            for k in range(1, 1 + args.extra):
                plan.append((row, machine, k, out, base + k))
        rows.append(row)
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.parallel) as pool:
        futures = {pool.submit(job, args.bin, out, seed): (row, machine, k)
                   for row, machine, k, out, seed in plan}
        for fut in concurrent.futures.as_completed(futures):
            row, machine, k = futures[fut]
            row["draws"][machine][k] = fut.result()

    print(f"\n`python3 experiments/protocol/more_draws.py {args.name} --bin REACHER --jobs "
          f"{args.jobs} --extra {args.extra}`; SMIRL's chosen policy, lower branch of the final "
          f"set, SAC seeds B, B+1, …, B+{args.extra} (B's job is the protocol's, or "
          "machine_or_reward.py's on the task's machine).\n")
    print("| task | base | learned machine | solved | task's machine | solved | note |")
    print("|---|---|---|---|---|---|---|")
    for row in rows:
        cells = []
        for machine in ("learned", "task"):
            got = row["draws"].get(machine)
            if not got:
                cells += ["—", "—"]
                continue
            shown = ", ".join("failed" if v is None else f"{v:.2f}" for v in got)
            solved = sum(v is not None and v >= SOLVED for v in got)
            cells += [shown, f"{solved} of {len(got)}"]
        print(f"| {row['task']} | {row['base']} | " + " | ".join(cells) + f" | {row['why']} |")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The tables of a preregistered evaluation, from its committed ledger: every job as it came
out, and the primary, secondary and exploratory summaries its protocol names.

Usage:
    python3 experiments/protocol/table.py NAME [--partial]

Reads `experiments/protocol/NAME.toml`, its lock and the ledger `run.py` keeps beside it
(`experiments/protocol/NAME/ledger.jsonl`: each finished job's `done` entry carries what this
script reads of its job file, so no run directory is needed); writes
`experiments/protocol/NAME/jobs.csv` (one row per job) and `experiments/protocol/NAME/summary.md`.
It refuses to run when run.py or table.py differ from the blobs the lock records (what computes
the numbers is frozen with the protocol). Without `--partial` it refuses while a planned job has
neither finished nor failed. With `--partial` it counts complete bases only: a base is complete
for an arm when every job planned on it, of that arm and of every arm of the same or an earlier
tier, has finished or failed (with one tier: every arm planned on the base); it says how many
bases each arm reached and how many are complete. Where a job file is still on disk (the session
that ran it), a file whose sha256 differs from the one the ledger recorded is refused; a job the
ledger records that the plan does not name is listed, not counted.

Per job, four policies, each scored on the job's final set (its own episodes, 50 per branch at
the standard config: `final_set_episodes` in src/pipeline/reacher_irl/evaluation.rs, never seen
by training or the choice): the loop's own (its policy after the last IRL iteration); the chosen
one (the final phase's choice by learned return, for an algorithm with a final phase; an
algorithm without one has no chosen policy but the loop's own, and the tables say so); a random
pick among the final phase's candidates, as its expected score (the mean over the candidates: no
draw); and the oracle best candidate (exploratory: it reads the final set after the fact). A
policy's score is its success on the lower branch (the branch it does worse on; a branch with no
episode is ignored; a task without branches has one); a branch with fewer than 10 episodes is
flagged. A job is solved when that score is at least 0.9. A failed job (error exit, timeout,
kill beyond the rerun limit, failed or refused prepare) scores 0 for every policy of its
algorithm, in every share and every mean. A cell (task, arm, algorithm) where more than half the
jobs failed is reported "did not run" and is not read.

Intervals: the SAC seeds of one base share its demonstrations and learned machine, so the base
is the unit that varies. A solved share gets a 95 % Wilson interval at n = the number of bases
(conservative for the clustering), the job-level one beside it. A mean gets a 95 % percentile
bootstrap that resamples bases (10 000 resamples, a generator seeded by the cell's name) only at
5 bases or more; below that the per-job scores are listed. No p-values; intervals per cell, not
adjusted.

Sections, as the protocol's `[analysis]` names them:
- Primary. P1: the primary unit's chosen policy on each of its tasks: solved share, mean score,
  and the goal's reading: *met* when the solved share is >= 0.9, *missed* when the clustered
  interval's upper bound is < 0.9, else *not resolved*, and *too few bases* for a cell of fewer
  than 5 bases whatever its scores; beside it the loop's own solved share and
  whether it is within 5 points of the chosen one (loop >= chosen - 0.05, on the solved shares).
  P2: primary chosen minus the paper unit's loop's own, paired by (base, SAC seed), per task and
  pooled over each of `[analysis] pools`; beside it the same with the primary's loop's own.
- Secondary: each pair of units, paired by (base, SAC seed), on the reported policy (chosen, or
  the loop's own without a final phase) and on the loop's own: a difference is called only when
  there are at least 3 pairs and one side solves all of them and the other none; anything else
  is "not resolved at this size". A pair with a unit `[analysis] control_failed` names (an arm
  that failed its positive control) is reported and called in neither direction.
- Exploratory: every cell, with the random pick, the oracle best candidate, chosen - loop, the
  demonstrations kept per base, flagged branches and wall time.
"""

import argparse
import csv
import hashlib
import json
import math
import os
import random
import statistics
import sys

sys.path.insert(0, os.path.dirname(__file__))
import run as protocol  # noqa: E402

SOLVED = 0.9
RESAMPLES = 10_000
# Fewer bases than this: no bootstrap interval (3 bases give 10 distinct resamples).
MIN_BOOTSTRAP_BASES = 5
# A branch with fewer final-set episodes than this is flagged.
FEW_EPISODES = 10
# Called only with this many pairs or more, one side solving all and the other none.
MIN_CALL_PAIRS = 3
# Fewest bases a cell's goal reading needs: below it the reading is "too few bases".
MIN_READING_BASES = 5
# Algorithms known to have no final phase (when the ledger has no finished job to tell).
NO_FINAL_PHASE = {"smirl-paper"}


def lower_branch(score, where):
    """(lower-branch success, per-branch successes, per-branch episodes) of a final-set score as
    the ledger keeps it (`run.score_of`)."""
    if not score:
        sys.exit(f"table: {where}: no final-set evaluation (a job file of a binary without it)")
    if len(score) == 1:
        rates, episodes = [score[0]], []
    else:
        branches = [(e, s) for e, s in (score[1:3], score[3:5]) if e > 0]
        rates, episodes = [s / e for e, s in branches], [e for e, _ in branches]
    if not rates or any(r != r for r in rates):
        sys.exit(f"table: {where}: no success rate in {score}")
    return min(rates), rates, episodes


def policies(fields, where):
    """(loop, chosen or None, random pick's expected score or None, oracle best or None) of a
    job's ledger fields; loop and chosen are `lower_branch` triples."""
    loop = lower_branch(fields.get("loop"), where)
    if "candidates" not in fields:
        return loop, None, None, None
    cands = [lower_branch(c, f"{where}, candidate {i}") for i, c in enumerate(fields["candidates"])]
    chosen = cands[fields["chosen"]]
    expected = sum(c[0] for c in cands) / len(cands)
    return loop, chosen, expected, max(c[0] for c in cands)


def rng_for(*names):
    return random.Random(hashlib.sha256(" ".join(map(str, names)).encode()).digest())


def mean(xs):
    return sum(xs) / len(xs)


def bootstrap(by_base, rng):
    """(mean, low, high) of per-job values grouped by base; no interval below
    MIN_BOOTSTRAP_BASES bases."""
    bases = sorted(by_base)
    if not bases:
        return None

    def mean_of(sample):
        return mean([x for b in sample for x in by_base[b]])

    m = mean_of(bases)
    if len(bases) < MIN_BOOTSTRAP_BASES:
        return m, None, None
    means = sorted(mean_of([rng.choice(bases) for _ in bases]) for _ in range(RESAMPLES))
    return m, means[int(0.025 * RESAMPLES)], means[int(0.975 * RESAMPLES) - 1]


def wilson(p, n, z=1.959964):
    """The 95 % Wilson interval of a share p observed over n units (n may be the number of
    bases while p is the share of jobs)."""
    if n == 0:
        return None
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(max(0.0, p * (1 - p) / n + z * z / (4 * n * n))) / d
    return max(0.0, c - h), min(1.0, c + h)


def f2(x):
    return "-" if x is None else f"{x:.2f}"


def mean_text(by_base, rng, list_jobs=False):
    """A mean with its base-cluster bootstrap interval, or below MIN_BOOTSTRAP_BASES bases the
    plain mean (and, with list_jobs, every job's score)."""
    b = bootstrap(by_base, rng)
    if b is None:
        return "-"
    m, lo, hi = b
    if lo is not None:
        return f"{m:+.2f} [{lo:+.2f}, {hi:+.2f}]" if m < 0 or lo < 0 else f"{m:.2f} [{lo:.2f}, {hi:.2f}]"
    text = f"{m:.2f}"
    if list_jobs:
        text += " (jobs: " + " ".join(f"{x:.2f}" for b_ in sorted(by_base) for x in by_base[b_]) + ")"
    return text


class Cell:
    """The jobs of one (task, arm, algorithm)."""

    def __init__(self, rows, final):
        self.rows, self.final = rows, final
        self.n = len(rows)
        self.bases = len({r["base"] for r in rows})
        self.failed = sum(r["status"] == "failed" for r in rows)
        self.did_not_run = self.failed * 2 > self.n

    def reported(self):
        return "chosen" if self.final else "loop"

    def share(self, policy):
        k = sum(r[policy] >= SOLVED for r in self.rows)
        return k, k / self.n

    def solved_text(self, policy):
        """k/N, the Wilson interval at n = bases, and the job-level one."""
        if policy == "chosen" and not self.final:
            return "-"
        k, p = self.share(policy)
        lo, hi = wilson(p, self.bases)
        jlo, jhi = wilson(p, self.n)
        return f"{k}/{self.n} [{lo:.2f}, {hi:.2f}; jobs {jlo:.2f}, {jhi:.2f}]"

    def by_base(self, value):
        out = {}
        for r in self.rows:
            v = value(r)
            if v is not None:
                out.setdefault(r["base"], []).append(v)
        return out

    def reading(self):
        """The goal's reading on the chosen (reported) policy's solved share."""
        if self.did_not_run:
            return "did not run"
        if self.bases < MIN_READING_BASES:
            return "too few bases"
        _, p = self.share(self.reported())
        _, hi = wilson(p, self.bases)
        return "met" if p >= SOLVED else ("missed" if hi < SOLVED else "not resolved")


def pairs_of(a, b):
    """{(base, seed): (row of a, row of b)} of the jobs both cells have."""
    rb = {(r["base"], r["seed"]): r for r in b.rows}
    return {(r["base"], r["seed"]): (r, rb[(r["base"], r["seed"])]) for r in a.rows if (r["base"], r["seed"]) in rb}


def call(pairs, pa, pb, a_name, b_name, control_failed=False):
    n = len(pairs)
    ka = sum(ra[pa] >= SOLVED for ra, _ in pairs.values())
    kb = sum(rb[pb] >= SOLVED for _, rb in pairs.values())
    text = f"{ka}/{n} vs {kb}/{n}"
    if control_failed:
        return text + ": control failed, not called"
    if n >= MIN_CALL_PAIRS and ka == n and kb == 0:
        return text + f": {a_name} called"
    if n >= MIN_CALL_PAIRS and kb == n and ka == 0:
        return text + f": {b_name} called"
    return text + ": not resolved at this size"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("name")
    p.add_argument("--partial", action="store_true")
    args = p.parse_args()
    name = args.name
    _, _, plan = protocol.load(name)
    lock_file = protocol.lock_path(name)
    if not os.path.isfile(lock_file):
        sys.exit(f"table: {protocol.rel(lock_file)} does not exist: no locked protocol")
    with open(lock_file) as fh:
        lock = json.load(fh)
    changed = protocol.scripts_changed(lock)
    if changed:
        sys.exit(f"table: {' and '.join(changed)} differ from the blobs locked in {protocol.rel(lock_file)}: "
                 "the scripts that compute the tables are frozen with the protocol: make its tables again in "
                 "a worktree of the commit that made them (`git worktree add DIR $(git log -1 "
                 f"--format=%h -- {protocol.rel(os.path.join(protocol.state_dir(name), 'summary.md'))})`)")
    runs, jobs = protocol.plan_runs(name, plan, lock)
    ledger = protocol.read_ledger(name)
    finished, demos = {}, {}
    for e in ledger:
        if e.get("event") == "prepared":
            demos.setdefault(e["dir"], e.get("demos_kept"))
        if e.get("event") not in ("done", "failed"):
            continue
        key = protocol.job_key(e)
        before = finished.get(key)
        if before and (before["event"], before.get("sha256")) != (e["event"], e.get("sha256")):
            sys.exit(f"table: {key} is recorded twice with different outcomes ({before['event']} "
                     f"{before.get('sha256')}, {e['event']} {e.get('sha256')})")
        finished[key] = e
    has_final = {}
    for e in finished.values():
        if e["event"] == "done":
            has_final[e["algo"]] = has_final.get(e["algo"], False) or "candidates" in e["job"]

    def final_of(algo):
        return has_final.get(algo, algo not in NO_FINAL_PHASE)

    key_of = {id(j): (protocol.rel(runs[j["run"]]["dir"]), j["algo"], j["seed"]) for j in jobs}
    missing = [j for j in jobs if key_of[id(j)] not in finished]
    if missing and not args.partial:
        sys.exit(f"table: {len(missing)} of {len(jobs)} jobs are missing (--partial for the complete bases)")
    # A base is complete for an arm when every job of that arm and of every arm of the same or
    # an earlier tier planned on it has finished.
    tier_of = {arm["name"]: arm.get("tier", 1) for arm in plan["arm"]}
    open_at = {}
    for j in missing:
        base = runs[j["run"]]["base"]
        open_at[base] = min(open_at.get(base, 4), j["tier"])

    def complete(arm, base):
        return open_at.get(base, 4) > tier_of[arm]

    rows, planned, reached = [], set(), {}
    for j in jobs:
        r = runs[j["run"]]
        key = key_of[id(j)]
        planned.add(key)
        e = finished.get(key)
        if e is not None:
            reached.setdefault(j["arm"], set()).add(r["base"])
        if e is None or not complete(j["arm"], r["base"]):
            continue
        final = final_of(j["algo"])
        row = {"arm": j["arm"], "tier": j["tier"], "task": protocol.task_label(r["task"]), "base": r["base"],
               "algo": j["algo"], "seed": j["seed"], "demos_kept": demos.get(key[0])}
        if e["event"] == "failed":
            zero = 0.0 if final else None
            rows.append({**row, "status": "failed", "loop": 0.0, "chosen": zero, "random_pick": zero,
                         "oracle": zero, "loop_branches": "", "chosen_branches": "", "episodes": "",
                         "few_episodes": "", "wall_secs": None, "why": e.get("why", "error exit")})
            continue
        path = protocol.job_file(r["dir"], j["algo"], j["seed"])
        if os.path.isfile(path) and protocol.sha256_of(path) != e["sha256"]:
            sys.exit(f"table: {path} is not the file the ledger recorded when the job finished")
        loop, chosen, expected, oracle = policies(e["job"], f"{key[0]} {j['algo']} seed {j['seed']}")
        reported = chosen or loop
        wall = e["job"].get("wall_secs")
        rows.append({**row, "status": "done", "loop": loop[0], "chosen": chosen[0] if chosen else None,
                     "random_pick": expected, "oracle": oracle,
                     "loop_branches": " ".join(f"{x:.2f}" for x in loop[1]),
                     "chosen_branches": " ".join(f"{x:.2f}" for x in chosen[1]) if chosen else "",
                     "episodes": " ".join(str(x) for x in reported[2]),
                     "few_episodes": "yes" if any(x < FEW_EPISODES for x in loop[2] + reported[2]) else "",
                     "wall_secs": round(wall) if isinstance(wall, (int, float)) and wall == wall else None,
                     "why": ""})
    unplanned = [f"{d} {a} seed {s}" for d, a, s in finished if (d, a, s) not in planned]
    out = protocol.state_dir(name)
    os.makedirs(out, exist_ok=True)
    fields = ["arm", "task", "base", "algo", "seed", "status", "loop", "chosen", "random_pick", "oracle",
              "loop_branches", "chosen_branches", "episodes", "few_episodes", "demos_kept", "wall_secs", "tier", "why"]
    with open(os.path.join(out, "jobs.csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        for row in rows:
            w.writerow({k: (f2(row[k]) if k in ("loop", "chosen", "random_pick", "oracle")
                            else ("-" if row[k] is None else row[k])) for k in fields})

    cells = {}
    for row in rows:
        cells.setdefault((row["task"], row["arm"], row["algo"]), []).append(row)
    cells = {k: Cell(v, final_of(k[2])) for k, v in cells.items()}
    tasks = []
    for row in rows:
        if row["task"] not in tasks:
            tasks.append(row["task"])
    command = f"python3 experiments/protocol/table.py {name}{' --partial' if args.partial else ''}"
    lines = [
        f"# Protocol {name}: summary ({len(rows)} of {len(jobs)} jobs"
        + (f"; INCOMPLETE, complete bases only: {len(missing)} jobs not run" if missing else "") + ")",
        "",
        f"`{command}`; every job is in jobs.csv. Score: success on the lower branch, on the job's final "
        "set; solved: score >= 0.9. A failed job scores 0 for every policy. Solved shares: k/N [95 % "
        "Wilson at n = bases; jobs: at n = jobs]. Means: 95 % bootstrap over bases at >= 5 bases, "
        "else the plain mean. \"did not run\": more than half the cell's jobs failed.",
    ]
    if args.partial:
        lines += ["", "Bases per arm (reached: some job finished; counted: complete for the arm):", ""]
        for arm in plan["arm"]:
            counted = {r["base"] for r in rows if r["arm"] == arm["name"]}
            lines.append(f"- {arm['name']} (tier {arm.get('tier', 1)}): {len(reached.get(arm['name'], ()))} reached, "
                         f"{len(counted)} counted, of {arm['n_bases']} planned")
    analysis = plan.get("analysis") or {}
    rng = lambda *names: rng_for(name, *names)  # noqa: E731
    # One cell per task of the primary (and the paper) units, which may be several arms.
    def unit_cells(refs):
        out = {}
        for ref in protocol.units_of(refs):
            arm, algo = ref.split(":")
            for task in tasks:
                if (task, arm, algo) in cells:
                    out.setdefault(task, cells[(task, arm, algo)])
        return out

    if analysis.get("primary"):
        primary = unit_cells(analysis["primary"])
        pa_name = ", ".join(protocol.units_of(analysis["primary"]))
        lines += ["", "## Primary (confirmatory)", "",
                  f"P1: {pa_name}, chosen policy. Goal read on the solved share: met at >= 0.9, "
                  "missed when the upper bound (n = bases) is < 0.9, else not resolved; with fewer than "
                  f"{MIN_READING_BASES} bases, too few bases (no claim).", "",
                  "| task | jobs (bases) | failed | solved, chosen | mean, chosen | goal | solved, loop's own | loop's own within 5 points |",
                  "|---|---|---|---|---|---|---|---|"]
        for task in tasks:
            c = primary.get(task)
            if c is None:
                continue
            pol = c.reported()
            kc, sc = c.share(pol)
            kl, sl = c.share("loop")
            within = "-" if c.did_not_run else ("yes" if sl >= sc - 0.05 else "no")
            lines.append(f"| {task} | {c.n} ({c.bases}) | {c.failed} | {c.solved_text(pol)} | "
                         f"{'did not run' if c.did_not_run else mean_text(c.by_base(lambda r: r[pol]), rng('P1', task), True)} | "
                         f"{c.reading()} | {c.solved_text('loop')} | {within} |")
        if analysis.get("paper"):
            paper = unit_cells(analysis["paper"])
            pp_name = ", ".join(protocol.units_of(analysis["paper"]))
            lines += ["", f"P2: {pa_name} minus {pp_name} (its loop's own policy), mean lower-branch "
                      "score, paired by (base, SAC seed); beside it the same with the primary's loop's own policy.", "",
                      "| task | pairs (bases) | chosen − paper's loop | loop's own − paper's loop |", "|---|---|---|---|"]
            common = [t for t in tasks if t in primary and t in paper]
            pools = dict(analysis.get("pools", {})) or ({"all": common} if len(common) > 1 else {})
            groups = [(t, [t]) for t in common] + [(f"pooled: {k}", [t for t in v if t in common]) for k, v in pools.items()]
            for label, group in groups:
                if not group:
                    continue
                if any(primary[t].did_not_run or paper[t].did_not_run for t in group):
                    lines.append(f"| {label} | - | did not run | did not run |")
                    continue
                dc, dl, n = {}, {}, 0
                for t in group:
                    ca = primary[t]
                    for (base, _), (ra, rb) in pairs_of(ca, paper[t]).items():
                        dc.setdefault(base, []).append(ra[ca.reported()] - rb["loop"])
                        dl.setdefault(base, []).append(ra["loop"] - rb["loop"])
                        n += 1
                lines.append(f"| {label} | {n} ({len(dc)}) | {mean_text(dc, rng('P2c', label), True)} | "
                             f"{mean_text(dl, rng('P2l', label), True)} |")
    if analysis.get("secondary"):
        control_failed = set(protocol.units_of(analysis.get("control_failed")))
        lines += ["", "## Secondary (descriptive)", "",
                  f"Paired by (base, SAC seed). Called only with >= {MIN_CALL_PAIRS} pairs, one side solving all "
                  "and the other none; else not resolved at this size. Reported policy: chosen, or the loop's own "
                  "for an algorithm without a final phase. A comparison with an arm that failed its positive "
                  "control (`[analysis] control_failed`: "
                  + (", ".join(sorted(control_failed)) or "none") + ") is called in neither direction.", "",
                  "| task | A | B | pairs | solved, reported | solved, loop's own |", "|---|---|---|---|---|---|"]
        for a_ref, b_ref in analysis["secondary"]:
            ua, ub = tuple(a_ref.split(":")), tuple(b_ref.split(":"))
            for task in tasks:
                ca, cb = cells.get((task, *ua)), cells.get((task, *ub))
                if ca is None or cb is None:
                    continue
                if ca.did_not_run or cb.did_not_run:
                    lines.append(f"| {task} | {a_ref} | {b_ref} | - | did not run | did not run |")
                    continue
                pr = pairs_of(ca, cb)
                cf = a_ref in control_failed or b_ref in control_failed
                lines.append(f"| {task} | {a_ref} | {b_ref} | {len(pr)} | "
                             f"{call(pr, ca.reported(), cb.reported(), 'A', 'B', cf)} | "
                             f"{call(pr, 'loop', 'loop', 'A', 'B', cf)} |")
    lines += ["", "## Exploratory", "",
              "Every cell. Random pick: the expected score of a uniform pick among the final phase's candidates; "
              "oracle: the best candidate on the final set (after the fact). `-`: no final phase. Few episodes: jobs "
              f"with a branch of fewer than {FEW_EPISODES} final-set episodes.", "",
              "| task | arm | algo | jobs (bases) | failed | solved, chosen | chosen mean | solved, loop's own | "
              "loop's own mean | random pick mean | oracle mean | chosen − loop | demos kept | few episodes | wall s (median) |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (task, arm, algo), c in cells.items():
        names = (task, arm, algo)
        dnr = " (did not run)" if c.did_not_run else ""
        fin = c.final
        kept = sorted({(r["base"], r["demos_kept"]) for r in c.rows})
        walls = [r["wall_secs"] for r in c.rows if r["wall_secs"] is not None]
        lines.append(
            f"| {task} | {arm} | {algo} | {c.n} ({c.bases}) | {c.failed}{dnr} | {c.solved_text('chosen')} | "
            f"{mean_text(c.by_base(lambda r: r['chosen']), rng(*names, 'chosen')) if fin else '-'} | "
            f"{c.solved_text('loop')} | {mean_text(c.by_base(lambda r: r['loop']), rng(*names, 'loop'))} | "
            f"{mean_text(c.by_base(lambda r: r['random_pick']), rng(*names, 'random')) if fin else '-'} | "
            f"{mean_text(c.by_base(lambda r: r['oracle']), rng(*names, 'oracle')) if fin else '-'} | "
            f"{mean_text(c.by_base(lambda r: r['chosen'] - r['loop']), rng(*names, 'diff')) if fin else '-'} | "
            f"{' '.join('-' if k is None else str(k) for _, k in kept)} | {sum(r['few_episodes'] == 'yes' for r in c.rows)} | "
            f"{round(statistics.median(walls)) if walls else '-'} |")
    if unplanned:
        lines += ["", "Jobs the ledger records that the plan does not name (not counted):", ""]
        lines += [f"- {u}" for u in sorted(unplanned)]
    with open(os.path.join(out, "summary.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

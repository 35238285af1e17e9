#!/usr/bin/env python3
"""Does a run's learned machine keep a cancel that comes after a ball was touched?

Usage: python3 experiments/reacher/cancel_probe.py RUN_DIR... [--write FILE]
       python3 experiments/reacher/cancel_probe.py --all [REACHER_BIN]
         (IF and Composite at base seeds 0 (tuning) and 3-21 (held out) under the standard
         profile and the stratified demonstrations: `reacher prepare` of each, well under a
         second, the same machines the sweeps learned, into a temporary directory; writes
         experiments/reacher/cancel_probe.md. REACHER_BIN defaults to target/release/reacher.)

For each run (a `reacher prepare` / sweep directory with rm/learned.txt, rm/perfect.txt and
config.toml) it plays probe histories on both machines: the fingertip touches ball X (red or
green) on step s alone (s = 4..7: the agent reaches red on step 5, the expert on 6-7), and a
cancel fires on step c of the cancel window, against the same history without the cancel.
Where the perfect machine ends in different states (the cancel changes what the task asks)
and the learned machine ends in the same one, the learned machine reads that cancel as a stay:
a *hole*. Holes at s = 5 are the history of the logged Composite base 18 misses (README,
"Seeds 18 and 21"); IF base 9's machine keeps that cancel but sends it to its "blue touched"
state, a merge (below). Reads only the machines, never a job's result.

Not probed: merges of two states the perfect machine keeps apart (IF's "blue touched" with
"cancelled", the failure sink with the state before it). Learned machines merge many such
pairs harmlessly — SMIRL's reward is per learned state *and* label, so "avoid blue after a
cancel" needs no state of its own — and a probe of all merges (tried: histories of up to three
touches) flags nearly every machine, including the ones whose jobs all succeed.

Prints one row per run: run, task, learned states, holes / separated probes, and the holes
as X@s:c.

       python3 experiments/reacher/cancel_probe.py --demos RUN_DIR...
         (the other side of a hole: how many of the run's demonstrations, logs/demos.mcap read
         by `reacher replay` — REACHER_BIN, default target/release/reacher — show a cancel
         after their first touch of red or green and before their first touch of blue, the
         history a hole would have to be learned from. One row per run.)
"""
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SETTINGS = [("standard", "experiments/reacher/config.toml"),
            ("stratified", "experiments/reacher/ablations/stratified_demos.toml")]
BASES = [0, 3, 6, 9, 12, 15, 18, 21]
HEADER = """# Cancel holes of the learned machines (issue 13)

Made by `python3 experiments/reacher/cancel_probe.py --all`. Per machine (setting-task-base
seed): probe histories touch red or green alone on step s = 4..7 and fire a cancel on step c
of the window (1..8); a *hole* is a probe whose cancel the perfect machine keeps (it ends in
another state than without the cancel) and the learned machine loses (same state). The agent
reaches red on step 5, the expert on 6-7.

"""

PROPS = "rgbyc"
STEPS = 12


def parse_guard(text):
    """A guard of the rm format (! > & > |, True, False, one letter per proposition) as a
    function of a label set."""
    tokens = re.findall(r"True|False|[rgbyc]|[!&|()]", text)
    if "".join(tokens) != re.sub(r"\s+", "", text):
        raise ValueError(f"guard {text!r}: unexpected characters")
    pos = 0

    def peek():
        return tokens[pos] if pos < len(tokens) else None

    def take(tok=None):
        nonlocal pos
        t = peek()
        if t is None or (tok is not None and t != tok):
            raise ValueError(f"guard {text!r}: expected {tok or 'a term'} at token {pos}")
        pos += 1
        return t

    def chain(op, operand, combine):
        """operand (op operand)*, its values combined by `combine` (any for |, all for &)."""
        terms = [operand()]
        while peek() == op:
            take(op)
            terms.append(operand())
        return lambda l: combine(t(l) for t in terms)

    def formula():
        return chain("|", conj, any)

    def conj():
        return chain("&", unary, all)

    def unary():
        t = take()
        if t == "!":
            inner = unary()
            return lambda l: not inner(l)
        if t == "(":
            inner = formula()
            take(")")
            return inner
        if t == "True":
            return lambda l: True
        if t == "False":
            return lambda l: False
        if t in PROPS:
            return lambda l: t in l
        raise ValueError(f"guard {text!r}: unexpected {t!r}")

    f = formula()
    if pos != len(tokens):
        raise ValueError(f"guard {text!r}: trailing tokens")
    return f


def load_machine(path):
    initial, edges = 0, []
    for n, line in enumerate(Path(path).read_text().splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if line.startswith("initial:"):
            initial = int(line.split(":")[1])
        m = re.match(r"\((\d+),\s*(\d+),\s*'([^']*)',\s*([-+\d.eE]+)\)$", line)
        if m:
            try:
                edges.append((int(m[1]), int(m[2]), parse_guard(m[3])))
            except ValueError as e:
                sys.exit(f"{path}:{n}: {e}")
    return initial, edges


def end_state(machine, trace):
    u, edges = machine
    for labels in trace:
        # Guards out of one state are disjoint in both written machines; no match = stay.
        u = next((to for frm, to, g in edges if frm == u and g(labels)), u)
    return u


def cancel_window(run):
    text = (Path(run) / "config.toml").read_text()
    section = text.split("[env.cancel]", 1)[1] if "[env.cancel]" in text else ""
    get = lambda key, default: int(re.search(rf"{key}\s*=\s*(\d+)", section)[1]) if re.search(rf"{key}\s*=", section) else default
    return get("earliest_step", 1), get("latest_step", 8)


def probe(run):
    """(learned states, probes the perfect machine separates, holes)."""
    learned = load_machine(Path(run) / "rm" / "learned.txt")
    perfect = load_machine(Path(run) / "rm" / "perfect.txt")
    first, last = cancel_window(run)
    separated, holes = 0, []
    for ball in "rg":
        for s in range(4, 8):
            for c in range(first, last + 1):
                base = [""] * STEPS
                base[s - 1] = ball
                cancel = list(base)
                cancel[c - 1] += "c"
                if end_state(perfect, base) == end_state(perfect, cancel):
                    continue
                separated += 1
                if end_state(learned, base) == end_state(learned, cancel):
                    holes.append(f"{ball}@{s}:{c}")
    n_states = 1 + max([u for e in learned[1] for u in e[:2]] + [0])
    return n_states, separated, holes


def table(runs, names):
    rows = ["| machine | learned states | holes / probes | holes (ball@touch step:cancel step) |",
            "|---|---|---|---|"]
    for run, name in zip(runs, names):
        n, separated, holes = probe(run)
        rows.append(f"| {name} | {n} | {len(holes)} / {separated} | {' '.join(holes) or '–'} |")
    return "\n".join(rows) + "\n"


def prepare_all(binary):
    """The probe table of every (setting, task, base) machine, prepared afresh."""
    with tempfile.TemporaryDirectory() as tmp:
        runs, names = [], []
        for setting, config in SETTINGS:
            for task in ["if", "composite"]:
                for base in BASES:
                    name = f"{setting}-{task}-{base}"
                    out = Path(tmp) / name
                    subprocess.run([binary, "prepare", "--task", task, "--algo", "smirl",
                                    "--seed", str(base), "--seeds", "1", "--config",
                                    str(REPO / config), "--out", str(out), "--quiet"],
                                   check=True, stdout=subprocess.DEVNULL)
                    runs.append(out)
                    names.append(name)
        return table(runs, names)


def touches(labels):
    """{proposition: first step} of a `reacher replay` label list such as `c@2 r@6–7 b@15`."""
    first = {}
    for token in labels.split():
        props, at = token.split("@", 1)
        step = int(re.split(r"[–-]", at)[0])
        for p in props:
            first.setdefault(p, step)
    return first


def demos_table(runs):
    binary = os.environ.get("REACHER_BIN", str(REPO / "target/release/reacher"))
    rows = ["| run | demonstrations | cancel after red/green, before blue |", "|---|---|---|"]
    for run in runs:
        log = Path(run) / "logs" / "demos.mcap"
        out = subprocess.run([binary, "replay", str(log)], check=True, capture_output=True, text=True).stdout
        episodes = re.findall(r"^episode .*labels \[([^\]]*)\]", out, re.M)
        late = 0
        for labels in episodes:
            t = touches(labels)
            ball = min([t[b] for b in "rg" if b in t], default=None)
            blue = t.get("b", float("inf"))
            late += ball is not None and "c" in t and ball < t["c"] < blue
        rows.append(f"| {run} | {len(episodes)} | {late} |")
    return "\n".join(rows) + "\n"


def main(argv):
    if argv and argv[0] == "--demos":
        if len(argv) < 2:
            sys.exit(__doc__)
        print(demos_table(argv[1:]), end="")
        return
    if argv and argv[0] == "--all":
        binary = argv[1] if len(argv) > 1 else str(REPO / "target/release/reacher")
        out = HEADER + prepare_all(binary)
        (REPO / "experiments/reacher/cancel_probe.md").write_text(out)
        print(out, end="")
        return
    write = None
    if "--write" in argv:
        i = argv.index("--write")
        write = argv[i + 1]
        argv = argv[:i] + argv[i + 2:]
    if not argv:
        sys.exit(__doc__)
    out = table(argv, argv)
    if write:
        Path(write).write_text(out)
    print(out, end="")


if __name__ == "__main__":
    main(sys.argv[1:])

"""Table of LRM's mechanisms ablated on the development range (no SAC).

Reads the rows `lrm_ablation` wrote (experiments/lrm/ablation.csv.gz, gzipped) and writes
experiments/lrm/ablation.md. Run by experiments/lrm/ablation.sh, which says how the rows were made.

Per (variant, task): the bases; the share whose learned machine tracks the task (the perfect
machine's state, failures read as stays, is a function of the learned machine's state on every
label sequence the task can produce over the balls the demonstrations touch, until the task
ends: `rm::language::undetermined`), the same over the label sets the demonstrations show, and
with the perfect machine's failures kept; the mean LRM cost (under the variant's own objective)
and the mean number of states. For each ablation: "lost" = bases the standard tracks and the
variant does not (the mechanism helps there), "gained" = the reverse (it hurts there).
"""
import csv
import gzip
import io
import sys
from collections import defaultdict

src = sys.argv[1] if len(sys.argv) > 1 else "experiments/lrm/ablation.csv.gz"
dst = sys.argv[2] if len(sys.argv) > 2 else "experiments/lrm/ablation.md"
opened = gzip.open(src, "rt", newline="") if src.endswith(".gz") else open(src, newline="")
with opened as fh:
    rows = list(csv.DictReader(io.StringIO(fh.read())))
tasks = ["or", "sequential", "if", "composite"]
variants = []
for r in rows:
    if r["variant"] not in variants:
        variants.append(r["variant"])
by = defaultdict(dict)
for r in rows:
    by[(r["variant"], r["task"])][int(r["base"])] = r
yes = lambda r, k: r[k] == "true"

out = []
bases = sorted({int(r["base"]) for r in rows})
out.append("# LRM's mechanisms on the development range\n")
out.append(f"Made by `nice -n 10 experiments/lrm/ablation.sh` (the table alone, from its rows: "
           f"`python3 experiments/lrm/ablation.py {src} {dst}`).\n")
out.append(f"Base seeds: {len(bases)} ({', '.join(map(str, bases))}); the demonstrations of "
           "`reacher prepare --task T --seed B` (standard config, 16 episodes, the failed ones dropped).\n")
out.append("| variant | task | bases | tracks the task | over the label sets shown | failures kept | "
           "lost vs standard | gained vs standard | mean LRM cost | mean states |")
out.append("|---|---|---|---|---|---|---|---|---|---|")
for v in variants:
    for t in tasks:
        cell = by.get((v, t), {})
        if not cell:
            continue
        std = by[("standard", t)]
        n = len(cell)
        det = sum(yes(r, "determined") for r in cell.values())
        seen = sum(yes(r, "determined_seen") for r in cell.values())
        fail = sum(yes(r, "determined_failures") for r in cell.values())
        lost = [b for b, r in cell.items() if b in std and yes(std[b], "determined") and not yes(r, "determined")]
        gained = [b for b, r in cell.items() if b in std and not yes(std[b], "determined") and yes(r, "determined")]
        cost = sum(float(r["cost"]) for r in cell.values()) / n
        states = sum(int(r["states"]) for r in cell.values()) / n
        fmt = lambda bs: "-" if v == "standard" else (f"{len(bs)}" + (f" ({', '.join(map(str, sorted(bs)[:8]))}{', ...' if len(bs) > 8 else ''})" if bs else ""))
        out.append(f"| {v} | {t} | {n} | {det}/{n} ({det / n:.2f}) | {seen}/{n} | {fail}/{n} | "
                   f"{fmt(lost)} | {fmt(gained)} | {cost:.2f} | {states:.2f} |")
open(dst, "w").write("\n".join(out) + "\n")
print("\n".join(out))

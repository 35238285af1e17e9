#!/usr/bin/env python3
"""SMIRL's reward trace (rewards/<algo>_seed<S>.trace.csv of a run directory), one line per IRL
iteration: for each learned-machine state u (separated by |), every feature whose weight or data
gradient is not small, as  <feature><weight>(<data gradient μ_π − μ_D>).  A data gradient of
−1.00 on the ball a state is left by means the agent's rollouts never took that transition.
The traces are not tracked (experiments/README.md): `reacher job` writes them into the run
directory, and those of the committed runs are in history (`git restore --source=4e88128
--worktree -- RUN_DIR/rewards`); experiments/archive/reacher/composite_cancel_weight.csv keeps the final Composite weights.
Usage: python3 experiments/reacher/trace.py RUN_DIR [ALGO] [SEED]"""
import csv, glob, os, sys

if len(sys.argv) < 2:
    sys.exit(__doc__)
run = sys.argv[1]
algo = sys.argv[2] if len(sys.argv) > 2 else "smirl"
seed = sys.argv[3] if len(sys.argv) > 3 else "*"
for path in sorted(glob.glob(os.path.join(run, "rewards", "%s_seed%s.trace.csv" % (algo, seed)))):
    print(os.path.basename(path))
    table, n_states, features = {}, 0, []
    for r in csv.DictReader(open(path)):
        u = int(r["rm_state"])
        n_states = max(n_states, u + 1)
        if r["feature"] not in features:
            features.append(r["feature"])
        table.setdefault(int(r["iteration"]), {})[(u, r["feature"])] = (
            float(r["weight"]), float(r["data_gradient"]))
    for it in sorted(table):
        row = table[it]
        states = []
        for u in range(n_states):
            states.append(" ".join("%s%+.1f(%+.2f)" % (f, *row[(u, f)]) for f in features
                                   if abs(row[(u, f)][0]) > 0.3 or abs(row[(u, f)][1]) > 0.05))
        print("%2d  %s" % (it, " | ".join(states)))

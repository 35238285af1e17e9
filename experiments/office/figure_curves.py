"""The Office figures' learning curves as a curve table for `reacher figure`: one panel per
task, the ground-truth return (1 = task done) of each IRL step's policy, mean ± std over seeds,
read from the run directories experiments/office/run.sh writes (runs<TAG>/t<N>/metrics.csv).

Usage: python3 experiments/office/figure_curves.py RUNS_DIR TASK... > CURVES.csv
(experiments/figures/make.sh: figure 4 is task 0, figure 5 tasks 1-4.)
"""
import csv
import os
import sys

# Panel titles: a curve table's fields hold no commas.
TITLES = {
    "0": "Task 0: reach D",
    "1": "Task 1: coffee then office",
    "2": "Task 2: mail then office",
    "3": "Task 3: coffee and mail then office",
    "4": "Task 4: patrol A B C D",
}


def main(runs, tasks):
    print("panel,algo,curve,seed,x,y")
    for t in tasks:
        with open(os.path.join(runs, f"t{t}", "metrics.csv"), newline="") as f:
            for r in csv.DictReader(f):
                print(f"{TITLES.get(t, 'Task ' + t)},{r['algo']},,{r['seed']},{r['step']},{r['gt_return']}")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2:])

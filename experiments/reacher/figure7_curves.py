"""Figure 7's learning curves as a curve table for `reacher figure`: one panel per task, the
ground-truth success of each IRL iteration's policy against environment steps, mean ± std over
SAC seeds; on IF and Composite each branch (normal solid, cancel dashed). Read from the
committed runs figure 7's tables use (make_results.sh): smirl and smirl-paper from
ablations/runs/fold-seeds0to5-<task>, maxent, fkl and js from runs/<task>-schedules, rkl from
runs/<task>-rkl_expert. SMIRL's curve is its loop's own policy (the final choice is a table
column, not a curve point).

Usage: python3 experiments/reacher/figure7_curves.py > CURVES.csv
then:  reacher figure --data CURVES.csv --out experiments/figures/figure7.svg --y-range 0,1 \
           --title "Figure 7: ReacherDelivery"
(experiments/figures/make.sh does both.)
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rundata  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
TASKS = [("or", "OR"), ("sequential", "Sequential"), ("if", "IF"), ("composite", "Composite")]
# (run directory pattern, algorithms read from it)
SOURCES = [
    ("ablations/runs/fold-seeds0to5-{task}", ["smirl", "smirl-paper"]),
    ("runs/{task}-schedules", ["maxent", "fkl", "js"]),
    ("runs/{task}-rkl_expert", ["rkl"]),
]


def main():
    print("panel,algo,curve,seed,x,y")
    for task, title in TASKS:
        conditional = task in ("if", "composite")
        for pattern, algos in SOURCES:
            rows = rundata.metrics(os.path.join(HERE, pattern.format(task=task)))
            for r in rows:
                if r["algo"] not in algos:
                    continue
                if conditional:
                    for branch in ("normal", "cancel"):
                        y = r[f"success_{branch}"] or "0"
                        print(f"{title},{r['algo']},{branch},{r['seed']},{r['env_steps']},{y}")
                else:
                    print(f"{title},{r['algo']},,{r['seed']},{r['env_steps']},{r['success_rate']}")


if __name__ == "__main__":
    main()

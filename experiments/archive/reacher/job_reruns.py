"""Reruns of single SMIRL jobs under one ablation's config, as reset_agent.py and clock.py make
them: a job is (scope, task, base, SAC seed); its run directory is
ablations/runs/<tuning prefix>-seeds0to5-<task> for the tuning jobs (base 0, SAC seeds 0-5) and
heldout/<held-out prefix>-seeds<B>-<task> for the others (SAC seeds B..B+2)."""
import os
import subprocess
import threading
from concurrent.futures import ThreadPoolExecutor

import rundata
import selection_cut
import standard_heldout


class Reruns:
    def __init__(self, config, tuning_prefix, heldout_prefix, label):
        self.config = config
        self.tuning_prefix = tuning_prefix
        self.heldout_prefix = heldout_prefix
        self.label = label

    def run_dir(self, scope, task, base):
        if scope == "tuning":
            return os.path.join(selection_cut.ABLATION_RUNS,
                                f"{self.tuning_prefix}-seeds0to5-{task}")
        return os.path.join(standard_heldout.HELDOUT, f"{self.heldout_prefix}-seeds{base}-{task}")

    def candidates(self, scope, task, base, seed):
        """The candidate rows of one job's rerun, or None when it has not run."""
        try:
            return rundata.final_policy(self.run_dir(scope, task, base)).get(("smirl", seed))
        except FileNotFoundError:
            return None

    def run(self, binary, jobs):
        """Runs the jobs (scope, task, base, seed, ...) not yet run, two at a time, in order:
        `reacher prepare` of a run when its first job comes up, `reacher job`, then `reacher
        aggregate --partial`."""
        todo = [j[:4] for j in jobs if self.candidates(*j[:4]) is None]
        locks = {self.run_dir(s, t, b): threading.Lock() for s, t, b, _ in todo}

        def job(item):
            s, t, b, seed = item
            out = self.run_dir(s, t, b)
            with locks[out]:
                selection_cut.prepare_run(binary, s, t, b, self.config, out)
            with open(out + f".seed{seed}.log", "w") as log:
                subprocess.run([binary, "job", "--run", out, "--algo", "smirl", "--seed",
                                str(seed), "--quiet"], check=True, stdout=log)
            subprocess.run([binary, "aggregate", out, "--partial"], check=True,
                           stdout=subprocess.DEVNULL)
            print(f"done: {self.label} {s} {t} {b} seed {seed}", flush=True)

        with ThreadPoolExecutor(max_workers=2) as pool:
            list(pool.map(job, todo))

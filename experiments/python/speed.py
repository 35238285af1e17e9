#!/usr/bin/env python3
"""Environment steps per second through the Python package, beside Gymnasium's own Reacher-v5
(MuJoCo 3 from PyPI), single and vectorised, measured interleaved in one run.

Usage (after `pip install ./python "gymnasium[mujoco]"`):
    python3 experiments/python/speed.py [--steps 20000] [--rounds 5] [--envs 16]
Prints one line per contender (median steps/s over the rounds) and the ratios the Python
issue targets: smirl single / Reacher-v5 single and smirl vector / Reacher-v5 single.
Random actions from a fixed generator; the episode resets are part of the cost.
"""

import argparse
import statistics
import time

import gymnasium as gym
import numpy as np

import smirl


def single(make, steps, rng):
    env = make()
    env.reset(seed=0)
    actions = rng.uniform(-1, 1, (steps, 2)).astype(np.float32)
    t = time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - t)


def vector(make, n, steps, rng):
    env = make(n)
    env.reset(seed=0)
    rounds = steps // n
    actions = rng.uniform(-1, 1, (rounds, n, 2)).astype(np.float32)
    t = time.perf_counter()
    for a in actions:
        env.step(a)
    rate = rounds * n / (time.perf_counter() - t)
    env.close()
    return rate


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=20000)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--envs", type=int, default=16)
    p.add_argument("--task", default="composite")
    args = p.parse_args()
    n = args.envs
    contenders = {
        "gymnasium Reacher-v5 (single)": lambda r: single(lambda: gym.make("Reacher-v5"), args.steps, r),
        f"gymnasium Reacher-v5 SyncVectorEnv x{n}": lambda r: vector(
            lambda k: gym.make_vec("Reacher-v5", num_envs=k, vectorization_mode="sync"), n, args.steps, r
        ),
        f"gymnasium Reacher-v5 AsyncVectorEnv x{n}": lambda r: vector(
            lambda k: gym.make_vec("Reacher-v5", num_envs=k, vectorization_mode="async"), n, args.steps, r
        ),
        f"smirl {args.task} (single)": lambda r: single(lambda: smirl.make(args.task), args.steps, r),
        f"smirl {args.task} vector x{n}, 1 thread": lambda r: vector(
            lambda k: smirl.make_vec(args.task, k, threads=1), n, args.steps, r
        ),
        f"smirl {args.task} vector x{n}, 2 threads": lambda r: vector(
            lambda k: smirl.make_vec(args.task, k, threads=2), n, args.steps, r
        ),
    }
    rates = {name: [] for name in contenders}
    for k in range(args.rounds):
        for name, run in contenders.items():  # interleaved: every contender once per round
            rates[name].append(run(np.random.default_rng(k)))
    med = {name: statistics.median(v) for name, v in rates.items()}
    for name, m in med.items():
        print(f"{name:48s} {m:12.0f} steps/s  (rounds: {', '.join(f'{x:.0f}' for x in rates[name])})")
    ref = med["gymnasium Reacher-v5 (single)"]
    print(f"ratio smirl single / Reacher-v5 single: {med[f'smirl {args.task} (single)'] / ref:.2f}")
    best_vec = max(med[f"smirl {args.task} vector x{n}, 1 thread"], med[f"smirl {args.task} vector x{n}, 2 threads"])
    print(f"ratio smirl vector (best) / Reacher-v5 single: {best_vec / ref:.2f}")


if __name__ == "__main__":
    main()

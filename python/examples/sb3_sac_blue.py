"""Stable-Baselines3's SAC trained on the `blue` task through the smirl package.

The training environment is ``smirl.make("blue", shaping=1.0)``: ReacherDelivery × the task's
perfect machine, paying the machine's reward plus its potential-based sub-goal shaping (the
reward the project's own SAC experts train on); success is judged on the unshaped task by the
``success`` entry of ``info``, over evaluation episodes with seeds no training episode used.
Prints one JSON object (success rate, steps, seconds, versions) and, with ``--out``, writes it.

Needs ``pip install ./python stable-baselines3`` (torch comes with it).
Usage: python3 python/examples/sb3_sac_blue.py [--steps N] [--seed S] [--episodes E] [--out F]
"""

import argparse
import json
import platform
import time

import numpy as np
import stable_baselines3
import torch
from stable_baselines3 import SAC

import smirl

# Evaluation reset seeds start here; training resets draw from the environment's own stream.
EVAL_SEED_BASE = 1_000_000


def success_rate(model, episodes: int) -> float:
    """Share of `episodes` unshaped `blue` episodes the policy's mean action solves."""
    env = smirl.make("blue")
    solved = 0
    for k in range(episodes):
        obs, _ = env.reset(seed=EVAL_SEED_BASE + k)
        done = False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        solved += bool(info["success"])
    return solved / episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--out", help="also write the JSON result here")
    args = parser.parse_args()

    torch.set_num_threads(1)
    env = smirl.make("blue", shaping=1.0)
    env.reset(seed=args.seed)
    model = SAC("MlpPolicy", env, seed=args.seed, learning_starts=1_000, verbose=0)
    start = time.perf_counter()
    model.learn(total_timesteps=args.steps)
    train_seconds = time.perf_counter() - start
    result = {
        "task": "blue",
        "algorithm": "stable_baselines3.SAC (MlpPolicy, defaults)",
        "steps": args.steps,
        "seed": args.seed,
        "eval_episodes": args.episodes,
        "success_rate": success_rate(model, args.episodes),
        "train_seconds": round(train_seconds, 1),
        "versions": {
            "smirl": smirl.__version__,
            "stable_baselines3": stable_baselines3.__version__,
            "torch": torch.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
    }
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()

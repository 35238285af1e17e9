"""Stable-Baselines3's SAC trained on the `blue` task through the smirl package.

The training environment is ``smirl.make("blue", shaping=0.2)``: ReacherDelivery × the task's
perfect machine, paying the machine's reward plus its potential-based sub-goal shaping at the
scale the project's own SAC experts train with; success is judged on the unshaped task by the
``success`` entry of ``info``, over evaluation episodes with seeds no training episode used.

SAC's settings are those of the project's experts (``reacher expert``'s defaults): a (64, 64)
network, Adam lr 1e-3, minibatch 100, a replay of 10⁶, 1 000 random steps before learning, and
the entropy temperature tuned from 0.2; SB3's defaults ((256, 256), lr 3e-4, batch 256, a
temperature tuned from 1.0) are ``--sb3-defaults``.
Prints one JSON object (success rate, steps, seconds, versions) and, with ``--out``, writes it.

Needs ``pip install ./python stable-baselines3`` (torch comes with it).
Usage: python3 python/examples/sb3_sac_blue.py [--steps N] [--seed S] [--episodes E] [--out F]
       [--sb3-defaults]
"""

import argparse
import copy
import json
import os
import platform
import time

import numpy as np
import stable_baselines3
import torch
from stable_baselines3 import SAC

import smirl

# Evaluation reset seeds start here; training resets draw from the environment's own stream.
EVAL_SEED_BASE = 1_000_000

# `reacher expert`'s SAC (src/pipeline/reacher_expert/config.rs) in SB3's terms.
EXPERT_SAC = {
    "policy_kwargs": {"net_arch": [64, 64]},
    "learning_rate": 1e-3,
    "batch_size": 100,
    "buffer_size": 1_000_000,
    "gamma": 0.99,
    "tau": 0.005,
    "ent_coef": "auto_0.2",
}
# The scale of the sub-goal shaping the project's experts train with.
EXPERT_SHAPING = 0.2


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
    parser.add_argument("--steps", type=int, default=150_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--out", help="also write the JSON result here (a new file: never replaced)")
    parser.add_argument(
        "--sb3-defaults",
        action="store_true",
        help="SB3's own SAC settings and shaping 1.0 instead of the project expert's",
    )
    args = parser.parse_args()
    if args.out and os.path.exists(args.out):
        parser.error(f"--out {args.out} exists: the result goes to a new file")

    torch.set_num_threads(1)
    if args.sb3_defaults:
        shaping, settings = 1.0, {}
        described = "stable_baselines3.SAC (MlpPolicy, SB3's defaults)"
    else:
        shaping = EXPERT_SHAPING
        settings = EXPERT_SAC
        described = "stable_baselines3.SAC (MlpPolicy, the project expert's settings)"
    env = smirl.make("blue", shaping=shaping)
    env.reset(seed=args.seed)
    # SB3 adds its own entries to the dicts it is given: it gets a copy, the record the original.
    model = SAC("MlpPolicy", env, seed=args.seed, learning_starts=1_000, verbose=0, **copy.deepcopy(settings))
    start = time.perf_counter()
    model.learn(total_timesteps=args.steps)
    train_seconds = time.perf_counter() - start
    result = {
        "task": "blue",
        "algorithm": described,
        "shaping": shaping,
        "settings": {k: str(v) for k, v in settings.items()},
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
        with open(args.out, "x") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()

"""Stable-Baselines3's SAC on SMIRL's learned product, read from a run directory.

The training environment is ``smirl.make_learned(RUN)``: ReacherDelivery × the run's learned
machine, paying the run's learned reward (``rewards/smirl_seed<k>.json``), the observation
with the learned state's one-hot. Nothing of the task's perfect machine
reaches the agent; it only judges the trained policy: success over evaluation episodes whose
reset seeds no training episode used, per branch for IF and Composite (``info["branch"]``). SB3's SAC gets no shaping
and none of SMIRL's other mechanisms, so this measures what the learned machine and reward
carry on their own. Prints one JSON object and, with ``--out``, writes it.

Needs ``pip install ./python stable-baselines3``.
Usage: python3 python/examples/sb3_sac_learned.py RUN [--seed-of-reward K] [--steps N]
           [--seed S] [--episodes E] [--out F]
"""

import argparse
import json
import os
import time

import stable_baselines3
import torch
from stable_baselines3 import SAC

import smirl

EVAL_SEED_BASE = 1_000_000


def evaluate(model, run: str, reward_seed: int, episodes: int) -> dict:
    env = smirl.make_learned(run, seed=reward_seed)
    tally = {}
    for k in range(episodes):
        obs, _ = env.reset(seed=EVAL_SEED_BASE + k)
        success, done, info = False, False, {}
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            success |= info["success"]
            done = terminated or truncated
        branch = info.get("branch", "all")
        solved, total = tally.get(branch, (0, 0))
        tally[branch] = (solved + int(success), total + 1)
    everything = sum(s for s, _ in tally.values()) / episodes
    return {
        "success_rate": everything,
        "branches": {b: {"solved": s, "episodes": n} for b, (s, n) in sorted(tally.items())},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run")
    parser.add_argument("--seed-of-reward", type=int, default=0)
    parser.add_argument("--steps", type=int, default=50_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--out")
    args = parser.parse_args()
    if args.out and os.path.exists(args.out):
        parser.error(f"--out {args.out} exists: the result goes to a new file")

    torch.set_num_threads(1)
    env = smirl.make_learned(args.run, seed=args.seed_of_reward)
    env.reset(seed=args.seed)
    model = SAC("MlpPolicy", env, seed=args.seed, learning_starts=1_000, verbose=0)
    start = time.perf_counter()
    model.learn(total_timesteps=args.steps)
    result = {
        "run": args.run,
        "task": env.task,
        "reward": f"rewards/smirl_seed{args.seed_of_reward}.json",
        "learned_states": env.reward_machine.n_states,
        "algorithm": "stable_baselines3.SAC (MlpPolicy, defaults)",
        "steps": args.steps,
        "seed": args.seed,
        "eval_episodes": args.episodes,
        **evaluate(model, args.run, args.seed_of_reward, args.episodes),
        "train_seconds": round(time.perf_counter() - start, 1),
        "versions": {
            "smirl": smirl.__version__,
            "stable_baselines3": stable_baselines3.__version__,
            "torch": torch.__version__,
        },
    }
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        with open(args.out, "x") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()

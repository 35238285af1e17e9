#!/usr/bin/env bash
# The peer of ReacherDelivery's step rate: Gymnasium's Reacher-v5 (MuJoCo 3, from PyPI) stepped
# with random actions, one environment and 8 environments behind SyncVectorEnv and
# AsyncVectorEnv (one process each), and in each repetition ReacherDelivery on one thread
# (`env_bench --reps 1`: the environment as it steps the shipped scene) for the ratio. Installs
# gymnasium[mujoco] into a venv (default target/gymnasium-venv; VENV=... to change) and writes
# experiments/env/gymnasium_peer.txt. Env steps/s count every environment's steps. Medians of
# REPS interleaved repetitions.
#
#   nice -n 10 experiments/env/gymnasium_peer.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
VENV=${VENV:-target/gymnasium-venv}
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet 'gymnasium[mujoco]'
fi
cargo build --release --bin env_bench
export ENV_BENCH=target/release/env_bench
OUT=experiments/env/gymnasium_peer.txt
{
    echo "# command: nice -n 10 experiments/env/gymnasium_peer.sh"
    echo "# machine: $(nproc) cores, $(date -u +%Y-%m-%d), load average $(cut -d' ' -f1-3 /proc/loadavg)"
    "$VENV/bin/python" - <<'EOF'
import os
import statistics
import subprocess
import time

import gymnasium as gym
import mujoco
import numpy as np

STEPS = 20_000
REPS = 5
N_VEC = 8


def rate_single():
    env = gym.make("Reacher-v5")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(STEPS, 2)).astype(np.float32)
    t = time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    rate = STEPS / (time.perf_counter() - t)
    env.close()
    return rate


def rate_vector(kind):
    make = [lambda: gym.make("Reacher-v5") for _ in range(N_VEC)]
    env = (gym.vector.SyncVectorEnv if kind == "sync" else gym.vector.AsyncVectorEnv)(make)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    n = STEPS // N_VEC
    actions = rng.uniform(-1, 1, size=(n, N_VEC, 2)).astype(np.float32)
    t = time.perf_counter()
    for a in actions:
        env.step(a)  # vector envs reset finished episodes themselves
    rate = n * N_VEC / (time.perf_counter() - t)
    env.close()
    return rate


def rate_smirl():
    out = subprocess.run([os.environ["ENV_BENCH"], "--reps", "1", "--steps", str(STEPS)],
                         check=True, capture_output=True, text=True).stdout
    line = next(l for l in out.splitlines() if l.startswith("ReacherDelivery (physics)"))
    return float(line.split(":")[1].split()[0])


rates = {"single": [], "sync": [], "async": [], "smirl": []}
for _ in range(REPS):
    rates["smirl"].append(rate_smirl())
    rates["single"].append(rate_single())
    rates["sync"].append(rate_vector("sync"))
    rates["async"].append(rate_vector("async"))
print(f"gymnasium {gym.__version__}, mujoco {mujoco.__version__}, Reacher-v5 (frame_skip 2), "
      f"random actions, {STEPS} env steps x {REPS} reps (interleaved; medians)")
single = statistics.median(rates["single"])
print(f"Reacher-v5, one env          : {single:9.0f} steps/s ({1e6 / single:.1f} us/step)")
for kind in ("sync", "async"):
    r = statistics.median(rates[kind])
    name = "SyncVectorEnv" if kind == "sync" else "AsyncVectorEnv"
    print(f"{name:>14} x {N_VEC} envs   : {r:9.0f} steps/s (x{r / single:.2f} one env)")
ours = statistics.median(rates["smirl"])
ratio = statistics.median(a / b for a, b in zip(rates["smirl"], rates["single"]))
print(f"ReacherDelivery, one thread  : {ours:9.0f} steps/s (x{ratio:.1f} Reacher-v5, median of "
      "per-repetition ratios)")
EOF
} > "$OUT"
cat "$OUT"

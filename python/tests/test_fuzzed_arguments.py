"""Fuzzed arguments: whatever Python passes, the core raises an exception or works; the
interpreter never crashes (a crash would end this process and fail the run)."""

import math

import numpy as np
import pytest

import smirl

VALUES = [
    None, 0, -1, 2**70, 1.5, math.nan, math.inf, -math.inf, "", "z", "rgbyc" * 100, b"\x00",
    [], [0.0], [0.0, 0.0], [math.nan, 1.0], [[0.0, 0.0]], np.zeros(2), np.zeros((3, 2)),
    np.zeros(2, dtype=np.int64), np.array(["a", "b"]), {"a": 1}, object(),
]


def attempt(f, *args, **kwargs):
    try:
        f(*args, **kwargs)
    except Exception:  # noqa: BLE001 - any Python exception is an acceptable answer
        pass


def test_env_calls_with_fuzzed_arguments():
    env = smirl.make("composite", render_mode="rgb_array")
    venv = smirl.make_vec("composite", 3)
    rng = np.random.default_rng(0)
    for _ in range(3):
        for v in VALUES:
            attempt(env.reset, seed=v)
            attempt(env.step, v)
            attempt(venv.reset, seed=v)
            attempt(venv.step, v)
            attempt(smirl.make, v)
            attempt(smirl.make_vec, "or", v)
            attempt(smirl.make, "or", shaping=v)
            attempt(smirl.make, "or", gamma=v)
            attempt(smirl.make, "or", render_size=v)
        env.reset(seed=int(rng.integers(0, 1000)))
        env.render()


def test_rm_calls_with_fuzzed_arguments(tmp_path):
    rm = smirl.RewardMachine.shipped("reacher_composite")
    for v in VALUES:
        attempt(smirl.RewardMachine.from_text, v)
        attempt(smirl.RewardMachine.read, v)
        attempt(smirl.RewardMachine.shipped, v)
        attempt(rm.step, v, "r")
        attempt(rm.step, 0, v)
        attempt(rm.run, v)
        attempt(rm.equivalent, v)
        attempt(smirl.learn_rm, v, "ab")
        attempt(smirl.learn_rm, [["a"]], v)
        attempt(smirl.learn_rm, [["a"]], "ab", rewards=v)
        attempt(smirl.learn_rm, [["a"]], "ab", max_states=v)
        attempt(smirl.read_log, v)
        attempt(smirl.write_log, tmp_path / "x.mcap", "or", v)
        attempt(smirl.write_log, tmp_path / "y.mcap", v, [])


@pytest.mark.parametrize("seed", range(20))
def test_random_label_traces_into_learn_rm(seed):
    rng = np.random.default_rng(seed)
    letters = ["", "a", "b", "ab", "c"]
    traces = [[letters[i] for i in rng.integers(0, 5, rng.integers(0, 12))] for _ in range(rng.integers(0, 6))]
    attempt(smirl.learn_rm, traces, "abc", max_states=int(rng.integers(1, 5)), max_steps=20)

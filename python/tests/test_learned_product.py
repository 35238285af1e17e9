"""SMIRL's learned product rebuilt from a run directory (``smirl.make_learned``)."""

import shutil
import subprocess

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import smirl


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory, reacher_bin):
    """A `--quick` SMIRL run of Sequential made by the `reacher` binary."""
    out = tmp_path_factory.mktemp("run") / "sequential"
    subprocess.run(
        [reacher_bin, "--task", "sequential", "--quick", "--algo", "smirl", "--out", str(out), "--quiet"],
        check=True,
        capture_output=True,
    )
    return out


def test_the_learned_product_is_a_checked_gymnasium_env(run_dir):
    env = smirl.make_learned(str(run_dir))
    check_env(env, skip_render_check=True)
    learned = smirl.RewardMachine.read(str(run_dir / "rm" / "learned.txt"))
    # smirl's agent sees the observation and the learned state's one-hot, no clock.
    assert env.observation_space.shape == (17 + learned.n_states,)
    assert env.reward_machine.n_states == learned.n_states


def test_it_pays_the_learned_reward_of_the_state_before_each_step(run_dir):
    env = smirl.make_learned(str(run_dir))
    reward = smirl.LearnedReward.read(str(run_dir / "rewards" / "smirl_seed0.json"))
    learned = env.reward_machine
    n = learned.n_states
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(0)
    u, steps, nonzero = learned.initial, 0, 0
    while True:
        assert obs[17 + u] == 1.0 and obs[17 : 17 + n].sum() == 1.0
        obs, r, terminated, truncated, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        expected = reward.reward(obs[None, :17].astype(np.float32), np.array([u], dtype=np.uint32))
        assert r == pytest.approx(float(expected[0]), abs=0.0)
        u, _ = learned.step(u, info["labels"])
        assert info["rm_state"] == u
        steps += 1
        nonzero += r != 0.0
        assert not terminated, "the learned product never terminates an episode"
        if truncated:
            break
    assert steps == 100
    assert nonzero > 0, "a learned reward of zero everywhere tests nothing"


def test_the_task_machine_only_fills_info(run_dir, tmp_path):
    """Replacing the run's perfect machine changes `info`'s judgement, never what the agent
    sees or is paid."""
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    perfect = copy / "rm" / "perfect.txt"
    text = perfect.read_text()
    # A task whose goal is never reached: no transition enters the terminal state.
    lines = [line for line in text.splitlines() if not line.startswith("(")]
    perfect.write_text("\n".join(lines) + "\n")

    def episode(run):
        env = smirl.make_learned(str(run))
        obs, _ = env.reset(seed=5)
        rng = np.random.default_rng(1)
        out = [obs]
        for _ in range(100):
            obs, r, _, truncated, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
            out.append(np.append(obs, r))
        return out

    for a, b in zip(episode(run_dir), episode(copy)):
        np.testing.assert_array_equal(a, b)


def test_bad_runs_raise_with_the_library_message(run_dir, tmp_path):
    with pytest.raises(smirl.SmirlError, match="smirl_seed9.json"):
        smirl.make_learned(str(run_dir), seed=9)
    with pytest.raises(smirl.SmirlError):
        smirl.make_learned(str(tmp_path / "missing"))
    env = smirl.make_learned(str(run_dir))
    with pytest.raises(smirl.SmirlError, match="before reset"):
        env.step(np.zeros(2, dtype=np.float32))
    reward = smirl.LearnedReward.read(str(run_dir / "rewards" / "smirl_seed0.json"))
    with pytest.raises(ValueError, match="columns"):
        reward.reward(np.zeros((2, 5), dtype=np.float32), np.zeros(2, dtype=np.uint32))
    with pytest.raises(ValueError, match="states"):
        reward.reward(np.zeros((2, 17), dtype=np.float32), np.zeros(3, dtype=np.uint32))

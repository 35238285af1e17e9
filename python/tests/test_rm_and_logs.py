"""Reward machines, LRM and logs through the package."""

import subprocess

import numpy as np
import pytest

import smirl
from conftest import scripted_demo_log

SEQUENCE = """\
vocabulary: ab
states: 3
initial: 0
terminal: 2
(0, 1, 'a', 0)
(1, 2, 'b', 1)
"""


def test_text_round_trip_and_stepping():
    rm = smirl.RewardMachine.from_text(SEQUENCE)
    again = smirl.RewardMachine.from_text(rm.to_text())
    assert again.to_text() == rm.to_text()
    assert rm.equivalent(again)
    assert (rm.n_states, rm.initial, rm.vocabulary) == (3, 0, "ab")
    assert rm.step(0, "a") == (1, 0.0)
    assert rm.step(1, "b") == (2, 1.0)
    assert rm.run(["", "b", "a", "", "b"])[-1] == (2, 1.0)
    assert "digraph" in rm.to_dot()


def test_write_refuses_to_replace_a_file(tmp_path):
    rm = smirl.RewardMachine.from_text(SEQUENCE)
    path = tmp_path / "m.txt"
    rm.write(path)
    assert smirl.RewardMachine.read(path).equivalent(rm)
    with pytest.raises(smirl.SmirlError, match="already exists"):
        rm.write(path)


def test_bad_machine_text_names_the_line():
    with pytest.raises(smirl.SmirlError, match=r"mine:5"):
        smirl.RewardMachine.from_text(SEQUENCE.replace("'a'", "'a&'"), "mine")
    with pytest.raises(ValueError):
        smirl.RewardMachine.from_text(SEQUENCE).step(0, "z")
    with pytest.raises(ValueError):
        smirl.RewardMachine.from_text(SEQUENCE).step(7, "a")


def test_learn_rm_recovers_a_sequence():
    # Demonstrations of "a then b" with rewards: LRM must find a machine equivalent to it.
    traces, rewards = [], []
    rng = np.random.default_rng(0)
    for _ in range(20):
        gap1, gap2 = rng.integers(1, 4, 2)
        t = [""] * gap1 + ["a"] + [""] * gap2 + ["b"]
        traces.append(t)
        rewards.append([0.0] * (len(t) - 1) + [1.0])
    rm, stats = smirl.learn_rm(traces, "ab", rewards=rewards, max_states=4, seed=1)
    truth = smirl.RewardMachine.from_text(SEQUENCE)
    # Up to the goal (the demonstrations show nothing after it) the learned machine pays
    # what the true one pays, also on orders no demonstration shows.
    probes = [["b"], ["", "b"], ["b", "", "a", "", "b"], ["a", "a", "", "b"], ["b", "a"], ["a", "b"]]
    for trace in probes:
        assert [r for _, r in rm.run(trace)] == [r for _, r in truth.run(trace)], (trace, rm.to_text())
    assert stats["cost"] >= 0


def test_learn_rm_refuses_bad_traces():
    with pytest.raises(ValueError, match="trace 1"):
        smirl.learn_rm([["a"], ["z"]], "ab")
    with pytest.raises(ValueError):
        smirl.learn_rm([["a"]], "ab", rewards=[[0.0], [1.0]])
    with pytest.raises(ValueError):
        smirl.learn_rm([["a"]], "aa")


@pytest.fixture(scope="module")
def demo_log(tmp_path_factory, reacher_bin):
    """A log written by the `reacher` binary (scripted demonstrations of Composite)."""
    return scripted_demo_log(reacher_bin, tmp_path_factory.mktemp("log") / "demo.mcap", "composite", 6)


def test_read_log_written_by_reacher(demo_log):
    log = smirl.read_log(demo_log)
    assert log["run"]["env"] == "ReacherDelivery"
    assert log["model_xml"] and log["recovery"] is None
    assert len(log["episodes"]) == 6
    for ep in log["episodes"]:
        n = ep["actions"].shape[0]
        assert ep["actions"].shape == (n, 2) and ep["qpos"].shape[0] == n
        assert ep["rewards"].shape == ep["rm_states"].shape == (n,)
        assert len(ep["label_text"]) == n and ep["complete"]


def test_read_log_truncated_needs_allow_partial(demo_log, tmp_path):
    data = demo_log.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    with pytest.raises(smirl.SmirlError, match="allow_partial"):
        smirl.read_log(cut)
    partial = smirl.read_log(cut, allow_partial=True)
    assert partial["recovery"] is not None
    whole = smirl.read_log(demo_log)["episodes"]
    for got, want in zip(partial["episodes"], whole):
        if got["complete"]:
            assert np.array_equal(got["actions"], want["actions"])


def test_read_log_refuses_garbage(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a log at all" * 10)
    with pytest.raises(smirl.SmirlError, match="junk.mcap"):
        smirl.read_log(junk)
    with pytest.raises(smirl.SmirlError):
        smirl.read_log(tmp_path / "missing.mcap")


def test_same_seed_same_trajectory_as_the_reacher_binary(demo_log):
    """The package's environment, fed a logged episode's seed and actions, reproduces the
    binary's observations, labels and machine states bit for bit."""
    env = smirl.make("composite")
    for ep in smirl.read_log(demo_log)["episodes"]:
        obs, info = env.reset(seed=ep["seed"])
        assert np.array_equal(obs[:17], ep["start_obs"])
        assert info["rm_state"] == ep["start_rm_state"]
        for t, action in enumerate(ep["actions"]):
            obs, _, term, trunc, info = env.step(action)
            assert np.array_equal(obs[:17], ep["observations"][t]), (ep["seed"], t)
            assert info["labels"] == ep["label_text"][t]
            assert info["rm_state"] == ep["rm_states"][t]
            assert info["env_reward"] == ep["rewards"][t]
            if term or trunc:  # the product ends here; the scripted demo may go on
                break


def python_episodes(task, seeds):
    """Episodes played in Python with random actions, ended where the environment ends them."""
    env = smirl.make(task)
    rng = np.random.default_rng(0)
    episodes = []
    for seed in seeds:
        env.reset(seed=seed)
        actions = []
        while True:
            a = rng.uniform(-1, 1, 2).astype(np.float32)
            actions.append(a)
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                break
        episodes.append((seed, np.array(actions, dtype=np.float32)))
    return episodes


def test_write_log_is_read_back_and_replayed_by_the_binary(tmp_path, reacher_bin):
    episodes = python_episodes("sequential", [3, 4, 5])
    path = tmp_path / "py.mcap"
    steps = smirl.write_log(path, "sequential", episodes)
    assert steps == sum(len(a) for _, a in episodes)
    log = smirl.read_log(path)
    assert log["run"]["task"] == "sequential"
    for (seed, actions), ep in zip(episodes, log["episodes"]):
        assert ep["seed"] == seed and np.array_equal(ep["actions"], actions)
    with pytest.raises(smirl.SmirlError, match="already exists"):
        smirl.write_log(path, "sequential", episodes)
    replay = subprocess.run([reacher_bin, "replay", "--verify", str(path)], capture_output=True, text=True)
    assert replay.returncode == 0, replay.stdout + replay.stderr
    learned = subprocess.run(
        [reacher_bin, "learn-rm", str(path), "--out", str(tmp_path / "lrm")], capture_output=True, text=True
    )
    assert learned.returncode == 0, learned.stdout + learned.stderr
    assert (tmp_path / "lrm" / "learned_rm.txt").exists()


def test_write_log_refuses_bad_episodes_and_leaves_no_file(tmp_path):
    path = tmp_path / "bad.mcap"
    long = np.zeros((101, 2), np.float32)  # one action past the time limit
    with pytest.raises(smirl.SmirlError, match="episode 0"):
        smirl.write_log(path, "blue", [(0, long)])
    with pytest.raises(smirl.SmirlError, match="shape"):
        smirl.write_log(path, "blue", [(0, np.zeros((5, 3), np.float32))])
    nan = np.full((5, 2), np.nan, np.float32)
    with pytest.raises(smirl.SmirlError, match="not a finite number"):
        smirl.write_log(path, "blue", [(0, nan)])
    assert not path.exists() and list(tmp_path.iterdir()) == []


def test_learn_rm_learns_what_the_reacher_binary_learns(demo_log, reacher_bin, tmp_path):
    """`smirl.learn_rm` with its defaults (SMIRL's learner, the task's event declared) learns
    from a log's label traces the machine `reacher learn-rm` learns from the log; the paper's
    rules are a different learner."""
    subprocess.run(
        [reacher_bin, "learn-rm", str(demo_log), "--out", str(tmp_path)],
        check=True,
        capture_output=True,
    )
    cli = smirl.RewardMachine.from_text((tmp_path / "learned_rm.txt").read_text())
    episodes = smirl.read_log(demo_log)["episodes"]
    traces = [list(ep["label_text"]) for ep in episodes]
    rewards = [[float(r) for r in ep["rm_rewards"]] for ep in episodes]
    vocab = cli.vocabulary
    rm, _ = smirl.learn_rm(traces, vocab, rewards=rewards, events="c")
    assert rm.to_text() == cli.to_text()
    with pytest.raises(ValueError, match="rules"):
        smirl.learn_rm(traces, vocab, events="c", rules="mine")

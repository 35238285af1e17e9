"""The Gymnasium environments: API conformance, seeding, the machine in the loop, errors."""

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import smirl


@pytest.mark.parametrize("task", ["or", "sequential", "if", "composite", "blue"])
def test_passes_gymnasium_env_checker(task):
    env = smirl.make(task, render_mode="rgb_array")
    check_env(env, skip_render_check=False)


def test_registered_ids_make_the_task():
    env = gym.make("smirl/ReacherDelivery-Composite-v0")
    assert env.unwrapped.task == "composite"
    obs, _ = env.reset(seed=3)
    # 17 arm values + 7 machine states (composite's perfect machine).
    assert obs.shape == (17 + 7,)
    assert gym.make("smirl/ReacherDelivery-IF-v0").unwrapped.task == "if"


def rollout(env, seed, steps=100):
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        out.append(np.append(obs, [r, term, trunc, info["rm_state"]]))
        if term or trunc:
            break
    return out


def test_same_seed_same_trajectory_other_seed_other():
    a = rollout(smirl.make("composite"), 5)
    b = rollout(smirl.make("composite"), 5)
    c = rollout(smirl.make("composite"), 6)
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_episode_is_truncated_at_the_task_length():
    env = smirl.make("blue")
    env.reset(seed=0)
    steps = 0
    while True:
        _, _, term, trunc, info = env.step(np.zeros(2, np.float32))
        steps += 1
        if term or trunc:
            break
    # An arm at rest near its start touches nothing: the episode runs its 100 steps.
    assert (steps, trunc, term, info["success"]) == (100, True, False, False)


def test_machine_state_one_hot_and_labels_follow_the_perfect_machine():
    env = smirl.make("composite")
    rm = env.reward_machine
    obs, info = env.reset(seed=1)
    u = info["rm_state"]
    rng = np.random.default_rng(0)
    for _ in range(100):
        obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, 2))
        u_next, reward = rm.step(u, info["labels"])
        assert info["rm_state"] == u_next
        assert info["task_reward"] == reward == r  # no shaping asked for
        one_hot = obs[17:]
        assert one_hot.sum() == 1.0 and one_hot[u_next] == 1.0
        assert info["branch"] in ("normal", "event")
        u = u_next
        if term or trunc:
            break


def test_cancel_event_appears_in_labels_on_its_step():
    env = smirl.make("if")
    for seed in range(50):
        _, _ = env.reset(seed=seed)
        while True:
            _, _, term, trunc, info = env.step(np.zeros(2))
            if info["cancel_step"] is not None and info["step"] == info["cancel_step"]:
                assert "c" in info["labels"]
                assert info["branch"] == "event"  # before blue: blue is off the task
                return
            if term or trunc:
                break
    pytest.fail("no episode of 50 had a cancel")


def scene_colours(scene):
    """Each geom's RGB (0–255) as the scene XML gives it, by geom name."""
    out = {}
    for geom in ET.parse(scene).iter("geom"):
        if "name" in geom.attrib and "rgba" in geom.attrib:
            out[geom.attrib["name"]] = [255 * float(c) for c in geom.attrib["rgba"].split()[:3]]
    return out


@pytest.mark.parametrize(
    "task, scene",
    [("composite", "reacher_delivery.xml"), ("scenes/six_targets_ring.toml", "scenes/six_targets.xml")],
)
def test_render_draws_each_region_in_its_geoms_colour(task, scene):
    root = Path(__file__).resolve().parents[2] / "assets"
    task = task if "/" not in task else str(root / task)
    env = smirl.make(task, render_mode="rgb_array", render_size=128)
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (128, 128, 3) and img.dtype == np.uint8
    colours = scene_colours(root / scene)
    _, regions = env.unwrapped._core.scene()
    assert len(regions) in (4, 6)
    for name, _, _, _, rgb in regions:
        assert np.abs(np.array(rgb) - colours[name]).max() <= 1, (name, rgb)
        assert (img == rgb).all(axis=2).any(), name
    assert (img == (60, 60, 60)).all(axis=2).any()  # the arm


@pytest.mark.parametrize(
    "action",
    [
        np.zeros(3, np.float32),
        np.zeros((2, 2)),
        [math.nan, 0.0],
        [math.inf, 0.0],
        "ab",
        None,
    ],
)
def test_bad_actions_raise_python_exceptions(action):
    env = smirl.make("or")
    env.reset(seed=0)
    with pytest.raises((ValueError, TypeError, smirl.SmirlError)):
        env.step(action)


def test_bad_arguments_raise_python_exceptions():
    with pytest.raises(smirl.SmirlError, match="no shipped task named 'nope'"):
        smirl.make("nope")
    with pytest.raises(ValueError):
        smirl.make("or", shaping=math.nan)
    with pytest.raises(ValueError):
        smirl.make("or", gamma=0.0)
    env = smirl.make("or")
    with pytest.raises((ValueError, gym.error.Error)):
        env.reset(seed=-1)
    with pytest.raises((ValueError, gym.error.Error)):
        env.reset(seed=2**64)
    with pytest.raises(smirl.SmirlError, match="before reset"):
        smirl.make("or").step([0.0, 0.0])


def test_step_after_the_end_raises():
    env = smirl.make("blue")
    env.reset(seed=0)
    for _ in range(100):
        env.step([0.0, 0.0])
    with pytest.raises(smirl.SmirlError, match="call reset first"):
        env.step([0.0, 0.0])


def test_vector_env_matches_single_envs_and_thread_count():
    # 7 environments: the chunks of 2 and 4 threads are uneven (4 + 3, 2 + 2 + 2 + 1); 130 steps
    # cross every episode's end, so the autoreset runs on the worker threads too.
    n, seed = 7, 11
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (130, n, 2)).astype(np.float32)
    results = []
    for threads in (1, 2, 4):
        venv = smirl.make_vec("composite", n, threads=threads)
        obs, _ = venv.reset(seed=seed)
        trace = [obs]
        for a in actions:
            obs, r, term, trunc, info = venv.step(a)
            trace.append(np.column_stack([obs, r, term, trunc, info["rm_state"]]))
        results.append(trace)
    for other in results[1:]:
        assert all(np.array_equal(x, y) for x, y in zip(results[0], other))
    for i in range(n):
        env = smirl.make("composite")
        obs, _ = env.reset(seed=seed + i)
        assert np.array_equal(obs, results[0][0][i])
        for t, a in enumerate(actions):
            obs, r, term, trunc, info = env.step(a[i])
            assert np.array_equal(obs, results[0][t + 1][i, : obs.size])
            assert r == results[0][t + 1][i, obs.size]
            if term or trunc:
                break


def test_vector_env_autoresets_next_step():
    venv = smirl.make_vec("blue", 2)
    venv.reset(seed=0)
    zeros = np.zeros((2, 2), np.float32)
    for _ in range(99):
        _, _, term, trunc, _ = venv.step(zeros)
        assert not (term | trunc).any()
    _, _, term, trunc, _ = venv.step(zeros)
    assert trunc.all()
    obs, r, term, trunc, _ = venv.step(zeros)  # the reset step
    assert (r == 0).all() and not (term | trunc).any()


def test_vector_env_refuses_bad_shapes_and_sizes():
    venv = smirl.make_vec("or", 3)
    venv.reset(seed=0)
    with pytest.raises(ValueError):
        venv.step(np.zeros((2, 2)))
    with pytest.raises(ValueError):
        smirl.make_vec("or", 0)
    with pytest.raises(ValueError):
        smirl.make_vec("or", 10**6)


def test_a_task_file_makes_an_environment(tmp_path):
    """A user's task file: the shipped IF task with its machine beside it and a later event."""
    root = Path(__file__).resolve().parents[2]
    text = (root / "assets" / "tasks" / "if.toml").read_text()
    text = text.replace('machine = "../rm/reacher_if.txt"', 'machine = "mine.txt"')
    text = text.replace("earliest_step = 1\nlatest_step = 8", "earliest_step = 20\nlatest_step = 30")
    (tmp_path / "mine.txt").write_text(smirl.RewardMachine.shipped("reacher_if").to_text())
    (tmp_path / "late.toml").write_text(text)
    env = smirl.make(str(tmp_path / "late.toml"))
    assert env.task == "late"
    check_env(env)
    for seed in range(40):
        env.reset(seed=seed)
        while True:
            _, _, term, trunc, info = env.step(np.zeros(2))
            if info["cancel_step"] is not None:
                assert 20 <= info["cancel_step"] <= 30
            if term or trunc:
                break
    (tmp_path / "bad.toml").write_text(text.replace("radius = 0.02", "radius = -1", 1))
    with pytest.raises(smirl.SmirlError, match="bad.toml"):
        smirl.make(str(tmp_path / "bad.toml"))

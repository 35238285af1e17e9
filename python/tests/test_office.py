"""Office gridworld tasks through the package."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import smirl


@pytest.mark.parametrize("task", ["0", "1", "2", "3", "4"])
def test_office_passes_the_env_checker(task):
    check_env(smirl.make_office(task), skip_render_check=True)
    assert gym.make(f"smirl/Office-T{task}-v0").unwrapped.task == task


def shortest_plan(env, max_depth=40):
    """Breadth-first search over (cell, machine state) for a sequence reaching success."""
    from collections import deque

    core = env.unwrapped._core
    start = tuple(env.reset()[0])
    queue, seen = deque([(start, [])]), {start}
    while queue:
        _, plan = queue.popleft()
        if len(plan) >= max_depth:
            continue
        for a in range(4):
            core.reset()
            for b in plan:
                core.step(b)
            (cell, u), _, term, _, info = core.step(a)
            if info["success"]:
                return plan + [a]
            if not term and (cell, u) not in seen:
                seen.add((cell, u))
                queue.append(((cell, u), plan + [a]))
    return None


def test_office_task_can_be_solved_and_pays_its_machine_reward():
    env = smirl.make_office("2")  # mail, then office
    plan = shortest_plan(env)
    assert plan is not None
    env.reset()
    total = 0.0
    for a in plan:
        _, r, term, trunc, info = env.step(a)
        total += r
    assert term and info["success"] and total == 1.0
    with pytest.raises(smirl.SmirlError, match="call reset first"):
        env.step(0)


def test_office_user_task_file(tmp_path):
    (tmp_path / "tiny.map").write_text(smirl.make_office("0").unwrapped._core.map_text)
    (tmp_path / "m.txt").write_text(smirl.RewardMachine.shipped("office_t1").to_text())
    (tmp_path / "task.toml").write_text('name = "mine"\nmap = "tiny.map"\nmachine = "m.txt"\n')
    env = smirl.make_office(str(tmp_path / "task.toml"))
    assert env.task == "mine"
    check_env(env, skip_render_check=True)


@pytest.mark.parametrize("action", [4, -1, 1.5, "a", None, np.array([1, 2]), True])
def test_office_bad_actions_raise(action):
    env = smirl.make_office("0")
    env.reset()
    with pytest.raises((ValueError, TypeError, OverflowError)):
        env.step(action)


def test_office_bad_tasks_raise(tmp_path):
    with pytest.raises(smirl.SmirlError):
        smirl.make_office("9")
    (tmp_path / "bad.toml").write_text('map = "nope.map"\nmachine = "m.txt"\n')
    with pytest.raises(smirl.SmirlError, match="nope.map"):
        smirl.make_office(str(tmp_path / "bad.toml"))
    with pytest.raises(ValueError):
        smirl.make_office("0", max_steps=0)

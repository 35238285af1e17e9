"""Gymnasium environments over the Rust core.

A task's environment is ReacherDelivery × the task's perfect reward machine: the observation
is the arm's observation followed by the machine state one-hot, the reward is the machine's
(plus sub-goal shaping when ``shaping > 0``), an episode terminates when the machine reaches
its goal or a failure sink and is truncated at the task's episode length.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _core

#: Largest seed a reset takes (seeds are unsigned 64-bit in the core).
MAX_SEED = 2**64 - 1

_ARENA_HALF = 0.33  # metres shown on each side of the base in ``render()``


def _observation_space(dim: int) -> spaces.Box:
    return spaces.Box(-np.inf, np.inf, shape=(dim,), dtype=np.float32)


def _action_space(dim: int) -> spaces.Box:
    return spaces.Box(-1.0, 1.0, shape=(dim,), dtype=np.float32)


def _seed_from(rng: np.random.Generator) -> int:
    return int(rng.integers(0, 2**63))


def _reset_seed(seed: int | None, rng: np.random.Generator) -> int:
    """A reset's seed: the one given, checked, or one drawn from ``rng``."""
    if seed is None:
        return _seed_from(rng)
    if not 0 <= int(seed) <= MAX_SEED:
        raise ValueError(f"seed must be in 0..2**64, got {seed}")
    return int(seed)


def _checked_action(action, shape) -> np.ndarray:
    """``action`` as a flat float32 array of ``shape``, or ``ValueError``."""
    action = np.asarray(action, dtype=np.float32).reshape(-1)
    if action.shape != shape:
        raise ValueError(f"action has shape {action.shape}, the environment takes {shape}")
    return action


class ReacherDeliveryEnv(gym.Env):
    """One ReacherDelivery task (``or``, ``sequential``, ``if``, ``composite``, ``blue``).

    ``info`` of a step holds ``labels`` (the propositions true after it, e.g. ``"rc"``),
    ``rm_state``, ``task_reward`` (the machine's reward without shaping), ``env_reward``,
    ``success``, ``failure``, ``step``, ``cancel_step`` and, for a task whose machine has an
    event branch (IF, Composite, ...), ``branch`` (``"normal"`` or ``"event"``).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(
        self,
        task: str = "composite",
        shaping: float = 0.0,
        gamma: float = 0.99,
        render_mode: str | None = None,
        render_size: int = 256,
    ):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if not 16 <= int(render_size) <= 4096:
            raise ValueError(f"render_size must be in 16..4096, got {render_size}")
        self._core = _core.ReacherCore(task, shaping, gamma)
        self.task = self._core.task
        self.render_mode = render_mode
        self.render_size = int(render_size)
        self.observation_space = _observation_space(self._core.obs_dim)
        self.action_space = _action_space(self._core.act_dim)
        self.spec_max_steps = self._core.max_steps
        self.reward_machine = _core.RewardMachine.from_text(
            self._core.reward_machine, f"perfect machine of {self.task}"
        )

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        seed = _reset_seed(seed, self.np_random)
        obs = self._core.reset(seed)
        return obs, {"rm_state": self._core.rm_state, "seed": seed}

    def step(self, action):
        action = _checked_action(action, self.action_space.shape)
        return self._core.step(action.tolist())

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        arm, regions = self._core.scene()
        return top_down(arm, regions, self.render_size)


def top_down(arm, regions, size: int) -> np.ndarray:
    """A top-down RGB picture (``size × size × 3``, uint8) of the arm among its regions.

    ``arm`` is the (shoulder, elbow, fingertip) positions; ``regions`` are ``(name, x, y,
    radius, rgb)``, each a disc of its label radius in the colour of the scene's geom of that
    name (as ``reacher render`` draws it).
    """
    img = np.full((size, size, 3), 245, dtype=np.uint8)
    ys, xs = np.mgrid[0:size, 0:size]
    scale = size / (2 * _ARENA_HALF)
    wx = xs / scale - _ARENA_HALF
    wy = _ARENA_HALF - ys / scale
    for _, x, y, radius, rgb in regions:
        mask = (wx - x) ** 2 + (wy - y) ** 2 < max(radius, 1.5 / scale) ** 2
        img[mask] = rgb
    shoulder, elbow, tip = (tuple(p) for p in arm)
    for (x0, y0), (x1, y1) in ((shoulder, elbow), (elbow, tip)):
        dx, dy = x1 - x0, y1 - y0
        t = np.clip(((wx - x0) * dx + (wy - y0) * dy) / (dx * dx + dy * dy + 1e-12), 0, 1)
        d2 = (wx - x0 - t * dx) ** 2 + (wy - y0 - t * dy) ** 2
        img[d2 < (0.008) ** 2] = (60, 60, 60)
    img[(wx - tip[0]) ** 2 + (wy - tip[1]) ** 2 < 0.01**2] = (0, 0, 0)
    return img


class LearnedProductEnv(gym.Env):
    """The environment SMIRL's agent learns in, rebuilt from a run directory: ReacherDelivery ×
    the run's learned machine (``rm/learned.txt``, or ``machine``), paying the learned reward
    ``rewards/<algo>_seed<seed>.json`` (δ_r(u, o) = w_uᵀ φ(o), u the learned state before the
    step, o the observation after it; no shaping).

    The observation is the environment's, then the learned state's one-hot, as smirl's agent
    sees it. Episodes are only
    truncated (at the task's episode length): the task's perfect machine never ends one, and
    the agent sees nothing of it. ``info`` holds ``labels``, ``rm_state`` (learned) and, for
    judging only, ``success``/``failure`` on the step the task's machine reaches its goal or a
    failure state, ``task_done``, ``task_rm_state`` and, for a conditional task, ``branch``.
    """

    metadata = {"render_modes": []}

    def __init__(self, run: str, algo: str = "smirl", seed: int = 0, machine: str | None = None):
        self._core = _core.LearnedProductCore(str(run), algo, int(seed), machine)
        self.task = self._core.task
        self.observation_space = _observation_space(self._core.obs_dim)
        self.action_space = _action_space(self._core.act_dim)
        self.reward_machine = _core.RewardMachine.from_text(
            self._core.reward_machine, f"learned machine of {run}"
        )

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        seed = _reset_seed(seed, self.np_random)
        return self._core.reset(seed), {"seed": seed}

    def step(self, action):
        action = _checked_action(action, self.action_space.shape)
        return self._core.step(action.tolist())


class ReacherDeliveryVectorEnv(VectorEnv):
    """``num_envs`` environments of one task stepped together in Rust (GIL released).

    Autoreset is Gymnasium's next-step mode: the step after an episode ends resets that
    environment (reward 0, not terminated) with a seed drawn from the vector environment's
    generator, seeded by ``reset(seed=...)``.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        task: str = "composite",
        num_envs: int = 8,
        shaping: float = 0.0,
        gamma: float = 0.99,
        threads: int = 1,
    ):
        self._batch = _core.ReacherBatch(task, int(num_envs), shaping, gamma, int(threads))
        self.task = task
        self.num_envs = int(num_envs)
        self.single_observation_space = _observation_space(self._batch.obs_dim)
        self.single_action_space = _action_space(self._batch.act_dim)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._needs_reset = np.ones(self.num_envs, dtype=bool)
        self._rng = np.random.default_rng()

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        if seed is None:
            seeds = [_seed_from(self._rng) for _ in range(self.num_envs)]
        elif isinstance(seed, (list, tuple)):
            if len(seed) != self.num_envs:
                raise ValueError(f"{len(seed)} seeds for {self.num_envs} environments")
            seeds = [int(s) for s in seed]
        else:
            seeds = [int(seed) + i for i in range(self.num_envs)]
            self._rng = np.random.default_rng(int(seed))
        obs = self._batch.reset(list(range(self.num_envs)), seeds)
        self._needs_reset[:] = False
        return obs, {"seed": np.asarray(seeds, dtype=np.uint64)}

    def step(self, actions):
        actions = np.ascontiguousarray(actions, dtype=np.float32)
        if actions.shape != self.action_space.shape:
            raise ValueError(
                f"actions have shape {actions.shape}, the environments take {self.action_space.shape}"
            )
        restart = np.flatnonzero(self._needs_reset)
        if restart.size:
            self._batch.reset(restart.tolist(), [_seed_from(self._rng) for _ in restart])
        obs, rewards, terminated, truncated, success, states = self._batch.step(actions)
        if restart.size:
            rewards[restart] = 0.0
            terminated[restart] = False
            truncated[restart] = False
            success[restart] = False
        self._needs_reset = terminated | truncated
        return obs, rewards, terminated, truncated, {"success": success, "rm_state": states}


class OfficeEnv(gym.Env):
    """An Office gridworld task (a shipped name ``"0"``–``"4"`` or a task file's path).

    Observation: ``(cell, machine state)`` as ``MultiDiscrete([n_cells, n_rm_states])``;
    actions ``0``–``3`` (up, right, down, left); reward: the task machine's; terminated when the
    machine reaches its goal or a failure state, truncated after ``max_steps``. ``info`` holds
    ``labels``, ``xy``, ``success`` and ``failure``. The world is deterministic: ``seed`` only
    seeds ``np_random`` for the caller.
    """

    metadata = {"render_modes": []}

    def __init__(self, task: str = "0", max_steps: int = 100):
        self._core = _core.OfficeCore(str(task), int(max_steps))
        self.task = self._core.name
        self.observation_space = spaces.MultiDiscrete([self._core.n_cells, self._core.n_rm_states])
        self.action_space = spaces.Discrete(4)
        self.reward_machine = _core.RewardMachine.from_text(
            self._core.reward_machine, f"machine of Office task {self.task}"
        )

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        cell, u = self._core.reset()
        return np.array([cell, u], dtype=np.int64), {}

    def step(self, action):
        if isinstance(action, (bool, np.bool_)) or not isinstance(action, (int, np.integer)):
            arr = np.asarray(action)
            if arr.shape != () or not np.issubdtype(arr.dtype, np.integer):
                raise TypeError(f"an Office action is an integer 0-3, got {action!r}")
            action = int(arr)
        (cell, u), reward, terminated, truncated, info = self._core.step(int(action))
        return np.array([cell, u], dtype=np.int64), reward, terminated, truncated, info


def _title(task: str) -> str:
    return {"or": "OR", "if": "IF"}.get(task, task.capitalize())


def register_envs() -> None:
    """Registers ``smirl/ReacherDelivery-<Task>-v0`` and ``smirl/Office-T<k>-v0`` for the
    shipped tasks."""
    for task in _core.task_names():
        env_id = f"smirl/ReacherDelivery-{_title(task)}-v0"
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point="smirl.envs:ReacherDeliveryEnv",
            kwargs={"task": task},
            max_episode_steps=None,
            vector_entry_point="smirl.envs:ReacherDeliveryVectorEnv",
        )
    for task in _core.office_task_names():
        env_id = f"smirl/Office-T{task}-v0"
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="smirl.envs:OfficeEnv", kwargs={"task": task})


def make(task: str = "composite", **kwargs):
    """The environment of a ReacherDelivery task (a shipped name, e.g. ``"composite"``)."""
    return ReacherDeliveryEnv(task, **kwargs)


def make_learned(run: str, algo: str = "smirl", seed: int = 0, machine: str | None = None):
    """SMIRL's learned product of a run directory (see ``LearnedProductEnv``)."""
    return LearnedProductEnv(run, algo, seed, machine)


def make_office(task: str = "0", **kwargs) -> OfficeEnv:
    """The environment of an Office task (``"0"``–``"4"`` or a task file's path)."""
    return OfficeEnv(task, **kwargs)


def make_vec(task: str = "composite", num_envs: int = 8, **kwargs) -> ReacherDeliveryVectorEnv:
    """``num_envs`` environments of a task stepped together in Rust."""
    return ReacherDeliveryVectorEnv(task, num_envs, **kwargs)

"""smirl: reward machines learned from demonstrations, from Python.

The Rust core (``smirl._core``) holds the environments, reward machines, LRM and the MCAP
logs; this package puts them behind Gymnasium's interfaces:

- ``smirl.make("composite")`` — a ``gymnasium.Env`` of a ReacherDelivery task (also
  registered as ``smirl/ReacherDelivery-Composite-v0``), ``smirl.make_vec("composite", 16)``
  its vector version, stepped in Rust without the GIL; ``smirl.make_office("0")`` an Office
  gridworld task (``smirl/Office-T0-v0``);
- ``smirl.make_learned(run_dir)`` — the environment SMIRL's agent learns in, rebuilt from a run
  directory: the learned machine's product paying the learned reward (``smirl.LearnedReward``);
- ``smirl.RewardMachine``, ``smirl.learn_rm`` — machines and LRM;
- ``smirl.read_log`` — a rollout log's episodes as NumPy arrays.
"""

from ._core import (  # noqa: F401  (re-exported)
    GIT_COMMIT,
    LearnedReward,
    RewardMachine,
    SmirlError,
    __version__,
    learn_rm,
    write_log,
    read_log,
    task_names,
)
from .envs import (
    LearnedProductEnv,
    OfficeEnv,
    ReacherDeliveryEnv,
    ReacherDeliveryVectorEnv,
    make,
    make_learned,
    make_office,
    make_vec,
    register_envs,
)

register_envs()

__all__ = [
    "GIT_COMMIT",
    "LearnedProductEnv",
    "LearnedReward",
    "OfficeEnv",
    "ReacherDeliveryEnv",
    "ReacherDeliveryVectorEnv",
    "RewardMachine",
    "SmirlError",
    "learn_rm",
    "make",
    "make_learned",
    "make_office",
    "make_vec",
    "read_log",
    "register_envs",
    "task_names",
    "write_log",
]

"""Fixtures shared by the package's tests."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def reacher_bin():
    """The `reacher` binary (SMIRL_REACHER_BIN, else on PATH, else the checkout's release
    build); the test is skipped without one."""
    binary = os.environ.get("SMIRL_REACHER_BIN") or shutil.which("reacher")
    if binary is None and (ROOT / "target" / "release" / "reacher").exists():
        binary = str(ROOT / "target" / "release" / "reacher")
    if binary is None:
        pytest.skip("no reacher binary (build it with cargo build --release)")
    return binary


def scripted_demo_log(reacher_bin, out, task, episodes):
    """Writes `out`: `episodes` scripted demonstrations of `task` with observations, logged by
    the `reacher` binary."""
    subprocess.run(
        [reacher_bin, "demo", "--task", task, "--episodes", str(episodes), "--observations", "--out", str(out)],
        check=True,
        capture_output=True,
    )
    return out

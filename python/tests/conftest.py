"""Fixtures shared by the package's tests."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def reacher_bin():
    """The `reacher` binary: SMIRL_REACHER_BIN, else `reacher` on PATH, else the release build
    in CARGO_TARGET_DIR or the checkout's `target/`. Without one the test fails rather than
    skips: a skip would let a broken build hide every test that drives the binary."""
    binary = os.environ.get("SMIRL_REACHER_BIN") or shutil.which("reacher")
    if binary is None:
        target = Path(os.environ.get("CARGO_TARGET_DIR") or ROOT / "target")
        built = target / "release" / "reacher"
        if built.exists():
            binary = str(built)
    if binary is None:
        pytest.fail(
            "no reacher binary: build it with `cargo build --release --bin reacher` "
            "(or set SMIRL_REACHER_BIN)"
        )
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

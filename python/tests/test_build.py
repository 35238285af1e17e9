"""The package's core (python/Cargo.toml, its own workspace) builds in the root workspace's
target directory (the README's test command and CI set CARGO_TARGET_DIR): that shares the
compiled dependencies (zstd's C sources among them) only while both
lock files resolve every crate they share to the same version."""

import pytest

from conftest import ROOT

tomllib = pytest.importorskip("tomllib")  # Python 3.11 and later


def locked(path):
    with open(path, "rb") as f:
        return {(p["name"], p["version"]) for p in tomllib.load(f)["package"]}


def compatible(version):
    """Cargo's compatibility class of a version: versions in one class unify to one build."""
    major, minor, patch = (int(x) for x in version.split("+")[0].split("-")[0].split("."))
    return (major,) if major else (0, minor) if minor else (0, 0, patch)


def test_the_package_locks_the_workspace_versions_of_shared_crates():
    workspace = locked(ROOT / "Cargo.lock")
    package = locked(ROOT / "python" / "Cargo.lock")
    classes = {(name, compatible(version)) for name, version in workspace}
    # A crate the workspace also uses, at another version of the same compatibility class
    # (another major version, e.g. pyo3's rustc-hash 2 beside bindgen's 1, is a crate apart).
    differ = sorted((n, v) for n, v in package - workspace if (n, compatible(v)) in classes)
    assert not differ, (
        f"python/Cargo.lock resolves {differ} differently from Cargo.lock; "
        "copy Cargo.lock to python/ and run `cargo metadata --manifest-path python/Cargo.toml`"
    )

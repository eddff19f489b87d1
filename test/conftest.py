"""Shared test fixtures: every pytest run gets its own ROS domain, confined to this host."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings

REPO = Path(__file__).resolve().parent.parent
SCENES = REPO / "config" / "scenes"
PROBLEMS = REPO / "config" / "problems"
PACKAGE = "physics_mapper"
COLCON = Path(sys.executable).parent / "colcon"
#: Top-level entries of the checkout that are not package sources.
NOT_SOURCES = {".venv", ".git", "build", "install", "log", "reports", ".mypy_cache", ".ruff_cache", ".pytest_cache"}


# Property-based tests (test_fuzz.py). `make test` runs the "ci" profile: a fixed set of examples,
# the same on every run (derandomized: seeded from each test's source), no example database.
# `HYPOTHESIS_PROFILE=fuzz .venv/bin/pytest test/msg_adapters/test_fuzz.py` searches at random, 50 times longer,
# and keeps every failure in .hypothesis/ (git-ignored) to try it first on the next run.
settings.register_profile("ci", max_examples=100, derandomize=True, database=None, deadline=None)
settings.register_profile("fuzz", max_examples=5_000, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def pytest_configure(config: pytest.Config) -> None:
    """Matplotlib's settings and font cache of this run's own (inherited by child processes), set before
    any test module imports matplotlib: a user's matplotlibrc (``text.usetex: True`` on a machine without
    LaTeX, another style) would otherwise break or change the figures that experiments and sweeps draw.

    And Ctrl-C as a terminal delivers it: a shell without job control starts a background job (``make test
    &`` in a script) with SIGINT ignored, children inherit that, and Python then never raises
    KeyboardInterrupt, so the tests of what Ctrl-C does would see it ignored. A handled signal is reset to
    the default at exec, so the commands under test get Python's own handler again."""
    os.environ["MPLCONFIGDIR"] = tempfile.mkdtemp(prefix="physics_mapper_matplotlib_")
    os.environ.pop("MATPLOTLIBRC", None)
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_unconfigure(config: pytest.Config) -> None:
    shutil.rmtree(os.environ["MPLCONFIGDIR"], ignore_errors=True)


def _domain_id() -> int:
    # Fast DDS supports domain ids 0..232; a per-process choice keeps parallel runs apart.
    return 10 + os.getpid() % 200


@pytest.fixture(scope="session", autouse=True)
def ros_environment() -> None:
    """Isolate DDS traffic of this run: own ROS_DOMAIN_ID, discovery on localhost only.

    Set in os.environ so that child processes (the node under test) inherit it.
    """
    # Unconditional: a domain set in the shell would let this run talk to other runs or robots.
    os.environ["ROS_DOMAIN_ID"] = str(_domain_id())
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")


@pytest.fixture(scope="session", autouse=True)
def decomposition_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A decomposition cache of this run's own (inherited by child processes), never the user's."""
    folder = tmp_path_factory.mktemp("cache")
    os.environ["PHYSICS_MAPPER_CACHE_DIR"] = str(folder)
    return folder / "decompositions"


def not_sources(directory: str, names: list[str]) -> set[str]:
    ignored = {n for n in names if n == "__pycache__" or n.endswith(".egg-info")}
    if Path(directory) == REPO:
        ignored |= NOT_SOURCES & set(names)
    return ignored


@pytest.fixture(scope="session")
def colcon_workspace(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A colcon workspace holding a copy of the package sources, built (``install/`` as on a ROS machine)."""
    root = tmp_path_factory.mktemp("colcon_ws")
    shutil.copytree(REPO, root / "src" / PACKAGE, ignore=not_sources)
    built = subprocess.run([str(COLCON), "build"], cwd=root, capture_output=True, text=True, timeout=300, check=False)
    assert built.returncode == 0, built.stdout + built.stderr
    yield root


def run_installed(
    workspace: Path, arguments: str, cwd: Path, timeout: float = 120.0
) -> subprocess.CompletedProcess[str]:
    """Run the installed ``physics-mapper ARGUMENTS`` in ``cwd`` with the workspace's colcon environment sourced."""
    script = workspace.resolve() / "install" / PACKAGE / "lib" / PACKAGE / "physics-mapper"
    command = f"source {workspace.resolve() / 'install' / 'setup.bash'} && exec {script} {arguments}"
    return subprocess.run(
        ["bash", "-c", command], cwd=cwd, capture_output=True, text=True, timeout=timeout, check=False
    )

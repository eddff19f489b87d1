"""``python -m physics_mapper`` (:mod:`physics_mapper.__main__`) is the ``physics-mapper`` command line."""

from __future__ import annotations

import subprocess
import sys


def test_python_m_physics_mapper_runs_the_command_line() -> None:
    completed = subprocess.run(
        [sys.executable, "-m", "physics_mapper", "bench", "no_such_benchmark"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert completed.returncode == 2
    assert completed.stderr.startswith("physics-mapper bench: error: no benchmark 'no_such_benchmark'")

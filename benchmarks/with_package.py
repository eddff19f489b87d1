"""A script run with another copy of the ``physics_mapper`` package (last round's), for side-by-side benchmarks."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any


def run_with_package(script: str, package: Path, data: object, failure: str) -> Any:
    """Run Python ``script`` in a subprocess whose path starts with ``package`` (a folder holding a
    ``physics_mapper`` package), ``data`` pickled on its stdin; returns the JSON of its last line of output.
    Raises RuntimeError, ``failure`` followed by the script's stderr, if it fails."""
    environment = {**os.environ, "PYTHONPATH": str(package)}
    command = [sys.executable, "-c", script]
    completed = subprocess.run(command, input=pickle.dumps(data), capture_output=True, env=environment)
    if completed.returncode != 0:
        raise RuntimeError(f"{failure}:\n{completed.stderr.decode()}")
    return json.loads(completed.stdout.decode().splitlines()[-1])

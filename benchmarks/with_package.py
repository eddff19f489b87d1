"""A script run with another copy of the ``physics_mapper`` package (last round's), for side-by-side benchmarks."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

#: Run first in the subprocess: the script must import the package in ``package``, or the comparison is the
#: code with itself (``python -c`` puts the working directory first on the path: run from a checkout, its
#: own ``physics_mapper`` would shadow ``package``'s).
GUARD = """
import pathlib as _pathlib, physics_mapper as _imported
if _pathlib.Path(_imported.__file__).resolve().parent.parent != _pathlib.Path({package!r}).resolve():
    raise SystemExit(f"physics_mapper was imported from {{_imported.__file__}}, not from {package!r}")
"""


def run_with_package(script: str, package: Path, data: object, failure: str) -> Any:
    """Run Python ``script`` in a subprocess whose path starts with ``package`` (a folder holding a
    ``physics_mapper`` package) and that checks it imports that package, ``data`` pickled on its stdin;
    returns the JSON of its last line of output. Raises RuntimeError, ``failure`` followed by the script's
    stderr, if it fails."""
    environment = {**os.environ, "PYTHONPATH": str(package)}
    command = [sys.executable, "-c", GUARD.format(package=str(package)) + script]
    completed = subprocess.run(command, input=pickle.dumps(data), capture_output=True, env=environment, cwd=package)
    if completed.returncode != 0:
        raise RuntimeError(f"{failure}:\n{completed.stderr.decode()}")
    return json.loads(completed.stdout.decode().splitlines()[-1])

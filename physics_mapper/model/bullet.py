"""pybullet, imported without its banner, and a way to silence what its C code prints.

pybullet's C extension writes a build-time banner to file descriptor 2 when it is imported, and
V-HACD prints its parameters and progress on file descriptor 1. Both bypass Python's streams, so
they are silenced at the descriptor: otherwise the banner would precede, on the same line, the
one-line errors of the commands and the node.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType


@contextmanager
def silenced_descriptor(descriptor: int) -> Iterator[None]:
    """Send file descriptor ``descriptor`` (1: stdout, 2: stderr) to /dev/null for the duration."""
    stream = sys.stdout if descriptor == 1 else sys.stderr
    stream.flush()
    saved, devnull = os.dup(descriptor), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, descriptor)
        yield
    finally:
        os.dup2(saved, descriptor)
        os.close(saved)
        os.close(devnull)


def _import_pybullet() -> ModuleType:
    with silenced_descriptor(2):
        return importlib.import_module("pybullet")


pybullet = _import_pybullet()

__all__ = ["pybullet", "silenced_descriptor"]

"""Print the machine facts a failure report needs, in one short block (run with the venv's python).

Floating-point results differ in their last bits between CPUs and library builds (numpy picks its
vectorised kernels and OpenBLAS its BLAS kernels for the CPU at run time), so a report says which.
Every fact is best effort: a missing field or package prints "unknown", never an error.
"""

from __future__ import annotations

import os
import platform
from collections.abc import Callable
from importlib.metadata import version
from pathlib import Path


def cpu_model() -> str:
    """The first ``model name`` of /proc/cpuinfo (x86; other CPUs may lack it), else what platform knows."""
    try:
        lines = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        lines = []
    fields = (line.partition(":") for line in lines)
    models = [value.strip() for key, _, value in fields if key.strip() == "model name" and value.strip()]
    return models[0] if models else platform.processor() or "unknown"


def cores() -> str:
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else "?"
    return f"{os.cpu_count()} cores, {usable} usable"


def numpy_build() -> str:
    import numpy

    config = numpy.show_config(mode="dicts")
    simd = " ".join(config["SIMD Extensions"]["found"])
    blas = config["Build Dependencies"]["blas"]
    return f"{numpy.__version__} (SIMD {simd}; BLAS {blas['name']} {blas['version']})"


def fact(function: Callable[[], str]) -> str:
    try:
        return function()
    except Exception as error:  # a fact we cannot get must not stop the tests
        return f"unknown ({type(error).__name__})"


def main() -> None:
    print("--- machine ---")
    print(f"cpu:      {fact(cpu_model)}, {platform.machine()}, {fact(cores)}")
    print(f"system:   {platform.system()} {platform.release()}")
    print(f"python:   {platform.python_version()}")
    print(f"numpy:    {fact(numpy_build)}")
    print(f"pybullet: {fact(lambda: version('pybullet'))}")
    print("---------------")


if __name__ == "__main__":
    main()

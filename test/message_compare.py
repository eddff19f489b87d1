"""Comparing decoded messages across machines: floats within a stated tolerance, everything else exactly.

Two runs of the same command on two machines agree in what they decide but not always in the last
bits of their floats: numpy's vectorised kernels (``exp``, sums) and the BLAS kernels behind matrix
products are chosen for the CPU at run time and round differently. Messages made on one machine are
therefore compared with those made on another field by field: numbers within a :class:`Tolerance`,
strings, integers (stamps, counts), types and lengths exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, is_dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Tolerance:
    """Two floats a and b agree when ``math.isclose(a, b, rel_tol=rel, abs_tol=abs)`` (or both are NaN)."""

    rel: float
    abs: float

    def __str__(self) -> str:
        return f"rel {self.rel:g}, abs {self.abs:g}"


#: Floats computed from the same inputs by the same code on another CPU. The vectorised and BLAS
#: kernels differ in rounding only, by a few units in the last place (2.2e-16 relative each); 1e-9
#: leaves a million times that for the errors to add up over a computation, and is still far below
#: any change a different argument makes. ``abs`` covers values that should be zero but come out as
#: rounding residue (1e-17 here, 1e-16 there), where a relative bound means nothing.
LAST_BITS = Tolerance(rel=1e-9, abs=1e-12)


def _floats_agree(expected: float, actual: float, tolerance: Tolerance) -> bool:
    if math.isnan(expected) or math.isnan(actual):
        return math.isnan(expected) and math.isnan(actual)
    return math.isclose(expected, actual, rel_tol=tolerance.rel, abs_tol=tolerance.abs)


def _array_differences(expected: np.ndarray, actual: np.ndarray, tolerance: Tolerance, where: str) -> list[str]:
    if expected.dtype != actual.dtype or expected.shape != actual.shape:
        return [f"{where}: {expected.dtype}{list(expected.shape)} != {actual.dtype}{list(actual.shape)}"]
    if expected.dtype.kind != "f":
        return [] if np.array_equal(expected, actual) else [f"{where}: {expected.tolist()} != {actual.tolist()}"]
    return [
        found
        for index, (a, b) in enumerate(zip(expected.tolist(), actual.tolist(), strict=True))
        for found in differences(a, b, tolerance, f"{where}[{index}]")
    ]


def differences(expected: Any, actual: Any, tolerance: Tolerance = LAST_BITS, where: str = "") -> list[str]:
    """Every place where ``actual`` differs from ``expected``, one line each (none: they agree).

    Recurses through dataclasses (decoded rosbags messages are dataclasses), lists, tuples and numpy
    arrays; floats must agree within ``tolerance``, anything else (types, lengths, integers, strings,
    integer arrays) exactly. ``where`` names the place in the lines, as ``where.poses[2].position.x``.
    """
    if type(expected) is not type(actual):
        return [f"{where}: {type(expected).__name__} {expected!r} != {type(actual).__name__} {actual!r}"]
    if isinstance(expected, float):
        agree = _floats_agree(expected, actual, tolerance)
        return [] if agree else [f"{where}: {expected!r} != {actual!r} (beyond {tolerance})"]
    if isinstance(expected, np.ndarray):
        return _array_differences(expected, actual, tolerance, where)
    if isinstance(expected, list | tuple):
        if len(expected) != len(actual):
            return [f"{where}: {len(expected)} items != {len(actual)}"]
        pairs = zip(expected, actual, strict=True)
        return [found for i, (a, b) in enumerate(pairs) for found in differences(a, b, tolerance, f"{where}[{i}]")]
    if is_dataclass(expected):
        return [
            found
            for field in fields(expected)
            for found in differences(
                getattr(expected, field.name), getattr(actual, field.name), tolerance, f"{where}.{field.name}"
            )
        ]
    return [] if expected == actual else [f"{where}: {expected!r} != {actual!r}"]

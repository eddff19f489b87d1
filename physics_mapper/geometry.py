"""Rigid-body poses and the distances between them.

Frames follow REP-103: metres, z up, gravity along -z. Orientations are unit
quaternions in ROS order ``(x, y, z, w)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Vector3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]

IDENTITY: Quaternion = (0.0, 0.0, 0.0, 1.0)

#: A quaternion whose norm is further than this from 1 is refused, not normalised:
#: hand-typed values such as ``(0, 0, 0.707, 0.707)`` pass, a zero or garbage one does not.
QUATERNION_NORM_TOLERANCE = 0.01


@dataclass(frozen=True)
class Pose:
    """A 6-DOF pose: ``position`` in metres, ``orientation`` a unit quaternion (x, y, z, w)."""

    position: Vector3
    orientation: Quaternion = IDENTITY


#: The world origin, unrotated.
ORIGIN = Pose((0.0, 0.0, 0.0), IDENTITY)


def pose_problem(position: tuple[float, ...], orientation: tuple[float, ...]) -> str | None:
    """Say what makes a pose unusable, or return None when it is fine.

    Refused: a non-finite value, a zero quaternion, or one whose norm is further than
    :data:`QUATERNION_NORM_TOLERANCE` from 1.
    """
    if len(position) != 3 or len(orientation) != 4:
        return "a pose needs a 3-vector position and a 4-vector orientation"
    if not all(math.isfinite(v) for v in (*position, *orientation)):
        return "non-finite value (NaN or Inf) in pose"
    norm = math.sqrt(sum(v * v for v in orientation))
    if norm == 0.0:
        return "zero quaternion"
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        return f"quaternion norm {norm:.4g} is not 1 (tolerance {QUATERNION_NORM_TOLERANCE})"
    return None


def make_pose(position: tuple[float, ...], orientation: tuple[float, ...] = IDENTITY) -> Pose:
    """Build a :class:`Pose` with its quaternion normalised; raise ValueError if unusable."""
    problem = pose_problem(position, orientation)
    if problem is not None:
        raise ValueError(problem)
    norm = math.sqrt(sum(v * v for v in orientation))
    x, y, z, w = (float(v) / norm for v in orientation)
    px, py, pz = (float(v) for v in position)
    return Pose((px, py, pz), (x, y, z, w))


def rotation_angle(a: Quaternion, b: Quaternion) -> float:
    """Angle in radians, in [0, pi], of the rotation taking orientation ``a`` to ``b``.

    theta = 2 * acos(|<a, b>|); the absolute value makes q and -q the same rotation.
    """
    dot = abs(sum(x * y for x, y in zip(a, b, strict=True)))
    return 2.0 * math.acos(min(1.0, dot))


def translation_distance(a: Pose, b: Pose) -> float:
    """Euclidean distance in metres between the positions of two poses."""
    return math.dist(a.position, b.position)


def pose_displacement(a: Pose, b: Pose, angular_weight: float) -> float:
    """Jitter between two poses: ``|p_a - p_b|`` (m) + ``angular_weight`` (m/rad) x angle (rad)."""
    return translation_distance(a, b) + angular_weight * rotation_angle(a.orientation, b.orientation)

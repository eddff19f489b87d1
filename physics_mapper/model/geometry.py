"""Rigid-body poses, and every quaternion and angle computation of the project.

Frames follow REP-103: metres, z up, gravity along -z. Orientations are unit quaternions in
ROS order ``(x, y, z, w)``, which is also scipy's :class:`~scipy.spatial.transform.Rotation`
order; the batch maths of the simulated perception uses ``Rotation`` directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Vector3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]

IDENTITY: Quaternion = (0.0, 0.0, 0.0, 1.0)
X_AXIS: Vector3 = (1.0, 0.0, 0.0)
Y_AXIS: Vector3 = (0.0, 1.0, 0.0)
Z_AXIS: Vector3 = (0.0, 0.0, 1.0)

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


def quaternion_dot(a: Quaternion, b: Quaternion) -> float:
    """|<a, b>|, in [0, 1] for unit quaternions: 1 for the same rotation (q and -q alike)."""
    return abs(sum(x * y for x, y in zip(a, b, strict=True)))


def rotation_angle(a: Quaternion, b: Quaternion) -> float:
    """Angle in radians, in [0, pi], of the rotation taking orientation ``a`` to ``b``.

    theta = 2 * acos(|<a, b>|) (:func:`quaternion_dot`); the same angle as scipy's
    ``(Rotation.from_quat(b) * Rotation.from_quat(a).inv()).magnitude()``.
    """
    return 2.0 * math.acos(min(1.0, quaternion_dot(a, b)))


def quaternion_about_axis(axis: Vector3, angle: float) -> Quaternion:
    """Unit quaternion (x, y, z, w) of a rotation by ``angle`` radians about ``axis`` (any length > 0)."""
    direction = np.asarray(axis, dtype=float)
    from scipy.spatial.transform import Rotation  # here: scipy costs a node ~40 MB it rarely needs

    x, y, z, w = Rotation.from_rotvec(angle * direction / np.linalg.norm(direction)).as_quat()
    return (float(x) + 0.0, float(y) + 0.0, float(z) + 0.0, float(w) + 0.0)  # + 0.0: no -0.0 in outputs


def rotation_vector(orientation: Quaternion) -> Vector3:
    """The rotation vector of a unit quaternion: its axis times its angle in radians, in [0, pi]."""
    from scipy.spatial.transform import Rotation  # here: see quaternion_about_axis

    x, y, z = Rotation.from_quat(orientation).as_rotvec()
    return (float(x), float(y), float(z))


def quaternion_multiply(a: Quaternion, b: Quaternion) -> Quaternion:
    """The Hamilton product a * b (x, y, z, w): rotation ``b`` first, then ``a``."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def rotate_vector(orientation: Quaternion, vector: Vector3) -> Vector3:
    """``vector`` rotated by the unit quaternion ``orientation``: v' = v + 2w (u x v) + 2 u x (u x v)."""
    ux, uy, uz, w = orientation
    vx, vy, vz = vector
    tx, ty, tz = 2.0 * (uy * vz - uz * vy), 2.0 * (uz * vx - ux * vz), 2.0 * (ux * vy - uy * vx)
    return (
        vx + w * tx + (uy * tz - uz * ty),
        vy + w * ty + (uz * tx - ux * tz),
        vz + w * tz + (ux * ty - uy * tx),
    )


def compose_poses(a: Pose, b: Pose) -> Pose:
    """The pose ``b``, given in the frame of ``a``, expressed in the frame ``a`` is given in (a * b)."""
    x, y, z = rotate_vector(a.orientation, b.position)
    ax, ay, az = a.position
    return Pose((ax + x, ay + y, az + z), quaternion_multiply(a.orientation, b.orientation))


def inverse_pose(pose: Pose) -> Pose:
    """The pose whose composition with ``pose`` is the identity: ``compose_poses(pose, inverse_pose(pose))``."""
    x, y, z, w = pose.orientation
    conjugate = (-x, -y, -z, w)
    px, py, pz = rotate_vector(conjugate, pose.position)
    return Pose((-px, -py, -pz), conjugate)


def translation_distance(a: Pose, b: Pose) -> float:
    """Euclidean distance in metres between the positions of two poses."""
    return math.dist(a.position, b.position)


def is_same_pose(a: Pose, b: Pose, position_tolerance: float, orientation_tolerance: float) -> bool:
    """Whether two poses agree: positions within ``position_tolerance`` metres, and
    ``1 - |<q_a, q_b>|`` at most ``orientation_tolerance`` (compared without ``acos``, which
    amplifies round-off near 0: ``1 - 2^-52`` becomes an angle of 4e-8 rad)."""
    close = translation_distance(a, b) <= position_tolerance
    return close and 1.0 - quaternion_dot(a.orientation, b.orientation) <= orientation_tolerance


def pose_displacement(a: Pose, b: Pose, angular_weight: float) -> float:
    """Jitter between two poses: ``|p_a - p_b|`` (m) + ``angular_weight`` (m/rad) x angle (rad)."""
    return translation_distance(a, b) + angular_weight * rotation_angle(a.orientation, b.orientation)

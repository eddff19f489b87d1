"""Axis-aligned boxes that hold an object's body at a pose: tighter than a cube around its bounding ball.

For a body whose points p (in its own frame) lie in a set P, posed at (t, R), the world body is
t + R P, and its axis-aligned bounding box is

    [t + c - e, t + c + e],   c = R c_P,   e_k = max over p in P of |(R (p - c_P))_k|

with c_P the centre of P's own bounding box. Per shape, in metres:

- box of half-size s: c_P = 0, e = |R| s (|R| the element-wise absolute rotation matrix);
- sphere of radius r: c_P = 0, e = (r, r, r);
- cylinder of radius r and half-length l along its z axis a = R e_z: c_P = 0,
  e_k = l |a_k| + r sqrt(1 - a_k^2) (the exact box of a disc swept along the axis);
- mesh: the exact box of its collision points (surface and convex parts) rotated.

Each box lies inside the cube of half-edge r_bound (the bounding radius) around t, so volumes made of
these boxes are never larger than those made of the cubes.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.geometry import ORIGIN, Pose, Quaternion, rotate_vector
from physics_mapper.model.meshes import MeshGeometry
from physics_mapper.model.scene import Box, Cylinder, Mesh, ObjectShape, Plane, Sphere, StaticBody

FloatArray = NDArray[np.float64]


def rotation_matrix(orientation: Quaternion) -> FloatArray:
    """The 3 x 3 matrix of a unit quaternion's rotation: its columns are the rotated unit axes."""
    axes = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    return np.array([rotate_vector(orientation, axis) for axis in axes]).T


def body_box(shape: ObjectShape, pose: Pose) -> tuple[FloatArray, FloatArray]:
    """The axis-aligned box (low corner, high corner), metres, of ``shape``'s body at ``pose`` (module docstring;
    read-only arrays)."""
    if isinstance(shape, Mesh):
        low, high = rotated_bounds(shape.geometry, pose.orientation)
        position = np.asarray(pose.position, dtype=float)
        return _read_only(position + low), _read_only(position + high)
    return _primitive_box(shape, pose)


#: Primitive bodies' boxes remembered (about 200 bytes each).
PRIMITIVE_BOX_CACHE = 50_000


# Remembered: a search asks for each hypothesis's box many times (every grouping after a merge, each group's
# conflict store, the ruling-out pass, the support rule), ~8 us each: 6,400 boxes for 1,250 hypotheses in four
# bins of 50. Meshes are not keyed so (two meshes of one file compare equal): their rotated bounds are.
@functools.lru_cache(maxsize=PRIMITIVE_BOX_CACHE)
def _primitive_box(shape: Box | Sphere | Cylinder, pose: Pose) -> tuple[FloatArray, FloatArray]:
    """:func:`body_box` of a box, sphere or cylinder."""
    rotation = rotation_matrix(pose.orientation)
    position = np.asarray(pose.position, dtype=float)
    if isinstance(shape, Box):
        half = np.abs(rotation) @ (np.asarray(shape.size, dtype=float) / 2.0)
    elif isinstance(shape, Sphere):
        half = np.full(3, shape.radius)
    else:
        axis = rotation[:, 2]
        half = shape.length / 2.0 * np.abs(axis) + shape.radius * np.sqrt(np.clip(1.0 - axis**2, 0.0, 1.0))
    return _read_only(position - half), _read_only(position + half)


def _read_only(array: FloatArray) -> FloatArray:
    array.flags.writeable = False
    return array


#: Orientations of meshes whose rotated bounds are remembered (about 100 bytes each).
ROTATED_BOUNDS_CACHE = 50_000


# Remembered: a search asks for each mesh hypothesis's box many times (every grouping after a merge, each group's
# blame rule, the support rule), ~16 us each for a mesh of a few hundred points: 17 % of the time to the answer of
# eight bins of 30 meshes. Keyed by the geometry object (compared by identity): two meshes of one file may differ.
@functools.lru_cache(maxsize=ROTATED_BOUNDS_CACHE)
def rotated_bounds(geometry: MeshGeometry, orientation: Quaternion) -> tuple[FloatArray, FloatArray]:
    """The (low, high) corners, metres, of the box holding ``geometry``'s surface and parts rotated by
    ``orientation`` about the mesh frame's origin (read-only arrays)."""
    points = geometry.collision_points @ rotation_matrix(orientation).T
    return _read_only(points.min(axis=0)), _read_only(points.max(axis=0))


def shape_extents(shape: ObjectShape) -> FloatArray:
    """The extents (3, m) of ``shape``'s axis-aligned box, unrotated."""
    low, high = body_box(shape, ORIGIN)
    return np.asarray(high - low, dtype=np.float64)


def meets_box(lows: FloatArray, highs: FloatArray, low: FloatArray, high: FloatArray) -> NDArray[np.bool_]:
    """Which of the boxes (corners ``lows``, ``highs``: K x 3) meet the box (``low``, ``high``); closed boxes:
    touching meets."""
    meets: NDArray[np.bool_] = np.all((lows <= high) & (highs >= low), axis=-1)
    return meets


def meets_boxes(lows_a: FloatArray, highs_a: FloatArray, lows_b: FloatArray, highs_b: FloatArray) -> NDArray[np.bool_]:
    """K x L: whether box k of a (corners K x 3) meets box l of b (L x 3); closed boxes."""
    return meets_box(lows_a[:, None, :], highs_a[:, None, :], lows_b[None, :, :], highs_b[None, :, :])


def stable_growth(radius: float, jitter_threshold: float, angular_weight: float) -> float:
    """Metres any point of a body of bounding radius ``radius`` can move while its jitter stays within
    ``jitter_threshold``.

    J_i = |dt| + w * angle <= tau; a point at distance <= r from the origin moves at most
    |dt| + r * angle <= max(1, r / w) * tau (with w = 0 the angle is unbounded: |dt| + 2 r).
    """
    if angular_weight <= 0.0:
        return jitter_threshold + 2.0 * radius
    return max(1.0, radius / angular_weight) * jitter_threshold


def may_overlap_static(body: StaticBody, lows: FloatArray, highs: FloatArray, depth: float) -> NDArray[np.bool_]:
    """Per box [``lows[k]``, ``highs[k]``] (K x 3, metres), whether a body inside it can overlap the static
    ``body`` deeper than ``depth`` metres.

    An overlap's depth is the shortest translation that separates the two bodies, so it is at most
    what separates their boxes: the boxes' overlap along any axis, or for a plane of normal n
    through t, how far the box's lowest point along n, (c - t) . n - e . |n| (c its centre, e its
    half-size), lies below the plane. False where the overlap cannot be deeper.
    """
    if isinstance(body.shape, Plane):
        normal = rotation_matrix(body.pose.orientation)[:, 2]
        centres, halves = (lows + highs) / 2.0, (highs - lows) / 2.0
        lowest = (centres - np.asarray(body.pose.position)) @ normal - halves @ np.abs(normal)
        return np.asarray(lowest < -depth)
    low, high = body_box(body.shape, body.pose)
    return np.asarray(np.all(np.minimum(highs, high) - np.maximum(lows, low) > depth, axis=1))


def inside_static(body: StaticBody, point: FloatArray) -> bool:
    """Whether ``point`` (metres) lies inside the static ``body``: below a plane (against its normal), or
    within a box; False for the other shapes (their insides are not told apart from their boxes' here)."""
    offset = np.asarray(point, dtype=float) - np.asarray(body.pose.position, dtype=float)
    rotation = rotation_matrix(body.pose.orientation)
    if isinstance(body.shape, Plane):
        return bool(offset @ rotation[:, 2] < 0.0)
    if isinstance(body.shape, Box):
        return bool(np.all(np.abs(rotation.T @ offset) < np.asarray(body.shape.size, dtype=float) / 2.0))
    return False

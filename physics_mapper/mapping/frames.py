"""Sensor frames: a transform tree over time, looked up as tf2 does it (ROS-free).

The node feeds :class:`TransformBuffer` with every transform of ``/tf`` (dynamic) and
``/tf_static`` (static), and with the scene file's fixed ``frames:`` (static); an input whose
poses are in another frame than the scene's is moved into the scene's frame at its header stamp
(:meth:`TransformBuffer.lookup`).

The rules are tf2's (``tf2::BufferCore``):

- Each frame has one parent; a transform ``parent -> child`` is the pose of ``child`` in
  ``parent`` (``geometry_msgs/TransformStamped``: ``header.frame_id`` the parent,
  ``child_frame_id`` the child).
- The pose of frame ``source`` in frame ``target`` at stamp t is the chain of transforms from
  ``source`` up to the frames' nearest common ancestor and down to ``target``, every edge
  evaluated at t. Edges above the common ancestor are not needed.
- A static transform holds at every time. A dynamic edge is evaluated between its two samples
  around t: the translation interpolated linearly, the rotation by slerp; a sample at exactly t
  is used as it is. Before its oldest sample or after its newest, the edge has no value
  ("extrapolation"): tf2 refuses, and so does this buffer.
- Stamp 0 means "the latest": every edge at the newest time all the chain's dynamic edges
  share (tf2's ``TimePointZero``).
- Dynamic samples older than ``cache_time`` (10 s, tf2's default) before an edge's newest are
  dropped.

Where it differs from tf2: a frame whose parent changes forgets its earlier samples (tf2 keeps
both parents' histories and picks by time); at most :data:`MAX_FRAMES` frames and
:data:`MAX_SAMPLES_PER_FRAME` samples per frame are kept (a flood of frames or samples costs
bounded memory); a transform with a non-finite value, or a quaternion whose norm is off 1 by
more than the model's tolerance, is refused (tf2 normalises a bad quaternion with a warning);
and there is no waiting inside a lookup: the caller waits (:class:`TransformWait`).

Maths: a transform is (R, t), a point p in the child frame is R p + t in the parent; the chain
composes (R1, t1)(R2, t2) = (R1 R2, R1 t2 + t1); rotations are scipy's :class:`Rotation`.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from physics_mapper.mapping.inputs import ReceivedPoses
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.model.geometry import Pose, Quaternion, Vector3, pose_problem
from physics_mapper.model.limits import MAX_QUOTED_TEXT, clipped

#: Seconds of dynamic samples kept per frame before its newest (tf2's default cache time).
DEFAULT_CACHE_TIME = 10.0
#: Frames the buffer holds at most; transforms of further new frames are refused.
MAX_FRAMES = 10_000
#: Dynamic samples kept per frame at most (the newest), whatever their rate.
MAX_SAMPLES_PER_FRAME = 10_000


@dataclass(frozen=True)
class StampedTransform:
    """The pose of frame ``child`` in frame ``parent`` at ``stamp_ns`` (integer nanoseconds):
    ``translation`` in metres, ``rotation`` a unit quaternion (x, y, z, w)."""

    parent: str
    child: str
    stamp_ns: int
    translation: Vector3
    rotation: Quaternion


@dataclass(frozen=True)
class Transform:
    """A rigid transform (R, t): a point p becomes R p + t; ``rotation`` is scipy's."""

    rotation: Rotation
    translation: NDArray[np.float64]

    def __matmul__(self, other: Transform) -> Transform:
        """This transform after ``other``: (R1, t1)(R2, t2) = (R1 R2, R1 t2 + t1)."""
        return Transform(self.rotation * other.rotation, self.rotation.apply(other.translation) + self.translation)

    def inverse(self) -> Transform:
        inverse = self.rotation.inv()
        return Transform(inverse, -inverse.apply(self.translation))

    def as_pose(self) -> Pose:
        x, y, z = (float(v) for v in self.translation)
        qx, qy, qz, qw = (float(v) for v in self.rotation.as_quat())
        return Pose((x, y, z), (qx, qy, qz, qw))

    @staticmethod
    def of(
        translation: Sequence[float] | NDArray[np.float64], rotation: Sequence[float] | NDArray[np.float64]
    ) -> Transform:
        return Transform(Rotation.from_quat(rotation), np.asarray(translation, dtype=np.float64))


IDENTITY_TRANSFORM = Transform(Rotation.identity(), np.zeros(3))


@dataclass(frozen=True)
class LookupFailure:
    """Why a lookup found no transform; ``may_arrive``: a later transform could still answer it
    (an unknown or unconnected frame, a stamp newer than the newest sample), so waiting helps."""

    reason: str
    may_arrive: bool


@dataclass
class _Edge:
    """One frame's link to its parent: a static transform, or dynamic samples sorted by stamp."""

    parent: str
    static: Transform | None = None
    stamps: list[int] = field(default_factory=list)
    translations: list[NDArray[np.float64]] = field(default_factory=list)
    rotations: list[NDArray[np.float64]] = field(default_factory=list)

    def add(self, stamp_ns: int, transform: StampedTransform, cache_ns: int) -> None:
        index = bisect.bisect_left(self.stamps, stamp_ns)
        translation = np.asarray(transform.translation, dtype=np.float64)
        rotation = np.asarray(transform.rotation, dtype=np.float64)
        if index < len(self.stamps) and self.stamps[index] == stamp_ns:  # the same stamp again: replaced
            self.translations[index], self.rotations[index] = translation, rotation
        else:
            self.stamps.insert(index, stamp_ns)
            self.translations.insert(index, translation)
            self.rotations.insert(index, rotation)
        oldest = bisect.bisect_left(self.stamps, self.stamps[-1] - cache_ns)
        oldest = max(oldest, len(self.stamps) - MAX_SAMPLES_PER_FRAME)
        if oldest > 0:
            del self.stamps[:oldest], self.translations[:oldest], self.rotations[:oldest]

    def at(self, stamp_ns: int) -> Transform | str:
        """The edge's transform at ``stamp_ns`` (0: its newest), or why there is none."""
        if self.static is not None:
            return self.static
        stamps = self.stamps
        if stamp_ns == 0:
            return Transform.of(self.translations[-1], self.rotations[-1])
        if stamp_ns < stamps[0] or stamp_ns > stamps[-1]:
            return "past" if stamp_ns < stamps[0] else "future"
        index = bisect.bisect_left(stamps, stamp_ns)
        if stamps[index] == stamp_ns:
            return Transform.of(self.translations[index], self.rotations[index])
        before, after = index - 1, index
        ratio = (stamp_ns - stamps[before]) / (stamps[after] - stamps[before])
        translation = (1.0 - ratio) * self.translations[before] + ratio * self.translations[after]
        slerp = Slerp([0.0, 1.0], Rotation.from_quat([self.rotations[before], self.rotations[after]]))
        return Transform(slerp([ratio])[0], translation)


def _seconds(stamp_ns: int) -> str:
    return f"{stamp_ns / NANOSECONDS_PER_SECOND:.3f} s"


def transform_problem(transform: StampedTransform) -> str | None:
    """What makes a transform unusable (empty or equal frame names, a bad pose), or None."""
    if not transform.parent or not transform.child:
        return "a transform needs a parent frame_id and a child_frame_id"
    if transform.parent == transform.child:
        return f"frame {clipped(transform.child, MAX_QUOTED_TEXT)!r} cannot be its own parent"
    return pose_problem(tuple(transform.translation), tuple(transform.rotation))


class TransformBuffer:
    """Transforms over time, by child frame; :meth:`lookup` as tf2's ``lookupTransform``.

    Not thread-safe by itself: the node adds and looks up from one callback group.
    """

    def __init__(self, cache_time: float = DEFAULT_CACHE_TIME) -> None:
        self._cache_ns = round(cache_time * NANOSECONDS_PER_SECOND)
        self._edges: dict[str, _Edge] = {}

    @property
    def frames(self) -> set[str]:
        """Every frame named so far, parents and children."""
        return set(self._edges) | {edge.parent for edge in self._edges.values()}

    def add(self, transform: StampedTransform, *, static: bool) -> str | None:
        """Add one transform (``static``: valid at every time, as on ``/tf_static``); why it is refused, or None.

        A child whose parent changes starts over with the new parent; a transform that would close
        a loop in the tree is refused.
        """
        problem = transform_problem(transform)
        if problem is not None:
            return problem
        child, parent = transform.child, transform.parent
        edge = self._edges.get(child)
        if edge is None and len(self._edges) >= MAX_FRAMES:
            return f"more than {MAX_FRAMES} frames"
        if (edge is None or edge.parent != parent) and child in self._ancestors(parent):
            return f"{clipped(parent, MAX_QUOTED_TEXT)!r} -> {clipped(child, MAX_QUOTED_TEXT)!r} would close a loop"
        if edge is None or edge.parent != parent or static != (edge.static is not None):
            edge = self._edges[child] = _Edge(parent)
        if static:
            edge.static = Transform.of(transform.translation, transform.rotation)
        else:
            edge.add(transform.stamp_ns, transform, self._cache_ns)
        return None

    def add_all(self, transforms: Iterable[StampedTransform], *, static: bool) -> list[str]:
        """Add several; the refusals, each naming its child frame."""
        refusals = []
        for transform in transforms:
            problem = self.add(transform, static=static)
            if problem is not None:
                refusals.append(f"transform to {clipped(transform.child, MAX_QUOTED_TEXT)!r} refused: {problem}")
        return refusals

    def _ancestors(self, frame: str) -> list[str]:
        """``frame``, its parent, its parent's parent, ... up to its root."""
        chain = [frame]
        while (edge := self._edges.get(chain[-1])) is not None:
            chain.append(edge.parent)
        return chain

    def lookup(self, target: str, source: str, stamp_ns: int) -> Transform | LookupFailure:
        """The transform taking coordinates in ``source`` to ``target`` at ``stamp_ns`` (0: the latest).

        Applied to a pose in ``source``, it gives the pose in ``target`` (tf2's
        ``lookupTransform(target, source, time)``).
        """
        if source == target:
            return IDENTITY_TRANSFORM
        quoted = f"from {clipped(source, MAX_QUOTED_TEXT)!r} to {clipped(target, MAX_QUOTED_TEXT)!r}"
        known = self.frames
        for frame in (source, target):
            if frame not in known:
                unknown = clipped(frame, MAX_QUOTED_TEXT)
                return LookupFailure(f"no transform {quoted}: frame {unknown!r} is unknown", True)
        up_source, up_target = self._ancestors(source), self._ancestors(target)
        common = next((frame for frame in up_source if frame in up_target), None)
        if common is None:
            return LookupFailure(f"no transform {quoted}: the frames are not connected", True)
        source_edges = up_source[: up_source.index(common)]
        target_edges = up_target[: up_target.index(common)]
        if stamp_ns == 0:
            stamp_ns = self._latest_common(source_edges + target_edges)
        source_in_common = self._chain(source_edges, stamp_ns)
        target_in_common = self._chain(target_edges, stamp_ns)
        for chained in (source_in_common, target_in_common):
            if isinstance(chained, LookupFailure):
                reason = f"no transform {quoted} at {_seconds(stamp_ns)}: {chained.reason}"
                return LookupFailure(reason, chained.may_arrive)
        assert isinstance(source_in_common, Transform) and isinstance(target_in_common, Transform)
        return target_in_common.inverse() @ source_in_common

    def _latest_common(self, frames: Sequence[str]) -> int:
        """The newest stamp every dynamic edge of ``frames`` has (0 if all are static)."""
        newest = [self._edges[frame].stamps[-1] for frame in frames if self._edges[frame].static is None]
        return min(newest) if newest else 0

    def _chain(self, frames: Sequence[str], stamp_ns: int) -> Transform | LookupFailure:
        """The pose of ``frames[0]`` in the parent of ``frames[-1]`` (the common ancestor), or why none.

        A stamp past an edge's newest sample may still be answered (the transform is late); one
        before its oldest kept sample never will.
        """
        result = IDENTITY_TRANSFORM
        for frame in reversed(frames):
            edge = self._edges[frame]
            value = edge.at(stamp_ns)
            if isinstance(value, str):
                quoted = clipped(frame, MAX_QUOTED_TEXT)
                if value == "future":
                    newest = _seconds(edge.stamps[-1])
                    return LookupFailure(f"the newest transform to {quoted!r} is at {newest}", True)
                oldest = _seconds(edge.stamps[0])
                return LookupFailure(f"the oldest transform to {quoted!r} kept is at {oldest}", False)
            result = result @ value
        return result


def transform_poses(transform: Transform, poses: NDArray[np.float64]) -> NDArray[np.float64]:
    """Poses as (M, 7) rows (x, y, z, qx, qy, qz, qw) moved by ``transform``: p -> R p + t, q -> R q.

    Rows with a non-finite value or a bad quaternion stay as they are (the input rules drop them).
    """
    moved = np.array(poses, dtype=np.float64).reshape(-1, 7)
    norms = np.linalg.norm(moved[:, 3:], axis=1)
    usable = np.isfinite(moved).all(axis=1) & (np.abs(norms - 1.0) <= 0.01)
    if usable.any():
        rows = moved[usable]
        rows[:, :3] = transform.rotation.apply(rows[:, :3]) + transform.translation
        rows[:, 3:] = (transform.rotation * Rotation.from_quat(rows[:, 3:])).as_quat()
        moved[usable] = rows
    return moved


def moved_into(poses: ReceivedPoses, transform: Transform, frame: str) -> ReceivedPoses:
    """Poses received in a sensor frame, moved into ``frame`` by ``transform`` (the frame's refusal lifted)."""
    refusal = None if poses.count else f"empty {poses.source}"
    return replace(poses, poses=transform_poses(transform, poses.poses), frame_id=frame, refusal=refusal)


def rotate_covariance(transform: Transform, covariance: NDArray[np.float64]) -> NDArray[np.float64]:
    """A 6x6 pose covariance (x, y, z, rotation about x, y, z), or a stack of them (..., 6, 6), expressed
    in the transform's target frame.

    Both the position and the small rotation are vectors of the source frame, so both rotate
    with R: Sigma' = J Sigma J^T, J = diag(R, R). The translation does not change a covariance.
    """
    rotation = transform.rotation.as_matrix()
    jacobian = np.zeros((6, 6))
    jacobian[:3, :3] = rotation
    jacobian[3:, 3:] = rotation
    return np.asarray(jacobian @ covariance @ jacobian.T, dtype=np.float64)


Item = TypeVar("Item")


@dataclass(frozen=True)
class _Waiting(Generic[Item]):
    item: Item
    frames: frozenset[str]
    stamp_ns: int
    since: float


@dataclass(frozen=True)
class Resolved(Generic[Item]):
    """An input whose frames are resolved: each frame's transform into the target, or why there is none."""

    item: Item
    transforms: dict[str, Transform]
    unresolved: dict[str, str]


class TransformWait(Generic[Item]):
    """Inputs waiting for the transforms of their frames, each for at most ``timeout`` seconds.

    tf2's ``lookupTransform(..., timeout)`` blocks; a node's callback must not, so an input whose
    frames cannot be looked up yet (:attr:`LookupFailure.may_arrive`) waits here and is tried
    again when transforms arrive or time passes (:meth:`ready`). After ``timeout`` seconds it is
    resolved with the lookup's reasons. At most ``capacity`` inputs wait; the oldest goes first
    ("too many inputs waiting").
    """

    def __init__(self, target: str, capacity: int = 100) -> None:
        self.target = target
        self._capacity = capacity
        self._waiting: list[_Waiting[Item]] = []

    def __len__(self) -> int:
        return len(self._waiting)

    def add(self, item: Item, frames: Iterable[str], stamp_ns: int, now: float) -> None:
        self._waiting.append(_Waiting(item, frozenset(frames), stamp_ns, now))

    def ready(self, buffer: TransformBuffer, now: float, timeout: float) -> list[Resolved[Item]]:
        """The inputs whose transforms are all found, or whose wait is over, in arrival order."""
        done: list[Resolved[Item]] = []
        kept: list[_Waiting[Item]] = []
        overflow = len(self._waiting) - self._capacity
        for index, waiting in enumerate(self._waiting):
            found = {frame: buffer.lookup(self.target, frame, waiting.stamp_ns) for frame in sorted(waiting.frames)}
            transforms = {frame: t for frame, t in found.items() if isinstance(t, Transform)}
            failures = {frame: f for frame, f in found.items() if isinstance(f, LookupFailure)}
            over = now - waiting.since >= timeout
            if not failures or index < overflow or over or not all(f.may_arrive for f in failures.values()):
                why = " (too many inputs waiting for transforms)" if index < overflow else f" (waited {timeout:g} s)"
                unresolved = {frame: f.reason + (why if f.may_arrive else "") for frame, f in failures.items()}
                done.append(Resolved(waiting.item, transforms, unresolved))
            else:
                kept.append(waiting)
        self._waiting = kept
        return done

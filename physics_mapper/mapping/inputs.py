"""The node's input bookkeeping: newest hypotheses per object, weights pairing, staleness (SPEC section 4).

ROS-free. The node's callbacks hand in :class:`ReceivedPoses` and :class:`ReceivedWeights`
(built from messages by ``msg_adapters``); every tick asks :class:`InputTracker` for a
:class:`InputSnapshot`: the ranked hypotheses each object's search uses, or why there are none.
Receive times are seconds on the node's clock (``received``); header stamps are integer
nanoseconds (``stamp_ns``), kept exact because the node's outputs carry them.

Rules:

- A weights message belongs to the PoseArray of the same length received closest in time
  to it, within ``max_age``; poses are never paired with weights of another length.
- A PoseArray whose weights have not arrived yet waits up to :data:`WEIGHTS_GRACE` seconds
  while the object's weights topic is active; meanwhile the previous hypotheses stay in use.
  With no weights after that, weights are uniform (a warning), or, with ``require_weights``,
  the PoseArray is refused.
- A refused message (wrong frame, empty, no usable pose, bad weights) never replaces the
  hypotheses in use; the next usable one does. Single bad poses (NaN/Inf, not a unit quaternion,
  outside the scene's workspace) are dropped with their weights.
- Hypotheses received more than ``max_age`` seconds ago are stale and not used.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum

from physics_mapper.core.geometry import Pose, make_pose
from physics_mapper.core.hypotheses import Hypothesis, RankedHypotheses, weights_problem
from physics_mapper.core.limits import MAX_QUOTED_TEXT, clipped
from physics_mapper.core.scene import Workspace

#: Seconds a new PoseArray waits for its weights message before uniform weights are assumed.
WEIGHTS_GRACE = 0.5
#: Messages per object remembered for pairing (the newest ones).
HISTORY_LENGTH = 16

RawPose = tuple[Sequence[float], Sequence[float]]


class Level(IntEnum):
    """Severity of an object's input state, as in diagnostic_msgs/DiagnosticStatus."""

    OK = 0
    WARN = 1
    ERROR = 2


@dataclass(frozen=True)
class InputSettings:
    """The node parameters that govern inputs.

    max_age: seconds after which received hypotheses are stale.
    max_hypotheses: hypotheses kept per object (the heaviest).
    require_weights: refuse PoseArrays without a weights message instead of assuming uniform weights.
    """

    max_age: float = 10.0
    max_hypotheses: int = 100
    require_weights: bool = False


@dataclass(frozen=True, eq=False)
class ReceivedPoses:
    """One PoseArray as received (compared by identity: each message is its own event).

    ``count`` is the number of poses in the message (weights must have this length);
    ``poses`` holds the usable ones as ``(index in the message, pose)``; ``dropped`` says
    what was wrong with the others; ``refusal`` is set when the whole message is unusable.
    ``stamp_ns``: header stamp, nanoseconds; ``received``: node clock, seconds.
    """

    stamp_ns: int
    received: float
    count: int
    poses: tuple[tuple[int, Pose], ...]
    dropped: tuple[str, ...] = ()
    refusal: str | None = None


@dataclass(frozen=True, eq=False)
class ReceivedWeights:
    """One weights message as received; ``refusal`` says why its values are unusable."""

    received: float
    values: tuple[float, ...]
    refusal: str | None = None


def check_poses(
    raw_poses: Sequence[RawPose],
    *,
    frame_id: str,
    expected_frame: str,
    workspace: Workspace,
    stamp_ns: int,
    received: float,
) -> ReceivedPoses:
    """Validate a PoseArray's contents: frame, emptiness, and each pose (finite, unit quaternion, in ``workspace``).

    A frame_id quoted in the refusal is clipped to :data:`~physics_mapper.core.limits.MAX_QUOTED_TEXT` characters.
    """
    count = len(raw_poses)
    if frame_id != expected_frame:
        refusal = f"frame_id {clipped(frame_id, MAX_QUOTED_TEXT)!r} is not the scene frame {expected_frame!r}"
        return ReceivedPoses(stamp_ns, received, count, (), refusal=refusal)
    if count == 0:
        return ReceivedPoses(stamp_ns, received, 0, (), refusal="empty PoseArray")
    usable: list[tuple[int, Pose]] = []
    dropped: list[str] = []
    for index, (position, orientation) in enumerate(raw_poses):
        try:
            pose = make_pose(tuple(position), tuple(orientation))
        except ValueError as error:
            dropped.append(f"poses[{index}]: {error}")
            continue
        outside = workspace.problem(pose.position)
        if outside is None:
            usable.append((index, pose))
        else:
            dropped.append(f"poses[{index}]: {outside}")
    if not usable:
        refusal = f"no usable pose ({dropped[0]}{' ...' if len(dropped) > 1 else ''})"
        return ReceivedPoses(stamp_ns, received, count, (), tuple(dropped), refusal)
    return ReceivedPoses(stamp_ns, received, count, tuple(usable), tuple(dropped))


def check_weights(values: Sequence[float], *, received: float) -> ReceivedWeights:
    """Validate a weights message on its own (its length is checked when it is paired)."""
    values = tuple(float(v) for v in values)
    refusal = "empty weights array" if not values else weights_problem(values, len(values))
    return ReceivedWeights(received, values, refusal)


@dataclass(frozen=True)
class InUse:
    """Hypotheses an object's search uses, and where they came from."""

    hypotheses: RankedHypotheses
    poses: ReceivedPoses
    weights: ReceivedWeights | None
    notes: tuple[str, ...]  # warnings about them: uniform weights, dropped poses, kept the heaviest


@dataclass(frozen=True)
class ObjectStatus:
    """One object's input state at a tick: what the search uses (or None) and why."""

    name: str
    level: Level
    message: str
    hypotheses: RankedHypotheses | None
    stamp_ns: int | None  # header stamp of the PoseArray in use, nanoseconds
    details: tuple[tuple[str, str], ...]


@dataclass(frozen=True)
class InputSnapshot:
    """Every object's input state at one tick, in scene object order."""

    objects: tuple[ObjectStatus, ...]

    @property
    def missing(self) -> tuple[str, ...]:
        """Objects without usable hypotheses; the search waits for them."""
        return tuple(o.name for o in self.objects if o.hypotheses is None)

    @property
    def hypotheses(self) -> tuple[RankedHypotheses, ...] | None:
        """Each object's ranked hypotheses, or None while any object has none."""
        ranked = tuple(o.hypotheses for o in self.objects if o.hypotheses is not None)
        return ranked if len(ranked) == len(self.objects) else None

    @property
    def stamp_ns(self) -> int | None:
        """Newest header stamp among the PoseArrays in use (nanoseconds): the stamp of the node's outputs."""
        stamps = [o.stamp_ns for o in self.objects if o.stamp_ns is not None]
        return max(stamps) if stamps else None


def rank(poses: ReceivedPoses, weights: ReceivedWeights | None, max_hypotheses: int) -> InUse | str:
    """Combine usable poses with their weights (None: uniform) into ranked hypotheses, or say why not."""
    if weights is not None and weights.refusal is not None:
        return f"its weights message is unusable: {weights.refusal}"
    hypotheses = [Hypothesis(pose, 1.0 if weights is None else weights.values[i]) for i, pose in poses.poses]
    try:
        ranked = RankedHypotheses.from_weighted(hypotheses, keep_at_most=max_hypotheses)
    except ValueError as error:
        return f"weights of its usable poses: {error}"
    notes = []
    if weights is None:
        notes.append("no weights message: uniform weights, ranked in published order")
    if poses.dropped:
        notes.append(f"dropped {len(poses.dropped)} of {poses.count} poses: {'; '.join(poses.dropped[:3])}")
    if len(hypotheses) > len(ranked):
        notes.append(f"kept the {len(ranked)} heaviest of {len(hypotheses)} hypotheses (max_hypotheses_per_object)")
    return InUse(ranked, poses, weights, tuple(notes))


class ObjectInputs:
    """Messages received for one object and the hypotheses currently in use."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._poses: deque[ReceivedPoses] = deque(maxlen=HISTORY_LENGTH)  # refused ones too: they own weights
        self._weights: deque[ReceivedWeights] = deque(maxlen=HISTORY_LENGTH)
        self._newest_usable: ReceivedPoses | None = None
        self._in_use: InUse | None = None
        self._tried: tuple[ReceivedPoses, ReceivedWeights | None, int, bool] | None = None
        self._refusals: dict[str, tuple[float, str]] = {}  # kind -> (when, why) of the newest refusal
        self._counts = {"poses received": 0, "poses refused": 0, "weights received": 0, "weights refused": 0}

    def add_poses(self, poses: ReceivedPoses) -> None:
        self._poses.append(poses)
        self._counts["poses received"] += 1
        if poses.refusal is None:
            self._newest_usable = poses
        else:
            self._refuse("PoseArray", poses.received, poses.refusal)

    def add_weights(self, weights: ReceivedWeights) -> None:
        self._weights.append(weights)
        self._counts["weights received"] += 1
        if weights.refusal is not None:
            self._refuse("weights", weights.received, weights.refusal)

    def _refuse(self, kind: str, when: float, why: str) -> None:
        self._refusals[kind] = (when, f"{kind} refused: {why}")
        self._counts["poses refused" if kind == "PoseArray" else "weights refused"] += 1

    def _owner(self, weights: ReceivedWeights) -> ReceivedPoses | None:
        """The PoseArray of the same length received closest in time to ``weights``."""
        same_length = [p for p in self._poses if p.count == len(weights.values)]
        return min(same_length, key=lambda p: abs(p.received - weights.received), default=None)

    def paired_weights(self, poses: ReceivedPoses, max_age: float) -> ReceivedWeights | None:
        """The weights message that belongs to ``poses``, if it has arrived."""
        own = [
            w
            for w in self._weights
            if len(w.values) == poses.count and abs(w.received - poses.received) <= max_age and self._owner(w) is poses
        ]
        return min(own, key=lambda w: abs(w.received - poses.received), default=None)

    def _missing_weights(self, poses: ReceivedPoses) -> str:
        lengths = sorted({len(w.values) for w in self._weights if len(w.values) != poses.count})
        other = f" (weights received have length {', '.join(map(str, lengths))})" if lengths else ""
        return f"no weights message of length {poses.count}{other}"

    def _adopt_newest(self, now: float, settings: InputSettings) -> str | None:
        """Put the newest usable PoseArray in use if its weights allow; return why it waits, if it does."""
        poses = self._newest_usable
        if poses is None:
            return None
        weights = self.paired_weights(poses, settings.max_age)
        weights_active = any(now - w.received <= settings.max_age for w in self._weights)
        if weights is None and weights_active and now - poses.received < WEIGHTS_GRACE:
            return "newest PoseArray is waiting for its weights message"
        key = (poses, weights, settings.max_hypotheses, settings.require_weights)
        if key == self._tried:
            return None
        self._tried = key
        if weights is None and settings.require_weights:
            attempt: InUse | str = f"{self._missing_weights(poses)} and require_weights is true"
        else:
            attempt = rank(poses, weights, settings.max_hypotheses)
        if isinstance(attempt, str):
            self._refuse("PoseArray", now, attempt)
        elif weights is None and self._weights:
            self._in_use = InUse(attempt.hypotheses, poses, None, (self._missing_weights(poses), *attempt.notes))
        else:
            self._in_use = attempt
        return None

    def status(self, now: float, settings: InputSettings) -> ObjectStatus:
        """Adopt the newest usable input and report the object's state at time ``now``."""
        pending = self._adopt_newest(now, settings)
        details = [(key, str(value)) for key, value in self._counts.items()]
        refusals = sorted(self._refusals.values())
        details += [(f"last {why.split(':')[0]}", f"{now - when:.1f} s ago: {why}") for when, why in refusals]
        in_use = self._in_use
        if in_use is None:
            why = pending or "; ".join(why for _, why in refusals) or "no PoseArray received yet"
            return ObjectStatus(self.name, Level.ERROR, why, None, None, tuple(details))
        age = now - in_use.poses.received
        details += [("hypotheses in use", str(len(in_use.hypotheses))), ("age [s]", f"{age:.2f}")]
        details.append(("weights", "uniform" if in_use.weights is None else "paired"))
        if age > settings.max_age:
            message = f"stale: newest usable hypotheses are {age:.1f} s old (max_age {settings.max_age:g} s)"
            return ObjectStatus(self.name, Level.ERROR, message, None, None, tuple(details))
        notes = list(in_use.notes)
        if pending is not None:
            notes.insert(0, pending)
        else:
            recent = [why for when, why in refusals if when > in_use.poses.received]
            if recent:
                notes.insert(0, f"{'; '.join(recent)}; older hypotheses stay in use")
        level = Level.WARN if notes else Level.OK
        message = "; ".join(notes) if notes else f"{len(in_use.hypotheses)} hypotheses, weighted"
        return ObjectStatus(self.name, level, message, in_use.hypotheses, in_use.poses.stamp_ns, tuple(details))


class InputTracker:
    """Inputs of every scene object, in scene order."""

    def __init__(self, names: Sequence[str]) -> None:
        self.objects = {name: ObjectInputs(name) for name in names}

    def add_poses(self, name: str, poses: ReceivedPoses) -> None:
        self.objects[name].add_poses(poses)

    def add_weights(self, name: str, weights: ReceivedWeights) -> None:
        self.objects[name].add_weights(weights)

    def snapshot(self, now: float, settings: InputSettings) -> InputSnapshot:
        return InputSnapshot(tuple(inputs.status(now, settings) for inputs in self.objects.values()))

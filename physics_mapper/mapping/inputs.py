"""The node's input bookkeeping: newest hypotheses per object, weights pairing, staleness.

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
- A clock that jumps back (simulated time restarted: a bag played again, a simulator reset) by
  more than :data:`CLOCK_JUMP_TOLERANCE` does not make ages negative: the tracker keeps its own
  timeline, the node's clock plus every backward jump seen so far, so ages go on from where they
  were and hypotheses go stale ``max_age`` after they arrived, as without the jump; the jump is
  named in every object's details.
- Messages the middleware reports lost are counted per object and kind, and named in the
  object's status while the last loss is more recent than ``max_age``.

Cost: a PoseArray is kept as received, one (M, 7) array (:data:`PoseBlock`); its poses are
checked and converted when it is adopted, heaviest first, until ``max_hypotheses`` usable ones
are found, so adopting an array of 10,000 poses costs what adopting its 100 heaviest does.
The tracker is thread-safe: subscriptions may add messages while a tick takes a snapshot.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from enum import IntEnum
from typing import Generic, Literal, TypeVar

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.geometry import make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, weights_problem
from physics_mapper.model.limits import MAX_QUOTED_TEXT, MAX_SEARCHED_HYPOTHESES, clipped
from physics_mapper.model.scene import Workspace

#: Seconds a new PoseArray waits for its weights message before uniform weights are assumed.
WEIGHTS_GRACE = 0.5
#: Messages per object remembered for pairing (the newest ones), of each kind.
HISTORY_LENGTH = 16
#: Bytes of the messages remembered per object, of each kind (a pose takes 56, a weight 8): beyond them
#: the oldest are forgotten, but the newest message is kept however large. 128 objects remember at most
#: 1 GiB beside their newest messages; 16 arrays of 100,000 poses and of 1M weights held 208 MiB for one
#: object without this cap, 13 MiB with it (``BENCHMARKS.md``, "Hostile inputs").
HISTORY_BYTES = 4 * 1024 * 1024
#: Backward clock jumps remembered (the newest; all are counted).
JUMPS_REMEMBERED = 16

Message = TypeVar("Message")
RawPose = tuple[Sequence[float], Sequence[float]]
#: Poses as received, one row each: position x, y, z (m), orientation quaternion x, y, z, w; unchecked.
PoseBlock = NDArray[np.float64]
#: Columns of a :data:`PoseBlock`.
POSE_COLUMNS = 7
#: An object's two input topics: its PoseArrays and its weights.
MessageKind = Literal["poses", "weights"]
MESSAGE_KINDS: tuple[MessageKind, ...] = ("poses", "weights")


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

    ``poses`` holds every pose of the message, unchecked (:func:`rank` checks those it keeps,
    against ``workspace``, the scene's); ``count`` is their number (weights must have this
    length); ``refusal`` is set when the whole message is unusable. ``stamp_ns``: header stamp,
    nanoseconds; ``received``: node clock, seconds. ``frame_assumed``: the message named no frame
    (an empty frame_id) and was taken in the scene's. ``weights``: weights that came in the same
    message (a detection's scores), which no separate weights message then pairs with. ``source``
    names the message in refusals: ``PoseArray``, or ``detection`` for a Detection3D's results.
    ``frame_id``: the frame the message named (a sensor frame is moved into the scene's by
    :func:`~physics_mapper.mapping.frames.moved_into`).
    """

    stamp_ns: int
    received: float
    poses: PoseBlock
    workspace: Workspace
    refusal: str | None = None
    frame_assumed: bool = False
    weights: ReceivedWeights | None = None
    source: str = "PoseArray"
    frame_id: str = ""

    @property
    def count(self) -> int:
        return len(self.poses)

    def with_weights(self, weights: ReceivedWeights) -> ReceivedPoses:
        """These poses with the weights of their own message."""
        return replace(self, weights=weights)


@dataclass(frozen=True, eq=False)
class ReceivedWeights:
    """One weights message as received; ``refusal`` says why its values are unusable."""

    received: float
    values: NDArray[np.float64]
    refusal: str | None = None


def pose_block(raw_poses: Sequence[RawPose] | PoseBlock) -> PoseBlock:
    """Poses as ``(position, orientation)`` pairs, or already an (M, 7) array, as one (M, 7) float array.

    A pair whose parts are not 3 and 4 numbers long gives a row of NaN, which :func:`rank` drops.
    """
    if isinstance(raw_poses, np.ndarray):
        return np.asarray(raw_poses, dtype=np.float64).reshape(-1, POSE_COLUMNS)
    block = np.full((len(raw_poses), POSE_COLUMNS), np.nan)
    for row, (position, orientation) in zip(block, raw_poses, strict=True):
        if len(position) == 3 and len(orientation) == 4:
            row[:] = (*position, *orientation)
    return block


def check_poses(
    raw_poses: Sequence[RawPose] | PoseBlock,
    *,
    frame_id: str,
    expected_frame: str,
    workspace: Workspace,
    stamp_ns: int,
    received: float,
    source: str = "PoseArray",
) -> ReceivedPoses:
    """A PoseArray's contents as received, refused as a whole for another frame or no pose at all.

    An empty frame_id (a message published without a header, as ``ros2 topic pub`` does unless told)
    is taken as the scene's frame: naming no frame is not naming another one. The poses themselves
    (finite, unit quaternion, inside ``workspace``) are checked when they
    are adopted (:func:`rank`). A frame_id quoted in the refusal is clipped to
    :data:`~physics_mapper.model.limits.MAX_QUOTED_TEXT` characters.
    """
    poses = pose_block(raw_poses)
    assumed = frame_id == ""
    received_as = ReceivedPoses(stamp_ns, received, poses, workspace, source=source, frame_id=frame_id)
    if frame_id != expected_frame and not assumed:
        refusal = f"frame_id {clipped(frame_id, MAX_QUOTED_TEXT)!r} is not the scene frame {expected_frame!r}"
        return replace(received_as, refusal=refusal)
    if len(poses) == 0:
        return replace(received_as, refusal=f"empty {source}", frame_assumed=assumed)
    return replace(received_as, frame_assumed=assumed)


def check_weights(values: Sequence[float] | NDArray[np.float64], *, received: float) -> ReceivedWeights:
    """Validate a weights message on its own (its length is checked when it is paired)."""
    array = np.array(values, dtype=np.float64)
    array.flags.writeable = False
    refusal = "empty weights array" if len(array) == 0 else weights_problem(array, len(array))
    return ReceivedWeights(received, array, refusal)


@dataclass(frozen=True)
class InUse:
    """Hypotheses an object's search uses, and where they came from.

    ``dropped`` names every pose examined and dropped, ``poses[i]: why``, heaviest first.
    """

    hypotheses: RankedHypotheses
    poses: ReceivedPoses
    weights: ReceivedWeights | None
    notes: tuple[str, ...]  # warnings about them: uniform weights, dropped poses, kept the heaviest
    dropped: tuple[str, ...] = ()


@dataclass(frozen=True)
class ObjectStatus:
    """One object's input state at a tick: what the search uses (or None) and why.

    ``notes``: the warnings about the hypotheses in use, each a fixed text (uniform weights,
    dropped poses, kept the heaviest), which the node logs once each.
    """

    name: str
    level: Level
    message: str
    hypotheses: RankedHypotheses | None
    stamp_ns: int | None  # header stamp of the PoseArray in use, nanoseconds
    details: tuple[tuple[str, str], ...]
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class InputSnapshot:
    """Every object's input state at one tick, in scene object order."""

    objects: tuple[ObjectStatus, ...]

    @property
    def names(self) -> tuple[str, ...]:
        """Every object's name, in scene object order."""
        return tuple(o.name for o in self.objects)

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


def _heaviest_first(poses: ReceivedPoses, weights: ReceivedWeights | None) -> NDArray[np.intp]:
    """Indices of the poses by decreasing weight; equal weights (and uniform ones) keep the published order."""
    if weights is None:
        return np.arange(poses.count)
    return np.argsort(-weights.values, kind="stable")


def rank(poses: ReceivedPoses, weights: ReceivedWeights | None, max_hypotheses: int) -> InUse | str:
    """The ``max_hypotheses`` heaviest usable poses with their weights (None: uniform), ranked, or why not.

    Poses are checked and converted heaviest first until enough usable ones are found: the cost
    grows with ``max_hypotheses``, not with the size of the message. An unusable pose (non-finite,
    zero or non-unit quaternion, outside the workspace) is dropped with its weight, and named.
    """
    if weights is not None and weights.refusal is not None:
        return f"its weights message is unusable: {weights.refusal}"
    requested = max_hypotheses
    max_hypotheses = min(max_hypotheses, MAX_SEARCHED_HYPOTHESES)
    kept: list[Hypothesis] = []
    dropped: list[str] = []
    examined = 0
    for index in _heaviest_first(poses, weights):
        if len(kept) == max_hypotheses:
            break
        examined += 1
        row = poses.poses[index]
        try:
            pose = make_pose(tuple(row[:3].tolist()), tuple(row[3:].tolist()))
        except ValueError as error:
            dropped.append(f"poses[{index}]: {error}")
            continue
        outside = poses.workspace.problem(pose.position)
        if outside is not None:
            dropped.append(f"poses[{index}]: {outside}")
            continue
        kept.append(Hypothesis(pose, 1.0 if weights is None else float(weights.values[index])))
    if not kept:
        return f"no usable pose ({dropped[0]}{' ...' if len(dropped) > 1 else ''})"
    try:
        ranked = RankedHypotheses.from_weighted(kept)
    except ValueError as error:
        return f"weights of its usable poses: {error}"
    notes = []
    if weights is None:
        notes.append("no weights message: uniform weights, ranked in published order")
    if dropped:
        of = f"{poses.count}" if examined == poses.count else f"the {examined} heaviest of {poses.count}"
        notes.append(f"dropped {len(dropped)} of {of} poses: {'; '.join(dropped[:3])}")
    if examined < poses.count:
        cap = (
            "max_hypotheses_per_object"
            if requested <= MAX_SEARCHED_HYPOTHESES
            else f"the hard cap of {MAX_SEARCHED_HYPOTHESES} per object; max_hypotheses_per_object is {requested}"
        )
        notes.append(f"kept the {len(ranked)} heaviest of {poses.count} hypotheses ({cap})")
    return InUse(ranked, poses, weights, tuple(notes), tuple(dropped))


def _poses_bytes(poses: ReceivedPoses) -> int:
    return poses.poses.nbytes + (0 if poses.weights is None else poses.weights.values.nbytes)


class History(Generic[Message]):
    """The newest messages of one kind: at most :data:`HISTORY_LENGTH` of them and :data:`HISTORY_BYTES`
    of their arrays (the newest always), oldest first."""

    def __init__(self, size: Callable[[Message], int]) -> None:
        self._messages: deque[Message] = deque()
        self._size = size
        self._bytes = 0

    def append(self, message: Message) -> None:
        self._messages.append(message)
        self._bytes += self._size(message)
        while len(self._messages) > 1 and (len(self._messages) > HISTORY_LENGTH or self._bytes > HISTORY_BYTES):
            self._bytes -= self._size(self._messages.popleft())

    @property
    def bytes(self) -> int:
        """Bytes of the arrays of the messages remembered."""
        return self._bytes

    def __iter__(self) -> Iterator[Message]:
        return iter(self._messages)

    def __len__(self) -> int:
        return len(self._messages)


class ObjectInputs:
    """Messages received for one object and the hypotheses currently in use."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._poses = History[ReceivedPoses](_poses_bytes)  # refused ones too: they own weights
        self._weights = History[ReceivedWeights](lambda w: w.values.nbytes)
        self._newest_usable: ReceivedPoses | None = None
        self._in_use: InUse | None = None
        self._tried: tuple[ReceivedPoses, ReceivedWeights | None, int, bool] | None = None
        self._refusals: dict[str, tuple[float, str]] = {}  # kind -> (when, why) of the newest refusal
        self._counts = {
            "poses received": 0,
            "poses refused": 0,
            "weights received": 0,
            "weights refused": 0,
            "poses lost": 0,
            "weights lost": 0,
        }
        self._last_lost: float | None = None  # when the middleware last reported a lost message

    @property
    def poses_received(self) -> int:
        """PoseArrays received so far, refused ones too."""
        return self._counts["poses received"]

    def add_poses(self, poses: ReceivedPoses) -> None:
        self._poses.append(poses)
        self._counts["poses received"] += 1
        if poses.refusal is None:
            self._newest_usable = poses
        else:
            self._refuse(poses.source, poses.received, poses.refusal)

    def add_weights(self, weights: ReceivedWeights) -> None:
        self._weights.append(weights)
        self._counts["weights received"] += 1
        if weights.refusal is not None:
            self._refuse("weights", weights.received, weights.refusal)

    def add_lost(self, kind: MessageKind, count: int, now: float) -> None:
        """Count ``count`` messages the middleware reports lost on the object's ``kind`` topic, at ``now``."""
        self._counts[f"{kind} lost"] += count
        self._last_lost = now

    def _lost_note(self, now: float, settings: InputSettings) -> str | None:
        """Names recent losses: newer hypotheses than those in use may have been lost."""
        if self._last_lost is None or now - self._last_lost > settings.max_age:
            return None
        lost = ", ".join(f"{self._counts[f'{kind} lost']} {kind}" for kind in MESSAGE_KINDS)
        return f"messages lost in the middleware ({lost} in total, the last {now - self._last_lost:.1f} s ago)"

    def _refuse(self, kind: str, when: float, why: str) -> None:
        self._refusals[kind] = (when, f"{kind} refused: {why}")
        self._counts["weights refused" if kind == "weights" else "poses refused"] += 1

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
        own = poses.weights
        weights = own if own is not None else self.paired_weights(poses, settings.max_age)
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
            self._refuse(poses.source, now, attempt)
        elif weights is None and self._weights:
            notes = (self._missing_weights(poses), *attempt.notes)
            self._in_use = InUse(attempt.hypotheses, poses, None, notes, attempt.dropped)
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
            why = pending or "; ".join(why for _, why in refusals)
            if not why:  # nothing received yet: waiting, not failing
                return ObjectStatus(self.name, Level.WARN, "no hypotheses received yet", None, None, tuple(details))
            return ObjectStatus(self.name, Level.ERROR, why, None, None, tuple(details))
        age = now - in_use.poses.received
        details += [("hypotheses in use", str(len(in_use.hypotheses))), ("age [s]", f"{age:.2f}")]
        details.append(("stamp [ns]", str(in_use.poses.stamp_ns)))
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
        lost = self._lost_note(now, settings)
        if lost is not None:
            notes.append(lost)
        level = Level.WARN if notes else Level.OK
        message = "; ".join(notes) if notes else f"{len(in_use.hypotheses)} hypotheses, weighted"
        return ObjectStatus(
            self.name, level, message, in_use.hypotheses, in_use.poses.stamp_ns, tuple(details), in_use.notes
        )


#: Seconds the node's clock may seem to go back without being taken as a jump: receive times are
#: estimated from the middleware's system-time stamps, so consecutive ones may disagree a little.
CLOCK_JUMP_TOLERANCE = 0.5


class InputTracker:
    """Inputs of every scene object, in scene order; safe to feed from other threads while a tick reads it.

    Times given to it are the node's clock, seconds; kept on the tracker's own timeline, which never
    goes back (module docstring).
    """

    def __init__(self, names: Sequence[str]) -> None:
        self.objects = {name: ObjectInputs(name) for name in names}
        self._lock = threading.Lock()
        self._latest = -math.inf  # the latest time seen, on the timeline
        self._offset = 0.0  # timeline - node clock: the backward jumps seen so far, seconds
        # (node clock after it, seconds back) of the newest jumps; every one counted
        self._jumps: deque[tuple[float, float]] = deque(maxlen=JUMPS_REMEMBERED)
        self._jump_count = 0
        self._several_clocks = False

    def set_several_clocks(self, several: bool) -> None:
        """Whether the node's clock has several sources (two ``/clock`` publishers): while it has, a jump
        forward (to the other source's time) is no time passed either, as a jump back never is."""
        with self._lock:
            self._several_clocks = several

    def _timeline(self, clock: float) -> float:
        """``clock`` (node clock, s) on the tracker's timeline; a backward jump moves the timeline's offset,
        and so does a forward one while the clock has several sources."""
        time = clock + self._offset
        if time < self._latest - CLOCK_JUMP_TOLERANCE:
            back = self._latest - time
            self._offset += back
            self._jumps.append((clock, back))
            self._jump_count += 1
            time = self._latest
        elif self._several_clocks and self._latest > -math.inf and time > self._latest + CLOCK_JUMP_TOLERANCE:
            self._offset -= time - self._latest
            time = self._latest
        self._latest = max(self._latest, time)
        return time

    def add_poses(self, name: str, poses: ReceivedPoses) -> None:
        with self._lock:
            self.objects[name].add_poses(replace(poses, received=self._timeline(poses.received)))

    def add_weights(self, name: str, weights: ReceivedWeights) -> None:
        with self._lock:
            self.objects[name].add_weights(replace(weights, received=self._timeline(weights.received)))

    def add_lost(self, name: str, kind: MessageKind, count: int, now: float) -> None:
        with self._lock:
            self.objects[name].add_lost(kind, count, self._timeline(now))

    def forget(self, name: str) -> None:
        """Drop everything received for object ``name`` (an instance whose track ended)."""
        with self._lock:
            self.objects[name] = ObjectInputs(name)

    @property
    def clock_jumps(self) -> tuple[tuple[float, float], ...]:
        """The newest backward jumps of the node's clock (:data:`JUMPS_REMEMBERED`): (the clock just after
        it, seconds back)."""
        with self._lock:
            return tuple(self._jumps)

    def snapshot(self, now: float, settings: InputSettings) -> InputSnapshot:
        with self._lock:
            time = self._timeline(now)
            statuses = tuple(inputs.status(time, settings) for inputs in self.objects.values())
            if self._jumps:
                clock, back = self._jumps[-1]
                jump = (("clock jumped back", f"{back:.3f} s, to {clock:.3f} s ({self._jump_count} jump(s) so far)"),)
                statuses = tuple(replace(status, details=status.details + jump) for status in statuses)
            return InputSnapshot(statuses)

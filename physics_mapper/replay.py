"""Evaluating a bag of hypotheses: the node's input snapshots, an offline search per snapshot, errors.

ROS-free. The bag's messages go through the node's own input rules (:mod:`physics_mapper.inputs`)
with the bag's receive times as the node's clock. A *snapshot* is taken at the end of every
burst of messages (messages less than :data:`BURST_GAP_NS` apart, such as one iteration of
``generate``), and in a continuous stream at least every :data:`MAX_BURST_NS` (the node's
default tick period); a snapshot whose hypotheses differ from the previous one is a new search
problem, as it would be for the node, which otherwise resumes its search.

An :class:`Outcome` pairs a snapshot with the configuration chosen for it, by the offline
search here or by a live node (read back from its recorded outputs, matched by stamp: the node
stamps its outputs with the newest input stamp used). Errors are position errors in metres
against the bag's ``/ground_truth``: per object, and in total (the sum over objects, the
paper's "total configuration error"), for C111 (every object's top hypothesis), the chosen
hypotheses and their settled poses.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from physics_mapper import topics
from physics_mapper.bags import (
    POSE_ARRAY,
    Bag,
    BagError,
    BagMessage,
    BagWriter,
    decoding,
    hypotheses_topic,
    pose_array_cdr,
    pose_array_from_cdr,
    weights_from_cdr,
    weights_topic,
)
from physics_mapper.geometry import Pose, translation_distance
from physics_mapper.hypotheses import RankedHypotheses
from physics_mapper.inputs import InputSettings, InputTracker, check_poses, check_weights
from physics_mapper.physics import PhysicsChecker
from physics_mapper.report import code_text
from physics_mapper.scene import Scene
from physics_mapper.scoring import position_errors, rank_one_poses
from physics_mapper.search import BranchAndBound, Code, SearchResult
from physics_mapper.stamps import NANOSECONDS_PER_SECOND

#: Messages closer together than this (ns) form one burst, after which the node's inputs are snapshot.
BURST_GAP_NS = 50_000_000
#: A burst is cut after this long (ns), like a node ticking at its default 2 Hz.
MAX_BURST_NS = 500_000_000
#: The node's outputs (node ``physics_mapper`` in the root namespace), as recorded.
CONFIGURATION_TOPIC = topics.recorded(topics.CONFIGURATION_TOPIC)
SETTLED_TOPIC = topics.recorded(topics.SETTLED_TOPIC)
DIAGNOSTICS_TOPIC = topics.recorded(topics.DIAGNOSTICS_TOPIC)
#: A published pose is a hypothesis whose position is this close (metres) and whose orientation q'
#: has 1 - |q . q'| at most :data:`SAME_ORIENTATION` (an angle of 2.8e-6 rad). Not a tolerance on the
#: angle: both quaternions went through make_pose, and after a CDR round trip and a second
#: normalisation |q . q'| can be 1 - 2^-52, which acos turns into an angle of 4e-8 rad.
SAME_POSITION = 1e-9
SAME_ORIENTATION = 1e-12


@dataclass(frozen=True)
class BagSnapshot:
    """The hypotheses a node would search after a burst of the bag's messages.

    ``time_ns``: bag time of the burst's last message; ``stamp_ns``: newest header stamp among
    the hypotheses used (the node's output stamp); ``ground_truth``: newest ``/ground_truth`` so far.
    """

    time_ns: int
    stamp_ns: int
    hypotheses: tuple[RankedHypotheses, ...]
    ground_truth: tuple[Pose, ...] | None


@dataclass(frozen=True)
class Outcome:
    """A snapshot and the configuration chosen for it (``code`` None: nothing was chosen or published)."""

    snapshot: BagSnapshot
    code: Code | None
    chosen: tuple[Pose, ...] | None
    settled: tuple[Pose, ...] | None


def _bursts(messages: Sequence[BagMessage]) -> Iterator[list[BagMessage]]:
    burst: list[BagMessage] = []
    for message in messages:
        if burst and (
            message.time_ns - burst[-1].time_ns >= BURST_GAP_NS or message.time_ns - burst[0].time_ns >= MAX_BURST_NS
        ):
            yield burst
            burst = []
        burst.append(message)
    if burst:
        yield burst


def _ground_truth(message: BagMessage, scene: Scene) -> tuple[Pose, ...]:
    poses = pose_array_from_cdr(message.raw).checked_poses()
    if len(poses) != len(scene.objects):
        raise BagError(f"{len(poses)} poses for {len(scene.objects)} scene objects")
    return poses


def input_topics(scene: Scene) -> tuple[str, ...]:
    """The topics a replay of ``scene`` reads from a bag: every object's hypotheses and weights, the ground truth."""
    per_object = ((hypotheses_topic(name), weights_topic(name)) for name in scene.object_names)
    return (*(topic for pair in per_object for topic in pair), topics.GROUND_TRUTH_TOPIC)


def bag_snapshots(bag: Bag, scene: Scene, settings: InputSettings | None = None) -> list[BagSnapshot]:
    """Feed the bag's hypotheses through the node's input rules; one snapshot per new set of hypotheses.

    Only the messages on :func:`input_topics` count, also for the bursts: other topics of the bag
    (a recording's camera or TF) neither decide nor cut a burst. Raises BagError, naming the bag,
    topic and time, for a message that cannot be decoded or a malformed ground truth.
    """
    settings = settings or InputSettings()
    tracker = InputTracker(scene.object_names)
    poses_of = {hypotheses_topic(name): name for name in scene.object_names}
    weights_of = {weights_topic(name): name for name in scene.object_names}
    wanted = set(input_topics(scene))
    truth: tuple[Pose, ...] | None = None
    snapshots: list[BagSnapshot] = []
    for burst in _bursts([m for m in bag.messages if m.topic in wanted]):
        for message in burst:
            received = message.time_ns / NANOSECONDS_PER_SECOND
            with decoding(bag, message):
                if message.topic in poses_of:
                    data = pose_array_from_cdr(message.raw)
                    checked = check_poses(
                        data.poses,
                        frame_id=data.frame_id,
                        expected_frame=scene.frame_id,
                        stamp_ns=data.stamp_ns,
                        received=received,
                    )
                    tracker.add_poses(poses_of[message.topic], checked)
                elif message.topic in weights_of:
                    tracker.add_weights(
                        weights_of[message.topic], check_weights(weights_from_cdr(message.raw), received=received)
                    )
                else:
                    truth = _ground_truth(message, scene)
        snapshot = tracker.snapshot(burst[-1].time_ns / NANOSECONDS_PER_SECOND, settings)
        hypotheses, stamp_ns = snapshot.hypotheses, snapshot.stamp_ns
        new = not snapshots or hypotheses != snapshots[-1].hypotheses
        if hypotheses is not None and stamp_ns is not None and new:
            snapshots.append(BagSnapshot(burst[-1].time_ns, stamp_ns, hypotheses, truth))
    return snapshots


def search_offline(
    snapshots: Sequence[BagSnapshot],
    scene: Scene,
    budget: float | None,
    progress: Callable[[int, SearchResult], None] | None = None,
) -> list[Outcome]:
    """One search per snapshot with the scene's parameters, ``budget`` seconds each (None: to the end).

    ``progress(index, result)`` is called after each search.
    """
    outcomes = []
    with PhysicsChecker(scene) as checker:
        for index, snapshot in enumerate(snapshots):
            result = BranchAndBound(checker, snapshot.hypotheses, scene.search).run(budget)
            outcomes.append(Outcome(snapshot, result.code, result.poses, result.settled_poses))
            if progress is not None:
                progress(index, result)
    return outcomes


def write_outcomes(writer: BagWriter, outcomes: Sequence[Outcome], frame_id: str) -> None:
    """Record offline results on the node's output topics, at each snapshot's bag time."""
    for outcome in outcomes:
        snapshot = outcome.snapshot
        if outcome.chosen is None or outcome.settled is None:
            continue
        chosen = pose_array_cdr(snapshot.stamp_ns, frame_id, outcome.chosen)
        writer.write(CONFIGURATION_TOPIC, POSE_ARRAY, snapshot.time_ns, chosen)
        settled = pose_array_cdr(snapshot.stamp_ns, frame_id, outcome.settled)
        writer.write(SETTLED_TOPIC, POSE_ARRAY, snapshot.time_ns, settled)


def is_same_pose(published: Pose, hypothesis: Pose) -> bool:
    """Whether a published pose is ``hypothesis``: :data:`SAME_POSITION` and :data:`SAME_ORIENTATION`."""
    dot = abs(sum(a * b for a, b in zip(published.orientation, hypothesis.orientation, strict=True)))
    return translation_distance(published, hypothesis) <= SAME_POSITION and 1.0 - dot <= SAME_ORIENTATION


def code_of(poses: Sequence[Pose], hypotheses: Sequence[RankedHypotheses]) -> Code | None:
    """The code whose hypotheses are ``poses`` (None if some pose is none of its object's hypotheses)."""
    code = []
    for pose, ranked in zip(poses, hypotheses, strict=True):
        rank = next((r for r in range(1, len(ranked) + 1) if is_same_pose(pose, ranked.pose(r))), None)
        if rank is None:
            return None
        code.append(rank)
    return tuple(code)


def _last_by_stamp(output: Bag, topic: str, count: int) -> dict[int, tuple[Pose, ...]]:
    """The last PoseArray of ``count`` poses recorded on ``topic`` for each header stamp (ns)."""
    latest: dict[int, tuple[Pose, ...]] = {}
    for message in output.on(topic):
        with decoding(output, message):
            data = pose_array_from_cdr(message.raw)
            if len(data.poses) == count:
                latest[data.stamp_ns] = data.checked_poses()
    return latest


def recorded_outcomes(snapshots: Sequence[BagSnapshot], output: Bag, scene: Scene) -> list[Outcome]:
    """What a live node chose for each snapshot: its last configuration stamped with the snapshot's stamp.

    Stamps are compared exactly (the node carries them as integer nanoseconds). A configuration
    that is not made of the snapshot's hypotheses (the node ticked halfway through a burst and
    never again before the next one) counts as no configuration.
    """
    count = len(scene.objects)
    chosen = _last_by_stamp(output, CONFIGURATION_TOPIC, count)
    settled = _last_by_stamp(output, SETTLED_TOPIC, count)
    outcomes = []
    for snapshot in snapshots:
        poses = chosen.get(snapshot.stamp_ns)
        code = None if poses is None else code_of(poses, snapshot.hypotheses)
        if code is None:
            outcomes.append(Outcome(snapshot, None, None, None))
        else:
            outcomes.append(Outcome(snapshot, code, poses, settled.get(snapshot.stamp_ns)))
    return outcomes


#: The estimates scored against ground truth: ``top``, every object's most likely hypothesis (the paper's
#: C111, no physics); ``chosen``, the configuration chosen with physics; ``settled``, its settled poses.
ESTIMATES = ("top", "chosen", "settled")


def _estimates(outcome: Outcome) -> tuple[tuple[Pose, ...] | None, ...]:
    """The poses of each of :data:`ESTIMATES` (None where nothing was chosen)."""
    return rank_one_poses(outcome.snapshot.hypotheses), outcome.chosen, outcome.settled


def _position_errors(outcome: Outcome) -> dict[str, tuple[float, ...]] | None:
    """Each estimate's per-object position error (m); None without a ground truth or a complete choice."""
    truth = outcome.snapshot.ground_truth
    estimates = _estimates(outcome)
    if truth is None or any(poses is None for poses in estimates):
        return None
    return {name: position_errors(poses or (), truth) for name, poses in zip(ESTIMATES, estimates, strict=True)}


def mean_errors(outcomes: Sequence[Outcome]) -> dict[str, tuple[float, ...]] | None:
    """Per estimate (:data:`ESTIMATES`), each object's mean position error in metres.

    Averaged over the outcomes with a ground truth and a chosen configuration; None if there is none.
    """
    scored = [errors for errors in map(_position_errors, outcomes) if errors is not None]
    if not scored:
        return None
    return {name: tuple(np.mean([e[name] for e in scored], axis=0).tolist()) for name in ESTIMATES}


def summary(outcomes: Sequence[Outcome], object_names: Sequence[str]) -> str:
    """Snapshot counts, how often C11..1 was kept, and the error table (centimetres) when there is ground truth.

    The total of a column is the sum over objects (the paper's total configuration error).
    """
    top = code_text((1,) * len(object_names))
    chosen = [o.code for o in outcomes if o.code is not None]
    kept_top = sum(1 for code in chosen if all(rank == 1 for rank in code))
    lines = [
        f"{len(outcomes)} snapshots, {len(chosen)} with a configuration: "
        f"{top} in {kept_top}, another configuration in {len(chosen) - kept_top}"
    ]
    errors = mean_errors(outcomes)
    if errors is None:
        lines.append("no error against ground truth (no /ground_truth in the bag, or no configuration)")
        return "\n".join(lines)
    width = max(len(name) for name in (*object_names, "total"))
    scored = sum(1 for o in outcomes if _position_errors(o) is not None)
    lines.append(f"mean position error against ground truth over the {scored} snapshots with a configuration [cm]:")
    labels = (top, "chosen", "settled")  # the names of ESTIMATES, for people
    lines.append(f"{'object':<{width}}" + "".join(f"{label:>10}" for label in labels))
    for index, name in enumerate(object_names):
        lines.append(f"{name:<{width}}" + "".join(f"{e[index] * 100:10.2f}" for e in errors.values()))
    lines.append(f"{'total':<{width}}" + "".join(f"{sum(e) * 100:10.2f}" for e in errors.values()))
    return "\n".join(lines)


def outcome_dict(outcome: Outcome) -> dict[str, Any]:
    """One snapshot's result as plain data: times, code, and per-object position errors (m) of each estimate."""
    snapshot = outcome.snapshot
    return {
        "time_ns": snapshot.time_ns,
        "stamp_ns": snapshot.stamp_ns,
        "code": None if outcome.code is None else list(outcome.code),
        "code_text": code_text(outcome.code),
        "errors": _position_errors(outcome),
    }

"""A bag's hypotheses as the node would see them: its input snapshots, burst by burst (ROS-free).

The bag's messages go through the node's own input rules (:mod:`physics_mapper.mapping.inputs`)
with the bag's receive times as the node's clock. A *snapshot* is taken at the end of every
burst of messages (messages less than :data:`BURST_GAP_NS` apart, such as one iteration of
``generate``), and in a continuous stream at least every :data:`MAX_BURST_NS` (the node's
default tick period); a snapshot whose hypotheses differ from the previous one is a new search
problem, as it would be for the node, which otherwise resumes its search.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import nullcontext
from dataclasses import dataclass
from typing import NamedTuple

from physics_mapper.bags.storage import (
    Bag,
    BagError,
    BagMessage,
    decoding,
    detections_from_cdr,
    pose_array_from_cdr,
    weights_from_cdr,
)
from physics_mapper.mapping.association import AssociationSettings, InstanceTracks
from physics_mapper.mapping.detections import RECORDED_DETECTIONS_TOPIC, detection_inputs
from physics_mapper.mapping.existence import (
    MapMemory,
    learn_from_result,
    searched_hypotheses,
)
from physics_mapper.mapping.inputs import InputSettings, InputTracker, check_poses, check_weights
from physics_mapper.mapping.seen_too_deep import moved_out_of_static
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.topics import GROUND_TRUTH_TOPIC, recorded_poses_topic, recorded_weights_topic
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import SearchResult

#: Messages closer together than this (ns) form one burst, after which the node's inputs are snapshot.
BURST_GAP_NS = 50_000_000
#: A burst is cut after this long (ns), like a node ticking at its default 2 Hz.
MAX_BURST_NS = 500_000_000


@dataclass(frozen=True)
class BagSnapshot:
    """The hypotheses a node would search after a burst of the bag's messages.

    ``time_ns``: bag time of the burst's last message; ``stamp_ns``: newest header stamp among
    the hypotheses used (the node's output stamp); ``stamps_ns``: the header stamp of each
    object's PoseArray in use, in scene order (what the node's diagnostics show as ``stamp [ns]``);
    ``ground_truth``: newest ``/ground_truth`` so far; ``detections``: (instance, index of the detection
    it took in the burst's last ``Detection3DArray``) for each instance the association gave one;
    ``remembered``: (object, pose) where each object the last valid map held came to rest (a node's
    :class:`~physics_mapper.mapping.existence.MapMemory`, where the bag's snapshots follow the maps chosen);
    ``remembered_refined``: whether those are a refined map's rests (no valid map yet).
    """

    time_ns: int
    stamp_ns: int
    hypotheses: tuple[RankedHypotheses, ...]
    ground_truth: tuple[Pose, ...] | None
    stamps_ns: tuple[int, ...] = ()
    detections: tuple[tuple[str, int], ...] = ()
    remembered: tuple[tuple[str, Pose], ...] = ()
    remembered_refined: bool = False


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
    """The topics a replay of ``scene`` reads from a bag: every object's hypotheses and weights, the scored
    detections (``vision_msgs/Detection3DArray``), the ground truth."""
    per_object = ((recorded_poses_topic(name), recorded_weights_topic(name)) for name in scene.object_names)
    return (*(topic for pair in per_object for topic in pair), RECORDED_DETECTIONS_TOPIC, GROUND_TRUTH_TOPIC)


def no_snapshot_reason(scene: Scene) -> str:
    """What a bag that gives no snapshot lacks: hypotheses of every object that pass the input rules."""
    return (
        "at no time does every object have usable hypotheses "
        f"(frame_id must be {scene.frame_id!r}, poses finite with unit quaternions, weights valid)"
    )


def has_instances(scene: Scene) -> bool:
    """Whether some class of the scene is associated across frames (identical instances, optional ones)."""
    return any(scene.is_instance(name) for name in scene.object_names)


class Decision(NamedTuple):
    """What was chosen for a snapshot: ``result`` (None: nothing chosen) and the ``hypotheses`` whose ranks its code
    names (:func:`~physics_mapper.mapping.previous_map.result_hypotheses`: the snapshot's, or the previous map's
    check's, with *held* poses)."""

    result: SearchResult | None
    hypotheses: tuple[RankedHypotheses, ...]


#: Told after each new snapshot's search: what was chosen for it.
Decide = Callable[["BagSnapshot"], Decision]


def bag_snapshots(
    bag: Bag,
    scene: Scene,
    settings: InputSettings | None = None,
    association: AssociationSettings | None = None,
    decide: Decide | None = None,
) -> list[BagSnapshot]:
    """Feed the bag's hypotheses through the node's input rules; one snapshot per new set of hypotheses.

    Only the messages on :func:`input_topics` count, also for the bursts: other topics of the bag
    (a recording's camera or TF) neither decide nor cut a burst. Raises BagError, naming the bag,
    topic and time, for a message that cannot be decoded or a malformed ground truth.

    In a scene without instances a snapshot needs hypotheses of every object. With instances the
    node's rules hold (:mod:`~physics_mapper.mapping.existence`): detections are associated across
    the bag's arrays (:mod:`~physics_mapper.mapping.association`, with ``association``'s settings;
    tracks unmatched for ``max_age`` end), an instance that may not be there gets its *absent*
    hypothesis, a silent object its last map pose beside *absent*, one never seen *absent* alone; and
    after each new snapshot ``decide(snapshot)`` gives the configuration chosen for it, whose map
    is remembered, whose instances may be confirmed and whose left-out tentative instances end
    (:func:`~physics_mapper.mapping.existence.learn_from_result`), as after the node's tick.
    """
    # A physics world for the instances' poses seen inside a static body: a scene of named objects needs none.
    with PhysicsChecker(scene) if has_instances(scene) else nullcontext() as checker:
        return _snapshots(bag, scene, settings or InputSettings(), InstanceTracks(scene, association), decide, checker)


def _snapshots(
    bag: Bag,
    scene: Scene,
    settings: InputSettings,
    instances: InstanceTracks,
    decide: Decide | None,
    checker: PhysicsChecker | None,
) -> list[BagSnapshot]:
    """:func:`bag_snapshots`, the instances tracked by ``instances``, their poses moved out of static bodies in
    ``checker``'s world (:mod:`~physics_mapper.mapping.seen_too_deep`; None: a scene without instances)."""
    tracker = InputTracker(scene.object_names)
    memory = MapMemory()
    poses_of = {recorded_poses_topic(name): name for name in scene.object_names}
    weights_of = {recorded_weights_topic(name): name for name in scene.object_names}
    wanted = set(input_topics(scene))
    truth: tuple[Pose, ...] | None = None
    snapshots: list[BagSnapshot] = []
    for burst in _bursts([m for m in bag.messages if m.topic in wanted]):
        taken: tuple[tuple[str, int], ...] = ()
        for message in burst:
            received = message.time_ns / NANOSECONDS_PER_SECOND
            with decoding(bag, message):
                if message.topic in poses_of:
                    data = pose_array_from_cdr(message.raw)
                    checked = check_poses(
                        data.poses,
                        frame_id=data.frame_id,
                        expected_frame=scene.frame_id,
                        workspace=scene.workspace,
                        stamp_ns=data.stamp_ns,
                        received=received,
                    )
                    tracker.add_poses(poses_of[message.topic], checked)
                elif message.topic in weights_of:
                    tracker.add_weights(
                        weights_of[message.topic], check_weights(weights_from_cdr(message.raw), received=received)
                    )
                elif message.topic == RECORDED_DETECTIONS_TOPIC:
                    detected = detection_inputs(
                        detections_from_cdr(message.raw, bag.definitions), scene, received=received, tracks=instances
                    )
                    if detected.association is not None:  # first: an instance may end and start again in one array
                        taken = tuple((name, index) for index, name in sorted(detected.association.assigned.items()))
                        for name in detected.association.ended:
                            tracker.forget(name)
                    for name, poses in detected.objects.items():
                        tracker.add_poses(name, poses)
                else:
                    truth = _ground_truth(message, scene)
        now = burst[-1].time_ns / NANOSECONDS_PER_SECOND
        for name in instances.expire(now):
            tracker.forget(name)
        snapshot = tracker.snapshot(now, settings)
        hypotheses = snapshot.hypotheses
        if checker is not None and (len(snapshot.missing) < len(scene.objects) or memory.poses):
            hypotheses = searched_hypotheses(snapshot, memory, instances, now, settings.max_age)
            hypotheses, _ = moved_out_of_static(checker, hypotheses, scene.search.penetration_threshold)
        new = not snapshots or hypotheses != snapshots[-1].hypotheses
        if hypotheses is None or snapshot.stamp_ns is None or not new:
            continue
        stamps = tuple(o.stamp_ns for o in snapshot.objects if o.stamp_ns is not None)
        remembered = tuple(memory.settled.items())
        snapshots.append(
            BagSnapshot(
                burst[-1].time_ns, snapshot.stamp_ns, hypotheses, truth, stamps, taken, remembered, memory.refined
            )
        )
        decision = Decision(None, hypotheses) if decide is None else decide(snapshots[-1])
        if checker is not None:  # as after the node's tick (Mapper.tick)
            names, ranked = scene.object_names, decision.hypotheses
            for name in learn_from_result(memory, instances, names, ranked, decision.result, now):
                tracker.forget(name)
    return snapshots

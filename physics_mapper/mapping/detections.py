"""Scored detections (``vision_msgs/Detection3DArray``) as the node's per-object inputs (ROS-free).

A pose estimator (FoundationPose, CosyPose, DOPE) publishes one ``Detection3DArray`` per frame:
each ``Detection3D`` holds ``results``, each an ``ObjectHypothesisWithPose`` with a ``class_id``,
a ``score`` and a pose. The rules that make them hypotheses:

- A result's class id names the scene objects it may be (:meth:`Scene.objects_of_class`): by
  default the object of that name, or those the scene's ``class_map:`` gives the estimator's id.
- A class of one object: every result of that class, in every detection of the array, is one of
  the object's hypotheses, its score the weight (normalised as any weights).
- A class of several objects (instances, e.g. two mugs): the k-th detection holding results of
  that class is the k-th object's, in ``class_map`` order; detections beyond them are counted,
  not used. Estimators do not keep an order across frames, so give instances a class id each
  where the estimator can (a tracker's id mapped by ``class_map``).
- Poses are in the detection's header frame, or the array's if the detection names none; the
  scene's frame is required, as for PoseArrays. An object absent from an array keeps the
  hypotheses it has (until they are older than ``max_age``).

Messages are read by attribute, so rclpy's messages and those rosbags decodes from a bag give the
same inputs (:func:`detection_inputs`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from physics_mapper.mapping.inputs import RawPose, ReceivedPoses, check_poses, check_weights
from physics_mapper.mapping.stamps import to_nanoseconds
from physics_mapper.model.scene import Scene

#: The node's input topic of scored detections, relative to its namespace.
DETECTIONS_TOPIC = "detections"
#: How a bag records it for a node in the root namespace.
RECORDED_DETECTIONS_TOPIC = "/" + DETECTIONS_TOPIC
DETECTION_ARRAY = "vision_msgs/msg/Detection3DArray"


@dataclass(frozen=True)
class DetectionInputs:
    """What one Detection3DArray gave: each named object's poses with their scores as weights (in
    object order), and what was not used (unknown class ids, detections beyond a class's instances)."""

    objects: dict[str, ReceivedPoses] = field(default_factory=dict)
    unused: tuple[str, ...] = ()


def _raw_pose(pose: Any) -> RawPose:
    p, q = pose.position, pose.orientation
    return (float(p.x), float(p.y), float(p.z)), (float(q.x), float(q.y), float(q.z), float(q.w))


@dataclass
class _Collected:
    frames: set[str] = field(default_factory=set)
    poses: list[RawPose] = field(default_factory=list)
    scores: list[float] = field(default_factory=list)


def _collect(message: Any, scene: Scene) -> tuple[dict[str, _Collected], list[str]]:
    """Each object's results, by the rules of the module docstring; and notes on what was left out."""
    collected: dict[str, _Collected] = {}
    seen: dict[str, int] = {}  # class id -> detections of it so far
    unknown: set[str] = set()
    beyond: dict[str, int] = {}
    array_frame = str(message.header.frame_id)
    for detection in message.detections:
        frame = str(detection.header.frame_id) or array_frame
        classes: dict[str, list[Any]] = {}
        for result in detection.results:
            classes.setdefault(str(result.hypothesis.class_id), []).append(result)
        for class_id, results in classes.items():
            objects = scene.objects_of_class(class_id)
            if not objects:
                unknown.add(class_id)
                continue
            instance = seen.get(class_id, 0) if len(objects) > 1 else 0
            seen[class_id] = seen.get(class_id, 0) + 1
            if instance >= len(objects):
                beyond[class_id] = beyond.get(class_id, 0) + 1
                continue
            target = collected.setdefault(objects[instance], _Collected())
            target.frames.add(frame)
            target.poses += [_raw_pose(result.pose.pose) for result in results]
            target.scores += [float(result.hypothesis.score) for result in results]
    notes = [f"class id {class_id!r} is no object of the scene" for class_id in sorted(unknown)]
    notes += [f"{count} detection(s) of class {c!r} beyond its instances" for c, count in sorted(beyond.items())]
    return collected, notes


def detection_inputs(message: Any, scene: Scene, *, received: float) -> DetectionInputs:
    """A ``Detection3DArray`` (rclpy's or rosbags') received at ``received`` seconds, as per-object inputs."""
    collected, notes = _collect(message, scene)
    stamp = message.header.stamp
    stamp_ns = to_nanoseconds(stamp.sec, stamp.nanosec)
    objects: dict[str, ReceivedPoses] = {}
    for name in scene.object_names:
        found = collected.get(name)
        if found is None:
            continue
        frame = next(iter(found.frames)) if len(found.frames) == 1 else _several(found.frames)
        poses = check_poses(
            found.poses,
            frame_id=frame,
            expected_frame=scene.frame_id,
            workspace=scene.workspace,
            stamp_ns=stamp_ns,
            received=received,
        )
        objects[name] = poses.with_weights(check_weights(found.scores, received=received))
    return DetectionInputs(objects, tuple(notes))


def _several(frames: Sequence[str] | set[str]) -> str:
    """The frame_id a refusal quotes when one object's detections name several frames."""
    return " and ".join(sorted(frames))

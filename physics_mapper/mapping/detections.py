"""Scored detections (``vision_msgs/Detection3DArray``) as the node's per-object inputs (ROS-free).

A pose estimator (FoundationPose, CosyPose, DOPE) publishes one ``Detection3DArray`` per frame:
each ``Detection3D`` holds ``results``, each an ``ObjectHypothesisWithPose`` with a ``class_id``,
a ``score`` and a pose. The rules that make them hypotheses:

- **One detection is one object.** Results of several classes in one ``Detection3D`` are one
  object seen: the class of the best-scored result wins (the first of equal ones), and the other
  classes' results are left out with a note. A result with a non-finite or negative score, or an
  unknown class id, is refused alone (a note) and the rest of its detection is used.
- A class id names the scene objects it may be (:meth:`Scene.objects_of_class`): by default the
  object of that name (or the instances of the ``count:`` entry of that name), or those the
  scene's ``class_map:`` gives the estimator's id.
- **A class of one named object**: every result of that class, in every detection of the array,
  is one of the object's hypotheses, its score the weight (normalised as any weights).
- **A tracked class** (:meth:`Scene.is_tracked`: several instances, or ``count: {max: K}``):
  each detection goes to one instance by the rules of :mod:`~physics_mapper.mapping.association`
  (ids, gated distance to each instance's filtered position, optimal assignment), never by its
  place in the array; its results are that instance's hypotheses.
- **Frames.** Poses are in the detection's header frame, or the array's if the detection names
  none (:func:`detection_frames`). A frame other than the scene's is moved into the scene's frame
  by the transform the caller looked up at the array's stamp (``transforms``, see
  :mod:`~physics_mapper.mapping.frames`), covariances rotating with their poses; a frame with no
  transform refuses its detections, with the lookup's reason where there is one
  (``unresolved``). An object absent from an array keeps the hypotheses it has (until they are
  older than ``max_age``).
- **Covariance.** Each result's ``PoseWithCovariance`` covariance weights it and supplies
  alternatives (:func:`~physics_mapper.mapping.covariance.expand`): its score times the
  covariance's weight, and up to 24 poses along the covariance's principal axes. A zero
  covariance leaves the result as it is; an unusable one is noted and left out of the weight.

Messages are read by attribute, so rclpy's messages and those rosbags decodes from a bag give the
same inputs (:func:`detection_inputs`). Each result's numbers are read once into one array per
detection; the checks then run on arrays.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from physics_mapper.mapping.association import FrameAssociation, InstanceTracks, Observation
from physics_mapper.mapping.covariance import covariance_matrices, covariance_problem, expand, is_absent
from physics_mapper.mapping.frames import Transform, rotate_covariance, transform_poses
from physics_mapper.mapping.inputs import POSE_COLUMNS, PoseBlock, ReceivedPoses, check_poses, check_weights
from physics_mapper.mapping.stamps import to_nanoseconds
from physics_mapper.model.limits import MAX_QUOTED_TEXT, clipped
from physics_mapper.model.scene import Scene

#: The node's input topic of scored detections, relative to its namespace.
DETECTIONS_TOPIC = "detections"
#: How a bag records it for a node in the root namespace.
RECORDED_DETECTIONS_TOPIC = "/" + DETECTIONS_TOPIC
DETECTION_ARRAY = "vision_msgs/msg/Detection3DArray"


@dataclass(frozen=True)
class DetectionInputs:
    """What one Detection3DArray gave: each object's poses with their scores as weights (in object
    order), notes on what was not used (unknown class ids, refused results and detections,
    detections outside every gate), and what the association did (None: no tracked class)."""

    objects: dict[str, ReceivedPoses] = field(default_factory=dict)
    unused: tuple[str, ...] = ()
    association: FrameAssociation | None = None


@dataclass(frozen=True)
class _Detection:
    """One Detection3D's usable results, all of the class that scored best."""

    index: int
    class_id: str
    frame: str
    key: str
    poses: PoseBlock  # (M, 7)
    scores: NDArray[np.float64]
    covariances: NDArray[np.float64]  # (M, 6, 6), in ``frame``

    def moved(self, transform: Transform, frame: str) -> _Detection:
        """This detection in ``frame``, the target of ``transform``: poses moved, covariances rotated."""
        covariances = np.array([rotate_covariance(transform, c) for c in self.covariances]).reshape(-1, 6, 6)
        return replace(self, frame=frame, poses=transform_poses(transform, self.poses), covariances=covariances)

    def expanded(self, notes: list[str]) -> _Detection:
        """Each result's covariance as its weight and alternatives (:func:`expand`), bad ones noted."""
        if not self.covariances.any():  # no estimator's covariance: the results as they are
            return self
        poses: list[NDArray[np.float64]] = []
        scores: list[float] = []
        for position, (pose, score, covariance) in enumerate(
            zip(self.poses, self.scores.tolist(), self.covariances, strict=True)
        ):
            problem = None if is_absent(covariance) else covariance_problem(covariance)
            if problem is not None:
                notes.append(f"detection {self.index}: result {position}: {problem}, not used")
            for alternative, weight in expand(pose, covariance, score):
                poses.append(alternative)
                scores.append(weight)
        return replace(
            self,
            poses=np.array(poses, dtype=np.float64).reshape(-1, POSE_COLUMNS),
            scores=np.array(scores, dtype=np.float64),
            covariances=np.zeros((len(poses), 6, 6)),
        )


def _read(
    detection: Any, index: int, array_frame: str, scene: Scene, notes: list[str], unknown: set[str]
) -> _Detection | None:
    """A detection's results as arrays, one class kept (module docstring), or None if none is usable;
    class ids of no scene object are added to ``unknown``."""
    results = list(detection.results)
    classes = [str(result.hypothesis.class_id) for result in results]
    scores = np.fromiter((float(result.hypothesis.score) for result in results), np.float64, len(results))
    usable = np.isfinite(scores) & (scores >= 0.0)
    for position in np.flatnonzero(~usable).tolist():
        notes.append(f"detection {index}: result {position} refused: score {scores[position]:g}")
    known_classes = {c: bool(scene.objects_of_class(c)) for c in set(classes)}
    unknown.update(c for c, known in known_classes.items() if not known)
    usable &= np.fromiter((known_classes[c] for c in classes), bool, len(classes))
    if not usable.any():
        if not results:
            notes.append(f"detection {index} refused: no results")
        return None
    best = int(np.flatnonzero(usable)[np.argmax(scores[usable])])
    chosen = classes[best]
    kept = usable & np.array([c == chosen for c in classes], dtype=bool)
    others = sorted({c for c, use in zip(classes, usable.tolist(), strict=True) if use and c != chosen})
    if others:
        left = ", ".join(repr(c) for c in others)
        notes.append(
            f"detection {index}: results of class {left} left out (one detection is one object; {chosen!r} scored best)"
        )
    positions = np.flatnonzero(kept).tolist()
    poses = np.array([_pose_row(results[p].pose.pose) for p in positions], dtype=np.float64).reshape(-1, POSE_COLUMNS)
    covariances = covariance_matrices([results[p].pose.covariance for p in positions])
    frame = str(detection.header.frame_id) or array_frame
    return _Detection(index, chosen, frame, str(detection.id), poses, scores[kept], covariances)


def detection_frames(message: Any) -> set[str]:
    """The frames a ``Detection3DArray``'s poses are in: each detection's, or the array's where it names none."""
    array_frame = str(message.header.frame_id)
    return {str(detection.header.frame_id) or array_frame for detection in message.detections}


def _in_scene_frame(
    detection: _Detection, scene: Scene, transforms: Mapping[str, Transform], unresolved: Mapping[str, str]
) -> tuple[_Detection, str | None]:
    """The detection in the scene's frame where a transform moves it there; or why it cannot be."""
    if detection.frame in ("", scene.frame_id):
        return detection, None
    transform = transforms.get(detection.frame)
    if transform is not None:
        return detection.moved(transform, scene.frame_id), None
    quoted = clipped(detection.frame, MAX_QUOTED_TEXT)
    return detection, unresolved.get(detection.frame, f"frame_id {quoted!r} is not the scene frame {scene.frame_id!r}")


def _pose_row(pose: Any) -> tuple[float, ...]:
    p, q = pose.position, pose.orientation
    return (p.x, p.y, p.z, q.x, q.y, q.z, q.w)


def _observation(detection: _Detection, notes: list[str], refusal: str | None) -> Observation | None:
    """A tracked class's detection (in the scene's frame) as an observation to associate, or None (a
    note) if it is refused: ``refusal`` says why its frame could not be moved into the scene's."""
    if refusal is not None:
        notes.append(f"detection {detection.index} refused: {refusal}")
        return None
    finite = np.isfinite(detection.poses).all(axis=1)
    if not finite.any():
        notes.append(f"detection {detection.index} refused: no finite pose")
        return None
    return Observation(
        detection.class_id, detection.poses[finite, :3], detection.scores[finite], detection.key, detection.index
    )


def detection_inputs(
    message: Any,
    scene: Scene,
    *,
    received: float,
    tracks: InstanceTracks | None = None,
    transforms: Mapping[str, Transform] | None = None,
    unresolved: Mapping[str, str] | None = None,
) -> DetectionInputs:
    """A ``Detection3DArray`` (rclpy's or rosbags') received at ``received`` seconds, as per-object inputs.

    ``tracks`` are the instances' tracks, kept from array to array (None: new ones, as for a first array).
    ``transforms``: for frames other than the scene's (:func:`detection_frames`), the transform into
    the scene's frame at the array's stamp; ``unresolved``: for frames without one, why.
    """
    notes: list[str] = []
    array_frame = str(message.header.frame_id)
    unknown: set[str] = set()
    read = [_read(d, index, array_frame, scene, notes, unknown) for index, d in enumerate(message.detections)]
    refusals: dict[int, str] = {}
    detections = []
    for detection in (d for d in read if d is not None):
        moved, refusal = _in_scene_frame(detection, scene, transforms or {}, unresolved or {})
        detections.append(moved.expanded(notes) if refusal is None else moved)
        if refusal is not None:
            refusals[detection.index] = refusal
    notes[:0] = [f"class id {class_id!r} is no object of the scene" for class_id in sorted(unknown)]
    stamp = message.header.stamp
    stamp_ns = to_nanoseconds(stamp.sec, stamp.nanosec)
    collected: dict[str, list[_Detection]] = {}
    tracked = [d for d in detections if scene.is_tracked(d.class_id)]
    association = None
    if tracked:
        tracks = tracks if tracks is not None else InstanceTracks(scene)
        observations = [o for o in (_observation(d, notes, refusals.get(d.index)) for d in tracked) if o is not None]
        association = tracks.associate(observations, received)
        by_index = {d.index: d for d in tracked}
        for index, instance in association.assigned.items():
            collected[instance] = [by_index[index]]
        notes += [
            f"{count} detection(s) of class {c!r} outside every gate, with no free instance"
            for c, count in sorted(association.outside.items())
        ]
        notes += [
            f"{count} second detection(s) of an instance of class {c!r}, not used"
            for c, count in sorted(association.doubles.items())
        ]
    for single in (d for d in detections if not scene.is_tracked(d.class_id)):
        collected.setdefault(scene.objects_of_class(single.class_id)[0], []).append(single)
    objects: dict[str, ReceivedPoses] = {}
    for name in scene.object_names:
        found = collected.get(name)
        if found is None:
            continue
        frames = {d.frame for d in found}
        poses = check_poses(
            np.concatenate([d.poses for d in found]),
            frame_id=next(iter(frames)) if len(frames) == 1 else _several(frames),
            expected_frame=scene.frame_id,
            workspace=scene.workspace,
            stamp_ns=stamp_ns,
            received=received,
            source="detection",
        )
        refused = [refusals[d.index] for d in found if d.index in refusals]
        if refused:  # the lookup's reason, rather than the frame's name alone
            poses = replace(poses, refusal=refused[0])
        scores = np.concatenate([d.scores for d in found])
        objects[name] = poses.with_weights(check_weights(scores, received=received))
    return DetectionInputs(objects, tuple(notes), association)


def _several(frames: Sequence[str] | set[str]) -> str:
    """The frame_id a refusal quotes when one object's detections name several frames."""
    return " and ".join(sorted(frames))

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
  place in the array; its results are that instance's hypotheses, each score weighted by the
  track's prior (where the track predicted the instance).
- **Frames.** Poses are in the detection's header frame, or the array's if the detection names
  none (:meth:`DetectionArrayData.frames`). A frame other than the scene's is moved into the scene's frame
  by the transform the caller looked up at the array's stamp (``transforms``, see
  :mod:`~physics_mapper.mapping.frames`), covariances rotating with their poses; a frame with no
  transform refuses its detections, with the lookup's reason where there is one
  (``unresolved``). An object absent from an array keeps the hypotheses it has (until they are
  older than ``max_age``).
- **Covariance.** Each result's ``PoseWithCovariance`` covariance weights it and supplies
  alternatives (:func:`~physics_mapper.mapping.covariance.expand`): its score times the
  covariance's weight, and up to 24 poses along the covariance's principal axes. A zero
  covariance leaves the result as it is; an unusable one is noted and left out of the weight.

The rules run on arrays (:class:`~physics_mapper.mapping.detection_data.DetectionArrayData`):
per detection, its results' class ids, scores, poses and covariances, read once. The node reads
them from the serialised message (:mod:`physics_mapper.msg_adapters.detection_array_cdr`), a bag
replay from rosbags' messages by attribute, with the same outcome; no rule then costs Python work
per result (but covariance's alternatives, made per result that has one).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from physics_mapper.mapping.association import FrameAssociation, InstanceTracks, Observation
from physics_mapper.mapping.covariance import covariance_problem, expand, is_absent
from physics_mapper.mapping.detection_data import DetectionArrayData, DetectionData, detection_array_data
from physics_mapper.mapping.frames import Transform, rotate_covariance, transform_poses
from physics_mapper.mapping.inputs import POSE_COLUMNS, PoseBlock, ReceivedPoses, check_poses, check_weights
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
    covariances: NDArray[np.float64] | None  # (M, 6, 6), in ``frame``; None: none given (all zero)

    def moved(self, transform: Transform, frame: str) -> _Detection:
        """This detection in ``frame``, the target of ``transform``: poses moved, covariances rotated."""
        poses = transform_poses(transform, self.poses)
        covariances = None if self.covariances is None else rotate_covariance(transform, self.covariances)
        return replace(self, frame=frame, poses=poses, covariances=covariances)

    def expanded(self, notes: list[str]) -> _Detection:
        """Each result's covariance as its weight and alternatives (:func:`expand`), bad ones noted."""
        if self.covariances is None:  # no estimator's covariance: the results as they are
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
            covariances=None,
        )


def _read(
    detection: DetectionData, index: int, array_frame: str, scene: Scene, notes: list[str], unknown: set[str]
) -> _Detection | None:
    """A detection's usable results, one class kept (module docstring), or None if none is usable;
    class ids of no scene object are added to ``unknown``."""
    scores, classes = detection.scores, detection.result_classes
    usable = np.isfinite(scores) & (scores >= 0.0)
    for position in np.flatnonzero(~usable).tolist():
        notes.append(f"detection {index}: result {position} refused: score {scores[position]:g}")
    known = np.array([bool(scene.objects_of_class(c)) for c in detection.class_ids], dtype=bool)
    unknown.update(c for c, is_known in zip(detection.class_ids, known.tolist(), strict=True) if not is_known)
    usable &= known[classes]
    if not usable.any():
        if not len(scores):
            notes.append(f"detection {index} refused: no results")
        return None
    best = int(np.argmax(np.where(usable, scores, -np.inf)))  # the first of equal best usable scores
    chosen = int(classes[best])
    kept = usable & (classes == chosen)
    left_out = classes[usable & ~kept]
    others = sorted(detection.class_ids[c] for c in np.unique(left_out).tolist()) if len(left_out) else []
    if others:
        left = ", ".join(repr(c) for c in others)
        notes.append(
            f"detection {index}: results of class {left} left out"
            f" (one detection is one object; {detection.class_ids[chosen]!r} scored best)"
        )
    frame = detection.frame_id or array_frame
    rows = slice(None) if kept.all() else kept  # all kept (as usual): the arrays themselves, not copies
    covariances = None if detection.covariances is None else detection.covariances[rows]
    return _Detection(
        index, detection.class_ids[chosen], frame, detection.key, detection.poses[rows], scores[rows], covariances
    )


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
    rows = slice(None) if finite.all() else finite
    return Observation(
        detection.class_id,
        detection.poses[rows, :3],
        detection.poses[rows, 3:],
        detection.scores[rows],
        detection.key,
        detection.index,
    )


def detection_inputs(
    message: DetectionArrayData | Any,
    scene: Scene,
    *,
    received: float,
    tracks: InstanceTracks | None = None,
    transforms: Mapping[str, Transform] | None = None,
    unresolved: Mapping[str, str] | None = None,
) -> DetectionInputs:
    """A ``Detection3DArray`` (rclpy's or rosbags') received at ``received`` seconds, as per-object inputs.

    ``tracks`` are the instances' tracks, kept from array to array (None: new ones, as for a first array).
    ``message`` may be read already (:class:`DetectionArrayData`, as the node reads it from its bytes).
    ``transforms``: for frames other than the scene's (:meth:`DetectionArrayData.frames`), the transform into
    the scene's frame at the array's stamp; ``unresolved``: for frames without one, why.
    """
    array = message if isinstance(message, DetectionArrayData) else detection_array_data(message)
    notes: list[str] = []
    unknown: set[str] = set()
    read = [_read(d, index, array.frame_id, scene, notes, unknown) for index, d in enumerate(array.detections)]
    refusals: dict[int, str] = {}
    detections = []
    for detection in (d for d in read if d is not None):
        moved, refusal = _in_scene_frame(detection, scene, transforms or {}, unresolved or {})
        detections.append(moved.expanded(notes) if refusal is None else moved)
        if refusal is not None:
            refusals[detection.index] = refusal
    notes[:0] = [f"class id {class_id!r} is no object of the scene" for class_id in sorted(unknown)]
    stamp_ns = array.stamp_ns
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
        prior = association.priors.get(name) if association is not None else None
        if prior is not None:
            scores = scores * prior.factors(poses.poses[:, :3])
        objects[name] = poses.with_weights(check_weights(scores, received=received))
    return DetectionInputs(objects, tuple(notes), association)


def _several(frames: Sequence[str] | set[str]) -> str:
    """The frame_id a refusal quotes when one object's detections name several frames."""
    return " and ".join(sorted(frames))

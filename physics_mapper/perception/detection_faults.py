"""A pose estimator's faults, simulated: per-object hypotheses turned into the detections of one frame.

``generate --format detections`` takes each object's particle-filter hypotheses of a frame
(:func:`~physics_mapper.perception.particle_filter.track`) and makes them what an estimator such as
CosyPose or FoundationPose publishes, with its faults, each drawn independently per frame from the
given :class:`numpy.random.Generator` (so a seed reproduces them):

* **Results per detection**: each detection keeps between ``results_min`` and ``results_max`` of the
  object's heaviest hypotheses (uniformly drawn), its scores the renormalised weights.
* **Confidence**: with ``confidence`` (low, high), each detection's scores are scaled so that its best
  is a confidence drawn uniformly in [low, high], as an estimator scores each result on its own (the
  ratios, so the normalised weights, stay); false positives are drawn from the same range: the
  estimator is as sure of them, and physics must tell them apart. Without, scores are the weights.
* **A wrong pose first**: with probability ``wrong_first``, a detection's first result is a wrong pose,
  its most likely hypothesis moved by ``wrong_offset`` metres in a uniformly random direction, scored
  1.05 to 1.5 times the best true result (then renormalised); the detection keeps its result count.
* **Misses**: each object is left out of the frame with probability ``miss``.
* **Double detections**: each detected object is detected a second time with probability ``double``:
  the same results moved by ``double_offset`` metres in a random horizontal direction.
* **False positives**: ``Binomial(objects, false_positive)`` detections of nothing, of a random
  object's class and true orientation. A share ``air_share`` of them floats in the air (above the
  highest true object by 2 to 4 bounding radii of its shape, over the true objects' horizontal
  extent); the rest lie inside a static body, chosen uniformly, the middle of their body's box at a box's,
  sphere's or cylinder's centre, a mesh's origin, or one half bounding radius below a plane's surface
  under the true objects (the body there, not its origin: a mesh's origin can lie at a corner of it). A
  scene without static bodies gets only false positives in the air. Their results are scattered around
  that position by ``sigma_position``.
* **Order**: unshuffled, the true detections come in scene order, each double right after its
  original, false positives last; ``shuffle`` puts them in a random order, as estimators keep none.
* **Ids** (``Detection3D.id``): ``none`` leaves them empty (CosyPose, happypose); ``stable`` gives
  each object a tracker's id on its first detection and keeps it; ``reassigned`` does the same but
  gives an object a new, never used id with probability ``id_change`` per frame and after every miss,
  as a tracker that loses a track and opens a new one. Doubles and false positives get a new id each
  time (ids with ``stable`` and ``reassigned``, never an object's). Ids are ``track_<n>``, numbered as
  first given.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from physics_mapper.model.extents import body_box
from physics_mapper.model.geometry import Pose, Quaternion, make_pose, rotate_vector
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import (
    Box,
    Cylinder,
    Mesh,
    ObjectShape,
    Plane,
    Scene,
    Sphere,
    StaticBody,
    object_radius,
)

IdMode = Literal["none", "stable", "reassigned"]
ID_MODES: tuple[IdMode, ...] = ("none", "stable", "reassigned")
#: What a simulated detection is of: a true object, its second detection, or a false positive.
DetectionKind = Literal["object", "double", "air", "static"]


@dataclass(frozen=True)
class DetectionFaults:
    """The faults and their rates (probabilities per object and frame; see the module docstring).

    Offsets and sigmas in metres. The defaults are a fault-free estimator: every object detected
    once, in scene order, its hypotheses as they are, no ids.
    """

    shuffle: bool = False
    miss: float = 0.0
    false_positive: float = 0.0
    air_share: float = 0.5
    double: float = 0.0
    double_offset: float = 0.006
    wrong_first: float = 0.0
    wrong_offset: float = 0.03
    results_min: int | None = None
    results_max: int | None = None
    confidence: tuple[float, float] | None = None
    ids: IdMode = "none"
    id_change: float = 0.1
    sigma_position: float = 0.005


def faults_problem(faults: DetectionFaults) -> str | None:
    """Say which setting is out of range, or return None."""
    for name in ("miss", "false_positive", "air_share", "double", "wrong_first", "id_change"):
        value = getattr(faults, name)
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):
            return f"{name} must be a probability in [0, 1], got {value:g}"
    for name in ("double_offset", "wrong_offset", "sigma_position"):
        value = getattr(faults, name)
        if not (math.isfinite(value) and value >= 0.0):
            return f"{name} must be a non-negative number of metres, got {value:g}"
    low, high = faults.results_min, faults.results_max
    if (low is not None and low < 1) or (high is not None and high < 1):
        return f"results per detection must be at least 1, got {low} to {high}"
    if low is not None and high is not None and low > high:
        return f"results_min ({low}) exceeds results_max ({high})"
    if faults.confidence is not None:
        bottom, top = faults.confidence
        if not (0.0 < bottom <= top <= 1.0):
            return f"confidence must be a range within (0, 1], got {bottom:g} to {top:g}"
    if faults.ids not in ID_MODES:
        return f"ids must be one of {', '.join(ID_MODES)}, got {faults.ids!r}"
    return None


@dataclass(frozen=True)
class SimulatedDetection:
    """One Detection3D of a frame: its class id, results (ranked hypotheses, scores as weights) and id;
    ``kind`` and ``source`` (the true object's index in scene order, None for a false positive) say what
    it really is, for tests and reports (the bag does not carry them)."""

    class_id: str
    hypotheses: RankedHypotheses
    id: str
    kind: DetectionKind
    source: int | None


@dataclass
class DetectionSimulator:
    """An estimator over the frames of one run: the faults, and the ids it has given (state across frames).

    ``truth``: the true poses in scene object order; ``top_m``: the hypotheses each object has per frame
    (a false positive's results are counted as an object's would be).
    """

    scene: Scene
    truth: tuple[Pose, ...]
    faults: DetectionFaults
    rng: np.random.Generator
    top_m: int
    _ids: dict[int, str] = field(default_factory=dict)
    _next_id: int = 1

    def frame(self, hypotheses: Sequence[RankedHypotheses]) -> list[SimulatedDetection]:
        """One frame's detections from every object's hypotheses (scene order), faults applied."""
        faults, rng = self.faults, self.rng
        detected: list[SimulatedDetection] = []
        for index, ranked in enumerate(hypotheses):
            if rng.random() < faults.miss:
                if faults.ids == "reassigned":
                    self._ids.pop(index, None)
                continue
            results = self._scored(self._results(ranked))
            class_id = self.scene.class_of(self.scene.objects[index].name)
            detected.append(SimulatedDetection(class_id, results, self._object_id(index), "object", index))
            if rng.random() < faults.double:
                moved = _moved(results, _horizontal(rng) * faults.double_offset)
                detected.append(SimulatedDetection(class_id, moved, self._fresh_id(), "double", index))
        for _ in range(int(rng.binomial(len(hypotheses), faults.false_positive))):
            detected.append(self._false_positive())
        if faults.shuffle:
            detected = [detected[i] for i in rng.permutation(len(detected))]
        return detected

    def _results(self, ranked: RankedHypotheses) -> RankedHypotheses:
        """The detection's results: ``results_min`` to ``results_max`` of the heaviest, maybe a wrong pose first."""
        faults, rng = self.faults, self.rng
        count = self._result_count(len(ranked))
        kept = ranked.heaviest(count)
        if rng.random() >= faults.wrong_first:
            return kept
        direction = _unit_vector(rng)
        wrong_pose = _shifted(kept.pose(1), direction * faults.wrong_offset)
        wrong = Hypothesis(wrong_pose, kept.weight(1) * float(rng.uniform(1.05, 1.5)))
        return RankedHypotheses.from_weighted([wrong, *kept.hypotheses[: count - 1]])

    def _scored(self, ranked: RankedHypotheses) -> RankedHypotheses:
        """Scores scaled so that the best is a confidence in ``confidence`` (unchanged without one)."""
        if self.faults.confidence is None:
            return ranked
        scale = float(self.rng.uniform(*self.faults.confidence)) / ranked.weight(1)
        return RankedHypotheses(tuple(Hypothesis(h.pose, h.weight * scale) for h in ranked.hypotheses))

    def _object_id(self, index: int) -> str:
        if self.faults.ids == "none":
            return ""
        if self.faults.ids == "reassigned" and index in self._ids and self.rng.random() < self.faults.id_change:
            del self._ids[index]
        if index not in self._ids:
            self._ids[index] = self._fresh_id()
        return self._ids[index]

    def _fresh_id(self) -> str:
        if self.faults.ids == "none":
            return ""
        given = f"track_{self._next_id}"
        self._next_id += 1
        return given

    def _false_positive(self) -> SimulatedDetection:
        """A detection of nothing, in the air or inside a static body (see the module docstring)."""
        rng, scene = self.rng, self.scene
        like = int(rng.integers(len(scene.objects)))
        radius = object_radius(scene.objects[like].shape)
        in_air = not scene.static or rng.random() < self.faults.air_share
        low, high = self._truth_extent()
        orientation = self.truth[like].orientation
        if in_air:
            centre = np.array([*rng.uniform(low[:2], high[:2]), high[2] + radius * rng.uniform(2.0, 4.0)])
        else:
            body = scene.static[int(rng.integers(len(scene.static)))]
            inside = _inside(body, rng.uniform(low[:2], high[:2]), radius)
            centre = _body_at(scene.objects[like].shape, inside, orientation)
        count = self._result_count(self.top_m)
        poses = [
            make_pose(tuple(centre + rng.normal(0.0, self.faults.sigma_position, 3)), orientation) for _ in range(count)
        ]
        scores = rng.uniform(0.5, 1.0, count)
        hypotheses = self._scored(
            RankedHypotheses.from_weighted([Hypothesis(p, float(s)) for p, s in zip(poses, scores, strict=True)])
        )
        class_id = scene.class_of(scene.objects[like].name)
        return SimulatedDetection(class_id, hypotheses, self._fresh_id(), "air" if in_air else "static", None)

    def _result_count(self, available: int) -> int:
        """Uniformly ``results_min`` to ``results_max`` (each at most ``available``; unset: ``available``)."""
        high = min(self.faults.results_max or available, available)
        low = min(self.faults.results_min or available, high)
        return int(self.rng.integers(low, high + 1))

    def _truth_extent(self) -> tuple[np.ndarray, np.ndarray]:
        """The smallest axis-aligned box (m) holding the true objects' positions."""
        positions = np.array([pose.position for pose in self.truth])
        return positions.min(axis=0), positions.max(axis=0)


def _unit_vector(rng: np.random.Generator) -> np.ndarray:
    """A direction drawn uniformly on the unit sphere."""
    vector = rng.normal(0.0, 1.0, 3)
    norm = float(np.linalg.norm(vector))
    return vector / norm if norm > 0.0 else np.array([1.0, 0.0, 0.0])


def _horizontal(rng: np.random.Generator) -> np.ndarray:
    """A direction drawn uniformly in the horizontal plane."""
    angle = float(rng.uniform(0.0, 2.0 * math.pi))
    return np.array([math.cos(angle), math.sin(angle), 0.0])


def _shifted(pose: Pose, offset: np.ndarray) -> Pose:
    return make_pose(tuple(np.asarray(pose.position) + offset), pose.orientation)


def _moved(ranked: RankedHypotheses, offset: np.ndarray) -> RankedHypotheses:
    """The same hypotheses and weights, every pose moved by ``offset`` metres."""
    return RankedHypotheses(tuple(Hypothesis(_shifted(h.pose, offset), h.weight) for h in ranked.hypotheses))


def _inside(body: StaticBody, below: np.ndarray, radius: float) -> np.ndarray:
    """A point inside the static body: a plane's half a ``radius`` under its surface below ``below`` (x, y),
    a bounded body's centre (a mesh's origin)."""
    shape = body.shape
    if isinstance(shape, Plane):
        origin = np.asarray(body.pose.position)
        normal = _rotated_z(body.pose)
        point = np.array([below[0], below[1], origin[2]])
        point -= normal * float(np.dot(point - origin, normal))  # onto the plane
        return point - normal * (radius / 2.0)
    if isinstance(shape, Box | Sphere | Cylinder | Mesh):
        return np.asarray(body.pose.position, dtype=float)
    raise TypeError(f"static body {body.name}: unknown shape {type(shape).__name__}")


def _body_at(shape: ObjectShape, point: np.ndarray, orientation: Quaternion) -> np.ndarray:
    """The position (m) that puts the middle of ``shape``'s box, turned by ``orientation``, at ``point``: a mesh's
    origin can lie at a corner of its body (pybullet_data's lego part), and the body, not the origin, is inside."""
    low, high = body_box(shape, Pose((float(point[0]), float(point[1]), float(point[2])), orientation))
    return np.asarray(point - ((low + high) / 2.0 - point), dtype=float)


def _rotated_z(pose: Pose) -> np.ndarray:
    """The pose's local +z axis in the scene frame (a plane's normal)."""
    return np.asarray(rotate_vector(pose.orientation, (0.0, 0.0, 1.0)))

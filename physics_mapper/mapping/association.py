"""Which detection is which instance: identical objects tracked across frames (ROS-free).

A pose estimator knows the class of each detection, not which of several identical objects it
saw, and keeps no order across frames. The rules that give each detection of a *tracked class*
(:meth:`~physics_mapper.model.scene.Scene.is_tracked`: a class of several objects, or of
``count: {max: K}`` ones) to one instance, per class and per array of detections:

- **One detection, one instance.** Each detection (an :class:`Observation`) is one observation
  of one instance, and its results are that instance's hypotheses, all of them.
- **A state per instance.** Each instance with a *track* has filterpy's ``KalmanFilter`` on its
  position p (m): a constant-position model, predict p' = p with process noise
  Q = ``process_noise`` · dt · I (m², dt the seconds since its last update), measurement
  z = p + v, R = ``measurement_noise``² · I. Orientation is not filtered: identical instances are
  told apart by where they are, and each detection's results bring their own orientations as
  hypotheses.
- **The measurement.** Of a detection's results, the one nearest the instance's predicted
  position (an estimator may rank a wrong pose first; the right one is usually among its
  results); a new track starts at the *central* result, the one nearest the median of its results'
  positions (where a wrong pose is ranked first, the detection's other results agree with each
  other, not with it). The first map that holds a new instance (a track matched once), valid or
  refined, once settled, is a second measurement: where that map rested it, within the gate
  (:meth:`InstanceTracks.first_rests`). A first estimate may lie half-way between two layers (a jenga
  block's 1.6 cm above the floor, where the estimator missed the block under the one it saw): the map
  rests the block on what holds it up, and from its first estimate alone the next array's detection of
  the block above matched it. Only the first map: a track's own measurements follow, and a later map's
  rest is no independent one (taken from every map, a refined map's misplacement stayed in three tracks).
- **The track's prior.** A matched instance's results are weighted by where its track predicted
  it: each result's score times exp(-(d_r - min_j d_j) / 2), d_r = (p_r - x)ᵀ S⁻¹ (p_r - x) the
  squared Mahalanobis distance of its position p_r from the predicted position x, S = P + R the
  prediction's covariance plus the measurement's (m²), min over the detection's results (the
  nearest keeps its score; the factors are relative, the weights normalised anyway). With the
  default noises a track seen every half second has S = 2e-4 I m² (1.4 cm): a wrong pose ranked
  first, 3 cm from where the track holds the instance, keeps a ninth of its score, so the search
  prefers the right pose where both are physically valid. A new track has no prior.
- **Ids first.** A detection with a non-empty ``Detection3D.id`` that is the key of an instance
  of its class goes to that instance, whatever the distance (a tracker upstream said so). The
  id a detection brings becomes its instance's key.
- **Then distance.** The other detections and instances are matched by
  ``scipy.optimize.linear_sum_assignment`` on the distances (m) between predicted positions and
  measurements; pairs farther apart than the class's *gate* are never matched. The gate is
  ``gate`` metres, or by default half the largest extent of the class's shape: wide enough for a
  first estimate that is still a centimetre off on a 3 cm part, and the assignment, not the gate,
  tells neighbours apart (gates of neighbours overlap). Nor, with the default gate, is a pair matched
  beyond the track's *reach*, where its filter gives a detection of its instance less than a 1 % chance
  (:data:`GATE_PROBABILITY`): sqrt(chi2_3(0.99) s) = 3.37 sqrt(s) metres, s the largest variance of
  S = P + R, 4.8 cm for a track seen every half second with the default noises. Half a jenga block's
  length (7.5 cm) reaches its neighbours and, from a block the estimator missed, a false detection in
  the floor beneath it; matched, its poses were the block's, all impossible, and the map invalid.
  Gate and reach hold for the body the detection shows, its central result, as well as for the
  measurement: a detection whose wrong pose, ranked first, lies a layer up near a missed block's
  instance (4.6 cm) while its other results agree on the block beside and below (5.6 cm) took that
  instance for a frame, whose name then stood on the lower block and went back: an identity switch
  (jenga blocks in two layers). Nor, with the default gate, is a pair matched whose bodies overlap by less
  than :data:`BODY_OVERLAP` of the shape's extent along one of its axes: the body the detection shows (the
  shape at its central result's pose) and the same body at the track's predicted position. A block lying on
  another overlaps it by nothing, and where the estimator missed the lower block in the array that first
  saw the upper one, the upper one's detection (2.8 cm off, 5 mm low on a block 3 cm thick) took the lower
  one's instance, which took a new name when seen again: an identity switch (jenga blocks and flat parts in
  two layers).
- **One body, one match.** Two detections the assignment matched whose central results, or whose
  measurements, lie within the *same-body distance* (below) of each other are one body seen twice (and so
  is one near a detection matched by its id): the one matched from farther is left out and the assignment
  made again without it (until no two are), so that detection is left for the rules below (a second
  detection). Where the estimator missed a block and saw the next one twice, the optimal assignment (each
  instance one detection) gave the second detection to the missed block's instance, which then stood in
  its neighbour's place; and a second detection whose wrong pose (3 cm off, ranked first) lay nearer a
  neighbour's instance than its own body took that instance, and the neighbour's detection went to the
  instance above it, missed in that array: three instances each on another's block (jenga blocks in two
  layers).
- **Second detections.** A detection matched to no instance whose results come within the *same-body
  distance* of an instance another detection of the same array matched is a second detection of
  that instance (an estimator that reports one object twice): counted as a *double*, not used. The
  distance is half the smallest extent of the class's shape (or the gate, if less): two identical
  bodies that do not overlap are never that close (a part lying on another is a part, not a double).
- **Births.** Another detection matched to no instance starts a *tentative* track on a free instance
  (one without a track): the one whose ended track was last within the gate of the detection (an
  instance seen again after a long miss keeps its name), else a never-tracked one, in scene
  order, else the one whose track ended longest ago, of those whose ended track was not last
  within the gate of another detection of the array that matched no instance (that one comes back
  to it, whichever of them is born first). With no free instance it takes that of a
  tentative track no valid map held, on which the last map held nothing up, and that this array's miss ends
  anyway; else it is counted
  as outside every gate and not used (``count: {max: K}`` stops at K). Detections born together
  take their instances in the order of the heights of their bodies' centres at their central results'
  poses (z, along gravity in REP-103's frames: a mesh's frame may lie at its bottom; ties by the
  central results' x, then y), from the lowest, not of the array: even a first frame names the same
  boxes the same way however it is ordered, and where more are born than instances are free, those
  left outside are the highest, a detection in the air (with nothing to stand on, the likeliest false
  one) before one low in the pile. Before
  them come those that *recur*: the central result within the gate of that of a detection of the
  class's last array (a
  true object comes back to its place, though it was left outside or its track ended; a false
  detection seldom does); after them those whose body, at the central result's pose, lies in a static
  body: below a plane (the floor) deeper than the penetration threshold, or its box's centre inside
  another (a wall). Where an array holds more detections than there are instances, the last are the
  ones left outside.
- **Confirmation.** A track is *tentative* until it was matched ``confirm_hits`` times and some
  *valid* map held its instance (:meth:`InstanceTracks.keep`): a detection physics finds no place for,
  a reflection in the air seen in every frame, is never confirmed by repeating itself, nor by a
  fallback's map, which holds every object it is given.
- **Misses and ends.** An instance no detection matched keeps its own state and hypotheses; it
  never takes another's. A tentative track matched only once ends once ``tentative_misses`` arrays in a
  row (2) matched it no detection (an estimator misses a true object now and then, a false detection
  seldom comes back to the same place: one matched :data:`CAME_BACK_HITS` times came back), unless the
  last map held another object up on it (:meth:`InstanceTracks.hold_up`; the box under a stacked one
  is the one the camera misses, and a false detection holds nothing up), and when
  physics leaves its instance out
  (:meth:`InstanceTracks.reject`): a finished search's map does, or every pose of it is ruled out before
  the search and the map leaves it out (a refined map keeps one another rests on), or
  :data:`CUT_SHORT_LEAVINGS` (2) valid maps in a row of searches the deadline stopped
  do (an invalid map of a stopped search is no verdict); a confirmed one ends when unmatched for more
  than ``max_age`` seconds. Two tracks on one body, whose poses the search rules out each against every
  pose of the other (:func:`~physics_mapper.mapping.existence.twins`), end as one, confirmed or not
  (:meth:`InstanceTracks.end_twins`); two a valid map holds both are two bodies. An ended track frees its
  instance, and the instance's hypotheses are forgotten.
- **Existence.** An instance that may not be there, a tentative track or an instance of a
  ``count: {max: K}`` entry, has a weight for *absent*:
  w_absent = prod_k (1 - c_k) over its track's (newest 20) matched detections, c_k the detection's best
  score clipped to [0, :data:`MAX_CONFIDENCE`] (each detection is independent evidence that the
  instance exists: a noisy-OR). A confirmed instance of ``count: K`` has none: it exists.

Identities never depend on the order of detections in an array: the assignment is optimal for
the whole array, and ties in cost go to the lower instance and detection index.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from filterpy.kalman import KalmanFilter
from numpy.linalg import norm
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from physics_mapper.model.extents import body_box, inside_static, may_overlap_static, shape_extents
from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import ObjectShape, Plane, Scene

#: A detection's best score counts as at most this confidence that its instance exists.
MAX_CONFIDENCE = 0.95
#: Matched detections whose confidence counts for existence (the newest): w_absent stays above 0.05^20.
CONFIDENCES_KEPT = 20
#: Matches after which a tentative track has come back to its place: misses no longer end it (``max_age``
#: and physics still do), since a false detection seldom comes back to the same place and a true object
#: missed twice in a row (10 % misses: often, in a bin of 24) would lose its track, and its name, while no
#: valid map has confirmed it yet.
CAME_BACK_HITS = 2
#: Valid maps of searches the deadline stopped that must leave a tentative instance out in a row before its
#: track ends: one such map may have left out a true object a longer search would have kept, and ended, its
#: track would start again with one detection's evidence, its *absent* then likelier than any one pose, so
#: that the next maps leave it out too.
CUT_SHORT_LEAVINGS = 2
#: Probability with which a detection of an instance lies within its track's reach (:meth:`Track.reach`).
GATE_PROBABILITY = 0.99
_GATE_CHI2 = float(chi2.ppf(GATE_PROBABILITY, 3))
#: The least share of the shape's extent, along each axis of the body a detection shows, by which that body and
#: the same body at a track's predicted position overlap where the detection is of the track's instance
#: (module docstring, then distance): a detection of the block lying on a missed one (3 cm thick, seen 5 mm
#: low) overlaps it by a sixth; in bins of boxes, cylinders, lego parts, jenga blocks and flat parts every
#: other match overlapped by a half or more (BENCHMARKS.md, "Bins of identical objects").
BODY_OVERLAP = 0.25
#: Cost of a pair outside the gate: never chosen over a gated pair (distances are metres, ≤ 1e7).
_FORBIDDEN = 1e12


@dataclass(frozen=True)
class AssociationSettings:
    """How detections are matched to instances (module docstring).

    gate: metres beyond which a detection never matches an instance (0: half the largest extent
    of the class's shape). confirm_hits: matches after which a track is confirmed.
    tentative_misses: arrays in a row without a detection matched to a tentative track matched once only, after
    which it ends.
    process_noise: m²/s of random walk per second. measurement_noise: m, standard deviation of a
    detection's position. max_age: seconds a confirmed track lives unmatched.
    """

    gate: float = 0.0
    confirm_hits: int = 3
    tentative_misses: int = 2
    process_noise: float = 1.0e-4
    measurement_noise: float = 0.01
    max_age: float = 10.0


@dataclass(frozen=True)
class Observation:
    """One detection of a tracked class: ``positions`` (M x 3, m), ``orientations`` (M x 4, quaternions x, y,
    z, w) and ``scores`` (M) of its usable results, its ``key`` (``Detection3D.id``, '' if none) and its
    ``index`` in the array."""

    class_id: str
    positions: NDArray[np.float64]
    orientations: NDArray[np.float64]
    scores: NDArray[np.float64]
    key: str = ""
    index: int = 0

    @property
    def best(self) -> int:
        """The index of the best-scored result (the first of equal ones)."""
        return int(np.argmax(self.scores))

    @cached_property
    def central(self) -> int:
        """The index of the result nearest the median of its results' positions (per axis), of equally near
        ones the best-scored (then the first). Where an estimator ranks a wrong pose first, the other
        results agree with each other, not with it; a wrong pose's score would outweigh them. Linear in
        the results (a detection of 1,000 results, or a covariance's alternatives, costs no more)."""
        offsets = np.linalg.norm(self.positions - np.median(self.positions, axis=0), axis=1)
        return int(np.lexsort((-self.scores, offsets))[0])

    def place(self) -> tuple[float, ...]:
        """Where its central result is, (x, y, z) in metres: where a new track starts, and the order in
        which new tracks are born."""
        return tuple(self.positions[self.central].tolist())

    def central_pose(self) -> Pose:
        """Its central result's pose."""
        x, y, z = self.positions[self.central].tolist()
        qx, qy, qz, qw = self.orientations[self.central].tolist()
        return Pose((x, y, z), (qx, qy, qz, qw))

    def nearest(self, point: NDArray[np.float64]) -> tuple[int, float]:
        """The result nearest ``point`` and its distance (m)."""
        distances = np.linalg.norm(self.positions - point, axis=1)
        index = int(np.argmin(distances))
        return index, float(distances[index])


@dataclass
class Track:
    """An instance's filtered position, its key and its history of matches."""

    filter: KalmanFilter
    updated: float  # seconds, when the filter last took a measurement
    key: str = ""
    hits: int = 0
    misses: int = 0  # arrays in a row that matched it no detection
    cut_short_leavings: int = 0  # valid maps cut short by the deadline in a row that left its instance out
    confidences: list[float] = field(default_factory=list)
    kept: bool = False  # some valid map held its instance
    holds_up: bool = False  # the last map held another object up on its instance
    rested: bool = False  # the first map that held its instance was taken as a measurement

    @property
    def position(self) -> NDArray[np.float64]:
        return np.asarray(self.filter.x[:, 0], dtype=np.float64)

    def predicted(self, now: float, process_noise: float) -> NDArray[np.float64]:
        """The position predicted at ``now``: unchanged (constant position), its uncertainty grown."""
        if now == self.updated:  # no time passed: the prediction is the state itself
            return self.position
        self.filter.Q = np.eye(3) * process_noise * max(0.0, now - self.updated)
        self.filter.predict()
        self.updated = now
        return self.position

    def reach(self) -> float:
        """Metres from the predicted position within which a measurement lies with probability
        :data:`GATE_PROBABILITY`: sqrt(chi2_3(GATE_PROBABILITY) * s), s the largest variance of S = P + R."""
        covariance = np.asarray(self.filter.P + self.filter.R, dtype=np.float64)
        return math.sqrt(_GATE_CHI2 * float(np.linalg.eigvalsh(covariance).max()))

    def absent_weight(self) -> float:
        """prod_k (1 - c_k) over the matched detections' confidences (module docstring)."""
        return float(np.prod([1.0 - c for c in self.confidences]))


@dataclass(frozen=True)
class PositionPrior:
    """Where a track predicted its instance before an array's detection updated it: ``mean`` (3, m) and
    ``covariance`` S = P + R (3 x 3, m²) of the position measured (module docstring, the track's prior)."""

    mean: NDArray[np.float64]
    covariance: NDArray[np.float64]

    def factors(self, positions: NDArray[np.float64]) -> NDArray[np.float64]:
        """Each of ``positions`` (N x 3, m)'s weight factor, exp(-(d - min d) / 2) with d the squared
        Mahalanobis distance from ``mean``: 1 for the nearest, in (0, 1] for all (1 for a non-finite row)."""
        offsets = positions - self.mean
        squared = np.einsum("ij,ij->i", offsets @ np.linalg.inv(self.covariance), offsets)
        finite = np.isfinite(squared)
        if not finite.any():
            return np.ones(len(positions))
        return np.where(finite, np.exp(-0.5 * (squared - squared[finite].min())), 1.0)


@dataclass(frozen=True)
class FrameAssociation:
    """What one array's detections became: detection index -> instance name, each matched instance's
    prior (new tracks have none), and what happened."""

    assigned: dict[int, str]
    priors: dict[str, PositionPrior] = field(default_factory=dict)
    born: tuple[str, ...] = ()
    ended: tuple[str, ...] = ()
    outside: dict[str, int] = field(default_factory=dict)  # class id -> detections matched to nothing
    doubles: dict[str, int] = field(default_factory=dict)  # class id -> second detections of an instance


@dataclass(frozen=True)
class Tracking:
    """What the association did over a while (a tick): instances whose tracks began (``births``) and
    ended (``ends``); each tracked class's instances with a track; detections matched to no instance
    (``outside``) and second detections of an instance (``doubles``) since the start."""

    births: tuple[str, ...] = ()
    ends: tuple[str, ...] = ()
    instances: tuple[tuple[str, int], ...] = ()
    outside: int = 0
    doubles: int = 0


def _nearest_distances(
    points: NDArray[np.float64], observations: Sequence[Observation], gate: float
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """(P x O) metres: from each of ``points`` (P x 3) to the nearest result of each observation, where
    that can be within ``gate``; inf where the point is farther than ``gate`` from the box bounding the
    observation's results (a lower bound of the distance to each of them): only the results of the
    observations near a point are measured, not every result from every point. Also (P x O) the index
    of that nearest result (0 where inf)."""
    results = np.concatenate([o.positions for o in observations])
    starts = np.cumsum([0] + [len(o.positions) for o in observations[:-1]])
    low, high = np.minimum.reduceat(results, starts), np.maximum.reduceat(results, starts)
    outside = np.maximum(low[None] - points[:, None], 0.0) + np.maximum(points[:, None] - high[None], 0.0)
    near = np.linalg.norm(outside, axis=2) <= gate
    distances = np.full(near.shape, np.inf)
    nearest = np.zeros(near.shape, dtype=np.intp)
    for column in np.flatnonzero(near.any(axis=0)).tolist():
        rows = np.flatnonzero(near[:, column])
        offsets = cdist(points[rows], observations[column].positions)
        nearest[rows, column] = np.argmin(offsets, axis=1)
        distances[rows, column] = offsets[np.arange(len(rows)), nearest[rows, column]]
    return distances, nearest


def _body_overlaps(
    points: NDArray[np.float64],
    places: NDArray[np.float64],
    orientations: NDArray[np.float64],
    extents: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(P x O): by what share of the shape's ``extents`` (m) a body at each of ``places`` (O x 3, m) turned by
    ``orientations`` (O x 4, quaternions x, y, z, w) and the same body moved to each of ``points`` (P x 3, m)
    overlap along the body's axis where they overlap least: 1 - max_i |d_i| / e_i, d the offset between the two
    in the body's frame (0 where they touch, negative where they lie apart)."""
    turns = Rotation.from_quat(orientations).as_matrix()
    offsets = np.einsum("oji,poj->poi", turns, places[None] - points[:, None])  # R^T d, P x O x 3
    return np.asarray(1.0 - np.max(np.abs(offsets) / extents, axis=2), dtype=np.float64)


def _assigned(costs: NDArray[np.float64]) -> list[tuple[int, int]]:
    """The (row, column) pairs of the least-cost assignment on ``costs`` that are not forbidden, cheapest first."""
    rows, columns = linear_sum_assignment(costs)
    pairs = [(r, c) for r, c in zip(rows.tolist(), columns.tolist(), strict=True) if costs[r, c] < _FORBIDDEN]
    return sorted(pairs, key=lambda pair: (costs[pair], pair))


def _one_match_per_body(
    observations: Sequence[Observation],
    costs: NDArray[np.float64],
    nearest: NDArray[np.intp],
    same_body: float,
    matched: Sequence[NDArray[np.float64]] = (),
) -> list[tuple[int, int]]:
    """:func:`_assigned` on ``costs``, each observation the assignment matches from farther than another whose
    central result, or measurement (``nearest``), lies within ``same_body`` metres of its own (one body seen
    twice), or whose central result or measurement lies so near one of ``matched`` (the central results of the
    detections matched before, by key), left out (its column forbidden in ``costs``) and the assignment made
    again, until none is."""
    while True:
        pairs = _assigned(costs)
        kept = [(place, place) for place in matched]  # (central result, measurement), m
        for row, column in pairs:
            observation = observations[column]
            place = observation.positions[observation.central]
            measured = observation.positions[nearest[row, column]]
            if any(min(norm(place - p), norm(measured - m)) <= same_body for p, m in kept):
                costs[:, column] = _FORBIDDEN
                break
            kept.append((place, measured))
        else:
            return pairs


class InstanceTracks:
    """The tracks of a scene's tracked classes (module docstring); not thread-safe."""

    def __init__(self, scene: Scene, settings: AssociationSettings | None = None) -> None:
        self.scene = scene
        self.settings = settings or AssociationSettings()
        self.tracks: dict[str, Track] = {}
        self._matched: dict[str, float] = {}  # name -> when its track was last matched, s
        self._ended_at: dict[str, float] = {}
        self._last_position: dict[str, NDArray[np.float64]] = {}  # where each ended track was
        self._shapes = {model.name: model.shape for model in scene.objects}
        self._extents: dict[str, NDArray[np.float64]] = {}  # class id -> its shape's extents (m)
        self._last_places: dict[str, NDArray[np.float64]] = {}  # class id -> the last array's central results (m)
        #: Counts since the start: tracks born and ended, detections matched to nothing.
        self.births = 0
        self.ends = 0
        self.outside = 0
        self.doubles = 0

    def gate(self, class_id: str) -> float:
        """The class's gate, metres."""
        if self.settings.gate > 0.0:
            return self.settings.gate
        return 0.5 * float(np.max(self._class_extents(class_id)))

    def same_body(self, class_id: str) -> float:
        """The class's same-body distance (module docstring, second detections), metres."""
        return min(0.5 * float(np.min(self._class_extents(class_id))), self.gate(class_id))

    def _class_extents(self, class_id: str) -> NDArray[np.float64]:
        """The class's shape's extents (m): their largest half is the default gate, their smallest half the
        same-body distance (two identical bodies that do not overlap have their centres farther apart)."""
        if class_id not in self._extents:
            self._extents[class_id] = shape_extents(self._class_shape(class_id))
        return self._extents[class_id]

    def _class_shape(self, class_id: str) -> ObjectShape:
        """The shape every instance of ``class_id`` shares."""
        return self._shapes[self.scene.objects_of_class(class_id)[0]]

    def tentative(self, name: str) -> bool:
        """Whether ``name`` has a track not confirmed yet: matched fewer than ``confirm_hits`` times, or never
        held by a valid map (:meth:`keep`)."""
        track = self.tracks.get(name)
        return track is not None and (track.hits < self.settings.confirm_hits or not track.kept)

    def absent_weight(self, name: str) -> float | None:
        """The weight of ``name`` being absent, or None if it is certainly there while tracked."""
        track = self.tracks.get(name)
        if track is None:
            return None
        if name in self.scene.optional or self.tentative(name):
            return track.absent_weight()
        return None

    def keep(self, names: Sequence[str]) -> None:
        """Note that a valid map holds the instances ``names``: their tracks may be confirmed."""
        for name in names:
            track = self.tracks.get(name)
            if track is not None:
                track.kept = True
                track.cut_short_leavings = 0

    def hold_up(self, names: Sequence[str]) -> None:
        """Note that the last map holds another object up on each instance of ``names`` (and on no other):
        misses do not end their tracks."""
        held = set(names)
        for name, track in self.tracks.items():
            track.holds_up = name in held

    def first_rests(self, rests: Mapping[str, NDArray[np.float64]]) -> None:
        """Take where the first map holding each new instance rested it (``rests``, m) as a second
        measurement of its track, where within the gate (module docstring, the measurement)."""
        for name, position in rests.items():
            track = self.tracks.get(name)
            if track is None or track.hits != 1 or track.rested:
                continue
            track.rested = True
            if norm(position - track.position) <= self.gate(self.scene.class_of(name)):
                track.filter.update(position.reshape(3, 1))

    def instances_per_class(self) -> dict[str, int]:
        """Tracked classes -> their instances with a track."""
        return {
            class_id: sum(name in self.tracks for name in names)
            for class_id, names in self.scene.class_map
            if self.scene.is_tracked(class_id)
        }

    def expire(self, now: float) -> tuple[str, ...]:
        """End the tracks unmatched for more than ``max_age`` seconds at ``now``."""
        ended = tuple(name for name, when in self._matched.items() if now - when > self.settings.max_age)
        for name in ended:
            self._end(name, now)
        return ended

    def reject(self, names: Sequence[str], cut_short: Sequence[str], now: float) -> tuple[str, ...]:
        """End the tentative tracks of ``names``, instances physics left out at ``now``
        (:func:`~physics_mapper.mapping.existence.left_out_by_physics`): it found no place for them; and
        of ``cut_short``, instances a valid map of a search the deadline stopped left out, once
        :data:`CUT_SHORT_LEAVINGS` such maps in a row did. Returns the names whose tracks ended."""
        repeated = []
        for name in cut_short:
            track = self.tracks.get(name)
            if track is not None:
                track.cut_short_leavings += 1
                if track.cut_short_leavings >= CUT_SHORT_LEAVINGS:
                    repeated.append(name)
        ended = tuple(name for name in dict.fromkeys([*names, *repeated]) if self.tentative(name))
        for name in ended:
            self._end(name, now)
        return ended

    def same_class(self, name: str, other: str) -> bool:
        """Whether the objects ``name`` and ``other`` are instances of one tracked class."""
        return name in self.tracks and other in self.tracks and self.scene.class_of(name) == self.scene.class_of(other)

    def end_twins(self, pairs: Sequence[tuple[str, str]], now: float) -> tuple[str, ...]:
        """End one track of each pair (instance, twin) of tracks on one body
        (:func:`~physics_mapper.mapping.existence.twins`), confirmed or not: the instance's, or where the twin
        is ruled out by it too, the one matched fewer times (then the later in scene order). Returns the
        names whose tracks ended."""
        paired = set(pairs)
        ended: list[str] = []
        for name, twin in pairs:
            if name not in self.tracks or twin not in self.tracks:  # one of the two ended already
                continue
            if (twin, name) in paired and self._evidence(name) > self._evidence(twin):
                name = twin
            self._end(name, now)
            ended.append(name)
        return tuple(ended)

    def _evidence(self, name: str) -> tuple[int, int]:
        """What keeps ``name``'s track rather than its twin's: more matches, then earlier in scene order."""
        return self.tracks[name].hits, -self.scene.object_names.index(name)

    def _end(self, name: str, now: float) -> None:
        self._last_position[name] = self.tracks[name].position
        del self.tracks[name]
        del self._matched[name]
        self._ended_at[name] = now
        self.ends += 1

    def associate(self, observations: Sequence[Observation], now: float) -> FrameAssociation:
        """Give each observation of one array, received at ``now`` (s), an instance (module docstring)."""
        frame = FrameAssociation({}, ended=self.expire(now))
        matched: set[str] = set()
        for class_id in dict.fromkeys(o.class_id for o in observations):
            of_class = [o for o in observations if o.class_id == class_id]
            names = self.scene.objects_of_class(class_id)
            pairs = self._match(of_class, [n for n in names if n in self.tracks], class_id, now)
            for observation, name, nearest in pairs:
                frame.priors[name] = self._update(name, observation, now, nearest)
                frame.assigned[observation.index] = name
                matched.add(name)
            unmatched = sorted((o for o in of_class if o.index not in frame.assigned), key=self._birth_order)
            frame = self._births(frame, unmatched, names, matched, now)
            self._last_places[class_id] = np.array([o.place() for o in of_class], dtype=np.float64)
        frame = replace(frame, ended=(*frame.ended, *self._miss([n for n in self.tracks if n not in matched], now)))
        self.births += len(frame.born)
        self.outside += sum(frame.outside.values())
        self.doubles += sum(frame.doubles.values())
        return frame

    def _births(
        self,
        frame: FrameAssociation,
        unmatched: Sequence[Observation],
        names: Sequence[str],
        matched: set[str],
        now: float,
    ) -> FrameAssociation:
        """``frame`` with the detections of one class that matched no instance: each a second detection,
        a new track or outside every gate (module docstring). ``matched``: the instances matched so far."""
        born, ended = list(frame.born), list(frame.ended)
        outside, doubles = dict(frame.outside), dict(frame.doubles)
        for observation in unmatched:
            gate, same_body = self.gate(observation.class_id), self.same_body(observation.class_id)
            if any(observation.nearest(self.tracks[n].position)[1] <= same_body for n in matched if n in names):
                doubles[observation.class_id] = doubles.get(observation.class_id, 0) + 1
                continue
            free = self._free(names, observation, gate, unmatched)
            if free is None and (free := self._yielded(names, matched, now)) is not None:
                ended.append(free)  # the track whose instance it takes
            if free is None:
                outside[observation.class_id] = outside.get(observation.class_id, 0) + 1
                continue
            self._birth(free, observation, now)
            frame.assigned[observation.index] = free
            matched.add(free)
            born.append(free)
        return replace(frame, born=tuple(born), ended=tuple(ended), outside=outside, doubles=doubles)

    def _birth_order(self, observation: Observation) -> tuple[bool, bool, float, tuple[float, ...]]:
        """Where a detection that matched no instance comes among those of its array (module docstring):
        those that recur first, those whose body at the central result's pose lies in a static body
        (:meth:`_inside`) last, then from the lowest body's centre up, then by place."""
        low, high = body_box(self._class_shape(observation.class_id), observation.central_pose())
        place = observation.place()
        return (
            self._inside(low, high),
            not self._recurs(observation.class_id, place),
            float(low[2] + high[2]) / 2.0,
            place,
        )

    def _inside(self, low: NDArray[np.float64], high: NDArray[np.float64]) -> bool:
        """Whether a body whose box is (``low``, ``high``) lies in a static body: below a plane deeper than the
        penetration threshold (on a floor the box's lowest point is the body's), or its box's centre inside
        another (a turned mesh's box reaches into a wall its body does not touch)."""
        depth = self.scene.search.penetration_threshold
        centre = (low + high) / 2.0
        return any(
            bool(may_overlap_static(body, low[None], high[None], depth)[0])
            if isinstance(body.shape, Plane)
            else inside_static(body, centre)
            for body in self.scene.static
        )

    def _recurs(self, class_id: str, place: tuple[float, ...]) -> bool:
        """Whether ``place`` (a detection's central result, m) lies within the gate of the central result of
        a detection of ``class_id``'s last array."""
        last = self._last_places.get(class_id)
        if last is None:
            return False
        return bool(np.linalg.norm(last - np.asarray(place), axis=1).min() <= self.gate(class_id))

    def _miss(self, names: Sequence[str], now: float) -> list[str]:
        """Count a miss of each tracked instance of ``names``; end the tentative ones missed
        ``tentative_misses`` times in a row. Returns the names whose tracks ended."""
        ended = []
        for name in names:
            self.tracks[name].misses += 1
            if self._ended_by_misses(name):
                self._end(name, now)
                ended.append(name)
        return ended

    def _ended_by_misses(self, name: str) -> bool:
        """Whether ``name``'s track ends by its misses: a tentative track matched fewer than
        :data:`CAME_BACK_HITS` times, missed ``tentative_misses`` times in a row, on which the last map held no
        other object up."""
        track = self.tracks[name]
        return (
            self.tentative(name)
            and track.hits < CAME_BACK_HITS
            and track.misses >= self.settings.tentative_misses
            and not track.holds_up
        )

    def _match(
        self, observations: list[Observation], names: list[str], class_id: str, now: float
    ) -> list[tuple[Observation, str, int | None]]:
        """Pairs by key, then by gated optimal assignment on distance, each with the index of the
        observation's result nearest the instance's predicted position where it was measured; a detection
        of a body another matched detection shows is not matched (module docstring, one body)."""
        pairs: list[tuple[Observation, str, int | None]] = []
        keyed = {self.tracks[n].key: n for n in names if self.tracks[n].key}
        rest: list[Observation] = []
        for observation in observations:
            name = keyed.pop(observation.key, None) if observation.key else None
            if name is None:
                rest.append(observation)
            else:
                pairs.append((observation, name, None))
        taken = {name for _, name, _ in pairs}
        free = [n for n in names if n not in taken]
        if not rest or not free:
            return pairs
        predicted = np.array([self.tracks[n].predicted(now, self.settings.process_noise) for n in free])
        gate = self.gate(class_id)
        costs, nearest = _nearest_distances(predicted, rest, gate)
        # The body a detection shows is at its central result: a result of it near the track (a wrong pose in
        # a neighbour's place) does not make that body the track's instance.
        places = np.array([o.positions[o.central] for o in rest])
        farthest = np.maximum(costs, cdist(predicted, places))
        costs[farthest > gate] = _FORBIDDEN
        if self.settings.gate <= 0.0:  # an explicit gate is the user's; the default one stops at the reach
            reaches = np.array([self.tracks[n].reach() for n in free])
            costs[farthest > reaches[:, None]] = _FORBIDDEN
            turns = np.array([o.orientations[o.central] for o in rest])
            overlaps = _body_overlaps(predicted, places, turns, self._class_extents(class_id))
            costs[overlaps < BODY_OVERLAP] = _FORBIDDEN
        keyed_places = [o.positions[o.central] for o, _, _ in pairs]
        assigned = _one_match_per_body(rest, costs, nearest, self.same_body(class_id), keyed_places)
        pairs.extend((rest[column], free[row], int(nearest[row, column])) for row, column in assigned)
        return pairs

    def _free(
        self, names: Sequence[str], observation: Observation, gate: float, unmatched: Sequence[Observation]
    ) -> str | None:
        """The instance a new track starts on (module docstring): of those without a track, the one whose
        ended track was last within the gate of ``observation``, else a never-tracked one, else the one
        whose track ended longest ago and was not last within the gate of another of ``unmatched`` (the
        array's detections that matched no instance: that one comes back to it)."""
        free = [n for n in names if n not in self.tracks]
        back = [(observation.nearest(self._last_position[n])[1], n) for n in free if n in self._last_position]
        near = min((pair for pair in back if pair[0] <= gate), default=None)
        if near is not None:
            return near[1]
        never = [n for n in free if n not in self._ended_at]
        if never:
            return never[0]
        others = [o for o in unmatched if o is not observation]
        unclaimed = [
            n
            for n in free
            if n not in self._last_position or all(o.nearest(self._last_position[n])[1] > gate for o in others)
        ]
        return min(unclaimed, key=lambda n: self._ended_at[n], default=None)

    def _yielded(self, names: Sequence[str], matched: set[str], now: float) -> str | None:
        """With no instance free: the instance of a tentative track that no valid map held, on which the last
        map held nothing up, and that matched nothing here nor in the ``tentative_misses`` - 1 arrays before
        (ended by this array's miss if it was matched only once, :meth:`_ended_by_misses`; ended here however
        often it came back, as a true object's detection needs its name more), now ended (the one with the
        least evidence of existing), or None."""
        last = self.settings.tentative_misses - 1
        waiting = [  # a track no valid map held is tentative
            n
            for n in names
            if n in self.tracks
            and n not in matched
            and not self.tracks[n].kept
            and not self.tracks[n].holds_up
            and self.tracks[n].misses >= last
        ]
        if not waiting:
            return None
        name = max(waiting, key=lambda n: self.tracks[n].absent_weight())
        self._end(name, now)
        return name

    def _birth(self, name: str, observation: Observation, now: float) -> None:
        kalman = KalmanFilter(dim_x=3, dim_z=3)
        kalman.x = observation.positions[observation.central].reshape(3, 1).copy()
        kalman.F = np.eye(3)
        kalman.H = np.eye(3)
        kalman.R = np.eye(3) * self.settings.measurement_noise**2
        kalman.P = np.eye(3) * self.settings.measurement_noise**2
        self.tracks[name] = Track(kalman, now)
        self._matched[name] = now
        self._confirm(name, observation)

    def _update(self, name: str, observation: Observation, now: float, nearest: int | None) -> PositionPrior:
        """Update ``name``'s track with the observation's result nearest its predicted position (its index
        ``nearest`` where the matching measured it); returns the prediction it updated."""
        track = self.tracks[name]
        point = track.predicted(now, self.settings.process_noise)
        prior = PositionPrior(point, np.asarray(track.filter.P + track.filter.R, dtype=np.float64))
        if nearest is None:
            nearest, _ = observation.nearest(point)
        track.filter.update(observation.positions[nearest].reshape(3, 1))
        self._matched[name] = now
        track.misses = 0
        self._confirm(name, observation)
        return prior

    def _confirm(self, name: str, observation: Observation) -> None:
        track = self.tracks[name]
        track.hits += 1
        track.confidences.append(min(MAX_CONFIDENCE, max(0.0, float(observation.scores[observation.best]))))
        del track.confidences[:-CONFIDENCES_KEPT]
        if observation.key:
            track.key = observation.key

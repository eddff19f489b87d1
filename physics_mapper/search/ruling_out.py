"""Ranks ruled out alone before a group's search starts: Rule 1 made consistent object by object, and free falls.

Object p at rank a is *ruled out alone* when no valid configuration holds it
(:mod:`physics_mapper.search.conflicts`, a one-assignment conflict {(p, a)}), which Rule 1 shows in two
ways:

- p at a overlaps a static body deeper than the ``penetration_threshold``;
- for some other object q, p at a overlaps q deeper than the threshold at every rank of q not ruled
  out alone already (in groups of :data:`PAIRS_FROM_OBJECTS` objects or more).

The second rule feeds on the first, so it is applied until nothing changes (arc consistency on the
pairwise Rule 1 table). Rule 2 rules out one more kind alone (:class:`FreeFall`): p at a *in free
fall*, its stable envelope E_p(a) (:mod:`physics_mapper.search.conflicts`) linked to no static body
through other objects' envelopes (a chain of them meeting, from a static body to p's), when the settling
lasts long enough for a fall to leave it: a detection in the air, or two side by side, with nothing below
them that rests on anything.

A search learns the same conflicts from rejected candidates, but only once a
candidate holding p at a is checked: meanwhile every queued candidate holding it is skipped one by
one, thousands in a crowded group. Learned first, those candidates are never made
(:meth:`~physics_mapper.search.conflicts.ConflictStore.next_rank`).

Only pairs that can overlap that deep are looked up in the table: an overlap's depth is at most the
overlap of the two bodies' boxes along every axis (:func:`~physics_mapper.model.extents.may_overlap_static`),
so boxes (from :func:`~physics_mapper.model.extents.body_box`) that overlap by less decide the pair
without the engine. The conflicts themselves come from the table's depths, the ones Rule 1 uses.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.extents import may_overlap_static, meets_boxes, stable_growth
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene, SearchParams, StaticBody, object_radius
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.search.conflicts import Conflict, ConflictStore, Region
from physics_mapper.search.groups import Grouping

FloatArray = NDArray[np.float64]
#: Objects a group needs for the pairwise rule: in a small group few candidates hold a rank it would
#: rule out, and the search meets them faster than the table's look-ups (the scale suite's piles of
#: 2 and 6 cubes at M = 20: 220 ms with the rule, 140 ms without; ``physics-mapper bench --crowded``).
PAIRS_FROM_OBJECTS = 7
#: Pairs of hypothesis boxes the pass compares at most; beyond, it is not made (the search is the
#: same without it, only slower to skip what it would have ruled out).
BOX_PAIR_LIMIT = 1 << 20
#: Pairs of envelopes the free-fall pass compares in one array (a few megabytes).
PAIRS_AT_ONCE = 1 << 20
#: m/s², along -z (REP-103): how far a body in free fall drops in a settling.
GRAVITY = 9.81


@dataclass(frozen=True, slots=True)
class Ruling:
    """Why one rank was ruled out alone: the object at ``position`` (in its group) at ``rank`` overlaps
    body ``other`` (a body index: the scene's objects, then its static bodies) ``depth`` metres deep;
    with ``every_rank``, at each rank of that object not ruled out already, ``depth`` the shallowest.
    A rank in free fall (``floating``) has no ``other`` (-1) and ``depth`` 0."""

    position: int
    rank: int
    other: int
    depth: float
    every_rank: bool = False
    floating: bool = False


@dataclass(frozen=True)
class RulingOut:
    """The pass over one group (module docstring): its objects' scene indices by position, the corners
    of each object p's body boxes by rank (``lows[p]``, ``highs[p]``: M_p x 3, metres), the pairwise
    table, the penetration threshold (m) and the store that learns the conflicts."""

    objects: Sequence[int]
    lows: Sequence[FloatArray]
    highs: Sequence[FloatArray]
    table: CollisionTable
    threshold: float
    store: ConflictStore

    def run(self, statics: Sequence[StaticBody]) -> list[Ruling]:
        """Learn every rank Rule 1 rules out alone, against ``statics`` and pairwise; why each, in
        learning order."""
        rulings = self._on_statics(statics)
        overlaps = (
            _box_overlaps(self.lows, self.highs, self.threshold) if len(self.objects) >= PAIRS_FROM_OBJECTS else None
        )
        if overlaps is None:
            return rulings
        pending = list(overlaps)
        while pending:  # a rank ruled out may rule out others: the pairs whose q lost ranks, again
            lost = self._on_pairs({pair: overlaps[pair] for pair in pending})
            rulings += lost
            losers = {ruling.position for ruling in lost}
            pending = [(p, q) for p, q in overlaps if q in losers]
        return rulings

    def _on_statics(self, statics: Sequence[StaticBody]) -> list[Ruling]:
        """Learn the ranks that overlap a static body deeper than the threshold; why each."""
        rulings = []
        lows, highs = np.concatenate(self.lows), np.concatenate(self.highs)
        reach = np.zeros(len(lows), dtype=bool)
        for body in statics:
            reach |= may_overlap_static(body, lows, highs, self.threshold)
        starts = np.cumsum([0, *(len(low) for low in self.lows)])
        for position, index in enumerate(self.objects):
            reached = reach[starts[position] : starts[position + 1]]
            for rank in (int(k) + 1 for k in np.nonzero(reached)[0]):
                other, depth = self.table.deepest_static(index, rank)
                if other is None or depth <= self.threshold:
                    continue
                if self.store.learn(Conflict(((position, rank),), "collision")):
                    rulings.append(Ruling(position, rank, other, depth))
        return rulings

    def _on_pairs(self, overlaps: dict[tuple[int, int], FloatArray]) -> list[Ruling]:
        """One pass over the pairs: learn each rank of p that overlaps q deeper than the threshold at
        every rank of q not ruled out; why each, once per rank."""
        lost = []
        for (p, q), overlap in overlaps.items():
            live = self.store.live_ranks(q)
            if not live:
                continue
            columns = np.asarray(live) - 1
            rows = overlap[:, columns]
            # The ranks of p whose boxes overlap every live rank's that deep, p's live ones among them.
            for rank in (int(k) + 1 for k in np.nonzero(np.all(rows > self.threshold, axis=1))[0]):
                if self.store.rules_out(p, rank):
                    continue
                # The ranks least deep by their boxes first: the first shallow one decides.
                ranks = [live[int(k)] for k in np.argsort(rows[rank - 1], kind="stable")]
                first, second = self.objects[p], self.objects[q]
                shallowest = math.inf
                for b in ranks:
                    shallowest = min(shallowest, self.table.pair_depth(first, rank, second, b))
                    if shallowest <= self.threshold:
                        break
                else:
                    self.store.learn(Conflict(((p, rank),), "collision"))
                    lost.append(Ruling(p, rank, second, shallowest, every_rank=True))
        return lost


@dataclass(frozen=True)
class Ground:
    """Every object of the scene's stable envelopes by rank (``envelopes[i]``: M_i x 3 lows and highs, m),
    which ranks are bodies (``bodies[i]``; False: *absent*) and which of those are *grounded* (``grounded[i]``).

    A rank is *grounded* when its envelope meets a static body or a grounded rank's envelope of another
    object (the least such set, grown from the static bodies outwards). Every rank of a valid
    configuration is grounded: were some of its objects at ranks that are not, those would meet nothing
    grounded while they stayed in their envelopes, nor any static body, so only they could push one
    another and their centre of mass would drop 1/2 g T² in the settling's T seconds, more than any of
    their g_p: one of them out of its envelope, beyond the jitter threshold (sound as the blame rule is).
    Every object of the scene is looked at, not only a group's: an envelope reaches further than the
    grouping's margin. Every rank of an object whose g_p the fall does not exceed is grounded (no verdict).
    An object no rank of which is grounded, and that cannot be absent, keeps them all (and they may hold
    others up): no configuration would be left to check, and the ``settled`` fallback reports the first one
    settled (it drops the object onto what is below: a map where no combination is valid).
    """

    envelopes: Sequence[tuple[FloatArray, FloatArray]]
    bodies: Sequence[NDArray[np.bool_]]
    grounded: Sequence[NDArray[np.bool_]]

    @classmethod
    def of(
        cls,
        envelopes: Sequence[tuple[FloatArray, FloatArray]],
        growths: Sequence[float],
        bodies: Sequence[NDArray[np.bool_]],
        settle_time: float,
        statics: Sequence[StaticBody],
    ) -> Ground:
        """The ground of these envelopes, their growths g_i (m), bodies and static bodies, for a settling of
        ``settle_time`` simulated seconds (class docstring)."""
        sizes = [len(low) for low, _ in envelopes]
        lows = np.concatenate([low for low, _ in envelopes])
        highs = np.concatenate([high for _, high in envelopes])
        owners = np.repeat(np.arange(len(sizes)), sizes)
        flat_bodies = np.concatenate(bodies)
        fall = 0.5 * GRAVITY * settle_time**2
        # The settling is too short for a fall to leave such an object's envelope: no verdict.
        grounded = flat_bodies & np.repeat([fall <= growth for growth in growths], sizes)
        for body in statics:
            grounded |= flat_bodies & may_overlap_static(body, lows, highs, 0.0)
        starts = np.cumsum([0, *sizes])
        always_there = [index for index, present in enumerate(bodies) if len(present) and present.all()]
        frontier = grounded.copy()
        while True:
            while frontier.any():
                waiting = np.flatnonzero(flat_bodies & ~grounded)
                met = _meets_another(waiting, np.flatnonzero(frontier), lows, highs, owners)
                frontier = np.zeros_like(grounded)
                frontier[waiting[met]] = True
                grounded |= frontier
            # Objects that cannot be absent and have no rank grounded keep them all.
            stuck = [index for index in always_there if not grounded[starts[index] : starts[index + 1]].any()]
            if not stuck:
                return cls(tuple(envelopes), tuple(bodies), tuple(np.split(grounded, starts[1:-1])))
            for index in stuck:
                frontier[starts[index] : starts[index + 1]] = True
            grounded |= frontier


class Grounds:
    """The :class:`Ground` of a search's hypotheses, made once per grouping's volumes (the envelopes are its boxes,
    less the grouping's margin, grown by g_i): every group of a grouped search asks for the same one (50
    groups of one object with 20 ranks each made it 50 times over, 1,000 envelopes against each other:
    0.33 s of a 0.47 s search)."""

    def __init__(self, scene: Scene, hypotheses: Sequence[RankedHypotheses], params: SearchParams) -> None:
        self.scene = scene
        self.params = params
        self.growths = tuple(
            stable_growth(object_radius(o.shape), params.jitter_threshold, params.angular_weight) for o in scene.objects
        )
        self.bodies = tuple(np.array([not h.absent for h in ranked.hypotheses]) for ranked in hypotheses)
        self._made: tuple[tuple[FloatArray, ...], Ground] | None = None

    def of(self, grouping: Grouping) -> Ground:
        """The ground of ``grouping``'s boxes (made on the first call for them: a grouping joined after an
        escape has its parent's)."""
        if self._made is None or self._made[0] is not grouping.lows:
            half_margin = self.params.interaction_margin / 2.0  # the grouping's boxes are grown by it
            envelopes = [
                (low + half_margin - growth, high - half_margin + growth)
                for low, high, growth in zip(grouping.lows, grouping.highs, self.growths, strict=True)
            ]
            ground = Ground.of(envelopes, self.growths, self.bodies, self.params.settle_time, self.scene.static)
            self._made = (grouping.lows, ground)
        return self._made[1]


@dataclass(frozen=True)
class FreeFall:
    """Rule 2's pass over one group (module docstring): its objects' scene indices by position, the
    :class:`Ground` of the scene, and the store that learns the conflicts. A rank that is not grounded is
    ruled out in free fall: a detection in the air, or two beside each other, with nothing below them that
    rests on anything."""

    objects: Sequence[int]
    ground: Ground
    store: ConflictStore

    def run(self) -> list[Ruling]:
        """Learn every rank in free fall; why each, in position order."""
        ground = self.ground
        rulings = []
        for position, index in enumerate(self.objects):
            low, high = ground.envelopes[index]
            for rank in (int(k) + 1 for k in np.nonzero(ground.bodies[index] & ~ground.grounded[index])[0]):
                corner_low, corner_high = low[rank - 1], high[rank - 1]
                region: Region = (
                    (float(corner_low[0]), float(corner_low[1]), float(corner_low[2])),
                    (float(corner_high[0]), float(corner_high[1]), float(corner_high[2])),
                )
                if self.store.learn(Conflict(((position, rank),), "unstable", region)):
                    rulings.append(Ruling(position, rank, -1, 0.0, floating=True))
        return rulings


def _meets_another(
    boxes: NDArray[np.intp], others: NDArray[np.intp], lows: FloatArray, highs: FloatArray, owners: NDArray[np.intp]
) -> NDArray[np.bool_]:
    """Per box of ``boxes`` (indices into the corners ``lows``, ``highs``: K x 3, m), whether it meets a box of
    ``others`` that another object ``owners`` (one per box) owns. In slices of at most
    :data:`PAIRS_AT_ONCE` pairs: a few hundred thousand ranks (detections of 1,000 results) stay in memory."""
    rows = max(1, PAIRS_AT_ONCE // max(1, len(others)))
    met = np.zeros(len(boxes), dtype=bool)
    for start in range(0, len(boxes), rows):
        some = boxes[start : start + rows]
        pairs = meets_boxes(lows[some], highs[some], lows[others], highs[others])
        pairs &= owners[some][:, None] != owners[others][None, :]
        met[start : start + rows] = pairs.any(axis=1)
    return met


def _box_overlaps(
    lows: Sequence[FloatArray], highs: Sequence[FloatArray], threshold: float
) -> dict[tuple[int, int], FloatArray] | None:
    """For each ordered pair of positions (p, q) whose boxes can overlap deeper than ``threshold``: the
    M_p x M_q matrix of their ranks' boxes' overlap (m), the least along the three axes, an upper
    bound of the bodies' overlap depth (None: more than :data:`BOX_PAIR_LIMIT` box pairs)."""
    low = np.array([box.min(axis=0) for box in lows])
    high = np.array([box.max(axis=0) for box in highs])
    whole = _least_overlap(low, high, low, high)
    pairs = [(int(p), int(q)) for p, q in zip(*np.nonzero(np.triu(whole > threshold, k=1)), strict=True)]
    if sum(len(lows[p]) * len(lows[q]) for p, q in pairs) > BOX_PAIR_LIMIT:
        return None
    overlaps: dict[tuple[int, int], FloatArray] = {}
    for p, q in pairs:
        overlap = _least_overlap(lows[p], highs[p], lows[q], highs[q])
        if np.any(overlap > threshold):
            overlaps[(p, q)], overlaps[(q, p)] = overlap, overlap.T
    return overlaps


def _least_overlap(low_a: FloatArray, high_a: FloatArray, low_b: FloatArray, high_b: FloatArray) -> FloatArray:
    """A x B: how far box a of the first set and box b of the second overlap (m), the least along the
    axes (negative: apart)."""
    extent = np.minimum(high_a[:, None, :], high_b[None, :, :]) - np.maximum(low_a[:, None, :], low_b[None, :, :])
    return np.asarray(extent.min(axis=2))

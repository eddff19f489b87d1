"""Interaction groups: which objects can influence each other's Rule 1 and Rule 2 outcomes.

The rule. Object i's *volume* is the union, over its hypotheses h, of the box of its body at h
(:func:`~physics_mapper.model.extents.body_box`: the smallest axis-aligned box holding the posed
shape: a rotated box, a tilted cylinder, a mesh's rotated points) grown by m / 2 on every side, m being
the search's ``interaction_margin`` in metres. Two objects *interact* when a box of one overlaps a box
of the other (closed boxes: touching counts), i.e. when two of their hypotheses' bodies come within m
of each other; the *groups* are the connected components of that relation. Static bodies belong to
no group: every group is checked with all of them. Each box lies inside the cube of half-edge r + m / 2
around h's position (r the shape's bounding radius), so groups are never coarser than with cubes.

Why it holds. At any of its hypotheses an object's body lies inside its box, so bodies of different
groups never overlap, whatever hypotheses are chosen: Rule 1 outcomes factorise. During a settling an
object whose body stays inside its grown box cannot touch an object of another group either, and the
groups' Rule 2 outcomes are those of separate simulations: a scene is valid iff every group is, and J
is the sum of the groups' J. Settling can move objects further (a ball rolls off a slope, a top cube
falls off its pile), which the *escape guard* catches: a settling tracks the box its body swept
(:attr:`~physics_mapper.physics.settling.Settling.extent`), and if that box meets another group's
volume (:meth:`Grouping.intruded`), the groups concerned are merged and searched again as one.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.extents import body_box, meets_box, meets_boxes
from physics_mapper.model.geometry import Vector3
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene


class Grouping:
    """A partition of a scene's objects into interaction groups, and the volumes it was built from.

    ``groups`` hold scene object indices, each group sorted, groups ordered by their first object.
    ``lows[i]`` and ``highs[i]`` (M_i x 3, metres) are the corners of object i's boxes, one per
    hypothesis in rank order, grown by half the margin.
    """

    def __init__(
        self,
        groups: tuple[tuple[int, ...], ...],
        lows: tuple[NDArray[np.float64], ...],
        highs: tuple[NDArray[np.float64], ...],
    ) -> None:
        self.groups = groups
        self.lows = lows
        self.highs = highs
        self._group_of = {index: g for g, members in enumerate(groups) for index in members}
        # Every box of every object, flattened, and the group each belongs to.
        sizes = [len(low) for low in lows]
        self._all_lows = np.concatenate(lows)
        self._all_highs = np.concatenate(highs)
        self._all_groups = np.repeat([self._group_of[i] for i in range(len(sizes))], sizes)

    def joined(self, objects: Iterable[int]) -> Grouping:
        """This grouping with the groups holding ``objects`` joined into one: what :func:`interaction_groups`
        gives with those objects linked as well (the volumes are the same; nothing is measured again)."""
        touched = {self._group_of[index] for index in objects}
        kept = [members for g, members in enumerate(self.groups) if g not in touched]
        merged = tuple(sorted(index for g in touched for index in self.groups[g]))
        return Grouping(tuple(sorted([*kept, merged])), self.lows, self.highs)

    def group_of(self, index: int) -> int:
        """The position in :attr:`groups` of the group holding object ``index``."""
        return self._group_of[index]

    def inside(self, index: int, rank: int, low: Vector3, high: Vector3) -> bool:
        """Whether the box [``low``, ``high``] (metres) lies in object ``index``'s volume box at ``rank``."""
        own_low, own_high = self.lows[index][rank - 1], self.highs[index][rank - 1]
        return bool(np.all(own_low <= np.asarray(low)) and np.all(np.asarray(high) <= own_high))

    def intruded(self, index: int, low: Vector3, high: Vector3) -> tuple[int, ...]:
        """Groups other than object ``index``'s whose volume the box [``low``, ``high``] (metres) meets."""
        reach_low, reach_high = np.asarray(low), np.asarray(high)
        met = meets_box(self._all_lows, self._all_highs, reach_low, reach_high)
        groups = {int(g) for g in self._all_groups[met]} - {self.group_of(index)}
        return tuple(sorted(groups))


#: Pairs of boxes compared at once: the comparison's arrays stay within a few MB, however many hypotheses.
PAIRS_PER_CHUNK = 1 << 18


def _boxes_meet(
    lows_a: NDArray[np.float64], highs_a: NDArray[np.float64], lows_b: NDArray[np.float64], highs_b: NDArray[np.float64]
) -> bool:
    """Whether some box of one set overlaps some box of the other (closed boxes).

    Only b's boxes that meet the box around all of a's can meet one of them; those are compared in
    chunks of :data:`PAIRS_PER_CHUNK` pairs. A search's sets are capped before this
    (:data:`~physics_mapper.model.limits.MAX_SEARCHED_HYPOTHESES`), which bounds the time.
    """
    near = meets_box(lows_b, highs_b, lows_a.min(axis=0), highs_a.max(axis=0))
    lows_b, highs_b = lows_b[near], highs_b[near]
    if len(lows_b) == 0:
        return False
    rows = max(1, PAIRS_PER_CHUNK // len(lows_b))
    for start in range(0, len(lows_a), rows):
        if np.any(meets_boxes(lows_a[start : start + rows], highs_a[start : start + rows], lows_b, highs_b)):
            return True
    return False


def volumes(
    scene: Scene, hypotheses: Sequence[RankedHypotheses], margin: float
) -> tuple[tuple[NDArray[np.float64], ...], tuple[NDArray[np.float64], ...]]:
    """Per object, the low and high corners (M x 3, metres) of its hypotheses' body boxes grown by ``margin`` / 2."""
    lows, highs = [], []
    for model, ranked in zip(scene.objects, hypotheses, strict=True):
        boxes = [body_box(model.shape, h.pose) for h in ranked.hypotheses]
        lows.append(np.array([low for low, _ in boxes]) - margin / 2.0)
        highs.append(np.array([high for _, high in boxes]) + margin / 2.0)
    return tuple(lows), tuple(highs)


def interaction_groups(
    scene: Scene, hypotheses: Sequence[RankedHypotheses], margin: float, linked: Iterable[Iterable[int]] = ()
) -> Grouping:
    """Partition the scene's objects into interaction groups (module docstring), ``margin`` in metres.

    ``linked`` are sets of objects that must share a group whatever their volumes say (groups the
    escape guard merged).
    """
    if len(hypotheses) != len(scene.objects):
        raise ValueError(f"{len(hypotheses)} hypothesis sets for {len(scene.objects)} objects")
    lows, highs = volumes(scene, hypotheses, margin)
    count = len(lows)
    parent = list(range(count))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def join(i: int, j: int) -> None:
        parent[max(root(i), root(j))] = min(root(i), root(j))

    # Each object's whole volume in one box first: only objects whose boxes overlap can interact.
    low = np.array([box.min(axis=0) for box in lows])
    high = np.array([box.max(axis=0) for box in highs])
    near = meets_boxes(low, high, low, high)
    for i, j in zip(*np.nonzero(np.triu(near, k=1)), strict=True):
        if root(i) != root(j) and _boxes_meet(lows[i], highs[i], lows[j], highs[j]):
            join(int(i), int(j))
    for members in linked:
        first, *rest = members
        for other in rest:
            join(first, other)
    components: dict[int, list[int]] = {}
    for i in range(count):
        components.setdefault(root(i), []).append(i)
    groups = tuple(sorted(tuple(members) for members in components.values()))
    return Grouping(groups, lows, highs)

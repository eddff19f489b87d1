"""Interaction groups: which objects can influence each other's Rule 1 and Rule 2 outcomes.

The rule. Object i's *volume* is the union, over its hypotheses h, of the axis-aligned cube centred on
h's position with half-edge

    a_i = r_i + m,

where r_i is the bounding radius of the object's shape (:func:`~physics_mapper.model.scene.bounding_radius`:
the body lies in the ball of that radius around its pose's origin, whatever its orientation; for a
mesh, around its file's origin) and m is the search's
``interaction_margin`` in metres. Two objects *interact* when a cube of one overlaps a cube of the
other (closed cubes: touching counts); the *groups* are the connected components of that relation.
Static bodies belong to no group: every group is checked with all of them.

Why it holds. At any of its hypotheses an object's body lies inside its cube, so bodies of different
groups never overlap, whatever hypotheses are chosen: Rule 1 outcomes factorise. During a settling an
object that moves less than m stays inside its cube, so it cannot touch an object of another group
either, and the groups' Rule 2 outcomes are those of separate simulations: a scene is valid iff every
group is, and J is the sum of the groups' J. Settling can move objects further (a ball rolls off a
slope, a top cube falls off its pile), which the *escape guard* catches: a settling tracks where each
object went (:attr:`~physics_mapper.physics.checker.Settling.reach`), and if the object's body there can
reach another group's volume (:meth:`Grouping.intruded`), the groups concerned are merged and
searched again as one.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.geometry import Vector3
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene, object_radius


class Grouping:
    """A partition of a scene's objects into interaction groups, and the volumes it was built from.

    ``groups`` hold scene object indices, each group sorted, groups ordered by their first object.
    ``centres[i]`` (M_i x 3, metres) are object i's hypothesis positions and ``half_edges[i]`` its
    cubes' half-edge a_i = r_i + margin; ``radii[i]`` is r_i.
    """

    def __init__(
        self,
        groups: tuple[tuple[int, ...], ...],
        centres: tuple[NDArray[np.float64], ...],
        half_edges: tuple[float, ...],
        radii: tuple[float, ...],
    ) -> None:
        self.groups = groups
        self.centres = centres
        self.half_edges = half_edges
        self.radii = radii
        self._group_of = {index: g for g, members in enumerate(groups) for index in members}
        # Every cube of every object, flattened: centres, half-edges and the group each belongs to.
        sizes = [len(c) for c in centres]
        self._all_centres = np.concatenate(centres)
        self._all_halves = np.repeat(half_edges, sizes)[:, None]
        self._all_groups = np.repeat([self._group_of[i] for i in range(len(sizes))], sizes)

    def group_of(self, index: int) -> int:
        """The position in :attr:`groups` of the group holding object ``index``."""
        return self._group_of[index]

    def intruded(self, index: int, low: Vector3, high: Vector3) -> tuple[int, ...]:
        """Groups other than object ``index``'s whose volume the object's body can reach from the
        positions in the box [``low``, ``high``] (metres): the box grown by r_index overlaps one of their cubes.
        """
        radius = self.radii[index]
        reach_low = np.asarray(low) - radius
        reach_high = np.asarray(high) + radius
        centres, halves = self._all_centres, self._all_halves
        met = np.all((centres - halves <= reach_high) & (centres + halves >= reach_low), axis=1)
        groups = {int(g) for g in self._all_groups[met]} - {self.group_of(index)}
        return tuple(sorted(groups))


#: Pairs of cubes compared at once: the comparison's arrays stay within a few MB, however many hypotheses.
PAIRS_PER_CHUNK = 1 << 18


def _cubes_meet(centres_a: NDArray[np.float64], half_a: float, centres_b: NDArray[np.float64], half_b: float) -> bool:
    """Whether some cube of one set overlaps some cube of the other (closed cubes).

    Compared in chunks of :data:`PAIRS_PER_CHUNK` pairs; a search's sets are capped before this
    (:data:`~physics_mapper.model.limits.MAX_SEARCHED_HYPOTHESES`), which bounds the time.
    """
    reach = half_a + half_b
    # Only cubes of b within reach of a's bounding box can meet one of a's (and the other way round).
    near_b = centres_b[
        np.all((centres_b >= centres_a.min(axis=0) - reach) & (centres_b <= centres_a.max(axis=0) + reach), axis=1)
    ]
    if len(near_b) == 0:
        return False
    rows = max(1, PAIRS_PER_CHUNK // len(near_b))
    for start in range(0, len(centres_a), rows):
        gaps = np.abs(centres_a[start : start + rows, None, :] - near_b[None, :, :])
        if np.any(np.all(gaps <= reach, axis=2)):
            return True
    return False


def interaction_groups(
    scene: Scene, hypotheses: Sequence[RankedHypotheses], margin: float, linked: Iterable[Iterable[int]] = ()
) -> Grouping:
    """Partition the scene's objects into interaction groups (module docstring), ``margin`` in metres.

    ``linked`` are sets of objects that must share a group whatever their volumes say (groups the
    escape guard merged).
    """
    if len(hypotheses) != len(scene.objects):
        raise ValueError(f"{len(hypotheses)} hypothesis sets for {len(scene.objects)} objects")
    radii = tuple(object_radius(model.shape) for model in scene.objects)
    centres = tuple(np.array([h.pose.position for h in ranked.hypotheses], dtype=float) for ranked in hypotheses)
    half_edges = tuple(radius + margin for radius in radii)
    count = len(radii)
    parent = list(range(count))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def join(i: int, j: int) -> None:
        parent[max(root(i), root(j))] = min(root(i), root(j))

    # Each object's whole volume in one box first: only objects whose boxes overlap can interact.
    low = np.array([c.min(axis=0) - a for c, a in zip(centres, half_edges, strict=True)])
    high = np.array([c.max(axis=0) + a for c, a in zip(centres, half_edges, strict=True)])
    near = np.all((low[:, None, :] <= high[None, :, :]) & (high[:, None, :] >= low[None, :, :]), axis=2)
    for i, j in zip(*np.nonzero(np.triu(near, k=1)), strict=True):
        if root(i) != root(j) and _cubes_meet(centres[i], half_edges[i], centres[j], half_edges[j]):
            join(int(i), int(j))
    for members in linked:
        first, *rest = members
        for other in rest:
            join(first, other)
    components: dict[int, list[int]] = {}
    for i in range(count):
        components.setdefault(root(i), []).append(i)
    groups = tuple(sorted(tuple(members) for members in components.values()))
    return Grouping(groups, centres, half_edges, radii)

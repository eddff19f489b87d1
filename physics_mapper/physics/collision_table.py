"""Rule 1 from a pairwise table, filled lazily and reused.

Whether hypothesis a of object i overlaps hypothesis b of object j, or a static body, depends on
those two bodies' poses alone: Bullet computes every pair's contacts from an empty cache. So the
deepest overlap of a configuration is the largest of its pairs' deepest overlaps, and each pair is
worth computing once. The table keeps, in metres,

- per object i and rank a: the deepest overlap of i at a with each static body;
- per pair of objects i < j and ranks a, b: the deepest overlap of i at a with j at b,

(-inf when the bodies have no contact point), in one array per object and per pair of objects,
made when first needed. A configuration whose entries are all known is
decided with no engine call; otherwise one collision pass with the configuration's objects placed
(:meth:`~physics_mapper.physics.checker.PhysicsChecker.contact_depths`) fills all its missing entries
at once. Two objects whose bounding balls are apart cannot overlap and are never looked up.

The depths are those :meth:`~physics_mapper.physics.checker.PhysicsChecker.find_collision` sees, bit for
bit, and the threshold is applied at lookup: the deepest pair beyond ``penetration_threshold`` is
the collision, equal depths resolved as a collision pass does
(:func:`~physics_mapper.physics.collision.deepest_collision`). Entries depend
on hypotheses only, not on search parameters; :meth:`CollisionTable.updated` drops the entries of
objects whose hypotheses changed. At most :data:`TABLE_LIMIT` numbers are kept; beyond, the table
starts over.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import object_radius
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision import Collision, deepest_collision

#: Numbers (8 bytes each) the table holds at most, 16 MB; beyond, it starts over.
TABLE_LIMIT = 2_000_000
#: An entry not computed yet, and a pair of bodies without a contact point.
UNKNOWN = math.nan
NO_CONTACT = -math.inf


class CollisionTable:
    """The pairwise Rule 1 table of one scene's checker and hypotheses (module docstring)."""

    def __init__(self, checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses]) -> None:
        self.checker = checker
        self.hypotheses = tuple(hypotheses)
        self._radii = tuple(object_radius(model.shape) for model in checker.scene.objects)
        # Every hypothesis's position, objects one after another, and where each object's first is.
        self._positions = np.array([h.pose.position for ranked in self.hypotheses for h in ranked.hypotheses])
        self._first_rank = np.cumsum([0, *(len(ranked) for ranked in self.hypotheses[:-1])])
        self._radius_array = np.array(self._radii)
        self._static_count = len(checker.scene.static)
        # Object i -> (M_i, statics + 1): depth against each static body, then 0 once the row is known.
        self._static: dict[int, NDArray[np.float64]] = {}
        # Objects (i, j), i < j -> (M_i, M_j): depth of i at a against j at b.
        self._pairs: dict[tuple[int, int], NDArray[np.float64]] = {}
        self._size = 0  # numbers held by the arrays above
        #: Collision passes run to fill entries (engine calls), over the table's life.
        self.engine_checks = 0

    def __len__(self) -> int:
        """Entries known: object-static rows and object-object pairs of ranks."""
        rows = sum(int(np.count_nonzero(~np.isnan(array[:, -1]))) for array in self._static.values())
        return rows + sum(int(np.count_nonzero(~np.isnan(array))) for array in self._pairs.values())

    def _numbers(self) -> int:
        """Numbers the table holds (kept as arrays are made: summing them per fill showed in profiles)."""
        return self._size

    def updated(self, hypotheses: Sequence[RankedHypotheses]) -> CollisionTable:
        """A table for new ``hypotheses`` that keeps the entries of every object whose hypotheses are unchanged."""
        table = CollisionTable(self.checker, hypotheses)
        same = [old == new for old, new in zip(self.hypotheses, table.hypotheses, strict=True)]
        table._static = {i: array for i, array in self._static.items() if same[i]}
        table._pairs = {(i, j): array for (i, j), array in self._pairs.items() if same[i] and same[j]}
        table._size = sum(array.size for array in (*table._static.values(), *table._pairs.values()))
        table.engine_checks = self.engine_checks
        return table

    def _static_rows(self, i: int) -> NDArray[np.float64]:
        if i not in self._static:
            self._static[i] = np.full((len(self.hypotheses[i]), self._static_count + 1), UNKNOWN)
            self._size += self._static[i].size
        return self._static[i]

    def _pair_table(self, i: int, j: int) -> NDArray[np.float64]:
        if (i, j) not in self._pairs:
            self._pairs[(i, j)] = np.full((len(self.hypotheses[i]), len(self.hypotheses[j])), UNKNOWN)
            self._size += self._pairs[(i, j)].size
        return self._pairs[(i, j)]

    def _near(self, objects: Sequence[int], code: Sequence[int]) -> list[tuple[int, int, int, int]]:
        """The object pairs (i, a, j, b), i < j, of a configuration whose bounding balls meet, in order.

        All pairs at once with numpy (2 ms for 50 objects pair by pair in Python; a ball distance that
        rounds the other way at the boundary changes nothing: balls that just touch hold no overlap)."""
        indices = np.asarray(objects)
        ranks = np.asarray(code)
        positions = self._positions[self._first_rank[indices] + ranks - 1]
        distances = np.linalg.norm(positions[:, None, :] - positions[None, :, :], axis=2)
        radii = self._radius_array[indices]
        meet = np.triu(distances < radii[:, None] + radii[None, :], k=1)
        firsts, seconds = np.nonzero(meet)
        return [
            (objects[f], code[f], objects[s], code[s]) for f, s in zip(firsts.tolist(), seconds.tolist(), strict=True)
        ]

    def find_collision(
        self, objects: Sequence[int], code: Sequence[int], penetration_threshold: float
    ) -> Collision | None:
        """Rule 1 for objects ``objects`` (scene indices, ascending) at ranks ``code``: the deepest
        overlap beyond ``penetration_threshold`` metres, or None (as ``PhysicsChecker.find_collision``)."""
        return deepest_collision(self.depths(objects, code), penetration_threshold, self.checker.body_name)

    def depths(self, objects: Sequence[int], code: Sequence[int]) -> dict[tuple[int, int], float]:
        """Every overlapping body pair's depth (m) of a configuration, pairs named as
        :meth:`~physics_mapper.physics.checker.PhysicsChecker.contact_depths` names them."""
        near = self._near(objects, code)
        rows, pairs = self._entries(objects, code, near)
        if any(math.isnan(row[-1]) for _, row in rows) or any(math.isnan(depth) for _, _, depth in pairs):
            self._fill(objects, code, near)
            rows, pairs = self._entries(objects, code, near)
        object_count = len(self._radii)
        depths = {
            (i, object_count + k): float(depth)
            for i, row in rows
            for k, depth in enumerate(row[:-1])
            if depth != NO_CONTACT
        }
        depths.update({(i, j): float(depth) for i, j, depth in pairs if depth != NO_CONTACT})
        return depths

    def static_depth(self, i: int, a: int) -> float:
        """Object ``i`` at rank ``a``: its deepest overlap (m, -inf: no contact) with any static body,
        filled by a collision pass of that object alone if unknown."""
        row = self._static_rows(i)[a - 1]
        if math.isnan(row[-1]):
            self._fill((i,), (a,), [])
        return float(np.max(row[:-1])) if self._static_count else NO_CONTACT

    def pair_depths(self, i: int, a: int, j: int) -> NDArray[np.float64]:
        """Object ``i`` at rank ``a`` against object ``j`` at each of its ranks: the deepest overlaps (m,
        -inf: no contact), missing entries filled by a collision pass of the two objects alone."""
        return np.array([self.pair_depth(i, a, j, b) for b in range(1, len(self.hypotheses[j]) + 1)])

    def pair_depth(self, i: int, a: int, j: int, b: int) -> float:
        """Object ``i`` at rank ``a`` against object ``j`` at rank ``b``: the deepest overlap (m, -inf: no
        contact), filled by a collision pass of the two objects alone if unknown."""
        low, high = min(i, j), max(i, j)
        entry = (a - 1, b - 1) if i == low else (b - 1, a - 1)
        table = self._pair_table(low, high)
        if math.isnan(table[entry]):
            pose_i, pose_j = self.hypotheses[i].pose(a), self.hypotheses[j].pose(b)
            if math.dist(pose_i.position, pose_j.position) >= self._radii[i] + self._radii[j]:
                table[entry] = NO_CONTACT
            else:
                depths = self.checker.contact_depths((low, high), (pose_i, pose_j) if i == low else (pose_j, pose_i))
                self.engine_checks += 1
                table[entry] = depths.get((low, high), NO_CONTACT)
        return float(table[entry])

    def _entries(
        self, objects: Sequence[int], code: Sequence[int], near: list[tuple[int, int, int, int]]
    ) -> tuple[list[tuple[int, NDArray[np.float64]]], list[tuple[int, int, float]]]:
        """A configuration's table entries: per object its static row, per near pair its depth (NaN: unknown)."""
        rows = [(i, self._static_rows(i)[a - 1]) for i, a in zip(objects, code, strict=True)]
        pairs = [(i, j, float(self._pair_table(i, j)[a - 1, b - 1])) for i, a, j, b in near]
        return rows, pairs

    def _fill(self, objects: Sequence[int], code: Sequence[int], near: list[tuple[int, int, int, int]]) -> None:
        """One collision pass with the configuration placed; store every entry it decides."""
        if self._numbers() > TABLE_LIMIT:
            self._static.clear()
            self._pairs.clear()
            self._size = 0
        poses = [self.hypotheses[i].pose(a) for i, a in zip(objects, code, strict=True)]
        depths = self.checker.contact_depths(objects, poses)
        self.engine_checks += 1
        object_count = len(self._radii)
        for i, a in zip(objects, code, strict=True):
            row = self._static_rows(i)[a - 1]
            row[:] = NO_CONTACT
            row[-1] = 0.0  # known
            for k in range(self._static_count):
                row[k] = depths.get((i, object_count + k), NO_CONTACT)
        for i, a, j, b in near:
            self._pair_table(i, j)[a - 1, b - 1] = depths.get((i, j), NO_CONTACT)

"""Rule 1 parts: whether a candidate's bodies overlap deeper than ``penetration_threshold``.

:class:`FullCollisionPass` places every object and asks the engine (the paper's way, which needs
every object of the scene). :class:`PairwiseTable` looks the overlaps up in the pairwise table
(:mod:`physics_mapper.physics.collision_table`): whether hypothesis a of object i overlaps hypothesis
b of object j, or a static body, depends on those two poses alone, so each depth is computed once
and reused; the deepest overlap beyond the threshold is the same as the full pass's, bit for bit,
and the verdict carries every overlap (a conflict-directed generator learns from them).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from physics_mapper.model.geometry import Pose
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision import deepest_collision
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.search.best_first import Rule1Verdict
from physics_mapper.search.results import Code


class FullCollisionPass:
    """Rule 1 by one collision pass of every object of the scene."""

    def __init__(self, checker: PhysicsChecker, penetration_threshold: float) -> None:
        self.checker = checker
        self.threshold = penetration_threshold

    def check(self, code: Code, poses: tuple[Pose, ...]) -> Rule1Verdict:
        return Rule1Verdict(self.checker.find_collision(poses, self.threshold), None)


class PairwiseTable:
    """Rule 1 of ``objects`` (scene indices, ascending) from the pairwise table ``table()`` gives.

    ``table`` is asked at each check: a grouped search that adopts the group hands it its own table.
    """

    def __init__(
        self,
        checker: PhysicsChecker,
        objects: Sequence[int],
        penetration_threshold: float,
        table: Callable[[], CollisionTable],
    ) -> None:
        self.checker = checker
        self.objects = tuple(objects)
        self.threshold = penetration_threshold
        self.table = table

    def check(self, code: Code, poses: tuple[Pose, ...]) -> Rule1Verdict:
        depths = self.table().depths(self.objects, code)
        return Rule1Verdict(deepest_collision(depths, self.threshold, self.checker.body_name), depths)

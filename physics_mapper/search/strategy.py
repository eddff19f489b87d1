"""The strategies as compositions of parts, in one table, and the one entry point.

Every search is the best-first core (:class:`~physics_mapper.search.best_first.BestFirst`) with parts
passed in: a candidate generator, a Rule 1 check, a Rule 2 policy, under a group scheduler.
:data:`STRATEGIES` lists how each ``strategy:`` is composed:

- ``joint``: the paper's queue, the full collision pass, full settling; one core over every object;
- ``grouped``: per interaction group, the paper's queue, the pairwise table, memoised settling;
- ``conflict`` (the default): per interaction group, conflict-free generation learning from each
  rejection, the pairwise table, trial, local and confirming settlings (memoised); what the previous
  search learned is carried over.

:func:`make_search` builds (or carries over) a search; :func:`solve` runs a fresh one to its
deadline. Every caller goes through them, so ``strategy: conflict|grouped|joint`` means the same
everywhere.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Generic, Protocol, cast

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.limits import MAX_SEARCHED_HYPOTHESES
from physics_mapper.model.scene import SearchParams, Strategy
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.physics.refine import load_solver
from physics_mapper.search.best_first import BestFirst, Bound, G, R, Rule1Check, Search, Trace, resumable, weight_table
from physics_mapper.search.conflict_directed import ConflictCarryOver, ConflictDirectedCandidates, ConflictGroup
from physics_mapper.search.conflicts import Blame, Clearance
from physics_mapper.search.grouped import CarryOver, GroupBuilder, GroupedSearch, GroupSpec, NothingCarried
from physics_mapper.search.local_settling import LocalSettling
from physics_mapper.search.paper_queue import PaperQueue
from physics_mapper.search.results import SearchResult
from physics_mapper.search.rule1 import FullCollisionPass, PairwiseTable
from physics_mapper.search.rule2 import FullSettling, MemoisedSettling, solver_residual
from physics_mapper.search.trial_settling import TrialSettling


def paper_search(
    checker: PhysicsChecker,
    hypotheses: Sequence[RankedHypotheses],
    params: SearchParams,
    objects: Sequence[int] | None = None,
    table: CollisionTable | None = None,
) -> BestFirst[PaperQueue, FullSettling]:
    """Algorithm 1 over ``objects`` (default: every object): the paper's queue and full settling, Rule 1 by
    the full collision pass, or from ``table`` (which a search over some objects only needs)."""
    objects = checker.all_objects if objects is None else tuple(objects)
    rule1: Rule1Check
    if table is not None:
        rule1 = PairwiseTable(checker, objects, params.penetration_threshold, lambda: table)
    elif objects == checker.all_objects:
        rule1 = FullCollisionPass(checker, params.penetration_threshold)
    else:
        raise ValueError("a search over some objects only needs a pairwise collision table")
    return BestFirst(
        checker,
        hypotheses,
        params,
        objects,
        candidates=PaperQueue(hypotheses, params.queue_limit),
        rule1=rule1,
        rule2=FullSettling(checker, objects, params),
        bound=Bound.of(params, weight_table(hypotheses)),
        trace=Trace(params.trace_limit),
    )


def paper_group(spec: GroupSpec) -> BestFirst[PaperQueue, MemoisedSettling]:
    """Algorithm 1 on one interaction group: the paper's queue, the pairwise table, memoised settling."""
    hypotheses = tuple(spec.hypotheses[i] for i in spec.objects)
    settling = FullSettling(spec.checker, spec.objects, spec.params, track_reach=True, observers=[spec.guard.settled])
    bound = Bound.of(spec.params, weight_table(hypotheses))
    return _group_core(
        spec, PaperQueue(hypotheses, spec.params.queue_limit), MemoisedSettling(spec.memo, settling), bound
    )


def conflict_group(spec: GroupSpec) -> ConflictGroup:
    """One interaction group searched conflict-directed: conflict-free generation, the pairwise table,
    trial and local settlings confirmed by memoised full ones (their early exits also stop a far-off
    object still moving; their solver ends early in groups without meshes, :func:`solver_residual`)."""
    checker, params, objects, guard, link = spec.checker, spec.params, spec.objects, spec.guard, spec.link
    hypotheses = tuple(spec.hypotheses[i] for i in objects)
    shapes = [checker.scene.objects[i].shape for i in objects]
    blame = Blame(shapes, hypotheses, params, clearance=_clearance_in(checker, objects))
    bound = Bound.of(params, weight_table(hypotheses))
    candidates = ConflictDirectedCandidates(
        checker,
        objects,
        spec.hypotheses,
        params,
        link.grouping,
        link.collision_table,
        link.ground,
        blame,
        bound,
        spec.trace_group,
    )
    residual = solver_residual(checker.scene, objects)
    settling = FullSettling(
        checker, objects, params, moving=True, track_reach=True, observers=[guard.settled], solver_residual=residual
    )
    confirm = MemoisedSettling(spec.memo, settling)
    rule2 = TrialSettling(checker, objects, params, LocalSettling(blame), confirm, observers=[guard.settled])
    return _group_core(spec, candidates, rule2, bound)


def _clearance_in(checker: PhysicsChecker, objects: Sequence[int]) -> Clearance:
    """The checker's clearance between two objects given by their positions in a group of ``objects``."""

    def clearance(first: int, first_pose: Pose, second: int, second_pose: Pose, cap: float) -> float:
        return checker.clearance(objects[first], first_pose, objects[second], second_pose, cap)

    return clearance


def _group_core(spec: GroupSpec, candidates: G, rule2: R, bound: Bound) -> BestFirst[G, R]:
    """A group's core with ``candidates`` and ``rule2``: Rule 1 from the grouped search's pairwise table, its
    trace entries to the grouped search's trace, its refined map guarded against escapes."""
    return BestFirst(
        spec.checker,
        tuple(spec.hypotheses[i] for i in spec.objects),
        spec.params,
        spec.objects,
        candidates=candidates,
        rule1=PairwiseTable(spec.checker, spec.objects, spec.params.penetration_threshold, spec.link.collision_table),
        rule2=rule2,
        bound=bound,
        trace=spec.link,
        trace_group=spec.trace_group,
        on_refined=[spec.guard.refined],
    )


#: The hypotheses a search is for, one set per object of the scene.
Searched = tuple[RankedHypotheses, ...]


class Composition(Protocol):
    """How one strategy is built: a search for ``hypotheses``, carrying over what ``previous`` found that
    still holds (``previous`` itself, resumed, when nothing but the deadline or the fallback changed)."""

    def make(
        self, checker: PhysicsChecker, hypotheses: Searched, params: SearchParams, previous: Search | None
    ) -> Search: ...


class Joint:
    """One core over every object, the paper's parts (:func:`paper_search`)."""

    def make(
        self, checker: PhysicsChecker, hypotheses: Searched, params: SearchParams, previous: Search | None
    ) -> Search:
        if isinstance(previous, BestFirst) and resumable(previous, checker, hypotheses, params):
            previous.params = params
            return previous
        return paper_search(checker, hypotheses, params)


@dataclass(frozen=True)
class Grouped(Generic[G, R]):
    """Interaction groups under one deadline (:class:`GroupedSearch`), each group's core made by
    ``build``, what earlier groups learned kept by ``carry_over``."""

    build: GroupBuilder[G, R]
    carry_over: CarryOver[G, R]

    def make(
        self, checker: PhysicsChecker, hypotheses: Searched, params: SearchParams, previous: Search | None
    ) -> Search:
        # A grouped search of another composition searches its groups otherwise: nothing of it is kept.
        same = isinstance(previous, GroupedSearch) and previous.build is self.build
        earlier = cast(GroupedSearch[G, R], previous) if same else None
        return GroupedSearch.following(checker, hypotheses, params, self.build, self.carry_over, earlier)


#: Every ``strategy:``, as the parts it is composed of (module docstring).
STRATEGIES: dict[Strategy, Composition] = {
    "joint": Joint(),
    "grouped": Grouped(paper_group, NothingCarried()),
    "conflict": Grouped(conflict_group, ConflictCarryOver()),
}


def make_search(
    checker: PhysicsChecker,
    hypotheses: Sequence[RankedHypotheses],
    params: SearchParams,
    previous: Search | None = None,
) -> Search:
    """The search ``params.strategy`` asks for (:data:`STRATEGIES`), carrying over what ``previous`` found
    that still holds. With the same hypotheses and parameters that only change the deadline or the
    fallback, ``previous`` itself is returned, to be resumed; a grouped search also keeps every group
    whose objects' hypotheses are unchanged.
    """
    hypotheses = searchable(hypotheses)
    if params.fallback == "refine":
        load_solver()  # before the deadline starts (once per process)
    return STRATEGIES[params.strategy].make(checker, hypotheses, params, previous)


def searchable(hypotheses: Sequence[RankedHypotheses]) -> tuple[RankedHypotheses, ...]:
    """Each object's heaviest :data:`~physics_mapper.model.limits.MAX_SEARCHED_HYPOTHESES`, the hypotheses
    a search ranks: bounded before any pairwise step (grouping, the collision table), whatever the caller
    passed."""
    return tuple(ranked.heaviest(MAX_SEARCHED_HYPOTHESES) for ranked in hypotheses)


def solve(checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], params: SearchParams) -> SearchResult:
    """Run a fresh search until ``params.deadline`` seconds have passed or the queue empties."""
    return make_search(checker, hypotheses, params).run(params.deadline)

"""The search ``strategy`` asks for: conflict-directed per interaction group, the paper's per group, or joint.

:func:`make_search` builds (or carries over) a search; :func:`solve` runs a fresh one to its
deadline. Every caller goes through them, so ``strategy: conflict|grouped|joint`` means the same
everywhere.
"""

from __future__ import annotations

from collections.abc import Sequence

from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.limits import MAX_SEARCHED_HYPOTHESES
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.refine import load_solver
from physics_mapper.search.branch_and_bound import BranchAndBound, Search, resumable
from physics_mapper.search.conflict_directed import ConflictSearch
from physics_mapper.search.grouped import GroupedSearch
from physics_mapper.search.results import SearchResult


def make_search(
    checker: PhysicsChecker,
    hypotheses: Sequence[RankedHypotheses],
    params: SearchParams,
    previous: Search | None = None,
) -> BranchAndBound | GroupedSearch:
    """The search ``params.strategy`` asks for, carrying over what ``previous`` found that still holds.

    ``joint``: the paper's single search (:class:`BranchAndBound`); ``grouped``: the paper's search per
    interaction group (:class:`~physics_mapper.search.grouped.GroupedSearch`); ``conflict``: per group,
    conflict-directed (:class:`~physics_mapper.search.conflict_directed.ConflictSearch`). With the same hypotheses and
    parameters that only change the deadline or the fallback, ``previous`` itself is returned, to be
    resumed; a grouped search also keeps every group whose objects' hypotheses are unchanged.
    """
    hypotheses = searchable(hypotheses)
    if params.fallback == "refine":
        load_solver()  # before the deadline starts (once per process)
    if params.strategy == "joint":
        if type(previous) is BranchAndBound and resumable(previous, checker, hypotheses, params):
            previous.params = params
            return previous
        return BranchAndBound(checker, hypotheses, params)
    if params.strategy == "grouped":
        return GroupedSearch.following(checker, hypotheses, params, previous)
    return ConflictSearch.following(checker, hypotheses, params, previous)


def searchable(hypotheses: Sequence[RankedHypotheses]) -> tuple[RankedHypotheses, ...]:
    """Each object's heaviest :data:`~physics_mapper.model.limits.MAX_SEARCHED_HYPOTHESES`, the hypotheses
    a search ranks: bounded before any pairwise step (grouping, the collision table), whatever the caller
    passed."""
    return tuple(ranked.heaviest(MAX_SEARCHED_HYPOTHESES) for ranked in hypotheses)


def solve(checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], params: SearchParams) -> SearchResult:
    """Run a fresh search until ``params.deadline`` seconds have passed or the queue empties."""
    return make_search(checker, hypotheses, params).run(params.deadline)

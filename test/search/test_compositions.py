"""Every search is the one best-first core with parts passed in; the strategies are compositions of parts.

Each ``strategy:`` is built in one place (``physics_mapper.search.strategy.STRATEGIES``) from the parts
``docs/search.md`` lists, the core is never subclassed, and a composition no strategy uses runs from
parts alone, without a new class, with the joint search's answers on the shipped paper problems.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any, get_args

import pytest
from conftest import REPO

from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import SearchParams, Strategy
from physics_mapper.model.scene_files import load_problem
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.search.best_first import BestFirst, Bound, Trace, weight_table
from physics_mapper.search.conflict_directed import ConflictDirectedCandidates
from physics_mapper.search.conflicts import Blame
from physics_mapper.search.grouped import GroupedSearch
from physics_mapper.search.groups import interaction_groups
from physics_mapper.search.paper_queue import PaperQueue
from physics_mapper.search.results import SearchResult
from physics_mapper.search.rule1 import FullCollisionPass, PairwiseTable
from physics_mapper.search.rule2 import FullSettling, MemoisedSettling
from physics_mapper.search.ruling_out import Grounds
from physics_mapper.search.strategy import STRATEGIES, make_search, paper_search
from physics_mapper.search.trial_settling import TrialSettling

PAPER_PROBLEMS = ("stack", "pyramid", "peg_in_hole", "sphere_groove")
#: A core composed in a test from parts (of whatever kinds).
Composed = BestFirst[Any, Any]


def decisions(result: SearchResult) -> list[tuple[object, ...]]:
    return [(e.code, e.outcome, e.bounded, e.pair, e.moved, e.parent) for e in result.trace]


def test_each_strategy_is_one_composition_of_parts_in_one_table() -> None:
    assert set(STRATEGIES) == set(get_args(Strategy)) == {"joint", "grouped", "conflict"}
    assert BestFirst.__subclasses__() == []  # variants are parts, never subclasses of the core
    loaded = load_problem(REPO / "config" / "problems" / "pyramid.yaml", lambda _: None)
    parts = {}
    with PhysicsChecker(loaded.scene) as checker:
        for strategy in STRATEGIES:
            search = make_search(checker, loaded.hypotheses, replace(loaded.scene.search, strategy=strategy))
            assert isinstance(search, GroupedSearch) == (strategy != "joint")
            cores = search.groups() if isinstance(search, GroupedSearch) else [search]
            assert all(type(core) is BestFirst for core in cores)
            parts[strategy] = {
                (type(core.candidates), type(core.rule1), type(core.rule2))
                for core in cores
                if isinstance(core, BestFirst)
            }
    assert parts == {
        "joint": {(PaperQueue, FullCollisionPass, FullSettling)},
        "grouped": {(PaperQueue, PairwiseTable, MemoisedSettling)},
        "conflict": {(ConflictDirectedCandidates, PairwiseTable, TrialSettling)},
    }


#: Makes a core over every object from its parts, given the checker, hypotheses, parameters and a pairwise table.
CoreMaker = Callable[[PhysicsChecker, tuple[RankedHypotheses, ...], SearchParams, CollisionTable], Composed]


def with_joint(problem: str, make: CoreMaker) -> tuple[SearchResult, SearchResult]:
    """The paper problem searched to its end by the core ``make`` composes, and by the joint search."""
    loaded = load_problem(REPO / "config" / "problems" / f"{problem}.yaml", lambda _: None)
    scene, hypotheses = loaded.scene, loaded.hypotheses
    params = replace(scene.search, trace_limit=None)
    with PhysicsChecker(scene) as checker:
        joint = paper_search(checker, hypotheses, params).run(None)
        return make(checker, hypotheses, params, CollisionTable(checker, hypotheses)).run(None), joint


def table_and_full_settling(
    checker: PhysicsChecker, hypotheses: tuple[RankedHypotheses, ...], params: SearchParams, table: CollisionTable
) -> Composed:
    objects = checker.all_objects
    queue = PaperQueue(hypotheses, params.queue_limit)
    from_table = PairwiseTable(checker, objects, params.penetration_threshold, lambda: table)
    bound = Bound.of(params, weight_table(hypotheses))
    return BestFirst(
        checker,
        hypotheses,
        params,
        objects,
        candidates=queue,
        rule1=from_table,
        rule2=FullSettling(checker, objects, params),
        bound=bound,
        trace=Trace(params.trace_limit),
    )


def conflict_free_and_full_pass(
    checker: PhysicsChecker, hypotheses: tuple[RankedHypotheses, ...], params: SearchParams, table: CollisionTable
) -> Composed:
    objects, scene = checker.all_objects, checker.scene
    bound = Bound.of(params, weight_table(hypotheses))
    blame = Blame([o.shape for o in scene.objects], hypotheses, params)
    grouping = interaction_groups(scene, hypotheses, params.interaction_margin)
    ground = Grounds(scene, hypotheses, params).of(grouping)
    return BestFirst(
        checker,
        hypotheses,
        params,
        objects,
        candidates=ConflictDirectedCandidates(
            checker, objects, hypotheses, params, grouping, lambda: table, lambda: ground, blame, bound, None
        ),
        rule1=FullCollisionPass(checker, params.penetration_threshold),
        rule2=FullSettling(checker, objects, params),
        bound=bound,
        trace=Trace(params.trace_limit),
    )


@pytest.mark.parametrize("problem", PAPER_PROBLEMS)
def test_the_pairwise_table_with_full_settling_gives_the_joint_trace(problem: str) -> None:
    """The paper's queue and full settling with Rule 1 from the pairwise table: no strategy's parts, the
    joint search's trace node for node (the table decides Rule 1 as the full pass does)."""
    result, joint = with_joint(problem, table_and_full_settling)
    assert decisions(result) == decisions(joint) and len(result.trace) == joint.stats.visited
    assert (result.valid, result.code, result.stats.end) == (joint.valid, joint.code, joint.stats.end)
    assert result.stats.settle_steps == joint.stats.settle_steps  # the same settlings, counted by the part


@pytest.mark.parametrize("problem", PAPER_PROBLEMS)
def test_conflict_free_generation_with_the_full_collision_pass_gives_the_joint_answer(problem: str) -> None:
    """Conflict-free generation with the full collision pass and full settling, over every object: the
    joint search's answer, found checking only configurations the joint search checks, the same valid
    ones among them (no valid configuration holds a conflict)."""
    result, joint = with_joint(problem, conflict_free_and_full_pass)
    assert (result.valid, result.code) == (joint.valid, joint.code)
    checked = {entry.code: entry.outcome for entry in result.trace}
    paper = {entry.code: entry.outcome for entry in joint.trace}
    assert checked.items() <= paper.items()
    assert {c for c, o in checked.items() if o == "valid"} == {c for c, o in paper.items() if o == "valid"}
    rejected = [entry for entry in result.trace if entry.outcome != "valid"]
    assert all(entry.conflict for entry in rejected)  # learned from the full pass's collisions too
    assert result.stats.part_counters["conflicts"] >= len(rejected)

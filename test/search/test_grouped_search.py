"""The grouped search: Algorithm 1 per interaction group, against the paper's joint search.

Real pybullet throughout. The reduced suite is the benchmark's generator
(``physics_mapper.scenarios.scale_suite``) at small sizes, where the joint search finishes: piles of
cubes whose only valid configuration is known by construction.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import pytest
from conftest import PROBLEMS
from core_builders import ON_FLOOR, cube, far_apart_cubes, floor_hypotheses, floor_scene, ranked, unrotated

from physics_mapper.mapping.inputs import InputSettings
from physics_mapper.mapping.mapper import Mapper, MapperSettings, TickReport
from physics_mapper.model.geometry import pose_displacement
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene, SearchParams
from physics_mapper.model.scene_files import load_problem
from physics_mapper.msg_adapters.diagnostics import search_values
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision import Collision
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.physics.settling import REST_SHARE, PartialSettling
from physics_mapper.scenarios.scale_suite import ScaleCase, ScaleProblem, scale_problem
from physics_mapper.search.grouped import GroupedSearch
from physics_mapper.search.report import result_dict, trace_tree
from physics_mapper.search.results import Code, SearchResult, TraceEntry
from physics_mapper.search.strategy import make_search, paper_search

SHIPPED = ("stack", "pyramid", "peg_in_hole", "sphere_groove")
#: The search this file is about: the paper's per interaction group, bounded relative to each group's root.
GROUPED = SearchParams(strategy="grouped", bound="relative")
REDUCED_SUITE = (
    ScaleCase("singletons", 4, 3, 0),
    ScaleCase("pairs", 4, 3, 1),
    ScaleCase("pyramids", 5, 3, 2),
    ScaleCase("mixed", 6, 3, 3),
    ScaleCase("pyramids", 6, 4, 4),
)


def run_to_end(scene: Scene, hypotheses: tuple[RankedHypotheses, ...], params: SearchParams) -> SearchResult:
    with PhysicsChecker(scene) as checker:
        return make_search(checker, hypotheses, params).run(None)


# --- a scene that is one group is the paper's search -----------------------------------------------


@pytest.mark.parametrize("name", SHIPPED)
def test_paper_problems_give_the_joint_search_s_trace_and_answer_bit_for_bit(name: str) -> None:
    problem = load_problem(PROBLEMS / f"{name}.yaml")
    params = problem.scene.search
    assert params.strategy == "grouped"  # the shipped paper scenes pin it
    with PhysicsChecker(problem.scene) as checker:
        search = make_search(checker, problem.hypotheses, params)
        grouped = search.run(None)
    with PhysicsChecker(problem.scene) as checker:
        joint = make_search(checker, problem.hypotheses, replace(params, strategy="joint")).run(None)
    assert isinstance(search, GroupedSearch) and len(grouped.groups) == 1
    assert grouped.trace == joint.trace  # codes, order, outcomes, evidence and jitters, bit for bit
    assert (grouped.code, grouped.probability, grouped.jitter) == (joint.code, joint.probability, joint.jitter)
    assert (grouped.poses, grouped.settled_poses, grouped.valid) == (joint.poses, joint.settled_poses, joint.valid)


# --- the reduced seeded suite: grouped (early exit) against joint (full settling, the paper's) -------


@dataclass(frozen=True)
class Compared:
    problem: ScaleProblem
    joint: SearchResult
    grouped: SearchResult
    grouped_full: SearchResult


@pytest.fixture(scope="module")
def reduced_suite() -> list[Compared]:
    compared = []
    for case in REDUCED_SUITE:
        problem = scale_problem(case, GROUPED)
        scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
        params = replace(scene.search, trace_limit=None)
        joint = run_to_end(scene, hypotheses, replace(params, strategy="joint", settle_exit="full"))
        grouped = run_to_end(scene, hypotheses, params)
        grouped_full = run_to_end(scene, hypotheses, replace(params, settle_exit="full"))
        compared.append(Compared(problem, joint, grouped, grouped_full))
    return compared


def group_outcomes(result: SearchResult) -> dict[tuple[tuple[int, ...], Code], TraceEntry]:
    """Each visited sub-configuration's trace entry, by (group objects, sub-code)."""
    objects = {group.id: group.objects for group in result.groups}
    return {(objects[entry.group], entry.code): entry for entry in result.trace}


def combined_outcome(code: Code, result: SearchResult) -> str | None:
    """The outcome the grouped search gives a whole configuration (None: a group never visited its part)."""
    visited = group_outcomes(result)
    outcomes = []
    for group in result.groups:
        part = tuple(code[i] for i in group.objects)
        if (group.objects, part) not in visited:
            return None
        outcomes.append(visited[(group.objects, part)].outcome)
    return next((kind for kind in ("collision", "unstable") if kind in outcomes), "valid")


def test_grouped_and_joint_searches_find_the_same_answer(reduced_suite: list[Compared]) -> None:
    for compared in reduced_suite:
        label = compared.problem.case.label
        assert len(compared.grouped.groups) > 1, label  # the suite's piles are separate groups
        for result in (compared.joint, compared.grouped, compared.grouped_full):
            assert result.valid and result.code == compared.problem.answer, label


def test_every_configuration_both_searches_visit_gets_the_same_outcome(reduced_suite: list[Compared]) -> None:
    for compared in reduced_suite:
        both = 0
        for entry in compared.joint.trace:
            for grouped in (compared.grouped, compared.grouped_full):
                outcome = combined_outcome(entry.code, grouped)
                if outcome is not None:
                    both += 1
                    assert outcome == entry.outcome, (compared.problem.case.label, entry.code)
        assert both > 0


def test_early_exit_keeps_every_outcome_and_settles_the_answer_within_tolerance(
    reduced_suite: list[Compared],
) -> None:
    for compared in reduced_suite:
        early, full = compared.grouped, compared.grouped_full
        assert [(e.group, e.code, e.outcome) for e in early.trace] == [(e.group, e.code, e.outcome) for e in full.trace]
        assert early.stats.settle_steps_saved > 0  # how many is a figure (BENCHMARKS.md, "Scale")
        assert full.stats.settle_steps_saved == 0
        assert any(e.settle_stop == "beyond_threshold" for e in early.trace)
        assert all(e.settle_stop is None for e in full.trace)
        assert early.settled_poses is not None and full.settled_poses is not None
        tolerance = REST_SHARE * SearchParams().jitter_threshold
        for a, b in zip(early.settled_poses, full.settled_poses, strict=True):
            assert pose_displacement(a, b, SearchParams().angular_weight) <= tolerance


def test_each_group_is_searched_as_algorithm_1_on_its_own_objects(reduced_suite: list[Compared]) -> None:
    compared = reduced_suite[2]
    scene, hypotheses = compared.problem.problem.scene, compared.problem.problem.hypotheses
    params = replace(scene.search, trace_limit=None)
    with PhysicsChecker(scene) as checker:
        table = CollisionTable(checker, hypotheses)
        for group in compared.grouped.groups:
            alone = paper_search(checker, [hypotheses[i] for i in group.objects], params, group.objects, table)
            own = alone.run(None).trace
            mine = [e for e in compared.grouped.trace if e.group == group.id]
            assert [(e.code, e.outcome, e.jitter, e.parent) for e in mine] == [
                (e.code, e.outcome, e.jitter, e.parent) for e in own
            ]
            # Its own tie rule and order: non-increasing p(C) relative to the group's root.
            assert all(b.probability <= a.probability * (1 + 1e-9) for a, b in itertools.pairwise(mine))


# --- the bound ----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def twenty_cubes() -> ScaleProblem:
    return scale_problem(ScaleCase("singletons", 20, 4, 5), GROUPED)


def test_a_20_object_problem_whose_root_is_below_an_absolute_t_is_searched_with_the_relative_bound(
    twenty_cubes: ScaleProblem,
) -> None:
    scene, hypotheses = twenty_cubes.problem.scene, twenty_cubes.problem.hypotheses
    params = scene.search
    root = math.prod(h.weight(1) for h in hypotheses)
    assert root < params.probability_threshold  # the paper's reading bounds the root itself
    absolute = run_to_end(scene, hypotheses, replace(params, bound="absolute", strategy="joint"))
    assert absolute.stats.visited == 1 and absolute.stats.expanded == 0 and absolute.trace[0].bounded
    assert absolute.stats.end == "bounded" and not absolute.stats.exhausted  # not "exhausted": it stopped at the bound
    assert absolute.code is None

    relative = run_to_end(scene, hypotheses, params)
    assert relative.valid and relative.code == twenty_cubes.answer
    assert len(relative.groups) == 20
    assert relative.stats.end == "exhausted" and relative.stats.exhausted  # 4 hypotheses, all within T of each root
    assert relative.stats.visited == 20 * 4 and relative.stats.bounded == 0


def test_bounded_and_exhausted_are_reported_apart_in_the_json_the_trace_and_the_diagnostics(
    twenty_cubes: ScaleProblem,
) -> None:
    scene, hypotheses = twenty_cubes.problem.scene, twenty_cubes.problem.hypotheses
    # T = 0.5 relative: each cube's lighter hypotheses are checked but not expanded.
    params = replace(scene.search, probability_threshold=0.5)
    result = run_to_end(scene, hypotheses, params)
    bounded_groups = [group for group in result.groups if group.end == "bounded"]
    assert bounded_groups and result.stats.end == "bounded"
    assert any(entry.bounded for entry in result.trace)
    for entry in result.trace:
        root = next(g for g in result.groups if g.id == entry.group)
        root_probability = hypotheses[root.objects[0]].weight(1)
        assert entry.bounded == (entry.probability / root_probability < 0.5)
    data = result_dict(result, scene.object_names)
    assert data["stats"]["end"] == "bounded" and data["stats"]["exhausted"] is False
    assert {group["end"] for group in data["groups"]} >= {"bounded"}

    mapper = Mapper(scene)
    try:
        report = mapper_tick(mapper, hypotheses, params)
    finally:
        mapper.close()
    values = dict(search_values(report))
    assert values["search"].startswith("new, bounded (the queue emptied")
    assert values["groups"] == "20" and values["groups solved"] == "20"


def mapper_tick(mapper: Mapper, hypotheses: tuple[RankedHypotheses, ...], params: SearchParams) -> TickReport:
    """One tick with ``hypotheses`` fed straight into the mapper's inputs."""
    from physics_mapper.mapping.inputs import check_poses, check_weights

    for name, ranked_hypotheses in zip(mapper.scene.object_names, hypotheses, strict=True):
        raw = [(h.pose.position, h.pose.orientation) for h in ranked_hypotheses.hypotheses]
        frame, workspace = mapper.scene.frame_id, mapper.scene.workspace
        checked = check_poses(raw, frame_id=frame, expected_frame=frame, workspace=workspace, stamp_ns=0, received=0)
        mapper.inputs.add_poses(name, checked)
        weights = [h.weight for h in ranked_hypotheses.hypotheses]
        mapper.inputs.add_weights(name, check_weights(weights, received=0.0))
    return mapper.tick(0.0, MapperSettings(replace(params, deadline=10.0), InputSettings(), rate_hz=0.05))


# --- the pairwise table and the settle memo ------------------------------------------------------------


def test_the_pairwise_table_decides_known_pairs_without_the_engine_and_drops_changed_hypotheses() -> None:
    scene = floor_scene(cube("a"), cube("b"))
    touching = [unrotated(0.0, 0.0, ON_FLOOR), unrotated(0.0, 0.0, ON_FLOOR - 0.02), unrotated(0.08, 0.0, ON_FLOOR)]
    hypotheses = (ranked(touching, [3, 2, 1]), ranked([unrotated(0.1, 0.0, ON_FLOOR)], [1]))
    threshold = SearchParams().penetration_threshold
    with PhysicsChecker(scene) as checker:
        table = CollisionTable(checker, hypotheses)

        def decide(code: Code, depth_threshold: float = threshold) -> Collision | None:
            return table.find_collision((0, 1), code, depth_threshold)

        def engine(code: Code, depth_threshold: float = threshold) -> Collision | None:
            return checker.find_collision(
                [h.pose(r) for h, r in zip(table.hypotheses, code, strict=True)], depth_threshold
            )

        assert decide((1, 1)) is None and table.engine_checks == 1
        assert decide((1, 1)) is None and table.engine_checks == 1  # known: no engine call
        sunk = decide((2, 1))
        assert sunk == engine((2, 1)) and sunk is not None and sunk.pair == ("a", "floor")
        overlapping = decide((3, 1))
        assert overlapping == engine((3, 1)) and overlapping is not None and overlapping.pair == ("a", "b")
        checks = table.engine_checks
        assert decide((3, 1), 0.09) is None and engine((3, 1), 0.09) is None  # the threshold applies at lookup
        assert table.engine_checks == checks

        # b's hypotheses change: entries with b go, a's against the floor stay.
        table = table.updated((hypotheses[0], ranked([unrotated(0.15, 0.0, ON_FLOOR)], [1])))
        assert len(table) == 3  # a at its three ranks against the floor
        closer = decide((3, 1))
        assert closer == engine((3, 1)) and closer is not None and closer.depth == pytest.approx(0.03)
        assert decide((3, 1)) == closer and table.engine_checks == checks + 1  # the new a-b pair, computed once
        table = table.updated((hypotheses[0], ranked([unrotated(0.5, 0.0, ON_FLOOR)], [1])))
        assert decide((3, 1)) is None and engine((3, 1)) is None
        assert table.engine_checks == checks + 2  # b against the floor; a and b apart need no entry
        assert decide((1, 1)) is None and table.engine_checks == checks + 2


def memo_problem() -> tuple[Scene, tuple[RankedHypotheses, ...]]:
    problem = scale_problem(ScaleCase("pairs", 4, 3, 6), GROUPED)
    return problem.problem.scene, problem.problem.hypotheses


def test_the_settle_memo_serves_a_restart_with_the_same_physics_and_is_dropped_when_physics_changes() -> None:
    scene, hypotheses = memo_problem()
    params = replace(scene.search, trace_limit=None)
    with PhysicsChecker(scene) as checker:
        first = make_search(checker, hypotheses, params)
        first.run(None)
        # A higher T changes which nodes are visited, not how they settle: every settling from the memo.
        higher_t = replace(params, probability_threshold=0.3)
        restarted = make_search(checker, hypotheses, higher_t, first)
        assert restarted is not first
        again = restarted.run(None)
        assert again.stats.memo_hits > 0 and again.stats.settle_steps == 0
        fresh = make_search(checker, hypotheses, higher_t).run(None)
        assert [replace(e, group=None) for e in again.trace] == [replace(e, group=None) for e in fresh.trace]
        # A longer settle_time changes settlings: nothing is reused.
        longer = make_search(checker, hypotheses, replace(params, settle_time=0.6), restarted).run(None)
        assert longer.stats.memo_hits == 0 and longer.stats.settle_steps > 0


def test_new_hypotheses_for_one_object_restart_its_group_only() -> None:
    scene, hypotheses = memo_problem()
    params = scene.search
    with PhysicsChecker(scene) as checker:
        first = make_search(checker, hypotheses, params)
        done = first.run(None)
        assert isinstance(first, GroupedSearch) and len(done.groups) == 2
        reweighted = ranked([h.pose for h in hypotheses[0].hypotheses], [1.0, 1.0, 3.0])  # its true pose first now
        changed = (reweighted, *hypotheses[1:])
        second = make_search(checker, changed, params, first)
        result = second.run(None)
    kept = {group.objects: group.kept for group in result.groups}
    assert kept == {(0, 1): False, (2, 3): True}
    before = {group.objects: group for group in done.groups}
    after = {group.objects: group for group in result.groups}
    assert after[(2, 3)].visited == before[(2, 3)].visited and after[(2, 3)].code == before[(2, 3)].code
    assert result.valid


# --- one deadline for all groups -----------------------------------------------------------------------


def test_unsolved_groups_go_first_and_every_result_combines_each_group_s_best_so_far() -> None:
    scene = far_apart_cubes(3)
    # cube_0 is valid at its root; cube_1 and cube_2 only at their 3rd hypothesis (the first two float).
    heights = [[0.0, 0.0, 0.0], [0.05, 0.04, 0.0], [0.06, 0.03, 0.0]]
    hypotheses = tuple(
        ranked([unrotated(i * 0.5, 0.0, ON_FLOOR + dz) for dz in row], [0.5, 0.3, 0.2]) for i, row in enumerate(heights)
    )
    params = replace(GROUPED, trace_limit=None)
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, hypotheses, params)
        assert isinstance(search, GroupedSearch)
        results = [search.run(0.0)]
        budget = 0.001
        while not search.done:
            results.append(search.run(budget))
            if len(results[-1].trace) == len(results[-2].trace):
                budget *= 2
    trace = results[-1].trace
    order = [(e.group, e.code) for e in trace]
    # Roots first (all unsolved, equally probable relative to their roots), then the unsolved groups'
    # nodes, most probable first; the solved group 0 only once 1 and 2 are solved.
    assert order[:3] == [(0, (1,)), (1, (1,)), (2, (1,))]
    solved_at = {g: next(i for i, e in enumerate(trace) if e.group == g and e.outcome == "valid") for g in (1, 2)}
    assert all(e.group != 0 for e in trace[3 : max(solved_at.values())])
    for result in results:
        best: dict[int | None, TraceEntry] = {}
        for entry in result.trace:
            if entry.outcome == "valid" and (
                entry.group not in best or (entry.jitter or 0.0) < (best[entry.group].jitter or 0.0)
            ):
                best[entry.group] = entry
        if len(best) == 3:
            assert result.valid and result.code == tuple(best[g].code[0] for g in range(3))
        else:
            assert not result.valid and result.code is None
        assert [g.code for g in result.groups] == [best[g.id].code if g.id in best else None for g in result.groups]


# --- bounded memory ----------------------------------------------------------------------------------------


def test_queue_and_trace_limits_bound_a_search_s_memory() -> None:
    hypotheses = floor_hypotheses([(0.4, 0.3, 0.2, 0.1)] * 3, lift=0.001)
    params = SearchParams(probability_threshold=0.0, strategy="joint", queue_limit=8, trace_limit=10)
    with PhysicsChecker(far_apart_cubes(3)) as checker:
        search = make_search(checker, hypotheses, params)
        queued = []
        while not search.done:
            search.run(0.0005)
            queued.append(search.queued)
        result = search.result()
        full = make_search(checker, hypotheses, replace(params, queue_limit=1000, trace_limit=None)).run(None)
    assert max(queued) <= 8
    assert result.stats.dropped > 0 and result.stats.end == "truncated" and not result.stats.exhausted
    assert len(result.trace) == 10 and result.stats.untraced == result.stats.visited - 10
    assert result.stats.visited < 64 == full.stats.visited
    # Still best-first, among configurations the whole search visits too.
    probabilities = [e.probability for e in result.trace]
    assert all(b <= a * (1 + 1e-9) for a, b in itertools.pairwise(probabilities))
    assert {e.code for e in result.trace} <= {e.code for e in full.trace}


def test_each_group_s_share_of_the_queue_limit_is_in_proportion_to_its_objects() -> None:
    """Three cubes side by side (one group) and one far off: the queue limit is shared 3 : 1."""
    scene = floor_scene(*(cube(name) for name in ("a", "b", "c", "far")))
    hypotheses = tuple(
        ranked([unrotated(x, 0.0, ON_FLOOR), unrotated(x, 0.01, ON_FLOOR)], [0.6, 0.4])
        for x in (0.0, 0.101, 0.202, 1.0)
    )
    params = SearchParams(queue_limit=400)
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, hypotheses, params)
        assert isinstance(search, GroupedSearch)
        shares = {group.objects: group.candidates.queue_limit for group in search.groups()}
    assert shares == {(0, 1, 2): 300, (3,): 100}


def test_runs_cut_short_anywhere_resume_to_the_uninterrupted_grouped_search_bit_for_bit() -> None:
    problem = scale_problem(ScaleCase("pairs", 4, 3, 7), GROUPED)
    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    # Full 2 s settlings (480 steps): many are cut by the 2 ms budgets, and other groups use the world between.
    params = replace(scene.search, settle_exit="full", settle_time=2.0, trace_limit=None)
    reference = run_to_end(scene, hypotheses, params)
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, hypotheses, params)
        results = [search.run(0.002)]
        while not search.done and len(results) < 5000:
            results.append(search.run(0.002))
    assert search.done
    assert sum(result.stats.stopped_at_deadline for result in results) > len(reference.trace)
    for result in results:
        assert result.trace == reference.trace[: len(result.trace)]
    final = results[-1]
    assert final.trace == reference.trace
    assert (final.code, final.settled_poses) == (reference.code, reference.settled_poses)


def test_a_group_s_interrupted_settling_resumes_exactly_after_other_groups_used_the_world() -> None:
    problem = scale_problem(ScaleCase("pairs", 4, 3, 8), GROUPED)
    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    first, second = (0, 1), (2, 3)
    floating = [hypotheses[i].pose(1) for i in first]
    other = [hypotheses[i].pose(1) for i in second]
    with PhysicsChecker(scene) as fresh:
        reference = fresh.settle(floating, 2.0, 0.1, objects=first)
    with PhysicsChecker(scene) as checker:
        partial = checker.settle(floating, 2.0, 0.1, 0.0, objects=first)  # a deadline long past
        assert isinstance(partial, PartialSettling)
        checker.settle(other, 1.0, 0.1, objects=second)  # the other pile, the first one parked
        checker.contact_depths(second, other)
        assert checker.resume_settling(partial) == reference


def test_the_tree_shows_one_tree_per_group_headed_by_its_objects(reduced_suite: list[Compared]) -> None:
    compared = reduced_suite[3]  # mixed piles
    result, names = compared.grouped, compared.problem.problem.scene.object_names
    lines = trace_tree(result.trace, result.groups, names).splitlines()
    heads = [line for line in lines if line.startswith("group ")]
    assert len(heads) == len(result.groups)
    for head, group in zip(heads, result.groups, strict=True):
        objects = ", ".join(names[i] for i in group.objects)
        assert head.startswith(f"group {group.id} ({objects}): C{'1' * len(group.objects)}  #")
    assert len(lines) == len(result.trace)

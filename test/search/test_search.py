"""Branch and bound (paper Algorithm 1) on hand-built probabilities, with real pybullet checks.

The scenes here make the physics predictable (cubes far apart on the floor are always
valid; one cube floating or sunk is not), so the tests see the search's own behaviour:
order, bounding, ties, anytime stops, resuming, fallback and the least-jitter choice.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

from conftest import PROBLEMS
from core_builders import (
    FIG4_ORDER,
    FIG4_THRESHOLD,
    FIG4_WEIGHTS,
    ON_FLOOR,
    cube,
    far_apart_cubes,
    floor_hypotheses,
    floor_scene,
    ranked,
    run_search,
    unrotated,
)

from physics_mapper.model.scene import SearchParams
from physics_mapper.model.scene_files import load_problem
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.settling import CLOCK_CHECK_STEPS
from physics_mapper.physics.world import TIME_STEP
from physics_mapper.search.results import Code, SearchResult, TraceEntry
from physics_mapper.search.strategy import paper_search

#: A 4 x 3 x 3 problem with distinct, unequal weights (normalised by the ranking).
UNEVEN_WEIGHTS = ((0.5, 0.3, 0.15, 0.05), (0.6, 0.25, 0.15), (0.45, 0.35, 0.2))


def children(code: Code, sizes: tuple[int, ...]) -> set[Code]:
    """Codes that advance one object's rank by one (the paper's branching)."""
    return {(*code[:i], rank + 1, *code[i + 1 :]) for i, rank in enumerate(code) if rank < sizes[i]}


def best_valid_so_far(trace: tuple[TraceEntry, ...]) -> TraceEntry | None:
    """The first valid entry of least jitter: what the search must report at that point."""
    valid = [entry for entry in trace if entry.outcome == "valid"]
    return min(valid, key=lambda entry: entry.jitter or 0.0) if valid else None


def test_fig4_order_then_only_bounded_nodes() -> None:
    params = SearchParams(probability_threshold=FIG4_THRESHOLD, bound="absolute")  # the paper's reading of T
    result = run_search(far_apart_cubes(3), floor_hypotheses(FIG4_WEIGHTS), params)
    codes = [entry.code for entry in result.trace]
    assert tuple(codes[: len(FIG4_ORDER)]) == FIG4_ORDER
    assert all(entry.outcome == "valid" for entry in result.trace)

    expanded, rest = result.trace[:13], result.trace[14:]
    first_bounded = result.trace[13]
    assert first_bounded.code == (2, 2, 2) and first_bounded.bounded
    assert not any(entry.bounded for entry in expanded)
    # After C222 the queue holds exactly the unvisited children of the 13 expanded nodes,
    # all below T: each is visited, marked bounded, and queues nothing.
    queued = set().union(*(children(entry.code, (3, 3, 3)) for entry in expanded)) - set(FIG4_ORDER)
    assert {entry.code for entry in rest} == queued
    assert all(entry.bounded and entry.probability < FIG4_THRESHOLD for entry in rest)
    bounded_codes = {entry.code for entry in result.trace if entry.bounded}
    assert not any(entry.parent in bounded_codes for entry in result.trace)
    assert result.stats.expanded == 13
    assert result.stats.bounded == len(result.trace) - 13
    # The queue emptied because of the bound: not every configuration was visited.
    assert result.stats.end == "bounded" and not result.stats.exhausted and not result.stats.stopped_at_deadline


def test_visits_are_in_non_increasing_probability_and_never_repeat() -> None:
    result = run_search(far_apart_cubes(3), floor_hypotheses(UNEVEN_WEIGHTS), SearchParams(probability_threshold=0.0))
    probabilities = [entry.probability for entry in result.trace]
    assert all(later <= earlier * (1 + 1e-9) for earlier, later in itertools.pairwise(probabilities))
    codes = [entry.code for entry in result.trace]
    assert len(set(codes)) == len(codes)
    # With T = 0 nothing is bounded, so every configuration is visited exactly once.
    assert len(codes) == math.prod(len(weights) for weights in UNEVEN_WEIGHTS)
    assert result.stats.visited == len(codes) and result.stats.bounded == 0


def test_nodes_below_threshold_are_checked_but_not_expanded() -> None:
    threshold = 0.02
    sizes = tuple(len(weights) for weights in UNEVEN_WEIGHTS)
    params = SearchParams(probability_threshold=threshold, bound="absolute")
    result = run_search(far_apart_cubes(3), floor_hypotheses(UNEVEN_WEIGHTS), params)
    trace = result.trace
    assert all(entry.bounded == (entry.probability < threshold) for entry in trace)
    assert any(entry.bounded for entry in trace) and not all(entry.bounded for entry in trace)
    # A bounded node never queues anything; its children appear only when an expanded node queued them.
    expanded = [entry for entry in trace if not entry.bounded]
    visited = {entry.code for entry in trace}
    assert visited == {(1, 1, 1)}.union(*(children(entry.code, sizes) for entry in expanded))
    expanded_codes = {entry.code for entry in expanded}
    for entry in trace[1:]:
        assert entry.parent in expanded_codes
        assert entry.code in children(entry.parent, sizes)
    assert result.stats.expanded == len(expanded)
    assert result.stats.bounded == len(trace) - len(expanded)


def test_equal_probabilities_visit_the_smaller_code_first() -> None:
    # Identical weight lists: codes with the same ranks in another order tie in p(C),
    # even though their floating-point products are taken in another order.
    same = (0.6, 0.3, 0.1)
    result = run_search(far_apart_cubes(3), floor_hypotheses((same, same, same)), SearchParams(probability_threshold=0))
    codes = [entry.code for entry in result.trace]
    assert codes[:7] == [(1, 1, 1), (1, 1, 2), (1, 2, 1), (2, 1, 1), (1, 2, 2), (2, 1, 2), (2, 2, 1)]
    for earlier, later in itertools.pairwise(result.trace):
        if math.isclose(earlier.probability, later.probability, rel_tol=1e-9):
            assert earlier.code < later.code


def test_uniform_weights_visit_in_code_order() -> None:
    result = run_search(far_apart_cubes(3), floor_hypotheses([(1.0, 1.0)] * 3), SearchParams(probability_threshold=0))
    codes = [entry.code for entry in result.trace]
    assert codes == sorted(codes) and len(codes) == 8


def test_tiny_deadline_returns_best_so_far_and_resuming_continues_the_same_trace() -> None:
    scene = far_apart_cubes(3)
    # Lifts of 0-3 mm make every configuration valid with its own jitter, so the best changes.
    hypotheses = floor_hypotheses([(0.4, 0.3, 0.2, 0.1)] * 3, lift=0.001)
    params = SearchParams(probability_threshold=0.0)
    reference = run_search(scene, hypotheses, params)

    with PhysicsChecker(scene) as checker:
        search = paper_search(checker, hypotheses, params)
        results = [search.run(0.0)]
        budget = 0.001  # seconds; doubled after a run that could not finish one node
        while not search.done:
            results.append(search.run(budget))
            if len(results[-1].trace) == len(results[-2].trace):
                budget *= 2

    first = results[0]
    assert first.stats.stopped_at_deadline and first.stats.visited == 0
    assert first.code is None and not first.valid
    for result in results[:-1]:
        assert result.stats.stopped_at_deadline and not result.stats.exhausted
    assert any(result.valid and result.stats.stopped_at_deadline for result in results)
    for result in results:
        assert result.trace == reference.trace[: len(result.trace)]  # same order, no repeats
        best = best_valid_so_far(result.trace)
        assert result.code == (best.code if best else None)
        assert result.jitter == (best.jitter if best else None)
    final = results[-1]
    assert final.stats.exhausted and not final.stats.stopped_at_deadline
    assert final.trace == reference.trace
    assert (final.code, final.jitter) == (reference.code, reference.jitter)
    assert final.stats.visited == reference.stats.visited == 64


def test_settlings_longer_than_the_budget_continue_across_runs_to_the_uninterrupted_trace() -> None:
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    settle_time = 5.0  # seconds, 1200 steps: tens of milliseconds per settling
    params = replace(problem.scene.search, settle_time=settle_time)
    reference = run_search(problem.scene, problem.hypotheses, params)
    settlings = sum(entry.outcome != "collision" for entry in reference.trace)
    assert settlings >= 10 and reference.valid
    budget = 0.002  # seconds per run, far less than one settling takes
    # Every run visits a node or simulates CLOCK_CHECK_STEPS steps of one: a generous cap.
    steps = settlings * round(settle_time / TIME_STEP)
    max_runs = 3 * (len(reference.trace) + steps // CLOCK_CHECK_STEPS)

    with PhysicsChecker(problem.scene) as checker:
        search = paper_search(checker, problem.hypotheses, params)
        results = [search.run(budget)]
        while not search.done and len(results) < max_runs:
            results.append(search.run(budget))

    assert search.done, f"{len(results)} runs visited {len(results[-1].trace)} of {len(reference.trace)} nodes"
    # Runs that ended inside a settling added nothing to the trace: settlings spanned several runs.
    runs_inside_a_settling = [len(b.trace) == len(a.trace) for a, b in itertools.pairwise(results)]
    assert sum(runs_inside_a_settling) >= settlings
    for result in results:
        assert result.trace == reference.trace[: len(result.trace)]
    final = results[-1]
    assert final.trace == reference.trace  # same codes, outcomes and jitters, bit for bit
    assert (final.code, final.jitter) == (reference.code, reference.jitter)
    assert final.settled_poses == reference.settled_poses
    assert final.stats.exhausted and final.stats.visited == reference.stats.visited


def one_cube_search(heights: tuple[float, ...], params: SearchParams) -> SearchResult:
    """One cube whose hypotheses (weights decreasing in the given order) are at these centre heights."""
    poses = [unrotated(0.0, 0.0, z) for z in heights]
    weights = [len(heights) - i for i in range(len(heights))]
    return run_search(floor_scene(cube("box")), [ranked(poses, weights)], params)


#: Rank 1 sunk 2 cm into the floor (collision); ranks 2 and 3 float 5 and 10 cm (unstable).
NO_VALID_HEIGHTS = (ON_FLOOR - 0.02, ON_FLOOR + 0.05, ON_FLOOR + 0.1)


def test_fallback_none_reports_nothing_when_no_configuration_is_valid() -> None:
    result = one_cube_search(NO_VALID_HEIGHTS, SearchParams(fallback="none"))
    assert [entry.outcome for entry in result.trace] == ["collision", "unstable", "unstable"]
    assert not result.valid and not result.fallback_used
    assert result.code is None and result.poses is None and result.settled_poses is None


def test_fallback_settled_reports_the_most_likely_collision_free_configuration_settled() -> None:
    result = one_cube_search(NO_VALID_HEIGHTS, SearchParams(fallback="settled"))
    assert not result.valid and result.fallback_used
    assert result.code == (2,)  # rank 1 collides, so the fallback skips it
    assert result.poses is not None and result.settled_poses is not None
    assert result.poses[0].position[2] == ON_FLOOR + 0.05
    assert math.isclose(result.settled_poses[0].position[2], ON_FLOOR, abs_tol=0.001)
    assert result.jitter is not None and math.isclose(result.jitter, 0.05, abs_tol=0.002)


def test_least_jitter_valid_configuration_wins_over_more_likely_ones() -> None:
    # Floating 8, 4 and 0 mm: all three within a 1 cm jitter threshold, the last settles least.
    result = one_cube_search((ON_FLOOR + 0.008, ON_FLOOR + 0.004, ON_FLOOR), SearchParams(jitter_threshold=0.01))
    jitters = [entry.jitter for entry in result.trace]
    assert [entry.outcome for entry in result.trace] == ["valid"] * 3
    assert jitters[0] is not None and jitters[1] is not None and jitters[2] is not None
    assert jitters[0] > jitters[1] > jitters[2]
    assert result.valid and result.code == (3,) and result.jitter == jitters[2]
    assert not result.fallback_used


def test_fallback_refine_makes_the_refined_map_before_it_visits_the_root() -> None:
    """The root floats 5 cm, collision-free: its settling would be the first visit, and on a slow machine
    could take the whole tick. The first step of a ``refine`` search makes the refined map instead, so
    that the tick has a map; the search then goes on and the valid rank replaces it."""
    hypotheses = [ranked([unrotated(0.0, 0.0, ON_FLOOR + 0.05), unrotated(0.0, 0.0, ON_FLOOR)], [2.0, 1.0])]
    with PhysicsChecker(floor_scene(cube("box"))) as checker:
        search = paper_search(checker, hypotheses, SearchParams(fallback="refine"))
        assert search.step(None)
        first = search.result()
        assert first.stats.visited == 0 and first.fallback == "refine" and first.refinement is not None
        assert first.settled_poses is not None and math.isclose(
            first.settled_poses[0].position[2], ON_FLOOR, abs_tol=0.002
        )
        final = search.run(None)
    assert final.valid and final.code == (2,) and [entry.outcome for entry in final.trace] == ["unstable", "valid"]

"""The conflict-directed search (``strategy: conflict``) against the paper's search on crowded scenes.

Real pybullet throughout. The reduced suite is the crowded benchmark's generator
(``physics_mapper.scenarios.crowded_suite``) at sizes where the paper's search, per group, finishes:
packed scenes whose only valid configuration is known by construction.
"""

from __future__ import annotations

import itertools
import json
import math
import random
from dataclasses import replace
from pathlib import Path
from typing import Any, cast

import pytest
import yaml
from core_builders import cli, cube, floor_scene, solve_json, unrotated
from core_builders import ranked as ranked_poses
from mesh_builders import box_mesh, floor_scene_dict, load_inline, mesh_object, write_mesh

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Bound, Box, Mesh, ObjectModel, SearchParams, Strategy
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.settling import (
    CLOCK_CHECK_STEPS,
    MOVING_BEYOND_LOOKS,
    REST_CHECKS,
    EarlyExit,
    Settling,
    early_exit_rule,
)
from physics_mapper.scenarios.crowded_suite import (
    JITTER_TOLERANCE,
    REDUCED,
    CrowdedCase,
    CrowdedProblem,
    crowded_problem,
    problem_document,
    same_answer,
    truth_is_valid,
)
from physics_mapper.search.best_first import Search
from physics_mapper.search.conflict_directed import ConflictDirectedCandidates, ConflictGroup
from physics_mapper.search.conflicts import Blame, Conflict, ConflictStore
from physics_mapper.search.grouped import GroupedSearch
from physics_mapper.search.results import Code, SearchResult
from physics_mapper.search.rule2 import PRIMITIVE_SOLVER_RESIDUAL
from physics_mapper.search.strategy import make_search
from physics_mapper.search.trial_settling import TRIAL_SOLVER_ITERATIONS

Outcomes = dict[tuple[tuple[int, ...], Code], str]
#: A problem, the paper's search of it per group, the conflict-directed one, and its groups.
CaseRuns = tuple[CrowdedProblem, SearchResult, SearchResult, list[ConflictGroup]]


def searched(problem: CrowdedProblem, **changes: object) -> tuple[SearchResult, list[ConflictGroup]]:
    """``problem`` searched to the end with the defaults changed by ``changes``, and its conflict groups."""
    search, result, _ = settling_options(problem, **changes)
    strategy = changes.get("strategy", problem.problem.scene.search.strategy)
    return result, conflict_groups(search) if strategy == "conflict" else []


def conflict_groups(search: Search) -> list[ConflictGroup]:
    """The groups of a conflict-directed search, each its core with the conflict-directed parts."""
    assert isinstance(search, GroupedSearch)
    groups = search.groups()
    assert all(isinstance(group.candidates, ConflictDirectedCandidates) for group in groups)
    return cast(list[ConflictGroup], groups)


def outcomes(result: SearchResult) -> Outcomes:
    """Every checked configuration's outcome, by (its group's objects, its code)."""
    objects = {group.id: group.objects for group in result.groups}
    return {(objects[entry.group], entry.code): entry.outcome for entry in result.trace}


@pytest.fixture(scope="module", params=REDUCED, ids=lambda case: case.label)
def case_runs(request: pytest.FixtureRequest) -> CaseRuns:
    problem = crowded_problem(request.param)
    paper, _ = searched(problem, strategy="grouped")
    conflict, groups = searched(problem)
    return problem, paper, conflict, groups


def test_the_suite_s_configuration_is_valid_by_construction() -> None:
    for case in REDUCED:
        assert truth_is_valid(crowded_problem(case)), case.label


def test_a_dropped_bin_that_still_creeps_is_settled_again_until_its_truth_is_valid() -> None:
    # This bin of 50 settles five times before its truth passes with half the jitter threshold to spare.
    assert truth_is_valid(crowded_problem(CrowdedCase("bin", 50, 5, 118)))


@pytest.mark.parametrize(
    ("objects", "seed", "unusable"),
    [(20, 115, "168.obj"), (10, 124, "178.obj")],
    ids=["one_that_does_not_load", "one_that_never_comes_to_rest"],
)
def test_a_bin_of_meshes_draws_again_a_random_object_it_cannot_use(objects: int, seed: int, unusable: str) -> None:
    """These seeds' bins first draw ``random_urdfs/168``, whose vertices are NaN, and ``random_urdfs/178``, a
    thin rod that Bullet rolls across the floor for good: each is drawn again, and the truth is valid."""
    problem = crowded_problem(CrowdedCase("mesh_bin", objects, 5, seed))
    files = [obj.shape.file.name for obj in problem.problem.scene.objects if isinstance(obj.shape, Mesh)]
    assert len(files) == objects
    assert unusable not in files
    assert truth_is_valid(problem)


def test_the_answer_is_the_exhaustive_paper_search_s(case_runs: CaseRuns) -> None:
    problem, paper, conflict, _ = case_runs
    assert paper.stats.finished and conflict.stats.finished
    assert (conflict.code, conflict.valid) == (paper.code, paper.valid) == (problem.answer, True)
    assert same_answer(conflict, paper)  # and every J_i within the early exit's tolerance
    assert conflict.stats.visited < paper.stats.visited  # the point of it


def test_conflicts_are_sound(case_runs: CaseRuns) -> None:
    """No configuration that contains a learned conflict (any combination of its rank sets) is valid when
    the paper's search checks it in full."""
    _, paper, _, groups = case_runs
    checked = outcomes(paper)
    contained = 0
    for group in groups:
        conflicts: list[Conflict] = list(group.candidates.conflicts)
        assert conflicts
        for (objects, code), outcome in checked.items():
            if objects == group.objects and any(conflict.holds_in(code) for conflict in conflicts):
                contained += 1
                assert outcome != "valid", code
    assert contained > 0


def test_conflicts_hold_for_more_ranks_than_the_rejected_candidate_s() -> None:
    """Both kinds of conflict carry rank sets wider than the rejected candidate's ranks, and the conflicts
    of the reduced suite and a small wall contain more of the configurations the paper's search
    rejected with them than without them."""
    wider = {"collision": 0, "unstable": 0}
    with_sets = without_sets = 0
    for case in (*REDUCED, CrowdedCase("wall", 6, 3, 1)):
        problem = crowded_problem(case)
        paper, _ = searched(problem, strategy="grouped")
        _, groups = searched(problem)
        rejected = [(objects, code) for (objects, code), outcome in outcomes(paper).items() if outcome != "valid"]
        for group in groups:
            conflicts = list(group.candidates.conflicts)
            for conflict in conflicts:
                wider[conflict.kind] += any(len(ranks) > 1 for ranks in conflict.ranks)
            exact = [Conflict(c.assignments, c.kind) for c in conflicts]
            codes = [code for objects, code in rejected if objects == group.objects]
            with_sets += sum(any(c.holds_in(code) for c in conflicts) for code in codes)
            without_sets += sum(any(c.holds_in(code) for c in exact) for code in codes)
    assert wider["collision"] > 0 and wider["unstable"] > 0
    assert with_sets > without_sets


def test_a_collision_conflict_s_rank_sets_collide_in_every_combination() -> None:
    """Every combination of a collision conflict's rank sets is in collision, checked in full with every
    object placed (the others at random ranks), or holds a rank ruled out alone."""
    rng = random.Random(1)
    problem = crowded_problem(CrowdedCase("tower", 6, 5, 3))
    scene, hypotheses, params = problem.problem.scene, problem.problem.hypotheses, problem.problem.scene.search
    _, groups = searched(problem)
    checked = wide = 0
    with PhysicsChecker(scene) as checker:
        for group in groups:
            ranks = [range(1, len(h) + 1) for h in group.hypotheses]
            for conflict in group.candidates.conflicts:
                if conflict.kind != "collision" or len(conflict.assignments) != 2:
                    continue
                wide += any(len(rank_set) > 1 for rank_set in conflict.ranks)
                for chosen in itertools.product(*conflict.ranks):
                    code = [rng.choice(r) for r in ranks]
                    for position, rank in zip(conflict.positions, chosen, strict=True):
                        code[position] = rank
                    if any(
                        group.candidates.conflicts.rules_out(p, r)
                        for p, r in zip(conflict.positions, chosen, strict=True)
                    ):
                        continue
                    poses = [hypotheses[i].pose(r) for i, r in zip(group.objects, code, strict=True)]
                    assert checker.find_collision(poses, params.penetration_threshold) is not None, code
                    checked += chosen != tuple(rank for _, rank in conflict.assignments)
    assert wide > 0 and checked > 0  # combinations beyond the rejected candidate's own ranks


def test_every_checked_configuration_has_the_paper_s_outcome(case_runs: CaseRuns) -> None:
    """Local settlings (and early exits) decide as the paper's full settlings do, wherever both check."""
    _, paper, conflict, _ = case_runs
    expected = outcomes(paper)
    found = outcomes(conflict)
    assert all(expected[key] == outcome for key, outcome in found.items())


def test_local_settlings_decide_as_full_ones() -> None:
    problem = crowded_problem(CrowdedCase("row", 8, 2, 8))
    paper, _ = searched(problem, strategy="grouped")
    conflict, _ = searched(problem)
    assert conflict.stats.part_counters["local_settlings"] > 0
    expected = outcomes(paper)
    assert all(expected[key] == outcome for key, outcome in outcomes(conflict).items())
    assert (conflict.code, conflict.valid) == (paper.code, paper.valid) == (problem.answer, True)


def settling_options(problem: CrowdedProblem, **changes: object) -> tuple[Search, SearchResult, list[dict[str, Any]]]:
    """``problem`` searched to the end with the defaults changed by ``changes``, and the options each settling
    asked of the checker (its solver's iterations and residual among them)."""
    params = replace(problem.problem.scene.search, trace_limit=None, **changes)  # type: ignore[arg-type]
    with PhysicsChecker(problem.problem.scene) as checker:
        options: list[dict[str, Any]] = []
        settle = checker.settle

        def noted(*args: Any, **asked: Any) -> Any:  # the checker's own settling, its options noted
            options.append(asked)
            return settle(*args, **asked)

        checker.settle = noted
        search = make_search(checker, problem.problem.hypotheses, params)
        return search, search.run(None), options


def row_of_meshes(problem: CrowdedProblem, folder: Path) -> CrowdedProblem:
    """``problem``, a row of identical cubes, with each cube a mesh of the same box (written into ``folder``)."""
    scene = problem.problem.scene
    cube = scene.objects[0].shape
    assert isinstance(cube, Box) and all(model.shape == cube for model in scene.objects)
    write_mesh(box_mesh(cube.size), folder / "cube.obj")
    objects = [mesh_object(model.name, "cube.obj", mass=model.mass) for model in scene.objects]
    meshes = replace(load_inline(floor_scene_dict(*objects), folder), search=scene.search)
    return replace(problem, problem=replace(problem.problem, scene=meshes))


def test_trials_run_fewer_solver_iterations_and_valid_verdicts_rule_2_s() -> None:
    """Trial settlings (local ones, and the whole group's before any context is known) run
    ``TRIAL_SOLVER_ITERATIONS``; the configuration found valid was settled with Rule 2's solver."""
    problem = crowded_problem(CrowdedCase("row", 8, 2, 8))
    search, result, options = settling_options(problem)
    iterations = [asked.get("solver_iterations") for asked in options]
    assert (result.code, result.valid) == (problem.answer, True)
    assert result.stats.part_counters["local_settlings"] > 0
    assert iterations.count(TRIAL_SOLVER_ITERATIONS) >= result.stats.part_counters["local_settlings"]
    assert None in iterations  # the confirmations: Rule 2's solver
    best = [group.best_valid for group in conflict_groups(search)]
    assert all(candidate is not None and candidate.settling.solver_iterations is None for candidate in best)


def rule_2_residuals(problem: CrowdedProblem, strategy: Strategy = "conflict") -> tuple[SearchResult, set[object]]:
    """The problem searched to its end under ``strategy``; the solver residuals of its Rule 2 settlings (those
    with Rule 2's iterations: no trial's), as asked of the checker (None: the world's, pybullet's)."""
    _, result, options = settling_options(problem, strategy=strategy)
    return result, {asked.get("solver_residual") for asked in options if asked.get("solver_iterations") is None}


def test_rule_2_s_own_settlings_of_primitives_end_the_solver_at_a_larger_residual_only_in_the_conflict_search(
    tmp_path: Path,
) -> None:
    """A row of cubes: the conflict-directed search's Rule 2 settlings end Bullet's iterations at
    ``PRIMITIVE_SOLVER_RESIDUAL``, the paper's grouped search's at pybullet's, with the same answer; the same
    row as meshes keeps pybullet's residual."""
    problem = crowded_problem(CrowdedCase("row", 8, 2, 8))
    conflict, residuals = rule_2_residuals(problem)
    assert residuals == {PRIMITIVE_SOLVER_RESIDUAL}
    paper, paper_residuals = rule_2_residuals(problem, "grouped")
    assert paper_residuals == {None}
    assert (conflict.code, conflict.valid) == (paper.code, paper.valid) == (problem.answer, True)
    result, mesh_residuals = rule_2_residuals(row_of_meshes(problem, tmp_path))
    assert mesh_residuals == {None}
    assert (result.code, result.valid) == (problem.answer, True)


def test_groups_with_meshes_are_settled_locally_with_the_same_answer(tmp_path: Path) -> None:
    """The same row with its cubes as meshes: settled locally too (their neighbours simulated), and the
    same answer."""
    problem = crowded_problem(CrowdedCase("row", 8, 2, 8))
    result, _ = searched(row_of_meshes(problem, tmp_path))
    assert result.stats.part_counters["local_settlings"] > 0 and result.stats.part_counters["full_settlings"] > 0
    assert (result.code, result.valid) == (problem.answer, True)


def test_rejections_name_their_conflict(case_runs: CaseRuns) -> None:
    problem, _, conflict, _ = case_runs
    names = problem.problem.scene.object_names
    for entry in conflict.trace:
        assert (entry.conflict is None) == (entry.outcome == "valid")
        for name, rank in entry.conflict or ():
            group = next(g for g in conflict.groups if g.id == entry.group)
            position = [names[i] for i in group.objects].index(name)
            assert entry.code[position] == rank


@pytest.mark.parametrize("bound", ["relative", "absolute"])
def test_the_same_answer_under_the_older_bounds(bound: Bound) -> None:
    problem = crowded_problem(CrowdedCase("wall", 6, 3, 6))
    threshold = 0.02 if bound == "relative" else 1e-4
    paper, _ = searched(problem, strategy="grouped", bound=bound, probability_threshold=threshold)
    conflict, _ = searched(problem, bound=bound, probability_threshold=threshold)
    assert (conflict.code, conflict.valid) == (paper.code, paper.valid)
    valid = {key for key, outcome in outcomes(paper).items() if outcome == "valid"}
    assert valid == {key for key, outcome in outcomes(conflict).items() if outcome == "valid"}


def test_the_resolving_bound_keeps_a_valid_configuration_the_relative_one_cuts_off() -> None:
    """Invalid first hypotheses put p(valid) / p(root) below T; relative to the first valid one it is 1."""
    problem = crowded_problem(CrowdedCase("row", 8, 3, 7))
    paper = problem.problem
    p_answer = 1.0
    p_root = 1.0
    for ranked, rank in zip(paper.hypotheses, problem.answer, strict=True):
        p_answer *= ranked.weight(rank)
        p_root *= ranked.weight(1)
    threshold = 2.0 * p_answer / p_root
    relative, _ = searched(problem, bound="relative", probability_threshold=threshold)
    resolving, _ = searched(problem, probability_threshold=threshold)
    assert not relative.valid and relative.stats.end == "bounded"
    assert (resolving.code, resolving.valid) == (problem.answer, True)


def test_the_default_is_the_conflict_search_with_the_resolving_bound() -> None:
    assert (SearchParams().strategy, SearchParams().bound) == ("conflict", "resolving")


def nudged(hypotheses: RankedHypotheses, metres: float) -> RankedHypotheses:
    """The same hypotheses moved ``metres`` along y: new input, the same outcomes."""
    moved = [
        Hypothesis(
            Pose((h.pose.position[0], h.pose.position[1] + metres, h.pose.position[2]), h.pose.orientation), h.weight
        )
        for h in hypotheses.hypotheses
    ]
    return RankedHypotheses.from_weighted(moved)


def test_new_hypotheses_for_one_object_keep_the_conflicts_of_the_others() -> None:
    problem = crowded_problem(CrowdedCase("row", 10, 5, 9))
    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    changed = tuple(nudged(h, 0.0005) if i == 9 else h for i, h in enumerate(hypotheses))
    with PhysicsChecker(scene) as checker:
        first = make_search(checker, hypotheses, scene.search)
        before = first.run(None)
        second = make_search(checker, changed, scene.search, first)
        after = second.run(None)
        old, new = conflict_groups(first)[0], conflict_groups(second)[0]
        kept = [c for c in old.candidates.conflicts if 9 not in c.positions]
        assert 0 < new.stats.part_counters["conflicts_kept"] <= len(kept) < len(old.candidates.conflicts)
    assert (after.code, after.valid) == (before.code, before.valid) == (problem.answer, True)
    assert after.stats.visited < before.stats.visited


def test_a_rank_ruled_out_by_a_neighbour_is_free_again_once_the_neighbour_moves() -> None:
    """Seven cubes in an L, one group: cube_1's only pose 3 cm into cube_0 rules out cube_0's only pose
    (and its own), so nothing is visited. Once cube_1's hypothesis moves to its place, cube_0's pose is
    free again though cube_0's hypotheses did not change: the next search must not keep that ruling-out."""
    scene = floor_scene(*(cube(f"cube_{i}") for i in range(7)))
    corners = [(0.0, 0.0), (0.11, 0.0), *((0.0, -0.11 * k) for k in range(1, 6))]
    place = [ranked_poses([unrotated(x, y, 0.05)], [1.0]) for x, y in corners]
    into_cube_0 = (place[0], ranked_poses([unrotated(0.03, 0.0, 0.05)], [1.0]), *place[2:])
    with PhysicsChecker(scene) as checker:
        first = make_search(checker, into_cube_0, scene.search)
        before = first.run(None)
        assert not before.valid and before.stats.visited == 0
        after = make_search(checker, tuple(place), scene.search, first).run(None)
    assert after.valid and after.code == (1,) * 7 and after.stats.visited > 0


def test_solve_trace_names_each_rejection_s_conflict(tmp_path: Path) -> None:
    problem = crowded_problem(CrowdedCase("row", 6, 3, 1))
    problem_file = tmp_path / "row.yaml"
    problem_file.write_text(yaml.safe_dump(problem_document(problem.problem)))
    trace_file = tmp_path / "trace.json"
    found = solve_json(problem_file, "--trace", trace_file)
    assert found["valid"] and found["code"] == list(problem.answer)
    trace = json.loads(trace_file.read_text())
    assert trace == found["trace"]
    rejected = [entry for entry in trace if entry["outcome"] != "valid"]
    assert rejected and all(entry["conflict"] for entry in rejected)
    names = problem.problem.scene.object_names
    for entry in rejected:
        assert all(entry["code"][names.index(name)] == rank for name, rank in entry["conflict"])
    text = cli("solve", problem_file, "--tree")
    assert text.returncode == 0 and "conflict {" in text.stdout and "candidates skipped" in text.stdout
    # The root holds a rank ruled out alone: never made, the line saying why comes first, and the first
    # candidate, none of whose parents was checked, heads a tree of its own.
    assert text.stdout.startswith("ruled out before the search: ") and "parent" not in trace[0]


def test_ranks_ruled_out_alone_are_in_collision_in_every_configuration() -> None:
    """Before its first candidate, a group's search knows the ranks Rule 1 rules out alone (against the
    floor, and against a neighbour at each of its ranks); each is in collision (checked in full, every
    object placed) whatever the other objects' ranks: all of them in a small tower, 100 drawn at random
    in a larger one, where the pairwise rule applies."""
    rng = random.Random(0)
    for case, sample in ((CrowdedCase("tower", 6, 3, 3), None), (CrowdedCase("tower", 9, 4, 3), 100)):
        problem = crowded_problem(case)
        scene, hypotheses, params = problem.problem.scene, problem.problem.hypotheses, problem.problem.scene.search
        with PhysicsChecker(scene) as checker:
            search = make_search(checker, hypotheses, params)
            (group,) = conflict_groups(search)
            assert group.objects == checker.all_objects
            ruled_out = list(group.candidates.conflicts)
            assert ruled_out and group.stats.visited == 0
            ranks = [range(1, len(h) + 1) for h in group.hypotheses]
            for conflict in ruled_out:
                ((position, rank),) = conflict.assignments
                assert rank not in group.candidates.conflicts.live_ranks(position) and problem.answer[position] != rank
                codes = (
                    [c for c in itertools.product(*ranks) if c[position] == rank]
                    if sample is None
                    else [
                        tuple(rank if p == position else rng.choice(r) for p, r in enumerate(ranks))
                        for _ in range(sample)
                    ]
                )
                for code in codes:
                    poses = [hypotheses[i].pose(r) for i, r in zip(group.objects, code, strict=True)]
                    assert checker.find_collision(poses, params.penetration_threshold) is not None, code
            assert (search.run(None).code, True) == (problem.answer, True)


def test_the_conflict_store_finds_the_smallest_conflict_and_the_ranks_left() -> None:
    store = ConflictStore([3, 3, 4])
    assert store.contained((1, 1, 1)) is None
    pair = Conflict(((0, 1), (2, 2)), "collision")
    triple = Conflict(((0, 1), (1, 1), (2, 2)), "unstable")
    assert store.learn(triple) and store.learn(pair) and not store.learn(pair)
    assert store.contained((1, 1, 2)) is pair  # the smaller of the two it holds
    assert store.contained((1, 2, 2)) is pair and store.contained((2, 1, 2)) is None
    assert store.next_rank(2, 1) == 2 and store.live_ranks(2) == [1, 2, 3, 4]
    store.learn(Conflict(((2, 2),), "collision"))
    store.learn(Conflict(((2, 3),), "collision"))
    assert store.next_rank(2, 1) == 4 and store.next_rank(2, 4) is None
    assert store.live_ranks(2) == [1, 4]
    assert store.contained((3, 3, 3)) == Conflict(((2, 3),), "collision")
    later_pair = Conflict(((0, 3), (1, 3)), "collision")
    store.learn(later_pair)
    assert store.contained((3, 3, 1)) is later_pair
    store.learn(Conflict(((0, 3), (2, 1)), "collision"))
    assert store.contained((3, 3, 1)) is later_pair  # of equal ones, the first learned


def test_a_conflict_with_rank_sets_holds_in_every_combination_and_expands_past_them() -> None:
    store = ConflictStore([3, 3, 5])
    wide = Conflict(((0, 1), (2, 2)), "collision", ranks=(frozenset({1, 2}), frozenset({2, 3, 5})))
    assert store.learn(wide) and not store.learn(wide)
    assert store.learn(Conflict(((0, 1), (2, 2)), "collision"))  # the same ranks, narrower: another conflict
    for code in itertools.product((1, 2, 3), (1, 2, 3), (1, 2, 3, 4, 5)):
        holds = code[0] in (1, 2) and code[2] in (2, 3, 5)
        assert wide.holds_in(code) == holds and (store.contained(code) is not None) == holds, code
    assert store.next_rank(2, 2, wide.ranks[1]) == 4 and store.next_rank(2, 4, wide.ranks[1]) is None
    assert store.next_rank(0, 1, wide.ranks[0]) == 3
    store.learn(Conflict(((1, 2),), "collision", ranks=(frozenset({2, 3}),)))  # one object: both ruled out
    assert store.live_ranks(1) == [1] and store.rules_out(1, 3) and not store.rules_out(1, 1)
    assert wide.renumbered({0: 4, 2: 1}) == Conflict(
        ((1, 2), (4, 1)), "collision", ranks=(frozenset({2, 3, 5}), frozenset({1, 2}))
    )
    with pytest.raises(ValueError, match="own ranks"):
        Conflict(((0, 1),), "collision", ranks=(frozenset({2}),))


def test_a_moving_settling_stops_a_falling_object_sooner_with_the_same_verdict() -> None:
    """``moving``: an object far off and still falling ends the settling before it comes to rest."""
    scene = floor_scene(cube("a"))
    params = scene.search
    floating = [unrotated(0.0, 0.0, 0.25)]  # 20 cm above its resting height
    with PhysicsChecker(scene) as checker:
        at_rest = checker.settle(
            floating, params.settle_time, params.angular_weight, early_exit=early_exit_rule(params, complete=False)
        )
        rule = early_exit_rule(params, complete=False, moving=True)
        assert rule is not None and rule.beyond_looks == MOVING_BEYOND_LOOKS < REST_CHECKS
        moving = checker.settle(floating, params.settle_time, params.angular_weight, early_exit=rule)
        three_looks = checker.settle(
            floating, params.settle_time, params.angular_weight, early_exit=replace(rule, beyond_looks=REST_CHECKS)
        )
    assert moving.stopped == "beyond_threshold" and moving.steps < at_rest.steps
    assert not moving.is_stable(params.jitter_threshold) and not at_rest.is_stable(params.jitter_threshold)
    # Each look fewer ends it one look (CLOCK_CHECK_STEPS steps) sooner, with the same verdict.
    assert three_looks.stopped == "beyond_threshold" and not three_looks.is_stable(params.jitter_threshold)
    assert moving.steps == three_looks.steps - (REST_CHECKS - MOVING_BEYOND_LOOKS) * CLOCK_CHECK_STEPS
    assert early_exit_rule(params, complete=True, moving=True) == early_exit_rule(params, complete=True)


@pytest.mark.parametrize(
    ("case", "rule_off"),
    [(CrowdedCase("bin", 30, 2, 108), {"wobble_rate": None}), (CrowdedCase("bin", 30, 5, 112), {"drift": None})],
    ids=["wobble", "drift"],
)
def test_a_packed_bin_is_at_rest_sooner_by_each_rest_rule_with_the_same_verdict(
    case: CrowdedCase, rule_off: dict[str, None]
) -> None:
    """``moving``: objects shaking in their contacts without going anywhere count as at rest
    (``wobble_rate``), and the rest rate grows as the settling's end nears (``drift``); with either,
    the settling stops sooner than without it and every J_i is within the tolerance of a full settling's."""
    problem = crowded_problem(case)
    params = problem.problem.scene.search
    truth = [h.pose(rank) for h, rank in zip(problem.problem.hypotheses, problem.answer, strict=True)]
    moving = early_exit_rule(params, complete=False, moving=True)
    assert moving is not None and all(getattr(moving, name) is not None for name in rule_off)
    with PhysicsChecker(problem.problem.scene) as checker:

        def settled(early_exit: EarlyExit | None) -> Settling:
            return checker.settle(truth, params.settle_time, params.angular_weight, early_exit=early_exit)

        without_rule = replace(moving, **rule_off)  # type: ignore[arg-type]
        with_rule, without, full = settled(moving), settled(without_rule), settled(None)
    assert with_rule.stopped == "rest" and with_rule.steps < without.steps
    assert all(s.is_stable(params.jitter_threshold) for s in (with_rule, without, full))
    assert all(abs(a - b) <= JITTER_TOLERANCE for a, b in zip(with_rule.jitters, full.jitters, strict=True))


def test_the_rest_rate_grows_as_the_time_left_shrinks() -> None:
    moving = early_exit_rule(SearchParams(), complete=False, moving=True)
    assert moving is not None and moving.drift is not None
    settle_time = SearchParams().settle_time
    assert moving.rate_scale(settle_time) == moving.rate_scale(2 * settle_time) == 1.0
    assert moving.rate_scale(settle_time / 4) == pytest.approx(4.0)
    not_moving = early_exit_rule(SearchParams(), complete=False)
    assert not_moving is not None and not_moving.rate_scale(settle_time / 4) == 1.0


def test_waiting_children_count_against_the_queue_limit() -> None:
    """The children an expansion holds back are nodes of the queue: with them, the queue holds at most
    ``queue_limit``; beyond, the least probable are dropped and the search says it is truncated."""
    problem = crowded_problem(CrowdedCase("wall", 10, 5, 2))
    params = replace(problem.problem.scene.search, queue_limit=4, trace_limit=None)
    with PhysicsChecker(problem.problem.scene) as checker:
        search = make_search(checker, problem.problem.hypotheses, params)
        queued = []
        while not search.done:
            search.run(0.001)
            queued.append(search.queued)
        result = search.result()
    assert max(queued) <= 4
    assert result.stats.dropped > 0 and result.stats.end == "truncated"


def test_the_chain_rule_holds_every_object_a_push_passed_through() -> None:
    """Cube a moved; its swept box meets b's, b's meets c's, and b barely moved: the contact rule holds a and b
    at their ranks, the chain rule c too (a push from c through b moved a as well)."""
    cubes = [cube(name) for name in "abc"]
    poses = [unrotated(0.05 + 0.1 * i, 0.0, 0.05) for i in range(3)]
    hypotheses = [ranked_poses([pose], [1.0]) for pose in poses]
    swept = tuple(((0.1 * i, -0.05, 0.0), (0.1 * i + 0.1, 0.05, 0.1)) for i in range(3))
    settling = Settling(tuple(poses), (0.05, 0.0004, 0.0), extent=swept)
    params = SearchParams()
    contact = Blame([c.shape for c in cubes], hypotheses, params)
    [by_contact] = contact.conflicts((1, 1, 1), settling)
    [by_chain] = contact.chained().conflicts((1, 1, 1), settling)
    assert by_contact.assignments == ((0, 1), (1, 1))
    assert by_chain.assignments == ((0, 1), (1, 1), (2, 1))


def test_a_group_out_of_candidates_with_none_valid_is_searched_again_under_the_chain_rule() -> None:
    """Two cubes side by side, each on the floor (rank 1) or sunk into it (rank 2): (1, 1) is valid. A
    conflict of both at rank 1, as an unsound blame would teach, leaves no valid candidate; the group is
    searched again without it under the chain rule, and finds (1, 1)."""
    scene = floor_scene(cube("left"), cube("right"))
    hypotheses = tuple(
        ranked_poses([unrotated(x, 0.0, 0.05), unrotated(x, 0.0, 0.02)], [0.6, 0.4]) for x in (0.0, 0.101)
    )
    params = replace(scene.search, trace_limit=None)
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, hypotheses, params)
        [group] = conflict_groups(search)
        group.candidates.conflicts.learn(Conflict(((0, 1), (1, 1)), "unstable"))
        result = search.run(None)
    assert (result.code, result.valid) == ((1, 1), True)
    assert result.stats.part_counters["searched_again"] == 1
    assert group.candidates.blame.chains
    assert [entry.code for entry in result.trace][-1] == (1, 1)


@pytest.mark.parametrize("case", [CrowdedCase("mesh_bin", 10, 5, 140), CrowdedCase("mesh_bin", 30, 5, 101)])
def test_a_bin_of_meshes_blames_only_what_its_settling_stopped_for(case: CrowdedCase) -> None:
    """In these bins a settling stopped early for a mesh that fell, while a mesh beside it rocked beyond the
    jitter threshold for a moment, touching only parts that did not move: blaming the rocking one too ruled
    out the answer (then searched again under the chain rule: the bin of 30 not answered in 10 s). Only the
    falling one is blamed, and the answer is found without searching again."""
    problem = crowded_problem(case)
    result, _ = searched(problem)
    assert (result.code, result.valid) == (problem.answer, True)
    assert result.stats.part_counters["searched_again"] == 0


def test_a_settling_stopped_as_unstable_blames_only_the_objects_it_stopped_for() -> None:
    """Cube a fell (beyond at the last looks), cube b beside it is beyond the threshold at that moment only:
    the settling teaches a's conflict alone."""
    cubes = [cube(name) for name in "ab"]
    poses = [unrotated(0.05 + 0.3 * i, 0.0, 0.05) for i in range(2)]
    hypotheses = [ranked_poses([pose], [1.0]) for pose in poses]
    swept = tuple(((0.3 * i, -0.05, 0.0), (0.3 * i + 0.1, 0.05, 0.1)) for i in range(2))
    params = SearchParams()
    rocking = 2 * params.jitter_threshold
    stopped = Settling(tuple(poses), (0.05, rocking), "beyond_threshold", extent=swept, beyond=(0,))
    ran_out = replace(stopped, stopped=None, beyond=())
    blame = Blame([c.shape for c in cubes], hypotheses, params)
    assert [c.assignments for c in blame.conflicts((1, 1), stopped)] == [((0, 1),)]
    assert [c.assignments for c in blame.conflicts((1, 1), ran_out)] == [((0, 1),), ((1, 1),)]


def test_a_neighbour_that_stayed_clear_of_a_fall_leaves_the_conflict_at_every_rank_clear_of_it() -> None:
    """A bar turned 45 degrees about z falls 3 cm beside a cube standing in a corner of the bar's box, 9 cm
    from its body. The boxes blame the cube at its rank; the clearance rule lets through each rank of the
    cube clear of the fall (rank 2, 9 cm off) and not one 4 mm from the bar (rank 3). Every configuration
    the widened conflict covers is unstable by a full settling."""
    bar = ObjectModel("bar", Box((0.3, 0.02, 0.02)), mass=0.2)
    scene = floor_scene(bar, cube("cube"))
    params = scene.search
    turned = Pose((0.0, 0.0, 0.04), (0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8)))
    cube_poses = [unrotated(0.12, -0.12, 0.05), unrotated(0.13, -0.11, 0.05), unrotated(0.07, -0.05, 0.05)]
    hypotheses = [ranked_poses([turned], [1.0]), ranked_poses(cube_poses, [0.5, 0.3, 0.2])]
    shapes = [model.shape for model in scene.objects]
    with PhysicsChecker(scene) as checker:
        settling = checker.settle(
            [turned, cube_poses[0]],
            params.settle_time,
            params.angular_weight,
            early_exit=early_exit_rule(params, False, moving=True),
            track_reach=True,
        )
        boxes = Blame(shapes, hypotheses, params).conflicts((1, 1), settling)
        cleared = Blame(shapes, hypotheses, params, clearance=checker.clearance).conflicts((1, 1), settling)
        assert [(c.assignments, c.ranks) for c in boxes] == [(((0, 1), (1, 1)), (frozenset({1}), frozenset({1})))]
        assert [(c.assignments, c.ranks) for c in cleared] == [(((0, 1), (1, 1)), (frozenset({1}), frozenset({1, 2})))]
        for rank in cleared[0].ranks[1]:
            full = checker.settle([turned, cube_poses[rank - 1]], params.settle_time, params.angular_weight)
            assert not full.is_stable(params.jitter_threshold)


def test_an_early_exit_counts_each_object_s_looks_beyond_on_its_own() -> None:
    """A cube falling from 20 cm beside one at rest: the settling stops for the falling one alone."""
    scene = floor_scene(cube("resting"), cube("falling"))
    params = scene.search
    poses = [unrotated(0.0, 0.0, 0.05), unrotated(0.3, 0.0, 0.25)]
    with PhysicsChecker(scene) as checker:
        settling = checker.settle(
            poses, params.settle_time, params.angular_weight, early_exit=early_exit_rule(params, False, moving=True)
        )
    assert settling.stopped == "beyond_threshold" and settling.beyond == (1,)

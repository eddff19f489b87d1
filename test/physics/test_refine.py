"""``fallback: refine``: penetrations resolved with little motion, no energy added, a settled map.

Core tests on small hand-made scenes and the shipped ones, then the same through ``solve --json``
and through the node over DDS.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path

import pytest
import yaml
from conftest import PROBLEMS, SCENES
from core_builders import (
    CUBE_SIZE,
    ON_FLOOR,
    cube,
    floor_scene,
    ground_truth,
    ranked,
    shipped_scene,
    solve_json,
    unrotated,
)
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray
from mesh_builders import MUG_FILE, MUG_PARTS
from ros_helpers import NodeProcess, RosClient, search_status, stamp_ns_of, values

from physics_mapper.model.bullet import pybullet
from physics_mapper.model.geometry import (
    Pose,
    make_pose,
    pose_displacement,
    quaternion_about_axis,
    translation_distance,
)
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, absent_hypothesis
from physics_mapper.model.scene import Fallback, Scene, SearchParams
from physics_mapper.model.scene_files import SceneError, load_problem, scene_from_dict
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs
from physics_mapper.msg_adapters.results import FALLBACK_COLOR, SHAPE_NAMESPACE
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.refine import (
    MAX_ITERATIONS,
    OVERLAP_TOLERANCE,
    SETTLING_SOLVER_ITERATIONS,
    STALL_ITERATIONS,
    RefinedMap,
    Refinement,
    refine_objects,
    refinement_start,
)
from physics_mapper.physics.settling import REST_SHARE, Settling, early_exit_rule
from physics_mapper.physics.world import SOLVER_ITERATIONS, TIME_STEP
from physics_mapper.search.results import SearchResult
from physics_mapper.search.strategy import make_search, paper_search

REFINE = SearchParams(fallback="refine")
#: A time.monotonic() instant long past: every deadline-aware call stops as soon as it may.
PAST = 0.0


def single(*poses: Pose) -> tuple[RankedHypotheses, ...]:
    """One hypothesis per object: no configuration but C11..1 to choose."""
    return tuple(ranked([pose], [1.0]) for pose in poses)


def refined_map(scene: Scene, hypotheses: Sequence[RankedHypotheses], params: SearchParams = REFINE) -> RefinedMap:
    with PhysicsChecker(scene) as checker:
        return refine_objects(checker, range(len(hypotheses)), hypotheses, params)


def is_valid_map(scene: Scene, poses: Sequence[Pose], params: SearchParams) -> bool:
    """Both rules hold for ``poses``: no overlap beyond the threshold, and every J_i within the threshold."""
    with PhysicsChecker(scene) as checker:
        if checker.find_collision(poses, params.penetration_threshold) is not None:
            return False
        return checker.settle(poses, params.settle_time, params.angular_weight).is_stable(params.jitter_threshold)


# --- the cases -------------------------------------------------------------------------------


def test_two_cubes_overlapping_3_cm_side_by_side_are_pushed_apart_by_as_little_as_possible() -> None:
    scene = floor_scene(cube("left"), cube("right"))
    overlap = 0.03
    half_apart = (CUBE_SIZE - overlap) / 2.0
    start = (unrotated(-half_apart, 0.0, ON_FLOOR), unrotated(half_apart, 0.0, ON_FLOOR))
    refined = refined_map(scene, single(*start))
    assert refined.converged and refined.initial_overlap == pytest.approx(overlap, abs=1e-6)
    assert is_valid_map(scene, refined.settled_poses, REFINE)
    moved = [translation_distance(a, b) for a, b in zip(start, refined.settled_poses, strict=True)]
    assert all(distance < overlap for distance in moved)
    assert sum(moved) == pytest.approx(overlap, abs=0.002)  # each half of it: the least motion
    assert all(pose.position[2] == pytest.approx(ON_FLOOR, abs=0.001) for pose in refined.settled_poses)


def test_a_cube_sunk_2_cm_into_the_floor_comes_out_resting_on_it_not_thrown() -> None:
    scene = floor_scene(cube("sunk"))
    start = unrotated(0.3, -0.2, ON_FLOOR - 0.02)
    (settled,) = refined_map(scene, single(start)).settled_poses
    assert settled.position[2] == pytest.approx(ON_FLOOR, abs=0.001)
    assert settled.position[2] - start.position[2] == pytest.approx(0.02, abs=0.001)
    assert math.dist(settled.position[:2], start.position[:2]) < 0.001  # straight up, not thrown aside


def on_left_slope(along: float, sunk: float) -> Pose:
    """The ball of sphere_groove.yaml ``along`` metres up the left slope from the vertex, ``sunk`` metres into it."""
    slope, radius = math.radians(30.0), 0.05
    normal = (math.sin(slope), 0.0, math.cos(slope))  # out of the left slope, into the groove
    surface = (-along * math.cos(slope), 0.0, 0.1 + along * math.sin(slope))
    return unrotated(*(s + (radius - sunk) * n for s, n in zip(surface, normal, strict=True)))


@pytest.mark.parametrize(
    "start",
    [
        pytest.param(on_left_slope(0.12, 0.02), id="overlapping a slope"),
        pytest.param(unrotated(0.06, 0.05, 0.02), id="deep inside the groove's block"),
    ],
)
def test_a_ball_overlapping_the_groove_ends_at_its_bottom(start: Pose) -> None:
    scene = shipped_scene("sphere_groove.yaml")
    refined = refined_map(scene, single(start), replace(scene.search, fallback="refine"))
    (settled,) = refined.settled_poses
    (truth,) = ground_truth(scene)
    assert refined.converged and refined.initial_overlap > scene.search.penetration_threshold
    assert math.hypot(settled.position[0] - truth.position[0], settled.position[2] - truth.position[2]) < 0.002
    assert settled.position[1] == pytest.approx(start.position[1], abs=0.005)  # it rolled across the groove only


def test_a_pyramid_whose_c111_overlaps_is_refined_to_a_standing_pyramid() -> None:
    scene, c111 = pyramid_c111()
    params = replace(scene.search, fallback="refine")
    refined = refined_map(scene, c111, params)
    assert refined.initial_overlap == pytest.approx(0.05) and refined.converged
    assert is_valid_map(scene, refined.settled_poses, params)  # J_i within 1 cm when settled again
    left, right, top = (pose.position for pose in refined.settled_poses)
    assert left[0] < top[0] < right[0] and top[2] == pytest.approx(0.3, abs=0.002)


# --- the method: speed cap, escape, subsets, the start, deadlines ---------------------------------------


def test_the_settling_caps_every_objects_speed() -> None:
    scene = floor_scene(cube("falling"))
    with PhysicsChecker(scene) as checker:
        free = checker.settle([unrotated(0.0, 0.0, 1.0)], 0.25, 0.0)
        capped = checker.settle([unrotated(0.0, 0.0, 1.0)], 0.25, 0.0, max_speed=0.2)
    assert free.jitters[0] > 0.25  # about g t^2 / 2 = 0.31 m
    # Capped after every step, an object falls within a step at most g TIME_STEP faster than the cap.
    assert 0.04 < capped.jitters[0] <= (0.2 + 9.81 * TIME_STEP) * 0.25


def test_depenetration_moves_no_object_faster_than_the_cap() -> None:
    scene = floor_scene(cube("sunk"))
    slow = replace(REFINE, refine_max_speed=0.5)
    refined = refined_map(scene, single(unrotated(0.0, 0.0, ON_FLOOR - 0.02)), slow)
    assert refined.iterations == math.ceil(0.02 / (slow.refine_max_speed * TIME_STEP))


def test_a_depenetration_that_stalls_ends_long_before_its_iteration_cap() -> None:
    """A rod through a mug's handle, thicker than the hole: the deepest closest point of the pair flips
    between the handle's bars from one iteration to the next, and no step lowers the overlap. The
    depenetration ends once :data:`STALL_ITERATIONS` steps have not lowered it (not at
    :data:`MAX_ITERATIONS`), unconverged, and the map is still made."""
    scene = scene_from_dict(
        {
            "static": [{"name": "floor", "shape": "plane"}],
            "objects": [
                {"name": "mug", "shape": "mesh", "file": MUG_FILE, "collision": "decomposition", "parts": MUG_PARTS},
                {"name": "rod", "shape": "cylinder", "radius": 0.018, "length": 0.2, "mass": 0.1},
            ],
        },
        "rod_through_handle.yaml",
    )
    # The handle's hole spans y 4.1-7.3 cm and z 3.5-6.5 cm of the mug's frame; the rod lies along x
    # through its middle, 3.6 cm thick.
    along_x = quaternion_about_axis((0.0, 1.0, 0.0), math.pi / 2.0)
    hypotheses = single(unrotated(0.0, 0.0, 0.0), make_pose((0.0, 0.057, 0.05), along_x))
    refined = refined_map(scene, hypotheses)
    assert not refined.converged and refined.remaining_overlap > OVERLAP_TOLERANCE
    assert STALL_ITERATIONS <= refined.iterations < MAX_ITERATIONS // 2
    assert len(refined.settled_poses) == 2


def test_the_settling_of_a_noisy_grid_rests_with_fewer_solver_iterations_and_gives_rule_2_s_back() -> None:
    # Nine touching cubes, each moved by up to 1 cm: neighbours overlap, some float or are sunk.
    shifts = [(0.008, -0.006, 0.01), (-0.01, 0.004, -0.008), (0.003, 0.009, 0.006)]
    poses = [
        unrotated(
            0.1 * (i % 3) + shifts[i % 3][0], 0.1 * (i // 3) + shifts[i // 3][1], ON_FLOOR + shifts[(i + 1) % 3][2]
        )
        for i in range(9)
    ]
    scene = floor_scene(*(cube(f"c{i}") for i in range(9)))
    with PhysicsChecker(scene) as checker:
        refined = Refinement(checker, range(9), poses, poses, REFINE)
        # Interrupted at every chance, in the depenetration and within the settling, each run going on
        # where the last stopped: Rule 2's solver comes back after every one.
        made, interruptions = None, 0
        while made is None:
            made = refined.run(PAST)
            assert solver_iterations(checker) == SOLVER_ITERATIONS
            interruptions += made is None
    assert interruptions > made.iterations  # some of them within the settling
    assert made.converged
    assert is_valid_map(scene, made.settled_poses, REFINE)  # at rest under Rule 2's own solver too


def test_a_packed_grid_s_map_is_taken_once_its_cubes_only_wobble_within_the_rest_tolerance() -> None:
    """The refinement's settling counts cubes shaking in their contacts as at rest (``wobbling``): on a
    5 x 5 grid of touching noisy cubes it stops at rest before ``settle_time``, where the rate alone
    runs it to the end, and its map lies within the rest tolerance (``REST_SHARE`` x the jitter
    threshold) of the map settled by the rate alone."""
    noise = [((7 * i) % 11 - 5) * 0.002 for i in range(75)]  # -1 to +1 cm, fixed
    count = 25
    poses = [
        unrotated(0.1 * (i % 5) + noise[3 * i], 0.1 * (i // 5) + noise[3 * i + 1], ON_FLOOR + noise[3 * i + 2])
        for i in range(count)
    ]
    scene = floor_scene(*(cube(f"c{i}") for i in range(count)))
    with PhysicsChecker(scene) as checker:
        made = Refinement(checker, range(count), poses, poses, REFINE).run()
        assert made is not None

        def settled(wobbling: bool) -> Settling:  # as the refinement settles, with or without ``wobbling``
            return checker.settle(
                made.depenetrated_poses,
                REFINE.settle_time,
                REFINE.angular_weight,
                early_exit=early_exit_rule(REFINE, complete=True, wobbling=wobbling),
                max_speed=REFINE.refine_max_speed,
                solver_iterations=SETTLING_SOLVER_ITERATIONS,
            )

        by_rate, wobbling = settled(False), settled(True)
    assert wobbling.stopped == "rest" and wobbling.steps < by_rate.steps
    assert wobbling.settled_poses == made.settled_poses  # the refinement's own settling
    tolerance = REST_SHARE * REFINE.jitter_threshold
    apart = [
        pose_displacement(a, b, REFINE.angular_weight)
        for a, b in zip(made.settled_poses, by_rate.settled_poses, strict=True)
    ]
    assert max(apart) <= tolerance


def solver_iterations(checker: PhysicsChecker) -> int:
    parameters = pybullet.getPhysicsEngineParameters(physicsClientId=checker.client_id)
    return int(parameters["numSolverIterations"])


def test_only_the_given_objects_are_refined_the_others_stay_parked() -> None:
    scene = floor_scene(cube("a"), cube("b"), cube("c"))
    poses = (unrotated(0.0, 0.0, ON_FLOOR), unrotated(0.05, 0.0, ON_FLOOR), unrotated(0.5, 0.0, ON_FLOOR - 0.01))
    hypotheses = single(*poses)
    with PhysicsChecker(scene) as checker:
        refined = Refinement(checker, (0, 2), (poses[0], poses[2]), (poses[0], poses[2]), REFINE).run()
    assert refined is not None and refined.objects == (0, 2) and len(refined.settled_poses) == 2
    a, c = refined.settled_poses
    assert translation_distance(a, poses[0]) < 0.001  # b, which it overlaps, is not there
    assert c.position[2] == pytest.approx(ON_FLOOR, abs=0.001)
    assert refined_map(scene, hypotheses).settled_poses[0].position[0] < -0.02  # with b there, a is pushed


def test_the_start_is_the_weighted_mean_of_the_hypotheses_near_the_most_likely_one() -> None:
    turned = quaternion_about_axis((0.0, 0.0, 1.0), 0.3)
    hypotheses = ranked(
        [make_pose((0.0, 0.0, 0.1), turned), unrotated(0.02, 0.0, 0.1), unrotated(0.0, 0.04, 0.1), unrotated(1, 0, 0)],
        [0.4, 0.3, 0.2, 0.1],
    )
    start = refinement_start(hypotheses, radius=0.1)
    assert start.position == pytest.approx((0.3 * 0.02 / 0.9, 0.2 * 0.04 / 0.9, 0.1))
    assert start.orientation == hypotheses.pose(1).orientation  # the most likely one's, never an average
    assert refinement_start(hypotheses, radius=0.0).position == (0.0, 0.0, 0.1)


def test_an_object_likelier_there_than_not_starts_at_the_mean_of_its_poses_as_the_others_do() -> None:
    """A tentative box: *absent* ranks first (0.30), then a wrong pose 3 cm off (0.25), then three poses
    within 3 mm of where it stands (0.15 each). Its poses outweigh its absence, so the refined map holds it,
    started at the weighted mean of its poses within ``refine_mean_radius`` of the most likely one, as an
    object whose first rank is a pose starts: not at the wrong pose alone."""
    wrong, *right = (unrotated(0.03, 0.0, ON_FLOOR), *(unrotated(0.003 * k, 0.0, ON_FLOOR) for k in range(3)))
    tentative = RankedHypotheses.from_weighted(
        [absent_hypothesis(0, 0.30), Hypothesis(wrong, 0.25), *(Hypothesis(p, 0.15) for p in right)]
    )
    assert tentative.is_absent(1)
    mean_x = (0.25 * 0.03 + 0.15 * (0.0 + 0.003 + 0.006)) / 0.70
    floating = ranked([unrotated(1.0, 0.0, 0.5)], [1.0])  # a named cube 0.5 m up: no configuration is valid
    scene = floor_scene(cube("box"), cube("floating"))
    with PhysicsChecker(scene) as checker:
        result = make_search(checker, (tentative, floating), replace(REFINE, strategy="joint")).run(None)
    assert not result.valid and result.refinement is not None
    assert result.refinement.start_poses[0].position == pytest.approx((mean_x, 0.0, ON_FLOOR), abs=1e-9)
    assert refinement_start(tentative, 0.0).position == wrong.position  # radius 0: the most likely pose


def pyramid_c111() -> tuple[Scene, tuple[RankedHypotheses, ...]]:
    """The shipped pyramid with only its C111 as hypotheses: the bottom cubes overlap 5 cm, the top floats."""
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    return problem.scene, single(*(h.pose(1) for h in problem.hypotheses))


def ball_in_the_block() -> tuple[Scene, tuple[RankedHypotheses, ...]]:
    """The shipped groove with a ball deep inside its block: it has to escape."""
    return shipped_scene("sphere_groove.yaml"), single(unrotated(0.06, 0.05, 0.02))


@pytest.mark.parametrize("problem", [pyramid_c111, ball_in_the_block], ids=["pyramid C111", "ball in the block"])
def test_an_interrupted_refinement_goes_on_where_it_stopped_and_ends_the_same(
    problem: Callable[[], tuple[Scene, tuple[RankedHypotheses, ...]]],
) -> None:
    scene, hypotheses = problem()
    params = replace(scene.search, fallback="refine")
    with PhysicsChecker(scene) as checker:
        whole = paper_search(checker, hypotheses, params).run(None)
        search = paper_search(checker, hypotheses, params)
        runs = [search.run(0.0002) for _ in range(1000)]
    pieces = [r for r in runs if r.settled_poses is not None and not r.unsettled]
    assert runs[0].code is None and pieces, "the first run stops early; a later one ends the refinement"
    assert pieces[0].settled_poses == whole.settled_poses and pieces[0].refinement == whole.refinement
    assert whole.fallback == "refine" and whole.refinement is not None and whole.refinement.iterations > 1


def test_a_refinement_stopped_in_its_settling_has_its_depenetrated_poses_as_its_map_so_far() -> None:
    """Driven one piece at a time (a deadline already past): no map while it depenetrates; within the settling,
    the depenetrated poses, marked unsettled; at the end the settled map. The search reports the same: its
    unsettled map is the tick's map (``settled_poses``, ``unsettled``), the finished one replaces it."""
    scene, hypotheses = pyramid_c111()
    poses = tuple(h.pose(1) for h in hypotheses)
    params = replace(scene.search, fallback="refine")
    with PhysicsChecker(scene) as checker:
        refinement = Refinement(checker, range(3), poses, poses, params)
        so_far = []
        while refinement.run(PAST) is None:
            so_far.append(refinement.so_far())
        made = refinement.so_far()
        search = paper_search(checker, hypotheses, params)
        results = []
        while search.refinement_due:
            search.step(PAST)
            results.append(search.result())
    assert made is not None and made.settled and so_far[0] is None
    unsettled = [m for m in so_far if m is not None]
    assert unsettled and all(not m.settled and m.settled_poses == made.depenetrated_poses for m in unsettled)
    assert unsettled[0].jitters != made.jitters  # measured at the depenetrated poses
    maps = [r for r in results if r.code is not None]
    assert results[0].code is None and maps[-1].refinement == made and not maps[-1].unsettled
    assert all(r.unsettled and r.settled_poses == made.depenetrated_poses for r in maps[:-1]) and len(maps) > 1


# --- the search and its outputs ------------------------------------------------------------------------


def test_fallback_switched_to_refine_mid_search_makes_the_map_without_revisiting_nodes() -> None:
    scene, c111 = pyramid_c111()
    with PhysicsChecker(scene) as checker:
        search = paper_search(checker, c111, replace(scene.search, fallback="none"))
        nothing = search.run(None)
        search.params = replace(search.params, fallback="refine")  # as the node does at its next tick
        refined = search.run(None)
        search.params = replace(search.params, fallback="none")
        again = search.run(None)
    assert nothing.code is None and again.code is None and nothing.stats.exhausted
    assert refined.fallback == "refine" and refined.settled_poses is not None
    assert refined.trace == nothing.trace and refined.stats.visited == nothing.stats.visited == 1


@pytest.mark.parametrize("name", ["stack", "pyramid"])
def test_a_valid_configuration_is_reported_exactly_as_without_refine(name: str) -> None:
    problem = load_problem(PROBLEMS / f"{name}.yaml")

    def solved(fallback: Fallback) -> SearchResult:
        params = replace(problem.scene.search, fallback=fallback)
        with PhysicsChecker(problem.scene) as checker:
            return paper_search(checker, problem.hypotheses, params).run(None)

    plain, refining = solved("none"), solved("refine")
    assert refining.valid and refining.fallback is None and refining.refinement is None
    same = ("code", "probability", "jitter", "poses", "settled_poses", "object_jitters", "trace")
    assert all(getattr(refining, key) == getattr(plain, key) for key in same)


def test_solve_json_reports_the_refined_map(tmp_path: Path) -> None:
    problem = yaml.safe_load((PROBLEMS / "pyramid.yaml").read_text())
    problem["scene"] = str(SCENES / "pyramid.yaml")
    problem["search"] = {"fallback": "refine"}
    problem["hypotheses"] = {name: hypotheses[:1] for name, hypotheses in problem["hypotheses"].items()}
    path = tmp_path / "c111.yaml"
    path.write_text(yaml.safe_dump(problem))
    result = solve_json(path)
    assert not result["valid"] and result["fallback_used"] and result["fallback"] == "refine"
    assert result["code"] == [1, 1, 1] and result["stats"]["collisions"] == 1
    refinement = result["refinement"]
    assert refinement["converged"] and refinement["remaining_overlap"] <= OVERLAP_TOLERANCE and refinement["settled"]
    assert (
        set(result["settled_poses"]) == set(refinement["depenetrated_poses"]) == {"cube_left", "cube_right", "cube_top"}
    )
    assert result["jitter"] == pytest.approx(sum(result["object_jitters"].values()))


@pytest.mark.parametrize(
    ("search", "problem"),
    [
        ({"refine_max_speed": 0.0}, "refine_max_speed must be in [0.001, 100], got 0"),
        ({"refine_mean_radius": -0.1}, "must be at least 0, got -0.1"),
        ({"fallback": "repair"}, "must be one of none, settled, refine, got 'repair'"),
    ],
)
def test_bad_refine_settings_are_refused_naming_the_key(search: dict[str, object], problem: str) -> None:
    data = {"objects": [{"name": "a", "shape": "sphere", "radius": 0.1}], "search": search}
    with pytest.raises(SceneError, match=r"^s\.yaml: search") as error:
        scene_from_dict(data, "s.yaml")
    assert str(error.value).endswith(problem)


# --- through the node over DDS -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def refining_node(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RosClient]:
    log = tmp_path_factory.mktemp("refine") / "node.log"
    node = NodeProcess(SCENES / "pyramid.yaml", {"fallback": "refine", "deadline": 0.2}, log, "/refine")
    client = RosClient("/refine")
    try:
        yield client
    finally:
        client.close()
        node.stop()


def test_the_node_publishes_the_refined_map_and_says_refine(refining_node: RosClient) -> None:
    client = refining_node
    problem = load_problem(PROBLEMS / "pyramid.yaml")
    c111 = single(*(h.pose(1) for h in problem.hypotheses))
    stamp_ns = time.time_ns()

    def publish() -> None:
        for name, hypotheses in zip(problem.scene.object_names, c111, strict=True):
            client.publish(name, *hypotheses_msgs(hypotheses, frame_id="world", stamp_ns=stamp_ns))

    objects = len(problem.scene.objects)

    def whole(message: PoseArray) -> bool:
        """A refined map of this stamp holding every object (before all have come, the others are absent)."""
        return stamp_ns_of(message) == stamp_ns and len(message.poses) == objects

    def refined_published() -> bool:
        return any(whole(m) for m in client.settled)

    client.keep_publishing(publish, refined_published, "the refined map")
    diagnostics = client.next_diagnostics(
        lambda d: "fallback refine" in (search_status(d) or DiagnosticStatus()).message
    )
    status = search_status(diagnostics)
    assert status is not None and status.level == DiagnosticStatus.WARN
    assert values(status)["fallback"] == "refine" and values(status)["fallback used"] == "true"
    with PhysicsChecker(problem.scene) as checker:
        offline = make_search(checker, c111, replace(problem.scene.search, fallback="refine")).run(None)
    assert offline.settled_poses is not None
    settled = next(m for m in client.settled if whole(m))
    got = [(p.position.x, p.position.y, p.position.z) for p in settled.poses]
    # The same map: within 1 mm, not bit for bit, since the node's world has searched the objects that came
    # first (they arrive one by one) before it refined all of them, which moves the last digits.
    assert all(math.dist(a, b.position) < 1e-3 for a, b in zip(got, offline.settled_poses, strict=True))
    client.wait_for(lambda: bool(client.markers) and bool(client.markers[-1].markers), what="markers")
    shapes = [m for m in client.markers[-1].markers if m.ns == SHAPE_NAMESPACE]
    assert [(m.pose.position.x, m.pose.position.y, m.pose.position.z) for m in shapes] == got
    orange = pytest.approx((FALLBACK_COLOR.r, FALLBACK_COLOR.g, FALLBACK_COLOR.b), abs=1e-6)  # float32 on the wire
    assert all((m.color.r, m.color.g, m.color.b) == orange for m in shapes)

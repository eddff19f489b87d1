"""The two rigid-body rules in a real pybullet world (paper section III-B), on the paper's scenes."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import replace

import pybullet
import pytest
from core_builders import CUBE_SIZE, ON_FLOOR, cube, floor_scene, ground_truth, moved, shipped_scene, unrotated

from physics_mapper.model.geometry import Pose, quaternion_about_axis, rotation_angle, translation_distance
from physics_mapper.model.scene import Box, Plane, Scene, SearchParams, StaticBody
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.settling import CLOCK_CHECK_STEPS, EarlyExit, PartialSettling, Settling, early_exit_rule
from physics_mapper.physics.world import TIME_STEP

JITTER_THRESHOLD = SearchParams().jitter_threshold
PENETRATION_THRESHOLD = SearchParams().penetration_threshold


def settle(checker: PhysicsChecker, poses: tuple[Pose, ...]) -> tuple[tuple[Pose, ...], tuple[float, ...]]:
    """Settle with the scene's own parameters; (settled poses, per-object jitters)."""
    params = checker.scene.search
    settling = checker.settle(poses, params.settle_time, params.angular_weight)
    return settling.settled_poses, settling.jitters


def two_cubes() -> Scene:
    return floor_scene(cube("cube_a"), cube("cube_b"))


def test_overlapping_cubes_collide_and_the_pair_is_named() -> None:
    with PhysicsChecker(two_cubes()) as checker:
        overlap = 0.02
        collision = checker.find_collision(
            (unrotated(0.0, 0.0, ON_FLOOR), unrotated(CUBE_SIZE - overlap, 0.0, ON_FLOOR)), PENETRATION_THRESHOLD
        )
        assert collision is not None
        assert collision.pair == ("cube_a", "cube_b")
        assert math.isclose(collision.depth, overlap, abs_tol=0.002)
        # Side by side, touching: no overlap beyond the threshold.
        touching = (unrotated(0.0, 0.0, ON_FLOOR), unrotated(CUBE_SIZE, 0.0, ON_FLOOR))
        assert checker.find_collision(touching, PENETRATION_THRESHOLD) is None


def test_cube_sunk_into_the_floor_collides_with_the_floor() -> None:
    with PhysicsChecker(floor_scene(cube("cube_a"))) as checker:
        collision = checker.find_collision((unrotated(0.0, 0.0, ON_FLOOR - 0.02),), PENETRATION_THRESHOLD)
        assert collision is not None and collision.pair == ("cube_a", "floor")


def test_cube_10cm_above_the_floor_is_unstable() -> None:
    with PhysicsChecker(floor_scene(cube("cube_a"))) as checker:
        floating = (unrotated(0.0, 0.0, ON_FLOOR + 0.1),)
        assert checker.find_collision(floating, PENETRATION_THRESHOLD) is None
        settling = checker.settle(floating, settle_time=0.5, angular_weight=0.1)
        assert not settling.is_stable(JITTER_THRESHOLD)
        assert math.isclose(settling.jitters[0], 0.1, abs_tol=0.005)
        assert math.isclose(settling.settled_poses[0].position[2], ON_FLOOR, abs_tol=0.001)


def test_an_early_exit_beyond_the_threshold_waits_until_the_object_rests_elsewhere() -> None:
    """Beyond the threshold mid-fall is not enough (a rocking object comes back): it must rest there."""
    early_exit = EarlyExit(rest_rate=0.001, jitter_threshold=JITTER_THRESHOLD)
    with PhysicsChecker(floor_scene(cube("cube_a"))) as checker:
        floating = (unrotated(0.0, 0.0, ON_FLOOR + 0.03),)  # beyond the 1 cm threshold 0.05 s into its fall
        settling = checker.settle(floating, settle_time=0.5, angular_weight=0.1, early_exit=early_exit)
        assert settling.stopped == "beyond_threshold" and settling.steps < settling.steps_total
        assert math.isclose(settling.settled_poses[0].position[2], ON_FLOOR, abs_tol=0.001)
        assert math.isclose(settling.jitters[0], 0.03, abs_tol=0.002)


def test_correct_three_cube_pyramid_is_valid() -> None:
    scene = shipped_scene("pyramid.yaml")
    with PhysicsChecker(scene) as checker:
        truth = ground_truth(scene)
        assert checker.find_collision(truth, scene.search.penetration_threshold) is None
        settling = checker.settle(truth, scene.search.settle_time, scene.search.angular_weight)
        assert settling.is_stable(scene.search.jitter_threshold)
        assert settling.total_jitter < scene.search.jitter_threshold


def on_groove_slope(side: int, distance: float) -> Pose:
    """The sphere touching one 30-degree slope of sphere_groove.yaml only.

    ``side`` -1 is the left slope, +1 the right; ``distance`` (m) is measured up the slope from
    the contact point of the ball resting at the bottom, where it touches both slopes.
    """
    radius, slope, vertex_height = 0.05, math.radians(30.0), 0.1
    along = distance + radius * math.tan(slope)  # from the groove's vertex to the contact point
    x = side * (along * math.cos(slope) - radius * math.sin(slope))
    z = vertex_height + along * math.sin(slope) + radius * math.cos(slope)
    return unrotated(x, 0.0, z)


@pytest.mark.parametrize("side", [-1, 1])
@pytest.mark.parametrize("distance", [0.03, 0.1, 0.15])
def test_sphere_on_the_groove_slope_is_unstable_and_settles_at_the_bottom(side: int, distance: float) -> None:
    scene = shipped_scene("sphere_groove.yaml")
    with PhysicsChecker(scene) as checker:
        on_slope = (on_groove_slope(side, distance),)
        assert checker.find_collision(on_slope, scene.search.penetration_threshold) is None
        settled, jitters = settle(checker, on_slope)
        assert jitters[0] > scene.search.jitter_threshold
        assert translation_distance(settled[0], ground_truth(scene)[0]) < 0.01


def test_the_groove_bottom_itself_is_stable() -> None:
    scene = shipped_scene("sphere_groove.yaml")
    with PhysicsChecker(scene) as checker:
        _, jitters = settle(checker, ground_truth(scene))
        assert jitters[0] <= scene.search.jitter_threshold


@pytest.mark.parametrize(
    ("dx", "dy", "wall"),
    [(-0.02, 0.0, "wall_left"), (0.02, 0.0, "wall_right"), (0.0, -0.02, "wall_front"), (0.0, 0.02, "wall_back")],
)
def test_peg_overlapping_a_wall_of_the_hole_collides_with_that_wall(dx: float, dy: float, wall: str) -> None:
    scene = shipped_scene("peg_in_hole.yaml")
    with PhysicsChecker(scene) as checker:
        collision = checker.find_collision((moved(ground_truth(scene)[0], dx, dy),), scene.search.penetration_threshold)
        assert collision is not None and collision.pair == ("peg", wall)


def test_peg_above_the_hole_settles_into_it() -> None:
    scene = shipped_scene("peg_in_hole.yaml")
    truth = ground_truth(scene)[0]
    with PhysicsChecker(scene) as checker:
        above = (moved(truth, dz=0.07),)
        assert checker.find_collision(above, scene.search.penetration_threshold) is None
        settled, jitters = settle(checker, above)
        assert jitters[0] > scene.search.jitter_threshold  # it fell: unstable where it was
        assert translation_distance(settled[0], truth) < 0.005
        assert rotation_angle(settled[0].orientation, truth.orientation) < math.radians(3.0)


def test_peg_in_the_hole_is_valid() -> None:
    # The hole's four walls touch each other and the floor: static pairs never count.
    scene = shipped_scene("peg_in_hole.yaml")
    with PhysicsChecker(scene) as checker:
        truth = ground_truth(scene)
        assert checker.find_collision(truth, scene.search.penetration_threshold) is None
        _, jitters = settle(checker, truth)
        assert jitters[0] <= scene.search.jitter_threshold


def test_same_configuration_gives_identical_results_whatever_was_checked_before() -> None:
    scene = shipped_scene("pyramid.yaml")
    truth = ground_truth(scene)
    leaning = (moved(truth[0], dx=0.03), moved(truth[1], dx=-0.03), truth[2])
    floating = (truth[0], truth[1], moved(truth[2], dz=0.06))
    params = scene.search

    def check(checker: PhysicsChecker, poses: tuple[Pose, ...]) -> tuple[object, object]:
        collision = checker.find_collision(poses, params.penetration_threshold)
        return collision, checker.settle(poses, params.settle_time, params.angular_weight)

    with PhysicsChecker(scene) as checker:
        first_truth, first_leaning = check(checker, truth), check(checker, leaning)
        check(checker, floating)
        check(checker, leaning)
        assert check(checker, truth) == first_truth
        assert check(checker, leaning) == first_leaning
    with PhysicsChecker(scene) as fresh:
        assert check(fresh, leaning) == first_leaning
        assert check(fresh, truth) == first_truth


#: Long enough (1200 steps) for the pyramid's cubes to fall, slide and come to rest.
LONG_SETTLE_TIME = 5.0
#: A ``time.monotonic()`` instant long past: every look at the clock interrupts the settling.
PAST = 0.0


def pyramid_starts() -> dict[str, tuple[Pose, ...]]:
    """Pyramid configurations that stay put, slide, fall and topple during :data:`LONG_SETTLE_TIME`."""
    truth = ground_truth(shipped_scene("pyramid.yaml"))
    tilted = Pose(truth[2].position, (0.258819, 0.0, 0.0, 0.965926))  # 30 degrees about x, one edge down
    return {
        "truth": truth,
        "leaning": (moved(truth[0], dx=0.03), moved(truth[1], dx=-0.03), truth[2]),
        "floating": (truth[0], truth[1], moved(truth[2], dz=0.06)),
        "tilted": (truth[0], moved(truth[1], dx=0.05), Pose(moved(truth[2], dz=0.04).position, tilted.orientation)),
    }


def settle_long(checker: PhysicsChecker, poses: tuple[Pose, ...]) -> Settling:
    return checker.settle(poses, LONG_SETTLE_TIME, checker.scene.search.angular_weight)


def interrupt_long(checker: PhysicsChecker, poses: tuple[Pose, ...]) -> PartialSettling:
    partial = checker.settle(poses, LONG_SETTLE_TIME, checker.scene.search.angular_weight, PAST)
    assert isinstance(partial, PartialSettling)
    return partial


def advance(checker: PhysicsChecker, partial: PartialSettling, resumes: int) -> PartialSettling:
    """Resume ``partial`` this many times, each for CLOCK_CHECK_STEPS steps."""
    for _ in range(resumes):
        outcome = checker.resume_settling(partial, PAST)
        assert isinstance(outcome, PartialSettling)
        partial = outcome
    return partial


def test_a_settling_interrupted_at_every_clock_check_ends_exactly_where_an_uninterrupted_one_does() -> None:
    scene = shipped_scene("pyramid.yaml")
    starts = pyramid_starts()
    # Twin worlds given the same configurations in the same order: one settles each at once,
    # the other is interrupted every CLOCK_CHECK_STEPS steps and resumed straight away.
    with PhysicsChecker(scene) as uninterrupted, PhysicsChecker(scene) as interrupted:
        for poses in starts.values():
            reference = settle_long(uninterrupted, poses)
            assert reference.settled_poses != poses  # the settling is not trivial: every start moves
            outcome: Settling | PartialSettling = interrupt_long(interrupted, poses)
            steps_done = []
            while isinstance(outcome, PartialSettling):
                steps_done.append(outcome.steps_done)
                outcome = interrupted.resume_settling(outcome, PAST)
            # A deadline long past stops each call after exactly CLOCK_CHECK_STEPS steps: the overrun
            # bound, and the least progress a resumed settling makes.
            total = round(LONG_SETTLE_TIME / TIME_STEP)
            assert steps_done == list(range(CLOCK_CHECK_STEPS, total, CLOCK_CHECK_STEPS))
            assert outcome == reference  # bit for bit: same poses, same jitters


def test_an_interrupted_settling_resumes_exactly_after_other_configurations_used_the_world() -> None:
    scene = shipped_scene("pyramid.yaml")
    starts = pyramid_starts()
    params = scene.search
    with PhysicsChecker(scene) as fresh:
        references = {name: settle_long(fresh, poses) for name, poses in starts.items()}
    with PhysicsChecker(scene) as checker:
        for name, poses in starts.items():
            partial = advance(checker, interrupt_long(checker, poses), 20)
            assert partial.steps_done == 21 * CLOCK_CHECK_STEPS
            for other_name, other in starts.items():
                if other_name != name:
                    checker.find_collision(other, params.penetration_threshold)
                    settle_long(checker, other)
            checker.trajectory(starts["floating"], 0.2, 0.05)
            assert checker.resume_settling(partial) == references[name]


def test_resuming_a_settling_the_checker_no_longer_keeps_starts_it_over_with_the_same_result() -> None:
    scene = shipped_scene("pyramid.yaml")
    starts = pyramid_starts()
    with PhysicsChecker(scene) as fresh:
        leaning_reference = settle_long(fresh, starts["leaning"])
        floating_reference = settle_long(fresh, starts["floating"])
    with PhysicsChecker(scene) as checker:
        leaning = interrupt_long(checker, starts["leaning"])
        floating = interrupt_long(checker, starts["floating"])  # the checker keeps this one only
        assert checker.resume_settling(leaning) == leaning_reference  # simulated again from its start
        assert checker.resume_settling(floating) == floating_reference  # restored after that
    with PhysicsChecker(scene) as other:
        assert other.resume_settling(leaning) == leaning_reference  # another checker's partial


def next_saved_state_id(checker: PhysicsChecker) -> int:
    """The id pybullet gives the next saved state of the checker's world, then frees it.

    pybullet reuses freed ids, so only states the checker leaked would push it up.
    """
    client = checker.client_id
    state = int(pybullet.saveState(physicsClientId=client))
    pybullet.removeState(state, physicsClientId=client)
    return state


def test_interrupted_settlings_never_hold_more_than_one_saved_state() -> None:
    scene = shipped_scene("pyramid.yaml")
    starts = list(pyramid_starts().values())
    with PhysicsChecker(scene) as checker:
        ids = [next_saved_state_id(checker)]
        for _ in range(10):
            for poses, other in itertools.pairwise(starts):
                # Interrupt, use the world for another configuration (which saves the interrupted one),
                # interrupt that one too (which frees the first's state), resume the first (started
                # over, which saves the second) and the second (started over, to the end).
                first = interrupt_long(checker, poses)
                checker.find_collision(other, scene.search.penetration_threshold)
                second = interrupt_long(checker, other)
                checker.resume_settling(first, PAST)
                checker.resume_settling(second)
                ids.append(next_saved_state_id(checker))
    # The initial state holds id 0 and an interrupted settling at most one more.
    assert ids[0] == 1 and max(ids) <= 2


def test_the_clearance_between_two_objects_at_given_poses_moves_no_body_and_errs_towards_touching() -> None:
    """Two cubes 3 cm apart: their clearance is within 2 mm of 3 cm and never more; beyond the cap, the cap;
    overlapping, negative; and no body moved (the cubes' own poses are where the settling left them)."""
    scene = floor_scene(cube("a"), cube("b"))
    apart = [unrotated(0.0, 0.0, ON_FLOOR), unrotated(CUBE_SIZE + 0.03, 0.0, ON_FLOOR)]
    with PhysicsChecker(scene) as checker:
        checker.settle(apart, 0.1, 0.1)
        before = checker.world.poses()
        gap = checker.clearance(0, apart[0], 1, apart[1], 0.1)
        assert 0.028 <= gap <= 0.03 + 1e-6
        assert checker.clearance(0, apart[0], 1, apart[1], 0.01) == 0.01
        assert checker.clearance(0, apart[0], 1, unrotated(CUBE_SIZE - 0.02, 0.0, ON_FLOOR), 0.1) < -0.015
        assert checker.world.poses() == before


def test_a_brick_rocking_on_another_s_studs_is_not_stopped_as_unstable_while_it_rocks() -> None:
    """The tabletop's lego bricks, one on the other's studs at poses a tracker gave: the top one tips 0.36 rad
    (J_i 4.5 cm at two looks, its position 9 mm) and rocks back to rest within the threshold. The
    conflict-directed search's early exit (``moving``) counts an object's position, not J_i, as beyond, so its
    verdict is the full settling's."""
    scene = shipped_scene("tabletop.yaml")
    params = scene.search
    bricks = [scene.object_names.index(name) for name in ("brick_a", "brick_b")]
    poses = [
        Pose((0.02245, 0.11159, 0.62321), (0.68752, -0.00777, 0.00802, 0.72608)),
        Pose((0.03151, 0.10945, 0.64451), (0.72234, 0.00057, 0.03037, 0.69087)),
    ]
    moving = early_exit_rule(params, False, moving=True)
    with PhysicsChecker(scene) as checker:
        tried = checker.settle(poses, params.settle_time, params.angular_weight, objects=bricks, early_exit=moving)
        full = checker.settle(poses, params.settle_time, params.angular_weight, objects=bricks)
    assert tried.stopped != "beyond_threshold"
    assert tried.is_stable(params.jitter_threshold) and full.is_stable(params.jitter_threshold)


def test_a_settling_ends_bit_for_bit_where_a_fresh_world_s_does_whatever_objects_earlier_work_parked() -> None:
    """The tabletop's ten meshes settled from their ground truth, in a fresh world and after work that parked
    some of them (a pair's collision pass, a settling of three, one against an object held fixed): the same
    poses, bit for bit. Bullet solves contacts in the order bodies entered its world, and parking re-enters
    a body; a world whose order depended on that history once settled a rocking part 1.6 cm apart."""
    scene = shipped_scene("tabletop.yaml")
    truth = ground_truth(scene)
    params = scene.search
    with PhysicsChecker(scene) as fresh:
        expected = fresh.settle(truth, params.settle_time, params.angular_weight)
    earlier_work: list[Callable[[PhysicsChecker], object]] = [
        lambda checker: checker.contact_depths([6, 7], truth[6:8]),
        lambda checker: checker.settle(truth[2:5], 0.1, params.angular_weight, objects=[2, 3, 4]),
        lambda checker: checker.settle(truth[6:7], 0.1, params.angular_weight, objects=[6], fixed=[(0, truth[0])]),
    ]
    for work in earlier_work:
        with PhysicsChecker(scene) as checker:
            work(checker)
            assert checker.settle(truth, params.settle_time, params.angular_weight) == expected


def test_a_settling_with_a_larger_solver_residual_ends_elsewhere_and_leaves_the_world_s_solver_as_it_was() -> None:
    """The pyramid's stack settled with Bullet's solver ending at a residual of 1e-5 rests a little elsewhere
    (its iterations ended earlier) but as stable; the next settling, without it, is bit for bit a fresh
    world's: the world went back to pybullet's residual."""
    scene = shipped_scene("pyramid.yaml")
    truth = ground_truth(scene)
    params = scene.search
    with PhysicsChecker(scene) as fresh:
        expected = fresh.settle(truth, params.settle_time, params.angular_weight)
    with PhysicsChecker(scene) as checker:
        early = checker.settle(truth, params.settle_time, params.angular_weight, solver_residual=1e-5)
        again = checker.settle(truth, params.settle_time, params.angular_weight)
    assert early.settled_poses != expected.settled_poses
    assert early.is_stable(JITTER_THRESHOLD) and expected.is_stable(JITTER_THRESHOLD)
    assert max(abs(a - b) for a, b in zip(early.jitters, expected.jitters, strict=True)) < 0.001
    assert again == expected


def cube_in_a_corner() -> Scene:
    """A cube over the floor, beside a wall whose face is the plane x = 0.2 (the wall 10 cm thick, 30 cm high)."""
    wall = StaticBody("wall", Box((0.1, 1.0, 0.3)), unrotated(0.25, 0.0, 0.15))
    return replace(floor_scene(cube("cube_a")), static=(StaticBody("floor", Plane()), wall))


MOVE_LIMIT = 0.05


def test_a_cube_seen_a_little_inside_the_floor_and_a_wall_is_moved_out_until_it_touches_both() -> None:
    with PhysicsChecker(cube_in_a_corner()) as checker:
        turned = quaternion_about_axis((0.0, 0.0, 1.0), 0.3)
        reach = ON_FLOOR * (math.cos(0.3) + math.sin(0.3))  # from its centre to its corners along x
        seen = Pose((0.2 - reach + 0.025, 0.1, ON_FLOOR - 0.02), turned)  # 2.5 cm into the wall, 2 cm into the floor
        pose = checker.moved_out_of_static(0, seen, PENETRATION_THRESHOLD, MOVE_LIMIT)
        assert pose is not None and pose.orientation == turned
        assert math.isclose(pose.position[0], 0.2 - reach, abs_tol=0.001)
        assert math.isclose(pose.position[1], seen.position[1], abs_tol=1e-9)  # along the normals only
        assert math.isclose(pose.position[2], ON_FLOOR, abs_tol=0.001)
        assert checker.static_overlap(0, pose) <= 0.001  # touching the floor and the wall, within a millimetre
        assert checker.find_collision((pose,), PENETRATION_THRESHOLD) is None


def test_a_cube_overlapping_a_static_body_within_the_threshold_is_not_moved() -> None:
    with PhysicsChecker(cube_in_a_corner()) as checker:
        seen = unrotated(0.0, 0.0, ON_FLOOR - PENETRATION_THRESHOLD / 2.0)
        assert checker.moved_out_of_static(0, seen, PENETRATION_THRESHOLD, MOVE_LIMIT) is None


@pytest.mark.parametrize("seen", [unrotated(0.0, 0.0, -0.01), unrotated(0.26, 0.0, 0.1)], ids=["floor", "wall"])
def test_a_cube_whose_centre_lies_inside_a_static_body_is_not_moved(seen: Pose) -> None:
    with PhysicsChecker(cube_in_a_corner()) as checker:
        assert checker.moved_out_of_static(0, seen, PENETRATION_THRESHOLD, MOVE_LIMIT) is None


def test_a_cube_is_not_moved_farther_than_the_limit() -> None:
    with PhysicsChecker(cube_in_a_corner()) as checker:
        seen = unrotated(0.0, 0.0, ON_FLOOR - 0.02)
        assert checker.moved_out_of_static(0, seen, PENETRATION_THRESHOLD, 0.015) is None
        assert checker.moved_out_of_static(0, seen, PENETRATION_THRESHOLD, 0.025) is not None

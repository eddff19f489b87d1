"""The two rigid-body rules in a real pybullet world (paper section III-B), on the paper's scenes."""

from __future__ import annotations

import math

import pytest
from core_builders import CUBE_SIZE, ON_FLOOR, cube, floor_scene, ground_truth, moved, shipped_scene, unrotated

from physics_mapper.geometry import Pose, rotation_angle, translation_distance
from physics_mapper.physics import PhysicsChecker
from physics_mapper.scene import Scene, SearchParams

JITTER_THRESHOLD = SearchParams().jitter_threshold
PENETRATION_THRESHOLD = SearchParams().penetration_threshold


def settle(checker: PhysicsChecker, poses: tuple[Pose, ...]) -> tuple[tuple[Pose, ...], tuple[float, ...]]:
    """Settle with the scene's own parameters; (settled poses, per-object jitters)."""
    params = checker.scene.search
    settling = checker.settle(poses, params.settle_time, params.angular_weight)
    assert settling is not None  # no deadline given
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
        assert settling is not None
        assert not settling.is_stable(JITTER_THRESHOLD)
        assert math.isclose(settling.jitters[0], 0.1, abs_tol=0.005)
        assert math.isclose(settling.settled_poses[0].position[2], ON_FLOOR, abs_tol=0.001)


def test_correct_three_cube_pyramid_is_valid() -> None:
    scene = shipped_scene("pyramid.yaml")
    with PhysicsChecker(scene) as checker:
        truth = ground_truth(scene)
        assert checker.find_collision(truth, scene.search.penetration_threshold) is None
        settling = checker.settle(truth, scene.search.settle_time, scene.search.angular_weight)
        assert settling is not None
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

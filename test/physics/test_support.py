"""What the refined map keeps of the objects it would leave out: those another object rests on."""

from __future__ import annotations

import math

from core_builders import CUBE_SIZE, ON_FLOOR, cube, floor_scene, moved, ranked, unrotated

from physics_mapper.model.geometry import Pose, make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, absent_hypothesis
from physics_mapper.model.scene import Box, Scene
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.support import (
    TOUCHING,
    held_up,
    holding,
    holding_up,
    leave_out_displaced,
    moved_away,
    present_where_likelier,
    put_back_supports,
    resting_pairs,
    within_reach,
)

#: The jitter threshold of the tests, metres.
TAU = 0.02
#: A top cube's centre height on a bottom cube.
ON_CUBE = ON_FLOOR + CUBE_SIZE


def may_be_absent(index: int, *poses: Pose) -> RankedHypotheses:
    """Poses of equal weight and *absent*, ranked last."""
    return RankedHypotheses.from_weighted([*(Hypothesis(p, 1.0) for p in poses), absent_hypothesis(index, 0.1)])


def put_back(hypotheses: list[RankedHypotheses], root: tuple[int, ...]) -> tuple[int, ...]:
    scene = floor_scene(*(cube(f"c{i}") for i in range(len(hypotheses))))
    return put_back_supports(root, hypotheses, [o.shape for o in scene.objects], scene.static, TAU)


def test_a_cube_left_out_under_a_cube_of_the_map_is_put_back() -> None:
    """The bottom cube's only pose is 1.5 cm into the floor (ruled out: the live root has it absent); the
    top cube rests on it, so it is put back at that pose, for the refinement to lift."""
    hypotheses = [may_be_absent(0, unrotated(0.0, 0.0, ON_FLOOR - 0.015)), ranked([unrotated(0.0, 0.0, ON_CUBE)], [1])]
    assert put_back(hypotheses, (2, 1)) == (1, 1)


def test_a_cube_whose_centre_lies_below_the_floor_is_not_put_back() -> None:
    """A false detection 6 cm into the floor (its centre below it) under a top cube seen 3 cm high: the top cube
    would land on the floor first, so it stays out (lifted out of the floor, it took a true cube's place)."""
    hypotheses = [
        may_be_absent(0, unrotated(0.0, 0.0, ON_FLOOR - 0.06)),
        ranked([unrotated(0.0, 0.0, ON_FLOOR + 0.03)], [1]),
    ]
    assert put_back(hypotheses, (2, 1)) == (2, 1)


def test_a_cube_bridging_two_needs_both() -> None:
    """A top cube across two bottom ones, 1 cm apart: on the one kept alone, its centre overhangs the gap."""
    hypotheses = [
        ranked([unrotated(-0.055, 0.0, ON_FLOOR)], [1]),
        may_be_absent(1, unrotated(0.055, 0.0, ON_FLOOR - 0.015)),
        ranked([unrotated(0.0, 0.0, ON_CUBE)], [1]),
    ]
    assert put_back(hypotheses, (1, 2, 1)) == (1, 1, 1)


def test_a_column_is_put_back_from_the_top_down() -> None:
    """Three cubes stacked, the lower two left out: the middle one is put back for the top one, then the
    bottom one for the middle one."""
    hypotheses = [
        may_be_absent(0, unrotated(0.0, 0.0, ON_FLOOR - 0.015)),
        may_be_absent(1, unrotated(0.0, 0.0, ON_CUBE - 0.005)),
        ranked([unrotated(0.0, 0.0, ON_CUBE + CUBE_SIZE)], [1]),
    ]
    assert put_back(hypotheses, (2, 2, 1)) == (1, 1, 1)


def test_what_holds_nothing_up_stays_out() -> None:
    """Left out and staying out: a detection inside the floor under a cube that stands on the floor, one in
    the air, and a second detection of a bottom cube that holds the top one up already."""
    hypotheses = [
        ranked([unrotated(0.0, 0.0, ON_FLOOR)], [1]),
        ranked([unrotated(0.0, 0.0, ON_CUBE)], [1]),
        may_be_absent(2, unrotated(0.3, 0.0, ON_FLOOR - 0.06)),  # in the floor, under nothing
        ranked([unrotated(0.3, 0.0, ON_FLOOR)], [1]),
        may_be_absent(4, unrotated(0.3, 0.0, 0.5)),  # in the air
        may_be_absent(5, unrotated(0.005, 0.0, ON_FLOOR - 0.015)),  # the bottom cube again, 5 mm aside
    ]
    root = (1, 1, 2, 1, 2, 2)
    assert put_back(hypotheses, root) == root


def test_the_most_probable_of_two_candidates_is_put_back_and_the_other_stays_out() -> None:
    """Two detections under the same top cube (the bottom cube and its double): one is enough."""
    bottom = unrotated(0.0, 0.0, ON_FLOOR - 0.015)
    hypotheses = [
        RankedHypotheses.from_weighted([Hypothesis(bottom, 0.3), absent_hypothesis(0, 0.7)]),
        RankedHypotheses.from_weighted([Hypothesis(bottom, 0.6), absent_hypothesis(1, 0.4)]),
        ranked([unrotated(0.0, 0.0, ON_CUBE)], [1]),
    ]
    assert hypotheses[0].is_absent(1) and hypotheses[1].is_absent(2)
    assert put_back(hypotheses, (1, 2, 1)) == (1, 1, 1)  # both left out: the likelier one is put back, alone
    assert put_back(hypotheses, (1, 1, 1)) == (1, 1, 1)  # the likelier one in: the other stays out


def five_cubes() -> tuple[list[Pose | None], Scene]:
    """A stack of two, a cube beside it, a cube left out of the map (None) under the one beside, and a cube in the
    air over the stack, 3 cm over the top cube (more than tau); their scene."""
    poses: list[Pose | None] = [
        unrotated(0.0, 0.0, ON_FLOOR),
        unrotated(0.0, 0.0, ON_CUBE),
        unrotated(0.3, 0.0, ON_CUBE),
        None,
        unrotated(0.0, 0.0, ON_CUBE + CUBE_SIZE + 0.03),
    ]
    return poses, floor_scene(*(cube(f"c{i}") for i in range(len(poses))))


def test_the_objects_holding_others_up_are_those_under_another_within_the_jitter_threshold() -> None:
    """The five cubes: only the bottom cube of the stack holds one up, and the one under the cube beside it once
    it is in the map."""
    poses, scene = five_cubes()
    assert holding_up(poses, [o.shape for o in scene.objects], TAU) == (0,)
    poses[3] = unrotated(0.3, 0.0, ON_FLOOR)
    assert holding_up(poses, [o.shape for o in scene.objects], TAU) == (0, 3)


def test_the_objects_held_up_stand_on_the_floor_or_on_another_within_the_jitter_threshold() -> None:
    """The same five: the stack stands (the floor, the bottom cube, which holds the top one up); the cube beside it
    stands only once the cube under it is in the map, which then holds it up; the cube 3 cm over the stack stands on
    nothing."""
    poses, scene = five_cubes()
    shapes = [o.shape for o in scene.objects]
    assert held_up(poses, shapes, scene.static, TAU) == {0, 1}
    assert [holding(poses, shapes, i, TAU) for i in (1, 2, 4)] == [{0}, set(), set()]
    poses[3] = unrotated(0.3, 0.0, ON_FLOOR)
    assert held_up(poses, shapes, scene.static, TAU) == {0, 1, 2, 3}
    assert holding(poses, shapes, 2, TAU) == {3}


def test_within_reach_are_the_objects_whose_boxes_come_within_the_margin() -> None:
    """A stack of two, a cube 1 cm beside the bottom one and one 5 cm beside that: what the top cube touches
    is the bottom cube; within 1 cm, the cube beside it too; within 5 cm, all four."""
    poses = [
        unrotated(0.0, 0.0, ON_FLOOR),
        unrotated(0.0, 0.0, ON_CUBE),
        unrotated(CUBE_SIZE + 0.01, 0.0, ON_FLOOR),
        unrotated(2 * CUBE_SIZE + 0.06, 0.0, ON_FLOOR),
    ]
    shapes = [o.shape for o in floor_scene(*(cube(f"c{i}") for i in range(len(poses)))).objects]
    assert within_reach(poses, shapes, {1}, TOUCHING) == {0, 1}
    assert within_reach(poses, shapes, {1}, 0.0101) == {0, 1, 2}
    assert within_reach(poses, shapes, {1, 2}, 0.0501) == {0, 1, 2, 3}


def test_what_the_refinement_moved_away_from_where_it_was_seen_is_left_out_if_it_may_be_absent() -> None:
    """Refined from ``start`` to ``settled``: a cube that fell a layer (10 cm) and may be absent is left out;
    one as far moved that may not be absent stays, as do one moved 3 cm (less than half its 10 cm) and one
    that fell a layer but on which another cube rests."""
    start = [
        unrotated(0.0, 0.0, ON_CUBE),  # fell into a hole, may be absent
        unrotated(0.3, 0.0, ON_CUBE),  # fell into a hole, named
        unrotated(0.6, 0.0, ON_FLOOR + 0.03),  # estimated 3 cm high
        unrotated(0.9, 0.0, ON_CUBE),  # fell, and another cube rests on it
        unrotated(0.9, 0.0, ON_CUBE + CUBE_SIZE),
    ]
    settled = [
        unrotated(0.0, 0.0, ON_FLOOR),
        unrotated(0.3, 0.0, ON_FLOOR),
        unrotated(0.6, 0.0, ON_FLOOR),
        unrotated(0.9, 0.0, ON_FLOOR),
        unrotated(0.9, 0.0, ON_CUBE),
    ]
    hypotheses = [
        may_be_absent(0, start[0]),
        ranked([start[1]], [1]),
        may_be_absent(2, start[2]),
        may_be_absent(3, start[3]),
        ranked([start[4]], [1]),
    ]
    scene = floor_scene(*(cube(f"c{i}") for i in range(len(start))))
    shapes = [o.shape for o in scene.objects]
    moved = moved_away(shapes, start, settled)
    assert moved == {0, 1, 3, 4}  # all but the one estimated 3 cm high
    resting = at_rest(scene, settled)
    assert resting == {(3, 4)}
    assert leave_out_displaced((1, 1, 1, 1, 1), hypotheses, shapes, moved, settled, resting, TAU) == (2, 1, 1, 1, 1)


def test_a_flat_object_that_fell_its_own_height_moved_away() -> None:
    """A flat part, 12 x 9 x 3 cm (half its largest extent 6 cm), that fell one layer (3 cm) is no longer where
    it was seen: its centre left the box its body filled (1.5 cm high either side), and so it did falling with
    a slide of 7 mm along its length. Slid 3 cm along its length, or 3 cm diagonally across its top, or sunk
    1.4 cm, it is still there."""
    shape = Box((0.12, 0.09, 0.03))
    start = unrotated(0.0, 0.0, 0.045)
    ends = [
        moved(start, dz=-0.03),
        moved(start, dx=0.007, dy=-0.005, dz=-0.029),
        moved(start, dx=0.03),
        moved(start, dx=0.021, dy=0.021),
        moved(start, dz=-0.014),
    ]
    assert moved_away([shape] * 5, [start] * 5, ends) == {0, 1}


def at_rest(scene: Scene, poses: list[Pose]) -> frozenset[tuple[int, int]]:
    """The (below, above) pairs of ``scene``'s objects resting on each other at ``poses``, from Bullet's closest
    points."""
    objects = tuple(range(len(poses)))
    with PhysicsChecker(scene) as checker:
        return resting_pairs(checker.proximities(poses, TOUCHING, objects), objects)


#: A cube turned 45 degrees about y standing on one edge beside a stack, its opposite edge 0.5 mm from the
#: bottom cube's side: it leans on the stack, the stack does not rest on it.
LEANING = make_pose(
    (CUBE_SIZE / 2 + CUBE_SIZE / math.sqrt(2) + 0.0005, 0.0, CUBE_SIZE / math.sqrt(2)),
    (0.0, math.sin(math.pi / 8), 0.0, math.cos(math.pi / 8)),
)


def test_what_rests_on_what_is_told_by_the_contact_normal_not_by_touching() -> None:
    """A stack of two cubes and a tilted cube leaning against the bottom one: the top cube rests on the bottom
    one; the leaning cube touches the bottom one along a level normal and holds nothing up."""
    poses = [unrotated(0.0, 0.0, ON_FLOOR), unrotated(0.0, 0.0, ON_CUBE), LEANING]
    scene = floor_scene(*(cube(f"c{i}") for i in range(len(poses))))
    with PhysicsChecker(scene) as checker:
        near = checker.proximities(poses, TOUCHING, (0, 1, 2))
    assert {(p.first, p.second) for p in near} >= {(0, 1), (0, 2)}  # the leaning cube touches the stack
    assert resting_pairs(near, (0, 1, 2)) == {(0, 1)}


def test_an_object_the_boxes_put_under_another_is_left_out_unless_the_other_rests_on_it() -> None:
    """A cube that fell a layer and may be absent, under a cube of the map by their boxes: kept only where the
    bodies say the upper one rests on it."""
    start = [unrotated(0.0, 0.0, ON_CUBE), unrotated(0.0, 0.0, ON_CUBE + CUBE_SIZE)]
    settled = [unrotated(0.0, 0.0, ON_FLOOR), unrotated(0.0, 0.0, ON_CUBE)]
    hypotheses = [may_be_absent(0, start[0]), ranked([start[1]], [1])]
    shapes = [o.shape for o in floor_scene(cube("c0"), cube("c1")).objects]
    assert holding_up(settled, shapes, TAU) == (0,)
    assert leave_out_displaced((1, 1), hypotheses, shapes, {0}, settled, {(0, 1)}, TAU) == (1, 1)
    assert leave_out_displaced((1, 1), hypotheses, shapes, {0}, settled, set(), TAU) == (2, 1)


def test_an_object_whose_poses_together_outweigh_its_absence_starts_the_refinement_where_they_agree() -> None:
    """*absent* ranks first in each object below (0.25 against poses of 0.20 and less), but the first object's
    poses weigh 0.75 in all and lie within 3 cm of each other: it starts at its first pose. The second's poses
    not ruled out weigh 0.20 only (its ranks 3-5 are ruled out), and the third's 0.25 in all: both stay out.
    The fourth's first pose lies 8-10 cm from the others (more than half the 10 cm cube), which agree without it
    and weigh 0.55: it starts at the first of them, its rank 3. The fifth's poses lie 20 cm apart, none agreeing
    with another: it stays out. An object at a pose is left as it is."""
    spread = [unrotated(0.01 * k, 0.0, ON_FLOOR) for k in range(4)]
    apart = [unrotated(0.11, 0.0, ON_FLOOR), *spread[1:]]
    scattered = [unrotated(0.2 * k, 0.0, ON_FLOOR) for k in range(4)]

    def weighted(index: int, poses: list[Pose], weights: list[float], absent: float) -> RankedHypotheses:
        hypotheses = [Hypothesis(p, w) for p, w in zip(poses, weights, strict=True)]
        return RankedHypotheses.from_weighted([*hypotheses, absent_hypothesis(index, absent)])

    hypotheses = [
        weighted(0, spread, [0.20, 0.20, 0.20, 0.15], 0.25),
        weighted(1, spread, [0.20, 0.20, 0.20, 0.15], 0.25),
        weighted(2, spread[:2], [0.15, 0.10], 0.75),
        weighted(3, apart, [0.20, 0.20, 0.20, 0.15], 0.25),
        weighted(4, scattered, [0.20, 0.20, 0.20, 0.15], 0.25),
        ranked([spread[0]], [1]),
    ]
    assert all(h.is_absent(1) for h in hypotheses[:5])
    assert hypotheses[3].pose(2) == apart[0] and hypotheses[3].pose(3) == spread[1]
    shapes = [o.shape for o in floor_scene(*(cube(f"c{i}") for i in range(len(hypotheses)))).objects]
    ruled_out = {(1, 3), (1, 4), (1, 5)}
    assert present_where_likelier((1,) * 6, hypotheses, shapes, ruled_out) == (2, 1, 1, 3, 1, 1)
    assert present_where_likelier((1,) * 6, hypotheses, shapes, set()) == (2, 2, 1, 3, 1, 1)

"""Interaction groups: which objects share a group, and the escape guard that merges groups.

The rule (``physics_mapper.search.groups``): an object's volume is the union of its hypotheses' body
boxes grown by half the margin; objects whose volumes meet share a group.
"""

from __future__ import annotations

import math
from dataclasses import replace

from core_builders import CUBE_SIZE, ON_FLOOR, cube, floor_scene, ranked, unrotated

from physics_mapper.model.geometry import Pose, quaternion_about_axis
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, absent_hypothesis
from physics_mapper.model.scene import Box, ObjectModel, Scene, SearchParams, Sphere, StaticBody, object_radius
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.grouped import GroupedSearch, schedule_key
from physics_mapper.search.groups import interaction_groups
from physics_mapper.search.strategy import make_search, paper_search, searchable

MARGIN = SearchParams().interaction_margin
#: Half-edge of a test cube's volume boxes (unrotated): half its edge plus half the margin.
CUBE_REACH = CUBE_SIZE / 2 + MARGIN / 2


def one(pose: Pose) -> RankedHypotheses:
    return ranked([pose], [1.0])


def test_separate_piles_are_separate_groups_and_a_pile_is_one() -> None:
    scene = floor_scene(*(cube(f"cube_{i}") for i in range(5)))
    pile = [unrotated(0.0, 0.0, ON_FLOOR), unrotated(0.0, 0.0, 3 * ON_FLOOR)]  # a stacked pair
    apart = 2 * CUBE_REACH + 0.01  # volumes 1 cm apart
    hypotheses = [
        one(pile[0]),
        one(pile[1]),
        one(unrotated(apart, 0.0, ON_FLOOR)),
        one(unrotated(2 * apart, 0.0, ON_FLOOR)),
        one(unrotated(0.0, apart, ON_FLOOR)),
    ]
    grouping = interaction_groups(scene, hypotheses, MARGIN)
    assert grouping.groups == ((0, 1), (2,), (3,), (4,))


def test_two_items_3_cm_apart_on_a_table_are_two_groups_and_a_domino_leaning_on_a_block_is_one() -> None:
    domino = ObjectModel("domino", Box((0.01, 0.05, 0.1)), mass=0.05)
    scene = floor_scene(cube("block"), cube("other"), domino)
    gap = 0.03
    # The domino (1 cm x 5 cm x 10 cm) tilted 20 degrees about y, its top resting on the block's side.
    tilt = quaternion_about_axis((0.0, 1.0, 0.0), math.radians(20.0))
    lean_x = -CUBE_SIZE / 2 - 0.05 * math.sin(math.radians(20.0)) - 0.006
    hypotheses = [
        one(unrotated(0.0, 0.0, ON_FLOOR)),
        one(unrotated(CUBE_SIZE + gap, 0.0, ON_FLOOR)),
        one(Pose((lean_x, 0.0, 0.05 * math.cos(math.radians(20.0)) + 0.005 * math.sin(math.radians(20.0))), tilt)),
    ]
    assert interaction_groups(scene, hypotheses, MARGIN).groups == ((0, 2), (1,))
    # With cubes around bounding balls, 3 cm apart was one group: r = 8.7 cm for a 10 cm cube.
    assert 2 * (object_radius(Box((CUBE_SIZE,) * 3)) + MARGIN) > CUBE_SIZE + gap


def test_objects_whose_hypotheses_could_touch_share_a_group() -> None:
    scene = floor_scene(*(cube(f"cube_{i}") for i in range(3)))
    apart = 2 * CUBE_REACH + 0.01
    # cube_1 is most likely far from cube_0, but its second hypothesis is close to it; cube_2 is far
    # from both, but cube_1's second hypothesis reaches halfway: cube_0 - cube_1 - cube_2 chain up.
    hypotheses = [
        one(unrotated(0.0, 0.0, ON_FLOOR)),
        ranked([unrotated(2 * apart, 0.0, ON_FLOOR), unrotated(apart - 0.02, 0.0, ON_FLOOR)], [0.9, 0.1]),
        one(unrotated(3 * apart - 0.02, 0.0, ON_FLOOR)),
    ]
    assert interaction_groups(scene, hypotheses, MARGIN).groups == ((0, 1, 2),)
    # Without the close hypothesis, three groups; a wider margin joins them again.
    far = [hypotheses[0], one(unrotated(2 * apart, 0.0, ON_FLOOR)), one(unrotated(4 * apart, 0.0, ON_FLOOR))]
    assert interaction_groups(scene, far, MARGIN).groups == ((0,), (1,), (2,))
    assert interaction_groups(scene, far, MARGIN + 2 * apart).groups == ((0, 1, 2),)


def test_linked_objects_stay_together_whatever_their_volumes() -> None:
    scene = floor_scene(*(cube(f"cube_{i}") for i in range(3)))
    hypotheses = [one(unrotated(i * 1.0, 0.0, ON_FLOOR)) for i in range(3)]
    assert interaction_groups(scene, hypotheses, MARGIN, linked=[{0, 2}]).groups == ((0, 2), (1,))


def test_a_grouping_joined_after_an_escape_is_the_grouping_made_with_the_link() -> None:
    scene = floor_scene(*(cube(f"cube_{i}") for i in range(6)))
    pile = [unrotated(2.0, 0.0, ON_FLOOR), unrotated(2.0, 0.0, 3 * ON_FLOOR)]
    hypotheses = [one(unrotated(i * 1.0, 0.0, ON_FLOOR)) for i in range(2)] + [one(pose) for pose in pile]
    hypotheses += [one(unrotated(3.0, 0.0, ON_FLOOR)), one(unrotated(4.0, 0.0, ON_FLOOR))]
    grouping = interaction_groups(scene, hypotheses, MARGIN, linked=[{1, 4}])
    assert grouping.groups == ((0,), (1, 4), (2, 3), (5,))
    # The escape guard joins whole groups: those of cube_0 and of the pile (found by any of their objects).
    joined = grouping.joined((0, 2, 3))
    assert joined.groups == interaction_groups(scene, hypotheses, MARGIN, linked=[{1, 4}, {0, 2, 3}]).groups
    assert joined.groups == ((0, 2, 3), (1, 4), (5,))
    assert joined.lows is grouping.lows and joined.group_of(3) == 0


# --- the escape guard: a ball rolls down a slope into a cube resting further down --------------

SLOPE_ANGLE = math.radians(20.0)
SLOPE_CENTRE = (0.0, 0.0, 0.2)
SLOPE_THICKNESS = 0.02
BALL_RADIUS = 0.04
SLOPE_ORIENTATION = quaternion_about_axis((0.0, 1.0, 0.0), SLOPE_ANGLE)  # descends towards +x


def on_slope(along: float, height: float, orientation: tuple[float, float, float, float] | None = None) -> Pose:
    """A pose ``along`` metres down the slope from its centre, centre ``height`` above its surface."""
    down = (math.cos(SLOPE_ANGLE), 0.0, -math.sin(SLOPE_ANGLE))
    normal = (math.sin(SLOPE_ANGLE), 0.0, math.cos(SLOPE_ANGLE))
    lift = SLOPE_THICKNESS / 2.0 + height
    position = tuple(c + along * d + lift * n for c, d, n in zip(SLOPE_CENTRE, down, normal, strict=True))
    return Pose((position[0], position[1], position[2]), orientation or (0.0, 0.0, 0.0, 1.0))


def slope_scene() -> Scene:
    slope = StaticBody("slope", Box((0.8, 0.3, SLOPE_THICKNESS)), Pose(SLOPE_CENTRE, SLOPE_ORIENTATION))
    ball = ObjectModel("ball", Sphere(BALL_RADIUS), mass=0.1)
    # The full settling lets the ball roll the whole 0.5 s (an early exit stops it after a centimetre).
    params = SearchParams(settle_exit="full", probability_threshold=0.0)
    return replace(floor_scene(ball, cube("cube")), static=(*floor_scene().static, slope), search=params)


def slope_hypotheses() -> tuple[RankedHypotheses, RankedHypotheses]:
    ball = ranked([on_slope(-0.25, BALL_RADIUS), on_slope(-0.27, BALL_RADIUS)], [0.7, 0.3])
    block = one(on_slope(0.08, CUBE_SIZE / 2.0, SLOPE_ORIENTATION))  # resting: the slope is not steep enough
    return ball, block


def test_a_ball_rolling_into_another_pile_merges_the_groups_and_the_search_starts_again() -> None:
    scene, hypotheses = slope_scene(), slope_hypotheses()
    assert interaction_groups(scene, hypotheses, MARGIN).groups == ((0,), (1,))
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, hypotheses, scene.search)
        assert isinstance(search, GroupedSearch)
        grouped = search.run(None)
        joint = paper_search(checker, hypotheses, scene.search).run(None)
        params = scene.search
        alone = checker.settle([hypotheses[1].pose(1)], params.settle_time, params.angular_weight, objects=(1,))
        hit = checker.settle([h.pose(1) for h in hypotheses], params.settle_time, params.angular_weight)
    assert grouped.stats.merges == 1
    assert [group.objects for group in grouped.groups] == [(0, 1)]
    assert search.links == [frozenset({0, 1})]
    # The merged group is searched from its root, both objects simulated together: as the joint search.
    assert [(e.code, e.outcome, e.moved) for e in grouped.trace] == [(e.code, e.outcome, e.moved) for e in joint.trace]
    assert all(e.group is None for e in grouped.trace)  # the merged group holds every object
    assert (grouped.valid, grouped.code) == (joint.valid, joint.code) == (False, None)
    # The cube rests where it is alone, and the ball knocks it off its place.
    assert alone.jitters[0] < 0.0001 and hit.jitters[1] > 0.003


def test_merged_objects_stay_merged_while_their_hypotheses_do_not_change() -> None:
    scene, hypotheses = slope_scene(), slope_hypotheses()
    with PhysicsChecker(scene) as checker:
        first = make_search(checker, hypotheses, scene.search)
        first.run(None)
        again = make_search(checker, hypotheses, replace(scene.search, probability_threshold=0.5), first)
        assert isinstance(again, GroupedSearch) and again.grouping.groups == ((0, 1),)
        moved_ball = (ranked([on_slope(-0.26, BALL_RADIUS)], [1.0]), hypotheses[1])
        fresh = make_search(checker, moved_ball, scene.search, again)
        assert isinstance(fresh, GroupedSearch) and fresh.grouping.groups == ((0,), (1,))


def test_a_detection_in_the_air_is_refined_before_the_pile_it_falls_onto_and_merges_with_it() -> None:
    """``fallback: refine``: a pile of two cubes and, in a group of its own, a cube 40 cm above them, which may be
    absent. The smallest group's refined map comes first (cheap; the pile's own would be made for nothing):
    the cube falls into the pile's volume, the groups merge, and the one refined map is the merged group's."""
    scene = floor_scene(cube("bottom"), cube("top"), cube("air"))
    air = RankedHypotheses((Hypothesis(unrotated(0.0, 0.0, 0.6), 0.6), absent_hypothesis(2, 0.4)))
    hypotheses = searchable((one(unrotated(0.0, 0.0, ON_FLOOR)), one(unrotated(0.0, 0.0, 3 * ON_FLOOR)), air))
    params = replace(scene.search, fallback="refine", strategy="grouped")
    assert interaction_groups(scene, hypotheses, MARGIN).groups == ((0, 1), (2,))
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, hypotheses, params)
        assert isinstance(search, GroupedSearch)
        assert min(search.groups(), key=schedule_key).objects == (2,)
        result = search.run(None)
    assert result.stats.merges == 1 and [group.objects for group in search.groups()] == [(0, 1, 2)]
    assert result.valid and result.code == (1, 1, 2)  # the cube in the air left out

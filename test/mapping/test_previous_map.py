"""The previous map first: the configuration nearest the last valid map, checked before a new search and
the tick's map only where the search finds no valid one of its own (real pybullet, the node's ROS-free tick)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from time import monotonic
from typing import Any

import pytest
from detection_builders import array, detection, result

from physics_mapper.mapping.inputs import InputSettings, check_poses, check_weights
from physics_mapper.mapping.mapper import Mapper, MapperSettings, TickReport
from physics_mapper.mapping.previous_map import (
    AGREE,
    HELD_SHARE,
    NEAR,
    PreviousMapCheck,
    check_previous_map,
    previous_map_code,
    search_with_previous_map,
    settling_goes_on,
    with_held,
)
from physics_mapper.model.geometry import IDENTITY, Pose, Quaternion, quaternion_about_axis
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, absent_hypothesis
from physics_mapper.model.scene import SearchParams
from physics_mapper.model.scene_files import scene_from_dict
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import SearchResult
from physics_mapper.search.strategy import make_search, searchable

BOX = {"shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2}
BOTTOM, TOP = (0.0, 0.0, 0.05), (0.0, 0.0, 0.15)
FLOATING = (0.0, 0.0, 0.19)  # 4 cm above TOP: it falls twice the jitter threshold
#: The joint search, its bound above p(root): it checks the root alone and ends (it expands nothing).
ROOT_ONLY = SearchParams(deadline=5.0, strategy="joint", bound="absolute", probability_threshold=0.95)
#: A generous deadline: these tests check what the tick decides, not how fast.
GENEROUS = SearchParams(deadline=5.0)
INPUTS = InputSettings(max_age=1.0)
STACK = scene_from_dict(
    {"objects": [{"name": "a", **BOX}, {"name": "b", **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
    "test",
)


def at(*positions: tuple[float, float, float]) -> RankedHypotheses:
    return RankedHypotheses(tuple(Hypothesis(Pose(p, IDENTITY), 1.0 / (i + 1)) for i, p in enumerate(positions)))


def test_each_object_takes_its_hypothesis_nearest_where_the_last_map_left_it() -> None:
    remembered = {"a": Pose(BOTTOM, IDENTITY), "b": Pose(TOP, IDENTITY)}
    far = (0.0, 0.0, 0.05 + NEAR + 0.01)
    with_absent = RankedHypotheses((Hypothesis(Pose(TOP, IDENTITY), 0.6), absent_hypothesis(2, 0.4)))
    hypotheses = (at(far, BOTTOM), at(FLOATING, (0.0, 0.005, 0.15), TOP), with_absent, at(TOP))
    # a: its rank 2 lies where a rested; b: rank 3 is nearest; c and d (not in the map): rank 1
    assert previous_map_code("abcd", hypotheses, remembered) == (2, 3, 1, 1)
    assert previous_map_code("ab", (at(far), at(FLOATING)), remembered) == (1, 1)  # none near: rank 1
    assert previous_map_code("ab", hypotheses[:2], {}) is None  # no previous map


def test_the_held_pose_ranks_last_and_only_where_a_pose_of_this_tick_lies_near_it() -> None:
    rested = Pose((0.0, 0.0, 0.05), IDENTITY)
    seen = RankedHypotheses.from_weighted(
        [Hypothesis(Pose((0.0, 0.005, 0.05), IDENTITY), 0.6), absent_hypothesis(0, 0.1), Hypothesis(rested, 0.3)]
    )
    held = with_held(seen, rested)
    assert held.held_rank() == len(held) == 4 and not held.is_absent(4) and held.pose(4) == rested
    assert held.weight(4) == HELD_SHARE * seen.weight(3)  # of the lightest, absent; outside the others' sum
    assert held.without_held() == seen  # the search's hypotheses, bit for bit: a search with them resumes
    far = RankedHypotheses.from_weighted([Hypothesis(Pose((0.0, NEAR + 0.001, 0.05), IDENTITY), 1.0)])
    assert with_held(far, rested) is far  # it moved: nothing of this tick's agrees with where it rested


def test_an_instance_seen_where_it_rested_starts_the_check_at_its_rest() -> None:
    """Its nearest pose within AGREE of where it rested: the check starts it at its *held* pose, the rest (a pose
    scattered a few millimetres can miss the studs it stood on); farther, at that pose."""
    rests = {"box_1": Pose(BOTTOM, IDENTITY), "box_2": Pose(TOP, IDENTITY)}
    seen = (0.0, AGREE - 0.001, 0.05)
    moved = (0.0, 0.0, 0.15 + AGREE + 0.002)
    hypotheses = (with_held(at(FLOATING, seen), rests["box_1"]), with_held(at(moved), rests["box_2"]))
    assert [ranked.held_rank() for ranked in hypotheses] == [3, 2]
    assert previous_map_code(("box_1", "box_2"), hypotheses, rests) == (3, 1)


def feed_poses(
    mapper: Mapper,
    name: str,
    positions: Sequence[tuple[float, float, float]],
    time: float,
    orientations: Sequence[Quaternion] | None = None,
) -> None:
    """Named input: ``positions`` (upright, or turned by ``orientations``) as hypotheses, weights 0.9, 0.1, ..."""
    turns = orientations or [IDENTITY] * len(positions)
    received = check_poses(
        list(zip(positions, turns, strict=True)),
        frame_id="world",
        expected_frame="world",
        workspace=STACK.workspace,
        stamp_ns=int(time * 1e9),
        received=time,
    )
    weights = [0.9, 0.1][: len(positions)]
    mapper.inputs.add_poses(name, received.with_weights(check_weights(weights, received=time)))


def stack_then(b_positions: Sequence[tuple[float, float, float]], params: SearchParams) -> TickReport:
    """A valid stack mapped first, then b's new hypotheses searched under ``params``."""
    mapper = Mapper(STACK)
    feed_poses(mapper, "a", [BOTTOM], 0.0)
    feed_poses(mapper, "b", [TOP], 0.0)
    first = mapper.tick(0.1, MapperSettings(GENEROUS, INPUTS, rate_hz=0.1))
    assert first.result is not None and first.result.valid and not first.result.previous_map
    feed_poses(mapper, "b", b_positions, 0.5)
    return mapper.tick(0.6, MapperSettings(params, INPUTS, rate_hz=0.1))


def test_the_previous_map_is_the_map_where_the_search_finds_no_valid_one() -> None:
    report = stack_then([FLOATING, TOP], ROOT_ONLY)
    result = report.result
    assert result is not None and result.stats.visited == 1 and result.stats.finished  # only the root, unstable
    assert result.trace[0].outcome == "unstable"
    assert result.valid and result.previous_map and result.code == (1, 2)  # b where it rested: its rank 2
    assert result.fallback is None and result.groups[0].valid and result.groups[0].code == (1, 2)


def test_the_search_s_own_valid_answer_stands() -> None:
    result = stack_then([FLOATING, TOP], GENEROUS).result
    assert result is not None and result.valid and result.code == (1, 2) and not result.previous_map


def test_what_breaks_a_rule_is_put_where_it_rested_with_what_it_touches_and_the_map_stays_valid() -> None:
    """Two confirmed instances, a stack in the last map; now the top one's only result is tilted 29 degrees on
    the bottom one (its lower edge 1.8 cm into it), centred where it rested: no configuration of this tick's
    results is valid. Each instance has one more hypothesis, *held*, where it rested in the last map; the
    previous map's check puts the top box and what it overlaps there, and that is the tick's map, valid. The
    search ranks this tick's results alone, and the remembered poses stay as they were (settled again each
    tick, a map at rest would creep). A named object has no held hypothesis: its meaning is unchanged."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": 2, **BOX}], "static": [{"name": "floor", "shape": "plane"}]}, "test"
    )
    mapper = Mapper(scene)
    for time in (0.0, 0.2, 0.4):
        mapper.add_detections(array([box_detection(BOTTOM), box_detection(TOP)]), received=time)
        first = mapper.tick(time + 0.1, MapperSettings(GENEROUS, INPUTS, rate_hz=0.1))
        assert first.result is not None and first.result.valid
    remembered = dict(mapper.memory.settled)
    tilted = result(TOP, 0.9, orientation=quaternion_about_axis((1.0, 0.0, 0.0), 0.5))
    mapper.add_detections(array([box_detection(BOTTOM), detection(tilted)]), received=0.8)
    report = mapper.tick(0.9, MapperSettings(GENEROUS, INPUTS, rate_hz=0.1))
    found = report.result
    assert found is not None and found.stats.finished and found.trace[0].outcome == "collision"
    assert [ranked.held_rank() for ranked in report.hypotheses] == [2, 2]
    assert all(entry.code == (1, 1) for entry in found.trace)  # the search's ranks: this tick's results
    assert found.valid and found.previous_map and found.code == (2, 2)
    names = report.snapshot.names
    assert [ranked.pose(2) for ranked in report.hypotheses] == [remembered[name] for name in names]
    assert mapper.memory.settled == remembered
    assert all(ranked.held_rank() is None for ranked in stack_then([TOP], GENEROUS).hypotheses)  # named


def test_a_previous_map_the_new_hypotheses_cannot_hold_is_not_used() -> None:
    result = stack_then([FLOATING], ROOT_ONLY).result  # b's only pose floats: nothing near where it rested
    assert result is not None and not result.valid and not result.previous_map


def test_where_no_valid_map_is_remembered_the_configuration_nearest_the_refined_map_is_checked() -> None:
    """The first tick: a's pose is good, b's best floats 4 cm above a and its second rests on a; the search checks
    the root alone (unstable). Its refined map rests b on a, so the configuration nearest it (b's second pose) is
    checked next, and is the tick's map, valid. Without a refined map (``fallback: none``) nothing is checked;
    a search that finds the same configuration valid itself gives its own answer."""

    def first_tick(params: SearchParams) -> SearchResult:
        mapper = Mapper(STACK)
        feed_poses(mapper, "a", [BOTTOM], 0.0)
        feed_poses(mapper, "b", [FLOATING, TOP], 0.0)
        result = mapper.tick(0.1, MapperSettings(params, INPUTS, rate_hz=0.1)).result
        assert result is not None
        return result

    result = first_tick(replace(ROOT_ONLY, fallback="refine"))
    assert result.stats.visited == 1 and result.trace[0].outcome == "unstable"
    assert result.valid and result.previous_map and result.code == (1, 2) and result.fallback is None
    assert result.settled_poses is not None and result.settled_poses[1].position == pytest.approx(TOP, abs=0.005)
    result = first_tick(ROOT_ONLY)
    assert not result.valid and not result.previous_map and result.code is None  # no map
    result = first_tick(replace(GENEROUS, fallback="refine"))
    assert result.valid and not result.previous_map and result.code == (1, 2)


def test_where_the_nearest_poses_overlap_the_check_takes_the_next_nearest() -> None:
    """The first tick: two boxes in a row, b's best pose 1.5 cm into a and its second 6 mm beside it. The search
    checks the root alone (an overlap); the refinement parts the two by moving both, so b's pose nearest where it
    rests is the overlapping one. The check then takes b's next pose near its rest, and that is the map, valid.
    Two instances the same: each has a *held* pose where the refined map rests it, but a pose of its own near
    there goes first (a collision pass each), and the map holds them at poses of their own."""
    row = scene_from_dict(
        {"objects": [{"name": "a", **BOX}, {"name": "b", **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
        "test",
    )
    settings = MapperSettings(replace(ROOT_ONLY, fallback="refine"), INPUTS, rate_hz=0.1)
    mapper = Mapper(row)
    feed_poses(mapper, "a", [BOTTOM], 0.0)
    feed_poses(mapper, "b", [(0.085, 0.0, 0.05), (0.106, 0.0, 0.05)], 0.0)
    result = mapper.tick(0.1, settings).result
    assert result is not None and result.stats.visited == 1 and result.trace[0].outcome == "collision"
    assert result.valid and result.previous_map and result.code == (1, 2)
    boxes = scene_from_dict(
        {"objects": [{"name": "box", "count": {"max": 2}, **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
        "test",
    )
    mapper = Mapper(boxes)
    mapper.add_detections(array([box_detection(BOTTOM), box_detection((0.085, 0.0, 0.05), (0.106, 0.0, 0.05))]), 0.0)
    report = mapper.tick(0.1, settings)
    assert report.result is not None and report.result.valid and report.result.previous_map
    assert report.result.code is not None and not report.absent
    assert any(ranked.held_rank() is not None for ranked in report.hypotheses)  # there to go to, but not needed
    assert all(ranked.held_rank() != rank for ranked, rank in zip(report.hypotheses, report.result.code, strict=True))


def test_where_the_nearest_pose_tips_over_the_check_takes_the_next_nearest() -> None:
    """A stack mapped; now b's best pose is tilted 20 degrees on an edge of a, 1.4 cm from where b rested, and its
    second upright on a, 1.8 cm beside it. The search checks the root alone (b tips back flat: unstable). The
    check starts b at its pose nearest where it rested, the tilted one; b, named, has no held pose and may not
    be left out, so it takes its next pose near its rest, stands, and that is the map, valid."""
    tilt = 0.35  # rad
    lowest = 0.05 * (math.cos(tilt) + math.sin(tilt))  # m, the tilted box's centre above its lowest edge
    tilted, beside = (0.0, 0.0, 0.1 + lowest + 0.001), (0.018, 0.0, 0.15)
    mapper = Mapper(STACK)
    feed_poses(mapper, "a", [BOTTOM], 0.0)
    feed_poses(mapper, "b", [TOP], 0.0)
    first = mapper.tick(0.1, MapperSettings(GENEROUS, INPUTS, rate_hz=0.1))
    assert first.result is not None and first.result.valid
    turned = quaternion_about_axis((1.0, 0.0, 0.0), tilt)
    feed_poses(mapper, "b", [tilted, beside], 0.5, orientations=[turned, IDENTITY])
    result = mapper.tick(0.6, MapperSettings(ROOT_ONLY, INPUTS, rate_hz=0.1)).result
    assert result is not None and result.stats.visited == 1 and result.trace[0].outcome == "unstable"
    assert result.valid and result.previous_map and result.code == (1, 2)


def test_what_the_last_check_put_where_it_rested_starts_there_at_the_next_frame() -> None:
    """Two instances, a stack in the last map; box_1 is seen where it rested (it starts every check at its *held*
    pose there), box_2's only pose is tilted 20 degrees on an edge of box_1 (it tips back flat) at one frame, 21
    and 22 degrees at the next two. The first check settles, sees box_2 tip, puts it at its held pose and settles
    again; the next frame's check starts it there, and passes at its first settling (a settling of a bin of 24
    takes half a tick: the repeated first one left no time for the second). For one frame only: the third
    frame's check starts box_2 at its own pose again (a wrong rest would otherwise stay the map's)."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": 2, **BOX}], "static": [{"name": "floor", "shape": "plane"}]}, "test"
    )
    rests = {"box_1": Pose(BOTTOM, IDENTITY), "box_2": Pose(TOP, IDENTITY)}

    def tipping(tilt: float) -> tuple[RankedHypotheses, ...]:
        centre = (0.0, 0.0, 0.1 + 0.05 * (math.cos(tilt) + math.sin(tilt)) + 0.001)
        on_edge = RankedHypotheses((Hypothesis(Pose(centre, quaternion_about_axis((1.0, 0.0, 0.0), tilt)), 1.0),))
        return searchable((with_held(at(BOTTOM), rests["box_1"]), with_held(on_edge, rests["box_2"])))

    with PhysicsChecker(scene) as checker:
        _, first, check = search_with_previous_map(checker, tipping(0.35), ROOT_ONLY, rests, 5.0)
        assert check is not None and check.start == (2, 1) and check.settlings == 2
        assert first.valid and first.previous_map and first.code == (2, 2)
        _, second, again = search_with_previous_map(checker, tipping(0.37), ROOT_ONLY, rests, 5.0, last=check)
        assert second.trace[0].outcome == "unstable"  # the search's own root: box_2 on its edge
        assert again is not None and again.start == (2, 1) and again.settlings == 1 and again.carried == {1}
        assert second.valid and second.previous_map and second.code == (2, 2)
        _, third, fresh = search_with_previous_map(checker, tipping(0.39), ROOT_ONLY, rests, 5.0, last=again)
    assert fresh is not None and fresh.settlings == 2 and fresh.carried == frozenset()
    assert third.valid and third.previous_map and third.code == (2, 2)


def test_a_check_that_ran_out_of_time_goes_on_after_the_search_has_its_map() -> None:
    """A check of the stack's previous map stopped for time before its settling (its deadline passed) is
    pending, its configuration unchanged. The next search of the same hypotheses goes on with it once the
    search has its answer (the root alone: b floats, unstable), and the previous map is the map, valid, after
    the one settling the first check never made."""
    floating_first = RankedHypotheses((Hypothesis(Pose(FLOATING, IDENTITY), 0.9), Hypothesis(Pose(TOP, IDENTITY), 0.1)))
    hypotheses = searchable((at(BOTTOM), floating_first))
    remembered = {"a": Pose(BOTTOM, IDENTITY), "b": Pose(TOP, IDENTITY)}
    code = previous_map_code("ab", hypotheses, remembered)
    assert code == (1, 2)
    with PhysicsChecker(STACK) as checker:
        unstarted = PreviousMapCheck(hypotheses, code, code, remembered, new=())
        cut = check_previous_map(checker, unstarted, ROOT_ONLY, monotonic() - 1.0)
        assert cut.pending and cut.settling is None and cut.code == code and cut.settlings == 0
        _, result, check = search_with_previous_map(checker, hypotheses, ROOT_ONLY, remembered, 5.0, last=cut)
    assert result.stats.visited == 1 and result.trace[0].outcome == "unstable"
    assert check is not None and not check.pending and check.settlings == 1 and check.settling is not None
    assert result.valid and result.previous_map and result.code == (1, 2)


def test_what_the_refined_map_leaves_out_the_check_leaves_out_from_the_start() -> None:
    """The first tick: the stack's b floats first (the root is unstable), and c, which may be absent, floats
    high above the floor beside it. The refined map rests b on a and leaves c out (it fell); the check of the
    configuration nearest it starts with c left out, as the refined map has it, and passes in one settling
    (c at its pose first would fall, to be left out at a second)."""
    three = scene_from_dict(
        {
            "objects": [{"name": "a", **BOX}, {"name": "b", **BOX}, {"name": "c", **BOX}],
            "static": [{"name": "floor", "shape": "plane"}],
        },
        "test",
    )
    maybe_c = RankedHypotheses((Hypothesis(Pose((0.6, 0.0, 0.5), IDENTITY), 0.6), absent_hypothesis(2, 0.4)))
    hypotheses = searchable((at(BOTTOM), at(FLOATING, TOP), maybe_c))
    params = replace(ROOT_ONLY, fallback="refine")
    with PhysicsChecker(three) as checker:
        _, result, check = search_with_previous_map(checker, hypotheses, params, {}, 5.0)
    assert result.trace[0].outcome == "unstable"
    assert check is not None and check.start == (1, 2, 2) and check.settlings == 1
    assert result.valid and result.previous_map and result.code == (1, 2, 2)


def test_the_first_tick_s_check_wins_over_a_valid_map_that_leaves_out_what_is_likelier_there() -> None:
    """The first tick: b's three poses agree (within 5 mm, 0.2 each) and each weighs less than its *absent*
    (0.4), though b is there with 0.6. The search's root leaves b out and is valid; it checks nothing more (its
    bound). Its refined map holds b where its poses agree, and the configuration nearest it, b at a pose of
    its own, passes both rules: of the two valid maps, the one whose pattern of existence is the more
    probable (b there, 0.6 against 0.4) is the map, as the search itself would have chosen had it gone on.
    Before, the search's own valid map stood, without b."""
    poses = [(0.3, 0.0, 0.05), (0.305, 0.0, 0.05), (0.3, 0.005, 0.05)]
    spread = RankedHypotheses.from_weighted(
        [*(Hypothesis(Pose(p, IDENTITY), 0.2) for p in poses), absent_hypothesis(1, 0.4)]
    )
    hypotheses = searchable((at(BOTTOM), spread))
    with PhysicsChecker(STACK) as checker:
        _, result, check = search_with_previous_map(checker, hypotheses, replace(ROOT_ONLY, fallback="refine"), {}, 5.0)
    assert spread.is_absent(1)  # absent ranks first
    assert result.trace[0].code == (1, 1) and result.trace[0].outcome == "valid" and result.stats.visited == 1
    assert check is not None and check.settling is not None
    assert result.valid and result.previous_map and result.code is not None and result.code[1] in (2, 3, 4)
    named = scene_from_dict({"objects": [{"name": "a", **BOX}], "static": [{"name": "floor", "shape": "plane"}]}, "t")
    with PhysicsChecker(named) as checker:  # nothing may be absent: no check, the search's own map stands
        _, alone, unchecked = search_with_previous_map(
            checker, (at(BOTTOM),), replace(ROOT_ONLY, fallback="refine"), {}, 5.0
        )
    assert alone.valid and not alone.previous_map and unchecked is None


def test_the_first_tick_s_check_holds_instances_where_the_refined_map_rests_them() -> None:
    """The first tick: two new boxes side by side, each of whose poses overlaps the other's by 1-1.3 cm (the
    root collides; the search checks it alone). The refinement parts the two, moving both; the check of the
    configuration nearest the refined map finds every pair of their poses overlapping, and puts both where the
    refined map rests them (their *held* poses), as a later tick's check does after a valid map. That is the
    map, valid, both boxes in it; the tick's hypotheses are the check's, whose held ranks the code names. Before,
    the check failed (no held pose to go to) and the tick's map was the refined map, invalid."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": {"max": 2}, **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
        "test",
    )
    mapper = Mapper(scene)
    left, right = [(0.0, 0.0, 0.05), (0.003, 0.0, 0.05)], [(0.09, 0.0, 0.05), (0.088, 0.0, 0.05)]
    mapper.add_detections(array([box_detection(*left), box_detection(*right)]), received=0.0)
    report = mapper.tick(0.1, MapperSettings(replace(ROOT_ONLY, fallback="refine"), INPUTS, rate_hz=0.1))
    result = report.result
    assert result is not None and result.stats.visited == 1 and result.trace[0].outcome == "collision"
    assert result.valid and result.previous_map and result.code is not None and not report.absent
    assert all(ranked.held_rank() == rank for ranked, rank in zip(report.hypotheses, result.code, strict=True))
    assert result.settled_poses is not None
    first, second = (pose.position for pose in result.settled_poses)
    assert math.dist(first, second) >= 0.1 - ROOT_ONLY.penetration_threshold  # apart, as the refined map rests them
    assert set(mapper.memory.poses) == {"box_1", "box_2"}  # a valid map: the next tick starts from it


def box_detection(*positions: Sequence[float]) -> Any:
    """A detection whose results are ``positions``, scored 0.9, 0.1, ..."""
    return detection(*(result(p, score) for p, score in zip(positions, (0.9, 0.1), strict=False)))


def test_new_instances_stay_in_the_previous_map_where_they_can_and_leave_it_where_they_fall() -> None:
    """The last map held two boxes; now box_1's best result is 4 cm up (the root is unstable), a third box
    appears on the floor and a false detection floats above the others. The previous map's configuration
    keeps box_1 where it rested, places the new box, leaves the floating one out (it fell), and ends no
    track: the next search decides (and leaves the floating one out for good)."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": {"max": 4}, **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
        "test",
    )
    mapper = Mapper(scene)
    first, second, new, floating = (0.0, 0.0, 0.05), (0.3, 0.0, 0.05), (0.6, 0.0, 0.05), (0.3, 0.0, 0.4)
    for time in (0.0, 0.3):
        mapper.add_detections(array([box_detection(first), box_detection(second)]), received=time)
    held = mapper.tick(0.4, MapperSettings(GENEROUS, INPUTS, rate_hz=0.1))
    assert held.result is not None and held.result.valid and held.absent == ("box_3", "box_4")
    lifted = (first[0], first[1], first[2] + 0.04)
    arrays = [box_detection(lifted, first), box_detection(second), box_detection(new), box_detection(floating)]
    mapper.add_detections(array(arrays), received=0.8)
    report = mapper.tick(0.9, MapperSettings(ROOT_ONLY, INPUTS, rate_hz=0.1))
    assert sorted(report.tracking.births) == ["box_3", "box_4"]
    assert report.result is not None and report.result.valid and report.result.previous_map
    names, code = report.snapshot.names, report.result.code
    assert code is not None
    placed = {name: report.hypotheses[i].pose(code[i]).position for i, name in enumerate(names)}
    (left_out,) = report.absent  # the floating one, fallen
    assert report.hypotheses[names.index(left_out)].pose(1).position == floating
    # Both where they rested (their held poses: seen there), box_1 not where its best result is.
    assert math.dist(placed["box_1"], first) < 1e-3 and math.dist(placed["box_2"], second) < 1e-3
    assert sorted(p for n, p in placed.items() if n not in ("box_1", "box_2", left_out)) == [new]
    after = mapper.tick(1.0, MapperSettings(GENEROUS, INPUTS, rate_hz=0.1))
    assert report.tracking.ends == ()  # the previous map's is no verdict
    assert after.result is not None and after.result.valid and len(after.absent) == 1


def test_until_a_map_is_valid_the_refined_map_s_rests_stand_in_for_the_previous_map() -> None:
    """A stack of three boxes of a class. The first tick: box_2 and box_3 are seen 4 cm above their places (the
    root is unstable); the refined map rests them in place, and no pose lies within ``NEAR`` of those rests: the
    tick's map is the refined map, whose rests are remembered, no pose. The next tick box_2 is seen tilted 20
    degrees on an edge of box_1, 1.4 cm from its rest, so into box_3, seen in place: the root collides, and
    leaving either out makes the other fall or tip. The check starts from the refined map's rests (box_1, seen
    where it rested, at its *held* pose there), puts the overlapping pair at their held poses, and the map is
    valid and holds all three (guided by that tick's own refined map instead, which parts the pair and sees both
    move away, the check left both out)."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": 3, **BOX}], "static": [{"name": "floor", "shape": "plane"}]}, "test"
    )
    settings = MapperSettings(replace(ROOT_ONLY, fallback="refine"), INPUTS, rate_hz=0.1)
    mapper = Mapper(scene)
    above = [box_detection(BOTTOM), box_detection(FLOATING), box_detection((0.0, 0.0, 0.29))]
    mapper.add_detections(array(above), received=0.0)
    first = mapper.tick(0.1, settings)
    assert first.result is not None and not first.result.valid and first.result.fallback == "refine"
    assert mapper.memory.poses == {} and mapper.memory.settled["box_2"].position == pytest.approx(TOP, abs=0.005)
    tilt = 0.35  # rad
    tilted = (0.0, 0.0, 0.1 + 0.05 * (math.cos(tilt) + math.sin(tilt)) + 0.001)
    lying = detection(result(tilted, orientation=quaternion_about_axis((1.0, 0.0, 0.0), tilt)))
    mapper.add_detections(array([box_detection(BOTTOM), lying, box_detection((0.0, 0.0, 0.25))], sec=2), received=0.5)
    report = mapper.tick(0.6, settings)
    result_ = report.result
    assert result_ is not None and result_.trace[0].outcome == "collision"
    assert result_.valid and result_.previous_map and result_.code is not None
    names = report.snapshot.names
    held = [name for i, name in enumerate(names) if report.hypotheses[i].hypotheses[result_.code[i] - 1].held]
    assert sorted(held) == ["box_1", "box_2", "box_3"] and report.absent == ()
    assert mapper.memory.poses["box_2"].position == pytest.approx(TOP, abs=0.005)


def test_where_only_a_refined_map_is_remembered_the_tick_makes_its_own_refined_map_before_the_check() -> None:
    """The stack, b's best pose floating (the search checks the root alone: unstable), the check's configuration
    (b where it rested) standing. Remembered from a valid map, the check runs first and passes, and the search
    runs without its fallback (no refined map: it would only stand in for the previous map). Remembered from a
    refined map only, the tick's own refined map comes first (it may be the tick's only map), then the check
    passes: the map is the previous map's either way."""
    floating_first = RankedHypotheses((Hypothesis(Pose(FLOATING, IDENTITY), 0.9), Hypothesis(Pose(TOP, IDENTITY), 0.1)))
    hypotheses = searchable((at(BOTTOM), floating_first))
    rests = {"a": Pose(BOTTOM, IDENTITY), "b": Pose(TOP, IDENTITY)}
    params = replace(ROOT_ONLY, fallback="refine")
    with PhysicsChecker(STACK) as checker:
        after_valid, valid_result, _ = search_with_previous_map(checker, hypotheses, params, rests, 5.0)
        after_refined, refined_result, _ = search_with_previous_map(
            checker, hypotheses, params, rests, 5.0, refined=True
        )
    for found in (valid_result, refined_result):
        assert found.valid and found.previous_map and found.code == (1, 2) and found.trace[0].outcome == "unstable"
    assert after_valid.result().fallback is None and after_refined.result().fallback == "refine"


def test_the_check_waits_only_for_a_settling_the_next_search_goes_on_with() -> None:
    """A search cut short in its settling of the stack: the next search with the same hypotheses of those
    objects goes on with it (the world holds it: no check then); with one of them moved it starts afresh,
    and the previous map may be checked."""
    hypotheses = searchable((at(BOTTOM), at(TOP)))
    moved = searchable((at(BOTTOM), at((0.0, 0.0, 0.151))))
    with PhysicsChecker(STACK) as checker:
        search = make_search(checker, hypotheses, GENEROUS)
        for _ in range(1000):
            if search.settling_in_progress is not None:
                break
            search.run(0.0002)
        assert search.settling_objects == (0, 1), "a run of 0.2 ms cuts the stack's settling short"
        assert settling_goes_on(search, hypotheses) and not settling_goes_on(search, moved)


def test_a_later_tick_s_check_wins_over_a_valid_map_that_leaves_out_a_part_likely_there() -> None:
    """Three boxes of a bin of up to three, seen three times where they stand 1 cm apart; then the estimator sees
    the last 1.8 cm towards its neighbour: every pose of it overlaps the neighbour. The search's valid maps leave
    one of the two out (each seen thrice, absent with 0.001); the previous map's check, the box at its *held*
    pose, holds all three: its pattern of existence is the likelier, so it is the map, and no track ends. Before,
    the search's own valid map stood, and the box it left out, placeless in a finished search, ended."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": {"max": 3}, **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
        "test",
    )
    mapper = Mapper(scene)
    row = [(0.0, 0.0, 0.05), (0.11, 0.0, 0.05), (0.22, 0.0, 0.05)]
    closer = [*row[:2], (0.22 - 0.018, 0.0, 0.05)]
    for step, positions in enumerate([row, row, row, closer]):
        mapper.add_detections(array([box_detection(p) for p in positions]), received=0.5 * step)
        report = mapper.tick(0.5 * step + 0.1, MapperSettings(GENEROUS, INPUTS, rate_hz=0.1))
    assert report.result is not None and report.result.valid and report.result.previous_map
    assert report.absent == () and report.tracking.ends == () and len(mapper.tracks.tracks) == 3


def test_a_new_instance_that_overlaps_at_its_best_pose_takes_its_next_before_it_is_left_out() -> None:
    """The last map held box_1. box_2 is new: its best pose lies 2 cm into box_1, its second beside it; box_3, a
    second detection of box_1, overlaps it at both its poses. The check keeps box_2 at its second pose and
    leaves box_3 out, and passes."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": {"max": 3}, **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
        "test",
    )

    def maybe(index: int, *positions: tuple[float, float, float]) -> RankedHypotheses:
        poses = tuple(Hypothesis(Pose(p, IDENTITY), 0.8 / (i + 1)) for i, p in enumerate(positions))
        return RankedHypotheses((*poses, absent_hypothesis(index, 0.1)))

    beside, into = (0.11, 0.0, 0.05), (0.08, 0.0, 0.05)
    hypotheses = (maybe(0, BOTTOM), maybe(1, into, beside), maybe(2, (0.01, 0.0, 0.05), (0.0, 0.01, 0.05)))
    start = (1, 1, 1)
    check = PreviousMapCheck(hypotheses, start, start, {"box_1": Pose(BOTTOM, IDENTITY)}, new=(1, 2))
    ended = check_previous_map(PhysicsChecker(scene), check, GENEROUS, None)
    assert ended.settling is not None and ended.code == (1, 2, 3)


def test_a_new_instance_that_tips_where_something_holds_it_up_takes_its_next_pose_before_it_is_left_out() -> None:
    """The last map held box_1. box_2 is new: its best pose is tilted 20 degrees on an edge of box_1 (it tips
    back flat: unstable), its second upright on it; box_3, a false detection, floats 30 cm up at both its poses.
    The first settling moves both: box_2, held up by box_1, takes its next pose, which stands in a local
    settling; box_3, held up by nothing, is left out. The second settling, the check's last, passes."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": {"max": 3}, **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
        "test",
    )
    tilt = 0.35  # rad
    lowest = 0.05 * (math.cos(tilt) + math.sin(tilt))  # m, the tilted box's centre above its lowest edge
    tilted = Pose((0.0, 0.0, 0.1 + lowest + 0.001), quaternion_about_axis((1.0, 0.0, 0.0), tilt))

    def maybe(index: int, *poses: Pose) -> RankedHypotheses:
        seen = tuple(Hypothesis(pose, 0.8 / (i + 1)) for i, pose in enumerate(poses))
        return RankedHypotheses((*seen, absent_hypothesis(index, 0.1)))

    in_the_air = (Pose((0.3, 0.0, 0.4), IDENTITY), Pose((0.31, 0.0, 0.4), IDENTITY))
    hypotheses = (maybe(0, Pose(BOTTOM, IDENTITY)), maybe(1, tilted, Pose(TOP, IDENTITY)), maybe(2, *in_the_air))
    start = (1, 1, 1)
    check = PreviousMapCheck(hypotheses, start, start, {"box_1": Pose(BOTTOM, IDENTITY)}, new=(1, 2))
    ended = check_previous_map(PhysicsChecker(scene), check, GENEROUS, None)
    assert ended.settling is not None and ended.code == (1, 2, 3) and ended.settlings == 2


def test_a_new_instance_whose_poses_together_outweigh_its_absence_starts_the_check_where_they_agree() -> None:
    """The last map held box_1. box_2 is new, seen three times within 3 mm, each pose weighing 0.2 against its
    *absent*'s 0.4, which ranks first. The search checks its root alone (box_2 absent: valid); the check starts
    box_2 where its poses agree (0.6 in all, more likely there than not), passes, and its pattern of existence
    is the likelier: box_2 is in the map. Started at rank 1, the check was the search's root."""
    scene = scene_from_dict(
        {"objects": [{"name": "box", "count": {"max": 2}, **BOX}], "static": [{"name": "floor", "shape": "plane"}]},
        "test",
    )
    seen = [(0.3, 0.0, 0.05), (0.303, 0.0, 0.05), (0.3, 0.003, 0.05)]
    box_2 = RankedHypotheses((absent_hypothesis(1, 0.4), *(Hypothesis(Pose(p, IDENTITY), 0.2) for p in seen)))
    box_1 = RankedHypotheses((Hypothesis(Pose(BOTTOM, IDENTITY), 0.9), absent_hypothesis(0, 0.1)))
    remembered = {"box_1": Pose(BOTTOM, IDENTITY)}
    _, result, check = search_with_previous_map(PhysicsChecker(scene), (box_1, box_2), ROOT_ONLY, remembered, None)
    assert check is not None and check.start == (1, 2)
    assert result.valid and result.previous_map and result.code == (1, 2)

"""Existence decided by physics: absent hypotheses for instances that may not be there and for silent
objects, through the node's ROS-free tick (:class:`Mapper`), with real pybullet."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from core_builders import CUBE_SIZE, ON_FLOOR, cube, floor_scene, ranked, unrotated
from detection_builders import array, detection, result

from physics_mapper.mapping.existence import (
    MapMemory,
    holding_others_up,
    left_out_by_physics,
    silent_absent_weight,
)
from physics_mapper.mapping.inputs import InputSettings, check_poses, check_weights
from physics_mapper.mapping.mapper import Mapper, MapperSettings, TickReport
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, absent_hypothesis
from physics_mapper.model.scene import Scene, SearchParams
from physics_mapper.model.scene_files import scene_from_dict
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.strategy import make_search, paper_search

BOX = {"shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2}
FLOOR = {"name": "floor", "shape": "plane"}
#: A generous deadline: these tests check what the search decides, not how fast.
SETTINGS = MapperSettings(SearchParams(deadline=5.0), InputSettings(max_age=1.0), rate_hz=0.1)


def make_scene(*objects: dict[str, Any], static: Sequence[dict[str, Any]] = ()) -> Scene:
    return scene_from_dict({"objects": list(objects), "static": [FLOOR, *static]}, "test")


def feed(mapper: Mapper, positions: Sequence[Sequence[float]], time: float) -> None:
    """One array: a detection per position (two results each: the true pose best, one 5 cm up), in this order."""
    detections = [detection(result(p, 0.9), result((p[0], p[1], p[2] + 0.05), 0.1)) for p in positions]
    mapper.add_detections(array(detections), received=time)


def present(report: TickReport) -> dict[str, tuple[float, ...]]:
    """The objects the map holds -> their chosen positions, rounded to the millimetre."""
    assert report.result is not None and report.result.poses is not None
    chosen = zip(report.snapshot.objects, report.result.poses, strict=True)
    return {s.name: tuple(np.round(p.position, 3).tolist()) for s, p in chosen if s.name not in report.absent}


FLOOR_BOXES = [(0.0, 0.0, 0.05), (0.3, 0.0, 0.05), (0.6, 0.0, 0.05)]


def test_a_floating_false_positive_is_absent_and_the_rest_valid() -> None:
    mapper = Mapper(make_scene({"name": "box", "count": {"max": 4}, **BOX}))
    floating = (0.3, 0.3, 0.4)
    feed(mapper, [floating, *FLOOR_BOXES], 0.0)  # the false positive listed first
    report = mapper.tick(0.1, SETTINGS)
    assert report.result is not None and report.result.valid
    assert sorted(present(report).values()) == sorted(FLOOR_BOXES)  # the rest valid
    (left_out,) = report.absent  # the floating one: left out, not invalidating the map
    index = report.snapshot.names.index(left_out)
    assert report.hypotheses[index].pose(1).position == floating
    assert report.result.code is not None and report.hypotheses[index].is_absent(report.result.code[index])
    assert sorted(report.tracking.births) == ["box_1", "box_2", "box_3", "box_4"]


def test_a_false_positive_inside_a_static_body_is_absent() -> None:
    wall = {"name": "wall", "shape": "box", "size": [0.1, 0.4, 0.3], "pose": {"position": [0.3, 0.4, 0.15]}}
    mapper = Mapper(make_scene({"name": "box", "count": {"max": 4}, **BOX}, static=[wall]))
    feed(mapper, [*FLOOR_BOXES, (0.3, 0.4, 0.05)], 0.0)
    report = mapper.tick(0.1, SETTINGS)
    assert report.result is not None and report.result.valid
    (left_out,) = report.absent
    assert report.hypotheses[report.snapshot.names.index(left_out)].pose(1).position == (0.3, 0.4, 0.05)


def test_a_double_detection_of_a_present_box_is_one_instance() -> None:
    mapper = Mapper(make_scene({"name": "box", "count": {"max": 3}, **BOX}))
    two = FLOOR_BOXES[:2]
    for time in (0.0, 0.5):
        feed(mapper, two, time)
    mapper.tick(0.6, SETTINGS)
    feed(mapper, [(0.006, 0.0, 0.05), *two], 1.0)  # box 1 detected twice, 6 mm apart, the copy first
    report = mapper.tick(1.1, SETTINGS)
    assert report.tracking.births == () and report.tracking.doubles == 1  # the copy: within box_1's gate
    assert report.result is not None and report.result.valid
    assert report.absent == ("box_3",) and present(report) == {"box_1": two[0], "box_2": two[1]}


def poses_input(positions: Sequence[Sequence[float]], time: float) -> Any:
    received = check_poses(
        [((*p,), (0.0, 0.0, 0.0, 1.0)) for p in positions],
        frame_id="world",
        expected_frame="world",
        workspace=SCENE_OF_THREE.workspace,
        stamp_ns=int(time * 1e9),
        received=time,
    )
    return received.with_weights(check_weights([1.0] * len(positions), received=time))


SCENE_OF_THREE = make_scene({"name": "a", **BOX}, {"name": "b", **BOX}, {"name": "c", **BOX})
BOTTOM, TOP, ALONE = (0.0, 0.0, 0.05), (0.0, 0.0, 0.15), (0.4, 0.0, 0.05)


def test_a_silent_named_object_never_stops_the_map_and_is_kept_where_another_rests_on_it() -> None:
    mapper = Mapper(SCENE_OF_THREE)
    for name, position in zip("abc", (BOTTOM, TOP, ALONE), strict=True):
        mapper.inputs.add_poses(name, poses_input([position], 0.0))
    first = mapper.tick(0.1, SETTINGS)
    assert first.result is not None and first.result.valid and first.absent == ()
    for time in (0.8, 1.6, 2.4):  # only b is seen from now on: a and c fall silent after max_age (1 s)
        mapper.inputs.add_poses("b", poses_input([TOP], time))
        report = mapper.tick(time + 0.1, SETTINGS)
        assert report.result is not None and report.result.valid  # the map never stops
    assert report.absent == ("c",)  # nothing needs c: it leaves the map
    assert present(report) == {"a": BOTTOM, "b": TOP}  # b rests on a: a is kept where it was


def test_a_named_object_never_seen_does_not_stop_the_map_of_the_others() -> None:
    mapper = Mapper(SCENE_OF_THREE)
    assert mapper.tick(0.0, SETTINGS).result is None  # nothing seen yet: waiting
    mapper.inputs.add_poses("c", poses_input([ALONE], 0.1))
    report = mapper.tick(0.2, SETTINGS)
    assert report.result is not None and report.result.valid
    assert report.absent == ("a", "b") and present(report) == {"c": ALONE}


def test_an_instance_ends_after_max_age_and_leaves_the_map() -> None:
    mapper = Mapper(make_scene({"name": "box", "count": 2, **BOX}))
    for time in (0.0, 0.3, 0.6):
        feed(mapper, FLOOR_BOXES[:2], time)
    assert mapper.tick(0.7, SETTINGS).absent == ()
    ends: list[str] = []
    for time in (1.0, 1.5, 2.0):
        feed(mapper, FLOOR_BOXES[:1], time)  # box 2 picked away
        report = mapper.tick(time + 0.1, SETTINGS)
        ends += report.tracking.ends
    assert ends == ["box_2"] and report.absent == ("box_2",)
    assert report.result is not None and report.result.valid and present(report) == {"box_1": FLOOR_BOXES[0]}


def test_no_configuration_only_swaps_identical_instances() -> None:
    """Each observation is fixed to one instance, so no two visited configurations are the same boxes
    in the same places under other names (a joint exhaustive search, every configuration visited)."""
    mapper = Mapper(make_scene({"name": "box", "count": 3, **BOX}))
    near = [(0.0, 0.0, 0.05), (0.105, 0.0, 0.05), (0.21, 0.0, 0.05)]
    for time, order in ((0.0, near), (0.2, near[::-1]), (0.4, near[1:] + near[:1])):  # confirmed: always there
        feed(mapper, order, time)
        mapper.tick(time + 0.1, SETTINGS)
    exhaustive = SearchParams(deadline=5.0, strategy="joint", probability_threshold=0.0, bound="absolute")
    report = mapper.tick(0.6, MapperSettings(exhaustive, InputSettings(max_age=1.0), rate_hz=0.1))
    assert report.result is not None and report.result.stats.end == "exhausted"
    trace = report.result.trace
    assert len(trace) == 2**3  # three instances, two hypotheses each
    placements = {
        tuple(sorted(tuple(h.pose(rank).position) for h, rank in zip(report.hypotheses, entry.code, strict=True)))
        for entry in trace
    }
    assert len(placements) == len(trace)  # no configuration is another's with instances swapped


def test_a_persistent_impossible_detection_is_never_confirmed() -> None:
    """A reflection detected in the air in every frame: physics leaves it out each time, so its track stays
    tentative and a count: K scene keeps a valid map (a confirmed instance of count: K would have no absent)."""
    mapper = Mapper(make_scene({"name": "box", "count": 4, **BOX}))
    for step in range(5):
        feed(mapper, [*FLOOR_BOXES, (0.3, 0.3, 0.4)], 0.5 * step)
        report = mapper.tick(0.5 * step + 0.1, SETTINGS)
        assert report.result is not None and report.result.valid
        assert report.absent == ("box_4",)  # the one at (0.3, 0.3): the highest, born last
    assert "box_4" not in mapper.tracks.tracks  # ended by the map at every tick: never confirmed


def test_a_silent_object_s_absent_weight_starts_at_one_half_and_grows() -> None:
    weights = [silent_absent_weight(silence, max_age=2.0) for silence in (0.0, 1.0, 2.0, 10.0)]
    assert weights[0] == 0.5 and weights == sorted(weights) and weights[-1] > 0.99


def test_a_finished_search_leaves_an_instance_out_for_good_a_valid_map_cut_short_once_it_is_repeated() -> None:
    """A tentative instance left out by a finished search ends; left out by a valid map of a search the
    deadline stopped, it is *cut short* (its track ends once such maps repeat it); left out by an invalid
    map of a stopped search, it keeps its track (that choice is the best so far, no verdict)."""
    mapper = Mapper(make_scene({"name": "box", "count": {"max": 4}, **BOX}))
    # The fourth box 7 cm from the first, 3 cm into it: one of the two is left out (not ruled out alone).
    feed(mapper, [*FLOOR_BOXES, (0.07, 0.0, 0.05)], 0.0)
    report = mapper.tick(0.1, SETTINGS)
    assert report.result is not None and report.result.stats.finished and len(report.absent) == 1
    assert (report.absent[0], 1) not in {(r.object, r.rank) for r in report.result.ruled_out}
    names, result = report.snapshot.names, report.result
    assert left_out_by_physics(names, report.hypotheses, result) == (report.absent, ())
    stopped = replace(result, stats=replace(result.stats, end=None))  # as if the deadline had come first
    assert left_out_by_physics(names, report.hypotheses, stopped) == ((), report.absent)  # but valid
    assert left_out_by_physics(names, report.hypotheses, replace(stopped, valid=False)) == ((), ())
    assert report.absent[0] not in mapper.tracks.tracks  # the finished search ended it


def test_an_instance_in_free_fall_at_every_rank_ends_whatever_the_search() -> None:
    """Every pose of the floating detection is ruled out before the search (Rule 2, free fall): no
    configuration holds it, a verdict even from a search the deadline stopped without a valid map."""
    mapper = Mapper(make_scene({"name": "box", "count": {"max": 4}, **BOX}))
    feed(mapper, [*FLOOR_BOXES, (0.3, 0.3, 0.4)], 0.0)
    report = mapper.tick(0.1, SETTINGS)
    assert report.result is not None and len(report.absent) == 1
    (floating,) = report.absent
    ranked = report.hypotheses[report.snapshot.names.index(floating)]
    ruled = [r for r in report.result.ruled_out if r.object == floating]
    assert {r.reason for r in ruled} == {"floating"}
    assert {r.rank for r in ruled} == {k for k in range(1, len(ranked) + 1) if not ranked.is_absent(k)}
    stopped = replace(report.result, valid=False, stats=replace(report.result.stats, end=None))
    assert left_out_by_physics(report.snapshot.names, report.hypotheses, stopped) == ((floating,), ())


def test_a_map_that_fails_the_rules_confirms_no_instance() -> None:
    """A false detection inside a wall, seen while no map is valid (two confirmed boxes overlap), is held
    by each fallback map; were that to confirm it, it would lose its *absent* and, its every pose in the
    wall ruled out, leave the next searches no configuration at all (0 visited). It stays tentative, and
    once the boxes are apart again physics leaves it out of a valid map."""
    wall = {"name": "wall", "shape": "box", "size": [0.1, 0.4, 0.3], "pose": {"position": [0.3, 0.4, 0.15]}}
    mapper = Mapper(make_scene({"name": "box", "count": 4, **BOX}, static=[wall]))
    # One interaction group: the fallback's map (the root, each object's first rank) holds the wall's one.
    settings = replace(SETTINGS, search=replace(SETTINGS.search, fallback="refine", interaction_margin=1.0))
    apart = [(0.0, 0.0, 0.05), (0.11, 0.0, 0.05), (0.6, 0.0, 0.05)]
    overlapping = [(0.0, 0.0, 0.05), (0.07, 0.0, 0.05), (0.6, 0.0, 0.05)]  # box_2 3 cm into box_1
    in_wall = (0.3, 0.4, 0.05)
    for step in range(3):  # box_1..box_3 confirmed: matched 3 times, held by valid maps
        feed(mapper, apart, 0.5 * step)
        report = mapper.tick(0.5 * step + 0.1, settings)
        assert report.result is not None and report.result.valid
    for step in range(3, 6):
        feed(mapper, [*overlapping, in_wall], 0.5 * step)
        report = mapper.tick(0.5 * step + 0.1, settings)
        assert report.result is not None and not report.result.valid and report.result.fallback == "refine"
        assert report.tracking.births == (() if step == 3 else ("box_4",)) or step == 3
        # held by the fallback's map, never confirmed by it: its every pose in the wall, it ends at each tick
        assert "box_4" not in mapper.tracks.tracks
    feed(mapper, [*apart, in_wall], 3.0)
    report = mapper.tick(3.1, settings)
    assert report.result is not None and report.result.valid and report.result.stats.visited > 0
    assert report.absent == ("box_4",)
    assert "box_4" not in mapper.tracks.tracks


def test_two_confirmed_tracks_on_one_body_keep_one_and_the_map_is_valid_again() -> None:
    """A row of seven boxes 1 cm apart and an eighth whose detections come closer step by step until they lie
    6 cm from the first's (a second detection of one box, a few centimetres off, tracked as an instance of its
    own). All confirmed, none may be absent: once every pose of the eighth overlaps every pose of the first,
    no configuration holds both and every search would end with none valid. The twins' rule ends one of the
    two tracks, and the next maps are valid."""
    mapper = Mapper(make_scene({"name": "box", "count": 8, **BOX}))
    row = [(0.0, 0.11 * k, 0.05) for k in range(7)]
    reports = []
    for step, x in enumerate(np.arange(0.3, 0.05, -0.02)):
        feed(mapper, [*row, (float(x), 0.0, 0.05)], 0.5 * step)
        reports.append(mapper.tick(0.5 * step + 0.1, SETTINGS))
        if step == 3:
            assert not any(mapper.tracks.tentative(f"box_{k}") for k in range(1, 9))  # all confirmed
    invalid = [k for k, report in enumerate(reports) if report.result is None or not report.result.valid]
    assert invalid, "the eighth box never overlapped the first"
    assert len(mapper.tracks.tracks) == 7  # one of the twins' tracks ended
    assert invalid[-1] < len(reports) - 1  # and the maps after it are valid again
    assert all(r.result is not None and r.result.valid for r in reports[invalid[-1] + 1 :])


def test_two_neighbours_seen_overlapping_in_one_frame_are_no_twins_where_the_map_holds_both() -> None:
    """A row of seven boxes 1 cm apart, confirmed; in one frame the estimator sees the first two 1.5 cm towards
    each other, so that every pose of one overlaps every pose of the other, as with a second detection of one
    box. The previous map's check holds both where they rested: the map is valid and holds two bodies there, so
    neither track ends (the twins' rule ended one, and its name went to the next box born)."""
    mapper = Mapper(make_scene({"name": "box", "count": 7, **BOX}))
    row = [(0.11 * k, 0.0, 0.05) for k in range(7)]
    closer = [(0.015, 0.0, 0.05), *((x - 0.015, y, z) for x, y, z in row[1:])]
    for step, positions in enumerate([row, row, row, closer]):
        feed(mapper, positions, 0.5 * step)
        report = mapper.tick(0.5 * step + 0.1, SETTINGS)
    assert report.result is not None and report.result.valid and report.result.previous_map
    assert {(r.object, r.other, r.reason) for r in report.result.ruled_out} == {("box_1", "box_2", "collision")}
    assert sorted(present(report)) == [f"box_{k}" for k in range(1, 8)]
    assert len(mapper.tracks.tracks) == 7 and report.tracking.ends == ()


def test_an_instance_the_refined_map_keeps_under_another_is_not_placeless() -> None:
    """A bottom box that may be absent, seen only 1.5 cm into the floor (every pose ruled out alone), under
    a box: the refined map keeps it (:mod:`physics_mapper.physics.support`), so physics found it a place and
    its track goes on; left out, it would be placeless and its track would end."""
    scene = floor_scene(cube("bottom"), cube("top"))
    sunk = unrotated(0.0, 0.0, ON_FLOOR - 0.015)
    hypotheses = (
        RankedHypotheses.from_weighted([Hypothesis(sunk, 0.9), absent_hypothesis(0, 0.1)]),
        ranked([unrotated(0.0, 0.0, ON_FLOOR + CUBE_SIZE)], [1]),
    )
    with PhysicsChecker(scene) as checker:
        result = make_search(checker, hypotheses, SearchParams(fallback="refine")).run(None)
    assert result.fallback == "refine" and result.code == (1, 1)
    assert [(r.object, r.rank) for r in result.ruled_out] == [("bottom", 1)]
    assert left_out_by_physics(("bottom", "top"), hypotheses, result) == ((), ())
    assert left_out_by_physics(("bottom", "top"), hypotheses, replace(result, code=(2, 1))) == (("bottom",), ())


def test_a_refined_map_stopped_in_its_settling_holds_nothing_up_and_is_not_remembered() -> None:
    """A box 1 cm over another, nothing valid: the refined map the deadline stopped within its settling (driven
    a piece at a time) is the depenetrated poses, which say nothing of what rests on what; the finished one says
    the bottom box holds the top one up, and its rests are remembered for the next tick's check."""
    scene = floor_scene(cube("bottom"), cube("top"))
    names = ("bottom", "top")
    hypotheses = (
        ranked([unrotated(0.0, 0.0, ON_FLOOR)], [1]),
        ranked([unrotated(0.0, 0.0, ON_FLOOR + CUBE_SIZE + 0.01)], [1]),
    )
    params = SearchParams(fallback="refine")
    with PhysicsChecker(scene) as checker:
        search = paper_search(checker, hypotheses, params)
        while search.result().code is None:
            search.step(0.0)  # a deadline already past: one piece of the refinement
        unsettled = search.result()
        finished = paper_search(checker, hypotheses, params).run(None)
    assert unsettled.unsettled and unsettled.settled_poses == hypotheses_poses(hypotheses)
    assert not finished.unsettled and finished.fallback == "refine"
    assert holding_others_up(names, hypotheses, unsettled, scene) == ()
    assert holding_others_up(names, hypotheses, finished, scene) == ("bottom",)
    memory = MapMemory()
    memory.remember(names, hypotheses, unsettled)
    assert memory.settled == {}
    memory.remember(names, hypotheses, finished)
    assert memory.refined and set(memory.settled) == set(names)


def hypotheses_poses(hypotheses: Sequence[RankedHypotheses]) -> tuple[Pose, ...]:
    return tuple(h.pose(1) for h in hypotheses)


def test_misses_do_not_end_a_track_seen_once_on_which_the_map_holds_another_up() -> None:
    """Three boxes seen once, two stacked and one beside them; then only the top box, twice: the box
    beside them, missed twice, ends (a false detection seldom comes back), the bottom box, as often missed
    (the camera sees the top of a stack), keeps its track and its place under the top one."""
    mapper = Mapper(make_scene({"name": "box", "count": 3, **BOX}))
    bottom, top, beside = (0.0, 0.0, 0.05), (0.0, 0.0, 0.15), (0.3, 0.0, 0.05)
    mapper.add_detections(array([detection(result(p, 0.9)) for p in (bottom, top, beside)]), received=0.0)
    first = mapper.tick(0.1, SETTINGS)
    assert first.result is not None and first.result.valid and first.absent == ()
    names = {position: name for name, position in present(first).items()}
    for time in (0.4, 0.8):  # within SETTINGS' max_age of the first array
        mapper.add_detections(array([detection(result(top, 0.9))]), received=time)
        report = mapper.tick(time + 0.1, SETTINGS)
    assert names[beside] not in mapper.tracks.tracks
    assert names[bottom] in mapper.tracks.tracks and mapper.tracks.tentative(names[bottom])
    assert report.result is not None and report.result.valid
    assert present(report) == {names[bottom]: bottom, names[top]: top}


def test_a_track_born_between_two_layers_follows_where_the_map_rests_its_part() -> None:
    """Two jenga-like blocks (15 x 5 x 3 cm), one on the other. The first array misses the bottom one and
    estimates the top one half-way down, 1.6 cm above the floor, a little nearer the top block's place than
    the bottom one's: the map rests it on the floor, in the bottom block's place. The next array sees both:
    the name the map gave the block on the floor stays on the block on the floor (from its first estimate
    alone, its track would take the top block's detection, and the name would jump a layer up)."""
    block = {"name": "block", "shape": "box", "size": [0.15, 0.05, 0.03], "mass": 0.05, "count": {"max": 2}}
    mapper = Mapper(make_scene(block))
    settings = replace(SETTINGS, search=SearchParams(deadline=5.0, jitter_threshold=0.02))
    bottom, top = (0.0, 0.0, 0.015), (0.0, 0.0, 0.045)
    mapper.add_detections(array([detection(result((0.0, 0.0, 0.031), 0.9, class_id="block"))]), received=0.0)
    first = mapper.tick(0.1, settings)
    assert first.result is not None and first.result.valid and first.result.settled_poses is not None
    (on_floor,) = present(first)  # the other instance was never seen
    assert first.result.settled_poses[0].position[2] < bottom[2] + 0.003  # at rest on the floor
    seen = [detection(result(p, 0.9, class_id="block")) for p in (top, bottom)]
    mapper.add_detections(array(seen), received=0.5)
    second = mapper.tick(0.6, settings)
    assert second.result is not None and second.result.valid
    assert present(second)[on_floor] == bottom

"""Detections of identical instances, associated across frames: the rules of ``mapping.association``.

Arrays are built as rosbags decodes them (``detection_builders``, a helper module of test/).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from detection_builders import array, detection, result

from physics_mapper.mapping.association import AssociationSettings, InstanceTracks
from physics_mapper.mapping.detections import detection_inputs
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import scene_from_dict

#: Six 10 cm cubes: four on the floor 1 cm apart, two on top.
BIN = [(0.0, 0.0, 0.05), (0.11, 0.0, 0.05), (0.0, 0.11, 0.05), (0.11, 0.11, 0.05), (0.0, 0.0, 0.15), (0.11, 0.11, 0.15)]


def bin_scene(count: Any = 6) -> Scene:
    box = {"name": "box", "shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2, "count": count}
    return scene_from_dict({"objects": [box], "static": [{"name": "floor", "shape": "plane"}]}, "bin")


def positions_of(inputs: Any) -> dict[str, tuple[float, ...]]:
    """Each instance's first hypothesis position, rounded to the millimetre."""
    return {name: tuple(np.round(poses.poses[0, :3], 3).tolist()) for name, poses in inputs.objects.items()}


def frames(count: int, seed: int = 0, missing: int | None = None, missed_frame: int = 3) -> list[list[Any]]:
    """``count`` frames of the bin, each shuffled, 2 mm of noise, three results (sometimes a wrong one first)."""
    rng = np.random.default_rng(seed)
    made = []
    for frame in range(count):
        detections = []
        for index, centre in enumerate(BIN):
            if index == missing and frame == missed_frame:
                continue
            true = tuple(np.asarray(centre) + rng.normal(0.0, 0.002, 3))
            wrong = tuple(np.asarray(true) + np.array([0.03, -0.02, 0.01]))
            first, second = (wrong, true) if rng.random() < 0.3 else (true, wrong)
            detections.append(detection(result(first, 0.6), result(second, 0.3), result(true, 0.1)))
        rng.shuffle(detections)
        made.append(detections)
    return made


def nearest_box(position: tuple[float, ...]) -> int:
    return int(np.argmin([np.linalg.norm(np.asarray(position) - centre) for centre in BIN]))


def identities(scene: Scene, arrays: list[list[Any]], tracks: InstanceTracks) -> list[dict[str, int]]:
    """Per frame, each instance -> the true box its detection came from (by its true result's place)."""
    seen = []
    for frame, detections in enumerate(arrays):
        inputs = detection_inputs(array(detections), scene, received=float(frame), tracks=tracks)
        tracks.keep(list(inputs.objects))  # as a map holding every instance detected would
        seen.append({name: nearest_box(tuple(p.poses[-1, :3])) for name, p in inputs.objects.items()})
    return seen


def test_shuffled_order_keeps_identities() -> None:
    scene = bin_scene()
    tracks = InstanceTracks(scene)
    seen = identities(scene, frames(12), tracks)
    first = seen[0]
    assert sorted(first.values()) == list(range(6))  # each box one instance
    assert all(frame == first for frame in seen)
    assert tracks.births == 6 and tracks.ends == 0


def test_a_first_frame_names_the_boxes_the_same_way_in_any_order() -> None:
    scene = bin_scene()
    (first,) = frames(1, seed=5)
    named = [
        identities(scene, [order], InstanceTracks(scene))[0] for order in (first, first[::-1], first[2:] + first[:2])
    ]
    assert named[0] == named[1] == named[2]


def test_a_stable_id_wins_over_distance() -> None:
    scene = bin_scene(2)
    tracks = InstanceTracks(scene)
    a, b = (0.0, 0.0, 0.05), (0.3, 0.0, 0.05)
    detection_inputs(
        array([detection(result(a), key="7"), detection(result(b), key="9")]), scene, received=0.0, tracks=tracks
    )
    # the tracker upstream says 7 is now where 9 was (and 9 where 7 was): the ids decide
    swapped = array([detection(result(b), key="7"), detection(result(a), key="9")])
    inputs = detection_inputs(swapped, scene, received=0.5, tracks=tracks)
    assert positions_of(inputs) == {"box_1": b, "box_2": a}


@pytest.mark.parametrize("missed_frame", [1, 3])  # while the track is tentative, and once it is confirmed
def test_a_miss_neither_duplicates_nor_loses(missed_frame: int) -> None:
    scene = bin_scene()
    tracks = InstanceTracks(scene)
    seen = identities(scene, frames(missed_frame + 2, seed=3, missing=2, missed_frame=missed_frame), tracks)
    missed = next(name for name, box in seen[0].items() if box == 2)
    during, after = seen[missed_frame], seen[missed_frame + 1]
    assert missed not in during and len(during) == 5
    assert {n: b for n, b in seen[0].items() if n != missed} == during  # nobody took the missed box's place
    assert after == seen[0]  # and it is its own again
    # confirmed or tentative, an instance keeps its own track through one miss (tentative_misses: 2)
    assert tracks.ends == 0


def test_an_instance_ends_after_max_age_and_its_name_is_free_again() -> None:
    scene = bin_scene(2)
    tracks = InstanceTracks(scene, AssociationSettings(max_age=1.0, confirm_hits=1))
    a, b = (0.0, 0.0, 0.05), (0.3, 0.0, 0.05)
    detection_inputs(array([detection(result(a)), detection(result(b))]), scene, received=0.0, tracks=tracks)
    tracks.keep(["box_1", "box_2"])  # a map held both: confirmed
    kept = detection_inputs(array([detection(result(a))]), scene, received=0.9, tracks=tracks)
    assert kept.association is not None and kept.association.ended == () and "box_2" in tracks.tracks
    ended = detection_inputs(array([detection(result(a))]), scene, received=1.5, tracks=tracks)
    assert ended.association is not None and ended.association.ended == ("box_2",)
    assert set(tracks.tracks) == {"box_1"} and tracks.ends == 1


def test_a_tentative_track_seen_once_ends_after_two_misses_in_a_row_one_that_came_back_does_not() -> None:
    """A detection in the air, seen once, then missed, seen again, then missed four times: seen once, two
    misses would have ended it; seen twice (it came back to its place), misses do not (``max_age`` and
    physics do). A new one seen once and missed twice ends."""
    scene = bin_scene(3)
    tracks = InstanceTracks(scene)  # confirmed after 3 matches
    a, floating = (0.0, 0.0, 0.05), (0.5, 0.0, 0.4)
    for time in (0.0, 0.5, 1.0):
        detection_inputs(array([detection(result(a))]), scene, received=time, tracks=tracks)
        tracks.keep(["box_1"])
    both = array([detection(result(a)), detection(result(floating))])
    detection_inputs(both, scene, received=1.5, tracks=tracks)
    assert tracks.tentative("box_2") and tracks.absent_weight("box_2") == pytest.approx(0.1)
    assert tracks.absent_weight("box_1") is None  # a confirmed instance of count: K exists
    ended = []
    for time, message in ((2.0, array([detection(result(a))])), (2.5, both), (3.0, array([detection(result(a))]))):
        association = detection_inputs(message, scene, received=time, tracks=tracks).association
        assert association is not None
        ended.append(association.ended)
    assert ended == [(), (), ()]  # missed, matched again, missed: never twice in a row
    for time in (3.5, 4.0, 4.5):
        later = detection_inputs(array([detection(result(a))]), scene, received=time, tracks=tracks).association
        assert later is not None and later.ended == ()
    assert tracks.tentative("box_2") and tracks.tracks["box_2"].misses == 4
    elsewhere = (0.5, 0.3, 0.4)
    detection_inputs(array([detection(result(a)), detection(result(elsewhere))]), scene, received=5.0, tracks=tracks)
    assert "box_3" in tracks.tracks
    for time, gone in ((5.5, ()), (6.0, ("box_3",))):
        later = detection_inputs(array([detection(result(a))]), scene, received=time, tracks=tracks).association
        assert later is not None and later.ended == gone


def test_count_max_stops_at_its_maximum_with_a_diagnostic() -> None:
    scene = bin_scene({"max": 2})
    tracks = InstanceTracks(scene)
    far = [(0.0, 0.0, 0.05), (0.3, 0.0, 0.05), (0.6, 0.0, 0.05)]
    inputs = detection_inputs(array([detection(result(p)) for p in far]), scene, received=0.0, tracks=tracks)
    assert sorted(inputs.objects) == ["box_1", "box_2"]
    assert inputs.unused == ("1 detection(s) of class 'box' outside every gate, with no free instance",)
    assert tracks.outside == 1
    assert tracks.absent_weight("box_1") == pytest.approx(0.1)  # optional: absent weighs (1 - 0.9)
    detection_inputs(array([detection(result(p)) for p in far[:2]]), scene, received=0.5, tracks=tracks)
    assert tracks.absent_weight("box_1") == pytest.approx(0.01)  # each detection is more evidence


def test_a_double_detection_is_one_instance() -> None:
    scene = bin_scene(2)
    tracks = InstanceTracks(scene)
    a, b = (0.0, 0.0, 0.05), (0.3, 0.0, 0.05)
    detection_inputs(array([detection(result(a)), detection(result(b))]), scene, received=0.0, tracks=tracks)
    twice = [detection(result((0.006, 0.0, 0.05))), detection(result(a)), detection(result(b))]
    inputs = detection_inputs(array(twice), scene, received=0.5, tracks=tracks)
    assert positions_of(inputs) == {"box_1": a, "box_2": b}  # the nearer one; the other matched nothing
    assert inputs.association is not None and inputs.association.doubles == {"box": 1}
    assert inputs.association.outside == {} and tracks.doubles == 1


def test_a_double_detection_in_a_first_array_starts_one_instance() -> None:
    scene = bin_scene(3)
    tracks = InstanceTracks(scene)
    a, b = (0.0, 0.0, 0.05), (0.3, 0.0, 0.05)
    twice = [detection(result((0.006, 0.0, 0.05))), detection(result(a)), detection(result(b))]
    inputs = detection_inputs(array(twice), scene, received=0.0, tracks=tracks)
    assert inputs.association is not None and inputs.association.born == ("box_1", "box_2")
    assert inputs.association.doubles == {"box": 1} and "box_3" not in tracks.tracks


def test_with_no_instance_free_a_new_detection_takes_that_of_a_tentative_track_ending_now() -> None:
    """A tentative track no valid map held, missed in the array before and again now, ends with this
    array: its instance goes to the new detection at once. One missed once only keeps its instance."""
    scene = bin_scene(2)
    tracks = InstanceTracks(scene)
    a, floating, b = (0.0, 0.0, 0.05), (0.3, 0.0, 0.4), (0.6, 0.0, 0.05)
    detection_inputs(array([detection(result(a)), detection(result(floating))]), scene, received=0.0, tracks=tracks)
    tracks.keep(["box_1"])  # a valid map held box_1, not the floating one
    both = array([detection(result(a)), detection(result(b))])
    first = detection_inputs(both, scene, received=0.5, tracks=tracks).association
    assert first is not None and first.outside == {"box": 1} and "box_2" in tracks.tracks  # missed once: kept
    second = detection_inputs(both, scene, received=1.0, tracks=tracks).association
    assert second is not None and second.ended == ("box_2",) and second.born == ("box_2",)
    assert second.outside == {} and tracks.tracks["box_2"].position.tolist() == list(b)


def test_a_track_on_which_the_map_holds_another_up_is_not_ended_by_misses_nor_gives_its_instance_away() -> None:
    """A bottom box seen once, then missed while the top box on it is seen: the map holds the top box up
    on it, so neither two misses end its track nor a new detection (no instance free) takes its instance;
    once the map no longer does, its next miss ends it."""
    scene = bin_scene(2)
    tracks = InstanceTracks(scene)
    bottom, top, floating = (0.0, 0.0, 0.05), (0.0, 0.0, 0.15), (0.3, 0.0, 0.4)
    detection_inputs(array([detection(result(top)), detection(result(bottom))]), scene, received=0.0, tracks=tracks)
    assert tracks.tracks["box_1"].position.tolist() == list(bottom)  # born from the lowest up
    tracks.hold_up(["box_1"])
    for time, seen in ((0.5, [top]), (1.0, [top, floating])):
        inputs = detection_inputs(array([detection(result(p)) for p in seen]), scene, received=time, tracks=tracks)
        association = inputs.association
        assert association is not None and association.ended == ()
    assert association is not None and association.outside == {"box": 1} and tracks.tracks["box_1"].misses == 2
    tracks.hold_up([])
    later = detection_inputs(array([detection(result(top))]), scene, received=1.5, tracks=tracks).association
    assert later is not None and later.ended == ("box_1",)


def test_the_gate_is_to_the_nearest_result_not_to_the_results_spread() -> None:
    """Results on both sides of an instance, none within its gate (5 cm), do not match it; one near result
    among far ones does, and it is the one the instance's filter takes."""
    scene = bin_scene(2)
    around = InstanceTracks(scene)
    detection_inputs(array([detection(result((0.0, 0.0, 0.05)))]), scene, received=0.0, tracks=around)
    both_sides = detection(result((-0.06, 0.0, 0.05)), result((0.06, 0.0, 0.05)))
    inputs = detection_inputs(array([both_sides]), scene, received=0.5, tracks=around)
    assert inputs.association is not None
    assert inputs.association.assigned == {0: "box_2"} and inputs.association.ended == ()  # box_1 missed once
    near = InstanceTracks(scene)
    detection_inputs(array([detection(result((0.0, 0.0, 0.05)))]), scene, received=0.0, tracks=near)
    spread = detection(result((0.5, 0.5, 0.05), 0.9), result((0.01, 0.0, 0.05), 0.1), result((-0.4, 0.2, 0.05)))
    inputs = detection_inputs(array([spread]), scene, received=0.5, tracks=near)
    assert inputs.association is not None and inputs.association.assigned == {0: "box_1"}
    assert 0.0 < near.tracks["box_1"].position[0] < 0.01  # moved towards the near result, not the best-scored


def test_results_of_several_classes_in_one_detection_are_one_object() -> None:
    box = {"shape": "box", "size": [0.1, 0.1, 0.1]}
    scene = scene_from_dict({"objects": [{"name": "a", **box}, {"name": "b", **box}]}, "two")
    mixed = detection(
        result((0.0, 0.0, 0.05), 0.4, "a"), result((0.0, 0.0, 0.06), 0.7, "b"), result((0, 0, 0.1), 0.2, "b")
    )
    inputs = detection_inputs(array([mixed]), scene, received=0.0)
    assert list(inputs.objects) == ["b"] and inputs.objects["b"].count == 2
    assert inputs.unused == (
        "detection 0: results of class 'a' left out (one detection is one object; 'b' scored best)",
    )


def test_a_bad_score_refuses_that_result_only() -> None:
    scene = bin_scene(1)
    bad = detection(result((0.0, 0.0, 0.05), float("nan")), result((0.0, 0.0, 0.06), 0.5))
    inputs = detection_inputs(array([bad]), scene, received=0.0)
    assert positions_of(inputs) == {"box_1": (0.0, 0.0, 0.06)}
    assert inputs.unused == ("detection 0: result 0 refused: score nan",)


def test_a_detection_inside_a_static_body_is_born_last_and_left_outside_when_instances_run_out() -> None:
    """Three detections for two instances, the one below the floor first in the array and first by
    place: the two on the floor take the instances."""
    scene = bin_scene(2)
    buried, a, b = (-0.3, 0.0, -0.04), (0.0, 0.0, 0.05), (0.3, 0.0, 0.05)
    inputs = detection_inputs(array([detection(result(p)) for p in (buried, a, b)]), scene, received=0.0)
    assert positions_of(inputs) == {"box_1": a, "box_2": b}
    assert inputs.association is not None and inputs.association.outside == {"box": 1}


def test_a_detection_in_the_air_is_born_after_those_below_it_and_left_outside_when_instances_run_out() -> None:
    """Three detections for two instances, the one 35 cm above the floor first in the array and first by
    x: the two on the floor, lower, take the instances."""
    scene = bin_scene(2)
    air, a, b = (-0.3, 0.0, 0.4), (0.0, 0.0, 0.05), (0.3, 0.0, 0.05)
    inputs = detection_inputs(array([detection(result(p)) for p in (air, a, b)]), scene, received=0.0)
    assert positions_of(inputs) == {"box_1": a, "box_2": b}
    assert inputs.association is not None and inputs.association.outside == {"box": 1}


def test_a_mesh_whose_frame_is_at_its_bottom_is_on_the_floor_not_inside_it() -> None:
    """pybullet's mug has its frame at its bottom: two true mugs detected 2-3 mm below the floor by noise
    rest on it (their bodies overlap it by less than the penetration threshold), so they are born before
    a detection in the air, listed first, which is left outside; one detected 4 cm into the floor is."""
    mug = {
        "name": "mug",
        "shape": "mesh",
        "file": "package://pybullet_data/objects/mug.obj",
        "mass": 0.3,
        "count": 2,
    }
    scene = scene_from_dict({"objects": [mug], "static": [{"name": "floor", "shape": "plane"}]}, "mugs")
    air, a, b, sunk = (-0.3, 0.0, 0.3), (0.0, 0.0, -0.003), (0.3, 0.0, -0.002), (0.15, 0.2, -0.04)
    inputs = detection_inputs(
        array([detection(result(p, class_id="mug")) for p in (sunk, air, a, b)]), scene, received=0.0
    )
    assert positions_of(inputs) == {"mug_1": a, "mug_2": b}
    assert inputs.association is not None and inputs.association.outside == {"mug": 2}


def test_a_turned_body_whose_box_reaches_into_a_wall_it_does_not_touch_is_not_inside_it() -> None:
    """Two 20 cm planks, one lying on the floor, one leaning at 45 degrees with its upper end over a 5 cm wall:
    the leaning plank's box reaches 2 cm into the wall, its body stays 8 cm clear of it. Both are born
    before a detection in the air, which is left outside."""
    plank = {"name": "plank", "shape": "box", "size": [0.02, 0.2, 0.02], "mass": 0.1, "count": 2}
    wall = {"name": "wall", "shape": "box", "size": [1.0, 0.1, 0.05], "pose": {"position": [0.0, 0.35, 0.025]}}
    static = [{"name": "floor", "shape": "plane"}, wall]
    scene = scene_from_dict({"objects": [plank], "static": static}, "planks")
    half = 0.1 * math.sqrt(0.5)  # half the plank's length along y and along z, leaning at 45 degrees
    leaning = (0.0, 0.3 + 0.02 - half, 0.15 - half)
    turned = (math.sin(math.pi / 8), 0.0, 0.0, math.cos(math.pi / 8))
    lying, air = (0.0, -0.3, 0.01), (0.3, -0.3, 0.4)
    made = [
        detection(result(air, class_id="plank")),
        detection(result(leaning, class_id="plank", orientation=turned)),
        detection(result(lying, class_id="plank")),
    ]
    inputs = detection_inputs(array(made), scene, received=0.0)
    assert positions_of(inputs) == {"plank_1": lying, "plank_2": tuple(round(c, 3) for c in leaning)}
    assert inputs.association is not None and inputs.association.outside == {"plank": 1}


def test_a_detection_that_recurs_is_born_before_a_new_one() -> None:
    """Two instances, three detections on the floor: a false one, first by place, takes an instance and
    the true box ``b`` is left outside. Physics leaves the false one out; in the next array a new false
    one, again first by place, does not take that instance: ``b`` comes back to its place and does."""
    scene = bin_scene(2)
    tracks = InstanceTracks(scene)
    a, b = (0.0, 0.0, 0.05), (0.3, 0.0, 0.05)
    first = [detection(result(p)) for p in ((-0.3, 0.0, 0.05), a, b)]
    inputs = detection_inputs(array(first), scene, received=0.0, tracks=tracks)
    assert positions_of(inputs) == {"box_1": (-0.3, 0.0, 0.05), "box_2": a}
    tracks.reject(["box_1"], (), 0.0)  # a finished search found no place for it
    second = [detection(result(p)) for p in ((-0.2, 0.1, 0.05), a, (0.301, 0.0, 0.05))]
    inputs = detection_inputs(array(second), scene, received=0.5, tracks=tracks)
    assert positions_of(inputs) == {"box_1": (0.301, 0.0, 0.05), "box_2": a}
    assert inputs.association is not None and inputs.association.outside == {"box": 1}


def test_a_tentative_track_ends_once_two_valid_maps_cut_short_leave_it_out_in_a_row() -> None:
    """One valid map of a search the deadline stopped may leave out a true box a longer search would have
    kept: the track keeps its history (its *absent* stays as unlikely). A map that holds it resets the
    count; two in a row that leave it out end it."""
    scene = bin_scene(2)
    tracks = InstanceTracks(scene)
    places = [(0.0, 0.0, 0.05), (0.3, 0.0, 0.05)]
    for received in (0.0, 0.5):
        detection_inputs(array([detection(result(p)) for p in places]), scene, received=received, tracks=tracks)
    absent = tracks.absent_weight("box_1")
    assert tracks.tentative("box_1") and absent is not None
    assert tracks.reject((), ["box_1"], 0.5) == ()
    assert tracks.absent_weight("box_1") == absent
    tracks.keep(["box_1"])  # a valid map held it: not yet confirmed (two hits of three), the count starts over
    assert tracks.tentative("box_1") and tracks.reject((), ["box_1"], 1.0) == ()
    assert tracks.reject((), ["box_1"], 1.5) == ("box_1",)
    assert "box_1" not in tracks.tracks and "box_2" in tracks.tracks


def test_a_wrong_pose_ranked_first_weighs_less_than_where_the_track_holds_the_instance() -> None:
    """A new track has no prior: its detection's scores are its weights, a wrong pose 3 cm off ranked
    first. Seen at its place for three arrays, the same detection's true pose is the heavier: the
    wrong one lies 2.1 sigma of the prediction away (S = 2e-4 m²: 1 cm measured, half a second's
    random walk), a factor of 0.11."""
    scene = bin_scene(2)
    a, b, wrong = (0.0, 0.0, 0.05), (0.3, 0.0, 0.05), (0.3, 0.03, 0.05)
    misranked = detection(result(wrong, 0.6), result(b, 0.3))

    def weights_of_b(tracks: InstanceTracks, received: float) -> list[float]:
        inputs = detection_inputs(array([detection(result(a)), misranked]), scene, received=received, tracks=tracks)
        received_b = inputs.objects["box_2"]
        assert received_b.weights is not None and positions_of(inputs)["box_2"] == wrong  # the estimator's order
        return [float(w) for w in received_b.weights.values]

    assert weights_of_b(InstanceTracks(scene), 0.0) == [0.6, 0.3]
    tracks = InstanceTracks(scene)
    for received in (0.0, 0.5, 1.0):
        detection_inputs(array([detection(result(a)), detection(result(b))]), scene, received=received, tracks=tracks)
    wrong_weight, true_weight = weights_of_b(tracks, 1.5)
    assert wrong_weight < 0.25 * true_weight


def test_a_track_born_of_a_detection_with_a_wrong_pose_first_starts_where_its_other_results_agree() -> None:
    """Lego-sized parts (gate 1.6 cm): a first detection ranks a pose 3 cm off first. Its track starts at
    the other results' place, so the next detection of the part, right first, matches it."""
    scene = bin_scene(2)
    tracks = InstanceTracks(scene, AssociationSettings(gate=0.016))
    a, b, wrong = (0.0, 0.0, 0.05), (0.3, 0.0, 0.05), (0.3, 0.03, 0.05)
    near_b = (0.302, 0.001, 0.05)
    first = [detection(result(a)), detection(result(wrong, 0.6), result(b, 0.3), result(near_b, 0.2))]
    detection_inputs(array(first), scene, received=0.0, tracks=tracks)
    assert np.linalg.norm(tracks.tracks["box_2"].position - b) < 0.003  # one of the two that agree
    second = detection_inputs(array([detection(result(a)), detection(result(b))]), scene, received=0.5, tracks=tracks)
    assert second.association is not None and second.association.assigned == {0: "box_1", 1: "box_2"}
    assert second.association.born == () and tracks.births == 2


def test_an_instance_whose_track_ended_waits_for_the_detection_that_comes_back_to_it() -> None:
    """Two boxes whose tentative tracks physics ended come back in one array, and a third box, first by
    place, is new: each returning box takes its own name back, the new one the other free instance."""
    scene = bin_scene(3)
    tracks = InstanceTracks(scene)
    new, a, b = (-0.3, 0.0, 0.05), (0.0, 0.0, 0.05), (0.3, 0.0, 0.05)
    inputs = detection_inputs(array([detection(result(p)) for p in (a, b)]), scene, received=0.0, tracks=tracks)
    assert positions_of(inputs) == {"box_1": a, "box_2": b}
    detection_inputs(array([detection(result((0.6, 0.0, 0.05)))]), scene, received=0.5, tracks=tracks)
    tracks.reject(["box_1", "box_2", "box_3"], (), 0.5)  # all three never confirmed: every instance ended
    inputs = detection_inputs(array([detection(result(p)) for p in (b, new, a)]), scene, received=1.0, tracks=tracks)
    assert positions_of(inputs) == {"box_1": a, "box_2": b, "box_3": new}


def test_the_gate_is_half_the_largest_extent_and_a_part_on_another_is_no_second_detection() -> None:
    """Flat 3 x 3 x 2 cm parts: a detection 1.2 cm from where a track is (a first estimate still off)
    matches it (gate 1.5 cm); a part lying on another, 2 cm above it, is a part of its own (two bodies
    that do not overlap are more than 1 cm apart), not a second detection of the one below."""
    part = {"name": "part", "shape": "box", "size": [0.03, 0.03, 0.02], "mass": 0.01, "count": 2}
    scene = scene_from_dict({"objects": [part], "static": [{"name": "floor", "shape": "plane"}]}, "parts")
    below, above = (0.0, 0.0, 0.01), (0.0, 0.0, 0.03)
    tracks = InstanceTracks(scene)
    first = detection_inputs(array([detection(result(below, class_id="part"))]), scene, received=0.0, tracks=tracks)
    assert first.association is not None and first.association.born == ("part_1",)
    off = detection_inputs(
        array([detection(result((0.012, 0.0, 0.01), class_id="part"))]), scene, received=0.5, tracks=tracks
    )
    assert off.association is not None and off.association.assigned == {0: "part_1"} and off.association.born == ()
    stacked = InstanceTracks(scene)
    inputs = detection_inputs(
        array([detection(result(p, class_id="part")) for p in (below, above)]), scene, received=0.0, tracks=stacked
    )
    assert inputs.association is not None and inputs.association.doubles == {}
    assert positions_of(inputs) == {"part_1": below, "part_2": above}


def block_scene(settings_count: int = 2) -> Scene:
    """Jenga-like blocks, 15 x 5 x 3 cm: half their length, the default gate, is 7.5 cm."""
    block = {"name": "block", "shape": "box", "size": [0.15, 0.05, 0.03], "mass": 0.05, "count": settings_count}
    return scene_from_dict({"objects": [block], "static": [{"name": "floor", "shape": "plane"}]}, "blocks")


def block_detections(*positions: tuple[float, float, float]) -> Any:
    return array([detection(result(p, class_id="block")) for p in positions])


def test_a_detection_beyond_a_tracks_reach_does_not_match_it_though_within_the_gate() -> None:
    """A block the estimator misses, and a false detection in the floor 6 cm from it: within half the
    block's length (7.5 cm), beyond where its filter expects a detection (sqrt(chi2_3(0.99) S), S = P + R:
    4.8 cm for a track seen every half second). Matched, its poses would all be impossible. Silent for
    seconds, the track's reach grows with its filter's uncertainty. A gate the user gives is not cut short."""
    scene = block_scene()
    tracks = InstanceTracks(scene)
    block, in_floor = (0.0, 0.0, 0.015), (0.03, 0.0, -0.037)
    for time in (0.0, 0.5, 1.0):
        detection_inputs(block_detections(block), scene, received=time, tracks=tracks)
    track = tracks.tracks["block_1"]
    assert np.linalg.norm(np.subtract(in_floor, block)) < tracks.gate("block")
    assert track.reach() == pytest.approx(
        math.sqrt(11.345 * float(np.max(np.diag(track.filter.P + track.filter.R)))), rel=1e-4
    )
    missed = detection_inputs(block_detections(in_floor), scene, received=1.5, tracks=tracks).association
    assert missed is not None and missed.assigned.get(0) != "block_1" and tracks.tracks["block_1"].misses == 1
    assert tracks.tracks["block_1"].position.tolist() == pytest.approx(list(block), abs=1e-9)  # its own state
    silent = InstanceTracks(scene)
    detection_inputs(block_detections(block), scene, received=0.0, tracks=silent)
    later = detection_inputs(block_detections((0.06, 0.0, 0.015)), scene, received=8.0, tracks=silent).association
    assert later is not None and later.assigned == {0: "block_1"}  # 8 s unseen: S grew, the reach with it
    given = InstanceTracks(scene, AssociationSettings(gate=0.1))  # a gate the user gave is the gate alone
    for time in (0.0, 0.5, 1.0):
        detection_inputs(block_detections(block), scene, received=time, tracks=given)
    taken = detection_inputs(block_detections(in_floor), scene, received=1.5, tracks=given).association
    assert taken is not None and taken.assigned == {0: "block_1"}


def test_a_detection_of_another_body_does_not_match_through_a_wrong_pose_near_the_track() -> None:
    """A top block the estimator misses, and a detection of the block beside and below it, whose wrong pose,
    ranked first, lies a layer up 3.7 cm from the top block (within its reach), while its other results agree on
    its own place 6.7 cm off (within the gate, beyond the reach). The body it shows is the one its results agree
    on: it starts an instance of its own, and the top block's keeps its state (matched, the top block's name
    would have stood on the lower block for a frame, and gone back: an identity switch on either block)."""
    scene = block_scene()
    tracks = InstanceTracks(scene)
    top, below = (0.0, -0.06, 0.045), (0.0, 0.0, 0.015)
    for time in (0.0, 0.5, 1.0):
        detection_inputs(block_detections(top), scene, received=time, tracks=tracks)
    wrong = (-0.01, -0.025, 0.04)
    assert np.linalg.norm(np.subtract(wrong, top)) < tracks.tracks["block_1"].reach()
    seen = detection(
        result(wrong, 0.5, class_id="block"),
        result(below, 0.3, class_id="block"),
        result((0.003, 0.002, 0.016), 0.2, class_id="block"),
    )
    association = detection_inputs(array([seen]), scene, received=1.5, tracks=tracks).association
    assert association is not None and association.assigned == {0: "block_2"} and association.born == ("block_2",)
    assert tracks.tracks["block_1"].misses == 1
    assert tracks.tracks["block_1"].position.tolist() == pytest.approx(list(top), abs=1e-9)


def test_a_detection_of_the_block_lying_on_a_missed_one_starts_an_instance_of_its_own() -> None:
    """A block seen twice, then missed in the array that first sees the block lying on it: that detection is
    2.8 cm from the missed block's track (within the gate and the reach), its body 3 cm thick, 5 mm lower than
    the truth. The bodies at the two places overlap by a sixth of the thickness: another body, which starts an
    instance of its own, and the missed block keeps its state (matched, the lower block's name stood on the
    upper one, and the lower one took a new name when seen again: an identity switch)."""
    scene = block_scene()
    tracks = InstanceTracks(scene)
    below, above = (0.0, 0.0, 0.015), (0.003, 0.011, 0.04)
    for time in (0.0, 0.5):
        detection_inputs(block_detections(below), scene, received=time, tracks=tracks)
    track = tracks.tracks["block_1"]
    assert np.linalg.norm(np.subtract(above, below)) < min(tracks.gate("block"), track.reach())
    association = detection_inputs(block_detections(above), scene, received=1.0, tracks=tracks).association
    assert association is not None and association.assigned == {0: "block_2"} and association.born == ("block_2",)
    assert track.misses == 1 and track.position.tolist() == pytest.approx(list(below), abs=1e-9)
    again = detection_inputs(block_detections(above, below), scene, received=1.5, tracks=tracks).association
    assert again is not None and again.assigned == {0: "block_2", 1: "block_1"}


def test_two_detections_of_one_body_match_one_instance_not_a_missed_neighbours() -> None:
    """Two blocks side by side, 5.5 cm apart; one is missed and the other seen twice, the second 6 mm off.
    With a noisy estimator's measurement noise (3 cm: the reach is wider than the gate) the neighbour's
    instance lies within the gate of the second detection, and the optimal assignment would give it that
    detection (each instance one detection): one body, one match, and the missed neighbour keeps its state."""
    scene = block_scene()
    tracks = InstanceTracks(scene, AssociationSettings(measurement_noise=0.03))
    seen, neighbour = (0.0, 0.0, 0.015), (0.0, 0.055, 0.015)
    detection_inputs(block_detections(seen, neighbour), scene, received=0.0, tracks=tracks)
    twice = detection_inputs(block_detections((0.0, 0.006, 0.015), seen), scene, received=0.5, tracks=tracks)
    association = twice.association
    assert association is not None and association.assigned == {1: "block_1"}
    assert association.doubles == {"block": 1} and association.born == ()
    assert tracks.tracks["block_2"].misses == 1
    assert tracks.tracks["block_2"].position.tolist() == pytest.approx(list(neighbour), abs=1e-9)


def test_a_second_detection_whose_wrong_pose_ranks_first_takes_no_instance() -> None:
    """Three blocks: one, its neighbour 5.5 cm away and one on the neighbour; the top one is missed and the
    first seen twice, the second detection's first result 3.5 cm off towards the neighbour (its other results
    agree, on the first block). Matched one by one, that pose reaches the missed block's instance (3.6 cm);
    its central result shows the first block's body, which another detection matched: it is a second
    detection, and the missed block's instance keeps its state."""
    scene = block_scene(3)
    tracks = InstanceTracks(scene)
    first, neighbour, above = (0.0, 0.0, 0.015), (0.0, 0.055, 0.015), (0.0, 0.055, 0.045)
    born = detection_inputs(block_detections(above, first, neighbour), scene, received=0.0, tracks=tracks)
    assert born.association is not None and born.association.born == ("block_1", "block_2", "block_3")
    assert tracks.tracks["block_3"].position.tolist() == pytest.approx(list(above))
    again = detection(
        result((0.0, 0.035, 0.015), 0.6, class_id="block"),
        result((0.0, 0.006, 0.015), 0.3, class_id="block"),
        result((0.0, 0.004, 0.015), 0.1, class_id="block"),
    )
    seen = array([detection(result(first, class_id="block")), again, detection(result(neighbour, class_id="block"))])
    association = detection_inputs(seen, scene, received=0.5, tracks=tracks).association
    assert association is not None and association.assigned == {0: "block_1", 2: "block_2"}
    assert association.doubles == {"block": 1} and association.born == ()
    assert tracks.tracks["block_3"].misses == 1
    assert tracks.tracks["block_3"].position.tolist() == pytest.approx(list(above), abs=1e-9)


def test_a_second_detection_with_an_id_of_its_own_takes_no_missed_neighbours_instance() -> None:
    """A tracker's ids: block a seen, its second detection 6 mm off with an id of its own, block b missed. The
    second detection matches no key; by distance it would reach b's instance (a noisy estimator's reach), and
    its id would become that instance's key. It shows the body block a's detection, matched by its id, shows."""
    scene = block_scene()
    tracks = InstanceTracks(scene, AssociationSettings(measurement_noise=0.03))
    seen, neighbour = (0.0, 0.0, 0.015), (0.0, 0.055, 0.015)
    first = array(
        [detection(result(seen, class_id="block"), key="a"), detection(result(neighbour, class_id="block"), key="b")]
    )
    detection_inputs(first, scene, received=0.0, tracks=tracks)
    second = detection(result((0.0, 0.006, 0.015), class_id="block"), key="c")
    again = detection_inputs(
        array([second, detection(result(seen, class_id="block"), key="a")]), scene, received=0.5, tracks=tracks
    )
    association = again.association
    assert association is not None and association.assigned == {1: "block_1"}
    assert association.doubles == {"block": 1} and tracks.tracks["block_2"].key == "b"


def test_only_the_first_map_holding_a_new_instance_is_a_measurement_and_within_the_gate() -> None:
    """The first map's rest is a second measurement of a track matched once (a Kalman update: P = R + Q dt =
    1.5e-4 m² after half a second, R = 1e-4 m², so its position moves 0.6 of the way to the rest); a later
    map's is not, nor one beyond the gate, nor any for a track matched twice."""
    scene = block_scene(3)
    tracks = InstanceTracks(scene)
    first, beside, far = (0.0, 0.0, 0.031), (0.0, 0.2, 0.015), (0.3, 0.0, 0.015)
    detection_inputs(block_detections(first, beside, far), scene, received=0.0, tracks=tracks)
    detection_inputs(block_detections(beside), scene, received=0.5, tracks=tracks)  # beside: matched twice
    names = {tuple(np.round(t.position, 3).tolist()): name for name, t in tracks.tracks.items()}
    new, twice, away = names[first], names[beside], names[far]
    rests = {new: np.array([0.0, 0.0, 0.015]), twice: np.array([0.0, 0.2, 0.0]), away: np.array([0.4, 0.0, 0.015])}
    tracks.first_rests(rests)
    assert tracks.tracks[new].position.tolist() == pytest.approx([0.0, 0.0, 0.031 - 0.6 * 0.016])
    assert tracks.tracks[twice].position.tolist() == pytest.approx(list(beside))
    assert tracks.tracks[away].position.tolist() == pytest.approx(list(far))  # 10 cm: beyond the 7.5 cm gate
    tracks.first_rests({new: np.array([0.0, 0.0, 0.0])})
    assert tracks.tracks[new].position.tolist() == pytest.approx([0.0, 0.0, 0.031 - 0.6 * 0.016])

"""Instances' poses seen a little inside a static body, moved out of it before the search, with real pybullet."""

from __future__ import annotations

from typing import Any

import numpy as np
from core_builders import ranked, unrotated
from detection_builders import array, detection, result

from physics_mapper.mapping.inputs import InputSettings
from physics_mapper.mapping.mapper import Mapper, MapperSettings
from physics_mapper.mapping.seen_too_deep import moved_out_of_static
from physics_mapper.model.scene import Scene, SearchParams
from physics_mapper.model.scene_files import scene_from_dict
from physics_mapper.msg_adapters.diagnostics import diagnostics_msg
from physics_mapper.physics.checker import PhysicsChecker

BOX = {"shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2}
WALL = {"name": "wall", "shape": "box", "size": [0.1, 1.0, 0.3], "pose": {"position": [0.5, 0.0, 0.15]}}
THRESHOLD = 0.005
SETTINGS = MapperSettings(
    SearchParams(deadline=5.0, penetration_threshold=THRESHOLD), InputSettings(max_age=1.0), rate_hz=0.1
)
#: Three boxes on the floor, the last against the wall (its face at x = 0.45).
ROW = [(0.0, 0.0, 0.05), (0.2, 0.0, 0.05), (0.4, 0.0, 0.05)]


def bin_scene(*objects: dict[str, Any]) -> Scene:
    return scene_from_dict({"objects": list(objects), "static": [{"name": "floor", "shape": "plane"}, WALL]}, "test")


def test_an_instance_seen_inside_the_floor_and_the_wall_is_moved_out_and_kept_in_the_map() -> None:
    """Every pose of the box against the wall lies 2 cm into the floor and 1.5 cm into the wall: ruled out as
    seen, its tentative instance would be left out; moved out, it rests where it is, and the map holds all three."""
    mapper = Mapper(bin_scene({"name": "box", "count": {"max": 3}, **BOX}))
    deep = (0.415, 0.0, 0.03)
    detections = [detection(result(p, 0.9), result((p[0], p[1] + 0.004, p[2]), 0.5)) for p in [*ROW[:2], deep]]
    mapper.add_detections(array(detections), received=0.0)
    report = mapper.tick(0.1, SETTINGS)
    assert report.result is not None and report.result.valid and report.result.poses is not None
    assert report.absent == () and report.moved_out == 2
    chosen = {s.name: p.position for s, p in zip(report.snapshot.objects, report.result.poses, strict=True)}
    against_wall = max(chosen.values())
    np.testing.assert_allclose(against_wall[::2], ROW[2][::2], atol=0.002)  # touching the floor and the wall
    assert report.result.ruled_out == ()
    status = diagnostics_msg(report, node_name="n", hardware_id="/n", stamp_ns=0).status[0]
    assert {kv.key: kv.value for kv in status.values}["poses moved out of static bodies"] == "2"


def test_a_named_object_s_poses_stay_as_given() -> None:
    """Named objects are never absent: their poses, and the search's explanation of them, are the user's."""
    scene = bin_scene({"name": "named", **BOX}, {"name": "box", "count": 2, **BOX})
    sunk = ranked([unrotated(0.0, 0.0, 0.03)], [1.0])
    with PhysicsChecker(scene) as checker:
        searched, moved = moved_out_of_static(checker, (sunk, sunk, sunk), THRESHOLD)
    assert searched[0] == sunk and moved == 2
    np.testing.assert_allclose(searched[1].pose(1).position, (0.0, 0.0, 0.05), atol=0.001)


def test_a_single_pose_into_the_floor_beside_right_ones_is_ruled_out_not_moved() -> None:
    """A wrong pose 3 cm off and into the floor, ranked first beside the right one: physics rules it out as
    before (moved out, it would rest where nothing is, and win over the right one)."""
    mapper = Mapper(bin_scene({"name": "box", "count": {"max": 3}, **BOX}))
    wrong = (0.0, 0.03, 0.02)
    detections = [detection(result(wrong, 0.9), result(ROW[0], 0.6)), *(detection(result(p, 0.9)) for p in ROW[1:])]
    mapper.add_detections(array(detections), received=0.0)
    report = mapper.tick(0.1, SETTINGS)
    assert report.result is not None and report.result.valid and report.result.poses is not None
    assert report.moved_out == 0 and report.absent == ()
    (ruling,) = report.result.ruled_out
    assert (ruling.rank, ruling.other) == (1, "floor")
    index = report.snapshot.names.index(ruling.object)
    assert report.hypotheses[index].pose(1).position == wrong
    np.testing.assert_allclose(report.result.poses[index].position, ROW[0], atol=1e-9)


def test_a_detection_inside_the_wall_is_not_moved_onto_it_by_the_one_pose_that_could_be() -> None:
    """A false detection inside the wall: two of its poses lie more inside the wall than out (they cannot be moved
    out), its third only a centimetre into the wall's top. A depth bias puts every pose of a part a little low;
    this detection is of nothing, and none of its poses is moved: it is left out. Before, the third was moved onto
    the wall's top, where a box rests, and the map held a box that is not there."""
    mapper = Mapper(bin_scene({"name": "box", "count": {"max": 3}, **BOX}))
    inside = [(0.5, 0.0, 0.15), (0.5, 0.01, 0.16), (0.5, 0.0, 0.34)]
    false = detection(*(result(p, score) for p, score in zip(inside, (0.9, 0.6, 0.5), strict=True)))
    mapper.add_detections(array([*(detection(result(p, 0.9)) for p in ROW[:2]), false]), received=0.0)
    report = mapper.tick(0.1, SETTINGS)
    assert report.result is not None and report.result.valid
    assert report.moved_out == 0 and len(report.absent) == 1
    index = report.snapshot.names.index(report.absent[0])
    assert [report.hypotheses[index].pose(rank).position for rank in (1, 2, 3)] == inside  # as seen

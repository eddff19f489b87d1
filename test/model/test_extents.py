"""Boxes and insides of bodies (ROS-free geometry): a point inside a static body."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics_mapper.model.extents import inside_static, meets_box, meets_boxes
from physics_mapper.model.geometry import Pose, quaternion_about_axis
from physics_mapper.model.scene import Box, Plane, Sphere, StaticBody

#: A wall 20 cm thick along x, turned 90 degrees about z: then 20 cm thick along y.
TURNED_WALL = StaticBody(
    "wall", Box((0.2, 1.0, 0.5)), Pose((1.0, 0.0, 0.25), quaternion_about_axis((0, 0, 1), math.pi / 2))
)


@pytest.mark.parametrize(
    ("body", "point", "inside"),
    [
        (StaticBody("floor", Plane()), (0.3, -2.0, -0.001), True),
        (StaticBody("floor", Plane()), (0.3, -2.0, 0.001), False),
        (
            StaticBody("ramp", Plane(), Pose((0, 0, 0), quaternion_about_axis((1, 0, 0), math.pi / 2))),
            (0, 0.1, 0.5),
            True,
        ),
        (TURNED_WALL, (1.0, 0.09, 0.2), True),
        (TURNED_WALL, (1.3, 0.0, 0.2), True),  # 30 cm along x is inside: the wall is turned
        (TURNED_WALL, (1.0, 0.11, 0.2), False),
        (TURNED_WALL, (1.0, 0.0, 0.6), False),
        (StaticBody("ball", Sphere(0.5)), (0.0, 0.0, 0.0), False),  # other shapes: never told inside
    ],
)
def test_a_point_inside_a_static_body(body: StaticBody, point: tuple[float, float, float], inside: bool) -> None:
    assert inside_static(body, np.asarray(point)) is inside


def test_boxes_meet_when_they_overlap_or_touch_and_not_across_a_gap() -> None:
    lows = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0 + 1e-9, 0.0, 0.0], [0.5, 0.5, 2.0]])
    highs = lows + 1.0
    # Box 1 touches box 0 along x = 1; box 2 is a nanometre away; box 3 is above, across z.
    assert meets_box(lows, highs, lows[0], highs[0]).tolist() == [True, True, False, False]
    pairs = meets_boxes(lows, highs, lows[:2], highs[:2])
    assert pairs.shape == (4, 2)
    assert pairs.tolist() == [[True, True], [True, True], [False, True], [False, False]]

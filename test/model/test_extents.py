"""Boxes of bodies (ROS-free geometry): which boxes meet."""

from __future__ import annotations

import numpy as np

from physics_mapper.model.extents import meets_box, meets_boxes


def test_boxes_meet_when_they_overlap_or_touch_and_not_across_a_gap() -> None:
    lows = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0 + 1e-9, 0.0, 0.0], [0.5, 0.5, 2.0]])
    highs = lows + 1.0
    # Box 1 touches box 0 along x = 1; box 2 is a nanometre away; box 3 is above, across z.
    assert meets_box(lows, highs, lows[0], highs[0]).tolist() == [True, True, False, False]
    pairs = meets_boxes(lows, highs, lows[:2], highs[:2])
    assert pairs.shape == (4, 2)
    assert pairs.tolist() == [[True, True], [True, True], [False, True], [False, False]]

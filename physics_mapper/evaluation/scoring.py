"""Scoring a scene estimate against ground truth, shared by the bag replay and the paper's experiments.

ROS-free. The estimate without physics is C11..1, every object's most likely hypothesis; an
estimate's error is, per object, the distance between its estimated and true centre positions.
Orientation is not scored: the paper's Figs. 6 and 8 estimate and score object centres.
"""

from __future__ import annotations

from collections.abc import Sequence

from physics_mapper.model.geometry import Pose, translation_distance
from physics_mapper.model.hypotheses import RankedHypotheses


def rank_one_poses(hypotheses: Sequence[RankedHypotheses]) -> tuple[Pose, ...]:
    """The configuration C11..1: every object's most likely hypothesis."""
    return tuple(h.pose(1) for h in hypotheses)


def position_errors(estimate: Sequence[Pose], truth: Sequence[Pose]) -> tuple[float, ...]:
    """Per object, e_i = |p_i - p_i_true| in metres, the estimated and true poses in the same object order."""
    return tuple(translation_distance(e, t) for e, t in zip(estimate, truth, strict=True))

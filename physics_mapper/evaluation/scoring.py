"""Scoring a scene estimate against ground truth, shared by the bag replay and the paper's experiments.

ROS-free. The estimate without physics is C11..1, every object's most likely hypothesis; an
estimate's error is, per object, the distance between its estimated and true centre positions.
Orientation is not scored: the paper's Figs. 6 and 8 estimate and score object centres.

A named object is scored against its own true pose. Identical instances (:class:`ObjectClasses`) are
not: their names say which track each is, not which true object, so within each class an estimate's
instances are matched to the class's true objects by least total distance (scipy's
``linear_sum_assignment``), snapshot by snapshot, and each is scored against the one it is matched to.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import linear_sum_assignment

from physics_mapper.model.geometry import Pose, translation_distance
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene


@dataclass(frozen=True)
class ObjectClasses:
    """A scene's objects as scoring tells them apart: ``names`` in scene order (the ground truth's order) and
    each one's entry in ``classes``: identical instances share their class id (which true object each is, is
    matched), a named object's entry is its own name (it is its own true object)."""

    names: tuple[str, ...]
    classes: tuple[str, ...]

    @classmethod
    def of(cls, scene: Scene) -> ObjectClasses:
        names = scene.object_names
        return cls(names, tuple(scene.class_of(n) if scene.is_instance(n) else n for n in names))

    @classmethod
    def named(cls, names: Sequence[str]) -> ObjectClasses:
        """Objects each its own class: scored by name."""
        return cls(tuple(names), tuple(names))

    @cached_property
    def class_of(self) -> dict[str, str]:
        """Each object's name -> its class entry."""
        return dict(zip(self.names, self.classes, strict=True))

    @cached_property
    def groups(self) -> tuple[tuple[int, ...], ...]:
        """The objects' indices by class, classes in order of first appearance."""
        indices: dict[str, list[int]] = {}
        for index, key in enumerate(self.classes):
            indices.setdefault(key, []).append(index)
        return tuple(tuple(group) for group in indices.values())


def rank_one_poses(hypotheses: Sequence[RankedHypotheses]) -> tuple[Pose, ...]:
    """The configuration C11..1: every object's most likely hypothesis."""
    return tuple(h.pose(1) for h in hypotheses)


def position_errors(estimate: Sequence[Pose], truth: Sequence[Pose]) -> tuple[float, ...]:
    """Per object, e_i = |p_i - p_i_true| in metres, the estimated and true poses in the same object order."""
    return tuple(translation_distance(e, t) for e, t in zip(estimate, truth, strict=True))


def matched_errors(
    estimate: Sequence[Pose], truth: Sequence[Pose], objects: ObjectClasses, present: Sequence[bool]
) -> tuple[float | None, ...]:
    """Per object, its distance in metres to its true object (module docstring): a named object's own, an
    instance's the one of its class the least-total-distance matching of the class's ``present`` instances
    gives it. None for an object not present (left out of the map)."""
    errors: list[float | None] = [None] * len(estimate)
    for group in objects.groups:
        placed = [i for i in group if present[i]]
        if len(group) == 1:
            errors[group[0]] = translation_distance(estimate[group[0]], truth[group[0]]) if placed else None
            continue
        positions = np.array([estimate[i].position for i in placed]).reshape(-1, 3)
        true = np.array([truth[i].position for i in group])
        distances = np.linalg.norm(positions[:, None, :] - true[None, :, :], axis=2)
        rows, columns = linear_sum_assignment(distances)
        for row, column in zip(rows, columns, strict=True):
            errors[placed[row]] = float(distances[row, column])
    return tuple(errors)

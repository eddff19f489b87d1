"""Weighted pose hypotheses of one object, ranked as the search needs them.

An object that may not be there (an instance not yet confirmed, a silent object) has one more
hypothesis, *absent* (:func:`absent_hypothesis`): a rank like any other, whose pose is the object's
parking spot, far above the scene and far from every other spot, where the physics holds it
massless (:mod:`~physics_mapper.physics.world`): it collides with nothing, never moves, and is
never published.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.geometry import IDENTITY, Pose

#: Metres between the parking spots, far above any scene, where objects not in the world wait.
PARKING_SPACING = 1000.0


@dataclass(frozen=True)
class Hypothesis:
    """One pose hypothesis and its (unnormalised or normalised) weight; ``absent``: the object is not
    in the world (its pose is then its parking spot, :func:`parking_pose`); ``held``: the pose is where the
    object rested in the last valid map, not one this tick's inputs gave
    (:mod:`~physics_mapper.mapping.existence`)."""

    pose: Pose
    weight: float
    absent: bool = False
    held: bool = False


def parking_pose(index: int) -> Pose:
    """Where object ``index`` (scene order) waits out of the world: (S (index + 1), S, S), S the spacing."""
    return Pose((PARKING_SPACING * (index + 1), PARKING_SPACING, PARKING_SPACING), IDENTITY)


def absent_hypothesis(index: int, weight: float) -> Hypothesis:
    """Object ``index`` (scene order) is not there, with ``weight``."""
    return Hypothesis(parking_pose(index), weight, absent=True)


def weights_problem(weights: Sequence[float] | NDArray[np.float64], expected_count: int) -> str | None:
    """Say what makes a weight vector unusable for ``expected_count`` poses, or return None.

    Refused: wrong length, a non-finite or negative weight, or weights that sum to zero or
    overflow to infinity. Vectorised: a message of 10,000 weights is checked in microseconds.
    """
    values = np.asarray(weights, dtype=np.float64)
    if len(values) != expected_count:
        return f"{len(values)} weights for {expected_count} poses"
    if not np.isfinite(values).all():
        return "non-finite weight (NaN or Inf)"
    if (values < 0.0).any():
        return "negative weight"
    with np.errstate(over="ignore"):  # an overflow is the refusal below, not a warning
        total = float(values.sum())
    if total <= 0.0:
        return "weights sum to zero"
    if not np.isfinite(total):
        return "weights sum to infinity (too large to normalise)"
    return None


@dataclass(frozen=True)
class RankedHypotheses:
    """An object's hypotheses, weights normalised to sum 1 (a *held* one aside: see :meth:`without_held`),
    ranked by decreasing weight.

    Ties keep their input order (a stable sort), so with uniform weights the
    published order is the ranking. Rank r (1-based) is ``hypotheses[r - 1]``.
    """

    hypotheses: tuple[Hypothesis, ...]

    @classmethod
    def from_weighted(cls, hypotheses: Sequence[Hypothesis], keep_at_most: int | None = None) -> RankedHypotheses:
        """Normalise and rank; keep only the ``keep_at_most`` heaviest (renormalised).

        Raises ValueError when there are no hypotheses or the weights are unusable.
        """
        if not hypotheses:
            raise ValueError("no hypotheses")
        problem = weights_problem([h.weight for h in hypotheses], len(hypotheses))
        if problem is not None:
            raise ValueError(problem)
        ranked = sorted(hypotheses, key=lambda h: -h.weight)[:keep_at_most]
        total = sum(h.weight for h in ranked)
        return cls(tuple(Hypothesis(h.pose, h.weight / total, h.absent, h.held) for h in ranked))

    def __len__(self) -> int:
        return len(self.hypotheses)

    def heaviest(self, count: int) -> RankedHypotheses:
        """The ``count`` heaviest hypotheses, renormalised (``self`` if there are no more than that)."""
        if len(self.hypotheses) <= count:
            return self
        return RankedHypotheses.from_weighted(self.hypotheses[:count])

    def weight(self, rank: int) -> float:
        """Normalised weight of the hypothesis of 1-based ``rank``."""
        return self.hypotheses[rank - 1].weight

    def absent_weight(self) -> float:
        """The normalised weight of the object being absent (0 without an absent hypothesis)."""
        return sum(h.weight for h in self.hypotheses if h.absent)

    def is_absent(self, rank: int) -> bool:
        """Whether the hypothesis of 1-based ``rank`` is *absent*."""
        return self.hypotheses[rank - 1].absent

    def absent_rank(self) -> int | None:
        """The 1-based rank of the *absent* hypothesis (None without one)."""
        return next((rank for rank, h in enumerate(self.hypotheses, start=1) if h.absent), None)

    def held_rank(self) -> int | None:
        """The 1-based rank of the *held* hypothesis (None without one)."""
        return next((rank for rank, h in enumerate(self.hypotheses, start=1) if h.held), None)

    def without_held(self) -> RankedHypotheses:
        """These hypotheses without the *held* one (``self`` without one). A held hypothesis ranks last and its
        weight is not in the others' sum (:func:`~physics_mapper.mapping.previous_map.with_held`): the others keep
        their ranks and weights, bit for bit."""
        if self.held_rank() is None:
            return self
        return RankedHypotheses(tuple(h for h in self.hypotheses if not h.held))

    def pose_ranks(self) -> tuple[int, ...]:
        """The 1-based ranks of the hypotheses that are poses (not *absent*), ascending."""
        return tuple(rank for rank, h in enumerate(self.hypotheses, start=1) if not h.absent)

    def pose(self, rank: int) -> Pose:
        """Pose of the hypothesis of 1-based ``rank``."""
        return self.hypotheses[rank - 1].pose


def existence_probability(hypotheses: Sequence[RankedHypotheses], code: Sequence[int]) -> float:
    """The probability of a configuration's pattern of existence: the product, over the objects with an
    *absent* hypothesis, of w(absent) where ``code`` (1-based ranks) leaves the object out and 1 - w(absent)
    where it keeps it (1 when no object may be absent)."""
    return math.prod(
        weight if ranked.is_absent(rank) else 1.0 - weight
        for ranked, rank in zip(hypotheses, code, strict=True)
        if (weight := ranked.absent_weight()) > 0.0
    )

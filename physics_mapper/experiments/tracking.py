"""The loop shared by Figs. 6 and 8: particle filters give hypotheses, the search picks, errors are scored.

For each run, every object is tracked by its own particle filter
(:func:`physics_mapper.perception.particle_filter.track`) around the scene's settled ground truth. After
each iteration two estimates of the scene are scored against that truth:

* without physics, C11..1: every object's most likely hypothesis;
* with physics, what :data:`PhysicsEstimate` takes from the exhaustive search of the top-M
  hypotheses (Fig. 6: the chosen hypotheses; Fig. 8: their settled poses). When the search
  yields nothing (no valid configuration and no fallback), C11..1 is kept and counted.

The filters run once; their hypotheses are searched under each of the given rule sets
(:class:`~physics_mapper.model.scene.SearchParams`), so that rule sets are compared on the same hypotheses.

Run k draws from child k of ``numpy.random.SeedSequence(seed)``
(:func:`~physics_mapper.perception.particle_filter.run_generators`, as ``generate`` does), so a run's numbers
do not depend on how many runs were asked for, and ``generate --seed S`` makes the same hypotheses.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from physics_mapper.evaluation.scoring import rank_one_poses
from physics_mapper.experiments.common import ExperimentOptions, exhaustive_search, position_errors_cm
from physics_mapper.model.geometry import Pose, Vector3
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Scene, SearchParams
from physics_mapper.perception.particle_filter import TrackerSettings, run_generators, settle_ground_truth, track
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.report import outcome_kind
from physics_mapper.search.results import SearchResult

#: The paper's sizes: 20 runs of a 1000-particle filter.
PAPER_RUNS = 20
PAPER_PARTICLES = 1000

#: From a search result, the physics-based estimate of every object's pose, or None if it has none.
PhysicsEstimate = Callable[[SearchResult], tuple[Pose, ...] | None]


@dataclass(frozen=True)
class TrackingOutcome:
    """Positions and errors of both estimates, indexed [run, iteration, object].

    ``*_positions`` are metres, shape (runs, iterations, objects, 3); ``*_errors`` centimetres,
    shape (runs, iterations, objects); ``hypothesis_positions`` are every object's M hypothesis
    positions in rank order, metres, shape (runs, iterations, objects, M, 3) (rank 1 is C11..1).
    ``truth`` holds the settled true poses.
    The flags, shape (runs, iterations), say whether C11..1 was valid (``root_valid``), whether it
    failed Rule 1 (``root_collision``), whether any configuration passed Rule 1
    (``collision_free``), whether one was valid (``valid``), whether the fallback was used
    (``fallback_used``), whether C11..1 had to stand in for the physics estimate
    (``no_estimate``) and whether the search emptied its queue (``finished``).
    ``root_outcomes`` counts why C11..1 was rejected (e.g. ``collision cube_left-floor``).
    """

    truth: tuple[Pose, ...]
    settings: TrackerSettings
    without_physics_positions: NDArray[np.float64]
    with_physics_positions: NDArray[np.float64]
    without_physics_errors: NDArray[np.float64]
    with_physics_errors: NDArray[np.float64]
    hypothesis_positions: NDArray[np.float64]
    root_valid: NDArray[np.bool_]
    root_collision: NDArray[np.bool_]
    collision_free: NDArray[np.bool_]
    valid: NDArray[np.bool_]
    fallback_used: NDArray[np.bool_]
    no_estimate: NDArray[np.bool_]
    finished: NDArray[np.bool_]
    root_outcomes: dict[str, int]

    @property
    def searches(self) -> int:
        return int(self.valid.size)


@dataclass(frozen=True)
class _Scored:
    """One iteration of one run: both estimates scored, and how the search went."""

    without_positions: list[Vector3]
    with_positions: list[Vector3]
    without_errors: tuple[float, ...]
    with_errors: tuple[float, ...]
    hypothesis_positions: list[list[Vector3]]
    #: root_valid, root_collision, collision_free, valid, fallback_used, no_estimate, finished
    #: (TrackingOutcome's order).
    flags: tuple[bool, bool, bool, bool, bool, bool, bool]
    root_outcome: str


def tracker_settings(options: ExperimentOptions, sigma_position: float, sigma_rotation: float) -> TrackerSettings:
    """The paper's filter (1000 particles, 10 iterations) unless ``options.particles`` says otherwise.

    ``sigma_position`` is the measurement noise per position axis, metres; ``sigma_rotation`` per
    rotation axis, radians.
    """
    particles = PAPER_PARTICLES if options.particles is None else options.particles
    return replace(TrackerSettings(), particles=particles, sigma_position=sigma_position, sigma_rotation=sigma_rotation)


def tracker_summary(settings: TrackerSettings) -> dict[str, float | int]:
    """The filter's settings as the experiments' JSON reports state them (noise in m, rad and degrees)."""
    return {
        "iterations": settings.iterations,
        "particles": settings.particles,
        "top_m": settings.top_m,
        "sigma_position_m": settings.sigma_position,
        "sigma_rotation_rad": settings.sigma_rotation,
        "sigma_rotation_deg": math.degrees(settings.sigma_rotation),
    }


def _score(
    checker: PhysicsChecker,
    hypotheses: tuple[RankedHypotheses, ...],
    truth: tuple[Pose, ...],
    rules: SearchParams,
    physics_estimate: PhysicsEstimate,
) -> _Scored:
    result = exhaustive_search(checker, hypotheses, rules)
    rank_one = rank_one_poses(hypotheses)
    estimate = physics_estimate(result)
    chosen = rank_one if estimate is None else estimate
    stats = result.stats
    return _Scored(
        without_positions=[pose.position for pose in rank_one],
        with_positions=[pose.position for pose in chosen],
        without_errors=position_errors_cm(rank_one, truth),
        with_errors=position_errors_cm(chosen, truth),
        hypothesis_positions=[[h.pose.position for h in ranked.hypotheses] for ranked in hypotheses],
        flags=(
            result.trace[0].outcome == "valid",
            result.trace[0].outcome == "collision",
            stats.collisions < stats.visited,
            result.valid,
            result.fallback_used,
            estimate is None,
            stats.finished,
        ),
        root_outcome=outcome_kind(result.trace[0]),
    )


def track_and_search(
    scene: Scene,
    truth: tuple[Pose, ...],
    settings: TrackerSettings,
    options: ExperimentOptions,
    name: str,
    physics_estimate: PhysicsEstimate,
    rule_sets: Sequence[SearchParams],
) -> tuple[TrackingOutcome, ...]:
    """Run the filters once per run, and search and score their hypotheses under each rule set.

    Returns one outcome per rule set, in the order given; see the module docstring.
    """
    runs = PAPER_RUNS if options.runs is None else options.runs
    settled_truth = settle_ground_truth(scene, truth)
    scored: list[list[list[_Scored]]] = [[] for _ in rule_sets]
    with PhysicsChecker(scene) as checker:
        for run, rng in enumerate(run_generators(options.seed, runs)):
            options.progress(f"{name}: run {run + 1}/{runs}")
            history = track(scene, settled_truth, settings, rng)
            for rules, scored_runs in zip(rule_sets, scored, strict=True):
                scored_runs.append(
                    [_score(checker, hypotheses, settled_truth, rules, physics_estimate) for hypotheses in history]
                )
    return tuple(_outcome(settled_truth, settings, scored_runs) for scored_runs in scored)


def _outcome(truth: tuple[Pose, ...], settings: TrackerSettings, scored: list[list[_Scored]]) -> TrackingOutcome:
    """Stack the scored iterations of every run, indexed [run, iteration]."""

    def stacked(field: str) -> NDArray[Any]:
        return np.array([[getattr(item, field) for item in run] for run in scored])

    flags = stacked("flags")
    return TrackingOutcome(
        truth=truth,
        settings=settings,
        without_physics_positions=stacked("without_positions"),
        with_physics_positions=stacked("with_positions"),
        without_physics_errors=stacked("without_errors"),
        with_physics_errors=stacked("with_errors"),
        hypothesis_positions=stacked("hypothesis_positions"),
        root_valid=flags[:, :, 0],
        root_collision=flags[:, :, 1],
        collision_free=flags[:, :, 2],
        valid=flags[:, :, 3],
        fallback_used=flags[:, :, 4],
        no_estimate=flags[:, :, 5],
        finished=flags[:, :, 6],
        root_outcomes=dict(Counter(item.root_outcome for run in scored for item in run).most_common()),
    )


def hypothesis_spread_cm(hypothesis_positions: NDArray[np.float64]) -> dict[str, float]:
    """How far apart an object's M hypotheses lie, centimetres, averaged over every object, run and iteration.

    ``hypothesis_positions`` are metres, shape (..., M, 3). Per set of M positions p_j with mean m:
    ``rms_from_mean`` = sqrt(mean_j |p_j - m|^2) and ``rms_pairwise`` = sqrt(mean_{j<k} |p_j - p_k|^2),
    which is sqrt(2M / (M - 1)) times the former.
    """
    count = hypothesis_positions.shape[-2]
    offsets = hypothesis_positions - hypothesis_positions.mean(axis=-2, keepdims=True)
    from_mean = np.sqrt((offsets**2).sum(axis=-1).mean(axis=-1))
    pairs = hypothesis_positions[..., :, None, :] - hypothesis_positions[..., None, :, :]
    # The M x M differences hold every pair twice and M zeros on the diagonal.
    pairwise = np.sqrt((pairs**2).sum(axis=(-3, -2, -1)) / (count * (count - 1)))
    return {"rms_from_mean": 100.0 * float(from_mean.mean()), "rms_pairwise": 100.0 * float(pairwise.mean())}

"""Simulated perception: one particle filter per object turns noisy 6-DOF measurements into hypotheses.

This is the hypothesis source of the paper's experiments (section IV-B, Figs. 6 and 8): each
object is estimated in isolation, so the objects' best particles, taken together, need not be a
physically valid scene.

Model, for one object whose true pose (p*, q*) does not move:

* **Particle state**: a pose x = (p, q), position p in metres and orientation q a unit
  quaternion; N particles with log-weights.
* **Measurement**: z = (p* + n_p, exp(n_r) q*) with n_p ~ N(0, sigma_position^2 I_3) metres and
  n_r ~ N(0, sigma_rotation^2 I_3) a rotation vector in radians applied in the world frame. The
  exponential map of a rotation vector always gives a unit quaternion.
* **Prior**: particles drawn around a first measurement z_0 with the same noise model, spread
  ``prior_scale`` times the measurement sigmas; equal weights.
* **Motion (roughening)**: the objects are static, so before each update every particle is only
  jittered by the same noise model with ``roughening_scale`` times the measurement sigmas. This
  keeps resampled copies apart, so the filter can still refine after resampling.
* **Measurement update**: log w += -1/2 (|p - z_p|^2 / sigma_position^2 + theta^2 / sigma_rotation^2),
  theta the angle in radians of the rotation from q to z_q: a Gaussian likelihood of the
  6-DOF measurement error.
* **Hypotheses**: after each update the ``top_m`` particles of largest posterior weight are
  emitted, weighted by their posterior weights (renormalised over the M).
* **Resampling**: filterpy's systematic resampling when the effective sample size
  N_eff = 1 / sum(w^2) falls below N/2; weights are then equal again.

Everything draws from the given :class:`numpy.random.Generator`, so a seed reproduces a run;
:func:`run_generators` gives each of several runs its own (``generate`` and the experiments).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from filterpy.monte_carlo import systematic_resample
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from physics_mapper.model.geometry import Pose, make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Scene
from physics_mapper.physics.checker import PhysicsChecker

FloatArray = NDArray[np.float64]

#: Simulated seconds a ground truth placement is left to settle under gravity.
GROUND_TRUTH_SETTLE_TIME = 2.0


@dataclass(frozen=True)
class TrackerSettings:
    """Particle filter and measurement noise settings (defaults: the paper's Fig. 6 experiment).

    particles: particles per object (paper: 1000).
    iterations: measurement updates, each emitting one set of hypotheses (paper: 10).
    sigma_position: measurement noise sigma per position axis, metres (paper Fig. 6: 3 cm).
    sigma_rotation: measurement noise sigma per rotation axis, radians. The paper gives only
        "sigma = 3 in each dimension"; we read it as 3 cm and 3 degrees (0.0524 rad).
    top_m: hypotheses emitted per object and iteration.
    prior_scale: prior spread around the first measurement, in measurement sigmas.
    roughening_scale: motion (roughening) noise, in measurement sigmas.
    """

    particles: int = 1000
    iterations: int = 10
    sigma_position: float = 0.03
    sigma_rotation: float = math.radians(3.0)
    top_m: int = 5
    prior_scale: float = 1.0
    roughening_scale: float = 0.1


def tracker_settings_problem(settings: TrackerSettings) -> str | None:
    """Say which setting is out of range, or return None."""
    for name in ("particles", "iterations", "top_m"):
        if getattr(settings, name) < 1:
            return f"{name} must be at least 1, got {getattr(settings, name)}"
    if settings.top_m > settings.particles:
        return f"top_m ({settings.top_m}) must not exceed particles ({settings.particles})"
    for name in ("sigma_position", "sigma_rotation", "prior_scale", "roughening_scale"):
        value = getattr(settings, name)
        if not (math.isfinite(value) and value > 0.0):
            return f"{name} must be a positive number, got {value:g}"
    return None


def run_generators(seed: int, runs: int) -> list[np.random.Generator]:
    """One generator per run: run k draws from child k of ``numpy.random.SeedSequence(seed)``.

    The children are independent streams, and a run's draws do not depend on how many runs there are.
    """
    return [np.random.default_rng(child) for child in np.random.SeedSequence(seed).spawn(runs)]


def fault_generator(seed: int, run: int) -> np.random.Generator:
    """The generator of run ``run``'s estimator faults (:mod:`~physics_mapper.perception.detection_faults`):
    grandchild (run, 1) of ``numpy.random.SeedSequence(seed)``, a stream apart from the run's particle
    filters (child ``run``, :func:`run_generators`), so faults leave the hypotheses as they were."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run, 1)))


def settle_ground_truth(
    scene: Scene, poses: Sequence[Pose], settle_time: float = GROUND_TRUTH_SETTLE_TIME
) -> tuple[Pose, ...]:
    """Settle a placement under gravity (PhysicsChecker) so that the ground truth is itself physically valid.

    ``poses`` are in scene object order; the objects are simulated from rest for ``settle_time``
    seconds and their resting poses returned.
    """
    with PhysicsChecker(scene) as checker:
        return checker.settle(poses, settle_time, scene.search.angular_weight).settled_poses


@dataclass
class _Particles:
    """N particle poses of one object: ``positions`` (N, 3) metres, ``rotations``, ``log_weights`` (N,)."""

    positions: FloatArray
    rotations: Rotation
    log_weights: FloatArray

    def weights(self) -> FloatArray:
        """Normalised weights, computed stably from the log-weights."""
        weights = np.exp(self.log_weights - self.log_weights.max())
        normalised: FloatArray = weights / weights.sum()
        return normalised


def _perturbed(
    positions: FloatArray, rotations: Rotation, sigma_position: float, sigma_rotation: float, rng: np.random.Generator
) -> tuple[FloatArray, Rotation]:
    """Add N(0, sigma_position^2) metres per axis and a world-frame rotation vector N(0, sigma_rotation^2) rad."""
    count = len(positions)
    noisy_positions = positions + rng.normal(0.0, sigma_position, (count, 3))
    noisy_rotations = Rotation.from_rotvec(rng.normal(0.0, sigma_rotation, (count, 3))) * rotations
    return noisy_positions, noisy_rotations


def _measure(truth: Pose, settings: TrackerSettings, rng: np.random.Generator) -> tuple[FloatArray, Rotation]:
    """One noisy 6-DOF measurement of ``truth``: position (1, 3) metres and a single-row rotation."""
    return _perturbed(
        np.array([truth.position]),
        Rotation.from_quat([truth.orientation]),
        settings.sigma_position,
        settings.sigma_rotation,
        rng,
    )


def _prior(truth: Pose, settings: TrackerSettings, rng: np.random.Generator) -> _Particles:
    """Particles spread ``prior_scale`` sigmas around a first measurement, equal weights."""
    position, rotation = _measure(truth, settings, rng)
    count = settings.particles
    positions, rotations = _perturbed(
        np.repeat(position, count, axis=0),
        Rotation.concatenate([rotation] * count),
        settings.prior_scale * settings.sigma_position,
        settings.prior_scale * settings.sigma_rotation,
        rng,
    )
    return _Particles(positions, rotations, np.zeros(count))


def _roughen(particles: _Particles, settings: TrackerSettings, rng: np.random.Generator) -> None:
    """Motion step of a static object: jitter by ``roughening_scale`` measurement sigmas."""
    particles.positions, particles.rotations = _perturbed(
        particles.positions,
        particles.rotations,
        settings.roughening_scale * settings.sigma_position,
        settings.roughening_scale * settings.sigma_rotation,
        rng,
    )


def _update(particles: _Particles, truth: Pose, settings: TrackerSettings, rng: np.random.Generator) -> None:
    """Measure ``truth`` once and multiply each particle's weight by the Gaussian likelihood."""
    measured_position, measured_rotation = _measure(truth, settings, rng)
    squared_distance = np.sum((particles.positions - measured_position) ** 2, axis=1)
    angle = (measured_rotation * particles.rotations.inv()).magnitude()
    particles.log_weights = particles.log_weights - 0.5 * (
        squared_distance / settings.sigma_position**2 + angle**2 / settings.sigma_rotation**2
    )


def _top_hypotheses(particles: _Particles, top_m: int) -> RankedHypotheses:
    """The ``top_m`` heaviest particles as hypotheses weighted by their posterior weights."""
    weights = particles.weights()
    heaviest = np.argsort(-weights, kind="stable")[:top_m]
    quaternions = particles.rotations[heaviest].as_quat(canonical=True)
    return RankedHypotheses.from_weighted(
        [
            Hypothesis(make_pose(tuple(particles.positions[i]), tuple(quaternion)), float(weights[i]))
            for i, quaternion in zip(heaviest, quaternions, strict=True)
        ]
    )


@contextmanager
def _global_numpy_seed(rng: np.random.Generator) -> Iterator[None]:
    """Seed numpy's global generator from ``rng`` for the duration, then restore it.

    filterpy's resampling draws from the global ``numpy.random`` state; this makes it follow
    our seeded generator without disturbing anyone else's use of the global state.
    """
    saved = np.random.get_state()
    np.random.seed(int(rng.integers(2**32)))
    try:
        yield
    finally:
        np.random.set_state(saved)


def _resample_if_degenerate(particles: _Particles, rng: np.random.Generator) -> None:
    """Systematic resampling (filterpy) when N_eff = 1 / sum(w^2) < N / 2."""
    weights = particles.weights()
    count = len(weights)
    if 1.0 / np.sum(weights**2) >= count / 2.0:
        return
    with _global_numpy_seed(rng):
        indexes = systematic_resample(weights)
    particles.positions = particles.positions[indexes]
    particles.rotations = particles.rotations[indexes]
    particles.log_weights = np.zeros(count)


def track(
    scene: Scene, truth: Sequence[Pose], settings: TrackerSettings, rng: np.random.Generator
) -> list[tuple[RankedHypotheses, ...]]:
    """One entry per iteration; each holds, in scene object order, the top-M particles as weighted hypotheses.

    ``truth`` gives each object's true pose in scene object order. Each iteration roughens,
    measures and updates every object's filter, emits its top-M, then resamples if degenerate
    (see the module docstring). Raises ValueError for bad settings or a wrong number of poses.
    """
    problem = tracker_settings_problem(settings)
    if problem is not None:
        raise ValueError(problem)
    if len(truth) != len(scene.objects):
        raise ValueError(f"{len(truth)} true poses for {len(scene.objects)} objects")
    filters = [_prior(pose, settings, rng) for pose in truth]
    history: list[tuple[RankedHypotheses, ...]] = []
    for _ in range(settings.iterations):
        snapshot = []
        for particles, pose in zip(filters, truth, strict=True):
            _roughen(particles, settings, rng)
            _update(particles, pose, settings, rng)
            snapshot.append(_top_hypotheses(particles, settings.top_m))
            _resample_if_degenerate(particles, rng)
        history.append(tuple(snapshot))
    return history

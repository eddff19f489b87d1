"""The simulated particle-filter hypothesis source: reproducible, converging, well-formed output."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from conftest import SCENES

from physics_mapper.model.geometry import Pose, make_pose, rotation_angle, translation_distance
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import load_scene
from physics_mapper.perception.particle_filter import (
    TrackerSettings,
    settle_ground_truth,
    track,
    tracker_settings_problem,
)
from physics_mapper.physics.checker import PhysicsChecker


def mean_error(estimate: list[Pose], truth: tuple[Pose, ...]) -> float:
    """Mean position error (m) over objects."""
    return float(np.mean([translation_distance(e, t) for e, t in zip(estimate, truth, strict=True)]))


def mean_rotation_error(estimate: list[Pose], truth: tuple[Pose, ...]) -> float:
    """Mean rotation error (rad) over objects."""
    return float(np.mean([rotation_angle(e.orientation, t.orientation) for e, t in zip(estimate, truth, strict=True)]))


@pytest.fixture(scope="module")
def pyramid() -> Scene:
    return load_scene(SCENES / "pyramid.yaml")


@pytest.fixture(scope="module")
def pyramid_truth(pyramid: Scene) -> tuple[Pose, ...]:
    assert pyramid.ground_truth is not None
    return settle_ground_truth(pyramid, pyramid.ground_truth)


def test_same_seed_same_hypotheses_other_seed_others(pyramid: Scene, pyramid_truth: tuple[Pose, ...]) -> None:
    settings = TrackerSettings(particles=200, iterations=4)
    first = track(pyramid, pyramid_truth, settings, np.random.default_rng(7))
    again = track(pyramid, pyramid_truth, settings, np.random.default_rng(7))
    other = track(pyramid, pyramid_truth, settings, np.random.default_rng(8))
    assert first == again
    assert first != other


def test_shape_of_the_output(pyramid: Scene, pyramid_truth: tuple[Pose, ...]) -> None:
    settings = TrackerSettings(particles=100, iterations=3, top_m=4)
    history = track(pyramid, pyramid_truth, settings, np.random.default_rng(0))
    assert len(history) == 3
    for snapshot in history:
        assert len(snapshot) == len(pyramid.objects)
        assert all(len(hypotheses) == 4 for hypotheses in snapshot)


def test_weights_normalised_and_ranked(pyramid: Scene, pyramid_truth: tuple[Pose, ...]) -> None:
    history = track(pyramid, pyramid_truth, TrackerSettings(particles=300, iterations=5), np.random.default_rng(1))
    for snapshot in history:
        for hypotheses in snapshot:
            weights = [h.weight for h in hypotheses.hypotheses]
            assert math.isclose(sum(weights), 1.0, abs_tol=1e-12)
            assert weights == sorted(weights, reverse=True)
            assert all(w >= 0.0 for w in weights)


def test_orientations_are_unit_quaternions_even_with_large_rotation_noise(
    pyramid: Scene, pyramid_truth: tuple[Pose, ...]
) -> None:
    settings = TrackerSettings(particles=200, iterations=5, sigma_rotation=1.5)
    history = track(pyramid, pyramid_truth, settings, np.random.default_rng(2))
    quaternions = [h.pose.orientation for snapshot in history for hs in snapshot for h in hs.hypotheses]
    assert len(quaternions) == 5 * 3 * 5
    for quaternion in quaternions:
        assert math.isclose(math.sqrt(sum(v * v for v in quaternion)), 1.0, abs_tol=1e-12)
    # Large rotation noise must actually rotate the hypotheses away from the (upright) truth.
    assert max(abs(q[3]) for q in quaternions) < 1.0 and min(abs(q[3]) for q in quaternions) < 0.9


def test_error_shrinks_over_iterations(pyramid: Scene, pyramid_truth: tuple[Pose, ...]) -> None:
    """Mean position error of the best hypothesis, over objects and seeds: late iterations beat the first."""
    errors = []
    for seed in range(8):
        history = track(pyramid, pyramid_truth, TrackerSettings(), np.random.default_rng(seed))
        errors.append([mean_error([h.pose(1) for h in snapshot], pyramid_truth) for snapshot in history])
    per_iteration = np.mean(errors, axis=0)
    assert np.mean(per_iteration[-3:]) < 0.75 * per_iteration[0]
    # The filter refines well below the 3 cm measurement noise per axis (5.2 cm in 3-D).
    assert np.mean(per_iteration[-3:]) < 0.035


def test_orientations_converge(pyramid: Scene, pyramid_truth: tuple[Pose, ...]) -> None:
    """Mean rotation error of the best hypothesis, over objects and seeds, in units of sigma_rotation.

    One measurement is off by 2 sqrt(2/pi) = 1.6 sigma on average (the mean length of a 3-D
    Gaussian rotation vector). A wrong sign in the rotation likelihood makes the error grow; a
    missing term or sigma in the wrong unit leaves it at about 2 sigma; an angle in degrees makes
    the likelihood so sharp that one particle takes all the weight.
    """
    settings = TrackerSettings()
    errors, weight_ratios = [], []
    for seed in range(24):
        history = track(pyramid, pyramid_truth, settings, np.random.default_rng(seed))
        errors.append([mean_rotation_error([h.pose(1) for h in snapshot], pyramid_truth) for snapshot in history])
        weight_ratios += [h.weight(settings.top_m) / h.weight(1) for snapshot in history for h in snapshot]
    per_iteration = np.mean(errors, axis=0) / settings.sigma_rotation
    late = np.mean(per_iteration[-5:])
    assert per_iteration[0] > 1.1
    assert late < 0.7 * per_iteration[0]
    assert late < 0.95  # 0.86 here; a measurement alone: 1.6
    assert np.median(weight_ratios) > 0.1  # 0.75 here


def test_global_numpy_random_state_is_left_alone(pyramid: Scene, pyramid_truth: tuple[Pose, ...]) -> None:
    np.random.seed(1234)
    expected = np.random.random()
    np.random.seed(1234)
    track(pyramid, pyramid_truth, TrackerSettings(particles=200, iterations=5), np.random.default_rng(3))
    assert np.random.random() == expected


def test_settled_ground_truth_is_physically_valid(pyramid: Scene) -> None:
    assert pyramid.ground_truth is not None
    lifted_top = replace(pyramid.ground_truth[2], position=(0.0, 0.0, 0.35))  # hovering 5 cm
    settled = settle_ground_truth(pyramid, (*pyramid.ground_truth[:2], lifted_top))
    assert settled[2].position[2] == pytest.approx(0.3, abs=0.003)
    params = pyramid.search
    with PhysicsChecker(pyramid) as checker:
        assert checker.find_collision(settled, params.penetration_threshold) is None
        settling = checker.settle(settled, params.settle_time, params.angular_weight)
        assert settling is not None and settling.is_stable(params.jitter_threshold)


def test_sphere_ground_truth_rolls_into_the_groove() -> None:
    groove = load_scene(SCENES / "sphere_groove.yaml")
    on_the_slope = make_pose((0.08, 0.0, 0.25))
    (settled,) = settle_ground_truth(groove, [on_the_slope])
    assert settled.position[0] == pytest.approx(0.0, abs=0.01)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"particles": 0}, "particles must be at least 1"),
        ({"top_m": 11, "particles": 10}, "top_m (11) must not exceed particles (10)"),
        ({"sigma_position": 0.0}, "sigma_position must be a positive number"),
        ({"sigma_rotation": math.nan}, "sigma_rotation must be a positive number"),
    ],
)
def test_bad_settings_are_refused(
    pyramid: Scene, pyramid_truth: tuple[Pose, ...], change: dict[str, Any], message: str
) -> None:
    settings = replace(TrackerSettings(), **change)
    problem = tracker_settings_problem(settings)
    assert problem is not None and problem.startswith(message)
    with pytest.raises(ValueError, match="must"):
        track(pyramid, pyramid_truth, settings, np.random.default_rng(0))


def test_wrong_number_of_true_poses_is_refused(pyramid: Scene, pyramid_truth: tuple[Pose, ...]) -> None:
    with pytest.raises(ValueError, match="2 true poses for 3 objects"):
        track(pyramid, pyramid_truth[:2], TrackerSettings(), np.random.default_rng(0))

"""A result's covariance weights it and supplies alternatives, deterministically; none keeps today's behaviour."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physics_mapper.mapping.covariance import (
    MAX_ALTERNATIVES,
    covariance_matrices,
    covariance_problem,
    covariance_weight,
    expand,
)

MEAN = np.array([0.1, 0.2, 0.3, 0.0, 0.0, 0.0, 1.0])


def diagonal(*variances: float) -> np.ndarray:
    return np.diag(np.array(variances, dtype=float))


def test_no_covariance_is_the_mean_with_its_score() -> None:
    ((pose, weight),) = expand(MEAN, np.zeros((6, 6)), 0.7)
    np.testing.assert_array_equal(pose, MEAN)
    assert weight == 0.7


def test_a_sure_result_outweighs_a_vague_one_of_the_same_score() -> None:
    sure = covariance_weight(diagonal(1e-6, 1e-6, 1e-6, 0, 0, 0))  # sigma 1 mm
    vague = covariance_weight(diagonal(1.0, 1.0, 1.0, 0, 0, 0))  # sigma 1 m
    assert sure == pytest.approx(2**-1.5)  # det ratio 2^3 along three axes
    assert vague == pytest.approx(1e-9, rel=1e-5)
    assert covariance_weight(np.zeros((6, 6))) == 1.0


def test_alternatives_lie_along_the_principal_axes_at_one_and_two_sigma() -> None:
    sigma_z = 0.01
    hypotheses = expand(MEAN, diagonal(0, 0, sigma_z**2, 0, 0, 0), 1.0)
    assert len(hypotheses) == 5  # the mean, then +-1 sigma and +-2 sigma along z
    positions = sorted(round(float(pose[2] - MEAN[2]), 9) for pose, _ in hypotheses)
    assert positions == [-0.02, -0.01, 0.0, 0.01, 0.02]
    by_offset = {round(float(pose[2] - MEAN[2]), 9): weight for pose, weight in hypotheses}
    mean_weight = by_offset[0.0]
    assert by_offset[0.01] == pytest.approx(mean_weight * math.exp(-0.5))
    assert by_offset[-0.02] == pytest.approx(mean_weight * math.exp(-2.0))
    assert expand(MEAN, diagonal(0, 0, sigma_z**2, 0, 0, 0), 1.0)[3][0] == pytest.approx(hypotheses[3][0])


def test_a_rotation_variance_turns_the_alternatives_about_the_frame_axis() -> None:
    sigma = 0.1  # radians about z
    hypotheses = expand(MEAN, diagonal(0, 0, 0, 0, 0, sigma**2), 1.0)
    angles = sorted(round(float(Rotation.from_quat(pose[3:]).as_rotvec()[2]), 9) for pose, _ in hypotheses)
    assert angles == [-0.2, -0.1, 0.0, 0.1, 0.2]
    for pose, _ in hypotheses:
        np.testing.assert_allclose(pose[:3], MEAN[:3])


def test_a_full_covariance_gives_at_most_the_documented_number() -> None:
    random = np.random.default_rng(3)
    root = random.normal(size=(6, 6)) * 0.01
    hypotheses = expand(MEAN, root @ root.T, 1.0)
    assert len(hypotheses) == 1 + MAX_ALTERNATIVES == 25
    positions = np.array([pose[:3] for pose, _ in hypotheses])
    np.testing.assert_allclose(positions.mean(axis=0), MEAN[:3], atol=1e-12)  # symmetric about the mean


@pytest.mark.parametrize(
    ("values", "problem"),
    [
        (diagonal(1, 1, 1, 1, 1, math.nan), "covariance has a non-finite value"),
        (diagonal(1, 1, 1, 1, 1, -1), "covariance is not positive semi-definite"),
        (np.triu(np.ones((6, 6))), "covariance is not symmetric"),
    ],
)
def test_an_unusable_covariance_is_named_and_gives_the_mean_alone(values: np.ndarray, problem: str) -> None:
    assert covariance_problem(values) == problem
    assert len(expand(MEAN, values, 0.5)) == 1


def test_the_message_layout_is_row_major() -> None:
    values = [0.0] * 36
    values[6 * 2 + 3] = values[6 * 3 + 2] = 0.5  # z with rotation about x
    (matrix, zero) = covariance_matrices([values, np.zeros(36)])
    assert matrix[2, 3] == matrix[3, 2] == 0.5
    assert not zero.any()
    assert covariance_matrices([]).shape == (0, 6, 6)

"""An estimator's uncertainty as hypotheses: a pose's 6x6 covariance weights it and supplies alternatives (ROS-free).

A result of a pose estimator (``vision_msgs/ObjectHypothesisWithPose``) carries a score and a
``geometry_msgs/PoseWithCovariance``: a mean pose and a 6x6 covariance Sigma over
(x, y, z, rotation about x, rotation about y, rotation about z), metres and radians, in the
pose's frame (row-major, as ROS lays it out). :func:`expand` turns it into weighted hypotheses:

- **Weight.** The mean's weight is ``score * rho(Sigma)``,
  rho(Sigma) = sqrt(det(Sigma_res) / det(Sigma + Sigma_res)), in (0, 1]: the density at its
  mean of the result's Gaussian blurred by a resolution Sigma_res (:data:`POSITION_RESOLUTION`
  metres, :data:`ROTATION_RESOLUTION` radians, standard deviations), relative to the resolution's
  own. A result as sure as the resolution keeps most of its score, a vague one little: equal
  scores with sigma = 1 mm and sigma = 1 m weigh about 0.35 and 1e-9.
- **Alternatives.** Along each principal axis v_j of Sigma (eigenvalue lambda_j > 0), at
  k = 1 and 2 standard deviations (:data:`SIGMA_STEPS`) on both sides, the pose moved by
  delta = +-k sqrt(lambda_j) v_j: position p + delta[:3], orientation exp(delta[3:]) q (a
  rotation about the frame's axes, applied after the mean's). Its weight is the mean's times the
  Gaussian's fall-off there, exp(-k^2 / 2): 0.61 at one sigma, 0.14 at two. At most 6 x 2 x 2 =
  24 alternatives per result (:data:`MAX_ALTERNATIVES`), drawn deterministically (the same input
  gives the same hypotheses), so that a single-pose estimator (FoundationPose, DOPE) gives the
  search poses to choose from when its mean is not physically possible.
- **Zero or absent covariance** (all 36 values 0): the mean alone, weighted by the score, as
  without covariance. A covariance that is not finite, not symmetric or not positive
  semi-definite is not used either (:func:`covariance_problem` says why).

A pose moved into another frame carries its covariance with it
(:func:`physics_mapper.mapping.frames.rotate_covariance`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

#: Standard deviations (metres, radians) of the resolution that a covariance's weight is taken against.
POSITION_RESOLUTION = 0.001
ROTATION_RESOLUTION = 0.01
#: Distances from the mean, in standard deviations along a principal axis, of the alternatives.
SIGMA_STEPS = (1.0, 2.0)
#: Alternatives per result at most: both sides of every step along each of the six principal axes.
MAX_ALTERNATIVES = 6 * 2 * len(SIGMA_STEPS)
#: Eigenvalues below this (in the covariance's units) are no spread: no alternative along their axis.
MIN_EIGENVALUE = 1e-12
#: Relative asymmetry |Sigma - Sigma^T| / |Sigma| tolerated (a float round-trip), and negative
#: eigenvalue tolerated relative to the largest.
SYMMETRY_TOLERANCE = 1e-6
_RESOLUTION = np.diag([POSITION_RESOLUTION**2] * 3 + [ROTATION_RESOLUTION**2] * 3)

#: A pose as (x, y, z, qx, qy, qz, qw) with its weight.
WeightedPose = tuple[NDArray[np.float64], float]


def covariance_matrices(values: Sequence[Sequence[float] | NDArray[np.float64]]) -> NDArray[np.float64]:
    """The 36 row-major values of each of several ``PoseWithCovariance.covariance`` as (M, 6, 6) matrices,
    read in one numpy call."""
    return np.array(values, dtype=np.float64).reshape(-1, 6, 6)


def is_absent(covariance: NDArray[np.float64]) -> bool:
    """All zero: the estimator gave no covariance."""
    return not np.any(covariance)


def covariance_problem(covariance: NDArray[np.float64]) -> str | None:
    """Why a 6x6 covariance cannot be used (non-finite, not symmetric, not positive semi-definite), or None."""
    if not np.all(np.isfinite(covariance)):
        return "covariance has a non-finite value"
    scale = float(np.abs(covariance).max())
    if float(np.abs(covariance - covariance.T).max()) > SYMMETRY_TOLERANCE * scale:
        return "covariance is not symmetric"
    if float(np.linalg.eigvalsh(covariance).min()) < -SYMMETRY_TOLERANCE * scale:
        return "covariance is not positive semi-definite"
    return None


def covariance_weight(covariance: NDArray[np.float64]) -> float:
    """rho(Sigma) = sqrt(det(Sigma_res) / det(Sigma + Sigma_res)), in (0, 1]; 1 for a zero covariance."""
    _, log_blurred = np.linalg.slogdet(covariance + _RESOLUTION)
    _, log_resolution = np.linalg.slogdet(_RESOLUTION)
    return float(np.exp(0.5 * (log_resolution - log_blurred)))


def expand(pose: NDArray[np.float64], covariance: NDArray[np.float64], score: float) -> list[WeightedPose]:
    """A result's weighted hypotheses: its mean first, then its alternatives (module docstring).

    ``pose``: (x, y, z, qx, qy, qz, qw); ``covariance``: 6x6. A zero or unusable covariance gives
    the mean alone with weight ``score`` (check :func:`covariance_problem` to report the latter).
    """
    mean = np.asarray(pose, dtype=np.float64)
    if is_absent(covariance) or covariance_problem(covariance) is not None:
        return [(mean, score)]
    weight = score * covariance_weight(covariance)
    hypotheses: list[WeightedPose] = [(mean, weight)]
    eigenvalues, eigenvectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    orientation = Rotation.from_quat(mean[3:])
    for eigenvalue, axis in zip(eigenvalues, eigenvectors.T, strict=True):
        if eigenvalue < MIN_EIGENVALUE:
            continue
        for step in SIGMA_STEPS:
            for sign in (1.0, -1.0):
                delta = sign * step * np.sqrt(eigenvalue) * axis
                moved = np.empty(7)
                moved[:3] = mean[:3] + delta[:3]
                moved[3:] = (Rotation.from_rotvec(delta[3:]) * orientation).as_quat()
                hypotheses.append((moved, weight * float(np.exp(-0.5 * step**2))))
    return hypotheses

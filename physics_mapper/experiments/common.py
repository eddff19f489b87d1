"""Shared pieces of the paper's experiments: options, error metric, exhaustive search, drawing.

Every experiment writes three files into the output folder: ``<name>.png`` (the plot),
``<name>.json`` (every number, machine-readable) and ``<name>.md`` (the same for people,
with the comparison against the paper).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.patches import Polygon
from numpy.typing import NDArray

from physics_mapper.evaluation.scoring import position_errors
from physics_mapper.evaluation.statistics import paired_by_run_test, reduction_percent
from physics_mapper.model.geometry import Pose, rotation_vector
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Box, Cylinder, Scene, SearchParams, StaticBody
from physics_mapper.model.scene_files import SceneError, load_scene
from physics_mapper.model.scene_loading import load_stoppably
from physics_mapper.model.shipped import shipped_path
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import SearchResult
from physics_mapper.search.strategy import solve

#: Wall-clock budget, seconds, of each search. The experiments have at most 5^3 = 125
#: configurations of ~4 ms each, so the search always empties its queue well before it;
#: the summaries count the searches that did not (expected: none).
EXHAUSTIVE_DEADLINE = 60.0


#: Sideways shift, in iterations, between the lines of an error plot.
SERIES_SHIFT = 0.08


def _silent(_: str) -> None:
    return None


@dataclass(frozen=True)
class ExperimentOptions:
    """What an experiment run is asked for.

    ``runs`` and ``particles`` of None mean the paper's sizes (20 runs, 1000 particles).
    ``search_budget`` (seconds per search, ``clutter``): None means each scene's ``deadline``.
    ``progress`` receives one short line per step, for people watching a long run.
    ``scenes_dir`` defaults to the shipped ``config/scenes`` (installed or in the checkout).
    """

    output_dir: Path
    seed: int = 0
    runs: int | None = None
    particles: int | None = None
    scenes_dir: Path = field(default_factory=lambda: shipped_path("config/scenes"))
    progress: Callable[[str], None] = _silent
    search_budget: float | None = None


def reproduce_command(name: str, options: ExperimentOptions, *, sized: bool = True) -> str:
    """The command line that reproduces an experiment's outputs; ``sized`` adds ``--runs``/``--particles``."""
    words = ["physics-mapper", "experiment", name, "-o", f"{options.output_dir}/", "--seed", str(options.seed)]
    if sized and options.runs is not None:
        words += ["--runs", str(options.runs)]
    if sized and options.particles is not None:
        words += ["--particles", str(options.particles)]
    if sized and options.search_budget is not None:
        words += ["--search-budget", f"{options.search_budget:g}"]
    return " ".join(words)


def position_errors_cm(estimate: Sequence[Pose], truth: Sequence[Pose]) -> tuple[float, ...]:
    """:func:`physics_mapper.evaluation.scoring.position_errors` in centimetres: e_i = 100 * |p_i - p_i_true|."""
    return tuple(100.0 * error for error in position_errors(estimate, truth))


def exhaustive_search(
    checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], params: SearchParams
) -> SearchResult:
    """Run the search with :data:`EXHAUSTIVE_DEADLINE` seconds, enough to empty its queue; the whole trace."""
    return solve(checker, hypotheses, replace(params, deadline=EXHAUSTIVE_DEADLINE, trace_limit=None))


def side_outline_cm(shape: Box | Cylinder, pose: Pose) -> NDArray[np.float64]:
    """Corners (x, z) in centimetres of a box's or a cylinder's silhouette seen along y.

    Exact for bodies turned about the y axis only, as every body drawn in these figures is.
    """
    if isinstance(shape, Box):
        half_width, half_height = shape.size[0] / 2.0, shape.size[2] / 2.0
    else:
        half_width, half_height = shape.radius, shape.length / 2.0
    angle = rotation_vector(pose.orientation)[1]  # about y
    cos, sin = math.cos(angle), math.sin(angle)
    local = np.array([[-half_width, -half_height], [half_width, -half_height], [half_width, half_height]])
    local = np.vstack([local, [-half_width, half_height]])
    # A rotation by `angle` about y takes local (x, z) to (x cos + z sin, -x sin + z cos).
    rotated = local @ np.array([[cos, -sin], [sin, cos]])
    outline: NDArray[np.float64] = 100.0 * (rotated + np.array([pose.position[0], pose.position[2]]))
    return outline


def draw_static_section(axes: Axes, static: Sequence[StaticBody]) -> None:
    """The scene's fixed boxes cut by the plane y = 0 (grey), and the floor line z = 0, in centimetres."""
    for body in static:
        if isinstance(body.shape, Box) and abs(body.pose.position[1]) < body.shape.size[1] / 2.0:
            axes.add_patch(Polygon(side_outline_cm(body.shape, body.pose), facecolor="0.82", edgecolor="0.3"))
    axes.axhline(0.0, color="0.3", linewidth=1.5)


@dataclass(frozen=True)
class ErrorSeries:
    """One line of an error plot: errors in cm indexed [run, iteration], its legend label and style."""

    errors: NDArray[np.float64]
    label: str
    color: str
    marker: str = "o"
    linestyle: str = "-"


def plot_mean_errors(axes: Axes, series: Sequence[ErrorSeries], title: str, *, legend: bool = True) -> None:
    """Per iteration, each series' mean +- standard error over runs.

    The series are shifted sideways by a few hundredths of an iteration so that equal values stay visible.
    """
    for index, line in enumerate(series):
        runs, iterations = line.errors.shape
        sem = line.errors.std(axis=0, ddof=1) / math.sqrt(runs) if runs > 1 else np.zeros(iterations)
        axes.errorbar(
            np.arange(1, iterations + 1) + SERIES_SHIFT * (index - (len(series) - 1) / 2.0),
            line.errors.mean(axis=0),
            yerr=sem,
            color=line.color,
            marker=line.marker,
            linestyle=line.linestyle,
            markersize=4,
            capsize=3,
            label=line.label,
        )
    axes.set_title(title, fontsize=9)
    axes.set_xlabel("particle filter iteration")
    axes.set_ylabel("error (cm)")
    axes.set_xticks(np.arange(1, series[0].errors.shape[1] + 1))
    axes.set_ylim(bottom=0.0)
    axes.grid(alpha=0.3)
    if legend:
        axes.legend(fontsize=7)


def most_likely_start(
    without: NDArray[np.float64], weighted_mean_start: NDArray[np.float64], most_likely: NDArray[np.float64]
) -> dict[str, Any]:
    """The refined map started at the most likely hypotheses (``refine_mean_radius`` 0) against C11..1
    (``without``) and against the map started at the hypotheses' weighted mean, errors [run, iteration]."""
    return {
        "refine_mean_radius_m": 0.0,
        "mean_error_cm": float(most_likely.mean()),
        "reduction_percent": reduction_percent(without, most_likely),
        "weighted_mean_start_vs_most_likely_start": paired_by_run_test(most_likely, weighted_mean_start),
    }


def spread_text(start: dict[str, Any], weighted_mean_start_cm: float, root: str, error: str) -> str:
    """What starting at the hypotheses' weighted mean rather than at ``root`` gave (:func:`most_likely_start`)."""
    paired = start["weighted_mean_start_vs_most_likely_start"]
    return (
        f"Using the hypotheses' spread: refined from {root} itself (`refine_mean_radius: 0`), the {error} is "
        f"{start['mean_error_cm']:.2f} cm ({start['reduction_percent']:.1f} % below {root}); starting at the "
        f"weighted mean lowers it to {weighted_mean_start_cm:.2f} cm, lower in {paired['runs_physics_lower']} of "
        f"{paired['pairs']} runs (paired Wilcoxon p = {paired['p_value']:.2g})."
    )


def load_experiment_scene(options: ExperimentOptions, file_name: str) -> tuple[Scene, tuple[Pose, ...]]:
    """Load a shipped scene and its ground truth, which every experiment scores against (in a thread a
    signal does not wait for: :func:`~physics_mapper.model.scene_loading.load_stoppably`)."""
    path = options.scenes_dir / file_name
    scene = load_stoppably(path, load_scene)
    if scene.ground_truth is None:
        raise SceneError(str(path), "ground_truth", "missing: the experiments score against it")
    return scene, scene.ground_truth

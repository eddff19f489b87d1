"""Shared pieces of the paper's experiments: options, error metric, search, output files.

Every experiment writes three files into the output folder: ``<name>.png`` (the plot),
``<name>.json`` (every number, machine-readable) and ``<name>.md`` (the same for people,
with the comparison against the paper).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon
from numpy.typing import NDArray
from scipy.stats import kruskal, wilcoxon

from physics_mapper.core.geometry import Pose, rotation_vector
from physics_mapper.core.hypotheses import RankedHypotheses
from physics_mapper.core.physics import PhysicsChecker
from physics_mapper.core.scene import Box, Cylinder, Scene, SearchParams, StaticBody
from physics_mapper.core.scene_files import SceneError, load_scene
from physics_mapper.core.scoring import position_errors
from physics_mapper.core.search import SearchResult
from physics_mapper.core.shipped import shipped_path
from physics_mapper.core.strategy import solve

#: Wall-clock budget, seconds, of each search. The experiments have at most 5^3 = 125
#: configurations of ~4 ms each, so the search always empties its queue well before it;
#: the summaries count the searches that did not (expected: none).
EXHAUSTIVE_DEADLINE = 60.0

#: The colours of the two estimates, as in the paper's plots: without physics blue, with black;
#: the refined map (``fallback: refine``) orange, as the node's markers draw a fallback's map.
COLOR_WITHOUT_PHYSICS = "tab:blue"
COLOR_WITH_PHYSICS = "black"
COLOR_REFINED = "tab:orange"

PNG_DPI = 110
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


@dataclass(frozen=True)
class ExperimentOutput:
    """The files one experiment wrote, and its summary."""

    png: Path
    json: Path
    markdown: Path
    summary: dict[str, Any]


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
    """:func:`physics_mapper.scoring.position_errors` in centimetres: e_i = 100 * |p_i - p_i_true|."""
    return tuple(100.0 * error for error in position_errors(estimate, truth))


def exhaustive_search(
    checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], params: SearchParams
) -> SearchResult:
    """Run the search with :data:`EXHAUSTIVE_DEADLINE` seconds, enough to empty its queue; the whole trace."""
    return solve(checker, hypotheses, replace(params, deadline=EXHAUSTIVE_DEADLINE, trace_limit=None))


def new_figure(width_inches: float, height_inches: float) -> Figure:
    """A matplotlib figure drawn by the Agg backend (no display, no global pyplot state)."""
    figure = Figure(figsize=(width_inches, height_inches), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


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


def compare_errors(without: NDArray[np.float64], with_: NDArray[np.float64]) -> dict[str, Any]:
    """Compare two estimates' errors, indexed [run, iteration] and paired by run and iteration.

    * ``wilcoxon_paired_by_run``: the headline test, :func:`paired_by_run_test`.
    * ``kruskal_wallis_pooled``: the paper's test, :func:`pooled_kruskal_wallis`.
    * ``physics_lower`` / ``physics_higher`` / ``equal``: how many of the runs x iterations pairs
      have ``with_`` below, above or equal to ``without``.
    """
    difference = with_ - without
    return {
        "wilcoxon_paired_by_run": paired_by_run_test(without, with_),
        "kruskal_wallis_pooled": pooled_kruskal_wallis(without, with_),
        "physics_lower": int((difference < 0).sum()),
        "physics_higher": int((difference > 0).sum()),
        "equal": int((difference == 0).sum()),
    }


def reduction_percent(without: NDArray[np.float64], with_: NDArray[np.float64]) -> float:
    """How much lower, in percent, the mean of ``with_`` errors is than the mean of ``without`` errors."""
    return float(100.0 * (1.0 - with_.mean() / without.mean()))


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


def paired_by_run_test(without: NDArray[np.float64], with_: NDArray[np.float64]) -> dict[str, Any]:
    """Wilcoxon signed-rank test (:func:`paired_wilcoxon`) of the per-run mean errors, two-sided.

    The runs are independent, the iterations of one run are not (they share one filter), and
    both estimates of a run come from the same hypotheses: so each run gives one pair
    (mean_t without[r, t], mean_t with_[r, t]).
    """
    without_means, with_means = without.mean(axis=1), with_.mean(axis=1)
    paired = paired_wilcoxon(without_means, with_means)
    return {
        "test": "Wilcoxon signed-rank, two-sided, exact, on the per-run mean errors paired by run (zeros dropped)",
        "statistic": paired["statistic"],
        "p_value": paired["p_value"],
        "pairs": paired["pairs"],
        "nonzero_pairs": paired["nonzero_pairs"],
        "runs_physics_lower": paired["pairs_lower"],
        "runs_physics_higher": paired["pairs_higher"],
        "per_run_mean_cm": {"without_physics": without_means.tolist(), "with_physics": with_means.tolist()},
    }


#: Up to this many nonzero differences the Wilcoxon p-value comes from the exact null distribution
#: (milliseconds); above, from the normal approximation, which is close there and exact's cost grows
#: as n^3 (a second at n = 1000).
EXACT_WILCOXON_PAIRS = 200


def paired_wilcoxon(without: NDArray[np.float64], with_: NDArray[np.float64]) -> dict[str, Any]:
    """Wilcoxon signed-rank test (scipy), two-sided, of paired samples: ``with_[k]`` against ``without[k]``.

    Zero differences (pairs where the two estimates agree) are dropped, Wilcoxon's convention, and
    the p-value of the remaining n differences comes from the exact null distribution (exact while
    they are distinct, as differences of continuous errors are; scipy's default would switch to the
    normal approximation as soon as one difference is zero, which is poor in the tails at n = 20)
    up to :data:`EXACT_WILCOXON_PAIRS`, from the normal approximation above (``method`` says which).
    With no nonzero difference there is no evidence either way: statistic 0, p = 1.
    ``pairs_lower`` / ``pairs_higher``: pairs where ``with_`` is below / above ``without``.
    """
    difference = with_ - without
    nonzero = int(np.count_nonzero(difference))
    method = "exact" if nonzero <= EXACT_WILCOXON_PAIRS else "asymptotic"
    if nonzero:
        statistic, p_value = wilcoxon(with_, without, zero_method="wilcox", method=method)
    else:
        statistic, p_value = 0.0, 1.0
    return {
        "statistic": float(statistic),
        "p_value": float(p_value),
        "method": method,
        "pairs": int(difference.size),
        "nonzero_pairs": nonzero,
        "pairs_lower": int((difference < 0).sum()),
        "pairs_higher": int((difference > 0).sum()),
    }


def pooled_kruskal_wallis(without: NDArray[np.float64], with_: NDArray[np.float64]) -> dict[str, Any]:
    """Kruskal-Wallis test (scipy) of all runs x iterations pooled into one sample per estimate.

    The paper's test, kept for comparison with its p-value. It treats the samples as
    independent and unpaired, which they are not (see :func:`paired_by_run_test`).
    """
    statistic, p_value = kruskal(without.ravel(), with_.ravel())
    return {
        "test": "Kruskal-Wallis on all runs x iterations pooled (the paper's test; ignores pairing and runs)",
        "statistic": float(statistic),
        "p_value": float(p_value),
        "samples_per_group": int(without.size),
    }


def tests_text(comparison: dict[str, Any], estimate: str) -> str:
    """One sentence for people: the paired test (headline), then the paper's pooled test."""
    paired, pooled = comparison["wilcoxon_paired_by_run"], comparison["kruskal_wallis_pooled"]
    return (
        f"paired Wilcoxon signed-rank test on the {paired['pairs']} per-run means: p = {paired['p_value']:.2g} "
        f"({estimate} lower in {paired['runs_physics_lower']} of {paired['pairs']} runs, higher in "
        f"{paired['runs_physics_higher']}); the paper's test, Kruskal-Wallis on the "
        f"{pooled['samples_per_group']} runs x iterations pooled: p = {pooled['p_value']:.3g}"
    )


def check_finite(data: Any, key: str = "summary") -> None:
    """Raise ValueError naming the key of the first NaN or infinite number in nested data."""
    if isinstance(data, float) and not math.isfinite(data):
        raise ValueError(f"{key} is {data}")
    if isinstance(data, dict):
        for name, value in data.items():
            check_finite(value, f"{key}.{name}")
    elif isinstance(data, list | tuple):
        for index, value in enumerate(data):
            check_finite(value, f"{key}[{index}]")


def write_outputs(
    output_dir: Path, name: str, figure: Figure, summary: dict[str, Any], markdown: str
) -> ExperimentOutput:
    """Write ``<name>.png``, ``<name>.json`` and ``<name>.md`` into ``output_dir`` (created if missing)."""
    check_finite(summary)
    output_dir.mkdir(parents=True, exist_ok=True)
    png, json_path, markdown_path = (output_dir / f"{name}.{ext}" for ext in ("png", "json", "md"))
    figure.savefig(png, dpi=PNG_DPI)
    json_path.write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    markdown_path.write_text(markdown.rstrip() + "\n", encoding="utf-8")
    return ExperimentOutput(png, json_path, markdown_path, summary)


def load_experiment_scene(options: ExperimentOptions, file_name: str) -> tuple[Scene, tuple[Pose, ...]]:
    """Load a shipped scene and its ground truth, which every experiment scores against."""
    path = options.scenes_dir / file_name
    scene = load_scene(path)
    if scene.ground_truth is None:
        raise SceneError(str(path), "ground_truth", "missing: the experiments score against it")
    return scene, scene.ground_truth

"""Real objects in clutter: the most likely hypotheses C11..1 against the physics map, on meshes.

Scenes (``config/scenes``): ``tabletop.yaml`` (ten household-like objects on a table),
``tray_pile.yaml`` (eight objects piled in a tray) and ``jenga_tower.yaml`` (twelve blocks), every
object a mesh. As in Fig. 6, each object is tracked by its own particle filter around the scene's
settled ground truth (noise sigma :data:`SIGMA_POSITION` per position axis and
:data:`SIGMA_ROTATION` per rotation axis, top 5 particles as hypotheses), and after each of its
iterations the hypotheses are searched with the scene's rules (:func:`~physics_mapper.search.strategy.solve`'s
search) for a budget of the scene's ``deadline`` (what the node does in one tick; ``--search-budget``
overrides it), in slices of :data:`SLICE` seconds so that the time the answer appeared is known.

Three estimates are scored against the settled truth, e_i = 100 |p_i - p_i_true| cm per object:

* ``C11..1``: every object's most likely hypothesis (no physics);
* ``chosen``: the hypotheses of the search's answer (the valid configuration of least jitter, or
  the scene's fallback: ``refine`` in the shipped scenes, C11..1 itself), C11..1 when there is no answer;
* ``settled``: the answer's settled poses (the node's ``~/settled_configuration``), C11..1 when none.

Time to answer: wall-clock seconds from the search's start until it first held a map to publish
(``first map``) and until it first held a valid configuration (``first valid``), to within a slice.
The totals of C11..1 and of each physics estimate are compared by the paired tests of Fig. 6
(:func:`~physics_mapper.evaluation.statistics.compare_errors`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import NDArray

from physics_mapper.evaluation.outputs import (
    COLOR_WITH_PHYSICS,
    COLOR_WITHOUT_PHYSICS,
    ReportFiles,
    new_figure,
    write_outputs,
)
from physics_mapper.evaluation.scoring import rank_one_poses
from physics_mapper.evaluation.statistics import compare_errors, tests_text
from physics_mapper.experiments.common import (
    ErrorSeries,
    ExperimentOptions,
    load_experiment_scene,
    plot_mean_errors,
    position_errors_cm,
    reproduce_command,
)
from physics_mapper.experiments.rendering import render_scene
from physics_mapper.experiments.tracking import tracker_settings
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Fallback, Scene, SearchParams
from physics_mapper.perception.particle_filter import TrackerSettings, run_generators, settle_ground_truth, track
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import SearchResult
from physics_mapper.search.strategy import make_search

NAME = "clutter"
SCENE_FILES = ("tabletop.yaml", "tray_pile.yaml", "jenga_tower.yaml")
#: Measurement noise: a good pose estimator's, 5 mm per position axis (m), 3 degrees per rotation axis (rad).
SIGMA_POSITION = 0.005
SIGMA_ROTATION = math.radians(3.0)
#: Runs per scene unless ``--runs`` says otherwise (each of 10 iterations is one search).
DEFAULT_RUNS = 5
#: Seconds a search runs between two looks at its answer.
SLICE = 0.02
ESTIMATES = ("C11..1", "chosen", "settled")
COLOR_SETTLED = "tab:green"


@dataclass(frozen=True)
class TimedSearch:
    """A search's answer and when it appeared: seconds to the first map and to the first valid one (None: never)."""

    result: SearchResult
    first_map: float | None
    first_valid: float | None
    seconds: float


def timed_search(
    checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], params: SearchParams, budget: float
) -> TimedSearch:
    """Search for ``budget`` seconds (or until the queue empties), looking at the answer every :data:`SLICE` s."""
    search = make_search(checker, hypotheses, params)
    start = time.monotonic()
    first_map = first_valid = None
    while True:
        result = search.run(min(SLICE, max(budget - (time.monotonic() - start), 1e-6)))
        elapsed = time.monotonic() - start
        if first_map is None and result.code is not None:
            first_map = elapsed
        if first_valid is None and result.valid:
            first_valid = elapsed
        if search.done or elapsed >= budget:
            return TimedSearch(result, first_map, first_valid, elapsed)


@dataclass(frozen=True)
class SceneOutcome:
    """One scene's numbers. ``errors[estimate]`` in cm, indexed [run, iteration, object]; the rest [run, iteration]."""

    scene_file: str
    scene: Scene
    truth: tuple[Pose, ...]
    budget: float
    errors: dict[str, NDArray[np.float64]]
    root_valid: NDArray[np.bool_]
    root_bounded: NDArray[np.bool_]
    valid: NDArray[np.bool_]
    fallback_used: NDArray[np.bool_]
    answered: NDArray[np.bool_]
    withdrawn: NDArray[np.bool_]
    finished: NDArray[np.bool_]
    first_map: NDArray[np.float64]  # seconds, NaN where no map
    first_valid: NDArray[np.float64]  # seconds, NaN where no valid configuration
    visited: NDArray[np.int64]


#: What the map is when no configuration is valid, per ``fallback``.
FALLBACK_MAPS: dict[Fallback, str] = {
    "none": "none",
    "settled": "settled poses of the most likely collision-free configuration",
    "refine": "C11..1 with its overlaps resolved by the least motion, then settled",
}


def _scored(timed: TimedSearch, hypotheses: Sequence[RankedHypotheses], truth: Sequence[Pose]) -> dict[str, Any]:
    result = timed.result
    roots = [entry for entry in result.trace if entry.parent is None]
    rank_one = rank_one_poses(hypotheses)
    chosen = rank_one if result.poses is None else result.poses
    settled = rank_one if result.settled_poses is None else result.settled_poses
    return {
        "errors": [position_errors_cm(estimate, truth) for estimate in (rank_one, chosen, settled)],
        # C11..1: every group's root (unchecked if the budget ran out first).
        "root_valid": len(roots) == len(result.groups) and all(entry.outcome == "valid" for entry in roots),
        "root_bounded": any(entry.bounded for entry in roots),
        "valid": result.valid,
        "fallback_used": result.fallback_used,
        "answered": result.code is not None,
        # A map shown and gone by the end because the escape guard merged groups (the merged one has
        # none yet); a map gone otherwise is not counted here, and the test of the summary fails.
        "withdrawn": timed.first_map is not None and result.code is None and result.stats.merges > 0,
        "finished": result.stats.finished,
        "first_map": math.nan if timed.first_map is None else timed.first_map,
        "first_valid": math.nan if timed.first_valid is None else timed.first_valid,
        "visited": result.stats.visited,
    }


def run_scene(scene_file: str, options: ExperimentOptions, settings: TrackerSettings) -> SceneOutcome:
    """Track every object, search and score each iteration's hypotheses (module docstring)."""
    scene, truth = load_experiment_scene(options, scene_file)
    truth = settle_ground_truth(scene, truth)
    budget = scene.search.deadline if options.search_budget is None else options.search_budget
    params = replace(scene.search, deadline=budget)
    runs = DEFAULT_RUNS if options.runs is None else options.runs
    rows: list[list[dict[str, Any]]] = []
    with PhysicsChecker(scene) as checker:
        for run, rng in enumerate(run_generators(options.seed, runs)):
            options.progress(f"{NAME}: {scene_file} run {run + 1}/{runs}")
            rows.append(
                [
                    _scored(timed_search(checker, hypotheses, params, budget), hypotheses, truth)
                    for hypotheses in track(scene, truth, settings, rng)
                ]
            )

    def stacked(key: str) -> NDArray[Any]:
        return np.array([[item[key] for item in run] for run in rows])

    errors = stacked("errors")  # [run, iteration, estimate, object]
    return SceneOutcome(
        scene_file=scene_file,
        scene=scene,
        truth=truth,
        budget=budget,
        errors={estimate: errors[:, :, i, :] for i, estimate in enumerate(ESTIMATES)},
        root_valid=stacked("root_valid"),
        root_bounded=stacked("root_bounded"),
        valid=stacked("valid"),
        fallback_used=stacked("fallback_used"),
        answered=stacked("answered"),
        withdrawn=stacked("withdrawn"),
        finished=stacked("finished"),
        first_map=stacked("first_map").astype(np.float64),
        first_valid=stacked("first_valid").astype(np.float64),
        visited=stacked("visited").astype(np.int64),
    )


def _seconds(values: NDArray[np.float64]) -> dict[str, float | int | None]:
    """Median, 90th percentile and largest of the finite values (seconds), and how many there are."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        return {"count": 0, "median": None, "p90": None, "max": None}
    return {
        "count": int(finite.size),
        "median": float(np.median(finite)),
        "p90": float(np.percentile(finite, 90)),
        "max": float(finite.max()),
    }


def scene_summary(outcome: SceneOutcome) -> dict[str, Any]:
    """Everything one scene measured, for the JSON and the text."""
    names = outcome.scene.object_names
    totals = {estimate: errors.sum(axis=2) for estimate, errors in outcome.errors.items()}
    searches = int(outcome.valid.size)
    return {
        "scene": f"config/scenes/{outcome.scene_file}",
        "objects": list(names),
        "runs": int(outcome.valid.shape[0]),
        "penetration_threshold_m": outcome.scene.search.penetration_threshold,
        "jitter_threshold_m": outcome.scene.search.jitter_threshold,
        "search_budget_s": outcome.budget,
        "fallback": outcome.scene.search.fallback,
        "per_object_cm": {
            estimate: {name: float(errors[:, :, i].mean()) for i, name in enumerate(names)}
            for estimate, errors in outcome.errors.items()
        },
        "mean_total_cm": {estimate: float(total.mean()) for estimate, total in totals.items()},
        "total_per_iteration_cm": {estimate: total.mean(axis=0).tolist() for estimate, total in totals.items()},
        "searches": searches,
        "root_valid": int(outcome.root_valid.sum()),
        "root_bounded": int(outcome.root_bounded.sum()),
        "valid": int(outcome.valid.sum()),
        "fallback_used": int(outcome.fallback_used.sum()),
        "no_map": int((~outcome.answered).sum()),
        "map_withdrawn": int(outcome.withdrawn.sum()),
        "finished": int(outcome.finished.sum()),
        "visited_mean": float(outcome.visited.mean()),
        "first_map_s": _seconds(outcome.first_map),
        "first_valid_s": _seconds(outcome.first_valid),
        "chosen_vs_c11": compare_errors(totals["C11..1"], totals["chosen"]),
        "settled_vs_c11": compare_errors(totals["C11..1"], totals["settled"]),
    }


def _draw_errors(axes: Axes, outcome: SceneOutcome) -> None:
    """Per object, the mean error of each estimate (bars) with its standard error over runs and iterations."""
    names = outcome.scene.object_names
    positions = np.arange(len(names))
    width = 0.27
    colors = (COLOR_WITHOUT_PHYSICS, COLOR_WITH_PHYSICS, COLOR_SETTLED)
    for offset, estimate, color in zip((-width, 0.0, width), ESTIMATES, colors, strict=True):
        errors = outcome.errors[estimate].reshape(-1, len(names))
        sem = errors.std(axis=0, ddof=1) / math.sqrt(len(errors)) if len(errors) > 1 else np.zeros(len(names))
        axes.bar(positions + offset, errors.mean(axis=0), width, yerr=sem, color=color, label=estimate, capsize=2)
    axes.set_xticks(positions, names, rotation=45, ha="right", fontsize=7)
    axes.set_ylabel("position error (cm)")
    axes.set_title("per object, mean over runs and iterations", fontsize=9)
    axes.grid(alpha=0.3, axis="y")
    axes.legend(fontsize=7)


def _draw_times(axes: Axes, outcome: SceneOutcome, summary: dict[str, Any]) -> None:
    """When the search first held a map and a valid map (seconds), and how often it found a valid one."""
    budget = outcome.budget
    bins = np.linspace(0.0, budget * 1.05, 22).tolist()
    for values, color, label in (
        (outcome.first_map, COLOR_WITH_PHYSICS, "first map"),
        (outcome.first_valid, COLOR_SETTLED, "first valid map"),
    ):
        finite = values[np.isfinite(values)]
        axes.hist(finite, bins=bins, color=color, alpha=0.6, label=f"{label} ({finite.size} of {values.size})")
    axes.axvline(budget, color="0.3", linestyle="--", linewidth=1)
    axes.set_xlabel(f"seconds from the search's start (budget {budget:g} s, dashed)")
    axes.set_ylabel("searches")
    share = summary["valid"] / summary["searches"]
    axes.set_title(f"time to answer; a valid map in {share:.0%}, C11..1 valid in {summary['root_valid']}", fontsize=9)
    axes.legend(fontsize=7)


def draw(outcomes: Sequence[SceneOutcome], summaries: Sequence[dict[str, Any]], settings: TrackerSettings) -> Figure:
    figure = new_figure(22.0, 5.2 * len(outcomes))
    grid = figure.subplots(len(outcomes), 4, squeeze=False, gridspec_kw={"width_ratios": [1.15, 1.3, 1.0, 1.0]})
    for row, (outcome, summary) in enumerate(zip(outcomes, summaries, strict=True)):
        picture = grid[row, 0]
        picture.imshow(render_scene(outcome.scene, outcome.truth))
        picture.set_title(f"{outcome.scene_file}: {len(outcome.truth)} objects (settled ground truth)", fontsize=9)
        picture.axis("off")
        _draw_errors(grid[row, 1], outcome)
        totals = [
            ErrorSeries(outcome.errors[estimate].sum(axis=2), label, color, marker)
            for estimate, label, color, marker in (
                ("C11..1", "C11..1 (no physics)", COLOR_WITHOUT_PHYSICS, "o"),
                ("chosen", "physics: chosen hypotheses", COLOR_WITH_PHYSICS, "s"),
                ("settled", "physics: settled", COLOR_SETTLED, "^"),
            )
        ]
        plot_mean_errors(grid[row, 2], totals, "total error (sum over the objects)")
        _draw_times(grid[row, 3], outcome, summary)
    figure.suptitle(
        f"Real objects in clutter: sigma = {1000 * settings.sigma_position:g} mm and "
        f"{math.degrees(settings.sigma_rotation):g} deg, {settings.particles} particles, top {settings.top_m} per "
        f"object; each iteration searched for the scene's deadline (mean +- standard error)",
        fontsize=11,
    )
    return figure


def run(options: ExperimentOptions) -> ReportFiles:
    """Track, search, score, plot and summarise each scene (module docstring)."""
    settings = tracker_settings(options, SIGMA_POSITION, SIGMA_ROTATION)
    outcomes = [run_scene(scene_file, options, settings) for scene_file in SCENE_FILES]
    summaries = [scene_summary(outcome) for outcome in outcomes]
    summary: dict[str, Any] = {
        "experiment": NAME,
        "seed": options.seed,
        "iterations": settings.iterations,
        "particles": settings.particles,
        "top_m": settings.top_m,
        "sigma_position_m": settings.sigma_position,
        "sigma_rotation_rad": settings.sigma_rotation,
        "slice_s": SLICE,
        "error_definition": "e_i = 100 |p_i - p_i_true| cm per object; total = sum_i e_i",
        "scenes": {
            outcome.scene_file.removesuffix(".yaml"): part for outcome, part in zip(outcomes, summaries, strict=True)
        },
    }
    figure = draw(outcomes, summaries, settings)
    return write_outputs(options.output_dir, NAME, figure, summary, markdown(summary, options))


def _seconds_text(seconds: dict[str, Any]) -> str:
    if not seconds["count"]:
        return "never"
    return f"median {seconds['median']:.3f} s, 90 % within {seconds['p90']:.3f} s, at most {seconds['max']:.3f} s"


def _scene_text(name: str, part: dict[str, Any]) -> str:
    names = part["objects"]
    rows = "\n".join(
        f"| {obj} | " + " | ".join(f"{part['per_object_cm'][e][obj]:.2f}" for e in ESTIMATES) + " |" for obj in names
    )
    totals = " | ".join(f"**{part['mean_total_cm'][e]:.2f}**" for e in ESTIMATES)
    searches = part["searches"]
    return f"""### {name} ({len(names)} objects, `{part["scene"]}`)

Rules: overlap at most {100 * part["penetration_threshold_m"]:g} cm, jitter at most
{100 * part["jitter_threshold_m"]:g} cm; {part["runs"]} runs, {searches} searches of {part["search_budget_s"]:g} s each.

| object | C11..1 | chosen | settled |
|---|---|---|---|
{rows}
| total | {totals} |

- Valid map in {part["valid"]} of {searches} searches (C11..1 itself valid in {part["root_valid"]}); the fallback
  (`{part["fallback"]}`: {FALLBACK_MAPS[part["fallback"]]}) in {part["fallback_used"]}; no map in
  {part["no_map"]} (in {part["map_withdrawn"]} of them a map had been shown, and was withdrawn when the escape
  guard merged groups). {part["finished"]} searches emptied their queue within the budget, visiting
  {part["visited_mean"]:.1f} configurations on average; in {part["root_bounded"]} the root C11..1 itself was
  bounded (p(C) below `probability_threshold`), so that nothing beyond it was searched.
- Time to the first map: {_seconds_text(part["first_map_s"])}; to the first valid map:
  {_seconds_text(part["first_valid_s"])}.
- Settled against C11..1: {tests_text(part["settled_vs_c11"], "settled")}.
- Chosen against C11..1: {tests_text(part["chosen_vs_c11"], "chosen")}.
"""


def markdown(summary: dict[str, Any], options: ExperimentOptions) -> str:
    scenes = "\n".join(_scene_text(name, part) for name, part in summary["scenes"].items())
    return f"""# Real objects in clutter: C11..1 against the physics map

Command: `{reproduce_command(NAME, options)}`

![clutter](clutter.png)

## Setup
Three shipped scenes of meshes (pybullet_data's mug, duck, bricks, blocks, random objects, tray, table).
One particle filter per object (`physics_mapper.perception.particle_filter`): {summary["particles"]} particles,
{summary["iterations"]} iterations, measurement noise sigma = {1000 * summary["sigma_position_m"]:g} mm per
position axis and {math.degrees(summary["sigma_rotation_rad"]):g} degrees per rotation axis; after each iteration
the top {summary["top_m"]} particles of each object are its weighted hypotheses, and they are searched with the
scene's rules for the scene's `deadline` (one node tick), looking at the answer every {1000 * summary["slice_s"]:g} ms.
Ground truth: the scene's, settled under gravity.

Error of object i: e_i = 100 |p_i - p_i_true| cm (position of the mesh frame; orientation is not scored); total:
their sum. Estimates: C11..1 (every object's most likely hypothesis), chosen (the hypotheses of the search's
answer: its valid configuration of least jitter, or the fallback's), settled (the answer's settled poses). Without
an answer C11..1 stands in. Tests as in Fig. 6: a paired Wilcoxon signed-rank test on the per-run means, and the
paper's Kruskal-Wallis on all runs x iterations pooled.

## Results (means over runs and iterations, cm)

{scenes}
## Compared with the paper
The paper's scenes hold at most three objects, each a box, a sphere or a cylinder, and ODE's primitives check them.
These hold eight to twelve real objects as meshes: convex hulls, convex decompositions (the mug's handle keeps its
hole) and a concave tray as a triangle mesh, the kind of scene its method was meant for. The comparison is the
paper's (the most likely hypotheses against the physics-chosen ones, errors per object and in total), with the
settled poses as the corrected estimate of its Fig. 8, and the time the anytime search needs for a first answer.
"""

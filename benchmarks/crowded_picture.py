"""A picture of one crowded search: the scene from the side, and every checked candidate with its conflict.

Top: a wall of cubes of the crowded suite seen along y, each object's most likely hypothesis outlined
and its true pose filled (red: the most likely hypothesis is wrong). Bottom: one column per candidate
the conflict-directed search checked, in visiting order, one row per object; a cell gives the
object's rank in that candidate, the cells of the conflict the rejection taught are dark, the column's
colour says the outcome (collision, unstable, valid), up to the first valid one. Candidates skipped
because they contained a known conflict are counted in the title: they never reached the physics.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

from physics_mapper.model.geometry import rotation_angle
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.scenarios.crowded_suite import CUBE_EDGE, CrowdedCase, crowded_problem
from physics_mapper.search.strategy import make_search

#: The search the docs show: a wall of 10 cubes two high, 5 hypotheses each.
PICTURE_CASE = CrowdedCase("wall", 10, 5, 5)
OUTCOME_COLOURS = {"collision": "#d62728", "unstable": "#ff7f0e", "valid": "#2ca02c"}


def plot_search(path: Path, case: CrowdedCase = PICTURE_CASE) -> None:
    """Search ``case`` with the defaults and draw it up to its first valid configuration (module docstring)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    problem = crowded_problem(case)
    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, hypotheses, replace(scene.search, trace_limit=None))
        result = search.run(None)
    first_valid = next(i for i, entry in enumerate(result.trace) if entry.outcome == "valid")
    trace = result.trace[: first_valid + 1]
    names = scene.object_names
    figure = Figure(figsize=(max(8.0, 0.32 * len(trace) + 2.0), 6.4), layout="constrained")
    FigureCanvasAgg(figure)
    side, grid = figure.subplots(2, 1, height_ratios=(1, 2))
    for index, ranked in enumerate(hypotheses):
        first, truth = ranked.pose(1), ranked.pose(problem.answer[index])
        wrong = problem.answer[index] != 1
        half = CUBE_EDGE / 2
        side.add_patch(
            Rectangle(
                (truth.position[0] - half, truth.position[2] - half),
                CUBE_EDGE,
                CUBE_EDGE,
                color="#d62728" if wrong else "#1f77b4",
                alpha=0.35,
            )
        )
        angle = math.degrees(rotation_angle(first.orientation, truth.orientation))
        side.add_patch(
            Rectangle(
                (first.position[0] - half, first.position[2] - half),
                CUBE_EDGE,
                CUBE_EDGE,
                angle=angle,
                rotation_point="center",
                fill=False,
                lw=0.8,
            )
        )
        side.annotate(names[index].split("_")[-1], (truth.position[0], truth.position[2]), ha="center", fontsize=7)
    side.autoscale_view()
    side.set_aspect("equal")
    side.set(xlabel="x [m]", ylabel="z [m]")
    side.set_title(
        f"{case.layout} of {case.objects} cubes, M = {case.hypotheses}, seen along y:\noutlines most likely "
        "hypotheses, filled true poses (red: the most likely one is wrong)",
        fontsize=8,
    )
    for column, entry in enumerate(trace):
        conflict = {name for name, _ in entry.conflict or ()}
        grid.add_patch(Rectangle((column, -1.0), 1.0, 0.8, color=OUTCOME_COLOURS[entry.outcome]))
        for row, rank in enumerate(entry.code):
            dark = names[row] in conflict
            grid.add_patch(Rectangle((column, row), 1.0, 1.0, color="#444444" if dark else "#eeeeee", ec="white"))
            ink = "white" if dark else "black"
            grid.text(column + 0.5, row + 0.5, str(rank), ha="center", va="center", fontsize=6, color=ink)
    grid.set_xlim(0, len(trace))
    grid.set_ylim(len(names), -1.2)
    grid.set_yticks([i + 0.5 for i in range(len(names))], list(names), fontsize=6)
    grid.set_xticks([i + 0.5 for i in range(len(trace))], [str(i + 1) for i in range(len(trace))], fontsize=6)
    grid.set_xlabel("checked candidates, in visiting order (top bar: red collision, orange unstable, green valid)")
    counted = result.stats.part_counters
    grid.set_title(
        f"conflict-directed search to its first valid configuration ({len(trace)} checked); to the end:\n"
        f"{result.stats.visited} checked, {counted['skipped']} skipped by {counted['conflicts']} conflicts, "
        f"{counted['local_settlings']} local and {counted['full_settlings']} full settlings. "
        "Dark cells: the conflict each rejection named",
        fontsize=8,
    )
    figure.savefig(path, dpi=130)

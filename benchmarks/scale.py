"""The scale benchmark: the joint and the grouped search side by side on the seeded suite.

Every problem of :mod:`physics_mapper.scenarios.scale_suite` is first searched to the end by the grouped
search (no deadline): its result is *the answer* (the configuration an exhaustive search returns).
It is searched to the end once more with ``settle_exit: full``: early exits must give every visited
configuration the same outcome and the same answer, its settled poses within
:data:`~physics_mapper.physics.settling.REST_SHARE` x ``jitter_threshold`` (m + weighted rad).
Then each strategy searches it afresh in slices of :data:`SLICE` seconds of wall-clock time, as the
node's ticks would, until its result is the answer or :data:`ANSWER_CAP` seconds have passed: the
*time to the answer* counts building the search (grouping, tables) and searching, not assembling
results between slices. Where the joint search can finish (N <= :data:`JOINT_FINISH_MAX_OBJECTS`), it
also runs to the end, for up to :data:`JOINT_FINISH_CAP` seconds, and its answer is compared with the
grouped one. Peak memory is the Python heap's peak (``tracemalloc``, pybullet's own memory not
included) over one second of each strategy's search, on the first seed of each (layout, N, M).
Seconds are wall-clock seconds on this machine.

Run: ``physics-mapper bench scale [--seeds N] [--node-minutes M] [--quick] [-o DIR]``. Prints the
table and the targets BENCHMARKS.md records ("Scale"), then samples a 50-object node's memory for
``--node-minutes`` minutes (10 by default; 0 skips it); with ``-o DIR`` it also writes ``scale.png``
(time to the answer against N) and ``scale_groups.png`` (a suite scene's interaction groups) into
``DIR``, and without it writes no file. Progress goes to stderr. The full suite takes about 15
minutes plus the node run on an otherwise idle 2-core machine.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import yaml

from physics_mapper.model.errors import InputError
from physics_mapper.model.geometry import pose_displacement
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.settling import REST_SHARE
from physics_mapper.scenarios.problems import AnswerRun, search_until_answer
from physics_mapper.scenarios.scale_suite import (
    CUBE_EDGE,
    LAYOUTS,
    ScaleCase,
    ScaleProblem,
    problem_document,
    scale_problem,
)
from physics_mapper.search.groups import interaction_groups
from physics_mapper.search.results import Code, SearchResult
from physics_mapper.search.strategy import make_search

Strategy = Literal["joint", "grouped"]
STRATEGIES: tuple[Strategy, ...] = ("joint", "grouped")
#: The suite's sizes: objects N, hypotheses per object M, problems per (layout, N, M).
SIZES = (3, 5, 6, 10, 20, 50)
HYPOTHESES = (5, 10, 20)
SEEDS = 3
#: Seconds of search between two looks at the result (the node's ticks look once per deadline).
SLICE = 0.001
#: Seconds a strategy gets to reach the answer.
ANSWER_CAP = 2.0
#: Problems up to this many objects are also searched to the end by the joint search (for up to
#: JOINT_FINISH_CAP seconds), to compare its answer with the grouped one.
JOINT_FINISH_MAX_OBJECTS = 6
JOINT_FINISH_CAP = 10.0
#: Seconds of search over which peak memory is measured.
MEMORY_RUN = 1.0
#: The scene whose interaction groups docs/search.md shows.
GROUPS_PICTURE = ScaleCase("mixed", 20, 5, 3)
#: The node's default deadline and one second: the two budgets the table reports.
BUDGETS = (0.2, 1.0)

Answer = tuple[Code | None, bool]


@dataclass(frozen=True)
class StrategyRun(AnswerRun):
    """One strategy on one problem (:class:`AnswerRun`) and its counters over that run: visits,
    simulation steps run and spared."""

    visited: int
    settle_steps: int
    settle_steps_saved: int


@dataclass(frozen=True)
class ProblemRun:
    """Both strategies on one problem: the answer, how many groups, whether a finished joint search
    agrees, and whether early exits changed anything against full settling."""

    case: ScaleCase
    answer: Answer
    constructed: bool  # the answer is the suite's valid configuration by construction
    groups: int
    merges: int
    runs: dict[Strategy, StrategyRun]
    joint_finished: bool | None  # None: not tried (too many objects)
    joint_agrees: bool | None  # None: the joint search did not finish
    early_exit_same: bool  # same outcome for every visited configuration, same answer, as full settling
    settled_difference: float  # largest difference of the answer's settled poses, early vs full (m + w rad)


def params_for(strategy: Strategy, base: SearchParams) -> SearchParams:
    """The benchmark's parameters: the defaults, no trace kept (results are read every slice).

    ``joint`` is the paper's search as it was before interaction groups: full settling.
    """
    if strategy == "joint":
        return replace(base, strategy="joint", settle_exit="full", trace_limit=0)
    return replace(base, strategy="grouped", trace_limit=0)


def exhaustive(problem: ScaleProblem, settle_exit: Literal["early", "full"]) -> SearchResult:
    """The grouped search run to the end (no deadline), with its whole trace."""
    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    params = replace(params_for("grouped", scene.search), settle_exit=settle_exit, trace_limit=None)
    with PhysicsChecker(scene) as checker:
        return make_search(checker, hypotheses, params).run(None)


def outcomes(result: SearchResult) -> dict[tuple[tuple[int, ...], Code], str]:
    """Every visited configuration's outcome, by (its group's objects, its code)."""
    objects = {group.id: group.objects for group in result.groups}
    return {(objects[entry.group], entry.code): entry.outcome for entry in result.trace}


def early_exit_difference(early: SearchResult, full: SearchResult, angular_weight: float) -> tuple[bool, float]:
    """Whether early exits kept every outcome and the answer, and how far apart the answer's settled poses are."""
    same = outcomes(early) == outcomes(full) and (early.code, early.valid) == (full.code, full.valid)
    if early.settled_poses is None or full.settled_poses is None:
        return same, 0.0
    pairs = zip(early.settled_poses, full.settled_poses, strict=True)
    return same, max(pose_displacement(a, b, angular_weight) for a, b in pairs)


def time_to_answer(problem: ScaleProblem, strategy: Strategy, answer: Answer, cap: float = ANSWER_CAP) -> StrategyRun:
    """Search in :data:`SLICE` slices until the result is ``answer``, the search ends or ``cap`` seconds pass."""
    params = params_for(strategy, problem.problem.scene.search)
    answer_time, elapsed, result = search_until_answer(problem.problem, params, answer, SLICE, cap)
    stats = result.stats
    return StrategyRun(answer_time, elapsed, stats.visited, stats.settle_steps, stats.settle_steps_saved)


def joint_to_the_end(problem: ScaleProblem, cap: float = JOINT_FINISH_CAP) -> Answer | None:
    """The joint search's answer if it finishes within ``cap`` seconds, else None."""
    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    with PhysicsChecker(scene) as checker:
        search = make_search(checker, hypotheses, params_for("joint", scene.search))
        result = search.run(cap)
    return (result.code, result.valid) if search.done else None


def peak_memory(problem: ScaleProblem, strategy: Strategy, seconds: float = MEMORY_RUN) -> int:
    """Bytes: the Python heap's peak while ``strategy`` searches ``problem`` for ``seconds``."""
    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    with PhysicsChecker(scene) as checker:
        tracemalloc.start()
        try:
            make_search(checker, hypotheses, params_for(strategy, scene.search)).run(seconds)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()


def run_problem(case: ScaleCase) -> ProblemRun:
    problem = scale_problem(case)
    early, full = exhaustive(problem, "early"), exhaustive(problem, "full")
    answer = (early.code, early.valid)
    same, difference = early_exit_difference(early, full, problem.problem.scene.search.angular_weight)
    runs = {strategy: time_to_answer(problem, strategy, answer) for strategy in STRATEGIES}
    finished = agrees = None
    if case.objects <= JOINT_FINISH_MAX_OBJECTS:
        joint_answer = joint_to_the_end(problem)
        finished = joint_answer is not None
        agrees = None if joint_answer is None else joint_answer == answer
    constructed = answer == (problem.answer, True)
    groups, merges = len(early.groups), early.stats.merges
    return ProblemRun(case, answer, constructed, groups, merges, runs, finished, agrees, same, difference)


def suite_cases(
    layouts: Iterable[str] = LAYOUTS,
    sizes: Iterable[int] = SIZES,
    hypotheses: Iterable[int] = HYPOTHESES,
    seeds: int = SEEDS,
) -> list[ScaleCase]:
    """Every (layout, N, M) with ``seeds`` seeds each; seeds differ across the whole suite."""
    cells = [(layout, objects, count) for layout in layouts for objects in sizes for count in hypotheses]
    cells = [cell for cell in cells for _ in range(seeds)]
    return [ScaleCase(layout, objects, count, seed) for seed, (layout, objects, count) in enumerate(cells)]  # type: ignore[arg-type]


# --- aggregation --------------------------------------------------------------------------------------


Cell = tuple[str, int, int]


@dataclass(frozen=True)
class CellFigures:
    """The figures of one (layout, N, M): shares solved within each budget, median time to the answer,
    configurations per second, share of settling steps early exit spared, peak memory and agreement."""

    cell: Cell
    problems: int
    groups: float
    solved: dict[Strategy, tuple[float, ...]]  # share solved within each of BUDGETS
    median_time: dict[Strategy, float | None]  # None: most problems not solved within the cap
    rate: dict[Strategy, float]  # configurations per second
    steps_saved: float  # grouped search's share of settling steps spared by early exit
    peak_mib: dict[Strategy, float | None]
    joint_finished: int
    agreed: int
    early_exit_same: int
    settled_difference: float


def median_time(runs: Sequence[StrategyRun]) -> float | None:
    times = sorted(run.answer_time if run.answer_time is not None else float("inf") for run in runs)
    value = statistics.median(times)
    return None if value == float("inf") else value


def cell_figures(problems: Sequence[ProblemRun], memory: dict[Cell, dict[Strategy, int]]) -> CellFigures:
    first = problems[0].case
    cell = (first.layout, first.objects, first.hypotheses)
    runs = {s: [p.runs[s] for p in problems] for s in STRATEGIES}
    grouped = runs["grouped"]
    steps = sum(r.settle_steps + r.settle_steps_saved for r in grouped)
    return CellFigures(
        cell=cell,
        problems=len(problems),
        groups=statistics.median(p.groups for p in problems),
        solved={
            s: tuple(sum(r.solved_within(b) for r in runs[s]) / len(problems) for b in BUDGETS) for s in STRATEGIES
        },
        median_time={s: median_time(runs[s]) for s in STRATEGIES},
        rate={s: sum(r.visited for r in runs[s]) / max(1e-9, sum(r.search_time for r in runs[s])) for s in STRATEGIES},
        steps_saved=sum(r.settle_steps_saved for r in grouped) / steps if steps else 0.0,
        peak_mib={s: memory[cell][s] / 2**20 if cell in memory else None for s in STRATEGIES},
        joint_finished=sum(bool(p.joint_finished) for p in problems),
        agreed=sum(bool(p.joint_agrees) for p in problems),
        early_exit_same=sum(p.early_exit_same for p in problems),
        settled_difference=max(p.settled_difference for p in problems),
    )


def by_cell(problems: Sequence[ProblemRun]) -> list[list[ProblemRun]]:
    cells: dict[Cell, list[ProblemRun]] = {}
    for problem in problems:
        cells.setdefault((problem.case.layout, problem.case.objects, problem.case.hypotheses), []).append(problem)
    return list(cells.values())


def _seconds(value: float | None) -> str:
    return "-" if value is None else (f"{value * 1000:.0f} ms" if value < 1.0 else f"{value:.2f} s")


def _kib(value: float | None) -> str:
    return "" if value is None else f"{value * 1024:.0f}"


def figures_table(figures: Sequence[CellFigures]) -> str:
    """The per-(layout, N, M) table, markdown."""
    lines = [
        "| layout | N | M | groups | solved ≤ 0.2 s grouped / joint | solved ≤ 1 s grouped / joint "
        "| median time to answer grouped / joint | configurations/s grouped / joint | settling steps spared "
        "| peak KiB grouped / joint | joint finished, agrees | early exit: outcomes as full, settled within |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for f in figures:
        layout, objects, count = f.cell
        solved = [f"{f.solved['grouped'][i]:.0%} / {f.solved['joint'][i]:.0%}" for i in range(len(BUDGETS))]
        times = f"{_seconds(f.median_time['grouped'])} / {_seconds(f.median_time['joint'])}"
        rates = f"{f.rate['grouped']:.0f} / {f.rate['joint']:.0f}"
        memory = f"{_kib(f.peak_mib['grouped'])} / {_kib(f.peak_mib['joint'])}"
        joint = f"{f.joint_finished}, {f.agreed}" if objects <= JOINT_FINISH_MAX_OBJECTS else ""
        early = f"{f.early_exit_same}/{f.problems}, {f.settled_difference * 1000:.2f} mm"
        lines.append(
            f"| {layout} | {objects} | {count} | {f.groups:g} | {solved[0]} | {solved[1]} | {times} | {rates} "
            f"| {f.steps_saved:.0%} | {memory} | {joint} | {early} |"
        )
    return "\n".join(lines)


@dataclass(frozen=True)
class Targets:
    """The targets of the scale benchmark, measured."""

    grouped_solved: tuple[int, int]  # (solved within 0.2 s, problems) for N <= 50, piles <= 3, M <= 10
    joint_solved_from_10: tuple[int, int]  # the same for the joint search, N >= 10
    agreement: tuple[int, int]  # (agreeing, joint finished)
    speedup_at_6: float | None  # median joint time to answer / median grouped one, N = 6 (problems both solved)
    constructed: tuple[int, int]  # answers equal to the configuration valid by construction
    early_exit_same: tuple[int, int]  # problems where early exits changed no outcome and not the answer
    settled_difference: float  # largest settled-pose difference of an answer, early vs full (m + w rad)
    merges: int  # escape-guard merges over the suite


def targets(problems: Sequence[ProblemRun]) -> Targets:
    target = [p for p in problems if p.case.hypotheses <= 10]
    from_10 = [p for p in target if p.case.objects >= 10]
    at_6 = [p for p in problems if p.case.objects == 6 and all(r.answer_time for r in p.runs.values())]
    finished = [p for p in problems if p.joint_finished]
    speedup = None
    if at_6:
        joint = statistics.median(p.runs["joint"].answer_time or 0.0 for p in at_6)
        grouped = statistics.median(p.runs["grouped"].answer_time or 0.0 for p in at_6)
        speedup = joint / grouped if grouped > 0 else None
    return Targets(
        grouped_solved=(sum(p.runs["grouped"].solved_within(BUDGETS[0]) for p in target), len(target)),
        joint_solved_from_10=(sum(p.runs["joint"].solved_within(BUDGETS[0]) for p in from_10), len(from_10)),
        agreement=(sum(bool(p.joint_agrees) for p in finished), len(finished)),
        speedup_at_6=speedup,
        constructed=(sum(p.constructed for p in problems), len(problems)),
        early_exit_same=(sum(p.early_exit_same for p in problems), len(problems)),
        settled_difference=max(p.settled_difference for p in problems),
        merges=sum(p.merges for p in problems),
    )


def targets_text(found: Targets) -> str:
    solved, total = found.grouped_solved
    joint_solved, joint_total = found.joint_solved_from_10
    agreeing, finished = found.agreement
    share = solved / total if total else 0.0
    speedup = "-" if found.speedup_at_6 is None else f"{found.speedup_at_6:.0f}x"
    verdict = "met" if share >= 0.95 else "missed"
    agreement = "met" if agreeing == finished else "missed"
    faster = "met" if found.speedup_at_6 is not None and found.speedup_at_6 >= 20 else "missed"
    constructed, problems = found.constructed
    return "\n".join(
        [
            f"- grouped search, N <= 50, piles <= 3, M <= 10: the exhaustive answer within 0.2 s in {solved} of "
            f"{total} problems ({share:.1%}; target >= 95 %: {verdict}); "
            f"joint from N = 10: {joint_solved} of {joint_total}",
            f"- where the joint search finishes: the same answer in {agreeing} of {finished} "
            f"(target 100 %: {agreement})",
            f"- time to the answer at N = 6, median joint / median grouped: {speedup} (target >= 20x: {faster})",
            f"- answers equal to the configuration valid by construction: {constructed} of {problems}",
            f"- early exit against full settling: every visited configuration's outcome and the answer the same in "
            f"{found.early_exit_same[0]} of {found.early_exit_same[1]} problems; the answers' settled poses within "
            f"{found.settled_difference * 1000:.3f} mm + weighted rad (tolerance "
            f"{REST_SHARE * SearchParams().jitter_threshold * 1000:.1f} mm)",
            f"- escape-guard merges over the suite: {found.merges}",
        ]
    )


def plot_time_to_answer(problems: Sequence[ProblemRun], path: Path) -> None:
    """PNG: median time to the answer against N, per strategy and M (unsolved problems at the cap)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.0, 4.2), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    counts = sorted({p.case.hypotheses for p in problems})
    sizes = sorted({p.case.objects for p in problems})
    styles = {"grouped": "-", "joint": "--"}
    for strategy in STRATEGIES:
        for index, count in enumerate(counts):
            medians = []
            for objects in sizes:
                runs = [p.runs[strategy] for p in problems if (p.case.objects, p.case.hypotheses) == (objects, count)]
                times = [r.answer_time if r.answer_time is not None else ANSWER_CAP for r in runs]
                medians.append(statistics.median(times))
            axes.plot(sizes, medians, styles[strategy], marker="o", color=f"C{index}", label=f"{strategy}, M = {count}")
    axes.axhline(BUDGETS[0], color="grey", linewidth=0.8)
    axes.text(sizes[0], BUDGETS[0] * 1.08, "node deadline 0.2 s", color="grey", fontsize=8)
    axes.axhline(ANSWER_CAP, color="grey", linewidth=0.8, linestyle=":")
    axes.text(sizes[0], ANSWER_CAP * 1.08, f"not answered within {ANSWER_CAP:g} s", color="grey", fontsize=8)
    axes.set(xscale="log", yscale="log", xlabel="objects N", ylabel="median time to the exhaustive answer [s]")
    axes.set_xticks(sizes, [str(n) for n in sizes])
    axes.set_xticks([], minor=True)
    axes.set_title("Joint (paper) vs grouped search, scale suite (all layouts)", fontsize=10)
    axes.legend(fontsize=7, ncols=2)
    figure.savefig(path, dpi=120)


def run_suite(
    cases: Sequence[ScaleCase], progress: Callable[[int, int, ProblemRun], None] | None = None
) -> tuple[list[ProblemRun], dict[Cell, dict[Strategy, int]]]:
    """Run every case (``progress(done, total, run)`` after each), then measure memory per (layout, N, M)."""
    problems = []
    for index, case in enumerate(cases):
        problems.append(run_problem(case))
        if progress is not None:
            progress(index + 1, len(cases), problems[-1])
    memory: dict[Cell, dict[Strategy, int]] = {}
    for cell_problems in by_cell(problems):
        case = cell_problems[0].case
        problem = scale_problem(case)
        memory[(case.layout, case.objects, case.hypotheses)] = {s: peak_memory(problem, s) for s in STRATEGIES}
    return problems, memory


def plot_groups(problem: ScaleProblem, path: Path) -> None:
    """PNG, seen from above: every object's volume (its hypotheses' body boxes grown by half the margin)
    and its most likely pose, coloured by interaction group."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    grouping = interaction_groups(scene, hypotheses, scene.search.interaction_margin)
    figure = Figure(figsize=(6.4, 6.0), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    colours = matplotlib.colormaps["tab20"]
    for colour_index, members in enumerate(grouping.groups):
        colour = colours(colour_index % 20)
        for index in members:
            for low, high in zip(grouping.lows[index], grouping.highs[index], strict=True):
                size = high - low
                axes.add_patch(Rectangle((low[0], low[1]), size[0], size[1], fill=False, color=colour, lw=0.5))
            x, y, _ = hypotheses[index].pose(1).position
            edge = CUBE_EDGE
            axes.add_patch(Rectangle((x - edge / 2, y - edge / 2), edge, edge, color=colour, alpha=0.6))
            below = [hypotheses[j].pose(1).position for j in members if j < index]
            stacked = sum(1 for position in below if math.dist(position[:2], (x, y)) < edge / 2)
            axes.annotate(f"{index}", (x, y + 0.025 * stacked), ha="center", va="center", fontsize=6)
    axes.autoscale_view()
    axes.set_aspect("equal")
    axes.set(xlabel="x [m]", ylabel="y [m]")
    axes.set_title(
        f"{len(scene.objects)} cubes in {problem.case.layout} piles, M = {problem.case.hypotheses}, seen from above: "
        f"{len(grouping.groups)} interaction groups\noutlines: every hypothesis's body box grown by half the "
        "margin; filled: most likely pose",
        fontsize=8,
    )
    figure.savefig(path, dpi=120)


#: The node memory figure's scene: 50 cubes in small pyramids, 100 hypotheses each (the node's most), T = 0, so the
#: search goes on for the whole run.
NODE_CASE_HYPOTHESES = 100
#: RSS the issue allows the node over ten minutes, bytes (200 MB, decimal megabytes as the issue writes them).
NODE_MEMORY_TARGET = 200 * 10**6


def main(argv: Sequence[str] | None = None) -> None:
    """The suite's table, the targets, the plots (with ``-o``), then the node's memory; progress on stderr."""
    parser = argparse.ArgumentParser(prog="physics-mapper bench scale", description=__doc__)
    parser.add_argument("--seeds", type=int, default=3, help="problems per (layout, N, M) (default: 3)")
    parser.add_argument(
        "--node-minutes", type=float, default=10.0, help="minutes of the node memory run; 0 skips it (default: 10)"
    )
    parser.add_argument("--quick", action="store_true", help="a small suite (N 3, 6, 10; M 5; 1 seed), to try it out")
    parser.add_argument("-o", "--output", type=Path, help="folder for scale.png and scale_groups.png (default: none)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        raise InputError(f"--seeds must be at least 1, got {args.seeds}")
    if args.node_minutes < 0:
        raise InputError(f"--node-minutes must not be negative, got {args.node_minutes:g}")
    cases = suite_cases(sizes=(3, 6, 10), hypotheses=(5,), seeds=1) if args.quick else suite_cases(seeds=args.seeds)
    started = time.monotonic()

    def progress(done: int, total: int, run: ProblemRun) -> None:
        times = " ".join(f"{s} {_seconds(run.runs[s].answer_time)}" for s in STRATEGIES)
        print(f"[{done}/{total} {time.monotonic() - started:.0f} s] {run.case.label}: {times}", file=sys.stderr)

    problems, memory = run_suite(cases, progress)
    figures = [cell_figures(cell, memory) for cell in by_cell(problems)]
    print(f"{len(problems)} problems, {args.seeds if not args.quick else 1} per (layout, N, M); {load_text()}")
    print(figures_table(figures))
    print()
    print(targets_text(targets(problems)))
    if args.output is not None:
        args.output.mkdir(parents=True, exist_ok=True)
        plot_time_to_answer(problems, args.output / "scale.png")
        plot_groups(scale_problem(GROUPS_PICTURE), args.output / "scale_groups.png")
        print(f"\nplots: {args.output / 'scale.png'}, {args.output / 'scale_groups.png'}")
    if args.node_minutes > 0:
        print()
        print(node_memory_text(args.node_minutes))


def load_text() -> str:
    """The machine's load average, as the tables' headers give it."""
    try:
        return "load average " + Path("/proc/loadavg").read_text().split()[0]
    except OSError:
        return "load average unknown"


def node_memory_text(minutes: float) -> str:
    """Run the node on 50 objects for ``minutes`` minutes with unchanged inputs; its RSS over time."""
    from physics_mapper.ros.node_memory import sample_node_memory

    problem = scale_problem(ScaleCase("pyramids", 50, NODE_CASE_HYPOTHESES, 0)).problem
    document = problem_document(problem)
    with tempfile.TemporaryDirectory(prefix="physics_mapper_memory_") as folder:
        directory = Path(folder)
        scene_document = {key: value for key, value in document.items() if key != "hypotheses"}
        (directory / "scene.yaml").write_text(yaml.safe_dump(scene_document))
        (directory / "problem.yaml").write_text(yaml.safe_dump(document))
        parameters = {"probability_threshold": 0.0, "max_age": 86400.0}
        interval = max(1.0, minutes * 60.0 / 40.0)

        def report(sample: object) -> None:
            print(f"node memory: {sample}", file=sys.stderr)

        samples = sample_node_memory(
            directory / "scene.yaml",
            directory / "problem.yaml",
            parameters,
            minutes * 60.0,
            interval,
            directory / "node.log",
            report,
        )
    mb = [sample.rss / 1e6 for sample in samples]
    verdict = "met" if max(sample.rss for sample in samples) < NODE_MEMORY_TARGET else "missed"
    middle = samples[len(samples) // 2]
    return (
        f"node, 50 objects (pyramids, M = {NODE_CASE_HYPOTHESES}, T = 0, unchanged inputs), {minutes:g} min: "
        f"RSS {mb[0]:.0f} MB at the start, {middle.rss / 1e6:.0f} MB after {middle.elapsed:.0f} s, "
        f"{mb[-1]:.0f} MB at the end, {max(mb):.0f} MB at most (target < 200 MB: {verdict})"
    )


if __name__ == "__main__":
    main()

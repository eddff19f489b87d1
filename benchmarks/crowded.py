"""The crowded benchmark: the conflict-directed, the grouped and the joint search on the crowded suite.

Every problem of :mod:`physics_mapper.scenarios.crowded_suite` has one valid configuration, known by
construction (checked valid with the suite's parameters first): *the answer*. Each search runs
afresh in slices of :data:`SLICE` seconds of wall-clock time, as the node's ticks would, until its
result is the answer or :data:`ANSWER_CAP` seconds have passed; the *time to the answer* counts
building the search and searching, not assembling results between slices. The conflict-directed
search's run also gives its counters (conflicts learned, candidates skipped, local and full
settlings), and each configuration it found unstable or valid is settled once more in full (the
whole ``settle_time``, no early exit), in a fresh world: the *agreement* of its verdicts with full
settling. Where the paper's search (per group) finishes within :data:`EXHAUSTIVE_CAP` seconds, its
answer is compared with the conflict-directed one's run to the end, on the suite and on the reduced
suite (:data:`~physics_mapper.scenarios.crowded_suite.REDUCED`), where it always finishes.
Seconds are wall-clock seconds on this machine.

Run: ``physics-mapper bench crowded [--seeds N] [--quick] [-o DIR]``. Prints the table and the
targets BENCHMARKS.md records ("Crowded scenes"), and the scale suite checked with the default
search; with ``-o DIR`` it also writes ``crowded.png`` (time to the answer against N) and
``crowded_search.png`` (one search, candidate by candidate: ``crowded_picture.py``) into ``DIR``,
and without it writes no file. Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import numpy as np

from physics_mapper.model.errors import InputError
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.scenarios.crowded_suite import (
    CROWDED_LAYOUTS,
    REDUCED,
    CrowdedCase,
    CrowdedProblem,
    crowded_problem,
    same_answer,
    truth_is_valid,
)
from physics_mapper.scenarios.problems import AnswerRun, search_until_answer
from physics_mapper.scenarios.scale_suite import ScaleCase, ScaleProblem, scale_problem
from physics_mapper.search.results import SearchResult
from physics_mapper.search.strategy import make_search

Strategy = Literal["conflict", "grouped", "joint"]
STRATEGIES: tuple[Strategy, ...] = ("conflict", "grouped", "joint")
SIZES = (10, 20, 30, 50)
HYPOTHESES = (5, 10)
SEEDS = 2
#: Seconds of search between two looks at the result; seconds a search gets to reach the answer.
SLICE = 0.001
ANSWER_CAP = 1.0
#: The node's default deadline and the cap: the two budgets the table reports.
BUDGETS = (0.2, ANSWER_CAP)
#: Seconds the paper's search gets to finish, for the agreement column.
EXHAUSTIVE_CAP = 5.0


@dataclass(frozen=True)
class SearchRun(AnswerRun):
    """One search on one problem until the answer (:class:`AnswerRun`) and its counters."""

    decided: int  # configurations checked or skipped by a conflict
    conflicts: int
    skipped: int
    local_settlings: int
    full_settlings: int


@dataclass(frozen=True)
class ProblemRun:
    """Every search on one problem, the local verdicts' agreement with full settling, and the exhaustive check."""

    case: CrowdedCase
    truth_valid: bool
    runs: dict[Strategy, SearchRun]
    unstable_checked: int  # configurations the conflict search found unstable, settled again in full
    unstable_agreed: int
    valid_checked: int  # configurations it found valid, settled again in full
    valid_agreed: int
    exhaustive_finished: bool
    exhaustive_agrees: bool | None


def params_for(strategy: Strategy, base: SearchParams, trace: bool = False) -> SearchParams:
    """The benchmark's parameters: the defaults with ``strategy``, no trace kept unless asked."""
    return replace(base, strategy=strategy, trace_limit=None if trace else 0)


def time_to_answer(
    problem: CrowdedProblem | ScaleProblem, strategy: Strategy, cap: float = ANSWER_CAP
) -> tuple[SearchRun, SearchResult]:
    """Search in :data:`SLICE` slices until the result is the answer, the search ends or ``cap`` seconds pass."""
    params = params_for(strategy, problem.problem.scene.search, trace=strategy == "conflict")
    answer_time, elapsed, result = search_until_answer(problem.problem, params, (problem.answer, True), SLICE, cap)
    s = result.stats
    run = SearchRun(
        answer_time, elapsed, s.visited + s.skipped, s.conflicts, s.skipped, s.local_settlings, s.full_settlings
    )
    return run, result


#: A Rule 2 verdict of a search's trace that a full settling can confirm.
Verdict = Literal["unstable", "valid"]


def settled_verdicts(
    checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], params: SearchParams, result: SearchResult
) -> dict[Verdict, tuple[int, int]]:
    """Per verdict, unstable or valid: (configurations of ``result``'s trace with it, those a full settling
    of their group in ``checker`` agrees with: unstable, or stable). A full settling runs the whole
    ``settle_time``, no early exit."""
    objects = {group.id: group.objects for group in result.groups}
    counts: dict[Verdict, tuple[int, int]] = {"unstable": (0, 0), "valid": (0, 0)}
    for entry in result.trace:
        if entry.outcome not in counts:
            continue
        group = objects[entry.group]
        poses = [hypotheses[i].pose(rank) for i, rank in zip(group, entry.code, strict=True)]
        settling = checker.settle(poses, params.settle_time, params.angular_weight, objects=group)
        stable = settling.is_stable(params.jitter_threshold)
        checked, agreed = counts[entry.outcome]
        counts[entry.outcome] = checked + 1, agreed + (stable == (entry.outcome == "valid"))
    return counts


def full_verdicts(problem: CrowdedProblem, result: SearchResult) -> dict[Verdict, tuple[int, int]]:
    """:func:`settled_verdicts` of ``result`` on ``problem``, in a fresh world."""
    with PhysicsChecker(problem.problem.scene) as checker:
        return settled_verdicts(checker, problem.problem.hypotheses, problem.problem.scene.search, result)


def exhaustive_agreement(
    problem: CrowdedProblem | ScaleProblem, cap: float = EXHAUSTIVE_CAP
) -> tuple[bool, bool | None]:
    """Whether the paper's search per group finishes within ``cap`` s, and then whether the conflict search
    run to the end gives its answer (:func:`~physics_mapper.scenarios.crowded_suite.same_answer`)."""
    scene, hypotheses = problem.problem.scene, problem.problem.hypotheses
    with PhysicsChecker(scene) as checker:
        paper = make_search(checker, hypotheses, params_for("grouped", scene.search))
        expected = paper.run(cap)
        if not paper.done:
            return False, None
    with PhysicsChecker(scene) as checker:
        found = make_search(checker, hypotheses, params_for("conflict", scene.search)).run(None)
    return True, same_answer(found, expected)


def run_problem(case: CrowdedCase, exhaustive_cap: float = EXHAUSTIVE_CAP) -> ProblemRun:
    problem = crowded_problem(case)
    runs, results = {}, {}
    for strategy in STRATEGIES:
        runs[strategy], results[strategy] = time_to_answer(problem, strategy)
    verdicts = full_verdicts(problem, results["conflict"])
    finished, agrees = exhaustive_agreement(problem, exhaustive_cap)
    return ProblemRun(case, truth_is_valid(problem), runs, *verdicts["unstable"], *verdicts["valid"], finished, agrees)


def suite_cases(
    layouts: Iterable[str] = CROWDED_LAYOUTS,
    sizes: Iterable[int] = SIZES,
    hypotheses: Iterable[int] = HYPOTHESES,
    seeds: int = SEEDS,
) -> list[CrowdedCase]:
    """Every (layout, N, M) with ``seeds`` seeds each; seeds differ across the whole suite (from 100: the
    reduced suite has the first ones)."""
    cells = [(layout, objects, count) for layout in layouts for objects in sizes for count in hypotheses]
    cells = [cell for cell in cells for _ in range(seeds)]
    return [CrowdedCase(layout, n, m, 100 + seed) for seed, (layout, n, m) in enumerate(cells)]  # type: ignore[arg-type]


def run_suite(
    cases: Sequence[CrowdedCase], progress: Callable[[int, int, ProblemRun], None] | None = None
) -> list[ProblemRun]:
    runs = []
    for index, case in enumerate(cases):
        runs.append(run_problem(case, EXHAUSTIVE_CAP if case.objects <= 10 else 0.0))
        if progress is not None:
            progress(index + 1, len(cases), runs[-1])
    return runs


@dataclass(frozen=True)
class ScaleCheck:
    """The conflict-directed search on the scale suite: answered within 0.2 s, and agreement where the
    paper's search per group finishes."""

    problems: int
    answered: int
    finished: int
    agreed: int


def scale_check(cases: Sequence[ScaleCase], progress: Callable[[int, int], None] | None = None) -> ScaleCheck:
    answered = finished = agreed = 0
    for index, case in enumerate(cases):
        problem = scale_problem(case)
        run, _ = time_to_answer(problem, "conflict")
        answered += run.solved_within(BUDGETS[0])
        done, same = exhaustive_agreement(problem)
        finished += done
        agreed += bool(same)
        if progress is not None:
            progress(index + 1, len(cases))
    return ScaleCheck(len(cases), answered, finished, agreed)


def scale_text(check: ScaleCheck) -> str:
    share = check.answered / check.problems if check.problems else 0.0
    return (
        f"- scale suite, conflict-directed search: the answer within 0.2 s in {check.answered} of {check.problems} "
        f"({share:.1%}); the same answer as the paper's search per group in {check.agreed} of {check.finished} "
        f"where it finished (target 100 %: {'met' if check.agreed == check.finished else 'missed'})"
    )


# --- figures --------------------------------------------------------------------------------------


def _median_time(runs: Sequence[SearchRun]) -> float | None:
    value = statistics.median(r.answer_time if r.answer_time is not None else float("inf") for r in runs)
    return None if value == float("inf") else value


def _seconds(value: float | None) -> str:
    return "-" if value is None else (f"{value * 1000:.0f} ms" if value < 1.0 else f"{value:.2f} s")


def figures_table(problems: Sequence[ProblemRun]) -> str:
    """The per-(layout, N, M) table, markdown: conflict / grouped / joint where three numbers are given."""
    lines = [
        "| layout | N | M | answered ≤ 0.2 s | answered ≤ 1 s | median time to answer | configurations decided/s "
        "| conflicts | skipped | local / full settlings | unstable verdicts as full |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    cells: dict[tuple[str, int, int], list[ProblemRun]] = {}
    for p in problems:
        cells.setdefault((p.case.layout, p.case.objects, p.case.hypotheses), []).append(p)
    for (layout, objects, count), runs in cells.items():
        by = {s: [p.runs[s] for p in runs] for s in STRATEGIES}
        shares = [
            " / ".join(f"{sum(r.solved_within(b) for r in by[s]) / len(runs):.0%}" for s in STRATEGIES) for b in BUDGETS
        ]
        times = " / ".join(_seconds(_median_time(by[s])) for s in STRATEGIES)
        rates = " / ".join(
            f"{sum(r.decided for r in by[s]) / max(1e-9, sum(r.search_time for r in by[s])):.0f}" for s in STRATEGIES
        )
        c = by["conflict"]
        conflicts = statistics.median(r.conflicts for r in c)
        skipped = statistics.median(r.skipped for r in c)
        settlings = (
            f"{statistics.median(r.local_settlings for r in c):g} / {statistics.median(r.full_settlings for r in c):g}"
        )
        verdicts = f"{sum(p.unstable_agreed for p in runs)}/{sum(p.unstable_checked for p in runs)}"
        lines.append(
            f"| {layout} | {objects} | {count} | {shares[0]} | {shares[1]} | {times} | {rates} | {conflicts:g} "
            f"| {skipped:g} | {settlings} | {verdicts} |"
        )
    return "\n".join(lines)


def linear_fit(problems: Sequence[ProblemRun], strategy: Strategy = "conflict") -> tuple[float, float]:
    """Least-squares t = a + b N over the answered problems (seconds; a, b)."""
    points = [(p.case.objects, p.runs[strategy].answer_time) for p in problems if p.runs[strategy].answer_time]
    if len(points) < 2:
        return 0.0, 0.0
    n, t = np.array(points, dtype=float).T
    slope, intercept = np.polyfit(n, t, 1)
    return float(intercept), float(slope)


def targets_text(problems: Sequence[ProblemRun], reduced: Sequence[ProblemRun]) -> str:
    answered = sum(p.runs["conflict"].solved_within(BUDGETS[0]) for p in problems)
    others = {s: sum(p.runs[s].solved_within(BUDGETS[0]) for p in problems) for s in ("grouped", "joint")}
    finished = [p for p in (*problems, *reduced) if p.exhaustive_finished]
    agreed = sum(bool(p.exhaustive_agrees) for p in finished)
    checked = sum(p.unstable_checked for p in problems)
    same = sum(p.unstable_agreed for p in problems)
    valid_checked = sum(p.valid_checked for p in problems)
    valid_same = sum(p.valid_agreed for p in problems)
    truth = sum(p.truth_valid for p in problems)
    intercept, slope = linear_fit(problems)
    share = answered / len(problems) if problems else 0.0
    return "\n".join(
        [
            f"- conflict-directed search, N <= 50, M <= 10: answered within 0.2 s in {answered} of {len(problems)} "
            f"problems ({share:.1%}; target >= 95 %: {'met' if share >= 0.95 else 'missed'}); grouped "
            f"{others['grouped']}, joint {others['joint']}",
            f"- where the paper's search finishes: the same answer in {agreed} of {len(finished)} "
            f"(target 100 %: {'met' if agreed == len(finished) else 'missed'})",
            f"- time to answer, least-squares line: {intercept * 1000:.1f} ms + {slope * 1000:.2f} ms x N",
            f"- unstable verdicts (local or full settling) confirmed by a full settling in a fresh world: "
            f"{same} of {checked}",
            f"- valid verdicts confirmed stable by a full settling (the whole settle_time) in a fresh world: "
            f"{valid_same} of {valid_checked}",
            f"- configurations valid by construction that pass both rules: {truth} of {len(problems)}",
        ]
    )


def plot_time_to_answer(problems: Sequence[ProblemRun], path: Path) -> None:
    """PNG: every problem's time to the answer against N, per search (unanswered at the cap), with the
    conflict search's linear fit."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.0, 4.2), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    sizes = sorted({p.case.objects for p in problems})
    for index, strategy in enumerate(STRATEGIES):
        xs = [p.case.objects + (index - 1) * 0.6 for p in problems]
        ys = [p.runs[strategy].answer_time or ANSWER_CAP * 1.05 for p in problems]
        axes.scatter(xs, ys, s=8, color=f"C{index}", alpha=0.6, label=strategy)
        medians = [
            statistics.median(y for x, y in zip(problems, ys, strict=True) if x.case.objects == n) for n in sizes
        ]
        axes.plot(sizes, medians, color=f"C{index}", linewidth=1.0)
    intercept, slope = linear_fit(problems)
    axes.plot(
        sizes,
        [intercept + slope * n for n in sizes],
        "k--",
        linewidth=0.8,
        label=f"conflict fit: {intercept * 1000:.0f} ms + {slope * 1000:.1f} ms x N",
    )
    axes.axhline(BUDGETS[0], color="grey", linewidth=0.8)
    axes.text(sizes[0], BUDGETS[0] * 1.03, "node deadline 0.2 s", color="grey", fontsize=8)
    axes.axhline(ANSWER_CAP, color="grey", linewidth=0.8, linestyle=":")
    axes.text(sizes[0], ANSWER_CAP * 1.07, f"not answered within {ANSWER_CAP:g} s", color="grey", fontsize=8)
    axes.set(xlabel="objects N", ylabel="time to the answer [s]", ylim=(0.0, ANSWER_CAP * 1.15))
    axes.set_xticks(sizes, [str(n) for n in sizes])
    axes.set_title("Crowded suite: conflict-directed vs grouped vs joint search (lines: medians)", fontsize=10)
    axes.legend(fontsize=7)
    figure.savefig(path, dpi=120)


def main(argv: Sequence[str] | None = None) -> None:
    """The crowded suite's table, the targets and the plots (with ``-o``); progress on stderr."""
    import scale
    from crowded_picture import plot_search

    parser = argparse.ArgumentParser(prog="physics-mapper bench crowded", description=__doc__)
    parser.add_argument("--seeds", type=int, default=3, help="problems per (layout, N, M) (default: 3)")
    parser.add_argument("--quick", action="store_true", help="a small suite (N 10, 20; M 5; 1 seed), to try it out")
    parser.add_argument(
        "-o", "--output", type=Path, help="folder for crowded.png and crowded_search.png (default: none)"
    )
    args = parser.parse_args(argv)
    if args.seeds < 1:
        raise InputError(f"--seeds must be at least 1, got {args.seeds}")
    cases = suite_cases(sizes=(10, 20), hypotheses=(5,), seeds=1) if args.quick else suite_cases(seeds=args.seeds)
    started = time.monotonic()

    def progress(done: int, total: int, run: ProblemRun) -> None:
        times = " ".join(f"{s} {_seconds(run.runs[s].answer_time)}" for s in STRATEGIES)
        print(f"[{done}/{total} {time.monotonic() - started:.0f} s] {run.case.label}: {times}", file=sys.stderr)

    problems = run_suite(cases, progress)
    reduced = run_suite(REDUCED, progress)
    scale_cases = scale.suite_cases(sizes=(3, 6, 10), hypotheses=(5,), seeds=1) if args.quick else scale.suite_cases()

    def scale_progress(done: int, total: int) -> None:
        print(f"[scale suite {done}/{total} {time.monotonic() - started:.0f} s]", file=sys.stderr)

    checked = scale_check(scale_cases, scale_progress)
    print(f"{len(problems)} problems, {1 if args.quick else args.seeds} per (layout, N, M); {scale.load_text()}")
    print("Three numbers: conflict / grouped / joint.")
    print(figures_table(problems))
    print()
    print(targets_text(problems, reduced))
    print(scale_text(checked))
    if args.output is not None:
        args.output.mkdir(parents=True, exist_ok=True)
        plot_time_to_answer(problems, args.output / "crowded.png")
        plot_search(args.output / "crowded_search.png")
        print(f"\nplots: {args.output / 'crowded.png'}, {args.output / 'crowded_search.png'}")


if __name__ == "__main__":
    main()

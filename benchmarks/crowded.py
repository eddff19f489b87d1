"""The crowded benchmark: the conflict-directed search (now and last round's), the grouped and the joint search.

Every problem of :mod:`physics_mapper.scenarios.crowded_suite` has one valid configuration, known by
construction (checked valid with the suite's parameters first): *the answer*. The suite: rows, walls,
towers, shelves and bins (N 10-50, M 5 and 10), the same layouts with weights drawn uniformly from 0.2
to 1.0 and ranked (close weights), and bins of pybullet_data's random meshes (N 10, 20, 30). Each
search runs afresh in slices of :data:`SLICE` seconds of wall-clock time, as the node's ticks would,
until its result is the answer or :data:`ANSWER_CAP` seconds have passed; the *time to the answer*
counts building the search and searching, not assembling results between slices. The
conflict-directed search's run also gives its counters (conflicts learned, candidates skipped, local
and full settlings), and each configuration it found unstable or valid is settled once more in full
(the whole ``settle_time``, no early exit), in a fresh world: the *agreement* of its verdicts with full
settling. Where the paper's search (per group) finishes within :data:`EXHAUSTIVE_CAP` seconds, its
answer is compared with the conflict-directed one's run to the end, on the suite and on the reduced
suite (:data:`~physics_mapper.scenarios.crowded_suite.REDUCED`), where it always finishes.

Targets that travel. Seconds are wall-clock seconds on this machine, so the run measures a *reference
settling* beside each search (:class:`ReferenceSettling`, :func:`beside_reference`): Rule 2 of the shipped
``stack`` problem's ground truth in one persistent world, the median of :data:`REFERENCE_REPEATS`, just
before and just after the search, their mean (``physics_costs.py``'s method). Times are reported as measured
and against the node's 0.2 s deadline scaled to the machine as it ran that search, 0.2 s x reference / 6.3 ms
(:data:`REFERENCE_SETTLING`). A virtual machine's speed drifts within a run: on the machine of BENCHMARKS.md's
latest round the reference took 12.3 ms at the start of one run and 6.5 ms at the start of the next, 23
minutes later, and 6.4 to 13.9 ms within one minute; one bin of 30 searched 25 times in a row took 110 to
212 ms, and its time over the mean of the references before and after it varied half as much as its time
(coefficient of variation 0.07 against 0.14; the time's correlation with that mean 0.99, with the reference
before alone 0.63). One reference for a whole run judged every problem by the speed of its first second.

Last round's default. With ``--previous DIR`` (a copy of last round's ``physics_mapper`` package,
e.g. ``git archive d7d60c9 physics_mapper | tar -x -C DIR``), each problem is also searched by that
code's default search, in a subprocess given the same problem (pickled), in the same run.

Run: ``physics-mapper bench crowded [--seeds N] [--quick | --layouts L ...] [--previous DIR] [-o DIR]``. Prints the
table and the targets BENCHMARKS.md records ("Crowded scenes"), naming each problem not answered within its
scaled deadline, and the scale suite checked with the default search; with ``-o DIR`` it also writes
``crowded.png`` (time to the answer against N) and ``crowded_search.png`` (one search, candidate by candidate:
``crowded_picture.py``) into ``DIR``, and without it writes no file. Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Literal, TypeVar

import numpy as np
from with_package import run_with_package

from physics_mapper.model.errors import InputError
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.scenarios.crowded_suite import (
    CROWDED_LAYOUTS,
    REDUCED,
    CrowdedCase,
    CrowdedProblem,
    crowded_problem,
    full_verdicts,
    same_answer,
    truth_is_valid,
)
from physics_mapper.scenarios.problems import AnswerRun, search_until_answer
from physics_mapper.scenarios.scale_suite import ScaleCase, ScaleProblem, scale_problem
from physics_mapper.search.results import SearchResult
from physics_mapper.search.strategy import make_search

T = TypeVar("T")
Strategy = Literal["conflict", "grouped", "joint"]
STRATEGIES: tuple[Strategy, ...] = ("conflict", "grouped", "joint")
#: The searches compared: this code's three, and last round's default (``previous``, with ``--previous``).
Runner = Literal["conflict", "previous", "grouped", "joint"]
SIZES = (10, 20, 30, 50)
MESH_SIZES = (10, 20, 30)
#: The reference settling the node's 0.2 s deadline was set against (s), and that deadline (s).
REFERENCE_SETTLING = 0.0063
NODE_DEADLINE = 0.2
#: Settlings of the reference timed before and after each search, whose median is taken (about 0.1 s of them).
REFERENCE_REPEATS = 9
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
    references: dict[Runner, float]  # s, per search: the reference settling measured beside it
    truth_valid: bool
    runs: dict[Runner, SearchRun]
    unstable_checked: int  # configurations the conflict search found unstable, settled again in full
    unstable_agreed: int
    valid_checked: int  # configurations it found valid, settled again in full
    valid_agreed: int
    exhaustive_finished: bool
    exhaustive_agrees: bool | None

    def deadline(self, runner: Runner) -> float:
        """The node's deadline scaled to the machine as it ran ``runner``'s search of this problem (s)."""
        return scaled_deadline(self.references[runner])

    def answered_in_time(self, runner: Runner) -> bool:
        """Whether ``runner``'s search reached the answer within its scaled deadline."""
        return self.runs[runner].solved_within(self.deadline(runner))


#: The counters of a run that the conflict-directed search's parts keep (``part_counters``; the paper's
#: searches, which learn, skip and settle locally nothing, have none of them: 0).
PART_COUNTERS = ("conflicts", "skipped", "local_settlings", "full_settlings")


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
    conflicts, skipped, local, full = (s.part_counters.get(name, 0) for name in PART_COUNTERS)
    run = SearchRun(answer_time, elapsed, s.visited + skipped, conflicts, skipped, local, full)
    return run, result


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


#: Last round's default search on one pickled (problem, answer, slice, cap), run with that code: its time to
#: the answer, seconds in all and counters, as JSON.
PREVIOUS_RUN = """
import json, pickle, sys, time
from dataclasses import replace
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.strategy import make_search
problem, answer, slice_seconds, cap = pickle.load(sys.stdin.buffer)
params = replace(problem.scene.search, strategy="conflict", trace_limit=0)
with PhysicsChecker(problem.scene) as checker:
    started = time.perf_counter()
    search = make_search(checker, problem.hypotheses, params)
    elapsed = time.perf_counter() - started
    build = elapsed
    while True:
        result = search.run(slice_seconds)
        elapsed = build + result.stats.search_time
        found = (result.code, result.valid) == answer
        if found or search.done or elapsed >= cap:
            break
s = result.stats
# The parts' counters: in part_counters, or (a package from before they were) fields of the stats.
c = {**vars(s), **getattr(s, "part_counters", {})}
print(json.dumps([elapsed if found else None, elapsed, s.visited + c["skipped"], c["conflicts"], c["skipped"],
                  c["local_settlings"], c["full_settlings"]]))
"""


def previous_time_to_answer(problem: CrowdedProblem, previous: Path, cap: float = ANSWER_CAP) -> SearchRun:
    """:func:`time_to_answer` of last round's default search (the package in ``previous``), in a subprocess."""
    data = (problem.problem, (problem.answer, True), SLICE, cap)
    failure = f"last round's search failed on {problem.case.label}"
    return SearchRun(*run_with_package(PREVIOUS_RUN, previous, data, failure))


def beside_reference(reference: ReferenceSettling, search: Callable[[], T]) -> tuple[T, float]:
    """``search()``'s outcome, run between two reference settlings, and their mean (s): the machine's speed
    while it ran (module docstring)."""
    before = reference.measure()
    outcome = search()
    return outcome, (before + reference.measure()) / 2.0


def run_problem(
    case: CrowdedCase,
    reference: ReferenceSettling,
    exhaustive_cap: float = EXHAUSTIVE_CAP,
    previous: Path | None = None,
) -> ProblemRun:
    """Every search on ``case``'s problem, each beside the ``reference`` settling."""
    problem = crowded_problem(case)
    runs: dict[Runner, SearchRun] = {}
    references: dict[Runner, float] = {}
    results = {}
    for strategy in STRATEGIES:
        (runs[strategy], results[strategy]), references[strategy] = beside_reference(
            reference, partial(time_to_answer, problem, strategy)
        )
    if previous is not None:
        runs["previous"], references["previous"] = beside_reference(
            reference, partial(previous_time_to_answer, problem, previous)
        )
    verdicts = full_verdicts(problem, results["conflict"])
    finished, agrees = exhaustive_agreement(problem, exhaustive_cap)
    truth_valid = truth_is_valid(problem)
    return ProblemRun(case, references, truth_valid, runs, *verdicts["unstable"], *verdicts["valid"], finished, agrees)


def suite_cases(
    layouts: Iterable[str] = CROWDED_LAYOUTS,
    sizes: Iterable[int] = SIZES,
    hypotheses: Iterable[int] = HYPOTHESES,
    seeds: int = SEEDS,
    mesh_sizes: Iterable[int] = MESH_SIZES,
) -> list[CrowdedCase]:
    """Every (layout, N, M) with ``seeds`` seeds each, then the same problems with uniform weights, then
    ``seeds`` bins of meshes per N of ``mesh_sizes`` (M 5); seeds differ across the whole suite (from 100:
    the reduced suite has the first ones)."""
    cells = [(layout, objects, count) for layout in layouts for objects in sizes for count in hypotheses]
    cells = [cell for cell in cells for _ in range(seeds)]
    cells += [("mesh_bin", objects, 5) for objects in mesh_sizes for _ in range(seeds)]
    cases = [CrowdedCase(layout, n, m, 100 + seed) for seed, (layout, n, m) in enumerate(cells)]  # type: ignore[arg-type]
    uniform = [replace(case, weights="uniform") for case in cases if case.layout != "mesh_bin"]
    return [*cases, *uniform]


def chosen_cases(seeds: int, quick: bool, layouts: Sequence[str] | None) -> list[CrowdedCase]:
    """The suite's cases: ``seeds`` per (layout, N, M), or the small suite (``quick``), of ``layouts`` only
    (None: all; ``mesh_bin`` for the bins of meshes)."""
    if quick:
        return suite_cases(sizes=(10, 20), hypotheses=(5,), seeds=1, mesh_sizes=(10,))
    if layouts is None:
        return suite_cases(seeds=seeds)
    primitive = [layout for layout in CROWDED_LAYOUTS if layout in layouts]
    return suite_cases(primitive, seeds=seeds, mesh_sizes=MESH_SIZES if "mesh_bin" in layouts else ())


def run_suite(
    cases: Sequence[CrowdedCase],
    reference: ReferenceSettling,
    progress: Callable[[int, int, ProblemRun], None] | None = None,
    previous: Path | None = None,
) -> list[ProblemRun]:
    runs = []
    for index, case in enumerate(cases):
        runs.append(run_problem(case, reference, EXHAUSTIVE_CAP if case.objects <= 10 else 0.0, previous))
        if progress is not None:
            progress(index + 1, len(cases), runs[-1])
    return runs


@dataclass(frozen=True)
class ScaleCheck:
    """The conflict-directed search on the scale suite: answered within the scaled deadline, and agreement
    where the paper's search per group finishes."""

    problems: int
    answered: int
    finished: int
    agreed: int
    references: tuple[float, ...]  # s, the reference settling beside each problem
    misses: tuple[str, ...]  # the problems not answered within the scaled deadline (:func:`miss_text`)


def scale_check(
    cases: Sequence[ScaleCase], reference: ReferenceSettling, progress: Callable[[int, int], None] | None = None
) -> ScaleCheck:
    answered = finished = agreed = 0
    references = []
    misses = []
    for index, case in enumerate(cases):
        problem = scale_problem(case)
        (run, _), measured = beside_reference(reference, partial(time_to_answer, problem, "conflict"))
        references.append(measured)
        deadline = scaled_deadline(measured)
        in_time = run.solved_within(deadline)
        answered += in_time
        if not in_time:
            misses.append(miss_text(case.label, run.answer_time, deadline))
        done, same = exhaustive_agreement(problem)
        finished += done
        agreed += bool(same)
        if progress is not None:
            progress(index + 1, len(cases))
    return ScaleCheck(len(cases), answered, finished, agreed, tuple(references), tuple(misses))


def scale_text(check: ScaleCheck) -> str:
    share = check.answered / check.problems if check.problems else 0.0
    return (
        f"- scale suite, conflict-directed search: the answer within the scaled deadline "
        f"({deadlines_text(check.references)}) in {check.answered} of {check.problems} "
        f"({share:.1%}; target 100 %: {'met' if share == 1.0 else 'missed'}); "
        f"the same answer as the paper's search per group in {check.agreed} of {check.finished} where it finished "
        f"(target 100 %: {'met' if check.agreed == check.finished else 'missed'}); "
        f"not answered within it: {'; '.join(check.misses) or 'none'}"
    )


def miss_text(label: str, answer_time: float | None, deadline: float) -> str:
    """A problem answered after its scaled deadline, or not within the bench's cap: its label, the time to the
    answer and the deadline, in ms."""
    answered = "no answer" if answer_time is None else f"{answer_time * 1000:.0f} ms"
    return f"{label} ({answered} / {deadline * 1000:.0f} ms)"


# --- figures --------------------------------------------------------------------------------------


class ReferenceSettling:
    """This machine's reference settling, timed whenever asked (module docstring): Rule 2 of the ``stack``
    problem's ground truth in one persistent world, the median of :data:`REFERENCE_REPEATS` (``physics_costs.py``'s
    measure). A context manager: the world lives until it exits."""

    def __init__(self) -> None:
        from physics_mapper.commands.files import load_problem_file
        from physics_mapper.model.shipped import shipped_path

        scene = load_problem_file(shipped_path("config/problems/stack.yaml"), "bench").scene
        assert scene.ground_truth is not None  # the shipped stack has its truth
        self._poses, self._params = scene.ground_truth, scene.search
        self._checker = PhysicsChecker(scene)

    def __enter__(self) -> ReferenceSettling:
        return self

    def __exit__(self, *_: object) -> None:
        self._checker.close()

    def measure(self) -> float:
        """Seconds of the reference settling now."""
        from physics_costs import median_seconds

        params = self._params
        return median_seconds(
            lambda: self._checker.settle(self._poses, params.settle_time, params.angular_weight), REFERENCE_REPEATS
        )


def scaled_deadline(reference: float, deadline: float = NODE_DEADLINE) -> float:
    """``deadline`` seconds (the node's 0.2 s unless given) scaled to a machine whose reference settling takes
    ``reference`` seconds."""
    return deadline * reference / REFERENCE_SETTLING


def _references(problems: Sequence[ProblemRun]) -> list[float]:
    """The reference settlings beside the conflict-directed searches (s)."""
    return [p.references["conflict"] for p in problems]


def deadlines_text(references: Sequence[float]) -> str:
    """The scaled deadlines of problems run beside ``references`` (s): their median and range, in ms."""
    deadlines = [scaled_deadline(r) * 1000 for r in references]
    return f"median {statistics.median(deadlines):.0f} ms, {min(deadlines):.0f}-{max(deadlines):.0f} ms"


def runners(problems: Sequence[ProblemRun]) -> tuple[Runner, ...]:
    """The searches the problems were run with, in the tables' order."""
    order: tuple[Runner, ...] = ("conflict", "previous", "grouped", "joint")
    return tuple(r for r in order if problems and r in problems[0].runs)


def _median_time(runs: Sequence[SearchRun]) -> float | None:
    value = statistics.median(r.answer_time if r.answer_time is not None else float("inf") for r in runs)
    return None if value == float("inf") else value


def _seconds(value: float | None) -> str:
    return "-" if value is None else (f"{value * 1000:.0f} ms" if value < 1.0 else f"{value:.2f} s")


def _cells(problems: Sequence[ProblemRun]) -> dict[tuple[str, str, int, int], list[ProblemRun]]:
    cells: dict[tuple[str, str, int, int], list[ProblemRun]] = {}
    for p in problems:
        cells.setdefault((p.case.layout, p.case.weights, p.case.objects, p.case.hypotheses), []).append(p)
    return cells


def figures_table(problems: Sequence[ProblemRun]) -> str:
    """The per-(layout, weights, N, M) table, markdown: one number per search, in :func:`runners`' order."""
    names = runners(problems)
    lines = [
        "| layout | weights | N | M | answered ≤ 0.2 s (as measured) | answered within the scaled deadline "
        "| answered ≤ 1 s | median time to answer | conflicts | skipped | local / full settlings "
        "| unstable verdicts as full |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for (layout, weights, objects, count), runs in _cells(problems).items():
        by = {s: [p.runs[s] for p in runs] for s in names}
        shares = [
            " / ".join(f"{sum(within(p, s) for p in runs) / len(runs):.0%}" for s in names)
            for within in (
                lambda p, s: p.runs[s].solved_within(NODE_DEADLINE),
                ProblemRun.answered_in_time,
                lambda p, s: p.runs[s].solved_within(ANSWER_CAP),
            )
        ]
        times = " / ".join(_seconds(_median_time(by[s])) for s in names)
        c = by["conflict"]
        conflicts = statistics.median(r.conflicts for r in c)
        skipped = sum(r.skipped for r in c)
        settlings = (
            f"{statistics.median(r.local_settlings for r in c):g} / {statistics.median(r.full_settlings for r in c):g}"
        )
        verdicts = f"{sum(p.unstable_agreed for p in runs)}/{sum(p.unstable_checked for p in runs)}"
        lines.append(
            f"| {layout} | {weights} | {objects} | {count} | {shares[0]} | {shares[1]} | {shares[2]} | {times} "
            f"| {conflicts:g} | {skipped} | {settlings} | {verdicts} |"
        )
    return "\n".join(lines)


def linear_fit(problems: Sequence[ProblemRun], strategy: Runner = "conflict") -> tuple[float, float] | None:
    """Least-squares t = a + b N over the answered problems (seconds; a, b); None where they have fewer than two
    sizes N (no line through them)."""
    points = [(p.case.objects, p.runs[strategy].answer_time) for p in problems if p.runs[strategy].answer_time]
    if len({objects for objects, _ in points}) < 2:
        return None
    n, t = np.array(points, dtype=float).T
    slope, intercept = np.polyfit(n, t, 1)
    return float(intercept), float(slope)


def _line_text(intercept: float, slope: float) -> str:
    """A fitted time to answer, t = a + b N (seconds), in milliseconds."""
    return f"{intercept * 1000:.1f} ms + {slope * 1000:.2f} ms x N"


def targets_text(problems: Sequence[ProblemRun], reduced: Sequence[ProblemRun]) -> str:
    """The targets: per layout (and weights) the share answered within each problem's scaled deadline, and the
    rest."""
    names = runners(problems)
    layouts: dict[str, list[ProblemRun]] = {}
    for p in problems:
        layouts.setdefault(f"{p.case.layout} ({p.case.weights} weights)", []).append(p)
    shares = {
        layout: {s: sum(p.answered_in_time(s) for p in runs) / len(runs) for s in names}
        for layout, runs in layouts.items()
    }
    worst = min((share["conflict"] for share in shares.values()), default=0.0)
    misses = [
        miss_text(p.case.label, p.runs["conflict"].answer_time, p.deadline("conflict"))
        for p in problems
        if not p.answered_in_time("conflict")
    ]
    per_layout = "; ".join(
        f"{layout} " + " / ".join(f"{share[s]:.0%}" for s in names) for layout, share in shares.items()
    )
    finished = [p for p in (*problems, *reduced) if p.exhaustive_finished]
    agreed = sum(bool(p.exhaustive_agrees) for p in finished)
    skipped = sum(p.runs["conflict"].skipped for p in problems)
    checked = sum(p.unstable_checked for p in problems)
    same = sum(p.unstable_agreed for p in problems)
    valid_checked = sum(p.valid_checked for p in problems)
    valid_same = sum(p.valid_agreed for p in problems)
    truth = sum(p.truth_valid for p in problems)
    fit = linear_fit(problems)
    line = "not fitted (answers at fewer than two sizes N)" if fit is None else _line_text(*fit)
    return "\n".join(
        [
            f"- answered within the scaled deadline ({deadlines_text(_references(problems))}), per layout, "
            f"{' / '.join(names)}: {per_layout}",
            f"- the conflict-directed search's worst layout: {worst:.0%} (target >= 95 % in every layout: "
            f"{'met' if worst >= 0.95 else 'missed'}); not answered within the scaled deadline (time to the answer "
            f"/ deadline): {'; '.join(misses) or 'none'}",
            f"- candidates generated holding a known conflict (skipped): {skipped} (target 0: "
            f"{'met' if skipped == 0 else 'missed'})",
            f"- where the paper's search finishes: the same answer in {agreed} of {len(finished)} "
            f"(target 100 %: {'met' if agreed == len(finished) else 'missed'})",
            f"- time to answer, least-squares line: {line}",
            f"- unstable verdicts (local or full settling) confirmed by a full settling in a fresh world: "
            f"{same} of {checked}",
            f"- valid verdicts confirmed stable by a full settling (the whole settle_time) in a fresh world: "
            f"{valid_same} of {valid_checked}",
            f"- configurations valid by construction that pass both rules: {truth} of {len(problems)}",
        ]
    )


def plot_time_to_answer(problems: Sequence[ProblemRun], path: Path) -> None:
    """PNG: every problem's time to the answer against N, per search (unanswered at the cap), with the
    conflict search's linear fit and the median of the problems' scaled deadlines."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.0, 4.2), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    sizes = sorted({p.case.objects for p in problems})
    names = runners(problems)
    for index, strategy in enumerate(names):
        xs = [p.case.objects + (index - 1.5) * 0.6 for p in problems]
        ys = [p.runs[strategy].answer_time or ANSWER_CAP * 1.05 for p in problems]
        axes.scatter(xs, ys, s=8, color=f"C{index}", alpha=0.6, label=strategy)
        medians = [
            statistics.median(y for x, y in zip(problems, ys, strict=True) if x.case.objects == n) for n in sizes
        ]
        axes.plot(sizes, medians, color=f"C{index}", linewidth=1.0)
    fit = linear_fit(problems)
    if fit is not None:
        intercept, slope = fit
        axes.plot(
            sizes,
            [intercept + slope * n for n in sizes],
            "k--",
            linewidth=0.8,
            label=f"conflict fit: {intercept * 1000:.0f} ms + {slope * 1000:.1f} ms x N",
        )
    references = _references(problems)
    deadline = scaled_deadline(statistics.median(references))
    axes.axhline(deadline, color="grey", linewidth=0.8)
    scaled = f"0.2 s scaled to this machine: {deadlines_text(references)}"
    axes.text(sizes[0], deadline * 1.03, scaled, color="grey", fontsize=8)
    axes.axhline(ANSWER_CAP, color="grey", linewidth=0.8, linestyle=":")
    axes.text(sizes[0], ANSWER_CAP * 1.07, f"not answered within {ANSWER_CAP:g} s", color="grey", fontsize=8)
    axes.set(xlabel="objects N", ylabel="time to the answer [s]", ylim=(0.0, ANSWER_CAP * 1.15))
    axes.set_xticks(sizes, [str(n) for n in sizes])
    axes.set_title("Crowded suite: time to the answer per search (lines: medians)", fontsize=10)
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
        "--layouts",
        nargs="+",
        choices=[*CROWDED_LAYOUTS, "mesh_bin"],
        help="only these layouts in the suite (default: all); the reduced and the scale suite run whole",
    )
    parser.add_argument("--previous", type=Path, help="folder holding last round's physics_mapper package")
    parser.add_argument(
        "-o", "--output", type=Path, help="folder for crowded.png and crowded_search.png (default: none)"
    )
    args = parser.parse_args(argv)
    if args.seeds < 1:
        raise InputError(f"--seeds must be at least 1, got {args.seeds}")
    if args.previous is not None and not (args.previous / "physics_mapper" / "__init__.py").is_file():
        raise InputError(f"--previous {args.previous}: no physics_mapper package there")
    cases = chosen_cases(args.seeds, args.quick, args.layouts)
    started = time.monotonic()

    def progress(done: int, total: int, run: ProblemRun) -> None:
        times = " ".join(f"{s} {_seconds(run.runs[s].answer_time)}" for s in run.runs)
        scaled = f"scaled deadline {run.deadline('conflict') * 1000:.0f} ms"
        print(
            f"[{done}/{total} {time.monotonic() - started:.0f} s] {run.case.label}: {times} ({scaled})", file=sys.stderr
        )

    scale_cases = scale.suite_cases(sizes=(3, 6, 10), hypotheses=(5,), seeds=1) if args.quick else scale.suite_cases()

    def scale_progress(done: int, total: int) -> None:
        print(f"[scale suite {done}/{total} {time.monotonic() - started:.0f} s]", file=sys.stderr)

    with ReferenceSettling() as reference:
        problems = run_suite(cases, reference, progress, args.previous)
        reduced = run_suite(REDUCED, reference, progress)
        checked = scale_check(scale_cases, reference, scale_progress)
    print(f"{len(problems)} problems, {1 if args.quick else args.seeds} per (layout, N, M); {scale.load_text()}")
    references = _references(problems)
    ms = [r * 1000 for r in references]
    print(
        f"reference settling beside each search (stack, Rule 2, median of {REFERENCE_REPEATS}, before and after the "
        f"search): median {statistics.median(ms):.2f} ms, {min(ms):.2f}-{max(ms):.2f} ms; "
        f"each search's time against the 0.2 s deadline scaled to its own, 0.2 s x reference / "
        f"{REFERENCE_SETTLING * 1000:.1f} ms ({deadlines_text(references)})"
    )
    print(f"Numbers per search: {' / '.join(runners(problems))}.")
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

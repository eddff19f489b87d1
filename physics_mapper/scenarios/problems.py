"""Problems made to load the search (ROS-free), for the benchmarks and the tests that need a search that never ends."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Generic, Literal, TypeVar

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Problem, Scene, SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import Code, SearchResult
from physics_mapper.search.strategy import make_search

#: A suite's layout names (a ``Literal`` of strings).
LayoutT = TypeVar("LayoutT", bound=str)


#: How a suite draws each object's hypothesis weights: its own way (``drawn``), or uniformly from 0.2 to
#: 1.0, then ranked (``uniform``: close weights, not steeply ranked).
Weights = Literal["drawn", "uniform"]


@dataclass(frozen=True)
class SuiteCase(Generic[LayoutT]):
    """One problem of a seeded suite: its layout, N objects, M hypotheses per object, seed and weights."""

    layout: LayoutT
    objects: int
    hypotheses: int
    seed: int
    weights: Weights = "drawn"

    @property
    def label(self) -> str:
        weights = "" if self.weights == "drawn" else f" weights={self.weights}"
        return f"{self.layout} N={self.objects} M={self.hypotheses} seed={self.seed}{weights}"


@dataclass(frozen=True)
class SuiteProblem(Generic[LayoutT]):
    """A suite problem and its only valid configuration (``answer``, a code)."""

    case: SuiteCase[LayoutT]
    problem: Problem
    answer: Code


#: Metres between two objects' columns of hypotheses: for objects up to 0.2 m wide, apart so that no two
#: ever touch, yet within the interaction margin, so that all objects are one interaction group and a
#: grouped search is one search of every combination (columns far apart would be separate small searches).
COLUMN_SPACING = 0.21


def floating_problem(scene: Scene, per_object: int) -> Problem:
    """``per_object`` hypotheses per object, all floating 0.3 m and more above the origin, in columns apart.

    No configuration collides and none is stable, so every one is simulated in full; with
    ``probability_threshold: 0``, a search of ``per_object ** objects`` configurations (60 per
    object: 216,000 for three) runs to every deadline. Weights fall as 1/rank.
    """
    hypotheses = tuple(
        RankedHypotheses.from_weighted(
            [
                Hypothesis(Pose((COLUMN_SPACING * (column - 1), 0.0, 0.3 + 0.01 * i)), 1.0 / (i + 1))
                for i in range(per_object)
            ]
        )
        for column in range(len(scene.objects))
    )
    return Problem(scene, hypotheses)


@dataclass(frozen=True)
class AnswerRun:
    """One search on one suite problem: when its result first was the answer (None: not within the
    cap), and its seconds of search in all; subclasses add their counters."""

    answer_time: float | None
    search_time: float

    def solved_within(self, budget: float) -> bool:
        return self.answer_time is not None and self.answer_time <= budget


def search_until_answer(
    problem: Problem, params: SearchParams, answer: tuple[Code | None, bool], slice_seconds: float, cap: float
) -> tuple[float | None, float, SearchResult]:
    """Search ``problem`` afresh in slices of ``slice_seconds`` until its result is ``answer`` (code,
    validity), the search ends or ``cap`` seconds pass (:func:`search_until`)."""
    with PhysicsChecker(problem.scene) as checker:
        return search_until(checker, problem.hypotheses, params, partial(_is_answer, answer), slice_seconds, cap)


def _is_answer(answer: tuple[Code | None, bool], result: SearchResult) -> bool:
    return (result.code, result.valid) == answer


def search_until(
    checker: PhysicsChecker,
    hypotheses: Sequence[RankedHypotheses],
    params: SearchParams,
    reached: Callable[[SearchResult], bool],
    slice_seconds: float,
    cap: float,
) -> tuple[float | None, float, SearchResult]:
    """Search ``hypotheses`` afresh in ``checker``'s world, in slices of ``slice_seconds``, until its result
    is ``reached``, the search ends or ``cap`` seconds pass: (seconds until then, building the search
    included, None if not reached; seconds in all; the last result). Assembling results between slices
    is not counted."""
    started = time.perf_counter()
    search = make_search(checker, hypotheses, params)
    build = time.perf_counter() - started
    while True:
        result = search.run(slice_seconds)
        elapsed = build + result.stats.search_time
        if reached(result):
            return elapsed, elapsed, result
        if search.done or elapsed >= cap:
            return None, elapsed, result

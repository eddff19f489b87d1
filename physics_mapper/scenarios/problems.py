"""Problems made to load the search (ROS-free), for the benchmarks and the tests that need a search that never ends."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Generic, TypeVar

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Problem, Scene, SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import Code, SearchResult
from physics_mapper.search.strategy import make_search

#: A suite's layout names (a ``Literal`` of strings).
LayoutT = TypeVar("LayoutT", bound=str)


@dataclass(frozen=True)
class SuiteCase(Generic[LayoutT]):
    """One problem of a seeded suite: its layout, N objects, M hypotheses per object and seed."""

    layout: LayoutT
    objects: int
    hypotheses: int
    seed: int

    @property
    def label(self) -> str:
        return f"{self.layout} N={self.objects} M={self.hypotheses} seed={self.seed}"


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
    validity), the search ends or ``cap`` seconds pass: (seconds to the answer, building the search
    included, None if not reached; seconds in all; the last result). Assembling results between
    slices is not counted."""
    with PhysicsChecker(problem.scene) as checker:
        started = time.perf_counter()
        search = make_search(checker, problem.hypotheses, params)
        build = time.perf_counter() - started
        while True:
            result = search.run(slice_seconds)
            elapsed = build + result.stats.search_time
            if (result.code, result.valid) == answer:
                return elapsed, elapsed, result
            if search.done or elapsed >= cap:
                return None, elapsed, result

"""Best-first branch and bound over configurations (paper Algorithm 1, SPEC section 2).

A configuration picks one hypothesis per object and is written as its *code*, the
1-based ranks in object order: ``(2, 1, 1)`` is the paper's C211. Its probability is
the product of the chosen normalised weights,

    p(C) = prod_i w_i(code_i).

The root is (1, ..., 1); a node's children each advance one object's rank by one, so
p(child) <= p(parent) and visits come in non-increasing p(C). A node with p(C) < T is
still checked but not expanded ("bounded"). Rule 1 is tested first, and only
collision-free nodes are simulated. Among valid nodes the least total jitter J wins.

With ``fallback: refine``, once the root has failed a rule and while no node is valid, the
search makes the refined map of the root (:mod:`physics_mapper.core.refine`) before it visits
further nodes, so that a map exists from the first tick; a valid node found later replaces it.

Ties in p(C) are broken by the smaller code in lexicographic order (C112 before
C121), after rounding p(C) to 12 significant digits so that products of the same
weights taken in another order compare equal.
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

from physics_mapper.core.geometry import Pose
from physics_mapper.core.hypotheses import RankedHypotheses
from physics_mapper.core.physics import Collision, PartialSettling, PhysicsChecker, Settling
from physics_mapper.core.refine import RefinedMap, Refinement, refinement_start
from physics_mapper.core.scene import Fallback, SearchParams

Code = tuple[int, ...]
Outcome = Literal["collision", "unstable", "valid"]


@dataclass(frozen=True)
class TraceEntry:
    """One visited node: its code, p(C), outcome and evidence (paper Fig. 4).

    ``bounded`` is true when p(C) < T, so the node was checked but not expanded.
    For ``collision``: ``pair`` and penetration ``depth`` (m). For ``unstable``:
    ``moved`` (the object with the largest J_i) and ``jitter`` (J). For ``valid``: ``jitter``.
    ``parent`` is the node whose expansion first queued this one (None for the root).
    """

    code: Code
    probability: float
    outcome: Outcome
    bounded: bool
    pair: tuple[str, str] | None = None
    depth: float | None = None
    moved: str | None = None
    jitter: float | None = None
    parent: Code | None = None


@dataclass
class SearchStats:
    """Counters and timing of a search, accumulated over resumed runs."""

    visited: int = 0
    expanded: int = 0
    bounded: int = 0
    collisions: int = 0
    unstable: int = 0
    valid: int = 0
    search_time: float = 0.0  # seconds of wall-clock time spent searching
    stopped_at_deadline: bool = False
    exhausted: bool = False  # the queue emptied: every reachable node was visited

    @property
    def configurations_per_second(self) -> float:
        return self.visited / self.search_time if self.search_time > 0.0 else 0.0


@dataclass(frozen=True)
class Candidate:
    """A checked, collision-free configuration with its settling."""

    code: Code
    probability: float
    settling: Settling


@dataclass(frozen=True)
class SearchResult:
    """Best configuration found so far.

    ``valid`` says whether ``code`` passed both rules. When no configuration is valid,
    ``code`` is the fallback's (the collision-free one of highest p(C), when the fallback
    is ``settled``; the root, when it is ``refine``) or None; ``poses`` are the chosen
    hypotheses, ``settled_poses`` the same objects after settling (for ``refine``: the refined
    map), ``object_jitters`` each object's J_i (their sum is ``jitter``). ``fallback`` names the
    fallback that gave the map (None for a valid one or none), and ``refinement`` tells how the
    refined map was made.
    """

    valid: bool
    code: Code | None
    probability: float | None
    jitter: float | None
    poses: tuple[Pose, ...] | None
    settled_poses: tuple[Pose, ...] | None
    object_jitters: tuple[float, ...] | None
    fallback_used: bool
    stats: SearchStats
    trace: tuple[TraceEntry, ...]
    fallback: Fallback | None = None
    refinement: RefinedMap | None = None


def _tie_key(probability: float) -> float:
    return float(f"{probability:.12g}")


@dataclass(order=True)
class _QueueItem:
    neg_probability: float
    code: Code
    probability: float = field(compare=False)
    parent: Code | None = field(compare=False)


class BranchAndBound:
    """Anytime best-first search; :meth:`run` may be called again to resume it.

    The physics checker must hold the same scene the hypotheses are for, objects in
    the same order.
    """

    def __init__(self, checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], params: SearchParams) -> None:
        if len(hypotheses) != len(checker.scene.objects):
            raise ValueError(f"{len(hypotheses)} hypothesis sets for {len(checker.scene.objects)} objects")
        self.checker = checker
        self.hypotheses = tuple(hypotheses)
        self.params = params
        self.stats = SearchStats()
        self._trace: list[TraceEntry] = []
        self._queue: list[_QueueItem] = []
        self._enqueued: set[Code] = set()
        self._best: Candidate | None = None
        self._first_collision_free: Candidate | None = None
        # The node whose settling the deadline interrupted (first in the queue), and that settling.
        self._interrupted: tuple[Code, PartialSettling] | None = None
        # fallback refine: the root's refinement under way, and the refined map once made.
        self._refinement: Refinement | None = None
        self._refined: RefinedMap | None = None
        self._root: Code = tuple(1 for _ in self.hypotheses)
        self._push(self._root, None)

    def probability(self, code: Code) -> float:
        """p(C): product of the chosen hypotheses' normalised weights."""
        return math.prod(h.weight(rank) for h, rank in zip(self.hypotheses, code, strict=True))

    def poses(self, code: Code) -> tuple[Pose, ...]:
        """The chosen hypotheses' poses, in object order."""
        return tuple(h.pose(rank) for h, rank in zip(self.hypotheses, code, strict=True))

    def _push(self, code: Code, parent: Code | None) -> None:
        if code in self._enqueued:
            return
        self._enqueued.add(code)
        probability = self.probability(code)
        heapq.heappush(self._queue, _QueueItem(-_tie_key(probability), code, probability, parent))

    def _children(self, code: Code) -> list[Code]:
        return [(*code[:i], rank + 1, *code[i + 1 :]) for i, rank in enumerate(code) if rank < len(self.hypotheses[i])]

    @property
    def settling_in_progress(self) -> Code | None:
        """The node whose settling the deadline interrupted; the next run continues it first."""
        return None if self._interrupted is None else self._interrupted[0]

    @property
    def done(self) -> bool:
        """True once every reachable node has been visited."""
        return not self._queue

    def run(self, budget: float | None = None) -> SearchResult:
        """Search for at most ``budget`` wall-clock seconds (None: until the queue empties).

        A node whose settling the deadline interrupts is put back and checked first on the
        next run, which continues its simulation where it stopped
        (:meth:`PhysicsChecker.resume_settling`), so resuming loses nothing: the runs together
        visit the same nodes with the same outcomes as one uninterrupted run. A run that gets
        to that node simulates at least :data:`~physics_mapper.physics.CLOCK_CHECK_STEPS` steps
        of it, so a settling longer than the budget still ends after enough runs.
        """
        start = time.monotonic()
        stop_at = None if budget is None else start + budget
        self.stats.stopped_at_deadline = False
        try:
            while self._queue or self._refinement_due():
                if stop_at is not None and time.monotonic() >= stop_at:
                    self.stats.stopped_at_deadline = True
                    break
                if self._refinement_due():
                    if not self._refine(stop_at):
                        self.stats.stopped_at_deadline = True
                        break
                    continue
                item = heapq.heappop(self._queue)
                if not self._visit(item, stop_at):
                    heapq.heappush(self._queue, item)
                    self.stats.stopped_at_deadline = True
                    break
        finally:
            self.stats.search_time += time.monotonic() - start
        self.stats.exhausted = not self._queue
        return self.result()

    def _refinement_due(self) -> bool:
        """Whether the root's refined map is to be made now: fallback refine, the root visited and
        not valid, no valid node yet, no node's settling waiting to be continued."""
        return (
            self.params.fallback == "refine"
            and self._refined is None
            and self._best is None
            and bool(self._trace)
            and self._interrupted is None
        )

    def _refine(self, stop_at: float | None) -> bool:
        """Make (or go on making) the root's refined map; False if ``stop_at`` came first."""
        if self._refinement is None:
            params = self.params
            start = [refinement_start(h, params.refine_mean_radius) for h in self.hypotheses]
            objects = range(len(self.hypotheses))
            self._refinement = Refinement(self.checker, objects, start, self.poses(self._root), params)
        self._refined = self._refinement.run(stop_at)
        return self._refined is not None

    def _visit(self, item: _QueueItem, stop_at: float | None) -> bool:
        """Check one node and expand it; False if the deadline interrupted its settling."""
        code, probability = item.code, item.probability
        bounded = probability < self.params.probability_threshold
        check = self._check(code, stop_at)
        if isinstance(check, PartialSettling):
            self._interrupted = (code, check)
            return False
        if isinstance(check, Collision):
            entry = TraceEntry(code, probability, "collision", bounded, pair=check.pair, depth=check.depth)
        else:
            entry = self._judge(Candidate(code, probability, check), bounded)
        self._record(replace(entry, parent=item.parent))
        if not bounded:
            for child in self._children(code):
                self._push(child, code)
            self.stats.expanded += 1
        return True

    def _check(self, code: Code, stop_at: float | None) -> Collision | Settling | PartialSettling:
        """Rule 1, then Rule 2 if no collision; an interrupted node's settling is continued."""
        interrupted, self._interrupted = self._interrupted, None
        if interrupted is not None and interrupted[0] == code:
            return self.checker.resume_settling(interrupted[1], stop_at)
        poses = self.poses(code)
        params = self.params
        collision = self.checker.find_collision(poses, params.penetration_threshold)
        if collision is not None:
            return collision
        return self.checker.settle(poses, params.settle_time, params.angular_weight, stop_at)

    def _judge(self, candidate: Candidate, bounded: bool) -> TraceEntry:
        settling = candidate.settling
        if self._first_collision_free is None:
            self._first_collision_free = candidate
        if not settling.is_stable(self.params.jitter_threshold):
            moved = self.checker.scene.objects[settling.most_moved].name
            return TraceEntry(
                candidate.code, candidate.probability, "unstable", bounded, moved=moved, jitter=settling.total_jitter
            )
        if self._best is None or settling.total_jitter < self._best.settling.total_jitter:
            self._best = candidate
        return TraceEntry(candidate.code, candidate.probability, "valid", bounded, jitter=settling.total_jitter)

    def _record(self, entry: TraceEntry) -> None:
        self._trace.append(entry)
        stats = self.stats
        stats.visited += 1
        stats.bounded += entry.bounded
        stats.collisions += entry.outcome == "collision"
        stats.unstable += entry.outcome == "unstable"
        stats.valid += entry.outcome == "valid"

    def result(self) -> SearchResult:
        """The best valid configuration so far, else the fallback, with stats and trace."""
        chosen, valid = self._best, True
        fallback = self.params.fallback
        if chosen is None:
            valid = False
            if fallback == "refine" and self._refined is not None:
                return self._refined_result(self._refined)
            chosen = self._first_collision_free if fallback == "settled" else None
        trace = tuple(self._trace)
        if chosen is None:
            return SearchResult(False, None, None, None, None, None, None, False, replace(self.stats), trace)
        return SearchResult(
            valid=valid,
            code=chosen.code,
            probability=chosen.probability,
            jitter=chosen.settling.total_jitter,
            poses=self.poses(chosen.code),
            settled_poses=chosen.settling.settled_poses,
            object_jitters=chosen.settling.jitters,
            fallback_used=not valid,
            stats=replace(self.stats),
            trace=trace,
            fallback=None if valid else fallback,
        )

    def _refined_result(self, refined: RefinedMap) -> SearchResult:
        """The root's refined map as the result: its hypotheses chosen, the map as their settled poses."""
        return SearchResult(
            valid=False,
            code=self._root,
            probability=self.probability(self._root),
            jitter=refined.total_jitter,
            poses=self.poses(self._root),
            settled_poses=refined.settled_poses,
            object_jitters=refined.jitters,
            fallback_used=True,
            stats=replace(self.stats),
            trace=tuple(self._trace),
            fallback="refine",
            refinement=refined,
        )


def solve(checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], params: SearchParams) -> SearchResult:
    """Run a fresh search until ``params.deadline`` seconds have passed or the queue empties."""
    return BranchAndBound(checker, hypotheses, params).run(params.deadline)

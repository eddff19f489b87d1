"""Best-first branch and bound over configurations (paper Algorithm 1), and the search entry points.

A configuration picks one hypothesis per object and is written as its *code*, the
1-based ranks in object order: ``(2, 1, 1)`` is the paper's C211. Its probability is
the product of the chosen normalised weights,

    p(C) = prod_i w_i(code_i).

The root is (1, ..., 1); a node's children each advance one object's rank by one, so
p(child) <= p(parent) and visits come in non-increasing p(C). A node below the bound is
still checked but not expanded ("bounded"): with ``bound: absolute`` (the paper's reading)
when p(C) < T, with ``bound: relative`` when p(C) / p(root) < T, with ``bound: resolving`` (the
default) when p(C) / p(V) < T, V the first valid node found (no node is bounded before one is).
V is the most probable configuration that resolves every known conflict, once found: every more
probable one was rejected (:mod:`physics_mapper.search.conflicts`), so invalid first hypotheses do not
push the valid configuration below T, however many objects have one. Rule 1 is tested first, and
only collision-free nodes are simulated. Among valid nodes the least total jitter J wins; where
objects may be absent (an *absent* hypothesis, :mod:`physics_mapper.model.hypotheses`), first the
most probable pattern of existence (:meth:`BranchAndBound.existence`), then the least J: an object
is left out where no valid configuration holds it, or where being absent is the likelier.

With ``fallback: refine``, once the root has failed a rule and while no node is valid, the
search makes the refined map of the root (:mod:`physics_mapper.physics.refine`) before it visits
further nodes, so that a map exists from the first tick; a valid node found later replaces it.

Ties in p(C) are broken by the smaller code in lexicographic order (C112 before
C121), after rounding p(C) to 12 significant digits so that products of the same
weights taken in another order compare equal. A child's (rounded p, code) key is therefore
always after its parent's, so nodes are visited in strictly increasing key order and a node is
never queued again once visited: the set that keeps a node from being queued twice only needs
to hold the queued nodes.

:class:`BranchAndBound` searches the objects it is given: every object of the scene (the paper's
joint search), or one interaction group (:mod:`physics_mapper.search.grouped`);
:mod:`physics_mapper.search.strategy` picks the search by ``params.strategy``, and every caller goes
through it.

The settlings' early exit (:func:`~physics_mapper.physics.settling.early_exit_rule`, with its
:data:`~physics_mapper.physics.settling.REST_SHARE`) is imported from the physics, which owns it.

Bounded memory: the queue holds at most ``queue_limit`` nodes (beyond, the least probable are
dropped and the search can no longer say it visited everything: it ends ``truncated``); the trace
holds at most ``trace_limit`` entries (later visits are counted in ``untraced``).
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision import Collision
from physics_mapper.physics.refine import RefinedMap, Refinement, refinement_start
from physics_mapper.physics.settling import EarlyExit, PartialSettling, Settling, early_exit_rule
from physics_mapper.physics.world import TIME_STEP
from physics_mapper.search.results import Candidate, Code, GroupResult, SearchResult, SearchStats, TraceEntry

if TYPE_CHECKING:
    from physics_mapper.physics.collision_table import CollisionTable


def tie_key(probability: float) -> float:
    """p(C) rounded to 12 significant digits: the first part of a node's place in the queue (module docstring)."""
    return float(f"{probability:.12g}")


class QueueItem(NamedTuple):
    """A queued node; compared as a tuple, by (-p(C) rounded, code), which are unique in the queue."""

    neg_probability: float
    code: Code
    probability: float
    parent: Code | None


class BranchAndBound:
    """Anytime best-first search; :meth:`run` may be called again to resume it.

    Extension surface, for searches built on this one (one interaction group; the conflict-directed
    search): overridable steps :meth:`step` (one unit of work), :meth:`visit` (check and expand a
    node), :meth:`check` (Rule 1 then Rule 2), :meth:`rule1`, :meth:`settle_node`,
    :meth:`on_settled`, :meth:`record` and :meth:`update_end`; and the tools they use:
    :meth:`bound_cut_some`; :meth:`head`, :meth:`drop_head` and :meth:`push` (the queue, in the paper's order and tie
    rule), :meth:`judge` (a settled node's outcome), :meth:`interrupt` (a settling its deadline
    cut), :meth:`is_bounded`, :attr:`tracks_reach`. The queue's order, the bound and the trace stay
    the paper's whatever a subclass does.

    The physics checker must hold the same scene the hypotheses are for. ``objects`` are the scene
    indices the hypotheses belong to (default: every object, in order); codes then rank those objects
    only, and the others stay parked while settling. With ``collisions`` (a pairwise table) Rule 1
    is looked up there; without it every node gets a collision pass of all objects (the paper's way,
    which needs every object).
    """

    def __init__(
        self,
        checker: PhysicsChecker,
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        objects: Sequence[int] | None = None,
        collisions: CollisionTable | None = None,
    ) -> None:
        self.objects = checker.all_objects if objects is None else tuple(objects)
        if len(hypotheses) != len(self.objects):
            raise ValueError(f"{len(hypotheses)} hypothesis sets for {len(self.objects)} objects")
        if collisions is None and self.objects != checker.all_objects:
            raise ValueError("a search over some objects only needs a pairwise collision table")
        self.checker = checker
        self.hypotheses = tuple(hypotheses)
        self.params = params
        self.collisions = collisions
        self.stats = SearchStats()
        self.queue_limit = params.queue_limit
        #: The group id trace entries carry (None: the codes rank every object).
        self.trace_group: int | None = None
        self._trace: list[TraceEntry] = []
        self._queue: list[QueueItem] = []
        self._enqueued: set[Code] = set()  # the queued codes (visited ones never come back)
        self._best: Candidate | None = None
        self._first_collision_free: Candidate | None = None
        # The node whose settling the deadline interrupted (first in the queue), and that settling.
        self._interrupted: tuple[Code, PartialSettling] | None = None
        # fallback refine: the root's refinement under way, and the refined map once made.
        self._refinement: Refinement | None = None
        self._refined: RefinedMap | None = None
        self._root: Code = tuple(1 for _ in self.hypotheses)
        self.root_probability = self.probability(self._root)
        #: p(C) of the first valid node found (the reference of ``bound: resolving``).
        self.first_valid_probability: float | None = None
        self._configurations = math.prod(len(h) for h in self.hypotheses)
        self._absent_weights = tuple(ranked.absent_weight() for ranked in self.hypotheses)
        self.push(self._root, None)

    def probability(self, code: Code) -> float:
        """p(C): product of the chosen hypotheses' normalised weights."""
        return math.prod(h.weight(rank) for h, rank in zip(self.hypotheses, code, strict=True))

    def poses(self, code: Code) -> tuple[Pose, ...]:
        """The chosen hypotheses' poses, in object order."""
        return tuple(h.pose(rank) for h, rank in zip(self.hypotheses, code, strict=True))

    def is_bounded(self, probability: float) -> bool:
        """Whether a node of p(C) = ``probability`` is below the bound (checked, not expanded)."""
        threshold = self.params.probability_threshold
        if self.params.bound == "relative":
            return probability / self.root_probability < threshold
        if self.params.bound == "resolving":
            reference = self.first_valid_probability
            return reference is not None and probability / reference < threshold
        return probability < threshold

    @property
    def bounds_any(self) -> bool:
        """Whether some node can be below the bound yet (``bound: resolving`` bounds none before a valid one)."""
        return self.params.bound != "resolving" or self.first_valid_probability is not None

    def push(self, code: Code, parent: Code | None) -> None:
        """Queue node ``code`` (first queued by expanding ``parent``), unless it is queued already."""
        if code in self._enqueued:
            return
        self._enqueued.add(code)
        probability = self.probability(code)
        heapq.heappush(self._queue, QueueItem(-tie_key(probability), code, probability, parent))
        if len(self._queue) > self.queue_limit:
            self._trim_queue()

    def _trim_queue(self) -> None:
        """Drop the least probable queued nodes, down to three quarters of the limit (so trims are rare)."""
        keep = max(1, self.queue_limit - self.queue_limit // 4)
        keys = np.fromiter((item.neg_probability for item in self._queue), float, len(self._queue))
        cut = np.partition(keys, keep - 1)[keep - 1]
        kept = [item for item in self._queue if item.neg_probability < cut]
        tied = sorted(item for item in self._queue if item.neg_probability == cut)  # by code, as they would pop
        kept += tied[: keep - len(kept)]
        self.stats.dropped += len(self._queue) - len(kept)
        heapq.heapify(kept)
        self._queue = kept
        self._enqueued = {item.code for item in kept}

    def _children(self, code: Code) -> list[Code]:
        return [(*code[:i], rank + 1, *code[i + 1 :]) for i, rank in enumerate(code) if rank < len(self.hypotheses[i])]

    @property
    def settling_in_progress(self) -> Code | None:
        """The node whose settling the deadline interrupted; the next run continues it first."""
        return None if self._interrupted is None else self._interrupted[0]

    @property
    def done(self) -> bool:
        """True once every reachable node has been visited (and a due refined map made)."""
        return not self._queue and not self.refinement_due

    @property
    def queued(self) -> int:
        """Nodes in the queue (at most ``queue_limit``)."""
        return len(self._queue)

    @property
    def next_probability(self) -> float | None:
        """p(C) of the node the search visits next (None: nothing left)."""
        return self._queue[0].probability if self._queue else None

    @property
    def best_valid(self) -> Candidate | None:
        """The valid configuration of least jitter found so far."""
        return self._best

    def run(self, budget: float | None = None) -> SearchResult:
        """Search for at most ``budget`` wall-clock seconds (None: until the queue empties).

        A node whose settling the deadline interrupts is put back and checked first on the
        next run, which continues its simulation where it stopped
        (:meth:`PhysicsChecker.resume_settling`), so resuming loses nothing: the runs together
        visit the same nodes with the same outcomes as one uninterrupted run. A run that gets
        to that node simulates at least :data:`~physics_mapper.physics.settling.CLOCK_CHECK_STEPS` steps
        of it, so a settling longer than the budget still ends after enough runs.
        """
        start = time.monotonic()
        stop_at = None if budget is None else start + budget
        self.stats.stopped_at_deadline = False
        try:
            while not self.done:
                if stop_at is not None and time.monotonic() >= stop_at:
                    self.stats.stopped_at_deadline = True
                    break
                if not self.step(stop_at):
                    self.stats.stopped_at_deadline = True
                    break
        finally:
            self.stats.search_time += time.monotonic() - start
        return self.result()

    def step(self, stop_at: float | None) -> bool:
        """Make the due refined map, or else visit the next node; False if the deadline ``stop_at``
        came first (the work goes on at the next step)."""
        if self.refinement_due:
            return self._refine(stop_at)
        item = self.drop_head()
        entry = self.visit(item, stop_at)
        if entry is None:
            heapq.heappush(self._queue, item)
            self._enqueued.add(item.code)
        self.update_end()
        return entry is not None

    def head(self) -> QueueItem:
        """The node the search visits next (the queue must not be empty)."""
        return self._queue[0]

    def drop_head(self) -> QueueItem:
        """Take the next node off the queue (extension point: a search that rules it out unchecked)."""
        item = heapq.heappop(self._queue)
        self._enqueued.discard(item.code)
        return item

    def interrupt(self, code: Code, partial: PartialSettling) -> None:
        """Keep the settling of node ``code`` its deadline interrupted: the next run continues it first."""
        self._interrupted = (code, partial)

    @property
    def refinement_due(self) -> bool:
        """Whether the root's refined map is to be made now: fallback refine, the root visited (or
        skipped by a conflict) and not valid, no valid node yet, no node's settling waiting to be continued."""
        return (
            self.params.fallback == "refine"
            and self._refined is None
            and self._best is None
            and self.stats.visited + self.stats.skipped > 0
            and self._interrupted is None
        )

    def _refine(self, stop_at: float | None) -> bool:
        """Make (or go on making) the root's refined map; False if ``stop_at`` came first."""
        if self._refinement is None:
            params = self.params
            start = [refinement_start(h, params.refine_mean_radius) for h in self.hypotheses]
            self._refinement = Refinement(self.checker, self.objects, start, self.poses(self._root), params)
        self._refined = self._refinement.run(stop_at)
        return self._refined is not None

    def update_end(self) -> None:
        """Say how the search ended once its queue is empty (:attr:`SearchStats.end`; extension point)."""
        if self._queue:
            self.stats.end = None
        elif self.stats.dropped:
            self.stats.end = "truncated"
        else:
            self.stats.end = "bounded" if self.bound_cut_some() else "exhausted"

    def bound_cut_some(self) -> bool:
        """Whether the bound kept some configuration from the queue (extension point: a search that
        skips configurations unchecked counts the cut ones itself)."""
        return self.stats.visited != self._configurations

    def visit(self, item: QueueItem, stop_at: float | None) -> TraceEntry | None:
        """Check one node and expand it; None if the deadline interrupted its settling."""
        code, probability = item.code, item.probability
        bounded = self.is_bounded(probability)
        check = self.check(code, stop_at)
        if isinstance(check, PartialSettling):
            self.interrupt(code, check)
            return None
        if isinstance(check, Collision):
            entry = TraceEntry(code, probability, "collision", bounded, pair=check.pair, depth=check.depth)
        else:
            entry = self.judge(Candidate(code, probability, check), bounded)
        entry = replace(entry, parent=item.parent, group=self.trace_group)
        self.record(entry)
        if not bounded:
            for child in self._children(code):
                self.push(child, code)
            self.stats.expanded += 1
        return entry

    def check(self, code: Code, stop_at: float | None) -> Collision | Settling | PartialSettling:
        """Rule 1, then Rule 2 if no collision; an interrupted node's settling is continued."""
        interrupted, self._interrupted = self._interrupted, None
        if interrupted is not None and interrupted[0] == code:
            outcome = self.checker.resume_settling(interrupted[1], stop_at)
            if isinstance(outcome, Settling):
                self.on_settled(code, outcome)
            return outcome
        poses = self.poses(code)
        collision = self.rule1(code, poses)
        if collision is not None:
            return collision
        return self.settle_node(code, poses, stop_at)

    def rule1(self, code: Code, poses: tuple[Pose, ...]) -> Collision | None:
        """Rule 1 of node ``code`` at ``poses``: the deepest overlap beyond the threshold, or None (extension point)."""
        threshold = self.params.penetration_threshold
        if self.collisions is not None:
            return self.collisions.find_collision(self.objects, code, threshold)
        return self.checker.find_collision(poses, threshold)

    @property
    def settling_completely(self) -> bool:
        """Whether the next settling must not stop beyond the threshold: it is the first collision-free
        node's, which the ``settled`` fallback reports."""
        return self._first_collision_free is None and self.params.fallback == "settled"

    def settle_node(self, code: Code, poses: tuple[Pose, ...], stop_at: float | None) -> Settling | PartialSettling:
        """Rule 2 of one collision-free node at ``poses``, interrupted at ``stop_at`` (extension point).

        Settles completely (:attr:`settling_completely`) when a fallback may report it, and calls
        :meth:`on_settled` for a settling the engine finished. An override may serve a settling it
        already knows instead (a memo), without calling :meth:`on_settled`.
        """
        params = self.params
        outcome = self.checker.settle(
            poses,
            params.settle_time,
            params.angular_weight,
            stop_at,
            objects=self.objects,
            early_exit=self.early_exit(),
            track_reach=self.tracks_reach,
        )
        if isinstance(outcome, Settling):
            self.on_settled(code, outcome)
        return outcome

    def early_exit(self) -> EarlyExit | None:
        """When a node's settling may stop early (extension point): at rest, or at rest beyond the jitter
        threshold unless it settles completely (:func:`~physics_mapper.physics.settling.early_exit_rule`)."""
        return early_exit_rule(self.params, complete=self.settling_completely)

    #: Whether settlings record where objects went (the grouped search's escape guard needs it).
    tracks_reach = False

    def on_settled(self, code: Code, settling: Settling) -> None:
        """Called once per settling the engine finished (extension point; overrides call this one)."""
        self.stats.settle_steps += settling.steps
        self.stats.settle_steps_saved += settling.steps_total - settling.steps

    def judge(self, candidate: Candidate, bounded: bool) -> TraceEntry:
        """A settled node's outcome (unstable or valid) as its trace entry; keeps the best valid one."""
        settling = candidate.settling
        if self._first_collision_free is None:
            self._first_collision_free = candidate
        if not settling.is_stable(self.params.jitter_threshold):
            moved = self.checker.scene.objects[self.objects[settling.most_moved]].name
            entry = TraceEntry(
                candidate.code, candidate.probability, "unstable", bounded, moved=moved, jitter=settling.total_jitter
            )
        else:
            if self.first_valid_probability is None:
                self.first_valid_probability = candidate.probability
            if self._best is None or self.preference(candidate) < self.preference(self._best):
                self._best = candidate
            entry = TraceEntry(candidate.code, candidate.probability, "valid", bounded, jitter=settling.total_jitter)
        if settling.stopped is None:
            return entry
        return replace(entry, settle_stop=settling.stopped, settled_time=settling.steps * TIME_STEP)

    def existence(self, code: Code) -> float:
        """The probability of the configuration's pattern of existence: the product, over objects with an
        *absent* hypothesis, of w(absent) where ``code`` leaves the object out and 1 - w(absent) where it
        keeps it (1 when no object may be absent)."""
        return math.prod(
            weight if ranked.is_absent(rank) else 1.0 - weight
            for ranked, weight, rank in zip(self.hypotheses, self._absent_weights, code, strict=True)
            if weight > 0.0
        )

    def preference(self, candidate: Candidate) -> tuple[float, float]:
        """The order of valid candidates, least first: the most probable pattern of existence
        (:meth:`existence`), then the least jitter (the paper's rule, unchanged where nothing may be absent)."""
        return (-self.existence(candidate.code), candidate.settling.total_jitter)

    def record(self, entry: TraceEntry) -> None:
        """Keep a visited node's trace entry (up to ``trace_limit``) and :meth:`count` it (extension point)."""
        limit = self.params.trace_limit
        if limit is None or len(self._trace) < limit:
            self._trace.append(entry)
        else:
            self.stats.untraced += 1
        self.count(entry)

    def count(self, entry: TraceEntry) -> None:
        """Add a visited node's outcome to :attr:`stats`."""
        stats = self.stats
        stats.visited += 1
        stats.bounded += entry.bounded
        stats.collisions += entry.outcome == "collision"
        stats.unstable += entry.outcome == "unstable"
        stats.valid += entry.outcome == "valid"

    def chosen(self) -> tuple[Candidate | None, bool]:
        """The candidate a result reports, and whether it is valid (else the fallback's, or None).

        The fallback reports a complete settling: one stopped beyond the threshold (settled while
        the fallback was ``none``) is simulated again, to the end, first.
        """
        if self._best is not None:
            return self._best, True
        if self.params.fallback == "refine":
            refined = self._refined
            if refined is None:
                return None, False
            settling = Settling(refined.settled_poses, refined.jitters)
            return Candidate(self._root, self.probability(self._root), settling), False
        candidate = self._first_collision_free
        if candidate is None or self.params.fallback != "settled":
            return None, False
        if candidate.settling.stopped == "beyond_threshold":
            params = self.params
            settling = self.checker.settle(
                self.poses(candidate.code),
                params.settle_time,
                params.angular_weight,
                objects=self.objects,
                early_exit=early_exit_rule(params, complete=True),
            )
            candidate = self._first_collision_free = replace(candidate, settling=settling)
        return candidate, False

    def group_result(self, group_id: int | None = None, kept: bool = False) -> GroupResult:
        """This search's part of a result, as a group of :attr:`objects`."""
        chosen, valid = self.chosen()
        return GroupResult(
            id=group_id,
            objects=self.objects,
            valid=valid and chosen is not None,
            code=None if chosen is None else chosen.code,
            probability=None if chosen is None else chosen.probability,
            jitter=None if chosen is None else chosen.settling.total_jitter,
            visited=self.stats.visited,
            end=self.stats.end,
            kept=kept,
            conflicts=self.stats.conflicts,
            conflicts_kept=self.stats.conflicts_kept,
            skipped=self.stats.skipped,
            local_settlings=self.stats.local_settlings,
            full_settlings=self.stats.full_settlings,
        )

    @property
    def refined(self) -> RefinedMap | None:
        """The root's refined map, once made (``fallback: refine``)."""
        return self._refined

    def result(self) -> SearchResult:
        """The best valid configuration so far, else the fallback, with stats and trace."""
        chosen, valid = self.chosen()
        trace = tuple(self._trace)
        groups = (self.group_result(),)
        stats = replace(self.stats, queued=self.queued)
        if chosen is None:
            return SearchResult(False, None, None, None, None, None, None, False, stats, trace, groups=groups)
        refinement = self._refined if not valid and self.params.fallback == "refine" else None
        return SearchResult(
            valid=valid,
            code=chosen.code,
            probability=chosen.probability,
            jitter=chosen.settling.total_jitter,
            poses=self.poses(chosen.code),
            settled_poses=chosen.settling.settled_poses,
            object_jitters=chosen.settling.jitters,
            fallback_used=not valid,
            stats=stats,
            trace=trace,
            fallback=None if valid else self.params.fallback,
            refinement=refinement,
            groups=groups,
        )


class Search(Protocol):
    """What every search offers (:class:`BranchAndBound` over all objects, or a grouped search)."""

    checker: PhysicsChecker
    hypotheses: tuple[RankedHypotheses, ...]
    params: SearchParams

    def run(self, budget: float | None = None) -> SearchResult: ...

    def result(self) -> SearchResult: ...

    @property
    def done(self) -> bool: ...

    @property
    def queued(self) -> int: ...

    @property
    def settling_in_progress(self) -> Code | None: ...


def continuable(running: SearchParams, wanted: SearchParams) -> bool:
    """Whether a search under ``running`` may go on under ``wanted``.

    The deadline and the fallback change neither which nodes are visited nor their outcomes,
    so changing them keeps the search's progress; any other parameter starts a new search.
    """
    return replace(running, deadline=wanted.deadline, fallback=wanted.fallback) == wanted


def resumable(
    previous: Search, checker: PhysicsChecker, hypotheses: tuple[RankedHypotheses, ...], params: SearchParams
) -> bool:
    """Whether ``previous`` may simply go on: the same world and hypotheses, parameters it can continue under."""
    return previous.checker is checker and previous.hypotheses == hypotheses and continuable(previous.params, params)

"""The best-first core of every search (paper Algorithm 1), to which its parts are passed.

A configuration picks one hypothesis per object and is written as its *code*, the
1-based ranks in object order: ``(2, 1, 1)`` is the paper's C211. Its probability is
the product of the chosen normalised weights,

    p(C) = prod_i w_i(code_i).

Candidates come in non-increasing p(C) (the *candidate generator*'s promise: the paper's queue of
children, :mod:`physics_mapper.search.paper_queue`, or conflict-free generation,
:mod:`physics_mapper.search.conflict_directed`). A candidate below the bound is still checked but not
expanded ("bounded"): with ``bound: absolute`` (the paper's reading) when p(C) < T, with
``bound: relative`` when p(C) / p(root) < T, with ``bound: resolving`` (the default) when
p(C) / p(V) < T, V the first valid candidate found (none is bounded before one is). V is the most
probable configuration that resolves every known conflict, once found: every more probable one was
rejected (:mod:`physics_mapper.search.conflicts`), so invalid first hypotheses do not push the valid
configuration below T, however many objects have one. Rule 1 is tested first (the *Rule 1 check*,
:mod:`physics_mapper.search.rule1`), and only collision-free candidates are simulated (the *Rule 2
policy*, :mod:`physics_mapper.search.rule2`, :mod:`physics_mapper.search.trial_settling`). Among valid
candidates the least total jitter J wins; where objects may be absent (an *absent* hypothesis,
:mod:`physics_mapper.model.hypotheses`), first the most probable pattern of existence
(:func:`~physics_mapper.model.hypotheses.existence_probability`), then the least J: an object is left out
where no valid configuration holds it, or where being absent is the likelier.

With ``fallback: refine``, the search first makes the refined map of the root
(:mod:`physics_mapper.physics.refine`), before it visits any candidate, so that every tick has a map:
checking the root first, a collision-free root's settling could take the whole tick on a slow
machine and leave no time for the refined map. A valid candidate found later replaces it.

Ties in p(C) are broken by the smaller code in lexicographic order (C112 before
C121), after rounding p(C) to 12 significant digits (:func:`tie_key`) so that products of the same
weights taken in another order compare equal.

:class:`BestFirst` searches the objects it is given: every object of the scene (the paper's
joint search), or one interaction group (:mod:`physics_mapper.search.grouped`);
:mod:`physics_mapper.search.strategy` composes each strategy from its parts, and every caller goes
through it. No part reads another's state; each keeps its own counters: those every search has it adds
to the result's :class:`~physics_mapper.search.results.SearchStats` (:meth:`count_into`), those only it
has it reports by name (:meth:`counters`), which the core gathers into the stats' ``part_counters``.

Bounded memory: the trace holds at most ``trace_limit`` entries (later visits are counted in
``untraced``); the generators bound their queues.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import replace
from operator import getitem
from typing import Generic, NamedTuple, Protocol, TypeVar

from physics_mapper.model.geometry import Pose, pose_displacement
from physics_mapper.model.hypotheses import RankedHypotheses, existence_probability
from physics_mapper.model.scene import ObjectShape, SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision import Collision
from physics_mapper.physics.refine import RefinedMap, Refinement, refinement_start
from physics_mapper.physics.settling import PartialSettling, Settling, early_exit_rule
from physics_mapper.physics.support import (
    TOUCHING,
    leave_out_displaced,
    moved_away,
    present_where_likelier,
    put_back_supports,
    resting_pairs,
)
from physics_mapper.physics.world import TIME_STEP
from physics_mapper.search.results import (
    Candidate,
    Code,
    Counters,
    GroupResult,
    RuledOut,
    SearchEnd,
    SearchResult,
    SearchStats,
    TraceEntry,
    summed,
)

#: Per object, its normalised weights by rank (index 0 unused): p(C) is looked up for every candidate.
WeightTable = tuple[tuple[float, ...], ...]
#: A conflict named for the trace: its assignments as (object name, rank).
NamedConflict = tuple[tuple[str, int], ...]


def tie_key(probability: float) -> float:
    """p(C) rounded to 12 significant digits: the first part of a candidate's place in the order (module docstring)."""
    return float(f"{probability:.12g}")


def weight_table(hypotheses: Sequence[RankedHypotheses]) -> WeightTable:
    """Per object its weights by rank, index 0 unused (:func:`code_probability`)."""
    return tuple((0.0, *(h.weight for h in ranked.hypotheses)) for ranked in hypotheses)


def code_probability(weights: WeightTable, code: Code) -> float:
    """p(C): the chosen weights multiplied in object order (every part multiplies them so: the same number)."""
    return math.prod(map(getitem, weights, code))


def parents(code: Code) -> Iterator[Code]:
    """The configurations ``code`` is a child of in Algorithm 1 (one object one rank better), in object order."""
    for position, rank in enumerate(code):
        if rank > 1:
            yield (*code[:position], rank - 1, *code[position + 1 :])


class QueueItem(NamedTuple):
    """A candidate to check; compared as a tuple, by (-p(C) rounded, code), which are unique in a queue."""

    neg_probability: float
    code: Code
    probability: float
    parent: Code | None


class Rule1Verdict(NamedTuple):
    """Rule 1 of a candidate: the deepest overlap beyond the threshold (None: none), and every body
    pair's overlap (m) where the check knows them (the pairwise table's; None: the full pass's)."""

    collision: Collision | None
    depths: Mapping[tuple[int, int], float] | None


class Rule1Check(Protocol):
    """A Rule 1 part (:mod:`physics_mapper.search.rule1`)."""

    def check(self, code: Code, poses: tuple[Pose, ...]) -> Rule1Verdict: ...


class Rule2Policy(Protocol):
    """A Rule 2 part (:mod:`physics_mapper.search.rule2`): the settling a collision-free candidate is judged by.

    ``complete``: the settling must not stop beyond the jitter threshold (a fallback may report it).
    A settling the deadline ``stop_at`` cut short comes back as a :class:`PartialSettling`, which the
    core hands to :meth:`resume` when it checks that candidate again. :meth:`count_into` adds the counters
    every search has (simulation steps, memo hits), :meth:`counters` are the part's own (empty: none).
    """

    def settle(
        self, code: Code, poses: tuple[Pose, ...], stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling: ...

    def resume(
        self, code: Code, poses: tuple[Pose, ...], partial: PartialSettling, stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling: ...

    def count_into(self, stats: SearchStats) -> None: ...

    def counters(self) -> Counters: ...


class CandidateGenerator(Protocol):
    """A candidate generator (:mod:`physics_mapper.search.paper_queue`, :mod:`physics_mapper.search.conflict_directed`).

    Candidates come in the paper's order: decreasing p(C), the smaller code first among equal ones
    (:func:`tie_key`). :meth:`ready` finds the next one (False: the deadline came first), :meth:`take`
    hands it out (None: none is left), :meth:`put_back` takes back one whose settling the deadline cut
    short (it is handed out first again), :meth:`observe` learns a checked candidate's verdict and
    returns the conflict it learned from a rejection (for the trace entry). :meth:`count_into` adds the
    counters every search has (nodes dropped), :meth:`counters` are the generator's own (empty: none).
    """

    queue_limit: int

    def ready(self, stop_at: float | None) -> bool: ...

    def take(self) -> QueueItem | None: ...

    def put_back(self, item: QueueItem) -> None: ...

    def observe(
        self, code: Code, verdict: Rule1Verdict | Settling, valid: bool, bounded: bool
    ) -> NamedConflict | None: ...

    @property
    def exhausted(self) -> bool: ...

    @property
    def end(self) -> SearchEnd | None: ...

    @property
    def queued(self) -> int: ...

    @property
    def next_probability(self) -> float | None: ...

    @property
    def ruled_out(self) -> tuple[RuledOut, ...]: ...

    @property
    def live_root(self) -> Code: ...

    def count_into(self, stats: SearchStats) -> None: ...

    def counters(self) -> Counters: ...


class TraceLog(Protocol):
    """Where visited candidates' trace entries go (a :class:`Trace`, or a grouped search's shared one)."""

    def record(self, entry: TraceEntry) -> None: ...

    @property
    def entries(self) -> list[TraceEntry]: ...

    @property
    def untraced(self) -> int: ...


class Trace:
    """Trace entries in visiting order, at most ``limit`` (None: all); later ones only counted."""

    def __init__(self, limit: int | None, entries: Sequence[TraceEntry] = ()) -> None:
        self.limit = limit
        self.entries = list(entries)
        self.untraced = 0

    def record(self, entry: TraceEntry) -> None:
        if self.limit is None or len(self.entries) < self.limit:
            self.entries.append(entry)
        else:
            self.untraced += 1


class Bound:
    """Whether a candidate of p(C) = ``probability`` is below the bound (checked, not expanded; module docstring).

    ``root_probability``: p(root), the reference of ``bound: relative``; :attr:`first_valid_probability`,
    p(C) of the first valid candidate, the reference of ``bound: resolving``.
    """

    def __init__(self, params: SearchParams, root_probability: float) -> None:
        self.mode = params.bound
        self.threshold = params.probability_threshold
        self.root_probability = root_probability
        self.first_valid_probability: float | None = None

    @classmethod
    def of(cls, params: SearchParams, weights: WeightTable) -> Bound:
        """The bound of a search over objects of these weights (its root is every rank 1)."""
        return cls(params, code_probability(weights, tuple(1 for _ in weights)))

    def __call__(self, probability: float) -> bool:
        if self.mode == "relative":
            return probability / self.root_probability < self.threshold
        if self.mode == "resolving":
            reference = self.first_valid_probability
            return reference is not None and probability / reference < self.threshold
        return probability < self.threshold

    def found_valid(self, probability: float) -> None:
        """A valid candidate of p(C) = ``probability`` was found (the first sets the resolving reference)."""
        if self.first_valid_probability is None:
            self.first_valid_probability = probability


G = TypeVar("G", bound=CandidateGenerator)
R = TypeVar("R", bound=Rule2Policy)


class BestFirst(Generic[G, R]):
    """Anytime best-first search over ``objects`` with its parts; :meth:`run` may be called again to resume it.

    The physics checker must hold the same scene the hypotheses are for. ``objects`` are the scene
    indices the hypotheses belong to; codes rank those objects only, and the others stay parked while
    settling. ``bound`` decides which candidates are bounded (the generator asks it too), ``trace``
    keeps the entries (tagged ``trace_group``), ``on_refined`` observe a finished refined map (a grouped
    search's escape guard; they may raise).
    """

    def __init__(
        self,
        checker: PhysicsChecker,
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        objects: Sequence[int],
        *,
        candidates: G,
        rule1: Rule1Check,
        rule2: R,
        bound: Bound,
        trace: TraceLog,
        trace_group: int | None = None,
        on_refined: Sequence[Callable[[RefinedMap], None]] = (),
    ) -> None:
        self.objects = tuple(objects)
        if len(hypotheses) != len(self.objects):
            raise ValueError(f"{len(hypotheses)} hypothesis sets for {len(self.objects)} objects")
        self.checker = checker
        self.hypotheses = tuple(hypotheses)
        self.params = params
        self.candidates = candidates
        self.rule1 = rule1
        self.rule2 = rule2
        self.bound = bound
        self.trace = trace
        #: The group id trace entries carry (None: the codes rank every object).
        self.trace_group = trace_group
        self._on_refined = tuple(on_refined)
        self._counts = SearchStats()  # the core's own counters (visits, outcomes, time)
        self._weights = weight_table(self.hypotheses)
        self._best: Candidate | None = None
        self._first_collision_free: Candidate | None = None
        # The candidate whose settling the deadline interrupted (handed out first again), and that settling.
        self._interrupted: tuple[Code, PartialSettling] | None = None
        # fallback refine: the root's refinement under way, and the refined map once made.
        self._refinement: Refinement | None = None
        self._refined: RefinedMap | None = None
        self._root: Code = tuple(1 for _ in self.hypotheses)
        self._refined_root: Code = self._root  # the code the refined map starts from
        self._refined_candidate: Candidate | None = None  # the map it makes, displaced objects left out
        # The refinement's map so far where a deadline stopped it in its settling (the depenetrated poses).
        self._unsettled: tuple[RefinedMap, Candidate] | None = None

    def probability(self, code: Code) -> float:
        """p(C): product of the chosen hypotheses' normalised weights."""
        return code_probability(self._weights, code)

    def poses(self, code: Code) -> tuple[Pose, ...]:
        """The chosen hypotheses' poses, in object order."""
        return tuple(h.pose(rank) for h, rank in zip(self.hypotheses, code, strict=True))

    @property
    def settling_in_progress(self) -> Code | None:
        """The candidate whose settling the deadline interrupted; the next run continues it first."""
        return None if self._interrupted is None else self._interrupted[0]

    @property
    def settling_group(self) -> int | None:
        """The group id of :attr:`settling_in_progress` (None: none, or the codes rank every object)."""
        return None if self._interrupted is None else self.trace_group

    @property
    def settling_objects(self) -> tuple[int, ...]:
        """The objects (scene indices) of :attr:`settling_in_progress` (none: no settling is)."""
        return () if self._interrupted is None else self.objects

    @property
    def done(self) -> bool:
        """True once no candidate is left (and a due refined map is made)."""
        return self.candidates.exhausted and not self.refinement_due

    @property
    def queued(self) -> int:
        """Candidates the generator holds (at most ``queue_limit``)."""
        return self.candidates.queued

    @property
    def next_probability(self) -> float | None:
        """p(C) of the candidate visited next, or an upper bound while it is not found (None: nothing left)."""
        return self.candidates.next_probability

    @property
    def best_valid(self) -> Candidate | None:
        """The valid configuration of least jitter found so far."""
        return self._best

    @property
    def stats(self) -> SearchStats:
        """The core's counters with its parts' added, how the search stands and how it ended."""
        stats = replace(
            self._counts,
            queued=self.queued,
            end=self.candidates.end,
            untraced=self.trace.untraced,
            part_counters=summed(self.candidates.counters(), self.rule2.counters()),
        )
        self.candidates.count_into(stats)
        self.rule2.count_into(stats)
        return stats

    def run(self, budget: float | None = None) -> SearchResult:
        """Search for at most ``budget`` wall-clock seconds (None: until no candidate is left).

        A candidate whose settling the deadline interrupts is put back and checked first on the
        next run, which continues its simulation where it stopped
        (:meth:`PhysicsChecker.resume_settling`), so resuming loses nothing: the runs together
        visit the same candidates with the same outcomes as one uninterrupted run. A run that gets
        to that candidate simulates at least :data:`~physics_mapper.physics.settling.CLOCK_CHECK_STEPS`
        steps of it, so a settling longer than the budget still ends after enough runs.
        """
        start = time.monotonic()
        stop_at = None if budget is None else start + budget
        self._counts.stopped_at_deadline = False
        try:
            while not self.done:
                if stop_at is not None and time.monotonic() >= stop_at:
                    self._counts.stopped_at_deadline = True
                    break
                if not self.step(stop_at):
                    self._counts.stopped_at_deadline = True
                    break
        finally:
            self._counts.search_time += time.monotonic() - start
        return self.result()

    def step(self, stop_at: float | None) -> bool:
        """Make the due refined map, or else visit the next candidate; False if the deadline ``stop_at``
        came first (finding the candidate, or settling it: the work goes on at the next step)."""
        if self.refinement_due:
            return self._refine(stop_at)
        if not self.candidates.ready(stop_at):
            return False
        item = self.candidates.take()
        if item is None:
            return True
        if self.visit(item, stop_at) is None:
            self.candidates.put_back(item)
            return False
        return True

    @property
    def refinement_due(self) -> bool:
        """Whether the root's refined map is to be made now: fallback refine, none made yet, no valid candidate
        yet, no settling waiting to be continued (module docstring: before the first candidate)."""
        return (
            self.params.fallback == "refine"
            and self._refined is None
            and self._best is None
            and self._interrupted is None
        )

    def _refine(self, stop_at: float | None) -> bool:
        """Make (or go on making) the refined map of the live root (the generator's
        :attr:`~CandidateGenerator.live_root`: each object at its most probable rank nothing ruled out
        alone, so a detection inside a wall or in free fall is left out where it may be absent), with the
        objects it leaves out though more likely there than not started at their most probable pose
        (:func:`present_where_likelier`) and those put back where another rests on them
        (:func:`put_back_supports`), and those it then moves farther than half their size left out where they
        may be absent and hold nothing up (:func:`leave_out_displaced`); False if ``stop_at`` came first."""
        params = self.params
        scene = self.checker.scene
        shapes = [scene.objects[i].shape for i in self.objects]
        if self._refinement is None:
            positions = {scene.objects[i].name: p for p, i in enumerate(self.objects)}
            ruled_out = {(positions[r.object], r.rank) for r in self.candidates.ruled_out if r.object in positions}
            live = present_where_likelier(self.candidates.live_root, self.hypotheses, shapes, ruled_out)
            root = put_back_supports(live, self.hypotheses, shapes, scene.static, params.jitter_threshold)
            self._refined_root = root
            start = [
                refinement_start(h, params.refine_mean_radius) if rank in h.pose_ranks()[:1] else h.pose(rank)
                for h, rank in zip(self.hypotheses, root, strict=True)
            ]
            self._refinement = Refinement(self.checker, self.objects, start, self.poses(root), params)
        refined = self._refined = self._refinement.run(stop_at)
        if refined is None:
            so_far = self._refinement.so_far()
            if so_far is not None and self._unsettled is None:
                self._unsettled = (so_far, self._map_of(so_far, shapes))
            return False
        for observe in self._on_refined:
            observe(refined)
        self._refined_candidate = self._map_of(refined, shapes)
        return True

    def _map_of(self, refined: RefinedMap, shapes: Sequence[ObjectShape]) -> Candidate:
        """The map ``refined`` makes: its settled poses, but of the objects it moved away from where they were
        seen (:func:`moved_away`), those that may be absent left out (:func:`leave_out_displaced`: their
        *absent* hypothesis, J_i 0), and the instances of tracked classes that may not, at their depenetrated
        pose, where they were seen (J_i from their hypothesis)."""
        params, scene = self.params, self.checker.scene
        moved = moved_away(shapes, refined.start_poses, refined.settled_poses)
        # Only an object that moved away and may be absent is ever left out: the others need no contacts.
        droppable = any(self.hypotheses[i].absent_rank() is not None for i in moved)
        near = self.checker.proximities(refined.settled_poses, TOUCHING, self.objects) if droppable else ()
        resting = resting_pairs(near, self.objects)
        code = leave_out_displaced(
            self._refined_root, self.hypotheses, shapes, moved, refined.settled_poses, resting, params.jitter_threshold
        )
        poses, jitters = list(refined.settled_poses), list(refined.jitters)
        for i in moved:
            ranked = self.hypotheses[i]
            if ranked.is_absent(code[i]):
                poses[i], jitters[i] = ranked.pose(code[i]), 0.0
            elif ranked.absent_rank() is None and scene.is_instance(scene.objects[self.objects[i]].name):
                poses[i] = refined.depenetrated_poses[i]
                jitters[i] = pose_displacement(ranked.pose(code[i]), poses[i], params.angular_weight)
        return Candidate(code, self.probability(code), Settling(tuple(poses), tuple(jitters)))

    def visit(self, item: QueueItem, stop_at: float | None) -> TraceEntry | None:
        """Check one candidate and let the generator learn from it; None if the deadline interrupted its settling."""
        code, probability = item.code, item.probability
        bounded = self.bound(probability)
        verdict = self._check(code, stop_at)
        if isinstance(verdict, PartialSettling):
            self._interrupted = (code, verdict)
            return None
        if isinstance(verdict, Settling):
            entry = self._judge(Candidate(code, probability, verdict), bounded)
        else:
            collision = verdict.collision
            assert collision is not None
            entry = TraceEntry(code, probability, "collision", bounded, pair=collision.pair, depth=collision.depth)
        conflict = self.candidates.observe(code, verdict, entry.outcome == "valid", bounded)
        entry = replace(entry, parent=item.parent, group=self.trace_group, conflict=conflict)
        self.trace.record(entry)
        self._count(entry)
        return entry

    def _check(self, code: Code, stop_at: float | None) -> Rule1Verdict | Settling | PartialSettling:
        """Rule 1, then Rule 2 if no collision (a collision's verdict returned); an interrupted
        candidate's settling is continued."""
        interrupted, self._interrupted = self._interrupted, None
        poses = self.poses(code)
        if interrupted is not None and interrupted[0] == code:
            return self.rule2.resume(code, poses, interrupted[1], stop_at, self.settling_completely)
        rule1 = self.rule1.check(code, poses)
        if rule1.collision is not None:
            return rule1
        return self.rule2.settle(code, poses, stop_at, self.settling_completely)

    @property
    def settling_completely(self) -> bool:
        """Whether the next settling must not stop beyond the threshold: it is the first collision-free
        candidate's, which the ``settled`` fallback reports."""
        return self._first_collision_free is None and self.params.fallback == "settled"

    def _judge(self, candidate: Candidate, bounded: bool) -> TraceEntry:
        """A settled candidate's outcome (unstable or valid) as its trace entry; keeps the best valid one."""
        settling = candidate.settling
        if self._first_collision_free is None:
            self._first_collision_free = candidate
        if not settling.is_stable(self.params.jitter_threshold):
            moved = self.checker.scene.objects[self.objects[settling.most_moved]].name
            entry = TraceEntry(
                candidate.code, candidate.probability, "unstable", bounded, moved=moved, jitter=settling.total_jitter
            )
        else:
            self.bound.found_valid(candidate.probability)
            if self._best is None or self.preference(candidate) < self.preference(self._best):
                self._best = candidate
            entry = TraceEntry(candidate.code, candidate.probability, "valid", bounded, jitter=settling.total_jitter)
        if settling.stopped is None:
            return entry
        return replace(entry, settle_stop=settling.stopped, settled_time=settling.steps * TIME_STEP)

    def preference(self, candidate: Candidate) -> tuple[float, float]:
        """The order of valid candidates, least first: the most probable pattern of existence
        (:func:`~physics_mapper.model.hypotheses.existence_probability`), then the least jitter (the paper's
        rule, unchanged where nothing may be absent)."""
        return (-existence_probability(self.hypotheses, candidate.code), candidate.settling.total_jitter)

    def _count(self, entry: TraceEntry) -> None:
        """Add a visited candidate's outcome to the core's counters."""
        counts = self._counts
        counts.visited += 1
        counts.expanded += not entry.bounded
        counts.bounded += entry.bounded
        counts.collisions += entry.outcome == "collision"
        counts.unstable += entry.outcome == "unstable"
        counts.valid += entry.outcome == "valid"

    def chosen(self) -> tuple[Candidate | None, bool]:
        """The candidate a result reports, and whether it is valid (else the fallback's, or None).

        The fallback reports a complete settling: one stopped beyond the threshold (settled while
        the fallback was ``none``) is simulated again, to the end, first.
        """
        if self._best is not None:
            return self._best, True
        if self.params.fallback == "refine":
            if self._refined_candidate is None and self._unsettled is not None:
                return self._unsettled[1], False
            return self._refined_candidate, False
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
        stats = self.stats
        return GroupResult(
            id=group_id,
            objects=self.objects,
            valid=valid and chosen is not None,
            code=None if chosen is None else chosen.code,
            probability=None if chosen is None else chosen.probability,
            jitter=None if chosen is None else chosen.settling.total_jitter,
            visited=stats.visited,
            end=stats.end,
            kept=kept,
            part_counters=stats.part_counters,
            ruled_out=self.candidates.ruled_out,
        )

    @property
    def refined_map(self) -> Candidate | None:
        """The map the root's refinement made (objects it moved away from where they were seen left out where
        they may be absent), once made: also after a valid candidate was found."""
        return self._refined_candidate

    @property
    def refined(self) -> RefinedMap | None:
        """The root's refined map, once made (``fallback: refine``), else its map so far once depenetrated
        (unsettled: :meth:`~physics_mapper.physics.refine.Refinement.so_far`)."""
        if self._refined is None and self._unsettled is not None:
            return self._unsettled[0]
        return self._refined

    def result(self) -> SearchResult:
        """The best valid configuration so far, else the fallback, with stats and trace."""
        chosen, valid = self.chosen()
        trace = tuple(self.trace.entries)
        groups = (self.group_result(),)
        stats = self.stats
        if chosen is None:
            return SearchResult(False, None, None, None, None, None, None, False, stats, trace, groups=groups)
        refinement = self.refined if not valid and self.params.fallback == "refine" else None
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
    """What every search offers its callers (a :class:`BestFirst` over all objects, or a grouped search):
    run it to a deadline and resume it, its result so far, whether it is done, what it holds queued, and
    the candidate (and its group's id, for a grouped search) whose settling the deadline cut short."""

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

    @property
    def settling_group(self) -> int | None: ...

    @property
    def settling_objects(self) -> tuple[int, ...]: ...

    @property
    def refined_map(self) -> Candidate | None: ...


def continuable(running: SearchParams, wanted: SearchParams) -> bool:
    """Whether a search under ``running`` may go on under ``wanted``.

    The deadline and the fallback change neither which candidates are visited nor their outcomes,
    so changing them keeps the search's progress; any other parameter starts a new search.
    """
    return replace(running, deadline=wanted.deadline, fallback=wanted.fallback) == wanted


def resumable(
    previous: Search, checker: PhysicsChecker, hypotheses: tuple[RankedHypotheses, ...], params: SearchParams
) -> bool:
    """Whether ``previous`` may simply go on: the same world and hypotheses, parameters it can continue under."""
    return previous.checker is checker and previous.hypotheses == hypotheses and continuable(previous.params, params)

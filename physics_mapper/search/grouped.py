"""The paper's Algorithm 1 per interaction group, under one shared deadline.

Objects of different interaction groups (:mod:`physics_mapper.search.groups`) never influence each
other's Rule 1 or Rule 2 outcomes, so each group is searched on its own, by :class:`GroupSearch`:
Algorithm 1 with its own queue, tie rule and bound (relative to the group's root with
``bound: relative``), only the group's objects simulated (the others parked, massless), Rule 1 from
the shared pairwise table (:mod:`physics_mapper.physics.collision_table`). A scene is valid iff every
group is; its code joins the groups' codes, p(C) is the product of theirs, J the sum.

One deadline for all groups. The search visits one node at a time, always of the group first in
this order:

1. the group whose settling the last deadline interrupted (it continues where it stopped);
2. groups without a valid configuration yet, before groups that have one (the scene is valid only
   once every group is);
3. the group whose next node is the most probable relative to its root, p(C) / p(root);
4. the group of the lowest object index.

The result, at any moment, combines every group's best so far (or its fallback).

Escape guard: settlings record where their objects went; when an object could reach another group's
volume, the groups concerned are merged and the merged group is searched again from its root (the
visits of the groups it replaces leave the trace). Merged objects stay together in later searches
(the node's next ticks) while their hypotheses are unchanged.

Settle memo: each group remembers up to its share of :data:`SETTLE_MEMO_LIMIT` settlings by sub-code.
A group searched again with the same objects, hypotheses and physics parameters (settle_time,
angular_weight, jitter_threshold, settle_exit), e.g. after a change of T, reuses them instead of
simulating; anything else starts an empty memo.
"""

from __future__ import annotations

import heapq
import math
import time
from array import array
from collections.abc import Sequence
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from physics_mapper.model.extents import body_box
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.physics.refine import RefinedMap
from physics_mapper.physics.settling import PartialSettling, SettleStop, Settling
from physics_mapper.search.branch_and_bound import BranchAndBound, Search, continuable, resumable
from physics_mapper.search.groups import Grouping, interaction_groups
from physics_mapper.search.results import Code, SearchEnd, SearchResult, SearchStats, TraceEntry

#: Settlings a grouped search remembers (each group an equal share), a few hundred bytes each.
SETTLE_MEMO_LIMIT = 5_000

#: The parameters a settling's outcome depends on (a memo is valid while they are unchanged).
PhysicsKey = tuple[float, float, float, str]


def physics_key(params: SearchParams) -> PhysicsKey:
    return (params.settle_time, params.angular_weight, params.jitter_threshold, params.settle_exit)


class Escape(Exception):  # not an error: the guard's signal to merge groups
    """A settling took an object where it can reach the volumes of ``groups`` (positions in the grouping)."""

    def __init__(self, groups: tuple[int, ...]) -> None:
        super().__init__(f"escaped into groups {groups}")
        self.groups = groups


class _FlatSettling(NamedTuple):
    """A settling in a few hundred bytes: its numbers in one array (which the garbage collector skips)."""

    stopped: SettleStop | None
    steps: int
    steps_total: int
    numbers: array[float]  # per object its jitter, then per object position x, y, z and orientation x, y, z, w

    @classmethod
    def of(cls, settling: Settling) -> _FlatSettling:
        numbers = array("d", settling.jitters)
        for pose in settling.settled_poses:
            numbers.extend((*pose.position, *pose.orientation))
        return cls(settling.stopped, settling.steps, settling.steps_total, numbers)

    def settling(self) -> Settling:
        n = self.numbers
        count = len(n) // 8
        poses = tuple(
            Pose((n[i], n[i + 1], n[i + 2]), (n[i + 3], n[i + 4], n[i + 5], n[i + 6])) for i in range(count, len(n), 7)
        )
        return Settling(poses, tuple(n[:count]), self.stopped, self.steps, self.steps_total)


class SettleMemo:
    """Settlings of one group's sub-configurations, valid for given hypotheses and physics parameters.

    A settling stopped beyond the jitter threshold does not serve a node that needs a complete one.
    Settlings are kept as numbers only, so a full memo costs no garbage-collection pauses.
    """

    def __init__(self, hypotheses: tuple[RankedHypotheses, ...], key: PhysicsKey, limit: int) -> None:
        self.hypotheses = hypotheses
        self.key = key
        self.limit = limit
        self._settlings: dict[Code, _FlatSettling] = {}

    def serves(self, hypotheses: tuple[RankedHypotheses, ...], key: PhysicsKey) -> bool:
        return self.hypotheses == hypotheses and self.key == key

    def get(self, code: Code, complete: bool) -> Settling | None:
        flat = self._settlings.get(code)
        if flat is None or (complete and flat.stopped == "beyond_threshold"):
            return None
        return flat.settling()

    def put(self, code: Code, settling: Settling) -> None:
        if code not in self._settlings and len(self._settlings) >= self.limit and self._settlings:
            del self._settlings[next(iter(self._settlings))]  # the oldest
        self._settlings[code] = _FlatSettling.of(settling)


class GroupSearch(BranchAndBound):
    """Algorithm 1 on one interaction group of a :class:`GroupedSearch` (codes rank its objects only)."""

    tracks_reach = True

    def __init__(self, owner: GroupedSearch, group_id: int, objects: tuple[int, ...], memo: SettleMemo) -> None:
        hypotheses = tuple(owner.hypotheses[i] for i in objects)
        super().__init__(owner.checker, hypotheses, owner.params, objects, owner.table)
        self.owner = owner
        self.group_id = group_id
        self.memo = memo
        self.kept = False
        # Trace entries name the group unless it holds every object (then its codes are whole codes).
        self.trace_group = None if objects == owner.checker.all_objects else group_id

    def settle_node(self, code: Code, poses: tuple[Pose, ...], stop_at: float | None) -> Settling | PartialSettling:
        memoised = self.memoised(code)
        if memoised is not None:
            return memoised
        return super().settle_node(code, poses, stop_at)

    def memoised(self, code: Code) -> Settling | None:
        """The memo's settling of ``code`` for this node (None: none serves), counted as a memo hit."""
        memoised = self.memo.get(code, complete=self.settling_completely)
        if memoised is not None:
            self.stats.memo_hits += 1
        return memoised

    def on_settled(self, code: Code, settling: Settling) -> None:
        super().on_settled(code, settling)
        self.guard(code, settling)
        self.memo.put(code, settling)

    def guard(self, code: Code, settling: Settling) -> None:
        """Raise :class:`Escape` if an object's body went where it can reach another group's volume.

        A body that stayed inside its own volume box at its hypothesis meets no other group's volume:
        only objects that went further are looked up.
        """
        assert settling.extent is not None  # tracked by every group search
        if len(self.owner.grouping.groups) == 1:
            return  # no other group to reach
        grouping = self.owner.grouping
        intruded: set[int] = set()
        for index, rank, (low, high) in zip(self.objects, code, settling.extent, strict=True):
            if not grouping.inside(index, rank, low, high):
                intruded.update(grouping.intruded(index, low, high))
        if intruded:
            raise Escape(tuple(sorted(intruded)))

    def _refine(self, stop_at: float | None) -> bool:
        """Make the root's refined map; raise :class:`Escape` if one of its bodies went where it can reach
        another group's volume (a floating object refined onto a neighbouring pile)."""
        made = super()._refine(stop_at)
        refined = self.refined
        if made and refined is not None and len(self.owner.grouping.groups) > 1:
            intruded: set[int] = set()
            models = self.checker.scene.objects
            poses = zip(self.objects, refined.depenetrated_poses, refined.settled_poses, strict=True)
            for index, start, end in poses:
                (low_a, high_a), (low_b, high_b) = (body_box(models[index].shape, pose) for pose in (start, end))
                low, high = np.minimum(low_a, low_b), np.maximum(high_a, high_b)
                intruded.update(self.owner.grouping.intruded(index, tuple(low), tuple(high)))
            if intruded:
                raise Escape(tuple(sorted(intruded)))
        return made

    def record(self, entry: TraceEntry) -> None:
        self.owner.record(entry)
        self.count(entry)


class GroupedSearch:
    """Algorithm 1 per interaction group, anytime and resumable like :class:`BranchAndBound` (module docstring).

    Build one with :func:`~physics_mapper.search.strategy.make_search` (``strategy: grouped``), or
    :meth:`following` to carry over a previous search's groups. Subclasses search each group with
    :attr:`group_search`.
    """

    #: The search each interaction group gets.
    group_search: type[GroupSearch] = GroupSearch

    def __init__(
        self,
        checker: PhysicsChecker,
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        previous: GroupedSearch | None = None,
    ) -> None:
        self.checker = checker
        self.hypotheses = tuple(hypotheses)
        self.params = params
        if previous is not None and previous.checker is not checker:
            previous = None
        unchanged = (
            [old == new for old, new in zip(previous.hypotheses, self.hypotheses, strict=True)]
            if previous is not None
            else [False] * len(self.hypotheses)
        )
        self.table: CollisionTable = (
            CollisionTable(checker, hypotheses) if previous is None else previous.table.updated(hypotheses)
        )
        #: Object sets the escape guard merged, kept together while their hypotheses are unchanged.
        self.links: list[frozenset[int]] = (
            [] if previous is None else [link for link in previous.links if all(unchanged[i] for i in link)]
        )
        self.grouping: Grouping = interaction_groups(checker.scene, hypotheses, params.interaction_margin, self.links)
        self._next_id: int = 0 if previous is None else previous.next_group_id
        self._groups: dict[int, GroupSearch] = {}
        self._trace: list[TraceEntry] = []
        self._untraced = 0
        self._merges = 0
        self._search_time = 0.0
        self._stopped_at_deadline = False
        self._schedule: list[tuple[tuple[int, int, float, int], int]] = []
        self._keys: dict[int, tuple[int, int, float, int]] = {}
        earlier = {} if previous is None else {group.objects: group for group in previous.groups()}
        for objects in self.grouping.groups:
            old = earlier.get(objects)
            same = old is not None and all(unchanged[i] for i in objects)
            if old is not None and same and continuable(old.params, params):
                self._adopt(old)
            else:
                memo = old.memo if old is not None and same else None
                self.add_group(objects, memo)
        if previous is not None:
            kept = {group.trace_group for group in self._groups.values() if group.kept}
            self._trace = [entry for entry in previous.trace if entry.group in kept]
        self._share_limits()

    @classmethod
    def following(
        cls,
        checker: PhysicsChecker,
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        previous: Search | None,
    ) -> GroupedSearch:
        """A search for ``hypotheses``: ``previous`` itself, resumed, if nothing but the deadline or the
        fallback changed; else a new one that keeps every group of ``previous`` still valid."""
        hypotheses = tuple(hypotheses)
        if not isinstance(previous, cls) or type(previous) is not cls:  # another class searches its groups otherwise
            return cls(checker, hypotheses, params)
        if resumable(previous, checker, hypotheses, params):
            previous.params = params
            for group in previous.groups():
                group.params = params
                group.kept = True
            return previous
        return cls(checker, hypotheses, params, previous)

    # --- groups -----------------------------------------------------------------------------------

    def add_group(self, objects: tuple[int, ...], memo: SettleMemo | None) -> GroupSearch:
        """A new group search of ``objects``, scheduled (extension point: a subclass seeds it)."""
        hypotheses = tuple(self.hypotheses[i] for i in objects)
        if memo is None or not memo.serves(hypotheses, physics_key(self.params)):
            memo = SettleMemo(hypotheses, physics_key(self.params), SETTLE_MEMO_LIMIT)
        group = self.group_search(self, self._next_id, objects, memo)
        self._next_id += 1
        self._groups[group.group_id] = group
        self._reschedule(group)
        return group

    def _adopt(self, group: GroupSearch) -> None:
        """Take over a previous search's group, progress and all."""
        group.owner = self
        group.collisions = self.table
        group.params = self.params
        group.kept = True
        self._groups[group.group_id] = group
        self._reschedule(group)

    def _share_limits(self) -> None:
        """Give each group an equal share of the queue and memo limits."""
        count = len(self._groups)
        for group in self._groups.values():
            group.queue_limit = max(1, self.params.queue_limit // count)
            group.memo.limit = max(1, SETTLE_MEMO_LIMIT // count)

    def merge_groups(self, escaped: GroupSearch, positions: tuple[int, ...]) -> None:
        """The escape guard's answer: replace ``escaped`` and the groups at ``positions`` by one, searched
        anew (extension point: a subclass carries over what they learned)."""
        by_objects = {group.objects: group for group in self._groups.values()}
        merged = [escaped, *(by_objects[self.grouping.groups[p]] for p in positions)]
        objects = tuple(sorted(i for group in merged for i in group.objects))
        gone = {group.group_id for group in merged}
        for group_id in gone:
            del self._groups[group_id]
            self._keys.pop(group_id, None)
        self._trace = [entry for entry in self._trace if entry.group not in gone]
        self.links.append(frozenset(objects))
        self.grouping = interaction_groups(
            self.checker.scene, self.hypotheses, self.params.interaction_margin, self.links
        )
        self._merges += 1
        self.add_group(objects, None)
        self._share_limits()

    def record(self, entry: TraceEntry) -> None:
        """Keep a group's trace entry, in visiting order, up to ``trace_limit`` entries in all."""
        limit = self.params.trace_limit
        if limit is None or len(self._trace) < limit:
            self._trace.append(entry)
        else:
            self._untraced += 1

    # --- scheduling (module docstring) ----------------------------------------------------------------

    def _priority(self, group: GroupSearch) -> tuple[int, int, float, int]:
        if group.settling_in_progress is not None or group.refinement_due:
            return (0, 0, -1.0, group.objects[0])  # work the last deadline interrupted, or a due refined map
        next_probability = group.next_probability
        assert next_probability is not None
        return (1, 0 if group.best_valid is None else 1, -next_probability / group.root_probability, group.objects[0])

    def _reschedule(self, group: GroupSearch) -> None:
        if group.done:
            self._keys.pop(group.group_id, None)
            return
        key = self._priority(group)
        self._keys[group.group_id] = key
        heapq.heappush(self._schedule, (key, group.group_id))

    def _next_group(self) -> GroupSearch | None:
        """The group whose node comes next, taken off the schedule (None: every group is done)."""
        while self._schedule:
            key, group_id = heapq.heappop(self._schedule)
            if self._keys.get(group_id) == key:
                del self._keys[group_id]
                return self._groups[group_id]
        return None

    # --- searching ------------------------------------------------------------------------------------

    @property
    def queued(self) -> int:
        """Nodes in the groups' queues (at most ``queue_limit`` in all)."""
        return sum(group.queued for group in self._groups.values())

    @property
    def done(self) -> bool:
        """True once every group's queue is empty."""
        return all(group.done for group in self._groups.values())

    @property
    def settling_in_progress(self) -> Code | None:
        """The code (of its group's objects) whose settling the deadline interrupted; continued first."""
        group = self._interrupted_group()
        return None if group is None else group.settling_in_progress

    @property
    def settling_group(self) -> int | None:
        """The id of the group whose settling the deadline interrupted (None: none, or the group of every object)."""
        group = self._interrupted_group()
        return None if group is None else group.trace_group

    def _interrupted_group(self) -> GroupSearch | None:
        return next((g for g in self._groups.values() if g.settling_in_progress is not None), None)

    def run(self, budget: float | None = None) -> SearchResult:
        """Search every group for at most ``budget`` wall-clock seconds in all (None: until every queue empties)."""
        start = time.monotonic()
        stop_at = None if budget is None else start + budget
        self._stopped_at_deadline = False
        try:
            while (group := self._next_group()) is not None:
                if stop_at is not None and time.monotonic() >= stop_at:
                    self._reschedule(group)
                    self._stopped_at_deadline = True
                    break
                try:
                    finished = group.step(stop_at)
                except Escape as escape:
                    self.merge_groups(group, escape.groups)
                    continue
                self._reschedule(group)
                if not finished:  # the deadline cut a settling (or a refinement) short
                    self._stopped_at_deadline = True
                    break
        finally:
            self._search_time += time.monotonic() - start
        return self.result()

    # --- results --------------------------------------------------------------------------------------

    @property
    def next_group_id(self) -> int:
        """The id the next new group gets (ids are never reused, so trace entries stay unambiguous)."""
        return self._next_id

    @property
    def trace(self) -> tuple[TraceEntry, ...]:
        """Every group's trace entries, in visiting order."""
        return tuple(self._trace)

    def groups(self) -> list[GroupSearch]:
        """The current groups, in order of their first object."""
        return sorted(self._groups.values(), key=lambda group: group.objects[0])

    def stats(self) -> SearchStats:
        """Every group's counters added up, with the grouped search's time and how it ended."""
        stats = SearchStats()
        groups = self.groups()
        for group in groups:
            stats.add(replace(group.stats, queued=group.queued))
        stats.search_time = self._search_time
        stats.stopped_at_deadline = self._stopped_at_deadline
        stats.untraced = self._untraced
        stats.merges = self._merges
        stats.end = _combined_end([group.stats.end for group in groups])
        return stats

    def result(self) -> SearchResult:
        """Every group's best so far combined: valid iff every group's is, J their sum, p(C) their product."""
        groups = self.groups()
        choices = [group.chosen() for group in groups]
        group_results = tuple(group.group_result(group.trace_group, group.kept) for group in groups)
        stats, trace = self.stats(), tuple(self._trace)
        chosen = [candidate for candidate, _ in choices if candidate is not None]
        if len(chosen) < len(groups):
            return SearchResult(False, None, None, None, None, None, None, False, stats, trace, groups=group_results)
        count = len(self.hypotheses)
        code, jitters = [0] * count, [0.0] * count
        poses: list[Pose] = [self.hypotheses[0].pose(1)] * count
        settled = list(poses)
        for group, candidate in zip(groups, chosen, strict=True):
            for position, index in enumerate(group.objects):
                code[index] = candidate.code[position]
                poses[index] = group.hypotheses[position].pose(candidate.code[position])
                settled[index] = candidate.settling.settled_poses[position]
                jitters[index] = candidate.settling.jitters[position]
        valid = all(is_valid for _, is_valid in choices)
        fallback = None if valid else self.params.fallback
        refined = [group.refined for group, (_, is_valid) in zip(groups, choices, strict=True) if not is_valid]
        refinement = combined_refinement([r for r in refined if r is not None]) if fallback == "refine" else None
        return SearchResult(
            valid=valid,
            code=tuple(code),
            probability=math.prod(candidate.probability for candidate in chosen),
            jitter=sum(jitters),
            poses=tuple(poses),
            settled_poses=tuple(settled),
            object_jitters=tuple(jitters),
            fallback_used=not valid,
            stats=stats,
            trace=trace,
            fallback=fallback,
            refinement=refinement,
            groups=group_results,
        )


def combined_refinement(refined: Sequence[RefinedMap]) -> RefinedMap | None:
    """The refined maps of several groups as one, objects in the groups' order (None: none made yet)."""
    if not refined:
        return None
    if len(refined) == 1:
        return refined[0]
    return RefinedMap(
        objects=tuple(i for r in refined for i in r.objects),
        start_poses=tuple(p for r in refined for p in r.start_poses),
        depenetrated_poses=tuple(p for r in refined for p in r.depenetrated_poses),
        settled_poses=tuple(p for r in refined for p in r.settled_poses),
        jitters=tuple(j for r in refined for j in r.jitters),
        iterations=max(r.iterations for r in refined),
        converged=all(r.converged for r in refined),
        initial_overlap=max(r.initial_overlap for r in refined),
        remaining_overlap=max(r.remaining_overlap for r in refined),
    )


def _combined_end(ends: Sequence[SearchEnd | None]) -> SearchEnd | None:
    """How a grouped search ended: None while any group has nodes queued, else the weakest claim."""
    if any(end is None for end in ends):
        return None
    for end in ("truncated", "bounded"):
        if end in ends:
            return end
    return "exhausted"

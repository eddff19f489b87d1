"""Interaction groups under one shared deadline: the grouped scheduler.

Objects of different interaction groups (:mod:`physics_mapper.search.groups`) never influence each
other's Rule 1 or Rule 2 outcomes, so each group is searched on its own, by a
:class:`~physics_mapper.search.best_first.BestFirst` core the *group builder* makes (the paper's parts,
or the conflict-directed ones: :mod:`physics_mapper.search.strategy`): its own queue, tie rule and bound
(relative to the group's root with ``bound: relative``), only the group's objects simulated (the others
parked, massless), Rule 1 from the shared pairwise table (:mod:`physics_mapper.physics.collision_table`).
A scene is valid iff every group is; its code joins the groups' codes, p(C) is the product of theirs,
J the sum.

One deadline for all groups. The search visits one candidate at a time, always of the group first in
this order:

1. the group whose settling the last deadline interrupted (it continues where it stopped); then the
   groups whose refined map is due (``fallback: refine`` makes it before the first candidate), the
   smallest first: a small group's refined map is cheap, and where it takes a body into a neighbour's
   volume (a detection in the air falling onto a pile) the two merge before the neighbour's own is made
   (24 cylinders and a detection above them: refined maps of 23 and then of 24 objects before, of 1 and
   24 now);
2. groups without a valid configuration yet, before groups that have one (the scene is valid only
   once every group is);
3. the group whose next candidate is the most probable relative to its root, p(C) / p(root);
4. the group of the lowest object index.

The result, at any moment, combines every group's best so far (or its fallback).

Escape guard: settlings record where their objects went; when an object could reach another group's
volume, the groups concerned are merged and the merged group is searched again from its root (the
visits of the groups it replaces leave the trace). Merged objects stay together in later searches
(the node's next ticks) while their hypotheses are unchanged.

Settle memo: each group remembers up to its share (in proportion to its objects, as its share of
``queue_limit``) of :data:`~physics_mapper.search.rule2.SETTLE_MEMO_LIMIT` settlings by sub-code
(:class:`~physics_mapper.search.rule2.SettleMemo`), kept by a group searched again with the same objects and
hypotheses.

Carry-over: a group searched anew because some of its objects got new hypotheses keeps, through the
*carry-over* part, what the previous search's groups learned about the others (the conflict-directed
search's conflicts and stable contexts); so does a group the escape guard merged, of the groups it
replaces.
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Generic, Protocol

import numpy as np

from physics_mapper.model.extents import body_box
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.physics.refine import RefinedMap
from physics_mapper.physics.settling import Settling
from physics_mapper.search.best_first import BestFirst, G, R, Trace, continuable, resumable
from physics_mapper.search.groups import Grouping, interaction_groups
from physics_mapper.search.results import Candidate, Code, SearchEnd, SearchResult, SearchStats, TraceEntry
from physics_mapper.search.rule2 import SETTLE_MEMO_LIMIT, SettleMemo, physics_key
from physics_mapper.search.ruling_out import Ground, Grounds


class Escape(Exception):  # not an error: the guard's signal to merge groups
    """A settling took an object where it can reach the volumes of ``groups`` (positions in the grouping)."""

    def __init__(self, groups: tuple[int, ...]) -> None:
        super().__init__(f"escaped into groups {groups}")
        self.groups = groups


class GroupLink:
    """What a group's parts share with the grouped search that holds the group: the pairwise table, the
    grouping, the free-fall pass's grounds and the trace. A later search that adopts the group points them
    at its own."""

    def __init__(self, table: CollisionTable, grouping: Grouping, grounds: Grounds, trace: Trace) -> None:
        self.table = table
        self.grouping = grouping
        self.grounds = grounds
        self.trace = trace

    def collision_table(self) -> CollisionTable:
        return self.table

    def ground(self) -> Ground:
        """The scene's ground for the free-fall pass, under the grouping as it is now."""
        return self.grounds.of(self.grouping)

    def record(self, entry: TraceEntry) -> None:
        self.trace.record(entry)

    @property
    def entries(self) -> list[TraceEntry]:
        return self.trace.entries

    @property
    def untraced(self) -> int:
        return self.trace.untraced


class EscapeGuard:
    """Raises :class:`Escape` when a body of the group's ``objects`` went where it can reach another
    group's volume, after a settling or a refined map (observer of both)."""

    def __init__(self, checker: PhysicsChecker, objects: tuple[int, ...], link: GroupLink) -> None:
        self.checker = checker
        self.objects = objects
        self.link = link

    def settled(self, code: Code, settling: Settling) -> None:
        """A body that stayed inside its own volume box at its hypothesis meets no other group's volume:
        only objects that went further are looked up."""
        assert settling.extent is not None  # tracked by every group's settlings
        grouping = self.link.grouping
        if len(grouping.groups) == 1:
            return  # no other group to reach
        intruded: set[int] = set()
        for index, rank, (low, high) in zip(self.objects, code, settling.extent, strict=True):
            if not grouping.inside(index, rank, low, high):
                intruded.update(grouping.intruded(index, low, high))
        if intruded:
            raise Escape(tuple(sorted(intruded)))

    def refined(self, refined: RefinedMap) -> None:
        """A refined map whose body went where it can reach another group's volume (a floating object
        refined onto a neighbouring pile)."""
        grouping = self.link.grouping
        if len(grouping.groups) == 1:
            return
        intruded: set[int] = set()
        models = self.checker.scene.objects
        poses = zip(self.objects, refined.depenetrated_poses, refined.settled_poses, strict=True)
        for index, start, end in poses:
            (low_a, high_a), (low_b, high_b) = (body_box(models[index].shape, pose) for pose in (start, end))
            low, high = np.minimum(low_a, low_b), np.maximum(high_a, high_b)
            intruded.update(grouping.intruded(index, tuple(low), tuple(high)))
        if intruded:
            raise Escape(tuple(sorted(intruded)))


@dataclass(frozen=True)
class GroupSpec:
    """What a group builder gets: the scene's checker and every object's hypotheses, the parameters, the
    group's ``objects`` (scene indices) and trace id (None: the group holds every object), what it shares
    with the grouped search (``link``), its settle memo and escape guard."""

    checker: PhysicsChecker
    hypotheses: tuple[RankedHypotheses, ...]
    params: SearchParams
    objects: tuple[int, ...]
    trace_group: int | None
    link: GroupLink
    memo: SettleMemo
    guard: EscapeGuard


class GroupBuilder(Protocol[G, R]):
    """Makes the core that searches one group, from its parts."""

    def __call__(self, spec: GroupSpec) -> BestFirst[G, R]: ...


class CarryOver(Protocol[G, R]):
    """What a new group keeps of an older group it overlaps."""

    def holds(self, learned_under: SearchParams, params: SearchParams) -> bool:
        """Whether what was learned under ``learned_under`` holds under ``params``."""
        ...

    def carry(self, old: BestFirst[G, R], new: BestFirst[G, R], changed: set[int]) -> None:
        """Take what ``old`` learned that still holds into ``new`` (``changed``: scene indices with new hypotheses)."""
        ...


class NothingCarried:
    """The carry-over of the paper's parts: they learn nothing beyond the settle memo."""

    def holds(self, learned_under: SearchParams, params: SearchParams) -> bool:
        return False

    def carry(self, old: object, new: object, changed: set[int]) -> None:
        return None


ScheduleKey = tuple[int, int, float, int]


def schedule_key(group: BestFirst[G, R]) -> ScheduleKey:
    """Where ``group`` stands in the grouped search's order (module docstring): the lowest key is searched next."""
    if group.settling_in_progress is not None:
        return (0, 0, -1.0, group.objects[0])  # the settling the last deadline interrupted
    if group.refinement_due:
        return (0, 1, float(len(group.objects)), group.objects[0])
    next_probability = group.next_probability
    assert next_probability is not None
    return (
        1,
        0 if group.best_valid is None else 1,
        -next_probability / group.bound.root_probability,
        group.objects[0],
    )


class GroupedSearch(Generic[G, R]):
    """Interaction groups under one deadline, each searched by a core ``build`` makes (module docstring);
    anytime and resumable like :class:`~physics_mapper.search.best_first.BestFirst`.

    Build one with :func:`~physics_mapper.search.strategy.make_search`; with ``previous`` (a grouped search
    of the same composition), the groups still valid are carried over (:meth:`following`).
    """

    def __init__(
        self,
        checker: PhysicsChecker,
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        build: GroupBuilder[G, R],
        carry_over: CarryOver[G, R],
        previous: GroupedSearch[G, R] | None = None,
    ) -> None:
        self.checker = checker
        self.hypotheses = tuple(hypotheses)
        self.params = params
        self.build = build
        self.carry_over = carry_over
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
        self.grounds = Grounds(checker.scene, hypotheses, params)
        self._next_id: int = 0 if previous is None else previous.next_group_id
        self._groups: dict[int, BestFirst[G, R]] = {}
        self._links: dict[int, GroupLink] = {}
        self._memos: dict[int, SettleMemo] = {}
        self._kept: set[int] = set()
        self._trace = Trace(params.trace_limit)
        self._merges = 0
        self._search_time = 0.0
        self._stopped_at_deadline = False
        self._schedule: list[tuple[ScheduleKey, int]] = []
        self._keys: dict[int, ScheduleKey] = {}
        carried = previous is not None and carry_over.holds(previous.params, params)
        #: Objects whose hypotheses changed since ``previous`` (what their groups learned is stale).
        self._changed = {i for i, same in enumerate(unchanged) if not same} if carried else set()
        earlier: list[BestFirst[G, R]] = [] if previous is None or not carried else previous.groups()
        by_objects = {} if previous is None else {group.objects: group_id for group_id, group in previous.items()}
        for objects in self.grouping.groups:
            old_id = by_objects.get(objects)
            same = old_id is not None and all(unchanged[i] for i in objects)
            if previous is not None and old_id is not None and same:
                if continuable(previous._groups[old_id].params, params):
                    self._adopt(previous, old_id)
                else:
                    self._add_group(objects, previous._memos[old_id], earlier)
            else:
                self._add_group(objects, None, earlier)
        if previous is not None:
            kept = {self._groups[group_id].trace_group for group_id in self._kept}
            self._trace.entries = [entry for entry in previous.trace if entry.group in kept]
        self._share_limits()

    @classmethod
    def following(
        cls,
        checker: PhysicsChecker,
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        build: GroupBuilder[G, R],
        carry_over: CarryOver[G, R],
        previous: GroupedSearch[G, R] | None,
    ) -> GroupedSearch[G, R]:
        """A search for ``hypotheses``: ``previous`` (of the same composition) itself, resumed, if nothing but
        the deadline or the fallback changed; else a new one that keeps every group of ``previous`` still valid."""
        hypotheses = tuple(hypotheses)
        if previous is None:
            return cls(checker, hypotheses, params, build, carry_over)
        if resumable(previous, checker, hypotheses, params):
            previous.params = params
            for group_id, group in previous.items():
                group.params = params
                previous._kept.add(group_id)
            return previous
        return cls(checker, hypotheses, params, build, carry_over, previous)

    # --- groups -----------------------------------------------------------------------------------

    def _add_group(self, objects: tuple[int, ...], memo: SettleMemo | None, earlier: Sequence[BestFirst[G, R]]) -> None:
        """A new group search of ``objects``, scheduled, keeping what the ``earlier`` groups it overlaps learned."""
        hypotheses = tuple(self.hypotheses[i] for i in objects)
        if memo is None or not memo.serves(hypotheses, physics_key(self.params)):
            memo = SettleMemo(hypotheses, physics_key(self.params), SETTLE_MEMO_LIMIT)
        group_id = self._next_id
        self._next_id += 1
        link = GroupLink(self.table, self.grouping, self.grounds, self._trace)
        # Trace entries name the group unless it holds every object (then its codes are whole codes).
        trace_group = None if objects == self.checker.all_objects else group_id
        spec = GroupSpec(
            self.checker, self.hypotheses, self.params, objects, trace_group, link, memo,
            EscapeGuard(self.checker, objects, link),
        )  # fmt: skip
        group = self._groups[group_id] = self.build(spec)
        self._links[group_id] = link
        self._memos[group_id] = memo
        self._reschedule(group_id)
        for old in earlier:
            if set(old.objects) & set(objects):
                self.carry_over.carry(old, group, self._changed)

    def _adopt(self, previous: GroupedSearch[G, R], group_id: int) -> None:
        """Take over a previous search's group, progress and all."""
        group = previous._groups[group_id]
        link = previous._links[group_id]
        link.table, link.grouping, link.grounds, link.trace = self.table, self.grouping, self.grounds, self._trace
        group.params = self.params
        self._groups[group_id] = group
        self._links[group_id] = link
        self._memos[group_id] = previous._memos[group_id]
        self._kept.add(group_id)
        self._reschedule(group_id)

    def _share_limits(self) -> None:
        """Give each group a share of the queue and memo limits in proportion to its objects: a group of one
        object never holds more than its ranks, one of 26 meshes needs thousands of nodes."""
        count = sum(len(group.objects) for group in self._groups.values())
        for group_id, group in self._groups.items():
            group.candidates.queue_limit = max(1, self.params.queue_limit * len(group.objects) // count)
            self._memos[group_id].limit = max(1, SETTLE_MEMO_LIMIT * len(group.objects) // count)

    def _merge(self, escaped_id: int, positions: tuple[int, ...]) -> None:
        """The escape guard's answer: replace the group ``escaped_id`` and the groups at ``positions`` by one,
        searched anew, keeping what they learned."""
        escaped = self._groups[escaped_id]
        merged = [escaped, *(g for g in self.groups() if self.grouping.group_of(g.objects[0]) in positions)]
        objects = tuple(sorted(i for group in merged for i in group.objects))
        gone = {group_id for group_id, group in self._groups.items() if any(group is m for m in merged)}
        gone_groups = {self._groups[group_id].trace_group for group_id in gone}
        for group_id in gone:
            del self._groups[group_id], self._links[group_id], self._memos[group_id]
            self._keys.pop(group_id, None)
            self._kept.discard(group_id)
        self._trace.entries = [entry for entry in self._trace.entries if entry.group not in gone_groups]
        self.links.append(frozenset(objects))
        self.grouping = self.grouping.joined(objects)
        for link in self._links.values():
            link.grouping = self.grouping
        self._merges += 1
        self._add_group(objects, None, merged)
        self._share_limits()

    # --- scheduling (module docstring) ----------------------------------------------------------------

    def _reschedule(self, group_id: int) -> None:
        group = self._groups[group_id]
        if group.done:
            self._keys.pop(group_id, None)
            return
        key = schedule_key(group)
        self._keys[group_id] = key
        heapq.heappush(self._schedule, (key, group_id))

    def _next_group(self) -> int | None:
        """The id of the group whose candidate comes next, taken off the schedule (None: every group is done)."""
        while self._schedule:
            key, group_id = heapq.heappop(self._schedule)
            if self._keys.get(group_id) == key:
                del self._keys[group_id]
                return group_id
        return None

    # --- searching ------------------------------------------------------------------------------------

    @property
    def queued(self) -> int:
        """Candidates in the groups' generators (at most ``queue_limit`` in all)."""
        return sum(group.queued for group in self._groups.values())

    @property
    def done(self) -> bool:
        """True once no group has a candidate left."""
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
        return None if group is None else group.settling_group

    @property
    def settling_objects(self) -> tuple[int, ...]:
        """The objects (scene indices) of the group whose settling the deadline interrupted (none: no group's)."""
        group = self._interrupted_group()
        return () if group is None else group.objects

    @property
    def refined_map(self) -> Candidate | None:
        """Every group's refined map as one map over every object, once each group has made its own."""
        groups = self.groups()
        maps = [group.refined_map for group in groups]
        if any(refined is None for refined in maps):
            return None
        return self._joined(groups, [refined for refined in maps if refined is not None])

    def _joined(self, groups: Sequence[BestFirst[G, R]], candidates: Sequence[Candidate]) -> Candidate:
        """One candidate per group (``groups``' order) as one over every object: codes, settled poses and
        jitters in object order, p(C) their product."""
        count = len(self.hypotheses)
        code, jitters = [0] * count, [0.0] * count
        settled: list[Pose] = [self.hypotheses[0].pose(1)] * count
        for group, candidate in zip(groups, candidates, strict=True):
            for position, index in enumerate(group.objects):
                code[index] = candidate.code[position]
                settled[index] = candidate.settling.settled_poses[position]
                jitters[index] = candidate.settling.jitters[position]
        probability = math.prod(candidate.probability for candidate in candidates)
        return Candidate(tuple(code), probability, Settling(tuple(settled), tuple(jitters)))

    def _interrupted_group(self) -> BestFirst[G, R] | None:
        return next((g for g in self._groups.values() if g.settling_in_progress is not None), None)

    def run(self, budget: float | None = None) -> SearchResult:
        """Search every group for at most ``budget`` wall-clock seconds in all (None: until no candidate is left)."""
        start = time.monotonic()
        stop_at = None if budget is None else start + budget
        self._stopped_at_deadline = False
        try:
            while (group_id := self._next_group()) is not None:
                if stop_at is not None and time.monotonic() >= stop_at:
                    self._reschedule(group_id)
                    self._stopped_at_deadline = True
                    break
                try:
                    finished = self._groups[group_id].step(stop_at)
                except Escape as escape:
                    self._merge(group_id, escape.groups)
                    continue
                self._reschedule(group_id)
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
        return tuple(self._trace.entries)

    def items(self) -> list[tuple[int, BestFirst[G, R]]]:
        """The current groups with their ids, in order of their first object."""
        return sorted(self._groups.items(), key=lambda item: item[1].objects[0])

    def groups(self) -> list[BestFirst[G, R]]:
        """The current groups' searches, in order of their first object."""
        return [group for _, group in self.items()]

    def stats(self) -> SearchStats:
        """Every group's counters added up, with the grouped search's time and how it ended."""
        stats = SearchStats()
        groups = self.groups()
        group_stats = [group.stats for group in groups]
        for each in group_stats:
            stats.add(each)
        stats.search_time = self._search_time
        stats.stopped_at_deadline = self._stopped_at_deadline
        stats.untraced = self._trace.untraced
        stats.merges = self._merges
        stats.end = _combined_end([each.end for each in group_stats])
        return stats

    def result(self) -> SearchResult:
        """Every group's best so far combined: valid iff every group's is, J their sum, p(C) their product."""
        items = self.items()
        groups = [group for _, group in items]
        choices = [group.chosen() for group in groups]
        group_results = tuple(
            group.group_result(group.trace_group, group_id in self._kept) for group_id, group in items
        )
        stats, trace = self.stats(), self.trace
        chosen = [candidate for candidate, _ in choices if candidate is not None]
        if len(chosen) < len(groups):
            return SearchResult(False, None, None, None, None, None, None, False, stats, trace, groups=group_results)
        joined = self._joined(groups, chosen)
        code, settled, jitters = joined.code, joined.settling.settled_poses, joined.settling.jitters
        valid = all(is_valid for _, is_valid in choices)
        fallback = None if valid else self.params.fallback
        refined = [group.refined for group, (_, is_valid) in zip(groups, choices, strict=True) if not is_valid]
        refinement = combined_refinement([r for r in refined if r is not None]) if fallback == "refine" else None
        return SearchResult(
            valid=valid,
            code=code,
            probability=joined.probability,
            jitter=sum(jitters),
            poses=tuple(ranked.pose(rank) for ranked, rank in zip(self.hypotheses, code, strict=True)),
            settled_poses=settled,
            object_jitters=jitters,
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
        settled=all(r.settled for r in refined),
    )


def _combined_end(ends: Sequence[SearchEnd | None]) -> SearchEnd | None:
    """How a grouped search ended: None while any group has nodes queued, else the weakest claim."""
    if any(end is None for end in ends):
        return None
    for end in ("truncated", "bounded"):
        if end in ends:
            return end
    return "exhausted"

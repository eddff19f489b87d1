"""A conflict-directed best-first search in each interaction group (``strategy: conflict``, the default).

The idea of conflict-directed A* (Williams & Ragno 2007) on the paper's Algorithm 1. Every rejection
teaches a *conflict* K, a few (object, rank) assignments no valid configuration holds together
(:mod:`physics_mapper.search.conflicts`); ranks Rule 1 rules out alone are learned before the first
candidate (:mod:`physics_mapper.search.ruling_out`). The next candidate is the most probable
configuration that holds no known conflict, generated directly
(:mod:`physics_mapper.search.conflict_free`): candidates come in the paper's order, decreasing p(C)
with its tie rule, and none that holds a known conflict is ever made (the paper's queue, skipping
such candidates one by one, made a number of them that grew combinatorially with the objects). A
candidate is checked only if one of its *parents* (one rank lower on one object) is above the bound,
or it has none: in the paper's search a node is queued iff some parent is visited and not bounded, and
a parent's p(C) is at least its child's. A candidate's parent in the trace is the first of its parents
visited above the bound (none when every one holds a conflict).

Rule 2 of a candidate is first *tried*, locally where the stable contexts allow
(:mod:`~physics_mapper.search.local_settling`), with Bullet's solver at :data:`TRIAL_SOLVER_ITERATIONS`; a
trial's instability is believed, and a candidate is valid only once Rule 2's own settling of its
whole group (50 iterations) confirms it.

Why the answer is the paper's. No valid configuration holds a conflict (conflicts are sound), so a
valid configuration is generated, in the paper's order, exactly when it has a parent above the bound
or none: exactly when the paper's search checks it (the bound's reference, the first valid p(C), is
then the same too). Both searches so check the same valid configurations in the same order; the least
J among them, the first of equal ones, is the same answer. The same argument with collision conflicts
only gives the ``settled`` fallback's configuration, the first collision-free one. The search ends
``exhausted`` when the bound kept no configuration out (every one was visited or holds a conflict),
else ``bounded``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from operator import getitem

import numpy as np

from physics_mapper.model.extents import stable_growth
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import SearchParams, object_radius
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision import Collision, deepest_collision
from physics_mapper.physics.settling import EarlyExit, PartialSettling, Settling, early_exit_rule
from physics_mapper.search.branch_and_bound import BranchAndBound, QueueItem, tie_key
from physics_mapper.search.conflict_free import ConflictFreeCandidates
from physics_mapper.search.conflicts import Blame, Conflict, ConflictStore, collision_conflicts
from physics_mapper.search.grouped import GroupedSearch, GroupSearch, SettleMemo, physics_key
from physics_mapper.search.local_settling import LocalPlan, LocalSettling
from physics_mapper.search.results import Candidate, Code, RuledOut, TraceEntry
from physics_mapper.search.ruling_out import FreeFall, Ruling, RulingOut

#: Bullet solver iterations of a trial settling (Rule 2's are 50, ``world.SOLVER_ITERATIONS``): its
#: instability is believed, its stability confirmed by a settling with Rule 2's solver. Walls, towers
#: and bins of 50 step 1.9 to 2.6 times faster; the 866 configurations the crowded suite's searches
#: found unstable or valid, settled in full with 50, 15 and 10 iterations, were stable alike.
TRIAL_SOLVER_ITERATIONS = 15
#: Objects a group needs before a candidate with no context known is tried as a whole: a small group's
#: first candidate is often valid (the scale suite's separate piles: the median search took 1.3 times
#: longer with whole-group trials in every group), and a valid trial costs one settling more.
WHOLE_TRIALS_FROM_OBJECTS = 7


class ConflictGroupSearch(GroupSearch):
    """One interaction group searched conflict-directed (module docstring); its conflicts in :attr:`conflicts`."""

    def __init__(self, owner: GroupedSearch, group_id: int, objects: tuple[int, ...], memo: SettleMemo) -> None:
        # Per object, its weights by rank (index 0 unused): p(C) is queried for every child and parent.
        self._weights = tuple((0.0, *(h.weight for h in owner.hypotheses[i].hypotheses)) for i in objects)
        super().__init__(owner, group_id, objects, memo)
        scene = self.checker.scene
        self.names = tuple(scene.objects[i].name for i in self.objects)
        self._object_positions = {index: position for position, index in enumerate(self.objects)}
        self.conflicts = ConflictStore([len(h) for h in self.hypotheses])
        self.blame = Blame([scene.objects[i].shape for i in self.objects], self.hypotheses, self.params)
        self.local = LocalSettling(self.blame)
        self._trial: tuple[Code, LocalPlan] | None = None  # the trial settling under way
        self._depths: dict[tuple[int, int], float] = {}  # the last Rule 1 check's overlaps, by body pair
        half_margin = self.params.interaction_margin / 2.0  # the grouping's boxes are grown by it
        grouping = owner.grouping
        rulings = RulingOut(
            self.objects,
            [grouping.lows[i] + half_margin for i in self.objects],
            [grouping.highs[i] - half_margin for i in self.objects],
            owner.table,
            self.params.penetration_threshold,
            self.conflicts,
        ).run(scene.static)
        growths = [
            stable_growth(object_radius(o.shape), self.params.jitter_threshold, self.params.angular_weight)
            for o in scene.objects
        ]
        rulings += FreeFall(
            self.objects,
            [
                (low + half_margin - growth, high - half_margin + growth)
                for low, high, growth in zip(grouping.lows, grouping.highs, growths, strict=True)
            ],
            growths,
            [np.array([not h.absent for h in ranked.hypotheses]) for ranked in owner.hypotheses],
            self.params.settle_time,
            self.conflicts,
        ).run(scene.static)
        self.ruled_out = tuple(self._ruled_out(r) for r in rulings)
        self.stats.conflicts += len(rulings)
        self.stats.ruled_out += len(rulings)
        self.drop_head()  # the paper's queue holds the root: the generator makes the candidates here
        self.candidates = ConflictFreeCandidates(
            [weights[1:] for weights in self._weights], self.conflicts, self.is_bounded, self.queue_limit
        )
        self._waiting: QueueItem | None = None  # the candidate whose settling the deadline interrupted
        self._expanded_codes: set[Code] = set()  # visited nodes above the bound (parents in the trace)

    def _ruled_out(self, ruling: Ruling) -> RuledOut:
        """Why a rank was ruled out, by object names."""
        name = self.names[ruling.position]
        if ruling.floating:
            return RuledOut(name, ruling.rank, "", 0.0, group=self.trace_group, reason="floating")
        other = self.checker.body_name(ruling.other)
        return RuledOut(name, ruling.rank, other, ruling.depth, ruling.every_rank, self.trace_group)

    def step(self, stop_at: float | None) -> bool:
        """Make the due refined map, or else check the next candidate (the one the deadline interrupted
        first); False if the deadline ``stop_at`` came first (finding the candidate, or settling it)."""
        if self.refinement_due:
            return self._refine(stop_at)
        self.candidates.queue_limit = self.queue_limit  # the grouped search shares it out after making groups
        if self._waiting is None and not self.candidates.find(stop_at):
            return False
        item = self._waiting or self._take()
        self._waiting = None
        if item is not None and self.visit(item, stop_at) is None:
            self._waiting = item
            return False
        self.update_end()
        return True

    def _take(self) -> QueueItem | None:
        """The next candidate off the generator, with the first of its parents visited above the bound."""
        found = self.candidates.take()
        if found is None:
            return None
        code, probability = found
        parent = next(
            (
                parent
                for position, rank in enumerate(code)
                if rank > 1 and (parent := (*code[:position], rank - 1, *code[position + 1 :])) in self._expanded_codes
            ),
            None,
        )
        return QueueItem(-tie_key(probability), code, probability, parent)

    @property
    def queued(self) -> int:
        """Prefixes the generator holds, and a candidate whose settling the deadline interrupted."""
        return len(self.candidates) + (self._waiting is not None)

    @property
    def done(self) -> bool:
        """True once no candidate is left (and a due refined map is made); how the search ended is then said
        (a group whose every configuration holds a conflict from the start is done before any step)."""
        if self._waiting is not None or not self.candidates.exhausted or self.refinement_due:
            return False
        self.update_end()
        return True

    @property
    def next_probability(self) -> float | None:
        """p(C) of the candidate checked next, or an upper bound while it is not found (None: none is left)."""
        if self._waiting is not None:
            return self._waiting.probability
        return self.candidates.next_probability

    @property
    def root_rejected(self) -> bool:
        """Whether the root was checked and rejected, or holds a known conflict (the generator never makes it)."""
        return self.stats.visited > 0 or self.conflicts.contained(self._root) is not None

    def update_end(self) -> None:
        """Say how the search ended once no candidate is left: ``truncated`` when the queue limit dropped
        prefixes, ``bounded`` when the bound kept configurations out, else ``exhausted``."""
        self.stats.dropped = self.candidates.dropped
        if self._waiting is not None or not self.candidates.exhausted:
            self.stats.end = None
        elif self.candidates.dropped:
            self.stats.end = "truncated"
        else:
            self.stats.end = "bounded" if self.candidates.cut else "exhausted"

    def visit(self, item: QueueItem, stop_at: float | None) -> TraceEntry | None:
        """Check a candidate that resolves every known conflict (:meth:`step` skipped the others), learn
        from a rejection, and expand by the conflict learned (None: the deadline cut a settling short)."""
        code, probability = item.code, item.probability
        bounded = self.is_bounded(probability)
        check = self.check(code, stop_at)
        if isinstance(check, PartialSettling):
            self.interrupt(code, check)
            return None
        conflict: Conflict | None
        if isinstance(check, Collision):
            entry = TraceEntry(code, probability, "collision", bounded, pair=check.pair, depth=check.depth)
            conflict = self._learn_collisions(code)
        else:
            settling = self._verdict(code, check, stop_at)
            if isinstance(settling, PartialSettling):
                self.interrupt(code, settling)
                return None
            entry = self.judge(Candidate(code, probability, settling), bounded)
            conflict = None if entry.outcome == "valid" else self._learn(self.blame.conflicts(code, settling))
        named = None if conflict is None else self.named(conflict)
        entry = replace(entry, parent=item.parent, group=self.trace_group, conflict=named)
        self.record(entry)
        self._expanded(code, bounded)
        return entry

    def rule1(self, code: Code, poses: tuple[Pose, ...]) -> Collision | None:
        """Rule 1 from the table, its overlaps kept for :meth:`_learn_collisions`."""
        assert self.collisions is not None  # a group search always has its table
        self._depths = self.collisions.depths(self.objects, code)
        return deepest_collision(self._depths, self.params.penetration_threshold, self.checker.body_name)

    def _learn_collisions(self, code: Code) -> Conflict:
        """Learn a conflict from every overlap beyond the threshold of the candidate Rule 1 just rejected;
        the smallest one, to expand by."""
        assert self.collisions is not None
        threshold = self.params.penetration_threshold
        depths = self._depths
        return self._learn(
            [
                conflict
                for pair, depth in sorted(depths.items())
                if depth > threshold
                for conflict in collision_conflicts(
                    code, pair, self._object_positions, self.collisions, self.conflicts, threshold
                )
            ]
        )

    def _learn(self, learned: list[Conflict]) -> Conflict:
        """Remember every conflict of ``learned``; the smallest, to expand by."""
        for conflict in learned:
            self.stats.conflicts += self.conflicts.learn(conflict)
        return min(learned, key=lambda conflict: len(conflict.assignments))

    def _verdict(self, code: Code, settling: Settling, stop_at: float | None) -> Settling | PartialSettling:
        """Rule 2's settling of ``code`` for the judge: a trial that shows an instability, else Rule 2's own
        (a trial that shows none is confirmed by a full settling with Rule 2's solver first), contexts
        recorded."""
        trial, self._trial = self._trial, None
        if trial is not None and trial[0] == code:
            plan = trial[1]
            self.local.observe(code, plan.simulated, settling.jitters)
            whole = self.local.whole(plan, settling, code)
            if not whole.is_stable(self.params.jitter_threshold):
                self._forget_moved(code, whole)
                return whole
            confirmed = super().settle_node(code, self.poses(code), stop_at)
            if isinstance(confirmed, PartialSettling):
                return confirmed
            settling = confirmed
        self.local.observe(code, range(len(self.objects)), settling.jitters)
        self._forget_moved(code, settling)
        return settling

    def _forget_moved(self, code: Code, settling: Settling) -> None:
        """Drop the stable contexts of the objects a settling of the whole group moved beyond the threshold."""
        threshold = self.params.jitter_threshold
        self.local.forget(code, [p for p, jitter in enumerate(settling.jitters) if jitter > threshold])

    def settle_node(self, code: Code, poses: tuple[Pose, ...], stop_at: float | None) -> Settling | PartialSettling:
        """Rule 2 of one node, tried first (:data:`TRIAL_SOLVER_ITERATIONS`) locally where the contexts
        allow (:mod:`~physics_mapper.search.local_settling`), else of the whole group (from
        :data:`WHOLE_TRIALS_FROM_OBJECTS` objects; a group holding a mesh with Rule 2's solver); with Rule
        2's own settling at once otherwise, for a node every context presumes valid and for the node a
        fallback may report."""
        plan = None if self.settling_completely else self.local.plan(code)
        whole = plan is not None and len(plan.simulated) == len(code)
        # A whole group holding a mesh is tried with Rule 2's solver: the trial would be Rule 2's settling.
        if plan is None or (whole and (len(code) < WHOLE_TRIALS_FROM_OBJECTS or self.local.holds_meshes)):
            return super().settle_node(code, poses, stop_at)
        memoised = self.memoised(code)
        if memoised is not None:
            return memoised
        self._trial = (code, plan)
        params = self.params
        outcome = self.checker.settle(
            [poses[p] for p in plan.simulated],
            params.settle_time,
            params.angular_weight,
            stop_at,
            objects=[self.objects[p] for p in plan.simulated],
            fixed=[(self.objects[p], poses[p]) for p in plan.fixed],
            early_exit=self.early_exit(),
            track_reach=True,
            # Meshes change verdicts at fewer iterations (7 of 377 at 15 on the shipped mesh scenes).
            solver_iterations=None if self.local.holds_meshes else TRIAL_SOLVER_ITERATIONS,
        )
        if isinstance(outcome, Settling):
            self.on_settled(code, outcome)
        return outcome

    def early_exit(self) -> EarlyExit | None:
        """As the paper's search's, and a settling not reported by a fallback also stops once an object
        is far off and still moving (``moving``)."""
        return early_exit_rule(self.params, complete=self.settling_completely, moving=True)

    def on_settled(self, code: Code, settling: Settling) -> None:
        """Count the settling; a trial is guarded as a settling of the whole group and kept out of the memo
        (which holds Rule 2's own settlings)."""
        trial = self._trial
        if trial is None or trial[0] != code:
            self.stats.full_settlings += 1
            super().on_settled(code, settling)
            return
        if len(settling.jitters) == len(self.objects):
            self.stats.full_settlings += 1
        else:
            self.stats.local_settlings += 1
        BranchAndBound.on_settled(self, code, settling)  # the step counters only
        self.guard(code, self.local.whole(trial[1], settling, code))

    def keep_from(self, old: ConflictGroupSearch, changed: set[int]) -> None:
        """Take over what ``old`` (a group of the previous search, same physics parameters) learned that
        still holds: its conflicts and stable contexts among objects of this group whose hypotheses did
        not change (``changed``: scene indices). An instability's conflict also needs every object
        that is new here, or changed, unable to reach the swept box it was learned from. A rank ruled out
        alone by Rule 1 is not taken over: the ruling-out pass, made anew for this group, learns it again
        where it still holds. It may have been ruled out by a neighbour at every rank of that neighbour
        (one assignment, yet it holds only while the neighbour's hypotheses do): kept after they change,
        it would rule out a pose that is now free, and an object with all its ranks so ruled out leaves
        the search nothing to visit."""
        moved = {p: self._object_positions[i] for p, i in enumerate(old.objects) if i in self._object_positions}
        stale = {p for p, i in enumerate(old.objects) if i in changed}
        newcomers = [self._object_positions[i] for i in self.objects if i in changed or i not in old.objects]
        for conflict in old.conflicts:
            if any(p in stale or p not in moved for p in conflict.positions) or _ruled_out_alone(conflict):
                continue
            region = conflict.region
            if region is not None and any(self.blame.reaches(p, region) for p in newcomers):
                continue
            self.stats.conflicts_kept += self.conflicts.learn(conflict.renumbered(moved))
        self.local.kept_from(old.local, moved, stale)

    def probability(self, code: Code) -> float:
        """p(C), multiplied in the same order as :meth:`BranchAndBound.probability` (the same number)."""
        return math.prod(map(getitem, self._weights, code))

    def named(self, conflict: Conflict) -> tuple[tuple[str, int], ...]:
        """A conflict's assignments as (object name, rank)."""
        return tuple((self.names[position], rank) for position, rank in conflict.assignments)

    def _expanded(self, code: Code, bounded: bool) -> None:
        """Count a visited node above the bound as expanded, and keep it as a parent for the trace (as many
        as the trace keeps entries)."""
        if bounded:
            return
        self.stats.expanded += 1
        limit = self.params.trace_limit
        if limit is None or len(self._expanded_codes) < limit:
            self._expanded_codes.add(code)


class ConflictSearch(GroupedSearch):
    """Interaction groups under one deadline (:class:`GroupedSearch`), each searched conflict-directed.

    A group searched anew because some of its objects got new hypotheses keeps what the previous
    search's groups learned about the others (:meth:`ConflictGroupSearch.keep_from`); so does a group
    the escape guard merged, of the groups it replaces.
    """

    group_search = ConflictGroupSearch

    def __init__(
        self,
        checker: PhysicsChecker,
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        previous: GroupedSearch | None = None,
    ) -> None:
        # Read by add_group while the groups are made, then dropped.
        self._earlier: list[ConflictGroupSearch] = []
        self._changed: set[int] = set()
        if previous is not None and previous.checker is checker and _same_rules(previous.params, params):
            self._earlier = [g for g in previous.groups() if isinstance(g, ConflictGroupSearch)]
            pairs = zip(previous.hypotheses, hypotheses, strict=True)
            self._changed = {i for i, (old, new) in enumerate(pairs) if old != new}
        super().__init__(checker, hypotheses, params, previous)
        self._earlier = []

    def merge_groups(self, escaped: GroupSearch, positions: tuple[int, ...]) -> None:
        """The escape guard's merge, the merged group keeping what the groups it replaces learned."""
        merged = [escaped, *(g for g in self.groups() if self.grouping.group_of(g.objects[0]) in positions)]
        self._earlier = [g for g in merged if isinstance(g, ConflictGroupSearch)]
        try:
            super().merge_groups(escaped, positions)
        finally:
            self._earlier = []

    def add_group(self, objects: tuple[int, ...], memo: SettleMemo | None) -> GroupSearch:
        group = super().add_group(objects, memo)
        assert isinstance(group, ConflictGroupSearch)
        for old in self._earlier:
            if set(old.objects) & set(objects):
                group.keep_from(old, self._changed)
        return group


def _ruled_out_alone(conflict: Conflict) -> bool:
    """Whether ``conflict`` rules out one rank of one object by Rule 1 (:mod:`physics_mapper.search.ruling_out`)."""
    return len(conflict.assignments) == 1 and conflict.kind == "collision"


def _same_rules(a: SearchParams, b: SearchParams) -> bool:
    """Whether conflicts learned under ``a`` hold under ``b``: the same thresholds and settling."""
    return physics_key(a) == physics_key(b) and a.penetration_threshold == b.penetration_threshold

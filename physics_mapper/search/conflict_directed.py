"""The conflict-directed candidate generator of an interaction group (``strategy: conflict``, the default).

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
(:mod:`~physics_mapper.search.trial_settling`); a trial's instability is believed, and a candidate is
valid only once Rule 2's own settling of its whole group (50 iterations) confirms it.

Searched again. The blame rule's one assumption fails where a push passes through an object that
barely moves (:mod:`physics_mapper.search.conflicts`): a conflict may then rule out a valid
configuration. So a group whose candidates run out with none valid, after the blame rule taught
conflicts of several objects, forgets those (it keeps the collisions' and the ones of one object),
learns again from the same settlings by the chain rule (each candidate visited contains the conflict its
own settling teaches, so none is made again; the first :data:`KEPT_INSTABILITIES` are kept), and
generates the candidates again from the first, learning from instabilities by the chain rule
(``searched_again`` counts it). Its end is then the second search's.

Why the answer is the paper's. No valid configuration holds a conflict (conflicts are sound, the chain
rule's where the contact rule's misled), so a
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
from collections.abc import Callable, Mapping, Sequence

from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.physics.settling import Settling
from physics_mapper.search.best_first import (
    BestFirst,
    Bound,
    NamedConflict,
    QueueItem,
    Rule1Verdict,
    parents,
    tie_key,
    weight_table,
)
from physics_mapper.search.conflict_free import ConflictFreeCandidates
from physics_mapper.search.conflicts import Blame, Conflict, ConflictStore, collision_conflicts
from physics_mapper.search.groups import Grouping
from physics_mapper.search.results import Code, Counters, RuledOut, SearchEnd, SearchStats
from physics_mapper.search.rule2 import physics_key
from physics_mapper.search.ruling_out import FreeFall, Ground, Ruling, RulingOut
from physics_mapper.search.trial_settling import TrialSettling

#: Instabilities a group keeps, until it finds a valid configuration, to teach again by the chain rule if it
#: is searched again (the candidates of any beyond are visited again then): a bound on a long search's memory.
KEPT_INSTABILITIES = 500


class ConflictDirectedCandidates:
    """The candidates of one interaction group, generated conflict-free, learning a conflict from each
    rejection (module docstring); its conflicts in :attr:`conflicts`.

    ``objects``: the group's scene indices; ``hypotheses``: every object's of the scene; ``grouping``: the
    interaction groups the group is one of (its volumes bound the Rule 1 pass); ``table()``: the pairwise
    Rule 1 table (asked at each use: a grouped search that adopts the group hands it its own); ``ground()``:
    the scene's :class:`~physics_mapper.search.ruling_out.Ground` for the free-fall pass (made once for
    every group of the grouping); ``blame``: the group's blame rule for
    instabilities. Counts the ``conflicts`` learned (``conflicts_kept``: carried over), the ranks
    ``ruled_out`` before the first candidate, and the regions of configurations the queue limit ``dropped``.
    """

    def __init__(
        self,
        checker: PhysicsChecker,
        objects: Sequence[int],
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        grouping: Grouping,
        table: Callable[[], CollisionTable],
        ground: Callable[[], Ground],
        blame: Blame,
        bound: Bound,
        trace_group: int | None,
    ) -> None:
        self.objects = tuple(objects)
        self.params = params
        self.table = table
        self.blame = blame
        self.trace_group = trace_group
        self._body_name = checker.body_name
        group_hypotheses = tuple(hypotheses[i] for i in self.objects)
        scene = checker.scene
        self.names = tuple(scene.objects[i].name for i in self.objects)
        self._positions = {index: position for position, index in enumerate(self.objects)}
        self.conflicts = ConflictStore([len(h) for h in group_hypotheses])
        self.conflicts_learned = 0
        self.conflicts_kept = 0
        half_margin = params.interaction_margin / 2.0  # the grouping's boxes are grown by it
        rulings = RulingOut(
            self.objects,
            [grouping.lows[i] + half_margin for i in self.objects],
            [grouping.highs[i] - half_margin for i in self.objects],
            table(),
            params.penetration_threshold,
            self.conflicts,
        ).run(scene.static)
        rulings += FreeFall(self.objects, ground(), self.conflicts).run()
        self._ruled_out = tuple(self._named_ruling(r) for r in rulings)
        self.conflicts_learned += len(rulings)
        self._root: Code = tuple(1 for _ in self.objects)
        self.candidates = ConflictFreeCandidates(
            [weights[1:] for weights in weight_table(group_hypotheses)], self.conflicts, bound, params.queue_limit
        )
        self._valid_found = False
        self._unstable: list[tuple[Code, Settling]] = []  # the instabilities the blame rule learned from
        self.searched_again = 0  # times the group was searched again under the chain rule
        self._waiting: QueueItem | None = None  # the candidate whose settling the deadline interrupted
        self._expanded: set[Code] = set()  # visited candidates above the bound (parents in the trace)

    def _named_ruling(self, ruling: Ruling) -> RuledOut:
        """Why a rank was ruled out, by object names."""
        name = self.names[ruling.position]
        if ruling.floating:
            return RuledOut(name, ruling.rank, "", 0.0, group=self.trace_group, reason="floating")
        other = self._body_name(ruling.other)
        return RuledOut(name, ruling.rank, other, ruling.depth, ruling.every_rank, self.trace_group)

    @property
    def queue_limit(self) -> int:
        return self.candidates.queue_limit

    @queue_limit.setter
    def queue_limit(self, limit: int) -> None:
        self.candidates.queue_limit = limit

    def ready(self, stop_at: float | None) -> bool:
        """Whether the next candidate is found (the one the deadline interrupted first); False if the
        deadline ``stop_at`` came first."""
        if self._waiting is not None:
            return True
        found = self.candidates.find(stop_at)
        if found and self._searches_again:
            self._search_again()
            return self.candidates.find(stop_at)
        return found

    @property
    def _searches_again(self) -> bool:
        """Whether the candidates ran out, none valid, after the blame rule taught conflicts of several
        objects: the rule's assumption may have failed (a push passed on by an object that barely moved),
        so the group is searched again under the chain rule (module docstring)."""
        return (
            self._waiting is None
            and self.candidates.exhausted
            and not self._valid_found
            and not self.blame.chains
            and any(_blamed_several(conflict) for conflict in self.conflicts)
        )

    def _search_again(self) -> None:
        """Forget the conflicts the blame rule taught about several objects, learn again from the same
        settlings by the chain rule (so no candidate visited is made again), and generate the candidates
        from the first, learning from instabilities by the chain rule."""
        self.blame = self.blame.chained()
        weights = self.candidates.weights
        kept = ConflictStore([len(ranked) for ranked in weights])
        for conflict in self.conflicts:
            if not _blamed_several(conflict):
                kept.learn(conflict)
        for code, settling in self._unstable:
            for conflict in self.blame.conflicts(code, settling):
                kept.learn(conflict)
        self._unstable.clear()
        self.conflicts = kept
        self.candidates = ConflictFreeCandidates(weights, kept, self.candidates.is_bounded, self.candidates.queue_limit)
        self.searched_again += 1

    def take(self) -> QueueItem | None:
        """The next candidate, with the first of its parents visited above the bound."""
        if self._waiting is not None:
            item, self._waiting = self._waiting, None
            return item
        found = self.candidates.take()
        if found is None:
            return None
        code, probability = found
        parent = next((parent for parent in parents(code) if parent in self._expanded), None)
        return QueueItem(-tie_key(probability), code, probability, parent)

    def put_back(self, item: QueueItem) -> None:
        self._waiting = item

    def observe(self, code: Code, verdict: Rule1Verdict | Settling, valid: bool, bounded: bool) -> NamedConflict | None:
        """Learn from a rejection (the conflict to expand by, named for the trace), and keep a candidate
        above the bound as a parent for the trace (as many as the trace keeps entries)."""
        conflict: Conflict | None
        if isinstance(verdict, Rule1Verdict):
            depths = verdict.depths if verdict.depths is not None else self.table().depths(self.objects, code)
            conflict = self._learn_collisions(code, depths)
        else:
            self._valid_found |= valid
            conflict = None if valid else self._learn(self.blame.conflicts(code, verdict))
            self._keep_instability(code, verdict, valid)
        if not bounded:
            limit = self.params.trace_limit
            if limit is None or len(self._expanded) < limit:
                self._expanded.add(code)
        return None if conflict is None else self.named(conflict)

    def _keep_instability(self, code: Code, settling: Settling, valid: bool) -> None:
        """Keep an instability the contact rule learned from, for a search again (none once a configuration
        was valid: the group is then never searched again)."""
        if self._valid_found:
            self._unstable.clear()
        elif not valid and not self.blame.chains and len(self._unstable) < KEPT_INSTABILITIES:
            self._unstable.append((code, settling))

    def _learn_collisions(self, code: Code, depths: Mapping[tuple[int, int], float]) -> Conflict:
        """Learn a conflict from every overlap beyond the threshold of the candidate Rule 1 just rejected;
        the smallest one, to expand by."""
        threshold = self.params.penetration_threshold
        table = self.table()
        return self._learn(
            [
                conflict
                for pair, depth in sorted(depths.items())
                if depth > threshold
                for conflict in collision_conflicts(code, pair, self._positions, table, self.conflicts, threshold)
            ]
        )

    def _learn(self, learned: list[Conflict]) -> Conflict:
        """Remember every conflict of ``learned``; the smallest, to expand by."""
        for conflict in learned:
            self.conflicts_learned += self.conflicts.learn(conflict)
        return min(learned, key=lambda conflict: len(conflict.assignments))

    def named(self, conflict: Conflict) -> NamedConflict:
        """A conflict's assignments as (object name, rank)."""
        return tuple((self.names[position], rank) for position, rank in conflict.assignments)

    @property
    def exhausted(self) -> bool:
        """True once no candidate is left, nor a search again under the chain rule (a group whose every
        configuration holds a conflict from the start is so before any step)."""
        return self._waiting is None and self.candidates.exhausted and not self._searches_again

    @property
    def end(self) -> SearchEnd | None:
        """None while a candidate is left; ``truncated`` when the queue limit dropped regions, ``bounded``
        when the bound kept configurations out, else ``exhausted``."""
        if not self.exhausted:
            return None
        if self.candidates.dropped:
            return "truncated"
        return "bounded" if self.candidates.cut else "exhausted"

    @property
    def queued(self) -> int:
        """Regions the generator holds, and a candidate whose settling the deadline interrupted."""
        return len(self.candidates) + (self._waiting is not None)

    @property
    def next_probability(self) -> float | None:
        """p(C) of the candidate checked next, or an upper bound while it is not found (None: none is left)."""
        if self._waiting is not None:
            return self._waiting.probability
        if self._searches_again:  # the search again starts at the root: every object at its best rank, at most
            return math.prod(weights[0] for weights in self.candidates.weights)
        return self.candidates.next_probability

    @property
    def ruled_out(self) -> tuple[RuledOut, ...]:
        return self._ruled_out

    @property
    def live_root(self) -> Code:
        """Each object at its most probable rank no one-assignment conflict rules out (rank 1 where every
        rank is: the refinement still gives it a place)."""
        return tuple(next(iter(self.conflicts.live_ranks(p)), 1) for p in range(len(self._root)))

    def keep_from(
        self, old: ConflictDirectedCandidates, moved: dict[int, int], stale: set[int], newcomers: Sequence[int]
    ) -> None:
        """Take over the conflicts ``old`` learned that still hold (:class:`ConflictCarryOver`): ``moved``
        maps old positions to positions here, ``stale`` are old positions whose hypotheses changed,
        ``newcomers`` positions here new to ``old`` or changed."""
        for conflict in old.conflicts:
            if any(p in stale or p not in moved for p in conflict.positions) or _ruled_out_alone(conflict):
                continue
            region = conflict.region
            if region is not None and any(self.blame.reaches(p, region) for p in newcomers):
                continue
            self.conflicts_kept += self.conflicts.learn(conflict.renumbered(moved))

    def count_into(self, stats: SearchStats) -> None:
        stats.dropped += self.candidates.dropped

    def counters(self) -> Counters:
        """Its conflicts and rulings (class docstring), and the candidates ``skipped`` for a known conflict."""
        return {
            "conflicts": self.conflicts_learned,
            "conflicts_kept": self.conflicts_kept,
            # Conflict-free generation makes no candidate that holds a known conflict: the count of those a
            # queue skipped stays, at 0, where readers of the conflict-directed search's counters look for it.
            "skipped": 0,
            "ruled_out": len(self._ruled_out),
            "searched_again": self.searched_again,
        }


#: The conflict-directed search of one group, as the grouped search holds it.
ConflictGroup = BestFirst[ConflictDirectedCandidates, TrialSettling]


class ConflictCarryOver:
    """What a group searched anew keeps of the groups of the previous search (or of the groups an escape
    merged) it overlaps: their conflicts and stable contexts among objects whose hypotheses did not change.

    An instability's conflict also needs every object that is new here, or changed, unable to reach the
    swept box it was learned from. A rank ruled out alone by Rule 1 is not taken over: the ruling-out
    pass, made anew for the group, learns it again where it still holds. It may have been ruled out by a
    neighbour at every rank of that neighbour (one assignment, yet it holds only while the neighbour's
    hypotheses do): kept after they change, it would rule out a pose that is now free, and an object with
    all its ranks so ruled out leaves the search nothing to visit.
    """

    def holds(self, learned_under: SearchParams, params: SearchParams) -> bool:
        """Whether conflicts learned under ``learned_under`` hold under ``params``: the same thresholds and settling."""
        same_settling = physics_key(learned_under) == physics_key(params)
        return same_settling and learned_under.penetration_threshold == params.penetration_threshold

    def carry(self, old: ConflictGroup, new: ConflictGroup, changed: set[int]) -> None:
        """Take over what ``old`` learned that still holds into ``new`` (``changed``: scene indices whose
        hypotheses changed)."""
        positions = {index: position for position, index in enumerate(new.objects)}
        moved = {p: positions[i] for p, i in enumerate(old.objects) if i in positions}
        stale = {p for p, i in enumerate(old.objects) if i in changed}
        newcomers = [positions[i] for i in new.objects if i in changed or i not in old.objects]
        new.candidates.keep_from(old.candidates, moved, stale, newcomers)
        new.rule2.keep_from(old.rule2, moved, stale)


def _blamed_several(conflict: Conflict) -> bool:
    """Whether the blame rule taught ``conflict`` about several objects (one alone touched nothing that moved
    it: the chain rule teaches it too)."""
    return conflict.kind == "unstable" and len(conflict.assignments) > 1


def _ruled_out_alone(conflict: Conflict) -> bool:
    """Whether ``conflict`` rules out one rank of one object by Rule 1 (:mod:`physics_mapper.search.ruling_out`)."""
    return len(conflict.assignments) == 1 and conflict.kind == "collision"

"""Conflict-free candidates: the next configuration is the most probable one that holds no known conflict.

A best-first search over *regions* of configurations, in the spirit of conflict-directed A* (Williams &
Ragno 2007): a region allows each object of the group a set of ranks, A_1 x ... x A_N. Since p(C) is a
product of one weight per object and ranks are in decreasing weight, a region's most probable
configuration, its *best completion* c, puts each object at its first allowed rank; its *key* bounds the
p(C) of every configuration of the region that holds no known conflict,

    f(region) = p(c) / prod over the chosen conflicts K that c holds of cost(K),

cost(K) being the least *penalty* of K's objects, w_j(c_j) / w_j(best allowed rank outside K's ranks of
j), what moving j out of the conflict costs at least (a conflict none of whose objects can leave it
empties the region of conflict-free configurations: the region is dropped). Conflicts without a common
object each need their own move, so the chosen ones are those of highest cost that share no object
(an admissible bound: every conflict-free configuration of the region pays them).

A region taken off the queue:

- if c holds a known conflict K = {(j, R_j)}, it is split into the parts that do not contain K, one per
  object of K in K's order: the part where the first k - 1 objects are within their rank sets and the
  k-th is outside its own, A_j & R_j for j before k, A_k minus R_k (an empty part is left out). The parts
  are disjoint and together hold every configuration of the region without K; only K's objects' sets
  change, so the tree grows with the conflicts met, not with N. The smallest conflict c holds is split on,
  of equal ones the one that costs most to leave (then the first learned): its parts lose the most of the
  region's key at once (the crowded benchmark's 17 slowest problems took up 32 % fewer regions than with the
  first learned, 34 other problems 14 % fewer);
- else c is the next candidate, and the region without c is split as in Murty's k-best assignments:
  the k-th part fixes the first k - 1 objects at c's ranks and allows the k-th every allowed rank but c's.

Every configuration is in exactly one region at any time, so none is made twice and none is lost: a
best-first enumeration in decreasing p(C). Ranks ruled out alone (one-object conflicts) are taken out of
every region's sets when it is taken up. Conflicts learned while regions wait apply when a region is taken
up (its best completion and key made again, queued again if the key fell). A part is queued under the
lower of its parent's key and its best completion's p(C) (x (1 + :data:`BOUND_SLACK`)), its own key made
when it is taken up (most parts never are).

The order is the paper's: p(C) rounded to 12 significant digits, then the smaller code first. A region is
queued under its key x (1 + :data:`BOUND_SLACK`) rounded the same way (exactly p(c) rounded when c holds
no conflict), so every configuration comes after the regions holding it. When a candidate comes off the
queue, every region of the same rounded key is taken up too, and the candidates of that key are handed
out by code. p(C) is multiplied in the group's object order, as the searches multiply it, so a
candidate's key is theirs bit for bit.

The bound. The paper's search (and the conflict-directed one) checks a configuration only if one of
its *parents* (one rank lower on one object) is above the bound, a node without parents (every rank
1) always. ``is_bounded(p)`` says whether p(C) = p is below it. A candidate with no parent above the
bound is not handed out; a region none of whose configurations can have one (its key times the largest
weight ratio w(r - 1) / w(r) of any object) is dropped; either is counted in
:attr:`ConflictFreeCandidates.cut` (the search then ends ``bounded``, not ``exhausted``).
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Callable, Sequence
from operator import itemgetter
from typing import NamedTuple

from physics_mapper.search.best_first import code_probability, parents, tie_key
from physics_mapper.search.conflicts import ConflictStore
from physics_mapper.search.results import Code

#: Relative slack of a region's key over the best p(C) it holds: far more than the rounding of a product
#: of 50 weights (1e-14) and far less than the 12-digit tie key's step.
BOUND_SLACK = 1e-9
#: Regions taken off the queue between two looks at the clock (a few microseconds each).
NODES_PER_CLOCK_CHECK = 64

#: Per object, its allowed ranks as a bit set (bit r: rank r).
Ranks = tuple[int, ...]
#: A conflict's objects (group positions) with their rank sets as bit sets.
RankSets = tuple[tuple[int, int], ...]


class _Region(NamedTuple):
    """A queued region, compared as a tuple by (-key, best completion): unique (regions are disjoint).
    ``known``: the conflicts known when its key was made (-1: its key is its parent's, made when taken up),
    ``split`` the one of them its best completion holds that it is split on (bit k: the k-th learned; -1: it
    holds none); ``masked``: the conflicts known when the ranks ruled out alone were last taken out of
    ``allowed``."""

    neg_key: float
    code: Code
    allowed: Ranks
    probability: float
    known: int
    split: int
    masked: int


class _Candidate(NamedTuple):
    """A configuration found: compared by (-p(C) rounded, code), the paper's order."""

    neg_key: float
    code: Code
    probability: float


class ConflictFreeCandidates:
    """The candidates of one group in the paper's order, none holding a known conflict (module docstring).

    ``weights[p]`` are object p's hypothesis weights by rank (non-increasing); ``store`` the group's
    conflicts, which may grow between two candidates; ``is_bounded(p)`` whether p(C) = p is below the
    bound. At most ``queue_limit`` regions wait; beyond, the least promising are dropped
    (:attr:`dropped`). :attr:`taken_up` counts the regions taken off the queue (the generator's work).
    """

    def __init__(
        self,
        weights: Sequence[Sequence[float]],
        store: ConflictStore,
        is_bounded: Callable[[float], bool],
        queue_limit: int,
    ) -> None:
        self.weights = tuple(tuple(w) for w in weights)
        self._table = tuple((0.0, *w) for w in self.weights)  # by rank, for code_probability
        self.store = store
        self.is_bounded = is_bounded
        self.queue_limit = queue_limit
        #: Configurations (a candidate, or every one of a region) kept out by the bound.
        self.cut = 0
        #: Regions the queue limit threw away.
        self.dropped = 0
        self.taken_up = 0
        self._gain = max((_ratio(w, r) for w in self.weights for r in range(2, len(w) + 1)), default=0.0)
        self._ready: list[_Candidate] = []  # found, of one rounded key, by code
        self._handed_out = 0  # 1 from a candidate handed out to the next look for one
        self._rank_sets: list[RankSets] = []  # per known conflict (bit k: the k-th learned)
        self._objects: list[frozenset[int]] = []  # per known conflict, its objects' positions
        self._live_at = -1
        self._live_changed = 0  # the conflicts known when a rank was last ruled out alone
        self._live: Ranks = ()
        self._queue: list[_Region] = []
        every = tuple((1 << (len(w) + 1)) - 2 for w in self.weights)
        best = tuple(1 for _ in self.weights)
        root = self._region(_Region(-math.inf, best, every, code_probability(self._table, best), -1, -1, -1))
        if root is not None:
            self._queue.append(root)

    def __len__(self) -> int:
        """Regions waiting, and candidates found and not yet handed out."""
        return len(self._queue) + len(self._ready)

    # --- the interface ---------------------------------------------------------------------------------

    def find(self, stop_at: float | None = None) -> bool:
        """Find the next candidate (:meth:`head`); False if the wall-clock time ``stop_at`` came first (the
        search goes on where it stopped at the next call)."""
        self._ready = [c for c in self._ready if self.store.contained(c.code) is None]
        self._handed_out = 0
        taken = 0
        while not self._ready and self._queue:
            taken += 1
            if stop_at is not None and taken % NODES_PER_CLOCK_CHECK == 0 and time.monotonic() >= stop_at:
                return False
            self._find_key(heapq.heappop(self._queue))
        return True

    @property
    def exhausted(self) -> bool:
        """No candidate is left (none found and no region waiting)."""
        return not self._ready and not self._queue

    def head(self) -> tuple[Code, float] | None:
        """The next candidate (ranks in the group's order) and its p(C), once :meth:`find` found it."""
        return (self._ready[0].code, self._ready[0].probability) if self._ready else None

    @property
    def next_probability(self) -> float | None:
        """p(C) of the next candidate, or while it is not found an upper bound of it (None: none is left)."""
        if self._ready:
            return self._ready[0].probability
        return -self._queue[0].neg_key if self._queue else None

    def take(self, stop_at: float | None = None) -> tuple[Code, float] | None:
        """The next candidate and its p(C), handed out (None: none is left, or ``stop_at`` came first)."""
        if not self.find(stop_at) or not self._ready:
            return None
        found = self._ready.pop(0)
        self._handed_out = 1
        self._trim()
        return found.code, found.probability

    # --- the best-first enumeration -----------------------------------------------------------------

    def _find_key(self, region: _Region) -> None:
        """Take up ``region`` and, if its best completion is a candidate, every region of its rounded key:
        the candidates of that key, ready by code."""
        found = self._take_up(region)
        if found is None:
            return
        self._ready = [found]  # held against the queue limit while the key's regions are taken up
        while self._queue and self._queue[0].neg_key <= found.neg_key:
            also = self._take_up(heapq.heappop(self._queue))
            if also is not None:
                self._ready.append(also)
        self._ready.sort()

    def _take_up(self, region: _Region) -> _Candidate | None:
        """A region off the queue: made again under the conflicts learned since its key was made (queued
        again if its key fell), then split; its best completion returned if it is a candidate."""
        self.taken_up += 1
        if region.known != len(self.store):
            fresh = self._region(region)
            if fresh is None:
                return None
            if fresh.neg_key > region.neg_key:
                self._push(fresh)
                return None
            region = fresh
        if not self._may_have_parent_above_bound(region):
            self.cut += 1
            return None
        if region.split >= 0:  # made under the conflicts known now
            self._split(region, self._rank_sets[region.split])
            return None
        self._split(region, tuple((position, 1 << rank) for position, rank in enumerate(region.code)))
        candidate = _Candidate(region.neg_key, region.code, region.probability)
        if self._has_parent_above_bound(candidate):
            return candidate
        self.cut += 1
        return None

    def _index(self) -> None:
        """Bring the conflicts' rank sets, and each object's ranks not ruled out alone, up to those known now."""
        if self._live_at == len(self.store):
            return
        for conflict in self.store.since(len(self._rank_sets)):
            self._rank_sets.append(
                tuple((p, _bits(ranks)) for p, ranks in zip(conflict.positions, conflict.ranks, strict=True))
            )
            self._objects.append(frozenset(conflict.positions))
        live = tuple(_bits(self.store.live_ranks(p)) for p in range(len(self.weights)))
        if live != self._live:
            self._live, self._live_changed = live, len(self.store)
        self._live_at = len(self.store)

    def _region(self, region: _Region) -> _Region | None:
        """``region`` without the ranks ruled out alone, under its own key (at most its key now); None if it
        holds no conflict-free configuration."""
        self._index()
        allowed, code, probability = region.allowed, region.code, region.probability
        if region.masked < self._live_changed:
            allowed = tuple(ranks & live for ranks, live in zip(allowed, self._live, strict=True))
            if not all(allowed):
                return None
            if allowed != region.allowed:
                code = tuple(_first(ranks) for ranks in allowed)
                probability = code_probability(self._table, code)
        known = len(self.store)
        keyed = self._neg_key(code, allowed, probability, self.store.held(code))
        if keyed is None:
            return None
        neg_key, split = keyed
        return _Region(max(region.neg_key, neg_key), code, allowed, probability, known, split, known)

    def _neg_key(self, code: Code, allowed: Ranks, probability: float, held: int) -> tuple[float, int] | None:
        """A region's key (module docstring), negated: its best completion ``code``'s p(C) over what resolving
        the conflicts it holds (``held``) costs at least, and the conflict it is split on (-1: it holds none).
        None: one of them cannot be resolved within ``allowed``."""
        if not held:
            return -tie_key(probability), -1
        weights, rank_sets_of = self.weights, self._rank_sets
        costs = []
        # The conflict split on: the smallest, then the costliest, then the first (held's lowest bits first).
        split, split_size, split_least = -1, math.inf, 0.0
        # Every region made again passes here: bit sets and first ranks unrolled, not called (its time -24 %,
        # BENCHMARKS.md, "Crowded scenes", round 14).
        while held:
            lowest = held & -held
            held ^= lowest
            bit = lowest.bit_length() - 1
            rank_sets = rank_sets_of[bit]
            least = math.inf
            for position, ranks in rank_sets:
                outside = allowed[position] & ~ranks
                if outside:
                    row = weights[position]
                    best = row[(outside & -outside).bit_length() - 2]  # the first rank outside, 0-based
                    if best > 0.0:
                        ratio = row[code[position] - 1] / best
                        if ratio < least:
                            least = ratio
            if least == math.inf:
                return None
            costs.append((least, bit))
            size = len(rank_sets)
            if size < split_size or (size == split_size and least > split_least):
                split, split_size, split_least = bit, size, least
        costs.sort(key=itemgetter(0), reverse=True)
        used: frozenset[int] = frozenset()
        bound = probability
        for cost, bit in costs:
            if cost > 1.0 and not self._objects[bit] & used:
                bound /= cost
                used |= self._objects[bit]
        return -tie_key(bound * (1.0 + BOUND_SLACK)), split

    def _split(self, region: _Region, conflict: RankSets) -> None:
        """Queue the parts of ``region`` that do not contain ``conflict`` (module docstring); with every object
        at its best completion's rank as the conflict, the parts without the best completion (Murty's
        partition). The objects before a part's own stay at their ranks: those are within the rank sets."""
        allowed = list(region.allowed)
        for position, ranks in conflict:
            outside = allowed[position] & ~ranks
            if outside:
                self._push_part(region, (*allowed[:position], outside, *allowed[position + 1 :]), position)
            allowed[position] &= ranks

    def _push_part(self, parent: _Region, allowed: Ranks, changed: int) -> None:
        """Queue a part of ``parent`` whose best completion differs from its parent's at position ``changed``
        alone, under the lower of its parent's key and its best completion's p(C)."""
        code = (*parent.code[:changed], _first(allowed[changed]), *parent.code[changed + 1 :])
        probability = code_probability(self._table, code)
        neg_key = max(parent.neg_key, -tie_key(probability * (1.0 + BOUND_SLACK)))
        self._push(_Region(neg_key, code, allowed, probability, -1, 0, parent.masked))

    def _push(self, region: _Region) -> None:
        heapq.heappush(self._queue, region)
        self._trim()

    def _trim(self) -> None:
        """Beyond the queue limit (candidates found, and the one handed out until the next is looked for,
        count against it), keep the most promising three quarters of the regions."""
        room = max(1, self.queue_limit - len(self._ready) - self._handed_out)
        if len(self._queue) > room:
            keep = max(1, room - room // 4)
            kept = heapq.nsmallest(keep, self._queue)
            self.dropped += len(self._queue) - len(kept)
            heapq.heapify(kept)
            self._queue = kept

    # --- the bound ------------------------------------------------------------------------------------

    def _has_parent_above_bound(self, candidate: _Candidate) -> bool:
        """Whether a configuration has no parent (every rank 1) or one that is not below the bound."""
        code = candidate.code
        if all(rank == 1 for rank in code):
            return True
        return any(not self.is_bounded(code_probability(self._table, parent)) for parent in parents(code))

    def _may_have_parent_above_bound(self, region: _Region) -> bool:
        """Whether some configuration of ``region`` may have a parent above the bound (or none at all): its
        key times the most a parent can gain on any object."""
        if self._gain == 0.0 or all(rank == 1 for rank in region.code):
            return True
        return math.isinf(self._gain) or not self.is_bounded(-region.neg_key * self._gain * (1.0 + BOUND_SLACK))


def _bits(ranks: Sequence[int] | frozenset[int]) -> int:
    """Ranks as a bit set (bit r: rank r)."""
    return sum(1 << rank for rank in ranks)


def _first(ranks: int) -> int:
    """The lowest rank of a non-empty bit set."""
    return (ranks & -ranks).bit_length() - 1


def _ratio(weights: Sequence[float], rank: int) -> float:
    """w(rank - 1) / w(rank): what p(C) gains one rank lower (inf for a zero weight)."""
    return weights[rank - 2] / weights[rank - 1] if weights[rank - 1] > 0.0 else math.inf

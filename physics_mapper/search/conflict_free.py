"""Conflict-free candidates: the next configuration is the most probable one that holds no known conflict.

A best-first search over *partial* assignments, in the spirit of conflict-directed A* (Williams &
Ragno 2007). The group's objects are taken in a *variable order* (below); a node ranks the first k of
them (its *prefix*), and its priority bounds the p(C) of every completion,

    f(prefix) = prod_{assigned i} w_i(c_i) * prod_{unassigned j} max_r w_j(r),

the maximum over the ranks r of j that no one-assignment conflict rules out and that complete no
conflict whose other objects are all in the prefix, each at one of the conflict's ranks (forward
checking; ranks are in decreasing weight, so the first such rank), divided by what resolving the
conflicts the prefix holds costs the unassigned objects at least: a conflict with two or more objects
after the prefix, whose objects in the prefix are all at its ranks, needs one of those objects at a rank
outside its ranks, and object j pays at least its *penalty* there, w_j(first live rank) / w_j(best live
rank outside the conflict's ranks); a conflict costs the least penalty of its objects, and conflicts
without a common object (and without an object forward checking already priced) each cost theirs, so
their costs multiply (an admissible bound: every completion pays them; a conflict none of whose objects
can leave it kills the prefix). f never grows from a prefix to its
children, so complete assignments come off the queue in decreasing p(C): a best-first enumeration. A
prefix that holds a known conflict, or leaves some object no rank, is dropped with all its completions,
so no candidate that holds a known conflict is ever made. Conflicts learned while nodes wait apply when
a node is taken (its prefix checked again, its f recomputed and the node queued again if it fell). A
node taken queues all its children at once (their keys are at most its own, so keys come off the
queue in order).

The order is the paper's: p(C) rounded to 12 significant digits, then the smaller code (in the
group's object order) first. A prefix is queued under f(prefix) * (1 + :data:`BOUND_SLACK`) rounded the
same way, so every completion comes after it. When a complete assignment comes off the queue, every
node of the same rounded key is taken too (prefixes expanded), and the complete ones of that key are
handed out by code: the tie rule holds whatever the variable order. A complete assignment's p(C) is
multiplied in the group's object order, as the searches multiply it, so its key is theirs bit for bit.

The variable order. Dead ends are found once every object of a conflict is ranked; a conflict whose
objects lie far apart in the order lets every combination of the objects between them be tried
before its prefixes die (a merged bin of 25 meshes: 95,000 prefixes for two candidates in the group's
own order). So the objects that share conflicts come first and together: the object in most
conflicts of two or more objects, then repeatedly the one sharing most conflicts with those placed.
When finding a candidate takes more than :data:`REORDER_NODES` prefixes and conflicts were learned
since the order was chosen, the order is chosen again and the enumeration starts over, handing out
only candidates after the last one handed out (every one before it was handed out already, or held a
conflict, or was cut by the bound, and still is).

The bound. The paper's search (and the conflict-directed one) checks a configuration only if one of
its *parents* (one rank lower on one object) is above the bound, a node without parents (every rank
1) always. ``is_bounded(p)`` says whether p(C) = p is below it. A complete assignment with no parent
above the bound is not a candidate; a prefix none of whose completions can have one (f times the
largest weight ratio w(r - 1) / w(r) a completion's parent can gain) is dropped; either is counted in
:attr:`ConflictFreeCandidates.cut` (the search then ends ``bounded``, not ``exhausted``).
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Callable, Sequence
from typing import NamedTuple

from physics_mapper.search.best_first import tie_key
from physics_mapper.search.conflicts import Conflict, ConflictStore
from physics_mapper.search.results import Code

#: Relative slack of a prefix's key over the best p(C) of its completions: far more than the rounding of
#: a product of 50 weights (1e-14) and far less than the 12-digit tie key's step.
BOUND_SLACK = 1e-9
#: Prefixes taken off the queue between two looks at the clock (a few microseconds each).
NODES_PER_CLOCK_CHECK = 64
#: Prefixes one candidate may take before the variable order is chosen again (if conflicts were learned).
REORDER_NODES = 2_000


class _Prefix(NamedTuple):
    """What a prefix's children need of it: its ranks (variable order), weight (its weights multiplied in
    that order), the conflicts it resolves (the union of its assignments' excluded sets) and how many
    conflicts were known then, and the largest w(r - 1) / w(r) of its ranks above 1 (0: all are 1)."""

    ranks: Code
    weight: float
    outside: int
    known: int
    gain: float


#: A conflict open at a variable index k (two or more of its objects at k or after): its bit, the least any of
#: those objects pays to resolve it, and those objects.
_OpenConflict = tuple[int, float, frozenset[int]]


class _Node(NamedTuple):
    """A queued prefix (every object ranked when complete), compared as a tuple by (-key, ranks): unique.
    ``exact``: its key is its bound; else a higher one, its parent's (the bound is made when it is taken)."""

    neg_key: float
    ranks: Code
    prefix: _Prefix
    exact: bool = True


class _Candidate(NamedTuple):
    """A complete assignment found: compared by (-p(C) rounded, code in the group's order), the paper's order."""

    neg_key: float
    code: Code
    probability: float


class ConflictFreeCandidates:
    """The candidates of one group in the paper's order, none holding a known conflict (module docstring).

    ``weights[p]`` are object p's hypothesis weights by rank (non-increasing); ``store`` the group's
    conflicts, which may grow between two candidates; ``is_bounded(p)`` whether p(C) = p is below the
    bound. At most ``queue_limit`` prefixes wait; beyond, the least promising are dropped
    (:attr:`dropped`). The variable order is chosen again after ``reorder_nodes`` prefixes for one
    candidate; :attr:`orders` counts the orders chosen.
    """

    def __init__(
        self,
        weights: Sequence[Sequence[float]],
        store: ConflictStore,
        is_bounded: Callable[[float], bool],
        queue_limit: int,
        reorder_nodes: int = REORDER_NODES,
    ) -> None:
        self.weights = tuple(tuple(w) for w in weights)
        self.store = store
        self.is_bounded = is_bounded
        self.queue_limit = queue_limit
        self.reorder_nodes = reorder_nodes
        #: Configurations (complete, or every completion of a prefix) kept out by the bound.
        self.cut = 0
        #: Prefixes the queue limit threw away.
        self.dropped = 0
        #: Variable orders chosen (the first is the group's own).
        self.orders = 0
        self._gains = [max((_ratio(w, r) for r in range(2, len(w) + 1)), default=0.0) for w in self.weights]
        self._ready: list[_Candidate] = []  # found, of one rounded key, by code
        self._last: _Candidate | None = None  # the last one handed out
        self._taken = 0  # prefixes taken since the last candidate was handed out
        self._start(tuple(range(len(self.weights))))

    def _start(self, order: tuple[int, ...]) -> None:
        """Enumerate from the root in variable ``order`` (group positions, first to last)."""
        self.orders += 1
        self._order = order
        self._variable = {position: k for k, position in enumerate(order)}
        self._w = tuple(self.weights[p] for p in order)
        self._gain_after = tuple(max((self._gains[p] for p in order[k:]), default=0.0) for k in range(len(order) + 1))
        count = len(order)
        self._within = [0] * count  # per k, the conflicts whose objects are all among the first k + 1
        self._but = [[0] * count for _ in range(count + 1)]  # per k, j >= k: all but j among the first k
        self._indexed = -1
        # Per k, the conflicts the object at variable index k resolves at each rank (the store's, kept up to date).
        self._resolved = [self.store.excluded_by_rank(p) for p in order]
        self._live: list[tuple[int, ...]] = []
        # Per k, the conflicts with two or more objects at variable index k or after (_OpenConflict).
        self._open: list[list[_OpenConflict]] = [[] for _ in range(count + 1)]
        self._ordered_at = len(self.store)
        self._queue: list[_Node] = []
        self._push_children(_Prefix((), 1.0, 0, 0, 0.0), -math.inf)

    def __len__(self) -> int:
        """Prefixes waiting, and candidates found and not yet handed out."""
        return len(self._queue) + len(self._ready)

    # --- the interface ---------------------------------------------------------------------------------

    def find(self, stop_at: float | None = None) -> bool:
        """Find the next candidate (:meth:`head`); False if the wall-clock time ``stop_at`` came first (the
        search goes on where it stopped at the next call)."""
        self._ready = [c for c in self._ready if self.store.contained(c.code) is None]
        taken = 0
        while not self._ready and self._queue:
            taken += 1
            if stop_at is not None and taken % NODES_PER_CLOCK_CHECK == 0 and time.monotonic() >= stop_at:
                return False
            self._taken += 1
            if self._taken > self.reorder_nodes and len(self.store) > self._ordered_at:
                self._taken = 0
                order = self._chosen_order()
                if order != self._order:
                    self._start(order)
                    continue
                self._ordered_at = len(self.store)
            self._find_key(heapq.heappop(self._queue))
        return True

    @property
    def exhausted(self) -> bool:
        """No candidate is left (none found and no prefix waiting)."""
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
        self._last = self._ready.pop(0)
        self._taken = 0
        return self._last.code, self._last.probability

    # --- the best-first enumeration -----------------------------------------------------------------

    def _find_key(self, node: _Node) -> None:
        """Take up ``node`` and, if it is a candidate, every node of its rounded key: the candidates of that
        key, after the last one handed out, ready by code."""
        found = self._take_up(node)
        if found is None:
            return
        key = found.neg_key
        ready = [found]
        while self._queue and self._queue[0].neg_key <= key:
            also = self._take_up(heapq.heappop(self._queue))
            if also is not None:
                ready.append(also)
        self._ready = sorted(c for c in ready if self._last is None or c > self._last)

    def _index(self) -> None:
        """Bring the order's conflict masks, and each object's live ranks, up to the conflicts known now."""
        if self._indexed == len(self.store):
            return
        start = max(self._indexed, 0)
        for bit, conflict in enumerate(self.store.since(start), start=start):
            flag = 1 << bit
            variables = sorted(self._variable[p] for p in conflict.positions)
            for k in range(variables[-1], len(self._within)):
                self._within[k] |= flag
            if len(variables) == 1:
                continue  # ruled out alone: no live rank holds it, so forward checking has nothing to do
            for j in variables:
                before = max((v for v in variables if v != j), default=-1)
                for k in range(before + 1, j + 1):
                    self._but[k][j] |= flag
        count = len(self._w)
        live = [tuple(self.store.live_ranks(p)) for p in self._order]
        if live != self._live:  # every penalty may have changed: index every conflict's anew
            start = 0
            self._open = [[] for _ in range(count + 1)]
        self._live = live
        self._first = [w[ranks[0] - 1] if ranks else 0.0 for w, ranks in zip(self._w, live, strict=True)]
        self._suffix = [math.prod(self._first[k:]) for k in range(count + 1)]
        self._open_from = [all(self._live[k:]) for k in range(count + 1)]
        self._held_at = [[j for j in range(k, count) if self._but[k][j]] for k in range(count + 1)]
        for bit, conflict in enumerate(self.store.since(start), start=start):
            self._index_open(1 << bit, self._penalty(conflict))
        self._indexed = len(self.store)

    def _penalty(self, conflict: Conflict) -> dict[int, float]:
        """Per object of ``conflict`` (variable index j), what resolving it costs j at best: its first live
        rank's weight over the weight of its best live rank outside the conflict's ranks (inf: none)."""
        penalties = {}
        for position, ranks in zip(conflict.positions, conflict.ranks, strict=True):
            j = self._variable[position]
            outside = [rank for rank in self._live[j] if rank not in ranks]
            best = self._w[j][outside[0] - 1] if outside else 0.0
            penalties[j] = self._first[j] / best if best > 0.0 else math.inf
        return penalties

    def _index_open(self, flag: int, penalties: dict[int, float]) -> None:
        """Enter a conflict (bit ``flag``, :meth:`_penalty`'s ``penalties``) at every variable index k with two
        or more of its objects at k or after. The objects after k change only where k passes one of them,
        so one entry serves each run of k between two of its objects."""
        variables = sorted(penalties)
        for i in range(len(variables) - 2, -1, -1):
            after = variables[i:]
            entry = (flag, min(penalties[j] for j in after), frozenset(after))
            for k in range(variables[i - 1] + 1 if i else 0, variables[i] + 1):
                self._open[k].append(entry)

    @staticmethod
    def _neg_key(prefix: _Prefix, best: float) -> float:
        """A prefix's queue key, negated: its bound on its completions' p(C), ``best`` the best weights of
        the objects after it (:meth:`_best_completion`)."""
        return -tie_key(prefix.weight * best * (1.0 + BOUND_SLACK))

    def _best_completion(self, prefix: _Prefix) -> float | None:
        """The product, over the objects after ``prefix``, of each one's best weight at a rank no
        one-assignment conflict rules out and that completes no conflict with the prefix (a conflict whose
        other objects are all in the prefix and held there); None if some object has no such rank."""
        self._index()
        k = len(prefix.ranks)
        if not self._open_from[k]:
            return None
        best = self._suffix[k]
        inside = ~prefix.outside
        but = self._but[k]
        forced: set[int] = set()
        for j in self._held_at[k]:
            held = but[j] & inside
            if not held:
                continue
            live = self._live[j]
            resolved = self._resolved[j]
            for rank in live:
                if held & resolved[rank] == held:
                    break
            else:
                return None
            # At its first live rank j pays nothing here (that weight is in the suffix product), so a conflict
            # it must resolve may still price it; only a j moved off that rank is priced once, here.
            if rank != live[0]:
                forced.add(j)
                if best > 0.0:
                    best *= self._w[j][rank - 1] / self._first[j]
        return self._resolving(k, inside, forced, best)

    def _resolving(self, k: int, inside: int, forced: set[int], best: float) -> float | None:
        """``best`` divided by what resolving the conflicts the prefix of length k holds (``inside``: bits of
        those it does not resolve) costs the objects after it at least (None: one cannot be resolved). Each
        needs one of its objects after k at a rank outside its ranks, for at least that object's penalty
        (:meth:`_penalty`); conflicts without a common object, and none of the ``forced`` objects (forward
        checking priced them), need that many: their least penalties multiply."""
        held = sorted(((penalty, objects) for bit, penalty, objects in self._open[k] if bit & inside), reverse=True)
        used = forced
        for penalty, objects in held:
            if math.isinf(penalty):
                return None
            if penalty > 1.0 and not objects & used:
                best /= penalty
                used = used | objects
        return best

    def _take_up(self, node: _Node) -> _Candidate | None:
        """A node off the queue: checked against conflicts learned since it was queued (or its own bound made),
        then returned as a candidate if it is one, else its children queued."""
        if node.prefix.known != len(self.store) or not node.exact:
            checked = self._checked(node)
            if checked is None or checked.neg_key > node.neg_key:
                return None  # holds a conflict or is cut by the bound, or queued again under its own key
            node = checked
        prefix = node.prefix
        if len(prefix.ranks) < len(self._w):
            self._push_children(prefix, node.neg_key)
            return None
        code = self._code(prefix.ranks)
        candidate = _Candidate(node.neg_key, code, _product(self.weights, code))
        if self._has_parent_above_bound(candidate):
            return candidate
        self.cut += 1
        return None

    def _code(self, ranks: Code) -> Code:
        """Complete ``ranks`` (variable order) as a code (the group's order)."""
        code = [0] * len(ranks)
        for k, rank in enumerate(ranks):
            code[self._order[k]] = rank
        return tuple(code)

    def _checked(self, node: _Node) -> _Node | None:
        """``node`` under the conflicts known now, with its own bound: None if its prefix holds one, leaves
        an object no rank or is cut by the bound; queued again, and returned with its new key, if its bound
        is below its key; else returned up to date."""
        self._index()
        prefix = self._updated(node.prefix)
        if prefix.ranks and self._within[len(prefix.ranks) - 1] & ~prefix.outside:
            return None
        best = self._best_completion(prefix)
        if best is None:
            return None
        if len(prefix.ranks) == len(self._w):
            neg_key = node.neg_key
        elif self._may_have_parent_above_bound(prefix, best):
            neg_key = max(node.neg_key, self._neg_key(prefix, best))
        else:
            self.cut += 1
            return None
        checked = _Node(neg_key, node.ranks, prefix)
        if checked.neg_key > node.neg_key:
            self._push(checked)
        return checked

    def _updated(self, prefix: _Prefix) -> _Prefix:
        """``prefix`` with the conflicts it resolves among those known now."""
        if prefix.known == len(self.store):
            return prefix
        outside = 0
        for k, rank in enumerate(prefix.ranks):
            outside |= self._resolved[k][rank]
        return prefix._replace(outside=outside, known=len(self.store))

    def _push_children(self, parent: _Prefix, parent_key: float) -> None:
        """Queue every child of ``parent`` (queued under ``parent_key``, negated): its next object at each rank
        no one-assignment conflict rules out, holding no known conflict. All at once: a child's bound is at
        most its parent's, but a sibling's may be above another's (forward checking), so children queued one
        at a time could come after candidates they precede. A complete child is queued under its p(C); a
        prefix under the lower of its parent's key and its own weight times the best weights after it, its
        own bound made when it is taken (most children never are)."""
        k = len(parent.ranks)
        if k == len(self._w):
            return
        self._index()
        weights = self._w[k]
        decided = self._within[k]
        resolved = self._resolved[k]
        for live in self._live[k]:
            outside = parent.outside | resolved[live]
            if decided & ~outside:
                continue
            ranks = (*parent.ranks, live)
            weight = parent.weight * weights[live - 1]
            gain = max(parent.gain, _ratio(weights, live)) if live > 1 else parent.gain
            child = _Prefix(ranks, weight, outside, len(self.store), gain)
            if len(ranks) == len(self._w):
                self._push(_Node(-tie_key(_product(self.weights, self._code(ranks))), ranks, child))
            else:
                optimistic = max(parent_key, self._neg_key(child, self._suffix[k + 1]))
                self._push(_Node(optimistic, ranks, child, exact=False))

    def _push(self, node: _Node) -> None:
        heapq.heappush(self._queue, node)
        if len(self._queue) > self.queue_limit:
            keep = max(1, self.queue_limit - self.queue_limit // 4)
            kept = heapq.nsmallest(keep, self._queue)
            self.dropped += len(self._queue) - len(kept)
            heapq.heapify(kept)
            self._queue = kept

    def _chosen_order(self) -> tuple[int, ...]:
        """The variable order (module docstring): the object in most conflicts of two or more objects first,
        then repeatedly the one sharing most of them with those placed (then most conflicts, then the first
        in the group's order); objects in none last, in the group's order."""
        shared: dict[int, dict[int, int]] = {}
        for conflict in self.store:
            if len(conflict.positions) > 1:
                for p in conflict.positions:
                    links = shared.setdefault(p, {})
                    for q in conflict.positions:
                        links[q] = links.get(q, 0) + 1
        order: list[int] = []
        ties = {p: links[p] for p, links in shared.items()}
        with_placed = dict.fromkeys(shared, 0)
        while with_placed:
            chosen = max(with_placed, key=lambda p: (with_placed[p], ties[p], -p))
            del with_placed[chosen]
            order.append(chosen)
            for q, count in shared[chosen].items():
                if q in with_placed:
                    with_placed[q] += count
        return (*order, *(p for p in range(len(self.weights)) if p not in shared))

    # --- the bound ------------------------------------------------------------------------------------

    def _has_parent_above_bound(self, candidate: _Candidate) -> bool:
        """Whether a complete assignment has no parent (every rank 1) or one that is not below the bound."""
        code = candidate.code
        if all(rank == 1 for rank in code):
            return True
        for position, rank in enumerate(code):
            if rank > 1:
                parent = (*code[:position], rank - 1, *code[position + 1 :])
                if not self.is_bounded(_product(self.weights, parent)):
                    return True
        return False

    def _may_have_parent_above_bound(self, prefix: _Prefix, best: float) -> bool:
        """Whether some completion of ``prefix`` may have a parent above the bound (or none at all): its
        best p(C) (``best``: :meth:`_best_completion`) times the most a parent can gain, on an object of
        the prefix or after it."""
        if prefix.gain == 0.0:
            return True
        gain = max(prefix.gain, self._gain_after[len(prefix.ranks)])
        return math.isinf(gain) or not self.is_bounded(prefix.weight * best * gain * (1.0 + BOUND_SLACK))


def _ratio(weights: Sequence[float], rank: int) -> float:
    """w(rank - 1) / w(rank): what p(C) gains one rank lower (inf for a zero weight)."""
    return weights[rank - 2] / weights[rank - 1] if weights[rank - 1] > 0.0 else math.inf


def _product(weights: Sequence[Sequence[float]], code: Sequence[int]) -> float:
    """p(C) of ``code``, multiplied in the group's object order as the searches do."""
    return math.prod(w[rank - 1] for w, rank in zip(weights, code, strict=True))

"""Conflict-free candidates: the next configuration is the most probable one that holds no known conflict.

A best-first search over *partial* assignments, in the spirit of conflict-directed A* (Williams &
Ragno 2007): a node assigns ranks to the group's first k objects (its *prefix*), its priority the
best p(C) of any completion,

    f(prefix) = prod_{i < k} w_i(c_i) * prod_{j >= k} max_r w_j(r),

the maximum over the ranks of object j that no one-assignment conflict rules out (its first live rank:
ranks are in decreasing weight). f never grows along a path (a child multiplies by a weight at most
the maximum it replaces), so complete assignments come off the queue in decreasing p(C): a best-first
enumeration. A prefix that contains a known conflict (every object of the conflict assigned, each at
one of the conflict's ranks: :meth:`~physics_mapper.search.conflicts.ConflictStore.within` and
:meth:`~physics_mapper.search.conflicts.ConflictStore.excluded`) is dropped with all its completions,
so no candidate that holds a known conflict is ever made. Conflicts learned while nodes wait are
applied when a node is taken (its prefix checked again, its f recomputed and the node queued again if
it fell).

The order is the paper's: (p(C) rounded to 12 significant digits, then the smaller code first). A
prefix is queued under f(prefix) * (1 + :data:`BOUND_SLACK`) rounded the same way, so it comes before
each of its completions, or, at an equal key, by its own ranks, which a completion starts with: every
completion that ties with a complete assignment C and has a smaller code than C comes from a prefix
ordered before C. Each node queues only its first child and, once taken, its next sibling (the next
live rank of its last object), so a step queues at most two nodes.

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
from collections.abc import Callable, Sequence
from typing import NamedTuple

from physics_mapper.search.branch_and_bound import tie_key
from physics_mapper.search.conflicts import ConflictStore
from physics_mapper.search.results import Code

#: Relative slack of a prefix's key over the best p(C) of its completions: far more than the rounding of
#: a product of 50 weights (1e-14) and far less than the 12-digit tie key's step.
BOUND_SLACK = 1e-9


class _Prefix(NamedTuple):
    """What a prefix's children need of it: its ranks, weight (its weights multiplied left to right, p(C)
    when complete), the conflicts it resolves (the union of its assignments' excluded sets) and how many
    conflicts were known then, and the largest w(r - 1) / w(r) of its ranks above 1 (0: every rank is 1)."""

    ranks: Code
    weight: float
    outside: int
    known: int
    gain: float


class _Node(NamedTuple):
    """A queued prefix (a whole code when complete), compared as a tuple by (-key, ranks): unique."""

    neg_key: float
    ranks: Code
    prefix: _Prefix
    parent: _Prefix


class ConflictFreeCandidates:
    """The candidates of one group in the paper's order, none holding a known conflict (module docstring).

    ``weights[p]`` are object p's hypothesis weights by rank (non-increasing); ``store`` the group's
    conflicts, which may grow between two candidates; ``is_bounded(p)`` whether p(C) = p is below the
    bound. At most ``queue_limit`` prefixes wait; beyond, the least promising are dropped
    (:attr:`dropped`).
    """

    def __init__(
        self,
        weights: Sequence[Sequence[float]],
        store: ConflictStore,
        is_bounded: Callable[[float], bool],
        queue_limit: int,
    ) -> None:
        self.weights = tuple(tuple(w) for w in weights)
        self.store = store
        self.is_bounded = is_bounded
        self.queue_limit = queue_limit
        #: Configurations (complete, or every completion of a prefix) kept out by the bound.
        self.cut = 0
        #: Prefixes the queue limit threw away.
        self.dropped = 0
        # Per k, the largest w(r - 1) / w(r) of any rank of the objects from k on (what a parent gains).
        gains = [max((_ratio(w, r) for r in range(2, len(w) + 1)), default=0.0) for w in self.weights]
        self._gain_after = tuple(max(gains[k:], default=0.0) for k in range(len(gains) + 1))
        self._queue: list[_Node] = []
        self._head: _Node | None = None
        self._best_after: tuple[float, ...] = ()
        self._best_known = -1
        self._push_first_live(_Prefix((), 1.0, 0, 0, 0.0), 1)

    def __len__(self) -> int:
        """Prefixes waiting, and the candidate found next if any."""
        return len(self._queue) + (self._head is not None)

    def head(self) -> tuple[Code, float] | None:
        """The next candidate and its p(C), not taken (None: no candidate is left)."""
        if self._head is not None and self._head.prefix.known != len(self.store):
            head, self._head = self._head, None
            checked = self._checked(head)
            if checked is not None and checked.neg_key == head.neg_key:
                self._head = checked  # (a head whose key fell is queued again)
        if self._head is None:
            self._head = self._next_complete()
        return None if self._head is None else (self._head.ranks, self._head.prefix.weight)

    def take(self) -> tuple[Code, float] | None:
        """The next candidate and its p(C), taken (None: none is left)."""
        found = self.head()
        self._head = None
        return found

    # --- the best-first enumeration -----------------------------------------------------------------

    def _best_suffix(self) -> tuple[float, ...]:
        """Per k, the product of the best live weights of the objects from k on (1 past the last)."""
        if self._best_known != len(self.store):
            best = [1.0] * (len(self.weights) + 1)
            for position in range(len(self.weights) - 1, -1, -1):
                first = self.store.next_rank(position, 0)
                best[position] = best[position + 1] * (0.0 if first is None else self.weights[position][first - 1])
            self._best_after = tuple(best)
            self._best_known = len(self.store)
        return self._best_after

    def _key(self, ranks: Code, weight: float) -> float:
        """The node's queue key, negated: -p(C) rounded, or a prefix's bound on its completions'."""
        if len(ranks) == len(self.weights):
            return -tie_key(weight)
        return -tie_key(weight * self._best_suffix()[len(ranks)] * (1.0 + BOUND_SLACK))

    def _next_complete(self) -> _Node | None:
        """Take prefixes off the queue, queuing their first children and next siblings, until a complete
        assignment that holds no known conflict and may be checked under the bound comes off."""
        while self._queue:
            node = heapq.heappop(self._queue)
            found = self._take_up(node)
            if found is not None:
                return found
        return None

    def _take_up(self, node: _Node) -> _Node | None:
        """A node off the queue: checked against conflicts learned since it was queued, its next sibling
        queued, and then the node itself returned if it is a candidate, else its first child queued."""
        if node.prefix.known != len(self.store):
            checked = self._checked(node)
            if checked is None:
                self._push_sibling(node)
                return None
            if checked.neg_key > node.neg_key:
                return None  # queued again: its sibling comes when it is taken
            node = checked
        self._push_sibling(node)
        prefix = node.prefix
        if len(prefix.ranks) == len(self.weights):
            if self._has_parent_above_bound(prefix):
                return node
            self.cut += 1
            return None
        self._push_first_live(prefix, 1)
        return None

    def _checked(self, node: _Node) -> _Node | None:
        """``node`` under the conflicts known now: None if its prefix holds one; queued again, and returned
        with its new key, if they lowered its completions' best; else returned up to date."""
        prefix = self._updated(node.prefix)
        if prefix.ranks and self.store.within(len(prefix.ranks) - 1) & ~prefix.outside:
            return None
        checked = node._replace(neg_key=self._key(prefix.ranks, prefix.weight), prefix=prefix)
        if checked.neg_key > node.neg_key:
            self._push(checked)
        return checked

    def _updated(self, prefix: _Prefix) -> _Prefix:
        """``prefix`` with the conflicts it resolves among those known now."""
        store = self.store
        if prefix.known == len(store):
            return prefix
        outside = 0
        for position, rank in enumerate(prefix.ranks):
            outside |= store.excluded(position, rank)
        return prefix._replace(outside=outside, known=len(store))

    def _push_sibling(self, node: _Node) -> None:
        """Queue the node's next sibling: its last object at the next rank left (the root has none)."""
        if node.ranks:
            self._push_first_live(self._updated(node.parent), node.ranks[-1] + 1)

    def _push_first_live(self, parent: _Prefix, rank: int) -> None:
        """Queue the child of ``parent`` whose next object is at the first rank from ``rank`` on that no
        one-assignment conflict rules out, that holds no known conflict, and that the bound lets through."""
        position = len(parent.ranks)
        if position == len(self.weights):
            return
        store = self.store
        weights = self.weights[position]
        decided = store.within(position)
        while (live := store.next_rank(position, rank - 1)) is not None:
            rank = live + 1
            outside = parent.outside | store.excluded(position, live)
            if decided & ~outside:
                continue
            ranks = (*parent.ranks, live)
            weight = parent.weight * weights[live - 1]
            gain = max(parent.gain, _ratio(weights, live)) if live > 1 else parent.gain
            child = _Prefix(ranks, weight, outside, len(store), gain)
            if len(ranks) == len(self.weights) or self._may_have_parent_above_bound(child):
                self._push(_Node(self._key(ranks, weight), ranks, child, parent))
                return
            self.cut += 1

    def _push(self, node: _Node) -> None:
        heapq.heappush(self._queue, node)
        if len(self._queue) > self.queue_limit:
            keep = max(1, self.queue_limit - self.queue_limit // 4)
            kept = heapq.nsmallest(keep, self._queue)
            self.dropped += len(self._queue) - len(kept)
            heapq.heapify(kept)
            self._queue = kept

    # --- the bound ------------------------------------------------------------------------------------

    def _has_parent_above_bound(self, prefix: _Prefix) -> bool:
        """Whether a complete assignment has no parent (every rank 1) or one that is not below the bound."""
        if prefix.gain == 0.0:
            return True
        code = prefix.ranks
        for position, rank in enumerate(code):
            if rank > 1:
                parent = (*code[:position], rank - 1, *code[position + 1 :])
                if not self.is_bounded(_product(self.weights, parent)):
                    return True
        return False

    def _may_have_parent_above_bound(self, prefix: _Prefix) -> bool:
        """Whether some completion of ``prefix`` may have a parent above the bound (or none at all): its
        best p(C) times the most a parent can gain, on an object of the prefix or after it."""
        if prefix.gain == 0.0:
            return True
        k = len(prefix.ranks)
        gain = max(prefix.gain, self._gain_after[k])
        best = prefix.weight * self._best_suffix()[k]
        return math.isinf(gain) or not self.is_bounded(best * gain * (1.0 + BOUND_SLACK))


def _ratio(weights: Sequence[float], rank: int) -> float:
    """w(rank - 1) / w(rank): what p(C) gains one rank lower (inf for a zero weight)."""
    return weights[rank - 2] / weights[rank - 1] if weights[rank - 1] > 0.0 else math.inf


def _product(weights: Sequence[Sequence[float]], code: Code) -> float:
    """p(C) of ``code``, multiplied left to right as the searches do."""
    return math.prod(w[rank - 1] for w, rank in zip(weights, code, strict=True))

"""Children of expanded nodes held back until the best-first order needs them.

In a crowded group most children a conflict-directed expansion makes are never visited: the answer
is found first (a 50-object bin: 70 % of the nodes queued were still queued at the answer). Queuing
one costs its p(C) (a product of N weights), its tie key and a heap push. So an expansion's children
wait here, sorted by p(child) / p(parent) = w_q(new rank) / w_q(old rank) for the object q each
advances, and are queued one at a time, each when it could come next.

The order is the paper's. A child c of parent X advanced on object q has

    tie_key(p(c)) <= p(X) * w_q(new) / w_q(old) * (1 + BOUND_SLACK) = bound(c)

(the two products differ by a few ulps, the 12-digit tie key by at most 5e-12 relative), and the
siblings wait in decreasing ratio, so the first waiting sibling's bound is at least every waiting
sibling's tie key. Before the search takes the head of its queue it releases every waiting child
whose bound is at least the head's tie key: a child that would come before the head (or tie with
it) is then in the queue, and the head is taken in the order of a search that queued every child
at once. The same holds for a child queued by two parents: it is released (and found queued
already) before it could come next.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence
from typing import NamedTuple

from physics_mapper.search.results import Code

#: Relative slack of a waiting child's bound over its parent's p(C) times its weight ratio: far more
#: than the products' rounding (N ulps) and the tie key's (5e-12); a child released early only costs
#: its push sooner.
BOUND_SLACK = 1e-9


class _Waiting(NamedTuple):
    """One expansion's waiting children, ordered by the negated bound of the next one (a min-heap)."""

    neg_bound: float
    order: int  # expansions in the order they were made: ties release the earlier first
    next_index: int
    siblings: tuple[tuple[float, Code], ...]  # (weight ratio, child code), decreasing ratio
    parent: Code
    parent_probability: float


class PendingChildren:
    """The children expansions made and the search has not queued yet (module docstring)."""

    def __init__(self) -> None:
        self._heap: list[_Waiting] = []
        self._made = 0
        self._waiting = 0

    def __len__(self) -> int:
        """Children waiting."""
        return self._waiting

    def add(self, parent: Code, parent_probability: float, children: Sequence[tuple[float, Code]]) -> None:
        """Hold ``children`` of ``parent`` (p(C) ``parent_probability``), each as (weight ratio, code)."""
        if not children:
            return
        siblings = tuple(sorted(children, key=lambda child: -child[0]))
        self._made += 1
        self._waiting += len(siblings)
        self._push(self._made, 0, siblings, parent, parent_probability)

    @property
    def neg_bound(self) -> float | None:
        """Minus the highest bound of a waiting child (compare with a queue item's ``neg_probability``)."""
        return self._heap[0].neg_bound if self._heap else None

    @property
    def highest_bound(self) -> float | None:
        """The highest bound (of p(C)) of a waiting child; None: none waits."""
        return None if not self._heap else -self._heap[0].neg_bound

    def release(self) -> tuple[Code, Code]:
        """The waiting child of highest bound and its parent, no longer waiting (one must wait)."""
        _, order, index, siblings, parent, parent_probability = heapq.heappop(self._heap)
        self._waiting -= 1
        if index + 1 < len(siblings):
            self._push(order, index + 1, siblings, parent, parent_probability)
        return siblings[index][1], parent

    def _push(
        self, order: int, index: int, siblings: tuple[tuple[float, Code], ...], parent: Code, parent_probability: float
    ) -> None:
        """Wait with sibling ``index`` next, under its bound."""
        bound = parent_probability * siblings[index][0] * (1.0 + BOUND_SLACK)
        heapq.heappush(self._heap, _Waiting(-bound, order, index, siblings, parent, parent_probability))

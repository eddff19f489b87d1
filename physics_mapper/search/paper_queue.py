"""The paper's candidate generator (Algorithm 1): a priority queue of children.

The root is (1, ..., 1); a checked candidate's children each advance one object's rank by one, so
p(child) <= p(parent) and candidates come off the queue in non-increasing p(C). A candidate below
the bound is not expanded: its children are queued only by another parent.

The queue is ordered by (-p(C) rounded to 12 significant digits, code)
(:func:`~physics_mapper.search.best_first.tie_key`). A child's key is therefore always after its
parent's, so candidates come off in strictly increasing key order and a code is never queued again
once taken: the set that keeps a code from being queued twice only needs to hold the queued ones.

Bounded memory: the queue holds at most ``queue_limit`` candidates (beyond, the least probable are
dropped and the search can no longer say it visited everything: it ends ``truncated``).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence

import numpy as np

from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.physics.settling import Settling
from physics_mapper.search.best_first import (
    NamedConflict,
    QueueItem,
    Rule1Verdict,
    code_probability,
    tie_key,
    weight_table,
)
from physics_mapper.search.results import Code, Counters, RuledOut, SearchEnd, SearchStats


class PaperQueue:
    """The paper's queue of children (module docstring); ``dropped`` counts what the queue limit threw away."""

    def __init__(self, hypotheses: Sequence[RankedHypotheses], queue_limit: int) -> None:
        self._weights = weight_table(hypotheses)
        self._sizes = tuple(len(h) for h in hypotheses)
        self.queue_limit = queue_limit
        self.dropped = 0
        self._configurations = math.prod(self._sizes)
        self._observed = 0
        self._queue: list[QueueItem] = []
        self._enqueued: set[Code] = set()  # the queued codes (taken ones never come back)
        self._push(tuple(1 for _ in self._sizes), None)

    def ready(self, stop_at: float | None) -> bool:
        return True  # the next candidate is the queue's head

    def take(self) -> QueueItem | None:
        if not self._queue:
            return None
        item = heapq.heappop(self._queue)
        self._enqueued.discard(item.code)
        return item

    def put_back(self, item: QueueItem) -> None:
        heapq.heappush(self._queue, item)
        self._enqueued.add(item.code)

    def observe(self, code: Code, verdict: Rule1Verdict | Settling, valid: bool, bounded: bool) -> NamedConflict | None:
        """Queue the children of a checked candidate above the bound; the paper learns no conflict."""
        self._observed += 1
        if not bounded:
            for position, rank in enumerate(code):
                if rank < self._sizes[position]:
                    self._push((*code[:position], rank + 1, *code[position + 1 :]), code)
        return None

    def _push(self, code: Code, parent: Code | None) -> None:
        """Queue candidate ``code`` (first queued by expanding ``parent``), unless it is queued already."""
        if code in self._enqueued:
            return
        self._enqueued.add(code)
        probability = code_probability(self._weights, code)
        heapq.heappush(self._queue, QueueItem(-tie_key(probability), code, probability, parent))
        if len(self._queue) > self.queue_limit:
            self._trim()

    def _trim(self) -> None:
        """Drop the least probable queued candidates, down to three quarters of the limit (so trims are rare)."""
        keep = max(1, self.queue_limit - self.queue_limit // 4)
        keys = np.fromiter((item.neg_probability for item in self._queue), float, len(self._queue))
        cut = np.partition(keys, keep - 1)[keep - 1]
        kept = [item for item in self._queue if item.neg_probability < cut]
        tied = sorted(item for item in self._queue if item.neg_probability == cut)  # by code, as they would pop
        kept += tied[: keep - len(kept)]
        self.dropped += len(self._queue) - len(kept)
        heapq.heapify(kept)
        self._queue = kept
        self._enqueued = {item.code for item in kept}

    @property
    def exhausted(self) -> bool:
        return not self._queue

    @property
    def end(self) -> SearchEnd | None:
        """None while candidates are queued; ``truncated`` when the limit dropped some, ``bounded`` when
        the bound kept some configuration from the queue, else ``exhausted``."""
        if self._queue:
            return None
        if self.dropped:
            return "truncated"
        return "bounded" if self._observed != self._configurations else "exhausted"

    @property
    def queued(self) -> int:
        return len(self._queue)

    @property
    def next_probability(self) -> float | None:
        return self._queue[0].probability if self._queue else None

    @property
    def ruled_out(self) -> tuple[RuledOut, ...]:
        return ()

    @property
    def live_root(self) -> Code:
        return tuple(1 for _ in self._sizes)  # the paper rules nothing out unchecked

    def count_into(self, stats: SearchStats) -> None:
        stats.dropped += self.dropped

    def counters(self) -> Counters:
        return {}  # the paper's queue counts only what every search counts

"""Which objects a tick's search may leave out of the map, and how likely each is absent (ROS-free).

At every tick each object gets the hypotheses the search ranks, from its input status and from
the map of the previous ticks (:class:`MapMemory`):

- **Fresh hypotheses** (received within ``max_age``) are searched as received. An instance that
  may not be there (a tentative track, or an instance of a ``count: {max: K}`` entry) gets one
  more, *absent*, with the weight w the association gives it
  (:meth:`~physics_mapper.mapping.association.InstanceTracks.absent_weight`); its other
  hypotheses are scaled by 1 - w.
- **Silent** (its newest hypotheses older than ``max_age``, or its track ended): if the map held
  it, its last map pose is kept as one hypothesis beside *absent*, whose weight grows with the
  silence s (seconds since it fell silent): w_absent = 1 - exp(-s / max_age) / 2. From s = 0
  being absent is at least as likely as being there, so the search (which prefers the most
  probable pattern of existence among valid maps, then the least jitter) drops the object where
  nothing needs it and keeps it where another rests on it (leaving it out would make that one
  fall).
- **Not in the map and nothing fresh** (never seen, or dropped): *absent* alone, weight 1: the
  object is not in the world.

Named objects and confirmed instances of ``count: K`` with fresh hypotheses have no *absent*.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from physics_mapper.mapping.inputs import InputSnapshot
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, absent_hypothesis
from physics_mapper.search.results import SearchResult


def silent_absent_weight(silence: float, max_age: float) -> float:
    """w_absent of an object silent for ``silence`` seconds: 1 - exp(-silence / max_age) / 2."""
    return 1.0 - 0.5 * math.exp(-max(0.0, silence) / max_age)


def with_absent(ranked: RankedHypotheses, index: int, weight: float) -> RankedHypotheses:
    """``ranked`` scaled by 1 - ``weight``, plus object ``index``'s *absent* of ``weight``, ranked."""
    scaled = [Hypothesis(h.pose, h.weight * (1.0 - weight)) for h in ranked.hypotheses]
    return RankedHypotheses.from_weighted([*scaled, absent_hypothesis(index, weight)])


@dataclass
class MapMemory:
    """What the map held: each object's last map pose (the chosen one), and since when each is silent."""

    poses: dict[str, Pose] = field(default_factory=dict)
    silent_since: dict[str, float] = field(default_factory=dict)

    def remember(self, names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult) -> None:
        """Keep the chosen pose of every object the result's map holds; forget those it leaves out."""
        if result.code is None or result.poses is None:
            return
        for name, ranked, rank, pose in zip(names, hypotheses, result.code, result.poses, strict=True):
            if ranked.is_absent(rank):
                self.poses.pop(name, None)
            else:
                self.poses[name] = pose


def searched_hypotheses(
    snapshot: InputSnapshot,
    memory: MapMemory,
    absent_weight: Callable[[str], float | None],
    now: float,
    max_age: float,
) -> tuple[RankedHypotheses, ...]:
    """Every object's hypotheses for this tick's search, by the rules of the module docstring.

    ``absent_weight`` gives an instance's weight of being absent (None: it is there); ``now``
    and ``max_age`` are seconds.
    """
    searched = []
    for index, status in enumerate(snapshot.objects):
        name = status.name
        if status.hypotheses is not None:
            memory.silent_since.pop(name, None)
            weight = absent_weight(name)
            searched.append(status.hypotheses if weight is None else with_absent(status.hypotheses, index, weight))
            continue
        since = memory.silent_since.setdefault(name, now)
        last = memory.poses.get(name)
        if last is None:
            searched.append(RankedHypotheses((absent_hypothesis(index, 1.0),)))
        else:
            kept = RankedHypotheses((Hypothesis(last, 1.0),))
            searched.append(with_absent(kept, index, silent_absent_weight(now - since, max_age)))
    return tuple(searched)


def left_out_by_physics(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult | None
) -> tuple[str, ...]:
    """The objects a *finished* search's map leaves out (none while the deadline stops it: its choice is
    the best so far, not physics' verdict)."""
    if result is None or result.code is None or not result.stats.finished:
        return ()
    return absent_objects(names, hypotheses, result)


def absent_objects(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult | None
) -> tuple[str, ...]:
    """The objects a result's map leaves out (all of them without a chosen configuration)."""
    if result is None or result.code is None:
        return names
    return tuple(
        name for name, ranked, rank in zip(names, hypotheses, result.code, strict=True) if ranked.is_absent(rank)
    )

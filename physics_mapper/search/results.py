"""What a search returns: configuration codes, trace entries (the paper's Fig. 4), statistics, results.

A configuration picks one hypothesis per object and is written as its *code*, the 1-based ranks
in object order: ``(2, 1, 1)`` is the paper's C211.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Literal

from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Fallback
from physics_mapper.physics.refine import RefinedMap
from physics_mapper.physics.settling import SettleStop, Settling

Code = tuple[int, ...]
Outcome = Literal["collision", "unstable", "valid"]
#: How a search that emptied its queue ended: ``exhausted`` (every configuration visited), ``bounded``
#: (configurations below the bound were never queued) or ``truncated`` (the queue limit dropped nodes).
SearchEnd = Literal["exhausted", "bounded", "truncated"]
#: A search part's own counters by name (the conflict-directed search's ``conflicts``, ``local_settlings``, ...).
Counters = Mapping[str, int]


def summed(*counters: Counters) -> dict[str, int]:
    """``counters`` added up name by name, the names in the order they first come."""
    total: dict[str, int] = {}
    for each in counters:
        for name, value in each.items():
            total[name] = total.get(name, 0) + value
    return total


@dataclass(frozen=True, slots=True)
class TraceEntry:
    """One visited node: its code, p(C), outcome and evidence (paper Fig. 4).

    ``bounded`` is true when the node is below the bound, so it was checked but not expanded.
    For ``collision``: ``pair`` and penetration ``depth`` (m). For ``unstable``:
    ``moved`` (the object with the largest J_i) and ``jitter`` (J). For ``valid``: ``jitter``.
    ``parent`` is the node whose expansion first queued this one (None for the root).
    ``group`` is the interaction group's id when the code covers that group's objects only
    (None: every object). ``settle_stop`` says why the settling stopped early (``rest`` or
    ``beyond_threshold``: the jitter is then the one at that moment) after ``settled_time``
    simulated seconds (both None for a settling of the whole ``settle_time``). ``conflict`` names the
    assignments (object name, rank) a conflict-directed search learned from the rejection
    (:mod:`physics_mapper.search.conflicts`).
    """

    code: Code
    probability: float
    outcome: Outcome
    bounded: bool
    pair: tuple[str, str] | None = None
    depth: float | None = None
    moved: str | None = None
    jitter: float | None = None
    parent: Code | None = None
    group: int | None = None
    settle_stop: SettleStop | None = None
    settled_time: float | None = None
    conflict: tuple[tuple[str, int], ...] | None = None


@dataclass(frozen=True, slots=True)
class RuledOut:
    """A rank ruled out before the search: no valid configuration holds ``object`` at ``rank``, because
    its body there overlaps ``other`` (a static body, or with ``every_rank`` an object at each of its
    ranks still possible) ``depth`` metres deep, beyond the penetration threshold (with ``every_rank``
    the shallowest of those overlaps): ``reason`` Rule 1's, ``collision``. Or Rule 2's, ``floating``:
    there it is in free fall, nothing within reach to rest on (no static body, nor any object at a rank
    that rests on something: :class:`~physics_mapper.search.ruling_out.FreeFall`; ``other`` empty,
    ``depth`` 0). ``group`` is the interaction group's id, as in the trace."""

    object: str
    rank: int
    other: str
    depth: float
    every_rank: bool = False
    group: int | None = None
    reason: Literal["collision", "floating"] = "collision"


@dataclass
class SearchStats:
    """Counters and timing of a search, accumulated over resumed runs.

    ``end`` is None while nodes are queued (``queued`` of them when the result was made);
    ``dropped`` counts queued nodes the queue limit threw away, ``untraced`` visits the trace
    limit left out. ``settle_steps`` are the simulation steps run, ``settle_steps_saved`` those
    early exits spared, ``memo_hits`` settlings reused, ``merges`` escape-guard merges.
    ``part_counters`` are what the search's parts count of their own, by name (empty where they count
    nothing, as the paper's parts): a conflict-directed search's ``conflicts`` learned and its trial
    settlings (:class:`~physics_mapper.search.conflict_directed.ConflictDirectedCandidates`,
    :class:`~physics_mapper.search.trial_settling.TrialSettling`).
    """

    visited: int = 0
    expanded: int = 0
    bounded: int = 0
    collisions: int = 0
    unstable: int = 0
    valid: int = 0
    search_time: float = 0.0  # seconds of wall-clock time spent searching
    stopped_at_deadline: bool = False
    end: SearchEnd | None = None
    queued: int = 0
    dropped: int = 0
    untraced: int = 0
    settle_steps: int = 0
    settle_steps_saved: int = 0
    memo_hits: int = 0
    merges: int = 0
    part_counters: Counters = field(default_factory=dict)

    @property
    def exhausted(self) -> bool:
        """Every configuration was visited: the result is the best of all of them."""
        return self.end == "exhausted"

    @property
    def finished(self) -> bool:
        """The queue emptied (``end`` is set): running longer would change nothing."""
        return self.end is not None

    @property
    def configurations_per_second(self) -> float:
        return self.visited / self.search_time if self.search_time > 0.0 else 0.0

    def add(self, other: SearchStats) -> None:
        """Add ``other``'s counters, its parts' too (not its time nor how it ended), to these."""
        for name in _COUNTERS:
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.part_counters = summed(self.part_counters, other.part_counters)


#: The fields of :class:`SearchStats` that every search counts (added up over groups).
_COUNTERS = tuple(f.name for f in fields(SearchStats) if f.type == "int")


@dataclass(frozen=True)
class Candidate:
    """A checked, collision-free configuration with its settling."""

    code: Code
    probability: float
    settling: Settling


@dataclass(frozen=True)
class GroupResult:
    """One interaction group's part of a result: its objects (scene indices), best so far and progress.

    ``id`` is the group's id in the trace (None for a search over every object), ``code`` the
    group's ranks (its objects' order), ``valid`` whether that sub-configuration passed both rules.
    ``kept`` says the group's search was carried over unchanged from the previous search.
    ``part_counters`` are its parts' own (:attr:`SearchStats.part_counters`), ``ruled_out`` why each rank
    it ruled out before its search was (a conflict-directed group's).
    """

    id: int | None
    objects: tuple[int, ...]
    valid: bool
    code: Code | None
    probability: float | None
    jitter: float | None
    visited: int
    end: SearchEnd | None
    kept: bool = False
    part_counters: Counters = field(default_factory=dict)
    ruled_out: tuple[RuledOut, ...] = ()


@dataclass(frozen=True)
class SearchResult:
    """Best configuration found so far.

    ``valid`` says whether ``code`` passed both rules. When no configuration is valid,
    ``code`` is the fallback's (the collision-free one of highest p(C), when the fallback
    is ``settled``; the root, when it is ``refine``) or None; ``poses`` are the chosen
    hypotheses, ``settled_poses`` the same objects after settling (for ``refine``: the refined
    map, or where the deadline stopped its settling the depenetrated poses: :attr:`unsettled`),
    ``object_jitters`` each object's J_i (their sum is ``jitter``). ``fallback`` names the
    fallback that gave the map (None for a valid one or none), and ``refinement`` tells how the
    refined map was made. ``groups`` are the interaction groups searched (one, with every
    object, for a joint search). ``previous_map``: the map is the previous map's configuration,
    valid, which a tick checked before a search that found no valid one of its own
    (:mod:`physics_mapper.mapping.previous_map`).
    """

    valid: bool
    code: Code | None
    probability: float | None
    jitter: float | None
    poses: tuple[Pose, ...] | None
    settled_poses: tuple[Pose, ...] | None
    object_jitters: tuple[float, ...] | None
    fallback_used: bool
    stats: SearchStats
    trace: tuple[TraceEntry, ...]
    fallback: Fallback | None = None
    refinement: RefinedMap | None = None
    groups: tuple[GroupResult, ...] = ()
    previous_map: bool = False

    @property
    def unsettled(self) -> bool:
        """Whether the map is a refined map the deadline stopped in its settling (its depenetrated poses)."""
        return self.refinement is not None and not self.refinement.settled

    @property
    def ruled_out(self) -> tuple[RuledOut, ...]:
        """Every group's ranks ruled out before its search, with why (in group order)."""
        return tuple(ruling for group in self.groups for ruling in group.ruled_out)

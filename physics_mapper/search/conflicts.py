"""Conflicts: what a rejected configuration teaches about every configuration that shares part of it.

A *conflict* is a set of assignments (object, rank), the objects given as positions in an interaction
group's object order, such that every configuration that contains all of them is invalid. A search
that knows a conflict never checks a configuration containing it (:mod:`physics_mapper.search.conflict_directed`).

From a collision (Rule 1). The deepest overlap of a configuration is the largest of its pairs'
overlaps, and a pair's overlap depends on the two bodies' poses alone
(:mod:`physics_mapper.physics.collision_table`). So if object i at rank a overlaps object j at rank b
deeper than ``penetration_threshold``, every configuration with i at a and j at b is in collision:
the conflict is {(i, a), (j, b)}; against a static body it is {(i, a)}, and so it is when, at every
one of j's ranks, i at a overlaps j or j is ruled out alone. A rejected configuration teaches one conflict per overlap
beyond the threshold, not only the deepest one's.

From an instability (Rule 2), the *blame rule*. Let the settling of configuration C move the objects U
beyond ``jitter_threshold`` tau (J_u > tau). Write

- S_p for object p's *swept box* in that settling: the smallest box holding its body at every moment
  looked at (:attr:`~physics_mapper.physics.checker.Settling.extent`, every 8 steps, 33 ms);
- E_p(h) for p's *stable envelope* at hypothesis h: the box of its body at h
  (:func:`~physics_mapper.model.extents.body_box`) grown by g_p = max(1, r_p / w) tau
  (:func:`~physics_mapper.model.extents.stable_growth`): no point of a body moves further while its
  jitter stays within tau.

One object of U moving beyond tau makes C unstable, so the rule blames one, u: B_u = {u}, plus every
object whose swept box meets S_u (it touched, or could have touched, u during the settling), plus
every object with some hypothesis h whose E_p(h) meets S_u (at another rank it could have been in
u's way). Each object u of U gives the conflict {(p, C_p) : p in B_u}.

Why it is sound. Take C' containing the conflict, and suppose C' stable: then every object stays
within its stable envelope, so no object outside B_u comes near S_u, while the objects of B_u start
where they started in C. u then meets exactly the bodies it could meet in C, and falls, slides or
topples as it did, beyond tau: C' is unstable after all. The argument takes the objects of
B_u \\ {u}, held within tau of the poses they had in C, to act on u as they did in C; that is
the rule's one assumption, checked on the crowded suite (every configuration a conflict skipped is
checked in full by the tests, and none is valid); so does sampling the motion every 8 steps. A
settling without swept boxes (reused from a memo) blames every object of the configuration, which is
trivially sound.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.extents import body_box, stable_growth
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import ObjectShape, SearchParams, object_radius
from physics_mapper.physics.collision_table import CollisionTable
from physics_mapper.physics.settling import Settling

#: (position of the object in its group, 1-based rank of its hypothesis).
Assignment = tuple[int, int]
ConflictKind = Literal["collision", "unstable"]
FloatArray = NDArray[np.float64]
#: An axis-aligned box, (low corner, high corner), metres.
Region = tuple[tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True, slots=True)
class Conflict:
    """Assignments no valid configuration holds together (module docstring), sorted by position.

    ``region`` (unstable only) is the swept box of the object blamed for moving beyond the threshold:
    an object whose hypotheses change keeps the conflict sound only if it cannot reach it.
    """

    assignments: tuple[Assignment, ...]
    kind: ConflictKind
    region: Region | None = None
    #: The assignments' positions (made once: every expansion by the conflict reads them).
    positions: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "positions", tuple(position for position, _ in self.assignments))

    def holds_in(self, code: Sequence[int]) -> bool:
        """Whether configuration ``code`` (ranks by position) contains every assignment."""
        return all(code[position] == rank for position, rank in self.assignments)


#: Conflicts one group's search keeps at most (a bit per conflict and hypothesis: 625 kB for 50
#: objects of 10 hypotheses); later ones still direct the expansion of the candidate they came from.
CONFLICT_LIMIT = 10_000


class ConflictStore:
    """The conflicts one group's search knows, in learning order, as bit sets.

    Conflict k is bit k. For each position p and rank r, ``_excluded[p][r - 1]`` holds the conflicts
    that assign p another rank than r: a configuration C contains exactly the conflicts in none of
    its N sets, all known conflicts minus their union (N integer ORs, a few microseconds whatever
    the number of conflicts; a 0/1 matrix gathered by numpy took 25 us per look-up).
    """

    def __init__(self, ranks: Sequence[int]) -> None:
        self._ranks = tuple(ranks)
        # Per position, the ranks a one-assignment conflict rules out alone.
        self._ruled_out: tuple[set[int], ...] = tuple(set() for _ in ranks)
        self._conflicts: list[Conflict] = []
        self._known: set[tuple[Assignment, ...]] = set()
        self._excluded: list[list[int]] = [[0] * count for count in ranks]

    def __len__(self) -> int:
        return len(self._conflicts)

    def __iter__(self) -> Iterator[Conflict]:
        return iter(self._conflicts)

    def knows(self, assignments: tuple[Assignment, ...]) -> bool:
        """Whether exactly these assignments are a known conflict."""
        return assignments in self._known

    def learn(self, conflict: Conflict) -> bool:
        """Remember ``conflict``; False if it was known already, or :data:`CONFLICT_LIMIT` are kept."""
        if conflict.assignments in self._known or len(self._conflicts) >= CONFLICT_LIMIT:
            return False
        bit = 1 << len(self._conflicts)
        self._known.add(conflict.assignments)
        self._conflicts.append(conflict)
        for position, rank in conflict.assignments:
            excluded = self._excluded[position]
            for other in range(len(excluded)):
                if other != rank - 1:
                    excluded[other] |= bit
        if len(conflict.assignments) == 1:
            position, rank = conflict.assignments[0]
            self._ruled_out[position].add(rank)
        return True

    def live_ranks(self, position: int) -> list[int]:
        """The ranks of the object at ``position`` that no one-assignment conflict rules out, ascending."""
        ruled_out = self._ruled_out[position]
        return [rank for rank in range(1, self._ranks[position] + 1) if rank not in ruled_out]

    def next_rank(self, position: int, rank: int) -> int | None:
        """The first rank after ``rank`` of the object at ``position`` that no one-assignment conflict rules
        out (None: none is left)."""
        ruled_out = self._ruled_out[position]
        for following in range(rank + 1, self._ranks[position] + 1):
            if following not in ruled_out:
                return following
        return None

    def contained(self, code: Sequence[int]) -> Conflict | None:
        """The smallest known conflict that configuration ``code`` contains, the first learned of equal
        ones (None: it resolves every one)."""
        if not self._conflicts:
            return None
        outside = 0
        for excluded, rank in zip(self._excluded, code, strict=True):
            outside |= excluded[rank - 1]
        held = ((1 << len(self._conflicts)) - 1) & ~outside
        best: Conflict | None = None
        while held:
            lowest = held & -held
            conflict = self._conflicts[lowest.bit_length() - 1]
            if best is None or len(conflict.assignments) < len(best.assignments):
                best = conflict
            held ^= lowest
        return best


def collision_conflict(
    code: Sequence[int],
    pair: tuple[int, int],
    positions: dict[int, int],
    table: CollisionTable,
    known: ConflictStore,
    threshold: float,
) -> Conflict:
    """The conflict of one overlap beyond ``threshold`` metres between bodies ``pair`` (body indices, lower
    first: an object, then an object or a static body; ``positions`` maps the group's object indices to
    their positions).

    Against a static body: {(i, a)}. Between objects i at a and j at b: {(i, a)} alone if, at every
    rank of j, i at a overlaps j or j is ruled out alone (a known one-assignment conflict, or an overlap
    with a static body): then no configuration with i at a is valid. Else the same for j, else
    {(i, a), (j, b)}.
    """
    first, second = pair
    i = positions[first]
    if second not in positions:
        return Conflict(((i, code[i]),), "collision")
    j = positions[second]
    for doomed, index, other, other_index in ((i, first, j, second), (j, second, i, first)):
        depths = table.pair_depths(index, code[doomed], other_index)
        if all(
            depth > threshold or known.knows(((other, rank),)) or table.static_depth(other_index, rank) > threshold
            for rank, depth in enumerate(depths, start=1)
        ):
            return Conflict(((doomed, code[doomed]),), "collision")
    return Conflict(((i, code[i]), (j, code[j])), "collision")


class Blame:
    """The blame rule (module docstring) for one group: its objects' stable envelopes.

    The envelopes, every hypothesis's body box grown by g_p (metres), are made on first use.
    """

    def __init__(
        self, shapes: Sequence[ObjectShape], hypotheses: Sequence[RankedHypotheses], params: SearchParams
    ) -> None:
        self.shapes = tuple(shapes)
        self.hypotheses = tuple(hypotheses)
        self.threshold = params.jitter_threshold
        radii = [object_radius(shape) for shape in self.shapes]
        self.growth = tuple(stable_growth(r, params.jitter_threshold, params.angular_weight) for r in radii)
        self._boxes: tuple[tuple[FloatArray, FloatArray], ...] | None = None
        self._envelopes: tuple[tuple[FloatArray, FloatArray], ...] | None = None
        # Every object's envelopes stacked (sum of M x 3 corners) and the position each belongs to.
        self._stacked: tuple[FloatArray, FloatArray, NDArray[np.intp]] | None = None

    @property
    def boxes(self) -> tuple[tuple[FloatArray, FloatArray], ...]:
        """Per object, (M x 3 low corners, M x 3 high corners) of its body's box at each hypothesis."""
        if self._boxes is None:
            self._boxes = tuple(
                body_boxes(shape, ranked) for shape, ranked in zip(self.shapes, self.hypotheses, strict=True)
            )
        return self._boxes

    @property
    def envelopes(self) -> tuple[tuple[FloatArray, FloatArray], ...]:
        """Per object, (M x 3 low corners, M x 3 high corners) of E_p(h) over its hypotheses."""
        if self._envelopes is None:
            self._envelopes = tuple(
                (low - growth, high + growth) for (low, high), growth in zip(self.boxes, self.growth, strict=True)
            )
        return self._envelopes

    def _stacked_envelopes(self) -> tuple[FloatArray, FloatArray, NDArray[np.intp]]:
        """(low corners, high corners, owner positions) of every envelope: one comparison meets them all."""
        if self._stacked is None:
            lows, highs = zip(*self.envelopes, strict=True)
            owners = np.repeat(np.arange(len(lows)), [len(low) for low in lows])
            self._stacked = np.concatenate(lows), np.concatenate(highs), owners
        return self._stacked

    def conflicts(self, code: Sequence[int], settling: Settling) -> list[Conflict]:
        """The conflicts an unstable settling of configuration ``code`` teaches: one per object that moved
        beyond the threshold (each alone makes the configuration unstable), smallest first."""
        moved = [p for p, jitter in enumerate(settling.jitters) if jitter > self.threshold]
        if settling.extent is None or not moved:
            return [Conflict(tuple(enumerate(code)), "unstable")]
        low = np.array([low for low, _ in settling.extent])
        high = np.array([high for _, high in settling.extent])
        found = []
        for u in moved:
            region: Region = (
                (float(low[u][0]), float(low[u][1]), float(low[u][2])),
                (float(high[u][0]), float(high[u][1]), float(high[u][2])),
            )
            blamed = self._blamed(u, low, high)
            found.append(Conflict(tuple((p, code[p]) for p in blamed), "unstable", region))
        return sorted(found, key=lambda conflict: len(conflict.assignments))

    def _blamed(self, moved: int, low: FloatArray, high: FloatArray) -> list[int]:
        """The object that moved, every object whose swept box meets its swept box, and every object with
        a stable envelope that does, in position order (``low``, ``high``: the swept boxes, N x 3)."""
        blamed = {moved}
        touches = np.all((low <= high[moved]) & (high >= low[moved]), axis=1)
        blamed.update(int(p) for p in np.nonzero(touches)[0])
        env_low, env_high, owners = self._stacked_envelopes()
        reaching = np.all((env_low <= high[moved]) & (env_high >= low[moved]), axis=1)
        blamed.update(int(p) for p in np.unique(owners[reaching]))
        return sorted(blamed)

    def reaches(self, position: int, region: Region) -> bool:
        """Whether some stable envelope of the object at ``position`` meets ``region``."""
        env_low, env_high = self.envelopes[position]
        low, high = np.asarray(region[0]), np.asarray(region[1])
        return bool(np.any(np.all((env_low <= high) & (env_high >= low), axis=1)))


def body_boxes(shape: ObjectShape, ranked: RankedHypotheses) -> tuple[FloatArray, FloatArray]:
    """(M x 3, M x 3): each hypothesis's body box (ranked order), metres."""
    boxes = [body_box(shape, hypothesis.pose) for hypothesis in ranked.hypotheses]
    return np.array([low for low, _ in boxes]), np.array([high for _, high in boxes])

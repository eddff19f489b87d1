"""Conflicts: what a rejected configuration teaches about every configuration that shares part of it.

A *conflict* is a set of assignments (object, rank), the objects given as positions in an interaction
group's object order, such that every configuration that contains all of them is invalid. A search
that knows a conflict never checks a configuration containing it (:mod:`physics_mapper.search.conflict_directed`).
What a rejection teaches often holds for other ranks of some of its objects too, so each assignment
comes with the ranks of its object under which the conflict still holds, its own among them
(:attr:`Conflict.ranks`): a configuration *contains* the conflict when each of its objects is at one
of those ranks. One such conflict stands for every combination of its rank sets, and a candidate
resolves it only by moving some object to a rank outside its set.

From a collision (Rule 1). The deepest overlap of a configuration is the largest of its pairs'
overlaps, and a pair's overlap depends on the two bodies' poses alone
(:mod:`physics_mapper.physics.collision_table`). So if object i at rank a overlaps object j at rank b
deeper than ``penetration_threshold``, every configuration with i at a and j at b is in collision:
the conflict is {(i, a), (j, b)}; against a static body it is {(i, a)}, and so it is when, at every
one of j's ranks, i at a overlaps j or j is ruled out alone. The same holds for every rank of j that
overlaps i at a (or is ruled out alone): j's rank set; and of i against j at b: so an overlap teaches
two conflicts, {i: a, j: every such rank} and {i: every such rank, j: b}. A rejected configuration
teaches them for every overlap beyond the threshold, not only the deepest one.

From an instability (Rule 2), the *blame rule*. Let the settling of configuration C move the objects U
beyond ``jitter_threshold`` tau (J_u > tau). A settling stopped early as unstable shows U as the objects it
stopped for (:attr:`~physics_mapper.physics.settling.Settling.beyond`): at that moment another object may
be beyond tau only in passing, rocking as a neighbour falls, and would come back. Write

- S_p for object p's *swept box* in that settling: the smallest box holding its body at every moment
  looked at (:attr:`~physics_mapper.physics.settling.Settling.extent`, every 8 steps, 33 ms);
- E_p(h) for p's *stable envelope* at hypothesis h: the box of its body at h
  (:func:`~physics_mapper.model.extents.body_box`) grown by g_p = max(1, r_p / w) tau
  (:func:`~physics_mapper.model.extents.stable_growth`): no point of a body moves further while its
  jitter stays within tau.

One object of U moving beyond tau makes C unstable, so the rule blames one, u: B_u = {u}, plus every
object whose swept box meets S_u (it touched, or could have touched, u during the settling), plus
every object with some hypothesis h whose E_p(h) meets S_u (at another rank it could have been in
u's way). Each object u of U gives the conflict {(p, C_p) : p in B_u}, with rank sets: u and the
objects whose swept box meets S_u at C_p alone; every other p of B_u at C_p or at any rank h whose
E_p(h) does not meet S_u (there it cannot be in u's way either).

Why it is sound. Take C' containing the conflict, and suppose C' stable: then every object stays
within its stable envelope, so no object at a rank whose envelope misses S_u comes near S_u, while
the objects held at their own rank start where they started in C. u then meets exactly the bodies it
could meet in C, and falls, slides or topples as it did, beyond tau: C' is unstable after all. The
argument takes the objects held at their rank in C, within tau of the poses they had there, to act
on u as they did in C; that is the rule's one assumption, checked on the crowded suite (every
configuration a conflict skipped is checked in full by the tests, and none is valid); so does
sampling the motion every 8 steps. A settling without swept boxes (reused from a memo) blames every
object of the configuration at its rank, which is trivially sound.

Boxes are coarse: a mug turned on a table has a box far wider than its body, and a part rocking in
place sweeps a box that meets every neighbour's envelope a few centimetres away, so each neighbour was
held at its rank though none was ever near it. The *clearance rule* then widens a blamed object's rank
set by distances between bodies (:meth:`~physics_mapper.physics.checker.PhysicsChecker.clearance`,
Bullet's closest points at given poses). Write u_k and p_k for the poses of u and p at look k of the
settling (the start first, the end last, :attr:`~physics_mapper.physics.settling.Settling.path`), and
d_q(k) for how far any point of object q moved from look k to the next: |t_k+1 - t_k| + r_q angle(k,
k+1) (0 after the last). p *stayed clear* of u in C when at every look its body lies more than
d_u(k) + d_p(k) + 1 mm from u's: between two looks neither body can close the gap, so p never touched
u (up to the sampling, as above). Such a p did not act on u, so at any rank h at which it stays clear of
u's path too, body at h more than g_p + d_u(k) + 1 mm from u_k at every look (in a stable C' it stays
within g_p of h), it cannot act on u either: h joins p's rank set, and p leaves the conflict when every
rank does. An object that did not stay clear keeps the rank set the boxes gave. Being finer, the rule
never blames an object the boxes did not; it is not used with the chain rule below.

The assumption fails where a push passes through an object that barely moves: an object far from S_u
then moved u through one held at its rank, and the conflict, leaving it out, may rule out a valid
configuration. The *chain rule* (``Blame(..., chains=True)``) holds at their rank every object
connected to u by swept boxes that meet, and lets through, for every other object, the ranks whose
envelopes miss all of their swept boxes. It learns less from each rejection, so the conflict-directed
search uses it only to search again a group whose candidates ran out with none valid
(:mod:`physics_mapper.search.conflict_directed`).
"""

from __future__ import annotations

import functools
import itertools
import operator
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.extents import body_box, meets_box, stable_growth
from physics_mapper.model.geometry import Pose, pose_displacement
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
    """Assignments no valid configuration holds together (module docstring), sorted by position: the
    rejected configuration's ranks of the conflict's objects.

    ``ranks``, per assignment, every rank of its object under which the conflict holds, its own among
    them (empty: each assignment's rank alone). ``region`` (unstable only) is the swept box of the
    object blamed for moving beyond the threshold: an object whose hypotheses change keeps the
    conflict sound only if it cannot reach it.
    """

    assignments: tuple[Assignment, ...]
    kind: ConflictKind
    region: Region | None = None
    ranks: tuple[frozenset[int], ...] = ()
    #: The assignments' positions (made once: every expansion by the conflict reads them).
    positions: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "positions", tuple(position for position, _ in self.assignments))
        if not self.ranks:
            object.__setattr__(self, "ranks", tuple(frozenset((rank,)) for _, rank in self.assignments))
        elif any(rank not in ranks for (_, rank), ranks in zip(self.assignments, self.ranks, strict=True)):
            raise ValueError("a conflict's rank sets hold its own ranks")

    def holds_in(self, code: Sequence[int]) -> bool:
        """Whether configuration ``code`` (ranks by position) contains the conflict: every object at one
        of its ranks."""
        return all(code[position] in ranks for position, ranks in zip(self.positions, self.ranks, strict=True))

    def renumbered(self, positions: dict[int, int]) -> Conflict:
        """The same conflict with its objects at other positions (``positions``: old -> new), sorted."""
        moved = sorted(
            ((positions[p], rank), ranks) for (p, rank), ranks in zip(self.assignments, self.ranks, strict=True)
        )
        return Conflict(
            tuple(assignment for assignment, _ in moved), self.kind, self.region, tuple(ranks for _, ranks in moved)
        )


#: A callable: metres between the bodies of two objects (positions in a group) at two poses, at most a cap
#: (:meth:`~physics_mapper.physics.checker.PhysicsChecker.clearance`).
Clearance = Callable[[int, Pose, int, Pose, float], float]
#: Metres beyond their travels two bodies must lie apart for the clearance rule to call them apart.
CLEARANCE_MARGIN = 0.001

#: Conflicts one group's search keeps at most (a bit per conflict and hypothesis: 625 kB for 50
#: objects of 10 hypotheses); later ones still direct the expansion of the candidate they came from.
CONFLICT_LIMIT = 10_000


class ConflictStore:
    """The conflicts one group's search knows, in learning order, as bit sets.

    Conflict k is bit k. For each position p and rank r, ``_excluded[p][r]`` holds the conflicts
    that constrain p to ranks without r (index 0 unused): a configuration C contains exactly the conflicts in none of
    its N sets, all known conflicts minus their union (N integer ORs, a few microseconds whatever
    the number of conflicts; a 0/1 matrix gathered by numpy took 25 us per look-up).
    """

    def __init__(self, ranks: Sequence[int]) -> None:
        self._ranks = tuple(ranks)
        # Per position, the ranks a one-assignment conflict rules out alone.
        self._ruled_out: tuple[set[int], ...] = tuple(set() for _ in ranks)
        self._conflicts: list[Conflict] = []
        self._known: set[tuple[tuple[Assignment, ...], tuple[frozenset[int], ...]]] = set()
        self._excluded: list[list[int]] = [[0] * (count + 1) for count in ranks]

    def __len__(self) -> int:
        return len(self._conflicts)

    def __iter__(self) -> Iterator[Conflict]:
        return iter(self._conflicts)

    def rules_out(self, position: int, rank: int) -> bool:
        """Whether a one-assignment conflict rules out the object at ``position`` at ``rank`` alone."""
        return rank in self._ruled_out[position]

    def learn(self, conflict: Conflict) -> bool:
        """Remember ``conflict``; False if it was known already, or :data:`CONFLICT_LIMIT` are kept."""
        key = (conflict.assignments, conflict.ranks)
        if key in self._known or len(self._conflicts) >= CONFLICT_LIMIT:
            return False
        bit = 1 << len(self._conflicts)
        self._known.add(key)
        self._conflicts.append(conflict)
        for position, ranks in zip(conflict.positions, conflict.ranks, strict=True):
            excluded = self._excluded[position]
            for other in range(1, len(excluded)):
                if other not in ranks:
                    excluded[other] |= bit
        if len(conflict.assignments) == 1:
            self._ruled_out[conflict.positions[0]].update(conflict.ranks[0])
        return True

    def excluded_by_rank(self, position: int) -> Sequence[int]:
        """Per rank of the object at ``position`` (index 0 unused), the conflicts (bit k: the k-th learned) it
        resolves there; kept up to date as conflicts are learned (one lookup per rank on the generator's
        hot path)."""
        return self._excluded[position]

    def since(self, count: int) -> list[Conflict]:
        """The conflicts learned after the first ``count`` (conflict k is bit k of the bit sets)."""
        return self._conflicts[count:]

    def live_ranks(self, position: int) -> list[int]:
        """The ranks of the object at ``position`` that no one-assignment conflict rules out, ascending."""
        ruled_out = self._ruled_out[position]
        return [rank for rank in range(1, self._ranks[position] + 1) if rank not in ruled_out]

    def next_rank(self, position: int, rank: int, holding: frozenset[int] = frozenset()) -> int | None:
        """The first rank after ``rank`` of the object at ``position`` that no one-assignment conflict rules
        out and that is not in ``holding`` (a conflict's ranks of that object: there it still holds;
        None: none is left)."""
        ruled_out = self._ruled_out[position]
        for following in range(rank + 1, self._ranks[position] + 1):
            if following not in ruled_out and following not in holding:
                return following
        return None

    def held(self, code: Sequence[int]) -> int:
        """The known conflicts configuration ``code`` contains (bit k: the k-th learned)."""
        if not self._conflicts:
            return 0
        outside = functools.reduce(operator.or_, map(operator.getitem, self._excluded, code))
        return ((1 << len(self._conflicts)) - 1) & ~outside

    def contained(self, code: Sequence[int]) -> Conflict | None:
        """The smallest known conflict that configuration ``code`` contains, the first learned of equal
        ones (None: it resolves every one)."""
        held = (self._conflicts[bit] for bit in bits_of(self.held(code)))
        return min(held, key=lambda conflict: len(conflict.assignments), default=None)


def bits_of(bits: int) -> list[int]:
    """The indices of a bit set's bits, lowest first (conflict k is bit k of a store's bit sets)."""
    found = []
    while bits:
        lowest = bits & -bits
        found.append(lowest.bit_length() - 1)
        bits ^= lowest
    return found


def collision_conflicts(
    code: Sequence[int],
    pair: tuple[int, int],
    positions: dict[int, int],
    table: CollisionTable,
    known: ConflictStore,
    threshold: float,
) -> list[Conflict]:
    """The conflicts of one overlap beyond ``threshold`` metres between bodies ``pair`` (body indices, lower
    first: an object, then an object or a static body; ``positions`` maps the group's object indices to
    their positions).

    Against a static body: {(i, a)}. Between objects i at a and j at b: {i: a, j: R_j}, R_j being the
    ranks of j that overlap i at a deeper than the threshold or are ruled out alone (a known
    one-assignment conflict, or an overlap with a static body), and {i: R_i, j: b} likewise; a
    conflict whose rank set is every rank of its object is the other assignment alone (then no
    configuration holding it is valid).
    """
    first, second = pair
    i = positions[first]
    if second not in positions:
        return [Conflict(((i, code[i]),), "collision")]
    j = positions[second]
    found = []
    for doomed, index, other, other_index in ((i, first, j, second), (j, second, i, first)):
        depths = table.pair_depths(index, code[doomed], other_index)
        overlapping = frozenset(
            rank
            for rank, depth in enumerate(depths, start=1)
            if depth > threshold or known.rules_out(other, rank) or table.static_depth(other_index, rank) > threshold
        )
        if len(overlapping) == len(depths):
            return [Conflict(((doomed, code[doomed]),), "collision")]
        ranks = {doomed: frozenset((code[doomed],)), other: overlapping}
        found.append(Conflict(((i, code[i]), (j, code[j])), "collision", ranks=(ranks[i], ranks[j])))
    return found


class Blame:
    """The blame rule (module docstring) for one group: its objects' stable envelopes.

    The envelopes, every hypothesis's body box grown by g_p (metres), are made on first use. With a
    ``clearance`` (metres between two objects' bodies at given poses), the *clearance rule* widens what the
    boxes blame. With ``chains``, the *chain rule*: the objects held at their rank are every object connected to the one
    that moved by swept boxes that meet, not only those whose swept box meets its own (module docstring).
    """

    def __init__(
        self,
        shapes: Sequence[ObjectShape],
        hypotheses: Sequence[RankedHypotheses],
        params: SearchParams,
        chains: bool = False,
        clearance: Clearance | None = None,
    ) -> None:
        self.params = params
        self.chains = chains
        self.clearance = clearance
        self.shapes = tuple(shapes)
        self.hypotheses = tuple(hypotheses)
        self.threshold = params.jitter_threshold
        self.radii = tuple(object_radius(shape) for shape in self.shapes)
        self.growth = tuple(stable_growth(r, params.jitter_threshold, params.angular_weight) for r in self.radii)
        self._boxes: tuple[tuple[FloatArray, FloatArray], ...] | None = None
        self._envelopes: tuple[tuple[FloatArray, FloatArray], ...] | None = None
        # Every object's envelopes stacked (sum of M x 3 corners) and the position each belongs to.
        self._stacked: tuple[FloatArray, FloatArray, NDArray[np.intp]] | None = None

    def chained(self) -> Blame:
        """The same group's chain rule (its envelopes made once for both)."""
        blame = Blame(self.shapes, self.hypotheses, self.params, chains=True, clearance=self.clearance)
        blame._boxes, blame._envelopes, blame._stacked = self._boxes, self._envelopes, self._stacked
        return blame

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
        moved = unstable_objects(settling, self.threshold)
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
            blamed = self._blamed(u, code, low, high)
            if self.clearance is not None and not self.chains and settling.path is not None:
                blamed = self._cleared(u, code, settling.path, blamed)
            found.append(Conflict(tuple((p, code[p]) for p in blamed), "unstable", region, tuple(blamed.values())))
        return sorted(found, key=lambda conflict: len(conflict.assignments))

    def _blamed(self, moved: int, code: Sequence[int], low: FloatArray, high: FloatArray) -> dict[int, frozenset[int]]:
        """The rank sets of the blamed objects, in position order (``low``, ``high``: the swept boxes, N x 3):
        the object that moved and every object whose swept box meets its swept box (with chains: every
        object connected to it by swept boxes that meet) at their own rank; every other object with a
        stable envelope that meets one of those swept boxes at its own rank or any rank whose envelope
        meets none."""
        touches = self._chain(moved, low, high) if self.chains else meets_box(low, high, low[moved], high[moved])
        touches[moved] = True
        env_low, env_high, owners = self._stacked_envelopes()
        reaching = np.zeros(len(owners), dtype=bool)
        for p in np.nonzero(touches)[0] if self.chains else (moved,):
            reaching |= meets_box(env_low, env_high, low[p], high[p])
        blamed: dict[int, frozenset[int]] = {}
        for p in sorted({*np.nonzero(touches)[0].tolist(), *owners[reaching].tolist()}):
            if touches[p]:
                blamed[p] = frozenset((code[p],))
            else:
                in_way = reaching[owners == p]  # by rank
                blamed[p] = frozenset(rank for rank in range(1, len(in_way) + 1) if not in_way[rank - 1]) | {code[p]}
        return blamed

    def _cleared(
        self, moved: int, code: Sequence[int], path: tuple[tuple[Pose, ...], ...], blamed: dict[int, frozenset[int]]
    ) -> dict[int, frozenset[int]]:
        """The blamed objects' rank sets widened by the clearance rule (module docstring), ``path`` the
        settling's poses at its looks: an object that stayed clear of the one that moved, at each rank that
        stays clear of it too; one clear at every rank leaves the conflict."""
        u = moved
        u_path = [poses[u] for poses in path]
        u_steps = self._steps(u, u_path)
        cleared: dict[int, frozenset[int]] = {}
        for p, ranks in blamed.items():
            ranked = self.hypotheses[p]
            p_path = [poses[p] for poses in path]
            if p == u or not self._apart(
                p, p_path, u, u_path, list(map(operator.add, u_steps, self._steps(p, p_path)))
            ):
                cleared[p] = ranks
                continue
            reach = [self.growth[p] + step for step in u_steps]
            widened = ranks | {
                rank
                for rank in range(1, len(ranked) + 1)
                if rank not in ranks
                and (ranked.is_absent(rank) or self._apart(p, [ranked.pose(rank)] * len(u_path), u, u_path, reach))
            }
            if len(widened) < len(ranked):
                cleared[p] = widened
        return cleared

    def _steps(self, p: int, poses: Sequence[Pose]) -> list[float]:
        """How far (m) any point of object ``p`` moved from each look to the next (``poses``: its pose at each
        look): the translation plus its bounding radius times the angle turned; 0 after the last look."""
        # pose_displacement weighs the angle by the radius: a point at that distance turns that far.
        return [*(pose_displacement(a, b, self.radii[p]) for a, b in itertools.pairwise(poses)), 0.0]

    def _apart(self, p: int, p_path: Sequence[Pose], u: int, u_path: Sequence[Pose], gaps: Sequence[float]) -> bool:
        """Whether object ``p`` (at ``p_path``'s poses) and ``u`` (at ``u_path``'s) lie more than ``gaps`` (+ the
        margin) apart at every look."""
        assert self.clearance is not None
        for p_pose, u_pose, gap in zip(p_path, u_path, gaps, strict=True):
            cap = gap + CLEARANCE_MARGIN
            if self.clearance(p, p_pose, u, u_pose, cap) < cap:
                return False
        return True

    @staticmethod
    def _chain(moved: int, low: FloatArray, high: FloatArray) -> NDArray[np.bool_]:
        """The objects connected to ``moved`` by swept boxes (``low``, ``high``: N x 3) that meet."""
        reached = np.zeros(len(low), dtype=bool)
        reached[moved] = True
        frontier = [moved]
        while frontier:
            p = frontier.pop()
            found = meets_box(low, high, low[p], high[p]) & ~reached
            reached |= found
            frontier.extend(np.nonzero(found)[0].tolist())
        return reached

    def reaches(self, position: int, region: Region) -> bool:
        """Whether some stable envelope of the object at ``position`` meets ``region``."""
        env_low, env_high = self.envelopes[position]
        low, high = np.asarray(region[0]), np.asarray(region[1])
        return bool(np.any(meets_box(env_low, env_high, low, high)))


def unstable_objects(settling: Settling, threshold: float) -> list[int]:
    """The objects (indices into the settling's) it shows moved beyond ``threshold``: those it stopped early
    for (:attr:`~physics_mapper.physics.settling.Settling.beyond`), else every one with J_i beyond it."""
    if settling.stopped == "beyond_threshold" and settling.beyond:
        return list(settling.beyond)
    return [p for p, jitter in enumerate(settling.jitters) if jitter > threshold]


def body_boxes(shape: ObjectShape, ranked: RankedHypotheses) -> tuple[FloatArray, FloatArray]:
    """(M x 3, M x 3): each hypothesis's body box (ranked order), metres."""
    boxes = [body_box(shape, hypothesis.pose) for hypothesis in ranked.hypotheses]
    return np.array([low for low, _ in boxes]), np.array([high for _, high in boxes])

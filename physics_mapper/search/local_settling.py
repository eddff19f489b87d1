"""Local settling: Rule 2 of a candidate simulates only what changed and its neighbours, the rest held fixed.

Neighbours. Objects p and q of a group are neighbours when some stable envelope of p meets some
stable envelope of q (:class:`~physics_mapper.search.conflicts.Blame`): in a stable configuration,
whatever their ranks, bodies that are not neighbours never touch.

Contexts. The *context* of object o in configuration C is the ranks, in C, of o and its neighbours.
Whenever a settling simulates o with every neighbour placed (simulated, or held fixed at its
hypothesis) and o stays within the jitter threshold, o's context is recorded as *stable*.

The rule. For a candidate C, the *unsettled* objects U are those whose context in C was never
recorded stable: the objects whose hypotheses differ from every settled configuration around them,
and those they can touch (a neighbour's context holds the changed rank too). Rule 2 simulates L = U,
with U's neighbours outside U held fixed at their hypotheses and every other object parked. An object
outside U is in a context seen stable, next to the same bodies at the same hypotheses. If an object of L moves
beyond the threshold, C is unstable (its conflict comes from that settling); else every object
either was just seen stable or is in a context seen stable, and C is *presumed valid*: it gets one
full settling of its group, which confirms it (and gives its J), or refutes it, and then the search
learns the conflict and drops the contexts of the objects that moved. A candidate with every object
unsettled (the first ones) is tried as a whole; one with no object unsettled gets the full settling
at once. The local verdict is a judgement; a refuted presumption costs one settling; agreement of
local and full verdicts is measured on the crowded suite (BENCHMARKS.md).

Meshes. A mesh held fixed (massless) beside a neighbour does not act on it as the same mesh resting
there, so in a group holding a mesh the unsettled objects' neighbours are simulated too, and the ring
of objects around them held fixed; the settlings run Rule 2's solver iterations.

Why this is cheap: the contexts are the memo. In a crowded group, a candidate differs from the
settled ones in the few objects of a conflict, so L is those objects and their neighbours, a handful
of bodies, whatever N is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from physics_mapper.model.extents import FloatArray, meets_boxes
from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Mesh
from physics_mapper.physics.settling import PositionRange, Settling
from physics_mapper.search.conflicts import Blame

#: (position, ranks of the object and its neighbours in position order).
Context = tuple[int, tuple[int, ...]]


@dataclass(frozen=True)
class LocalPlan:
    """A local settling: positions ``simulated`` and positions ``fixed`` at their hypotheses."""

    simulated: tuple[int, ...]
    fixed: tuple[int, ...]


class LocalSettling:
    """One group's neighbours and stable contexts (module docstring)."""

    def __init__(self, blame: Blame) -> None:
        self.blame = blame
        #: Whether the group holds a mesh: a mesh held fixed beside a neighbour does not act on it as the
        #: same mesh resting there (the shipped mesh scenes: 20 of 660 local unstable verdicts were wrong
        #: with the neighbours held fixed), so there the neighbours are simulated too, a ring further out held.
        self.holds_meshes = any(isinstance(shape, Mesh) for shape in blame.shapes)
        self._neighbours: tuple[tuple[int, ...], ...] | None = None
        self._contexts: tuple[tuple[int, ...], ...] | None = None
        self._stable: set[Context] = set()

    @property
    def neighbours(self) -> tuple[tuple[int, ...], ...]:
        """Per position, its neighbours' positions (made on first use)."""
        if self._neighbours is None:
            self._neighbours = neighbours(self.blame)
        return self._neighbours

    @property
    def context_positions(self) -> tuple[tuple[int, ...], ...]:
        """Per position, it and its neighbours in position order: whose ranks make its context (made on first use)."""
        if self._contexts is None:
            self._contexts = tuple(tuple(sorted((p, *around))) for p, around in enumerate(self.neighbours))
        return self._contexts

    def context(self, position: int, code: Sequence[int]) -> Context:
        return position, tuple(map(code.__getitem__, self.context_positions[position]))

    def plan(self, code: Sequence[int]) -> LocalPlan | None:
        """The settling that tries ``code``: its unsettled objects (and, in a group holding a mesh, their
        neighbours), every object when none was settled yet (None: every context was seen stable)."""
        unsettled = {p for p in range(len(code)) if self.context(p, code) not in self._stable}
        if not unsettled:
            return None
        if self.holds_meshes:
            unsettled |= self._around(unsettled)
        return LocalPlan(tuple(sorted(unsettled)), tuple(sorted(self._around(unsettled))))

    def _around(self, positions: set[int]) -> set[int]:
        """The neighbours of ``positions`` that are not among them."""
        return set().union(*(self.neighbours[p] for p in positions)) - positions

    def observe(self, code: Sequence[int], simulated: Sequence[int], jitters: Sequence[float]) -> None:
        """Record the contexts of the ``simulated`` positions that stayed within the threshold."""
        threshold = self.blame.threshold
        for position, jitter in zip(simulated, jitters, strict=True):
            if jitter <= threshold:
                self._stable.add(self.context(position, code))

    def forget(self, code: Sequence[int], positions: Sequence[int]) -> None:
        """Drop the contexts of ``positions`` in ``code`` (a full settling moved them beyond the threshold)."""
        for position in positions:
            self._stable.discard(self.context(position, code))

    def kept_from(self, old: LocalSettling, moved: dict[int, int], changed: set[int]) -> int:
        """Take over ``old``'s stable contexts whose objects all kept their hypotheses and their
        neighbours (``moved``: old position -> position here; ``changed``: old positions whose
        hypotheses changed); how many."""
        kept = 0
        for position, ranks in old._stable:
            around = old.context_positions[position]
            if any(p in changed or p not in moved for p in around):
                continue
            here = moved[position]
            positions = self.context_positions[here]
            if tuple(sorted(moved[p] for p in around)) != positions:
                continue
            by_position = dict(zip((moved[p] for p in around), ranks, strict=True))
            self._stable.add((here, tuple(by_position[p] for p in positions)))
            kept += 1
        return kept

    def whole(self, plan: LocalPlan, local: Settling, code: Sequence[int]) -> Settling:
        """A local settling of configuration ``code`` as one of the whole group: objects not simulated
        stayed at their hypotheses (J_i = 0, their body's box there as their extent)."""
        if len(plan.simulated) == len(code):
            return local
        start = [ranked.pose(rank) for ranked, rank in zip(self.blame.hypotheses, code, strict=True)]
        settled, jitters = list(start), [0.0] * len(start)
        boxes = self.blame.boxes
        extent = [_box((boxes[p][0][rank - 1], boxes[p][1][rank - 1])) for p, rank in enumerate(code)]
        for index, position in enumerate(plan.simulated):
            settled[position] = local.settled_poses[index]
            jitters[position] = local.jitters[index]
            if local.extent is not None:
                extent[position] = local.extent[index]
        return Settling(
            tuple(settled),
            tuple(jitters),
            local.stopped,
            local.steps,
            local.steps_total,
            tuple(extent),
            local.solver_iterations,
            tuple(plan.simulated[index] for index in local.beyond),
            None if local.path is None else _whole_path(local.path, start, plan.simulated),
        )


def _whole_path(
    path: tuple[tuple[Pose, ...], ...], start: list[Pose], simulated: Sequence[int]
) -> tuple[tuple[Pose, ...], ...]:
    """A local settling's poses at each look as the whole group's: objects not simulated stay at ``start``."""
    whole = []
    for poses in path:
        look = list(start)
        for index, position in enumerate(simulated):
            look[position] = poses[index]
        whole.append(tuple(look))
    return tuple(whole)


def _box(box: tuple[FloatArray, FloatArray]) -> PositionRange:
    low, high = box
    return (float(low[0]), float(low[1]), float(low[2])), (float(high[0]), float(high[1]), float(high[2]))


def neighbours(blame: Blame) -> tuple[tuple[int, ...], ...]:
    """Per object, the objects one of whose stable envelopes meets one of its own."""
    envelopes = blame.envelopes
    low = np.array([env_low.min(axis=0) for env_low, _ in envelopes])
    high = np.array([env_high.max(axis=0) for _, env_high in envelopes])
    near = meets_boxes(low, high, low, high)
    found: list[set[int]] = [set() for _ in envelopes]
    for p, q in zip(*np.nonzero(np.triu(near, k=1)), strict=True):
        (low_p, high_p), (low_q, high_q) = envelopes[p], envelopes[q]
        if np.any(meets_boxes(low_p, high_p, low_q, high_q)):
            found[int(p)].add(int(q))
            found[int(q)].add(int(p))
    return tuple(tuple(sorted(members)) for members in found)

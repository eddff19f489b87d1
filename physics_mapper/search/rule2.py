"""Rule 2 parts: the settling a collision-free candidate is judged by.

:class:`FullSettling` settles every object of the search (the others parked) for ``settle_time`` under
gravity, stopping early by :func:`~physics_mapper.physics.settling.early_exit_rule` (with its
:data:`~physics_mapper.physics.settling.REST_SHARE`), imported from the physics, which owns it.
Observers passed in see each settling the engine finished (a grouped search's escape guard, which may
raise :class:`~physics_mapper.search.grouped.Escape`).

:class:`MemoisedSettling` serves a settling from a :class:`SettleMemo` when it has one. A memo holds a
group's settlings by sub-code, up to its share of :data:`SETTLE_MEMO_LIMIT`, for given hypotheses and
physics parameters (settle_time, angular_weight, jitter_threshold, settle_exit): a group searched again
with the same (e.g. after a change of T) reuses them instead of simulating; anything else starts an
empty memo.
"""

from __future__ import annotations

from array import array
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Mesh, Scene, SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.settling import PartialSettling, SettleStop, Settling, early_exit_rule
from physics_mapper.search.results import Code, Counters, SearchStats

#: The residual ((m/s)^2: 3.2 mm/s) at which Bullet's solver ends a step's iterations in the conflict-directed
#: search's own Rule 2 settlings (:class:`FullSettling`'s ``solver_residual``) of a group of boxes, cylinders
#: and spheres; pybullet's is 1e-7 (``world.SOLVER_RESIDUAL``), which the paper's searches keep. Contacts at
#: rest converge in a few iterations: a bin of 50 boxes settles 40-50 % faster. Of 811 Rule 2 verdicts of
#: such groups (the crowded suite's searches, bins of 24 boxes and cylinders in two layers) one changed, a
#: jitter of 20.1 mm against a threshold of 20; of 633 with meshes five did, a mug resting 8 mm from where it
#: stood tipping (even at 1e-6), so a group holding a mesh, or in a scene with a static mesh, keeps
#: pybullet's. So do the trials, whose instability is believed: at their 15 iterations it turned 8 of 106
#: stable configurations of 24 cylinders in two layers unstable, 3 without it (BENCHMARKS.md, "Crowded
#: scenes", round 12).
PRIMITIVE_SOLVER_RESIDUAL = 1e-5
#: Settlings a grouped search remembers (each group a share in proportion to its objects), a few hundred bytes each.
SETTLE_MEMO_LIMIT = 5_000

#: The parameters a settling's outcome depends on (a memo is valid while they are unchanged).
PhysicsKey = tuple[float, float, float, str]

#: Sees each settling the engine finished, with the candidate's code (it may raise to stop the search).
SettlingObserver = Callable[[Code, Settling], None]


def physics_key(params: SearchParams) -> PhysicsKey:
    return (params.settle_time, params.angular_weight, params.jitter_threshold, params.settle_exit)


def solver_residual(scene: Scene, objects: Sequence[int]) -> float | None:
    """The solver residual ((m/s)^2) of the conflict-directed search's Rule 2 settlings of a group of
    ``objects`` (scene indices) in ``scene``: :data:`PRIMITIVE_SOLVER_RESIDUAL` unless one of them or a static
    body is a mesh (None: the world's)."""
    shapes = [scene.objects[i].shape for i in objects] + [body.shape for body in scene.static]
    return None if any(isinstance(shape, Mesh) for shape in shapes) else PRIMITIVE_SOLVER_RESIDUAL


class StepCounts:
    """The simulation steps of the settlings the engine finished: run, and spared by early exits."""

    def __init__(self) -> None:
        self.run = 0
        self.saved = 0

    def add(self, settling: Settling) -> None:
        self.run += settling.steps
        self.saved += settling.steps_total - settling.steps

    def count_into(self, stats: SearchStats) -> None:
        stats.settle_steps += self.run
        stats.settle_steps_saved += self.saved


@dataclass(eq=False)
class FullSettling:
    """Rule 2's own settling of every object of ``objects`` (scene indices); counts the settlings finished
    and their simulation ``steps``.

    ``moving``: a settling no fallback reports also stops once an object is far off and still moving;
    ``track_reach``: settlings record where objects went (an escape guard needs it); ``solver_residual``:
    the residual ((m/s)^2) that ends each step's solver iterations (None: the world's, pybullet's).
    """

    checker: PhysicsChecker
    objects: tuple[int, ...]
    params: SearchParams
    moving: bool = False
    track_reach: bool = False
    observers: Sequence[SettlingObserver] = ()
    solver_residual: float | None = None
    settlings: int = field(default=0, init=False)
    steps: StepCounts = field(default_factory=StepCounts, init=False)

    def settle(
        self, code: Code, poses: tuple[Pose, ...], stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling:
        params = self.params
        outcome = self.checker.settle(
            poses,
            params.settle_time,
            params.angular_weight,
            stop_at,
            objects=self.objects,
            early_exit=early_exit_rule(params, complete=complete, moving=self.moving),
            track_reach=self.track_reach,
            solver_residual=self.solver_residual,
        )
        return self.finished(code, outcome)

    def resume(
        self, code: Code, poses: tuple[Pose, ...], partial: PartialSettling, stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling:
        return self.finished(code, self.checker.resume_settling(partial, stop_at))

    def finished(self, code: Code, outcome: Settling | PartialSettling) -> Settling | PartialSettling:
        """Count a settling the engine finished and show it to the observers."""
        if isinstance(outcome, Settling):
            self.settlings += 1
            self.steps.add(outcome)
            for observe in self.observers:
                observe(code, outcome)
        return outcome

    def count_into(self, stats: SearchStats) -> None:
        self.steps.count_into(stats)

    def counters(self) -> Counters:
        return {}  # Rule 2's own settlings only: the steps every search counts tell them


class _FlatSettling(NamedTuple):
    """A settling in a few hundred bytes: its numbers in one array (which the garbage collector skips)."""

    stopped: SettleStop | None
    steps: int
    steps_total: int
    numbers: array[float]  # per object its jitter, then per object position x, y, z and orientation x, y, z, w

    @classmethod
    def of(cls, settling: Settling) -> _FlatSettling:
        numbers = array("d", settling.jitters)
        for pose in settling.settled_poses:
            numbers.extend((*pose.position, *pose.orientation))
        return cls(settling.stopped, settling.steps, settling.steps_total, numbers)

    def settling(self) -> Settling:
        n = self.numbers
        count = len(n) // 8
        poses = tuple(
            Pose((n[i], n[i + 1], n[i + 2]), (n[i + 3], n[i + 4], n[i + 5], n[i + 6])) for i in range(count, len(n), 7)
        )
        return Settling(poses, tuple(n[:count]), self.stopped, self.steps, self.steps_total)


class SettleMemo:
    """Settlings of one group's sub-configurations, valid for given hypotheses and physics parameters.

    A settling stopped beyond the jitter threshold does not serve a candidate that needs a complete one.
    Settlings are kept as numbers only, so a full memo costs no garbage-collection pauses.
    """

    def __init__(self, hypotheses: tuple[RankedHypotheses, ...], key: PhysicsKey, limit: int) -> None:
        self.hypotheses = hypotheses
        self.key = key
        self.limit = limit
        self._settlings: dict[Code, _FlatSettling] = {}

    def serves(self, hypotheses: tuple[RankedHypotheses, ...], key: PhysicsKey) -> bool:
        return self.hypotheses == hypotheses and self.key == key

    def get(self, code: Code, complete: bool) -> Settling | None:
        flat = self._settlings.get(code)
        if flat is None or (complete and flat.stopped == "beyond_threshold"):
            return None
        return flat.settling()

    def put(self, code: Code, settling: Settling) -> None:
        if code not in self._settlings and len(self._settlings) >= self.limit and self._settlings:
            del self._settlings[next(iter(self._settlings))]  # the oldest
        self._settlings[code] = _FlatSettling.of(settling)


class MemoisedSettling:
    """Rule 2's own settling (``settling``), served from ``memo`` when it holds one (``memo_hits``), every
    settling finished remembered."""

    def __init__(self, memo: SettleMemo, settling: FullSettling) -> None:
        self.memo = memo
        self.settling = settling
        self.memo_hits = 0

    def known(self, code: Code, complete: bool) -> Settling | None:
        """The memo's settling of ``code`` (None: none serves), counted as a memo hit."""
        memoised = self.memo.get(code, complete)
        if memoised is not None:
            self.memo_hits += 1
        return memoised

    def settle(
        self, code: Code, poses: tuple[Pose, ...], stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling:
        memoised = self.known(code, complete)
        if memoised is not None:
            return memoised
        return self._remembered(code, self.settling.settle(code, poses, stop_at, complete))

    def resume(
        self, code: Code, poses: tuple[Pose, ...], partial: PartialSettling, stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling:
        return self._remembered(code, self.settling.resume(code, poses, partial, stop_at, complete))

    def _remembered(self, code: Code, outcome: Settling | PartialSettling) -> Settling | PartialSettling:
        if isinstance(outcome, Settling):
            self.memo.put(code, outcome)
        return outcome

    @property
    def settlings(self) -> int:
        """Settlings the engine finished (memo hits not counted)."""
        return self.settling.settlings

    def count_into(self, stats: SearchStats) -> None:
        stats.memo_hits += self.memo_hits
        self.settling.count_into(stats)

    def counters(self) -> Counters:
        return self.settling.counters()

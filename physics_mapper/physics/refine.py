"""``fallback: refine``: a physically plausible map when no configuration is valid.

The search can only choose among the hypotheses it is given. When every combination breaks a
rule, the refinement repairs the most probable configuration instead of rejecting it:

1. **Start.** Each object starts at the weighted mean position of its poses lying within
   ``refine_mean_radius`` metres of its most likely pose, with that pose's orientation
   (:func:`refinement_start`). Orientations are not averaged: the mean of two symmetric readings of
   a box is a box turned half-way. Which objects start (the search's live root, with the objects
   another rests on put back) is :mod:`physics_mapper.physics.support`'s rule; an object it starts
   at its most likely pose though *absent* ranks first (a tentative instance more likely there than
   not) starts at the mean as the others do: at its most likely pose alone, where an estimator's
   pose 3 cm off ranked first, a box came to rest beside where its other poses put it, overlapping a
   neighbour, and the first snapshot of a bin had no valid map.

2. **Depenetration, with as little motion as possible.** Positions x_i (metres) move,
   orientations stay. Each iteration lists the pairs of bodies closer than a margin (an object
   and another object or a static body), each with Bullet's closest points: signed distance
   d_k (negative for an overlap) and unit normal n_k
   (:meth:`~physics_mapper.physics.checker.PhysicsChecker.proximities`), and solves

       minimise    sum_i |x_i + dx_i - s_i|^2                    (s_i: object i's start)
       subject to  d_k + n_k . (dx_a - dx_b) >= 0   for every listed pair (a, b); dx = 0 for statics,

   the contact distances linearised at the current positions, as a least-distance program
   (Lawson and Hanson, *Solving Least Squares Problems*, 1974, ch. 23: one non-negative least
   squares problem, scipy's ``nnls``). The objective measures from the start, not from the
   current positions, so the estimate keeps pulling: an object pushed out comes back as far as
   the others let it. **Speed cap:** the step is scaled down so that no object moves more than
   ``refine_max_speed * TIME_STEP`` metres per iteration (4.2 mm at the default 1 m/s), which
   also keeps objects from tunnelling through thin bodies. Objects are moved kinematically, at
   rest, so the depenetration gives them no velocity at all. It stops when no pair overlaps by
   more than :data:`OVERLAP_TOLERANCE` (converged), after :data:`MAX_ITERATIONS`, or once it has
   *stalled*: :data:`STALL_ITERATIONS` least-distance steps in a row left the summed overlap of
   all pairs no lower than its lowest so far (by :data:`OVERLAP_TOLERANCE`). Closest points of
   concave bodies made of convex parts can contradict each other from one iteration to the next
   (a mug's handle hooked through another's): 24 mugs in two layers, packed, came from 228 mm
   of summed overlap to 9.1 mm, two pairs, in 30 iterations, and stayed there for the other 210,
   a quarter of a second. The settling, speeds capped, resolves what is left.

   **Escape.** Pairwise closest points describe each body alone, so an object deep inside
   static bodies that touch each other (a ball below the floor and inside a block standing on
   it) gets contradictory constraints: no translation meets them. Then every object overlapping
   a static body leaves the static bodies along the shortest of :data:`ESCAPE_DIRECTIONS`,
   found by moving it out in steps of the speed cap along all of them at once (upwards first
   on a tie) and bisecting the last step down to :data:`OVERLAP_TOLERANCE`; each step counts
   as an iteration.

3. **Settling.** From rest at the depenetrated poses, ``settle_time`` seconds under gravity,
   each object's linear speed capped at ``refine_max_speed`` after every simulation step
   (within a step gravity adds at most 0.04 m/s), so that an overlap the depenetration left
   (not converged) is not resolved by Bullet throwing the bodies apart. It stops once every object
   is at rest (``settle_exit: early``, as a fallback's settling in the search:
   :func:`~physics_mapper.physics.settling.early_exit_rule` with ``complete``). Bullet's solver runs
   :data:`SETTLING_SOLVER_ITERATIONS` iterations per step here, a fifth of Rule 2's: the map needs
   resting contacts, not Rule 2's verdict, and the settling is most of the refinement's cost.

The map is the settled poses; each object's J_i is measured from its most likely hypothesis.
Only the given objects take part (a subset of the scene's, e.g. one interaction group); the
checker's other objects stay parked, far from everything. :class:`Refinement` is resumable: it
stops at a deadline and goes on where it stopped, as the search does; stopped within its settling, its map
so far is the depenetrated poses (:meth:`Refinement.so_far`, ``settled`` False).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.geometry import Pose, Vector3, pose_displacement
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.collision import Proximity
from physics_mapper.physics.settling import PartialSettling, early_exit_rule
from physics_mapper.physics.world import TIME_STEP

FloatArray = NDArray[np.float64]

#: Metres of overlap left at which the depenetration has converged: far below any sensible
#: ``penetration_threshold``, and resolved by the settling at negligible speed.
OVERLAP_TOLERANCE = 1e-4
#: Depenetration iterations at most: one simulated second of motion at the speed cap.
MAX_ITERATIONS = 240
#: Least-distance steps in a row without a new lowest summed overlap that end the depenetration as
#: stalled (the module docstring). At the speed cap every object can move 4.2 mm an iteration, so a
#: depenetration that makes progress shows it well within this many.
STALL_ITERATIONS = 20
#: Iterations of Bullet's constraint solver per step in the refinement's settling: Bullet's own
#: default, not pybullet's 50 that Rule 2 uses. On 50 touching cubes the settling costs 0.8 ms a step
#: instead of 2.3 ms, and the maps lie within 2.5 mm of the 50-iteration ones, 0.17 mm or less at the
#: median (BENCHMARKS.md, "`fallback: refine` on 50 touching cubes").
SETTLING_SOLVER_ITERATIONS = 10


def _escape_directions() -> tuple[Vector3, ...]:
    """The 26 unit vectors towards the neighbours of a cell in a 3 x 3 x 3 grid, upwards first."""
    grid = [v for v in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(v)]
    grid.sort(key=lambda v: (-v[2], sum(abs(c) for c in v), v))
    return tuple((x / math.hypot(x, y, z), y / math.hypot(x, y, z), z / math.hypot(x, y, z)) for x, y, z in grid)


#: Directions along which an object stuck in static bodies leaves them (the module docstring).
ESCAPE_DIRECTIONS = _escape_directions()


def refinement_start(hypotheses: RankedHypotheses, radius: float) -> Pose:
    """Where the refinement starts an object: its poses' weighted mean position, most likely pose's orientation.

    The mean is over the pose hypotheses (not *absent*) whose positions lie within ``radius`` metres of the
    most likely pose's (always including it), weighted by their weights: sum_j w_j p_j / sum_j w_j.
    """
    ranks = hypotheses.pose_ranks()
    positions = np.array([hypotheses.pose(rank).position for rank in ranks], dtype=float)
    weights = np.array([hypotheses.weight(rank) for rank in ranks], dtype=float)
    near = np.linalg.norm(positions - positions[0], axis=1) <= radius
    near[0] = True
    mean = weights[near] @ positions[near] / weights[near].sum()
    return Pose((float(mean[0]), float(mean[1]), float(mean[2])), hypotheses.pose(ranks[0]).orientation)


@dataclass(frozen=True)
class RefinedMap:
    """A refinement of ``objects`` (scene indices); every pose tuple is in that order.

    ``start_poses``: where it started; ``depenetrated_poses``: after the depenetration;
    ``settled_poses``: the map. ``jitters``: each object's J_i from its most likely hypothesis
    to the map (metres + ``angular_weight`` x radians). ``iterations``: depenetration
    iterations; ``converged``: whether they removed every overlap (to :data:`OVERLAP_TOLERANCE`);
    ``initial_overlap`` and ``remaining_overlap``: the deepest overlap, metres, at the start and
    after the depenetration. ``settled``: False for the map so far of a refinement a deadline stopped in its
    settling (:meth:`Refinement.so_far`): ``settled_poses`` are then the depenetrated ones.
    """

    objects: tuple[int, ...]
    start_poses: tuple[Pose, ...]
    depenetrated_poses: tuple[Pose, ...]
    settled_poses: tuple[Pose, ...]
    jitters: tuple[float, ...]
    iterations: int
    converged: bool
    initial_overlap: float
    remaining_overlap: float
    settled: bool = True

    @property
    def total_jitter(self) -> float:
        """J, the sum of the per-object jitters."""
        return sum(self.jitters)


def _deepest_overlap(proximities: Sequence[Proximity]) -> float:
    """The deepest overlap among the pairs, metres (0 when none overlaps)."""
    return max([0.0, *(-p.distance for p in proximities)])


def _summed_overlap(proximities: Sequence[Proximity]) -> float:
    """The overlaps of all pairs added up, metres."""
    return sum(max(0.0, -p.distance) for p in proximities)


def _stuck_in_statics(proximities: Sequence[Proximity]) -> list[int]:
    """The objects (scene indices, sorted) overlapping a static body by more than :data:`OVERLAP_TOLERANCE`."""
    return sorted({p.first for p in proximities if p.second is None and -p.distance > OVERLAP_TOLERANCE})


def load_solver() -> None:
    """Import the solver (scipy) now: about 0.2 s and 40 MB the first time, which is why it is not
    imported with this module; a search that may refine calls this before its deadline starts."""
    import scipy.optimize  # noqa: F401


def _least_distance(constraints: FloatArray, bounds: FloatArray) -> FloatArray | None:
    """The z of least norm with ``constraints @ z >= bounds``, or None when there is none.

    Lawson and Hanson's least-distance programming: with E = [G^T; h^T] and f = (0, ..., 0, 1),
    the non-negative least squares solution u of E u ~ f has residual r = E u - f; the
    constraints are infeasible iff r = 0, and otherwise z = -r[:n] / r[n].
    """
    from scipy.optimize import nnls  # here, not at the top: see load_solver

    rows, columns = constraints.shape
    matrix = np.vstack([constraints.T, bounds[None, :]])
    target = np.zeros(columns + 1)
    target[-1] = 1.0
    try:
        multipliers, _ = nnls(matrix, target, maxiter=10 * (rows + columns + 1))
    except RuntimeError:  # no convergence: treated as no solution
        return None
    residual = matrix @ multipliers - target
    if residual[-1] > -1e-12:
        return None
    solution: FloatArray = -residual[:-1] / residual[-1]
    return solution


def _step(proximities: Sequence[Proximity], slots: dict[int, int], offsets: FloatArray) -> FloatArray | None:
    """The displacement dx (k x 3, metres) to the nearest point meeting the linearised constraints.

    ``slots`` maps a scene index to its row in ``offsets``, the objects' current positions
    minus their starts (k x 3). Solves min |offsets + dx|^2 subject to
    d + n . (dx_a - dx_b) >= 0, as a least-distance program in z = offsets + dx.
    """
    count = len(offsets)
    constraints = np.zeros((len(proximities), 3 * count))
    bounds = np.zeros(len(proximities))
    for row, proximity in enumerate(proximities):
        first = slots[proximity.first]
        constraints[row, 3 * first : 3 * first + 3] = proximity.normal
        if proximity.second is not None:
            second = slots[proximity.second]
            constraints[row, 3 * second : 3 * second + 3] = np.negative(proximity.normal)
        bounds[row] = -proximity.distance
    # n . (dx_a - dx_b) >= -d with dx = z - offsets:  G z >= -d + G offsets.
    flat_offsets = offsets.ravel()
    solution = _least_distance(constraints, bounds + constraints @ flat_offsets)
    if solution is None:
        return None
    step: FloatArray = (solution - flat_offsets).reshape(count, 3)
    return step


class Refinement:
    """The refinement of ``objects`` (scene indices) of ``checker``'s scene, resumable (see the module docstring).

    ``start`` are the objects' starting poses and ``reference`` their most likely hypotheses
    (J_i is measured from them), both in the order of ``objects``. ``params`` gives
    ``settle_time``, ``angular_weight`` and ``refine_max_speed``; ``solver_iterations`` the
    settling's constraint solver iterations per step. :meth:`run` may be called again after it
    stopped at a deadline; it goes on where it stopped.
    """

    def __init__(
        self,
        checker: PhysicsChecker,
        objects: Sequence[int],
        start: Sequence[Pose],
        reference: Sequence[Pose],
        params: SearchParams,
        solver_iterations: int = SETTLING_SOLVER_ITERATIONS,
    ) -> None:
        if not len(objects) == len(start) == len(reference):
            raise ValueError(f"{len(objects)} objects, {len(start)} starts, {len(reference)} references")
        self.checker = checker
        self.objects = tuple(objects)
        self.start = tuple(start)
        self.reference = tuple(reference)
        self.params = params
        self.solver_iterations = solver_iterations
        self._slots = {index: slot for slot, index in enumerate(self.objects)}
        self._starts = np.array([pose.position for pose in self.start], dtype=float)
        self._positions = self._starts.copy()
        self._iterations = 0
        self._escape_steps = 0  # speed-cap steps the objects stuck in static bodies have marched out
        self._lowest_overlap = math.inf  # the lowest summed overlap so far, metres
        self._stalled_steps = 0  # least-distance steps since it was last lowered
        self._initial_overlap: float | None = None
        self._depenetrated: tuple[tuple[Pose, ...], bool, float] | None = None
        self._settling: PartialSettling | None = None
        self._result: RefinedMap | None = None

    @property
    def max_step(self) -> float:
        """Metres an object may move in one depenetration iteration: the speed cap times one time step."""
        return self.params.refine_max_speed * TIME_STEP

    def _poses(self) -> tuple[Pose, ...]:
        return tuple(
            Pose((float(x), float(y), float(z)), pose.orientation)
            for (x, y, z), pose in zip(self._positions, self.start, strict=True)
        )

    def run(self, stop_at: float | None = None) -> RefinedMap | None:
        """Refine until done (the map) or until the ``time.monotonic()`` instant ``stop_at`` (None)."""
        while self._result is None:
            if self._depenetrated is None:
                if not self._depenetrate(stop_at):
                    return None
            elif not self._settle(stop_at):
                return None
        return self._result

    def so_far(self) -> RefinedMap | None:
        """The map so far: the finished one, else, once the depenetration has ended, its poses unsettled
        (``settled`` False: overlapping nothing, where the objects were seen, not yet where they come to rest);
        None while it depenetrates."""
        if self._result is not None or self._depenetrated is None:
            return self._result
        poses, converged, overlap = self._depenetrated
        return self._map(poses, poses, converged, overlap, settled=False)

    def _depenetrate(self, stop_at: float | None) -> bool:
        """Iterate the depenetration until it ends (True) or ``stop_at`` passes (False).

        An iteration is one least-distance step or, when no translation meets the linearised
        constraints, one step of the escape of the objects stuck in static bodies.
        """
        margin = 2.0 * self.max_step  # two objects each moving one step towards each other
        while True:
            poses = self._poses()
            proximities = self.checker.proximities(poses, margin, self.objects)
            overlap = _deepest_overlap(proximities)
            if self._initial_overlap is None:
                self._initial_overlap = overlap
            converged = overlap <= OVERLAP_TOLERANCE
            self._lower(_summed_overlap(proximities))
            stalled = self._stalled_steps >= STALL_ITERATIONS
            if converged or self._iterations >= MAX_ITERATIONS or stalled:
                self._depenetrated = (poses, converged, overlap)
                return True
            step = _step(proximities, self._slots, self._positions - self._starts)
            stuck = _stuck_in_statics(proximities)
            if step is None and not stuck:  # no translation fits, and no escape would help
                self._depenetrated = (poses, False, overlap)
                return True
            if step is not None:
                largest = float(np.linalg.norm(step, axis=1).max())
                if largest > self.max_step:
                    step *= self.max_step / largest
                self._positions = self._positions + step
                self._escape_steps = 0
                self._stalled_steps += 1
            else:
                self._escape_steps += 1
                for index in stuck:
                    self._escape(index, self._escape_steps * self.max_step)
            self._iterations += 1
            if stop_at is not None and time.monotonic() >= stop_at:
                return False

    def _lower(self, summed: float) -> None:
        """Count the least-distance steps from scratch where ``summed`` (metres) is a new lowest summed overlap, by
        more than :data:`OVERLAP_TOLERANCE` (the stall of the module docstring; escape steps are not counted: the
        overlap stays put while the escape's reach grows)."""
        if summed < self._lowest_overlap - OVERLAP_TOLERANCE:
            self._lowest_overlap, self._stalled_steps = summed, 0

    def _escape(self, index: int, reach: float) -> None:
        """Move object ``index`` out of the static bodies if that is possible within ``reach`` metres.

        The escape marches all :data:`ESCAPE_DIRECTIONS` out together, one speed-cap step per
        iteration (every shorter reach was tried by the iterations before), and takes the first
        free direction in their order; the last step is bisected down to :data:`OVERLAP_TOLERANCE`.
        """
        slot = self._slots[index]
        position, orientation = self._positions[slot].copy(), self.start[slot].orientation

        def free(distance: float, direction: Vector3) -> bool:
            x, y, z = position + distance * np.asarray(direction)
            pose = Pose((float(x), float(y), float(z)), orientation)
            return self.checker.static_overlap(index, pose) <= OVERLAP_TOLERANCE

        direction = next((d for d in ESCAPE_DIRECTIONS if free(reach, d)), None)
        if direction is None:
            return
        inside, outside = max(0.0, reach - self.max_step), reach
        while outside - inside > OVERLAP_TOLERANCE:
            middle = (inside + outside) / 2.0
            inside, outside = (inside, middle) if free(middle, direction) else (middle, outside)
        self._positions[slot] = position + outside * np.asarray(direction)

    def _settle(self, stop_at: float | None) -> bool:
        """Settle the depenetrated poses, speeds capped, until done (True) or ``stop_at`` passes (False)."""
        assert self._depenetrated is not None and self._initial_overlap is not None
        poses, converged, overlap = self._depenetrated
        params, checker = self.params, self.checker
        if self._settling is None:
            outcome = checker.settle(
                poses,
                params.settle_time,
                params.angular_weight,
                stop_at,
                objects=self.objects,
                max_speed=params.refine_max_speed,
                early_exit=early_exit_rule(params, complete=True, wobbling=True),
                solver_iterations=self.solver_iterations,
            )
        else:
            outcome = checker.resume_settling(self._settling, stop_at)
        if isinstance(outcome, PartialSettling):
            self._settling = outcome
            return False
        self._result = self._map(poses, outcome.settled_poses, converged, overlap)
        return True

    def _map(
        self,
        depenetrated: tuple[Pose, ...],
        map_poses: tuple[Pose, ...],
        converged: bool,
        overlap: float,
        settled: bool = True,
    ) -> RefinedMap:
        """The map of ``map_poses`` (the settled poses, or with ``settled`` False the depenetrated ones)."""
        assert self._initial_overlap is not None
        jitters = tuple(
            pose_displacement(reference, pose, self.params.angular_weight)
            for reference, pose in zip(self.reference, map_poses, strict=True)
        )
        return RefinedMap(
            objects=self.objects,
            start_poses=self.start,
            depenetrated_poses=depenetrated,
            settled_poses=map_poses,
            jitters=jitters,
            iterations=self._iterations,
            converged=converged,
            initial_overlap=self._initial_overlap,
            remaining_overlap=overlap,
            settled=settled,
        )


def refine_objects(
    checker: PhysicsChecker,
    objects: Sequence[int],
    hypotheses: Sequence[RankedHypotheses],
    params: SearchParams,
    solver_iterations: int = SETTLING_SOLVER_ITERATIONS,
) -> RefinedMap:
    """Refine ``objects`` (scene indices) from their ``hypotheses`` (same order) to the end, without a deadline.

    Starts at :func:`refinement_start` with ``params.refine_mean_radius``; J_i is measured from
    each object's most likely hypothesis; ``solver_iterations`` as :class:`Refinement`'s.
    """
    start = [refinement_start(h, params.refine_mean_radius) for h in hypotheses]
    reference = [h.pose(1) for h in hypotheses]
    result = Refinement(checker, objects, start, reference, params, solver_iterations).run()
    assert result is not None  # no deadline
    return result

"""Rule 2, stability: under gravity for ``settle_time`` seconds, each object moves at most ``jitter_threshold``.

Object i's jitter is

    J_i = |p_i - p'_i| + angular_weight * angle(q_i, q'_i)

with p in metres and the rotation angle in radians, between its pose at the start and after
settling; the configuration's jitter J is the sum.

A settling given a deadline (``stop_at``) that passes is interrupted, not abandoned: it returns
a :class:`PartialSettling` that :meth:`Settler.resume_settling` continues where it stopped, ending
bit for bit where the same settling run uninterrupted in this world ends. Resumed at once, the
world simply holds the interrupted simulation and goes on; if the world is used for another
configuration first, the interrupted simulation is saved and restored on resume, positions,
velocities and contact points, measured bit for bit too (BENCHMARKS.md, "Interrupted settlings").
A settler keeps one interrupted settling: interrupting another frees the first's saved state, and
resuming the first then simulates it again from its start (same result, more time); so does
resuming after other objects were parked or placed. A settling may cap the objects' speed
(``max_speed``) and run Bullet's solver with fewer iterations than Rule 2's (``solver_iterations``), or ending
each step's iterations at a larger residual (``solver_residual``).

Early exit (:class:`EarlyExit`): a settling may stop before ``settle_time`` once every simulated
object has stayed at rest for :data:`REST_CHECKS` looks at it, or once an object has stayed at rest
with its jitter beyond the jitter threshold for as many looks. Beyond the threshold alone is not
enough: a rocking object's jitter passes the threshold and comes back (measured on the tabletop
mesh scene: 5 of 50 valid C11..1 were cut short as unstable). An exit may also count an object
wobbling in its contacts, fast at an instant but going nowhere over the last looks, as at rest
(:attr:`EarlyExit.wobble_rate`). The state is looked at every
:data:`CLOCK_CHECK_STEPS` steps (the same instants as the clock), and looking does not change the
simulation, so a settling that does not stop early ends bit for bit where a full one does.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal, TypedDict, Unpack, overload

from physics_mapper.model.bullet import pybullet
from physics_mapper.model.geometry import Pose, Vector3, pose_displacement, rotation_angle, translation_distance
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.world import SOLVER_ITERATIONS, SOLVER_RESIDUAL, TIME_STEP, PhysicsWorld

#: Simulation steps between two looks at the wall clock during settling: an interrupted settling
#: stops at most this many steps after its deadline, and a resumed one advances at least this many.
CLOCK_CHECK_STEPS = 8
#: Consecutive looks (every :data:`CLOCK_CHECK_STEPS` steps, 0.1 s in all at 240 Hz) at which every
#: simulated object, or one object beyond the jitter threshold, must be at rest before a settling
#: stops early.
REST_CHECKS = 3
#: Why a settling stopped before ``settle_time``: every object at rest, or one object at rest with
#: its jitter beyond the threshold (it came to rest elsewhere: the configuration is unstable).
SettleStop = Literal["rest", "beyond_threshold"]
#: The smallest axis-aligned box (low corner, high corner), metres, holding an object's positions.
PositionRange = tuple[Vector3, Vector3]


@dataclass(frozen=True)
class EarlyExit:
    """When a settling may stop before its ``settle_time``.

    ``rest_rate`` (m/s): an object is at rest while its jitter rate |v| + angular_weight * |omega|
    (linear speed in m/s, angular speed in rad/s) is at most this; once every simulated object has
    been at rest at :data:`REST_CHECKS` consecutive looks, the settling stops (``"rest"``).
    ``jitter_threshold`` (m + weighted rad): once an object has been at rest with its J_i beyond it at
    :data:`REST_CHECKS` consecutive looks, the settling stops (``"beyond_threshold"``): the object
    came to rest elsewhere. None keeps such a settling going (a complete settling).
    ``wobble_rate`` (m/s): an object is also at rest while its jitter rate is at most this and its
    pose moved at most ``rest_rate`` x the time since the look :data:`REST_CHECKS` looks before (or
    since the start): it wobbles in its contacts without going anywhere. None: the rate alone.
    ``drift`` (m + weighted rad): both rates (and the wobble's stay) are scaled up at a look by
    ``drift`` / (``rest_rate`` x the time left), when that is more than 1: an object drifting on at
    the rate would add at most ``drift`` to its J_i by the settling's end. None: fixed rates.
    ``beyond_looks``: the consecutive looks an object must be beyond (at rest beyond
    ``jitter_threshold``, or anyhow its position beyond ``moving_beyond`` or its orientation beyond
    ``turning_beyond``) before the settling stops.
    """

    rest_rate: float
    jitter_threshold: float | None
    #: (m) once an object's position has been beyond this from its start at ``beyond_looks`` consecutive
    #: looks, at rest or not, the settling stops (``"beyond_threshold"``); None: only at rest.
    moving_beyond: float | None = None
    wobble_rate: float | None = None
    drift: float | None = None
    beyond_looks: int = REST_CHECKS
    #: (rad) as ``moving_beyond``, for the angle an object turned from its start; None: not by its angle.
    turning_beyond: float | None = None

    def rate_scale(self, time_left: float) -> float:
        """What the rates are multiplied by with ``time_left`` seconds of the settling to go (``drift``)."""
        if self.drift is None or time_left <= 0.0:
            return 1.0
        return max(1.0, self.drift / (self.rest_rate * time_left))


#: An object is at rest while its jitter rate (m/s, |v| + angular_weight * |omega|) would add at most
#: this share of ``jitter_threshold`` over a whole ``settle_time``.
REST_SHARE = 0.05
#: How many jitter thresholds from its start an object's position must be, moving or not, at
#: :data:`MOVING_BEYOND_LOOKS` consecutive looks, to end a ``moving`` settling as unstable: a body falling
#: or sliding that far does not come back within the threshold (measured on the crowded suite). Its position
#: (or its turn, :data:`TURNING_BEYOND`), not J_i: a body rocking in place turns and comes back (a lego brick
#: on another's studs tipped 0.36 rad, J_i 4.5 cm at two looks, its position 9 mm, and came to rest at J_i
#: 1.1 cm).
MOVING_BEYOND_SHARE = 2.0
#: Radians an object must have turned from its start, moving or not, at :data:`MOVING_BEYOND_LOOKS`
#: consecutive looks, to end a ``moving`` settling as unstable: it topples rather than rocks (the lego brick
#: above turned 0.36 rad at most). A domino toppling on the tabletop is beyond at steps 56 and 64, its
#: position at 80 and 88 (its J_i at 48 and 56).
TURNING_BEYOND = 0.5
#: Consecutive looks (every :data:`CLOCK_CHECK_STEPS` steps, 33 ms apart) that end a ``moving``
#: settling once an object is beyond: a cube floating 2 to 4 cm is 2 thresholds down at the look after
#: 67 ms and lands by 90 ms, so two looks end its trial at step 24 instead of 32 (the crowded
#: benchmark confirms every unstable verdict with a full settling).
MOVING_BEYOND_LOOKS = 2
#: How many times the rest rate a ``moving`` settling's object may wobble at while its pose stays put
#: (:attr:`EarlyExit.wobble_rate`): boxes and cylinders packed in a bin shake at 1-7 mm/s in their
#: contacts after they have settled, moving 0.1-0.9 mm over a whole settling (crowded suite).
WOBBLE_SHARE = 10.0


def early_exit_rule(
    params: SearchParams, complete: bool, moving: bool = False, wobbling: bool = False
) -> EarlyExit | None:
    """When a settling may stop early under ``params`` (None: ``settle_exit: full``).

    At rest: jitter rate at most :data:`REST_SHARE` x jitter_threshold / settle_time (1 mm/s with
    the defaults). ``complete`` keeps a settling going past the jitter threshold (the settling a
    fallback may report), so it ends at rest or at ``settle_time``. ``wobbling`` counts an object
    wobbling at up to :data:`WOBBLE_SHARE` x the rest rate as at rest while its pose stays put, both
    rates measured against the time left (``drift``: :data:`REST_SHARE` x jitter_threshold, what the
    rest rate allows over a whole settling). ``moving`` (not with ``complete``) does too, and also
    stops a settling once an object's position has been :data:`MOVING_BEYOND_SHARE` x the threshold away,
    or it has turned :data:`TURNING_BEYOND`, or it has been at rest beyond the threshold, at
    :data:`MOVING_BEYOND_LOOKS` consecutive looks: the
    conflict-directed search's verdicts, whose agreement with full settling ``physics-mapper bench
    --crowded`` measures.
    """
    if params.settle_exit == "full" or params.settle_time <= 0.0:
        return None
    threshold = params.jitter_threshold
    rest_rate = REST_SHARE * threshold / params.settle_time
    moving = moving and not complete
    jitter_threshold = None if complete else threshold
    wobble_rate, drift = (WOBBLE_SHARE * rest_rate, REST_SHARE * threshold) if wobbling or moving else (None, None)
    if moving:
        beyond = MOVING_BEYOND_SHARE * threshold
        return EarlyExit(rest_rate, jitter_threshold, beyond, wobble_rate, drift, MOVING_BEYOND_LOOKS, TURNING_BEYOND)
    return EarlyExit(rest_rate, jitter_threshold, None, wobble_rate, drift)


@dataclass(frozen=True)
class Settling:
    """Rule 2 measurement: poses after ``settle_time`` and each object's jitter J_i.

    ``stopped`` says why the settling ended before ``settle_time`` (None: it ran to the end);
    ``steps`` of ``steps_total`` :data:`TIME_STEP` steps were simulated. When the settling was asked to
    track where objects went, ``path`` holds every object's poses at its start and every look at the world
    (every :data:`CLOCK_CHECK_STEPS` steps, and the end), and ``extent`` each object's smallest box holding
    its body (Bullet's axis-aligned bounding box) at those moments. ``beyond``: for a
    settling stopped ``beyond_threshold``, the objects (indices into ``jitters``) that were beyond at the
    early exit's ``beyond_looks`` last looks: the ones shown unstable. Another object's J_i beyond the
    threshold at that moment may be a passing swing (a part rocking as a neighbour falls) that would
    have come back.
    """

    settled_poses: tuple[Pose, ...]
    jitters: tuple[float, ...]
    stopped: SettleStop | None = None
    steps: int = 0
    steps_total: int = 0
    extent: tuple[PositionRange, ...] | None = None
    #: Bullet solver iterations it ran with when fewer than Rule 2's (None: Rule 2's, ``SOLVER_ITERATIONS``).
    solver_iterations: int | None = None
    beyond: tuple[int, ...] = ()
    path: tuple[tuple[Pose, ...], ...] | None = None

    @property
    def total_jitter(self) -> float:
        """J, the sum of the per-object jitters."""
        return sum(self.jitters)

    @property
    def most_moved(self) -> int:
        """Index of the object with the largest J_i."""
        return max(range(len(self.jitters)), key=self.jitters.__getitem__)

    def is_stable(self, jitter_threshold: float) -> bool:
        """True iff every J_i is at most ``jitter_threshold``."""
        return max(self.jitters) <= jitter_threshold


@dataclass(frozen=True, eq=False)
class PartialSettling:
    """A settling its deadline interrupted, for :meth:`PhysicsChecker.resume_settling`.

    ``steps_done`` of ``steps_total`` :data:`TIME_STEP` steps are simulated from rest at
    ``poses`` (the start, from which the jitters are measured). Compared by identity: the
    checker that interrupted it recognises it as the settling it kept. ``objects``, ``max_speed``,
    ``early_exit``, ``solver_iterations``, ``solver_residual`` and ``fixed`` (objects held where they are:
    scene index, pose) are the settling's (see :meth:`PhysicsChecker.settle`), with the consecutive looks so far
    with every object at rest (``rest_checks``) and, per object, with it beyond (``beyond_checks``, empty
    before the first look), the last looks' poses (``recent``: step, poses; for ``wobble_rate``), and the
    ``extent`` and ``path`` so far (None: not tracked; an extent not begun).
    """

    poses: tuple[Pose, ...]
    angular_weight: float
    steps_done: int
    steps_total: int
    objects: tuple[int, ...] | None = None
    max_speed: float | None = None
    early_exit: EarlyExit | None = None
    fixed: tuple[tuple[int, Pose], ...] = ()
    solver_iterations: int | None = None
    solver_residual: float | None = None
    rest_checks: int = 0
    beyond_checks: tuple[int, ...] = ()
    recent: tuple[tuple[int, tuple[Pose, ...]], ...] = ()
    extent: tuple[PositionRange, ...] | None = None
    path: tuple[tuple[Pose, ...], ...] | None = None

    def restarted(self) -> PartialSettling:
        """The same settling, not yet begun."""
        path = None if self.path is None else (self.poses,)
        return replace(self, steps_done=0, rest_checks=0, beyond_checks=(), recent=(), extent=None, path=path)


def _grown(ranges: tuple[PositionRange, ...], boxes: Sequence[PositionRange]) -> tuple[PositionRange, ...]:
    """Each range grown to hold the matching box."""
    grown = []
    for (low, high), (box_low, box_high) in zip(ranges, boxes, strict=True):
        grown.append(
            (
                (min(low[0], box_low[0]), min(low[1], box_low[1]), min(low[2], box_low[2])),
                (max(high[0], box_high[0]), max(high[1], box_high[1]), max(high[2], box_high[2])),
            )
        )
    return tuple(grown)


#: How far an object went from its start: (metres its position moved, radians it turned).
Move = tuple[float, float]


def _moves(start: Sequence[Pose], now: Sequence[Pose]) -> list[Move]:
    """Each object's :data:`Move` from ``start`` to ``now``."""
    return [
        (translation_distance(a, b), rotation_angle(a.orientation, b.orientation))
        for a, b in zip(start, now, strict=True)
    ]


def _jitters(moves: Sequence[Move], angular_weight: float) -> tuple[float, ...]:
    """Each object's J_i from its move (:func:`~physics_mapper.model.geometry.pose_displacement`, bit for bit)."""
    return tuple(distance + angular_weight * angle for distance, angle in moves)


def _beyond_checks(
    checks: tuple[int, ...], rule: EarlyExit, at_rest: Sequence[bool], jitters: Sequence[float], moves: Sequence[Move]
) -> tuple[int, ...]:
    """Per object, its consecutive looks beyond after this one (``checks``: before it, empty before the first):
    at rest with J_i beyond ``rule.jitter_threshold``, or anyhow its position moved beyond ``rule.moving_beyond``
    or turned beyond ``rule.turning_beyond``."""
    before = checks or (0,) * len(jitters)
    return tuple(
        looks + 1
        if (resting and _beyond(rule.jitter_threshold, jitter))
        or _beyond(rule.moving_beyond, distance)
        or _beyond(rule.turning_beyond, angle)
        else 0
        for looks, resting, jitter, (distance, angle) in zip(before, at_rest, jitters, moves, strict=True)
    )


def _beyond(bound: float | None, value: float) -> bool:
    return bound is not None and value > bound


class SettleOptions(TypedDict, total=False):
    """Keyword options of :meth:`PhysicsChecker.settle` (see there): which objects settle (scene
    indices; the others stay parked), a speed cap (m/s), an early exit, whether to record where objects
    went, objects held fixed at given poses (scene index, pose) while the others settle, the solver's
    iterations per step (None: :data:`~physics_mapper.physics.world.SOLVER_ITERATIONS`) and the residual
    ((m/s)^2) that ends them (None: :data:`~physics_mapper.physics.world.SOLVER_RESIDUAL`)."""

    objects: Sequence[int] | None
    max_speed: float | None
    early_exit: EarlyExit | None
    track_reach: bool
    fixed: Sequence[tuple[int, Pose]]
    solver_iterations: int | None
    solver_residual: float | None


@dataclass(frozen=True)
class TrajectorySample:
    """The objects' poses ``time`` seconds into a simulation."""

    time: float
    poses: tuple[Pose, ...]


class Settler:
    """Rule 2 in a :class:`~physics_mapper.physics.world.PhysicsWorld`: settlings, their interruption and resumption."""

    def __init__(self, world: PhysicsWorld) -> None:
        self.world = world
        # The interrupted settling a resume continues (the world keeps its simulation), and the
        # world's count of re-entries when it stopped.
        self._interrupted: PartialSettling | None = None
        self._interrupted_entries = 0

    @overload
    def settle(
        self, poses: Sequence[Pose], settle_time: float, angular_weight: float, **options: Unpack[SettleOptions]
    ) -> Settling: ...

    @overload
    def settle(
        self,
        poses: Sequence[Pose],
        settle_time: float,
        angular_weight: float,
        stop_at: float | None,
        **options: Unpack[SettleOptions],
    ) -> Settling | PartialSettling: ...

    def settle(
        self,
        poses: Sequence[Pose],
        settle_time: float,
        angular_weight: float,
        stop_at: float | None = None,
        **options: Unpack[SettleOptions],
    ) -> Settling | PartialSettling:
        """Rule 2: simulate ``settle_time`` seconds from rest at ``poses``; measure each J_i.

        ``stop_at`` is a ``time.monotonic()`` instant. The clock is read every
        :data:`CLOCK_CHECK_STEPS` steps; once it has passed, the simulation stops and a
        :class:`PartialSettling` is returned, so a caller overruns its deadline by at most that
        many steps. :meth:`resume_settling` continues it.

        ``objects`` (scene indices) settles only those objects, ``poses`` being theirs; the others
        stay parked. ``max_speed`` (m/s) caps each object's linear speed after every step (within a
        step, gravity adds at most g * TIME_STEP = 0.04 m/s to it). ``early_exit`` may end the
        settling before ``settle_time`` (:class:`EarlyExit`); ``track_reach`` records where each
        object went (:attr:`Settling.path`, :attr:`Settling.extent`). ``fixed`` (scene index, pose) places
        further objects that do not move (massless, as parked ones) and are not measured: the others rest
        against them.
        ``solver_iterations`` runs Bullet's constraint solver with that many iterations per step
        instead of Rule 2's :data:`~physics_mapper.physics.world.SOLVER_ITERATIONS` (cheaper, less stiff
        contacts; the world goes back to Rule 2's when the settling returns). ``solver_residual`` ((m/s)^2) ends
        each step's iterations once the last one changed no contact's velocity by more than its square root,
        instead of at :data:`~physics_mapper.physics.world.SOLVER_RESIDUAL` (cheaper where contacts are at
        rest; the world goes back to that when the settling returns).
        """
        objects = options.get("objects")
        fixed = tuple(options.get("fixed", ()))
        self.world.place(poses, objects, fixed)
        plan = PartialSettling(
            poses=tuple(poses),
            angular_weight=angular_weight,
            steps_done=0,
            steps_total=round(settle_time / TIME_STEP),
            objects=None if objects is None else tuple(objects),
            max_speed=options.get("max_speed"),
            early_exit=options.get("early_exit"),
            fixed=fixed,
            solver_iterations=options.get("solver_iterations"),
            solver_residual=options.get("solver_residual"),
            path=(tuple(poses),) if options.get("track_reach", False) else None,
        )
        return self._simulate(plan, stop_at)

    @overload
    def resume_settling(self, partial: PartialSettling) -> Settling: ...

    @overload
    def resume_settling(self, partial: PartialSettling, stop_at: float | None) -> Settling | PartialSettling: ...

    def resume_settling(self, partial: PartialSettling, stop_at: float | None = None) -> Settling | PartialSettling:
        """Continue an interrupted settling where it stopped, until done or ``stop_at`` (as :meth:`settle`).

        The settled poses are bit for bit those of the settling run uninterrupted, also when
        other configurations were checked in between (see the module docstring). Each call
        simulates at least :data:`CLOCK_CHECK_STEPS` steps, so repeated calls finish. A partial
        this settler no longer keeps (it interrupted another settling since, or the partial is
        another settler's, or objects were parked or placed since) is simulated again from its start.
        """
        if partial is not self._interrupted:
            self.world.place(partial.poses, partial.objects, partial.fixed)
            return self._simulate(partial.restarted(), stop_at)
        if self.world.kept_was_saved() and self.world.entries != self._interrupted_entries:
            # Objects were parked or placed since (their masses changed): Bullet re-entered them into
            # its world, so the saved contact points would not come back as they were. Start over.
            self._forget_interrupted()
            self.world.place(partial.poses, partial.objects, partial.fixed)
            return self._simulate(partial.restarted(), stop_at)
        if self.world.kept_was_saved():
            self.world.restore_kept(partial.objects, partial.fixed)
        self._forget_interrupted()
        return self._simulate(partial, stop_at)

    def _simulate(self, plan: PartialSettling, stop_at: float | None) -> Settling | PartialSettling:
        """Step the world from ``plan.steps_done`` to ``plan.steps_total``, or until it may stop early
        or ``stop_at`` passes (:meth:`settle`), with the plan's solver iterations and residual."""
        if plan.solver_iterations is None and plan.solver_residual is None:
            return self._step_through(plan, stop_at)
        self.world.set_solver_iterations(plan.solver_iterations or SOLVER_ITERATIONS)
        self.world.set_solver_residual(plan.solver_residual or SOLVER_RESIDUAL)
        try:
            return self._step_through(plan, stop_at)
        finally:
            self.world.set_solver_iterations(SOLVER_ITERATIONS)
            self.world.set_solver_residual(SOLVER_RESIDUAL)

    def _step_through(self, plan: PartialSettling, stop_at: float | None) -> Settling | PartialSettling:
        """:meth:`_simulate` with the world's solver as it is."""
        steps_done, steps_total = plan.steps_done, plan.steps_total
        uids = self.world.uids(plan.objects)
        watched = plan.early_exit is not None or plan.path is not None
        rest_checks, beyond_checks, path = plan.rest_checks, plan.beyond_checks, plan.path
        extent, recent = plan.extent, plan.recent or ((0, plan.poses),)
        iterations = plan.solver_iterations
        if path is not None and extent is None:
            extent = tuple(self.world.extents(uids))
        while steps_done < steps_total:
            batch_end = min(steps_done + CLOCK_CHECK_STEPS, steps_total)
            for _ in range(steps_done, batch_end):
                self.world.step()
                if plan.max_speed is not None:
                    self._cap_speeds(uids, plan.max_speed)
            steps_done = batch_end
            if watched and steps_done < steps_total:
                poses = self.world.poses(plan.objects)
                if path is not None and extent is not None:
                    path, extent = (*path, poses), _grown(extent, self.world.extents(uids))
                if plan.early_exit is not None:
                    moves = _moves(plan.poses, poses)
                    jitters = _jitters(moves, plan.angular_weight)
                    at_rest = self._at_rest(
                        uids, plan.angular_weight, plan.early_exit, recent[0], poses, steps_done, steps_total
                    )
                    recent = (*recent, (steps_done, poses))[-REST_CHECKS:]
                    beyond_checks = _beyond_checks(beyond_checks, plan.early_exit, at_rest, jitters, moves)
                    rest_checks = rest_checks + 1 if all(at_rest) else 0
                    shown = tuple(i for i, looks in enumerate(beyond_checks) if looks >= plan.early_exit.beyond_looks)
                    if shown:
                        return Settling(
                            poses,
                            jitters,
                            "beyond_threshold",
                            steps_done,
                            steps_total,
                            extent,
                            iterations,
                            shown,
                            path,
                        )
                    if rest_checks >= REST_CHECKS:
                        return Settling(poses, jitters, "rest", steps_done, steps_total, extent, iterations, path=path)
            if stop_at is not None and steps_done < steps_total and time.monotonic() >= stop_at:
                self.world.keep_simulation()
                self._interrupted = replace(
                    plan,
                    steps_done=steps_done,
                    rest_checks=rest_checks,
                    beyond_checks=beyond_checks,
                    recent=recent,
                    extent=extent,
                    path=path,
                )
                self._interrupted_entries = self.world.entries
                return self._interrupted
        settled = self.world.poses(plan.objects)
        if path is not None and extent is not None:
            path, extent = (*path, settled), _grown(extent, self.world.extents(uids))
        jitters = _jitters(_moves(plan.poses, settled), plan.angular_weight)
        return Settling(settled, jitters, None, steps_done, steps_total, extent, iterations, path=path)

    def _forget_interrupted(self) -> None:
        self.world.forget_kept()
        self._interrupted = None

    def _at_rest(
        self,
        uids: Sequence[int],
        angular_weight: float,
        early_exit: EarlyExit,
        since: tuple[int, Sequence[Pose]],
        poses: Sequence[Pose],
        step: int,
        steps_total: int,
    ) -> list[bool]:
        """Per body, whether it is at rest at ``step`` of ``steps_total`` (:class:`EarlyExit`): its jitter
        rate |v| + angular_weight * |omega| (m/s) at most ``rest_rate``, or at most ``wobble_rate`` with
        its pose moved at most ``rest_rate`` x the time since the look ``since`` (step, poses); the rates
        scaled by :meth:`EarlyExit.rate_scale` of the time left."""
        scale = early_exit.rate_scale((steps_total - step) * TIME_STEP)
        rest_rate = scale * early_exit.rest_rate
        wobble_rate = None if early_exit.wobble_rate is None else scale * early_exit.wobble_rate
        stay = rest_rate * (step - since[0]) * TIME_STEP
        resting = []
        for uid, was, now in zip(uids, since[1], poses, strict=True):
            linear, angular = pybullet.getBaseVelocity(uid, physicsClientId=self.world.client)
            rate = math.hypot(*linear) + angular_weight * math.hypot(*angular)
            wobbling = wobble_rate is not None and rate <= wobble_rate
            resting.append(rate <= rest_rate or (wobbling and pose_displacement(was, now, angular_weight) <= stay))
        return resting

    def _cap_speeds(self, uids: Sequence[int], max_speed: float) -> None:
        """Scale down every linear velocity faster than ``max_speed`` m/s to that speed (same direction)."""
        for uid in uids:
            linear, angular = pybullet.getBaseVelocity(uid, physicsClientId=self.world.client)
            speed = math.hypot(*linear)
            if speed > max_speed:
                scale = max_speed / speed
                capped = [v * scale for v in linear]
                pybullet.resetBaseVelocity(uid, capped, angular, physicsClientId=self.world.client)

    def trajectory(
        self, poses: Sequence[Pose], duration: float, sample_interval: float
    ) -> tuple[TrajectorySample, ...]:
        """Simulate ``duration`` seconds from rest at ``poses``, recording the objects' poses.

        Returns a sample at time 0 and then every ``sample_interval`` seconds (rounded to
        whole :data:`TIME_STEP` steps, at least one). For plots and inspection; the rules use
        :meth:`settle`, which steps the same world the same way.
        """
        self.world.place(poses)
        steps_per_sample = max(1, round(sample_interval / TIME_STEP))
        samples = [TrajectorySample(0.0, self.world.poses())]
        for step in range(1, round(duration / TIME_STEP) + 1):
            self.world.step()
            if step % steps_per_sample == 0:
                samples.append(TrajectorySample(step * TIME_STEP, self.world.poses()))
        return tuple(samples)

"""A Rule 2 part of trial, local and confirming settlings (the conflict-directed search's).

Rule 2 of a candidate is first *tried*, locally where the stable contexts allow
(:mod:`~physics_mapper.search.local_settling`), with Bullet's solver at :data:`TRIAL_SOLVER_ITERATIONS`; a
trial's instability is believed, and a candidate is judged stable only once Rule 2's own settling of its
whole group (50 iterations) confirms it. With Rule 2's own settling at once: a candidate every context
presumes valid, the candidate a fallback may report, and a whole-group trial where it would not pay
(fewer than :data:`WHOLE_TRIALS_FROM_OBJECTS` objects) or would be Rule 2's settling anyway (a group
holding a mesh).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.settling import PartialSettling, Settling, early_exit_rule
from physics_mapper.search.local_settling import LocalPlan, LocalSettling
from physics_mapper.search.results import Code, Counters, SearchStats
from physics_mapper.search.rule2 import MemoisedSettling, SettlingObserver, StepCounts

#: Bullet solver iterations of a trial settling (Rule 2's are 50, ``world.SOLVER_ITERATIONS``): its
#: instability is believed, its stability confirmed by a settling with Rule 2's solver. Walls, towers
#: and bins of 50 step 1.9 to 2.6 times faster; the 866 configurations the crowded suite's searches
#: found unstable or valid, settled in full with 50, 15 and 10 iterations, were stable alike.
TRIAL_SOLVER_ITERATIONS = 15
#: Objects a group needs before a candidate with no context known is tried as a whole: a small group's
#: first candidate is often valid (the scale suite's separate piles: the median search took 1.3 times
#: longer with whole-group trials in every group), and a valid trial costs one settling more.
WHOLE_TRIALS_FROM_OBJECTS = 7


@dataclass(eq=False)
class TrialSettling:
    """Trial settlings where the stable contexts of ``local`` allow, confirmed by ``confirm`` (Rule 2's own,
    memoised); the stable contexts learned from every settling (module docstring).

    ``observers`` see each trial as a settling of the whole group (the escape guard). Counts its trials'
    ``steps``, the ``local_settlings`` (part of the group simulated) and every settling of the whole group
    (``full_settlings``: whole trials and Rule 2's own).
    """

    checker: PhysicsChecker
    objects: tuple[int, ...]
    params: SearchParams
    local: LocalSettling
    confirm: MemoisedSettling
    observers: Sequence[SettlingObserver] = ()
    local_settlings: int = field(default=0, init=False)
    whole_trials: int = field(default=0, init=False)
    steps: StepCounts = field(default_factory=StepCounts, init=False)
    _trial: tuple[Code, LocalPlan] | None = field(default=None, init=False)  # the trial settling under way

    def settle(
        self, code: Code, poses: tuple[Pose, ...], stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling:
        plan = None if complete else self.local.plan(code)
        whole = plan is not None and len(plan.simulated) == len(code)
        # A whole group holding a mesh is tried with Rule 2's solver: the trial would be Rule 2's settling.
        if plan is None or (whole and (len(code) < WHOLE_TRIALS_FROM_OBJECTS or self.local.holds_meshes)):
            outcome = self.confirm.settle(code, poses, stop_at, complete)
        else:
            memoised = self.confirm.known(code, complete)
            outcome = memoised if memoised is not None else self._try(code, poses, plan, stop_at, complete)
        return self._verdict(code, poses, outcome, stop_at, complete)

    def resume(
        self, code: Code, poses: tuple[Pose, ...], partial: PartialSettling, stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling:
        trial = self._trial
        if trial is not None and trial[0] == code:
            outcome = self._tried(code, trial[1], self.checker.resume_settling(partial, stop_at))
        else:
            outcome = self.confirm.resume(code, poses, partial, stop_at, complete)
        return self._verdict(code, poses, outcome, stop_at, complete)

    def _try(
        self, code: Code, poses: tuple[Pose, ...], plan: LocalPlan, stop_at: float | None, complete: bool
    ) -> Settling | PartialSettling:
        """The trial settling of ``plan``'s objects, the others held fixed at their hypotheses."""
        self._trial = (code, plan)
        params = self.params
        outcome = self.checker.settle(
            [poses[p] for p in plan.simulated],
            params.settle_time,
            params.angular_weight,
            stop_at,
            objects=[self.objects[p] for p in plan.simulated],
            fixed=[(self.objects[p], poses[p]) for p in plan.fixed],
            early_exit=early_exit_rule(params, complete=complete, moving=True),
            track_reach=True,
            # Meshes change verdicts at fewer iterations (7 of 377 at 15 on the shipped mesh scenes).
            solver_iterations=None if self.local.holds_meshes else TRIAL_SOLVER_ITERATIONS,
        )
        return self._tried(code, plan, outcome)

    def _tried(self, code: Code, plan: LocalPlan, outcome: Settling | PartialSettling) -> Settling | PartialSettling:
        """Count a trial the engine finished; the observers see it as a settling of the whole group."""
        if isinstance(outcome, Settling):
            if len(outcome.jitters) == len(self.objects):
                self.whole_trials += 1
            else:
                self.local_settlings += 1
            self.steps.add(outcome)
            whole = self.local.whole(plan, outcome, code)
            for observe in self.observers:
                observe(code, whole)
        return outcome

    def _verdict(
        self,
        code: Code,
        poses: tuple[Pose, ...],
        settling: Settling | PartialSettling,
        stop_at: float | None,
        complete: bool,
    ) -> Settling | PartialSettling:
        """Rule 2's settling of ``code`` for the judge: a trial that shows an instability, else Rule 2's own
        (a trial that shows none is confirmed by a full settling with Rule 2's solver first), contexts
        recorded."""
        if isinstance(settling, PartialSettling):
            return settling
        trial, self._trial = self._trial, None
        if trial is not None and trial[0] == code:
            plan = trial[1]
            self.local.observe(code, plan.simulated, settling.jitters)
            whole = self.local.whole(plan, settling, code)
            if not whole.is_stable(self.params.jitter_threshold):
                self._forget_moved(code, whole)
                return whole
            confirmed = self.confirm.settle(code, poses, stop_at, complete)
            if isinstance(confirmed, PartialSettling):
                return confirmed
            settling = confirmed
        self.local.observe(code, range(len(self.objects)), settling.jitters)
        self._forget_moved(code, settling)
        return settling

    def _forget_moved(self, code: Code, settling: Settling) -> None:
        """Drop the stable contexts of the objects a settling of the whole group moved beyond the threshold."""
        threshold = self.params.jitter_threshold
        self.local.forget(code, [p for p, jitter in enumerate(settling.jitters) if jitter > threshold])

    def keep_from(self, old: TrialSettling, moved: dict[int, int], stale: set[int]) -> None:
        """Take over ``old``'s stable contexts (:meth:`LocalSettling.kept_from`)."""
        self.local.kept_from(old.local, moved, stale)

    def count_into(self, stats: SearchStats) -> None:
        self.steps.count_into(stats)
        self.confirm.count_into(stats)

    def counters(self) -> Counters:
        """Its settlings by kind (class docstring)."""
        return {"local_settlings": self.local_settlings, "full_settlings": self.whole_trials + self.confirm.settlings}

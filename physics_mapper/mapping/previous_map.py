"""The previous map first: a tick keeps a valid map while the scene stands still (ROS-free).

The search visits configurations in decreasing p(C) and stops at its deadline with its best so far.
In a bin of identical boxes, a box whose best pose is wrong (a few centimetres too high, say) makes
every configuration that holds it unstable, and the blame rule's conflict also holds its neighbours at
their ranks; their other ranks, nearly as probable, come first, and the deadline can pass before the
box's own second rank is tried. Yet the last tick's map was valid and the bin has not moved.

So before a new search runs, the tick checks one configuration, the *previous map's*:

- an object the last valid map held (:class:`~physics_mapper.mapping.existence.MapMemory`; before any, the
  last refined map: below) takes its hypothesis from this tick's inputs whose position is nearest where it
  came to rest in that map's settling, if one lies within :data:`NEAR` metres (the rest pose, not the chosen
  hypothesis: a hypothesis near where the object rests is one it rests at); else rank 1. An instance whose
  nearest hypothesis lies within :data:`AGREE` of that rest starts at its *held* pose, the rest itself
  (:mod:`~physics_mapper.mapping.existence`): the estimator sees it where it stood, and its poses scatter a
  few millimetres from frame to frame, enough to miss the studs or the rim it stood on, so that the check
  started from them saw objects tip at every frame and its repairs took the settlings of the tick (24
  cylinders, lego parts and mugs in two layers: BENCHMARKS.md, "Bins of identical objects");
- an object the map did not hold (a new instance, a silent object the map left out) takes rank 1.

Where that rank 1 is an instance's *absent*, yet its poses agree and together outweigh it, the object starts at
the pose where they agree, as in the refined map (:func:`~physics_mapper.physics.support.present_where_likelier`):
it is more likely there than not. Started absent, a part seen at every frame, each of whose poses weighed less
than its *absent*, stayed out of the check's map, and the parts above it fell and were left out with it (24 parts
of five shapes in two layers, four seeds: 204 misses before, 186 so; BENCHMARKS.md, "Bins of identical objects").

It is checked by Rule 1 (the collision pass of every object) and Rule 2 (a settling of every object,
ended early at rest as the search's are), within half the deadline, and repaired where it fails:

- where an object the last map held breaks a rule (one of the overlapping pair; or it moved beyond the
  jitter threshold), it and the objects it touches (body boxes within
  :data:`~physics_mapper.physics.support.TOUCHING`: what it leant on or pushed) that have a *held*
  hypothesis (where they rested in the last valid map, :mod:`~physics_mapper.mapping.existence`) are put
  there. In 24 lego parts in two layers standing still, a top part's poses each tilted on the studs (0.8
  cm and 0.26 rad) where the parts under it were given theirs: put back alone where it had rested, it
  tilted still; put back with the parts under it, it stood. Five ticks in a row had no valid map before
  (BENCHMARKS.md, "Bins of identical objects");
- where only new objects broke it, those that may be absent are left out (a new box on the floor stays;
  a false detection in the air or inside the bin's wall goes), or, if none may be, what they touch is
  put where it rested. Where such an object overlaps another, it first takes its other poses, in rank order,
  a collision pass each: a second detection of a box overlaps it at every pose, while a part seen beside a
  neighbour may overlap it at its best pose alone. Where one moved beyond the threshold at the pose it
  started at though something holds it up there (:func:`~physics_mapper.physics.support.held_up`, the
  refined map's box rule), its other poses are tried in rank order, each by a *local* settling: it, the
  objects that hold it up and those its body box comes within :data:`~physics_mapper.physics.support.TOUCHING`
  of settle, what those touch held fixed (a few bodies, 1-12 ms, where a settling of the bin's 24 parts takes
  20-60 ms); it takes the first that stands there, and the check's next settling confirms it. A lego part's
  best pose, tilted 4 degrees on the studs, slides off where its next, tilted 2, stands. Where none stands it
  is left out; a detection in the air is held up by nothing and is left out at once. Poses are tried only where
  the time left holds two settlings as long as the longest so far: one to confirm, one to leave out what tips
  still (the trials' time is the confirming settling's: a settling that ends at rest runs two to three times as
  long as one that ends when an object moves);
- where an overlapping pair has none of these, one of the two takes its next hypothesis near where it
  rested (within :data:`NEAR`, nearest first; no settling, only the collision pass again). Where the
  tick's refined map guides the check (below), the refinement parts two overlapping objects by moving both,
  and the hypothesis nearest where one came to rest can be the overlapping one, its next the one beside;
- where objects that moved beyond the threshold have none of these either, each takes its next hypothesis
  near where it rested. Where the refined map guides the check, a named object has no held pose and those
  the refined map placed may not be left out; a pose a few millimetres from where an object rests can still
  tip it (a mug on two others, a lego part on the studs), and the next may not (12 mugs in two layers:
  two of the first three ticks' checks passed this way, none before);

and the rest checked again, with at most :data:`CHECK_SETTLINGS` settlings in all. Where the check passed and the
search ends without a valid configuration, the previous map's configuration is the tick's map, valid, with
``previous_map`` set in the result. Where the search found a valid configuration too, the map is the one of the
two with the more probable pattern of existence (:func:`~physics_mapper.model.hypotheses.existence_probability`,
the search's own preference among valid configurations; on a tie, and always where nothing may be absent, the
search's answer stands: it is the paper's). A search the deadline stops can find first a valid configuration that
leaves out an instance seen in every frame, whose poses of this frame overlap a neighbour or the floor, where the
check holds it at its held pose: a finished search's map would then have ended its track. Where the check
passed, the search runs without its ``fallback``: a fallback map (the refined root, the settled first
collision-free configuration) would only stand in for a valid map that exists, and making it takes the search's
time (the refined root of 24 cylinders in two layers took most of a 0.2 s tick).

A check that its half of the deadline stopped with a repaired configuration still to check is *pending*:
the search runs first, leaving :data:`RESERVE_SHARE` times the check's longest settling, then, unless the
search found a valid configuration, the check goes on with the time left (:func:`search_with_previous_map`). A
settling of 24 cylinders or mugs in two layers takes 40-70 ms, so at the 0.2 s deadline a repair's second
settling never fitted in half a tick. For the same reason an object the last tick's check put at its held pose
(one not seen within :data:`AGREE` of it) starts the next frame's check there (:func:`held_again`): its poses
are much like those that broke a rule then, and checking them again took the settling the repair needed (24
boxes, cylinders and lego parts in two layers, four seeds: BENCHMARKS.md, "Bins of identical objects"). For one
frame only: the frame after, its own poses are checked again, so that a rest that was wrong (one the estimator
does not agree with) does not stay the map's.

Where no valid map is remembered (the first ticks of a bin) and the scene's fallback is ``refine``, the
tick's own refined map guides the check instead (:func:`refined_map_check`): the search runs until it has
made its map (the refined map comes first, so a tick keeps its map) and checked its own first configuration,
the most probable (often valid where the one nearest the refined map is not); then, where its map is still the
refined map or an object may be absent, the configuration nearest where the refined map rests the objects is
checked with the time left, the objects it leaves out left out from the start (it saw them fall or slide away;
a settling to see it again would take the check's time), then the search goes on. Of the search's own valid
answer and the check's configuration, the map is the one with the more probable pattern of existence
(:func:`~physics_mapper.model.hypotheses.existence_probability`, the search's own preference among valid
configurations; on a tie, the search's answer stands): in a first frame each pose of a tentative part can weigh
less than its *absent* while its poses together outweigh it, so the search's first valid configurations leave
such parts out, and the refined map, started where the poses agree, holds them (12 jenga blocks in two layers,
seed 2: the search's first map held 8 blocks, 5 of them within the identity gate of their own, the check's 11).
The refined map's objects rest overlapping nothing, so the hypotheses nearest them are worth one check: in 24
cylinders in two layers searched 0.1 s a tick, whose refined map took most of each tick, no tick had a valid
map; now 14 of 30 do (BENCHMARKS.md, "Bins of identical objects"). In that check each instance has a *held*
pose where the refined map rests it (:func:`with_held`; the check's map is then made of the check's hypotheses,
:func:`result_hypotheses`), as at the ticks after: what moved beyond the threshold is put there with what it
touches, as above. An overlapping pair goes there only once the poses near its rests are spent (``held_last``):
the refinement parts overlapping neighbours by moving both, so that every pair of their poses can overlap while
the rests overlap nothing; but a rest stands with the refined map's other rests, not always beside neighbours at
poses of their own (12 cylinders in two layers, seed 3: put at their rests at the first overlap, a cylinder
tipped and the first two ticks lost their valid map). The check starts at poses of the objects' own, not at the
rests. Bins of 12 and 24 in two layers, five seeds: a valid map at every snapshot in 21 bins of 50 before, 39 so
(BENCHMARKS.md, "Bins of identical objects", round 34).
Where that check fails too, the tick's map is its refined map, and its rests are remembered until a valid
map holds an object (:meth:`~physics_mapper.mapping.existence.MapMemory.remember`, ``refined``): the next
tick still makes its own refined map first (it may be the tick's only map), then checks the configuration
nearest the remembered rests, where an instance that breaks a rule is put at its rest there (its *held*
pose), as after a valid map. 24 lego parts in two layers (seed 3): the first nine ticks had the refined map,
now the first alone (BENCHMARKS.md, "Bins of identical objects").

Such a map is no verdict on the objects it leaves out
(:func:`~physics_mapper.mapping.existence.left_out_by_physics`): its repairs are greedy (a new object
that fell may have fallen for a neighbour's rank), so a track it leaves out goes on and the next
searches decide. A search resumed with unchanged hypotheses checks nothing new (it reuses the last
check of the same configuration, if any): it touches no physics unless it still has candidates, and
the world may hold its interrupted settling. Nor does a search that goes on with the last one's
interrupted settling (:func:`settling_goes_on`); where that settling's objects have new hypotheses it is
dropped, and the check runs (in a bin whose estimator updates every object at every frame, skipping it
there would skip it at nearly every tick the deadline cut a settling short).
"""

from __future__ import annotations

import math
import time
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, replace

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, existence_probability
from physics_mapper.model.scene import ObjectShape, SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.physics.settling import Settling, early_exit_rule
from physics_mapper.physics.support import TOUCHING, held_up, holding, present_where_likelier, within_reach
from physics_mapper.search.best_first import Search, resumable
from physics_mapper.search.results import Code, SearchResult
from physics_mapper.search.strategy import make_search, searchable

#: How far (m) a hypothesis may lie from the previous map's pose of its object to stand for it there.
NEAR = 0.02
#: How near (m) an instance's nearest hypothesis must lie to where it rested for the check to start it at its
#: *held* pose there: the estimator sees it where it stood, within its scatter from frame to frame (a few
#: millimetres), and the rest is where it stood on its neighbours.
AGREE = 0.005


#: The weight of an object's *held* hypothesis, as a share of its lightest hypothesis's
#: (:mod:`~physics_mapper.mapping.existence`).
HELD_SHARE = 0.5

#: Settlings one check may make: the first, and again after each repair (objects put at their held poses, new
#: objects left out).
CHECK_SETTLINGS = 4
#: The time a search leaves a pending check, in its longest settling so far: the check begins no settling that
#: would not end in time, and a search's run ends a few simulation steps after its budget.
RESERVE_SHARE = 1.25
#: Slices of a tick's time in which a search runs until its refined map is made (each ends at a step: a
#: settling the slice interrupts goes on in the next, losing nothing).
MAP_SLICES = 20


def with_held(ranked: RankedHypotheses, rested: Pose) -> RankedHypotheses:
    """``ranked`` plus a *held* hypothesis at ``rested`` (where the object rested in the remembered map) weighing
    :data:`HELD_SHARE` of its lightest hypothesis (outside the others' sum, which stays 1), ranked last;
    ``ranked`` itself where no pose of it lies within :data:`NEAR` metres of ``rested``."""
    if not nearby_ranks(ranked, rested):
        return ranked
    lightest = min(hypothesis.weight for hypothesis in ranked.hypotheses)
    # Appended, not renormalised: the search's hypotheses (without it) stay bit for bit the inputs', so a
    # search with unchanged inputs still resumes.
    return RankedHypotheses((*ranked.hypotheses, Hypothesis(rested, HELD_SHARE * lightest, held=True)))


def previous_map_code(
    names: Sequence[str], hypotheses: Sequence[RankedHypotheses], remembered: Mapping[str, Pose]
) -> Code | None:
    """Where the previous map's configuration starts among this tick's ``hypotheses`` (module docstring):
    each object the map held at its *held* pose where its hypothesis nearest where it rested lies within
    :data:`AGREE` of it, else at that hypothesis, each other at rank 1; None when the last valid map held none
    of ``names``."""
    if not any(name in remembered for name in names):
        return None
    return tuple(_start_rank(ranked, remembered.get(name)) for name, ranked in zip(names, hypotheses, strict=True))


def _start_rank(ranked: RankedHypotheses, rested: Pose | None) -> int:
    """Where an object that rested at ``rested`` in the previous map (None: not in it) starts the check."""
    if rested is None:
        return 1
    nearest = next(iter(nearby_ranks(ranked, rested)), None)
    if nearest is None:
        return 1
    held = ranked.held_rank()
    if held is not None and math.dist(ranked.pose(nearest).position, rested.position) <= AGREE:
        return held
    return nearest


def held_again(hypotheses: Sequence[RankedHypotheses], last: PreviousMapCheck | None) -> dict[int, int]:
    """The objects (index -> held rank) that start this frame's check at their held poses: those the ``last``
    check's repairs put there (it, or what it touches, broke a rule at their own poses), where they have one:
    this frame's poses are much like the last's. For one frame: those it started there (``carried``) start at
    their own poses again, so that a rest that was wrong (a refined map's, made from a wrong pose) does not
    stay the map's (12 lego parts in two layers, seed 2: a part 3 cm from its place missed for five to six ticks
    where held for as long as the checks passed, for four so, for three where nothing was carried)."""
    if last is None:
        return {}
    repaired = zip(hypotheses, last.hypotheses, last.start, last.code, strict=True)
    return {
        i: held
        for i, (ranked, before, started, rank_before) in enumerate(repaired)
        if (held := ranked.held_rank()) is not None
        and before.held_rank() == rank_before
        and rank_before != started
        and i not in last.carried
    }


def nearby_ranks(ranked: RankedHypotheses, rested: Pose | None) -> list[int]:
    """The ranks of this tick's poses of ``ranked`` (not its held one) within :data:`NEAR` metres of ``rested``,
    nearest first (none where ``rested`` is None)."""
    if rested is None:
        return []
    held = ranked.held_rank()
    distances = {
        rank: math.dist(ranked.pose(rank).position, rested.position) for rank in ranked.pose_ranks() if rank != held
    }
    return sorted((rank for rank, distance in distances.items() if distance <= NEAR), key=distances.__getitem__)


@dataclass(frozen=True)
class PreviousMapCheck:
    """The previous map's configuration for ``hypotheses``: where it started (``start``), what it became
    (``code``: repaired where it broke a rule), where each object it placed rested (``rested``: object name ->
    pose, in the map that guides it), the objects that map did not hold (``new``: scene indices), and its
    settling if it passed both rules (None: it failed one, or it is ``pending``: not begun, or stopped for
    time with ``code`` still to be checked). ``settlings``: how many it made, the longest
    ``longest_settling`` seconds. ``carried``: the objects it started at their held poses, where the last
    check had put them (:func:`held_again`). ``held_last``: where the held poses are the tick's own refined map's
    rests, an object is put there only once its poses near its rest are spent (:func:`refined_map_check`)."""

    hypotheses: tuple[RankedHypotheses, ...]
    start: Code
    code: Code
    rested: Mapping[str, Pose]
    new: tuple[int, ...]
    settling: Settling | None = None
    pending: bool = True
    settlings: int = 0
    longest_settling: float = 0.0
    carried: frozenset[int] = frozenset()
    held_last: bool = False

    @property
    def time_to_go_on(self) -> float:
        """Seconds a search leaves this check to go on: :data:`RESERVE_SHARE` times its longest settling."""
        return RESERVE_SHARE * self.longest_settling


def check_previous_map(
    checker: PhysicsChecker, check: PreviousMapCheck, params: SearchParams, stop_at: float | None
) -> PreviousMapCheck:
    """``check`` (not begun, or ``pending``) gone on with: Rule 1 and Rule 2 of its configuration over every
    object, settlings stopped at ``stop_at`` (a ``time.monotonic()`` instant; an unfinished settling leaves the
    check pending), repaired where it fails (module docstring): where an object the previous map held breaks a
    rule (one of the overlapping pair, or moved beyond the jitter threshold), it and the objects it touches are
    put at their *held* ranks; where only its ``new`` objects break it, they are left out (their *absent*
    ranks, where they have one), one that overlaps another only once each of its poses has, one that tipped where
    something holds it up only where none of its other poses stands in a local settling; where neither
    changes an overlapping pair, one of the two takes its next pose near where it rested (not the rank it
    started at), and where neither changes what moved, each of those takes its next;
    then the rest is checked again, with at most :data:`CHECK_SETTLINGS` settlings in all, none begun that
    would not end before ``stop_at`` if it took as long as the longest so far (the check is left pending: the
    time is the search's then, and its fallback map may need it)."""
    hypotheses, start, new, rested = check.hypotheses, check.start, check.new, check.rested
    code = list(check.code)
    names = checker.scene.object_names
    shapes = [model.shape for model in checker.scene.objects]
    droppable = {i for i in new if hypotheses[i].absent_rank() is not None and not hypotheses[i].is_absent(code[i])}
    holdable = {i: rank for i, ranked in enumerate(hypotheses) if (rank := ranked.held_rank()) not in (None, code[i])}
    nearer = {
        i: [r for r in nearby_ranks(ranked, rested.get(name)) if r not in (code[i], start[i])]
        for i, (name, ranked) in enumerate(zip(names, hypotheses, strict=True))
    }
    # A new object's other poses, tried before an overlap or a tip leaves it out.
    others = {
        i: [r for r in hypotheses[i].pose_ranks() if r not in (code[i], hypotheses[i].held_rank())] for i in droppable
    }
    early_exit = early_exit_rule(params, complete=False, moving=True)
    settlings, longest = check.settlings, check.longest_settling

    def ended(settling: Settling | None = None, pending: bool = False) -> PreviousMapCheck:
        return replace(
            check, code=tuple(code), settling=settling, pending=pending, settlings=settlings, longest_settling=longest
        )

    def repaired(culprits: set[int], reached: Collection[int], poses_left: dict[int, list[int]], every: bool) -> bool:
        if every or not check.held_last:
            held_or_left_out = _repaired(hypotheses, code, culprits, reached, new, droppable, holdable, poses_left)
            return held_or_left_out or _next_pose(code, culprits, nearer, every)
        # A refined map's rests stand together, not one by one: an overlapping object goes to its rest once the
        # poses near it are spent (a collision pass each); what moved goes there at once (a pose costs a settling).
        left_out = _repaired(hypotheses, code, culprits, reached, new, droppable, {}, poses_left)
        return left_out or _next_pose(code, culprits, nearer, every) or _held(code, reached, holdable)

    while settlings < CHECK_SETTLINGS:
        if _time_up(stop_at, longest):
            return ended(pending=True)  # a settling that would not end in time only takes the search's
        poses = _poses(hypotheses, code)
        collision = checker.find_collision(poses, params.penetration_threshold)
        while collision is not None:
            pair = {names.index(body) for body in collision.pair if body in names}
            if not repaired(pair, pair, others, every=False):
                return ended()
            poses = _poses(hypotheses, code)
            collision = checker.find_collision(poses, params.penetration_threshold)
        started = time.monotonic()
        outcome = checker.settle(poses, params.settle_time, params.angular_weight, stop_at, early_exit=early_exit)
        settlings, longest = settlings + 1, max(longest, time.monotonic() - started)
        if not isinstance(outcome, Settling):
            return ended(pending=True)
        if outcome.is_stable(params.jitter_threshold):
            return ended(outcome)
        moved = {i for i, jitter in enumerate(outcome.jitters) if jitter > params.jitter_threshold}
        retried: set[int] = set()
        tipped = {i for i in moved & droppable if code[i] == start[i] and others.get(i)}
        if tipped and not _time_up(stop_at, 2.0 * longest):  # time to confirm a pose found, and to leave one out
            tipped &= held_up(poses, shapes, checker.scene.static, params.jitter_threshold)
            retried = _next_standing_pose(checker, hypotheses, shapes, code, tipped, others, params, stop_at)
        culprits = moved - retried
        reached = within_reach(poses, shapes, culprits, TOUCHING)
        # What else moved takes no other pose: each costs a settling.
        if culprits and not repaired(culprits, reached, {}, every=True):
            return ended()
    return ended()


def _repaired(
    hypotheses: tuple[RankedHypotheses, ...],
    code: list[int],
    culprits: set[int],
    reached: Collection[int],
    new: Collection[int],
    droppable: set[int],
    holdable: dict[int, int],
    others: dict[int, list[int]],
) -> bool:
    """One repair of ``code`` where ``culprits`` broke a rule (module docstring): where one of them is not
    ``new``, the ``reached`` objects put at their held ranks (or, if none has one to go to, the culprits that
    may be absent left out, the first of them with a pose left in ``others`` first taking it); else the other
    way round. Whether anything changed."""

    def left_out() -> bool:
        return _next_pose(code, culprits, others, every=False) or _left_out(hypotheses, code, culprits, droppable)

    if culprits - set(new):
        return _held(code, reached, holdable) or left_out()
    return left_out() or _held(code, reached, holdable)


def _next_pose(code: list[int], objects: Collection[int], untried: dict[int, list[int]], every: bool) -> bool:
    """Move the first of ``objects`` that has one left (``every``: each that has) to its next pose in ``untried``
    (per object, the poses not tried yet, in the order to try them: near where it rested, nearest first, or a
    new object's in rank order); whether one moved. Of an overlapping pair one is enough to part them; each
    object that moved beyond the threshold needs its own."""
    found = [i for i in sorted(objects) if untried.get(i)]
    for i in found if every else found[:1]:
        code[i] = untried[i].pop(0)
    return bool(found)


def _next_standing_pose(
    checker: PhysicsChecker,
    hypotheses: tuple[RankedHypotheses, ...],
    shapes: Sequence[ObjectShape],
    code: list[int],
    tipped: Collection[int],
    others: dict[int, list[int]],
    params: SearchParams,
    stop_at: float | None,
) -> set[int]:
    """Move each of ``tipped`` (new objects that may be absent, held up at their poses in ``code``, yet moved
    beyond the threshold) to the first of its poses left in ``others`` that stands there in a local settling
    (:func:`_stands_locally`); those moved. Poses found not to stand are spent."""
    poses = list(_poses(hypotheses, code))
    found = set()
    for i in sorted(tipped):
        while others.get(i) and not _time_up(stop_at):
            rank = others[i].pop(0)
            poses[i] = hypotheses[i].pose(rank)
            if _stands_locally(checker, poses, shapes, i, params, stop_at):
                code[i] = rank
                found.add(i)
                break
        poses[i] = hypotheses[i].pose(code[i])
    return found


def _stands_locally(
    checker: PhysicsChecker,
    poses: Sequence[Pose],
    shapes: Sequence[ObjectShape],
    index: int,
    params: SearchParams,
    stop_at: float | None,
) -> bool:
    """Whether object ``index`` stays within the jitter threshold where it is at ``poses``, settled with the objects
    that hold it up (:func:`~physics_mapper.physics.support.holding`) and those its body box comes within
    :data:`TOUCHING` of (they may give way under it), those they touch held fixed: a few bodies, not the bin
    (module docstring)."""
    touched = sorted(
        within_reach(poses, shapes, {index}, TOUCHING) | holding(poses, shapes, index, params.jitter_threshold)
    )
    around = within_reach(poses, shapes, touched, TOUCHING) - set(touched)
    outcome = checker.settle(
        [poses[i] for i in touched],
        params.settle_time,
        params.angular_weight,
        stop_at,
        objects=touched,
        fixed=[(i, poses[i]) for i in sorted(around)],
        early_exit=early_exit_rule(params, complete=False, moving=True),
    )
    return isinstance(outcome, Settling) and outcome.is_stable(params.jitter_threshold)


def _held(code: list[int], culprits: Collection[int], holdable: dict[int, int]) -> bool:
    """Put those of ``culprits`` that are ``holdable`` (index -> held rank) at their held ranks in ``code`` (no
    longer holdable); whether there was one."""
    found = holdable.keys() & culprits
    for i in found:
        code[i] = holdable.pop(i)
    return bool(found)


def _left_out(
    hypotheses: tuple[RankedHypotheses, ...], code: list[int], culprits: set[int], droppable: set[int]
) -> bool:
    """Put those of ``culprits`` that are ``droppable`` at their *absent* ranks in ``code`` (no longer droppable);
    whether there was one."""
    found = droppable & culprits
    for i in found:
        absent = hypotheses[i].absent_rank()
        assert absent is not None  # droppable objects have one
        code[i] = absent
    droppable -= found
    return bool(found)


def _poses(hypotheses: Sequence[RankedHypotheses], code: Sequence[int]) -> tuple[Pose, ...]:
    """The poses of configuration ``code``, in object order."""
    return tuple(ranked.pose(rank) for ranked, rank in zip(hypotheses, code, strict=True))


def search_with_previous_map(
    checker: PhysicsChecker,
    hypotheses: Sequence[RankedHypotheses],
    params: SearchParams,
    remembered: Mapping[str, Pose],
    budget: float | None,
    previous: Search | None = None,
    last: PreviousMapCheck | None = None,
    refined: bool = False,
) -> tuple[Search, SearchResult, PreviousMapCheck | None]:
    """A tick's search with the previous map first (module docstring): the previous map's configuration
    checked within half of ``budget`` seconds (``last`` reused if it checked the same configuration of the
    same hypotheses; else what ``last`` put at held poses starts there), then the search made
    (:func:`~physics_mapper.search.strategy.make_search`, carrying over ``previous``) and run for the rest of
    ``budget``; where no valid map is remembered, the refined map's check once the search has its map, and
    where ``remembered`` holds a refined map's rests (``refined``), the check of the configuration nearest
    them, once the search has its map; a check left pending gone on with before the deadline, after the
    search. Where the previous map passed, the search runs without its fallback (a fallback map would only
    stand in for the previous map). Returns the search, its result or the previous map's where that is the
    valid one, and the check. The search ranks ``hypotheses`` without their *held* ones
    (:mod:`~physics_mapper.mapping.existence`): those are the check's."""
    started = time.monotonic()
    hypotheses = searchable(hypotheses)
    searched = tuple(ranked.without_held() for ranked in hypotheses)
    names = checker.scene.object_names
    code = previous_map_code(names, hypotheses, remembered)
    if code is not None:  # an instance more likely there than not starts where its poses agree
        code = present_where_likelier(code, hypotheses, [model.shape for model in checker.scene.objects], ())
    check = last if last is not None and (last.hypotheses, last.start) == (hypotheses, code) else None
    # A search resumed had its chance at the last tick (and one that finished touches no physics); a
    # settling the deadline interrupted lives in the world until the search resumes it.
    resumed = previous is not None and resumable(previous, checker, searched, params)
    waiting = previous is not None and settling_goes_on(previous, searched)
    # Where only a refined map is remembered, this tick's refined map comes first: it may be the only map.
    map_first = (code is None or refined) and params.fallback == "refine" and not resumed and not waiting
    unchecked = None
    if code is not None:
        new = tuple(i for i, name in enumerate(names) if name not in remembered)
        again = held_again(hypotheses, last)
        held = tuple(again.get(i, rank) for i, rank in enumerate(code))
        unchecked = PreviousMapCheck(hypotheses, code, held, remembered, new, carried=frozenset(again))
    if check is None and unchecked is not None and not (map_first or resumed or waiting):
        check = check_previous_map(checker, unchecked, params, None if budget is None else started + budget / 2.0)
    passed = check is not None and check.settling is not None
    search = make_search(checker, searched, replace(params, fallback="none") if passed else params, previous)
    stop_at = None if budget is None else started + budget
    # Of a check's valid map and the search's, the map is the one with the more probable pattern of existence
    # (where nothing may be absent, a tie: the search's stands). The first tick's refined map guides a check
    # even where the search found a valid map.
    compete = any(ranked.absent_rank() is not None for ranked in searched)
    first = unchecked is None and compete
    if map_first:
        result = _run_until_map(search, stop_at)
        if _time_up(stop_at) or (result.valid and not first):
            return search, result, None
        if unchecked is None:
            check = refined_map_check(checker, hypotheses, params, _guiding_map(search, result), stop_at)
        elif check is None:
            check = check_previous_map(checker, unchecked, params, stop_at)
    if check is not None and check.pending and not _time_up(stop_at, check.time_to_go_on):
        assert stop_at is not None  # without a deadline a check ends passed or failed
        result = _run_leaving(search, stop_at, check.time_to_go_on)
        if result.valid or _time_up(stop_at):
            return search, with_previous_map(result, check, compete), check
        check = check_previous_map(checker, check, params, stop_at)
    remaining = None if stop_at is None else max(0.0, stop_at - time.monotonic())
    return search, with_previous_map(search.run(remaining), check, compete), check


def result_hypotheses(
    hypotheses: Sequence[RankedHypotheses], result: SearchResult, check: PreviousMapCheck | None
) -> tuple[RankedHypotheses, ...]:
    """The hypotheses whose ranks ``result``'s code names: the ``check``'s where its map is the previous map's (the
    first tick's check adds *held* poses where the tick's refined map rests the instances: :func:`refined_map_check`),
    else ``hypotheses``."""
    return check.hypotheses if result.previous_map and check is not None else tuple(hypotheses)


def _guiding_map(search: Search, result: SearchResult) -> tuple[Code, tuple[Pose, ...]] | None:
    """The code and settled poses of the map that guides the first tick's check: the search's result where it
    holds the refined map (its groups found valid at their answers), the refined map the search made where
    the result is valid; None where it holds none."""
    if result.valid:
        refined = search.refined_map
        return None if refined is None else (refined.code, refined.settling.settled_poses)
    if result.fallback != "refine" or result.code is None or result.settled_poses is None:
        return None
    return result.code, result.settled_poses


def refined_map_check(
    checker: PhysicsChecker,
    hypotheses: tuple[RankedHypotheses, ...],
    params: SearchParams,
    guide: tuple[Code, tuple[Pose, ...]] | None,
    stop_at: float | None,
) -> PreviousMapCheck | None:
    """Where no valid map is remembered, the configuration nearest where the tick's refined map ``guide`` (its
    code and settled poses) rests the objects, those it leaves out left out, each instance it holds with a *held*
    pose at its rest there (module docstring), checked until ``stop_at`` (None: no refined map)."""
    if guide is None:
        return None
    guide_code, settled = guide
    scene = checker.scene
    names = scene.object_names
    chosen = zip(names, hypotheses, guide_code, settled, strict=True)
    rests = {name: pose for name, ranked, rank, pose in chosen if not ranked.is_absent(rank)}
    nearest = previous_map_code(names, hypotheses, rests)
    assert nearest is not None
    hypotheses = tuple(
        with_held(ranked, rests[name]) if name in rests and scene.is_instance(name) else ranked
        for name, ranked in zip(names, hypotheses, strict=True)
    )
    new = tuple(i for i, name in enumerate(names) if name not in rests)
    start = tuple(guide_code[i] if i in new else rank for i, rank in enumerate(nearest))
    check = PreviousMapCheck(hypotheses, start, start, rests, new, held_last=True)
    return check_previous_map(checker, check, params, stop_at)


def _time_up(stop_at: float | None, needed: float = 0.0) -> bool:
    """Whether less than ``needed`` seconds are left before ``stop_at`` (a ``time.monotonic()`` instant; None:
    no deadline)."""
    return stop_at is not None and time.monotonic() + needed >= stop_at


def _run_until_map(search: Search, stop_at: float | None) -> SearchResult:
    """``search`` run in :data:`MAP_SLICES` slices of the time to ``stop_at`` (to its end where None) until its
    result holds a map (a valid configuration or a fallback's) and it has checked a configuration of its own:
    its first, the most probable, is often valid where the one nearest the refined map is not (24 lego parts
    in two layers, named, seed 2: 22 ticks of 30 with a valid map where the check came first, 26 now)."""
    if stop_at is None:
        return search.run(None)
    piece = max(0.0, stop_at - time.monotonic()) / MAP_SLICES
    before = search.result().stats.visited
    while True:
        result = search.run(piece)
        tried = result.stats.visited > before
        if result.valid or (result.fallback is not None and tried) or search.done or _time_up(stop_at):
            return result


def _run_leaving(search: Search, stop_at: float, reserve: float) -> SearchResult:
    """``search`` run until ``reserve`` seconds before ``stop_at`` (time for a check), and on to ``stop_at`` where
    it has no map by then. In one run, not in slices: each slice that cuts a settling saves the world's state,
    7 ms for 24 mugs (slices there left ticks with no map at all)."""
    result = search.run(max(0.0, stop_at - time.monotonic() - reserve))
    if result.valid or (result.fallback is not None and not result.unsettled) or search.done:
        return result
    return search.run(max(0.0, stop_at - time.monotonic()))


def settling_goes_on(previous: Search, hypotheses: Sequence[RankedHypotheses]) -> bool:
    """Whether a search of ``hypotheses`` following ``previous`` may go on with its interrupted settling (the
    hypotheses of that settling's objects unchanged): the settling lives in the world, which a check would
    move. Where they changed, the next search starts that group afresh and the check may use the world."""
    objects = previous.settling_objects
    return bool(objects) and all(previous.hypotheses[i] == hypotheses[i] for i in objects)


def with_previous_map(result: SearchResult, check: PreviousMapCheck | None, compete: bool = False) -> SearchResult:
    """``result`` where it is valid (or no previous map passed); else the previous map's configuration, valid.
    With ``compete``, a valid ``result`` too gives way to it where its pattern of existence is the more
    probable (:func:`~physics_mapper.model.hypotheses.existence_probability`; on a tie the search's stands)."""
    if check is None or check.settling is None:
        return result
    if result.valid and not (compete and _likelier_pattern(check, result)):
        return result
    code, settling, hypotheses = check.code, check.settling, check.hypotheses
    groups = tuple(
        replace(
            group,
            valid=True,
            code=tuple(code[i] for i in group.objects),
            probability=math.prod(hypotheses[i].weight(code[i]) for i in group.objects),
            jitter=sum(settling.jitters[i] for i in group.objects),
        )
        for group in result.groups
    )
    return replace(
        result,
        valid=True,
        code=code,
        probability=math.prod(ranked.weight(rank) for ranked, rank in zip(hypotheses, code, strict=True)),
        jitter=settling.total_jitter,
        poses=_poses(hypotheses, code),
        settled_poses=settling.settled_poses,
        object_jitters=settling.jitters,
        fallback_used=False,
        fallback=None,
        refinement=None,
        groups=groups,
        previous_map=True,
    )


def _likelier_pattern(check: PreviousMapCheck, result: SearchResult) -> bool:
    """Whether ``check``'s configuration has a more probable pattern of existence than ``result``'s."""
    assert result.code is not None  # a valid result has a configuration
    hypotheses = check.hypotheses
    return existence_probability(hypotheses, check.code) > existence_probability(hypotheses, result.code)

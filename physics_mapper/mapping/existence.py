"""Which objects a tick's search may leave out of the map, and how likely each is absent (ROS-free).

At every tick each object gets the hypotheses the search ranks, from its input status and from
the map of the previous ticks (:class:`MapMemory`):

- **Fresh hypotheses** (received within ``max_age``) are searched as received. An instance that
  may not be there (a tentative track, or an instance of a ``count: {max: K}`` entry) gets one
  more, *absent*, with the weight w the association gives it
  (:meth:`~physics_mapper.mapping.association.InstanceTracks.absent_weight`); its other
  hypotheses are scaled by 1 - w.
- **Held**: an instance (an object of a tracked class) with fresh hypotheses that the last valid map held, one of
  whose fresh poses lies within :data:`~physics_mapper.mapping.previous_map.NEAR` of where it came to rest in that
  map, gets one more, *held*, at that rest pose, weighing :data:`~physics_mapper.mapping.previous_map.HELD_SHARE`
  of its lightest hypothesis: it ranks last. It is the previous map's check's alone: the search ranks this tick's
  inputs (a configuration at rest where it rested would have the least jitter and win over every fresh valid one,
  and the map would stay where it first became valid). An estimator's poses scatter a few millimetres around the
  truth from frame to frame, and a lego part stands on the studs under it only within a millimetre or two: in a
  bin standing still, a tick whose poses each miss by that much has no valid configuration of them, yet the map of
  the last tick still agrees with them. The previous map's check (:mod:`~physics_mapper.mapping.previous_map`)
  starts an instance seen where it rested (its nearest pose within
  :data:`~physics_mapper.mapping.previous_map.AGREE`) at its held pose, and puts an object that breaks a rule
  there, and the objects it touches, at their held poses. A map that holds an object at its held pose leaves the
  remembered pose as it was: settled again every tick, a map at rest would creep. Until a valid map holds any
  object (the first ticks of a bin), the last refined map stands in for the last valid map: its objects' rests are
  remembered (:meth:`MapMemory.remember`), the previous map's check (made after the tick's own refined map) starts
  from them, and an instance's held pose is its rest there; at the very first tick, the check guided by the tick's
  own refined map gives each instance a held pose at its rest there too. The refined map's objects rest together
  without overlapping, so where the tick's poses miss the studs, the rests a pose agrees with may still stand.
- **Silent** (its newest hypotheses older than ``max_age``, or its track ended): if the last valid
  map held it, its pose there is kept as one hypothesis beside *absent*, whose weight grows with the
  silence s (seconds since it fell silent): w_absent = 1 - exp(-s / max_age) / 2. From s = 0
  being absent is at least as likely as being there, so the search (which prefers the most
  probable pattern of existence among valid maps, then the least jitter) drops the object where
  nothing needs it and keeps it where another rests on it (leaving it out would make that one
  fall).
- **Not in the map and nothing fresh** (never seen, or dropped): *absent* alone, weight 1: the
  object is not in the world.

Named objects and confirmed instances of ``count: K`` with fresh hypotheses have no *absent*. Before the search,
an instance's poses seen a little inside the floor or a wall are moved out of it
(:mod:`~physics_mapper.mapping.seen_too_deep`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from physics_mapper.mapping.association import InstanceTracks
from physics_mapper.mapping.inputs import InputSnapshot
from physics_mapper.mapping.previous_map import with_held
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, absent_hypothesis
from physics_mapper.model.scene import Scene
from physics_mapper.physics.support import holding_up
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
    """What the valid maps held: each object's last pose in one (the chosen hypothesis's, ``poses``, and where
    it came to rest in Rule 2's settling, ``settled``), and since when each is silent. Until a valid map holds
    an object, the last refined map stands in for one in ``settled`` alone (:meth:`remember`)."""

    poses: dict[str, Pose] = field(default_factory=dict)
    settled: dict[str, Pose] = field(default_factory=dict)
    silent_since: dict[str, float] = field(default_factory=dict)

    @property
    def refined(self) -> bool:
        """Whether ``settled`` holds a refined map's rests: rests, but no valid map's poses (:meth:`remember`)."""
        return bool(self.settled) and not self.poses

    def remember(self, names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult) -> None:
        """Keep the chosen pose of every object a *valid* result's map holds; forget those it leaves out.

        An invalid map (a fallback's, or a search's best so far that failed a rule) is not remembered as a
        pose: its poses may lie inside a wall or another object, and kept as a silent object's only pose
        beside *absent* they would feed that conflict to every later search. An object the map holds at its
        *held* rank keeps the pose remembered (module docstring), or takes that pose where none was.

        While no valid map holds any object (the first ticks of a bin), a refined map's rests are kept in
        ``settled`` (replacing the last refined map's; ``refined`` says so): the next tick's previous-map check
        starts from the hypotheses nearest them, with *held* poses there, as from a valid map's."""
        if result.code is None or result.poses is None or result.settled_poses is None:
            return
        if not result.valid:
            if result.fallback == "refine" and not result.unsettled and not self.poses:
                chosen = zip(names, hypotheses, result.code, result.settled_poses, strict=True)
                self.settled = {name: settled for name, ranked, rank, settled in chosen if not ranked.is_absent(rank)}
            return
        chosen_poses = zip(names, hypotheses, result.code, result.poses, result.settled_poses, strict=True)
        for name, ranked, rank, pose, settled in chosen_poses:
            if ranked.is_absent(rank):
                self.poses.pop(name, None)
                self.settled.pop(name, None)
            elif not ranked.hypotheses[rank - 1].held or name not in self.poses:
                self.poses[name] = pose
                self.settled[name] = settled


def searched_hypotheses(
    snapshot: InputSnapshot, memory: MapMemory, tracks: InstanceTracks, now: float, max_age: float
) -> tuple[RankedHypotheses, ...]:
    """Every object's hypotheses for this tick's search, by the rules of the module docstring.

    ``tracks`` tell the instances and their weights of being absent; ``now`` and ``max_age`` are seconds.
    """
    searched = []
    for index, status in enumerate(snapshot.objects):
        name = status.name
        if status.hypotheses is not None:
            memory.silent_since.pop(name, None)
            weight = tracks.absent_weight(name)
            ranked = status.hypotheses if weight is None else with_absent(status.hypotheses, index, weight)
            rested = memory.settled.get(name)
            searched.append(
                ranked if rested is None or not tracks.scene.is_instance(name) else with_held(ranked, rested)
            )
            continue
        since = memory.silent_since.setdefault(name, now)
        last = memory.poses.get(name)
        if last is None:
            searched.append(RankedHypotheses((absent_hypothesis(index, 1.0),)))
        else:
            kept = RankedHypotheses((Hypothesis(last, 1.0),))
            searched.append(with_absent(kept, index, silent_absent_weight(now - since, max_age)))
    return tuple(searched)


class LeftOut(NamedTuple):
    """What physics left out of a map: ``placeless``, the objects it finds no place for, and ``cut_short``,
    those a valid map of a search the deadline stopped left out (a longer search might have kept them)."""

    placeless: tuple[str, ...]
    cut_short: tuple[str, ...]


def left_out_by_physics(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult | None
) -> LeftOut:
    """The objects physics finds no place for (``placeless``): those a *finished* search's map leaves out,
    and, in any map that leaves them out, those that may be absent and whose every other rank overlaps a
    static body or falls freely (ruled out before the search began: no configuration holds them); and those
    a *valid* map of a search the deadline stopped leaves out (``cut_short``: a verdict only once repeated,
    :data:`~physics_mapper.mapping.association.CUT_SHORT_LEAVINGS`). A search the deadline stopped without
    a valid map gives its best so far: no verdict.

    The previous map's configuration (:mod:`~physics_mapper.mapping.previous_map`) is no verdict either:
    it leaves out what the last map did not hold."""
    if result is None:
        return LeftOut((), ())
    placeless = _ruled_out_alone(names, hypotheses, result)
    if result.code is None or result.previous_map or not (result.stats.finished or result.valid):
        return LeftOut(placeless, ())
    absent = absent_objects(names, hypotheses, result)
    if result.stats.finished:
        return LeftOut(tuple(dict.fromkeys([*absent, *placeless])), ())
    return LeftOut(placeless, tuple(name for name in absent if name not in placeless))


def _ruled_out_alone(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult
) -> tuple[str, ...]:
    """The objects with an *absent* rank whose every other rank the search ruled out before it began
    by a body that is none of ``names`` (a static body), or as a free fall (no ``other``), and that the
    map leaves out (a refined map keeps such an object where another rests on it:
    :mod:`physics_mapper.physics.support`)."""
    ruled: dict[str, set[int]] = {}
    for ruling in result.ruled_out:
        if ruling.other not in names:
            ruled.setdefault(ruling.object, set()).add(ruling.rank)
    left_out = []
    for index, (name, ranked) in enumerate(zip(names, hypotheses, strict=True)):
        searched = ranked.without_held()  # the search's ranks
        present = set(searched.pose_ranks())
        in_map = result.code is not None and not ranked.is_absent(result.code[index])
        if len(present) < len(searched) and present <= ruled.get(name, set()) and not in_map:
            left_out.append(name)
    return tuple(left_out)


def twins(
    names: tuple[str, ...],
    hypotheses: tuple[RankedHypotheses, ...],
    result: SearchResult | None,
    tracks: InstanceTracks,
) -> tuple[tuple[str, str], ...]:
    """Pairs (instance, twin) of tracked instances of one class, the first of which the search ruled out at
    every pose because each overlaps the twin at every pose of the twin's (:mod:`~physics_mapper.search.ruling_out`):
    two tracks on one body (a second detection of a part a centimetre off, born as an instance of its own).
    Confirmed, neither may be absent, and no configuration holds both: every search ends with none valid
    until one track ends (:meth:`~physics_mapper.mapping.association.InstanceTracks.end_twins`). Two that a
    valid map holds both are two bodies: the poses of two neighbours can overlap in one frame while the
    previous map's check holds them where they rested (24 jenga blocks in two layers: the rule ended a
    confirmed block, and its name went to the next one born)."""
    if result is None:
        return ()
    held = set(held_by_valid_map(names, hypotheses, result))
    others: dict[str, set[str]] = {}
    ranks: dict[str, set[int]] = {}
    for ruling in result.ruled_out:
        if ruling.reason == "collision" and ruling.other in names:
            others.setdefault(ruling.object, set()).add(ruling.other)
            ranks.setdefault(ruling.object, set()).add(ruling.rank)
    found = []
    for name, ranked in zip(names, hypotheses, strict=True):
        poses = set(ranked.without_held().pose_ranks())  # the search's ranks
        if len(others.get(name, ())) != 1 or not poses or not poses <= ranks[name]:
            continue
        (twin,) = others[name]
        if tracks.same_class(name, twin) and not {name, twin} <= held:
            found.append((name, twin))
    return tuple(found)


def absent_objects(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult | None
) -> tuple[str, ...]:
    """The objects a result's map leaves out (all of them without a chosen configuration)."""
    if result is None or result.code is None:
        return names
    return tuple(
        name for name, ranked, rank in zip(names, hypotheses, result.code, strict=True) if ranked.is_absent(rank)
    )


def held_by_valid_map(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult | None
) -> tuple[str, ...]:
    """The objects a *valid* result's map holds (none for an invalid one): the instances a map may confirm.

    An invalid map (a fallback's, or the best so far of a search the deadline stopped) holds every
    object it was given, a detection inside a wall among them; confirmed by it, such a track would lose
    its *absent* and leave its object no rank physics allows."""
    if result is None or not result.valid or result.code is None:
        return ()
    left_out = absent_objects(names, hypotheses, result)
    return tuple(name for name in names if name not in left_out)


def holding_others_up(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult | None, scene: Scene
) -> tuple[str, ...]:
    """The objects of a result's map, valid or not, that hold another object of it up where it came to rest
    (:func:`~physics_mapper.physics.support.holding_up`); ``names`` are ``scene``'s objects, in its order."""
    if result is None or result.code is None or result.unsettled:
        return ()
    poses = result.settled_poses or result.poses
    if poses is None:
        return ()
    in_map = _in_map(names, hypotheses, result, poses)
    shapes = [model.shape for model in scene.objects]
    return tuple(names[i] for i in holding_up(in_map, shapes, scene.search.jitter_threshold))


def map_rests(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult
) -> dict[str, NDArray[np.float64]]:
    """Where a result's settled map put each object it holds (none for an unsettled one)."""
    if result.code is None or result.unsettled or result.settled_poses is None:
        return {}
    in_map = _in_map(names, hypotheses, result, result.settled_poses)
    return {
        name: np.asarray(pose.position, dtype=np.float64)
        for name, pose in zip(names, in_map, strict=True)
        if pose is not None
    }


def _in_map(
    names: tuple[str, ...], hypotheses: tuple[RankedHypotheses, ...], result: SearchResult, poses: Sequence[Pose]
) -> list[Pose | None]:
    """``poses`` (one per object of ``names``), None for each object the result's map leaves out."""
    left_out = set(absent_objects(names, hypotheses, result))
    return [None if name in left_out else pose for name, pose in zip(names, poses, strict=True)]


def learn_from_result(
    memory: MapMemory,
    tracks: InstanceTracks,
    names: tuple[str, ...],
    hypotheses: tuple[RankedHypotheses, ...],
    result: SearchResult | None,
    now: float,
) -> tuple[str, ...]:
    """What a tick's search teaches the next ticks: its map remembered if valid, the instances a valid map
    holds confirmed, those on which its map (any) holds another object up noted (misses do not end them),
    where it rested new instances taken as measurements of their tracks (:func:`map_rests`),
    and the tentative ones physics leaves out (:func:`left_out_by_physics`) ended at ``now`` (s), those
    valid maps cut short leave out once repeated, and one track of each pair of :func:`twins`. Returns the
    names whose tracks ended (their inputs are to be forgotten)."""
    if result is None:
        return ()
    memory.remember(names, hypotheses, result)
    tracks.keep(held_by_valid_map(names, hypotheses, result))
    tracks.hold_up(holding_others_up(names, hypotheses, result, tracks.scene))
    tracks.first_rests(map_rests(names, hypotheses, result))
    left_out = left_out_by_physics(names, hypotheses, result)
    ended = tracks.reject(left_out.placeless, left_out.cut_short, now)
    return (*ended, *tracks.end_twins(twins(names, hypotheses, result, tracks), now))

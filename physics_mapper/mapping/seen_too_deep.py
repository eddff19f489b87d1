"""An instance's poses seen a little inside a static body, moved out of it before the search (ROS-free).

An estimator's depth bias puts a part resting on the floor of a bin, or against its wall, a centimetre or two
into it, frame after frame: measured in a bin of 24 jenga blocks (``physics-mapper bench instances --seed 11``),
every pose of one block lay 6-13 mm low, its ends 10-18 mm into the floor, in each of the first five arrays.
Rule 1 rules such a pose out alone (it overlaps a static body deeper than the penetration threshold), and an
instance that may be absent is then left out of the map as a detection inside a wall would be: its track
ends, and its name goes to the next track born where it is seen again.

So before each tick's search, where every pose of an instance (but *absent* and *held*) overlaps a static body
deeper than the ``penetration_threshold``, each is moved out of it along the contact normal until the two
touch (:meth:`~physics_mapper.physics.checker.PhysicsChecker.moved_out_of_static`): the nearest pose Rule 1
admits against the static bodies, with the same weight. Only where every pose lies that deep: a depth bias
moves all of an estimator's poses of a part, while a single wrong pose pushed into the floor beside right
ones is what physics rules out (a lego part's best result, 3 cm off and into the floor, moved out, was
chosen over its right ones: ``bench instances --seed 12``, 6 parts). A pose cannot be moved out where the
move would exceed :data:`MOVE_LIMIT`, or where its body's centre lies behind the surface it would be moved out
of, more inside the static body than out of it; where one of an instance's poses cannot, none is moved (and
the search rules them out): a depth bias puts every pose a little low, while the poses of a false detection
inside a wall or under the floor scatter, some of them a little out of it. So a false detection stays
impossible, and is left out. Before, the one pose of such a detection that lay only a centimetre into the top
of a tray's rim 1.9 cm high was moved onto it, where a lego part rests, and valid maps held a part that was not
there for three frames (``bench instances --seed 31``, lego and flat parts 12 x 2: BENCHMARKS.md, "Bins of
identical objects", round 35). Named objects keep their poses as the estimator
gave them: their maps and the search's explanations (``solve``'s ruled-out ranks) are the user's, and a named
object is never absent.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.physics.checker import PhysicsChecker

#: Metres a pose is moved at most: beyond the depths measured (18 mm) with some margin; a deeper overlap is
#: more than a depth bias.
MOVE_LIMIT = 0.03


def moved_out_of_static(
    checker: PhysicsChecker, hypotheses: Sequence[RankedHypotheses], threshold: float
) -> tuple[tuple[RankedHypotheses, ...], int]:
    """``hypotheses`` (scene order) with the poses of each instance every pose of which overlaps a static body
    deeper than ``threshold`` metres moved out of it (module docstring), and how many poses were moved."""
    scene = checker.scene
    searched, moved = [], 0
    for index, ranked in enumerate(hypotheses):
        seen = [h for h in ranked.hypotheses if not (h.absent or h.held)]
        instance = scene.is_instance(scene.objects[index].name)
        deep = instance and bool(seen) and all(_too_deep(checker, index, h, threshold) for h in seen)
        out = _moved_out(checker, index, ranked, threshold) if deep else None
        searched.append(ranked if out is None else out)
        moved += 0 if out is None else len(seen)
    return tuple(searched), moved


def _too_deep(checker: PhysicsChecker, index: int, hypothesis: Hypothesis, threshold: float) -> bool:
    """Whether object ``index`` at ``hypothesis`` overlaps a static body deeper than ``threshold`` metres."""
    return checker.static_overlap(index, hypothesis.pose) > threshold


def _moved_out(
    checker: PhysicsChecker, index: int, ranked: RankedHypotheses, threshold: float
) -> RankedHypotheses | None:
    """Object ``index``'s ``ranked`` with each pose (not *absent*, not *held*) moved out of the static bodies, or
    None where one cannot be: a detection inside, not one seen too low (module docstring)."""
    moved = []
    for hypothesis in ranked.hypotheses:
        if not (hypothesis.absent or hypothesis.held):
            pose = checker.moved_out_of_static(index, hypothesis.pose, threshold, MOVE_LIMIT)
            if pose is None:
                return None
            hypothesis = replace(hypothesis, pose=pose)
        moved.append(hypothesis)
    return RankedHypotheses(tuple(moved))

"""What holds what up in a map, and which objects the refined map holds: those another object rests on,
not those it moved away from where they were seen (ROS-free).

``fallback: refine`` starts from the *live root* (each object at its most probable rank not ruled out
alone), so an object that may be absent and whose every pose was ruled out is left out of the refined
map. Where *absent* is that rank only because the object's poses share their weight (a tentative lego
part's five particle poses of 0.20 and less, 0.75 in all, against *absent*'s 0.25), the object is more
likely there than not: the refined map holds it at the pose not ruled out around which its poses within
half its size weigh most, where they weigh more than *absent* (:func:`present_where_likelier`). Where that
pose is its most probable, it starts as any object whose most probable hypothesis is a pose, at the
weighted mean of its poses around that one (:func:`~physics_mapper.physics.refine.refinement_start`):
started at that pose alone, a wrong pose that ranks first, 3 cm from the others, started it where no part
is. Where that wrong pose ranks first and the others agree without it (a lego part's: 0.20, then 0.14 four
times, *absent* 0.25), the four hold the part. Left out, it was a miss in the map. A detection
1 cm into the floor is ruled out for that alone (deeper than ``penetration_threshold``), yet the refinement
lifts such a pose out of the floor in a few iterations; left out, the box resting on it falls into its place,
and the map names the upper box where the lower one stands. So, as the silent
objects' rule has it (physics keeps an object where others rest on it), an object left out is put back
where an object of the map would otherwise have nothing under it.

In terms of axis-aligned body boxes (:func:`~physics_mapper.model.extents.body_box`), z along gravity,
tau = ``jitter_threshold`` (m):

- body B is *below* object X when their footprints (x-y extents) overlap, each axis by at least
  :data:`FOOTPRINT_SHARE` of the smaller extent, and B's box is lower than X's (both its low and its high
  z); B *holds X up* when it is below X and its top reaches X's bottom within tau (high_z(B) >= low_z(X) -
  tau): without anything holding it up, X would fall further than a stable object may move;
- X *stands* when a static plane lies within tau under its box, or its box centre's x and y lie within
  the x-y box of the bodies holding it up among the static bodies and the objects in the map (one under
  its centre, or two it bridges);
- while some object in the map does not stand, the objects left out below it, each at its most probable
  pose, are candidates: the one with the highest top (X would land on it first), of equal ones the most
  probable, is put back, and the rule runs again (the box put back may need its own support; a detection
  sunk deeper than tau into the floor holds nothing up until the refinement lifts it). Objects it never
  reaches stay out: a detection in the air or in a wall holds nothing up, and a second detection of a box
  that stands holds up nothing that box does not. Nor is an object whose box's centre lies in a static body
  (below the floor, in a wall) a candidate: what falls meets that static body first. A false detection of a
  jenga block 4-6 cm into the floor, put back under a block seen 2 cm high, was lifted out of the floor into
  the place of the block below, and the other came to rest a layer up.

Once refined, an object that may be absent and that the refinement moved out of the box its body filled at its
start, or farther than half its shape's largest extent (the association's default gate): it is no longer where it
was seen, and on
which no object of the map rests, is left out (:func:`leave_out_displaced`), repeated until none is. There
the objects are at rest, so *rests on* asks the bodies as well as their boxes: B holds X up, and B and X
touch (closest points within :data:`TOUCHING` m) along a normal that pushes X up, within 60 degrees of the
vertical (:data:`RESTING_NORMAL`; :func:`resting_pairs`). A tumbled part's box is far wider than its body:
a false detection in the air that fell and came to lean, tilted, against the wall and a part of the top
layer has a box under that part's, within tau of its bottom, yet holds nothing up (24 lego parts in two
layers, seed 2: the map kept it, a false object). A box
seen on top of one the estimator missed falls a whole layer into its place, and the map would name it where
the other box stands; a detection in the air the free-fall rule could not rule out falls onto the pile, and a
second detection of a box is pushed out of it: the map holds each of them where nothing was seen. A
confirmed instance moved as far (a lego part that slides off the studs it was seen on) stays where it was
seen, at its depenetrated pose (overlapping nothing; :class:`~physics_mapper.search.best_first.BestFirst`):
where it slid, the map would name it where a neighbour stands, or where nothing is. Named objects stay
where the refinement put them.

The objects of a map that hold another up (:func:`holding_up`) are also those whose tracks misses do not end
(:mod:`~physics_mapper.mapping.association`): the box under a stacked one is often hidden from the camera.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.extents import (
    FloatArray,
    body_box,
    inside_static,
    may_overlap_static,
    meets_box,
    shape_extents,
)
from physics_mapper.model.geometry import Pose, Vector3
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import ObjectShape, Plane, StaticBody
from physics_mapper.physics.collision import Proximity

#: Least share of the smaller footprint's extent, per horizontal axis, two footprints overlap by for one
#: body to be below another: a neighbour's box a few millimetres into the footprint (estimates' noise) is not.
FOOTPRINT_SHARE = 0.25

#: Metres between two bodies' closest points within which they touch (a settled map's resting contacts lie
#: within Bullet's margins, a fraction of a millimetre apart).
TOUCHING = 0.002
#: Least upward component (the cosine of the angle to the vertical) of the normal of a contact on which one
#: body rests on another: steeper, the contact pushes it sideways more than it holds it up.
RESTING_NORMAL = 0.5

#: A body's box: (low corner, high corner), metres.
_Box = tuple[FloatArray, FloatArray]


def present_where_likelier(
    root: Sequence[int],
    hypotheses: Sequence[RankedHypotheses],
    shapes: Sequence[ObjectShape],
    ruled_out: Collection[tuple[int, int]],
) -> tuple[int, ...]:
    """``root`` (ranks, 1-based) with each object it leaves out (at *absent*) put where its poses not ruled out
    (``ruled_out``: (object, rank) pairs) agree and together weigh more than *absent*: of the groups of those
    poses within half the shape's largest extent of one of them, the heaviest, at that one (the most probable
    of equal ones). The object is more likely there than not, though each of its poses alone is less likely
    than its absence (module docstring)."""
    ranks = list(root)
    for i, (ranked, rank) in enumerate(zip(hypotheses, root, strict=True)):
        live = [r for r in ranked.pose_ranks() if (i, r) not in ruled_out] if ranked.is_absent(rank) else []
        if not live:
            continue
        positions = np.array([ranked.pose(r).position for r in live])
        agreeing = np.linalg.norm(positions[:, None] - positions[None], axis=2) <= half_size(shapes[i])
        weights = agreeing @ np.array([ranked.weight(r) for r in live])
        heaviest = int(np.argmax(weights))
        if weights[heaviest] > ranked.weight(rank):
            ranks[i] = live[heaviest]
    return tuple(ranks)


def put_back_supports(
    root: Sequence[int],
    hypotheses: Sequence[RankedHypotheses],
    shapes: Sequence[ObjectShape],
    static: Sequence[StaticBody],
    jitter_threshold: float,
) -> tuple[int, ...]:
    """``root`` (ranks, 1-based, of the objects of ``hypotheses`` and ``shapes``) with the objects it leaves
    out (at *absent*) put back at their most probable pose where an object of the map has nothing else
    under it (module docstring)."""
    ranks = list(root)
    boxes = {
        i: body_box(shapes[i], ranked.pose(rank))
        for i, (ranked, rank) in enumerate(zip(hypotheses, ranks, strict=True))
        if not ranked.is_absent(rank)
    }
    most_probable = _most_probable_poses(hypotheses, ranks)
    left_out_boxes = {i: body_box(shapes[i], hypotheses[i].pose(rank)) for i, rank in most_probable.items()}
    # A body whose centre lies in a static body is met by what falls only after that static body.
    left_out = {
        i: rank
        for i, rank in most_probable.items()
        if not any(inside_static(body, (left_out_boxes[i][0] + left_out_boxes[i][1]) / 2.0) for body in static)
    }
    supports, planes = _static_supports(static)
    while left_out:
        lows, highs = _corners(list(boxes.values()))
        falling = _falling(lows, highs, supports, planes, jitter_threshold)
        waiting = list(left_out)
        left_lows, left_highs = _corners([left_out_boxes[i] for i in waiting])
        under_falling = _below_pairs(left_lows, left_highs, lows[falling], highs[falling]).any(axis=1)
        candidates = [waiting[k] for k in np.flatnonzero(under_falling)]
        if not candidates:
            break
        chosen = max(candidates, key=lambda i: (left_out_boxes[i][1][2], hypotheses[i].weight(left_out[i]), -i))
        ranks[chosen] = left_out.pop(chosen)
        boxes[chosen] = left_out_boxes[chosen]
    return tuple(ranks)


def held_up(
    poses: Sequence[Pose | None], shapes: Sequence[ObjectShape], static: Sequence[StaticBody], jitter_threshold: float
) -> frozenset[int]:
    """The objects of a map (``poses`` of the objects of ``shapes``, None for one the map leaves out) that stand
    (module docstring) on a static plane, on the other static bodies or on another object of the map, by index."""
    indices, lows, highs = _map_boxes(poses, shapes)
    supports, planes = _static_supports(static)
    falling = _falling(lows, highs, supports, planes, jitter_threshold)
    return frozenset(indices[k] for k in np.flatnonzero(~falling))


def holding_up(poses: Sequence[Pose | None], shapes: Sequence[ObjectShape], jitter_threshold: float) -> tuple[int, ...]:
    """The objects of a map (``poses`` of the objects of ``shapes``, None for one the map leaves out) that hold
    another object of the map up (module docstring), by index."""
    indices, lows, highs = _map_boxes(poses, shapes)
    holds = _holds_up_pairs(lows, highs, lows, highs, jitter_threshold)
    np.fill_diagonal(holds, False)
    return tuple(indices[k] for k in np.flatnonzero(holds.any(axis=1)))


def holding(
    poses: Sequence[Pose | None], shapes: Sequence[ObjectShape], above: int, jitter_threshold: float
) -> frozenset[int]:
    """The objects of a map (``poses`` of the objects of ``shapes``, None for one the map leaves out) that hold object
    ``above`` (in the map) up (module docstring), by index. No body is below itself: ``above`` is not among them."""
    indices, lows, highs = _map_boxes(poses, shapes)
    k = indices.index(above)
    holds = _holds_up_pairs(lows, highs, lows[k : k + 1], highs[k : k + 1], jitter_threshold)[:, 0]
    return frozenset(indices[j] for j in np.flatnonzero(holds))


def within_reach(
    poses: Sequence[Pose], shapes: Sequence[ObjectShape], objects: Collection[int], margin: float
) -> frozenset[int]:
    """``objects`` and every object (index into ``poses`` and ``shapes``) whose body box comes within ``margin``
    metres of one of theirs: what they may have leant on, or pushed, while moving that far."""
    lows, highs = _corners([body_box(shape, pose) for shape, pose in zip(shapes, poses, strict=True)])
    reached = set(objects)
    for i in objects:
        reached.update(np.flatnonzero(meets_box(lows, highs, lows[i] - margin, highs[i] + margin)).tolist())
    return frozenset(reached)


def moved_away(shapes: Sequence[ObjectShape], start: Sequence[Pose], settled: Sequence[Pose]) -> frozenset[int]:
    """The objects (indices) a refinement took from ``start`` to ``settled`` out of the box their body filled at
    ``start``, or farther than half their shape's largest extent: no longer where they were seen (module
    docstring)."""
    return frozenset(i for i, shape in enumerate(shapes) if _left_its_box(shape, start[i], settled[i].position))


def _left_its_box(shape: ObjectShape, start: Pose, position: Vector3) -> bool:
    """Whether ``position`` lies outside the box of the body at ``start`` along some axis, or farther from
    ``start``'s than :func:`half_size`: a flat part falling one layer has moved its own height, a fraction of its
    largest extent (the box, not the distance along the move: a few millimetres along a long block's length
    widen that by centimetres)."""
    moved = np.abs(np.subtract(position, start.position))
    low, high = body_box(shape, start)
    return bool(np.any(moved > (high - low) / 2.0) or np.linalg.norm(moved) > half_size(shape))


def half_size(shape: ObjectShape) -> float:
    """Half the largest extent (m) of ``shape``'s box: how far an object's poses may lie from where it was seen
    and still stand for it there (module docstring)."""
    return 0.5 * float(np.max(shape_extents(shape)))


def resting_pairs(proximities: Iterable[Proximity], objects: Sequence[int]) -> frozenset[tuple[int, int]]:
    """(below, above) pairs of objects (indices into ``objects``, scene indices) whose bodies touch, the
    contact pushing the upper one up (module docstring), from their closest points (``proximities`` of the
    objects at rest, found within at least :data:`TOUCHING` m)."""
    index = {scene_index: i for i, scene_index in enumerate(objects)}
    pairs = set()
    for near in proximities:
        if near.second is None or near.distance > TOUCHING:
            continue
        first, second, upward = index[near.first], index[near.second], near.normal[2]
        if upward >= RESTING_NORMAL:  # moving the first object up frees it: it rests on the second
            pairs.add((second, first))
        elif upward <= -RESTING_NORMAL:
            pairs.add((first, second))
    return frozenset(pairs)


def leave_out_displaced(
    code: Sequence[int],
    hypotheses: Sequence[RankedHypotheses],
    shapes: Sequence[ObjectShape],
    moved: Collection[int],
    settled: Sequence[Pose],
    resting: Collection[tuple[int, int]],
    jitter_threshold: float,
) -> tuple[int, ...]:
    """``code`` (ranks, 1-based) of a refined map whose objects came to rest at ``settled``, touching as
    ``resting`` says (:func:`resting_pairs`), with those of ``moved`` (:func:`moved_away`) set to *absent* where
    they may be absent and no object of the map rests on them (module docstring); repeated until none is."""
    ranks = list(code)
    absent = {i: rank for i in moved if (rank := hypotheses[i].absent_rank()) is not None}
    while True:
        in_map = [None if h.is_absent(r) else pose for h, r, pose in zip(hypotheses, ranks, settled, strict=True)]
        touching = {below for below, above in resting if in_map[below] is not None and in_map[above] is not None}
        holding = touching.intersection(holding_up(in_map, shapes, jitter_threshold))
        leaving = [i for i in absent if in_map[i] is not None and i not in holding]
        if not leaving:
            return tuple(ranks)
        for i in leaving:
            ranks[i] = absent[i]


def _most_probable_poses(hypotheses: Sequence[RankedHypotheses], ranks: Sequence[int]) -> dict[int, int]:
    """Per object left out (at *absent*) that has a pose, the rank of its most probable one."""
    found = {}
    for i, (ranked, rank) in enumerate(zip(hypotheses, ranks, strict=True)):
        poses = ranked.pose_ranks()
        if ranked.is_absent(rank) and poses:
            found[i] = poses[0]
    return found


def _holds_up_pairs(
    lows: FloatArray, highs: FloatArray, above_lows: FloatArray, above_highs: FloatArray, jitter_threshold: float
) -> NDArray[np.bool_]:
    """[i, j]: whether body i (box corners ``lows[i]``, ``highs[i]``: N x 3) holds body j (``above_lows[j]``,
    ``above_highs[j]``: M x 3) up (module docstring): below it, its top within ``jitter_threshold`` of its
    bottom. Pairwise at once: a map of 50 objects is 2,500 pairs."""
    return _below_pairs(lows, highs, above_lows, above_highs) & (
        highs[:, np.newaxis, 2] >= above_lows[np.newaxis, :, 2] - jitter_threshold
    )


def _below_pairs(
    lows: FloatArray, highs: FloatArray, above_lows: FloatArray, above_highs: FloatArray
) -> NDArray[np.bool_]:
    """[i, j]: whether body i is below body j (module docstring): footprints overlapping, its box lower."""
    low, high = lows[:, np.newaxis, :], highs[:, np.newaxis, :]
    above_low, above_high = above_lows[np.newaxis, :, :], above_highs[np.newaxis, :, :]
    overlap = np.minimum(high[..., :2], above_high[..., :2]) - np.maximum(low[..., :2], above_low[..., :2])
    smaller = np.minimum(high[..., :2] - low[..., :2], above_high[..., :2] - above_low[..., :2])
    below: NDArray[np.bool_] = (
        np.all(overlap >= FOOTPRINT_SHARE * smaller, axis=-1)
        & (low[..., 2] < above_low[..., 2])
        & (high[..., 2] < above_high[..., 2])
    )
    return below


def _corners(boxes: Sequence[_Box]) -> tuple[FloatArray, FloatArray]:
    """The boxes' low and high corners, each K x 3 (m)."""
    lows = np.array([low for low, _ in boxes], dtype=float).reshape(-1, 3)
    highs = np.array([high for _, high in boxes], dtype=float).reshape(-1, 3)
    return lows, highs


def _map_boxes(poses: Sequence[Pose | None], shapes: Sequence[ObjectShape]) -> tuple[list[int], FloatArray, FloatArray]:
    """The objects of a map (``poses`` of the objects of ``shapes``, None for one the map leaves out), by index, and
    their body boxes' low and high corners, each K x 3 (m), in the same order."""
    boxes = {
        i: body_box(shape, pose) for i, (shape, pose) in enumerate(zip(shapes, poses, strict=True)) if pose is not None
    }
    lows, highs = _corners(list(boxes.values()))
    return list(boxes), lows, highs


def _static_supports(static: Sequence[StaticBody]) -> tuple[tuple[FloatArray, FloatArray], list[StaticBody]]:
    """What may hold an object up among ``static``: the box corners of the bodies that are not planes, and the
    planes."""
    boxes = [body_box(body.shape, body.pose) for body in static if not isinstance(body.shape, Plane)]
    return _corners(boxes), [body for body in static if isinstance(body.shape, Plane)]


def _falling(
    lows: FloatArray,
    highs: FloatArray,
    supports: tuple[FloatArray, FloatArray],
    planes: Sequence[StaticBody],
    jitter_threshold: float,
) -> NDArray[np.bool_]:
    """Per object of the map (box ``lows[k]``, ``highs[k]``: K x 3), whether it does not stand (module
    docstring) on a plane of ``planes``, on another of the map's objects or on ``supports`` (the other static
    bodies' box corners)."""
    lowered = lows - np.array([0.0, 0.0, jitter_threshold])
    stands = np.zeros(len(lows), dtype=bool)
    for plane in planes:
        stands |= may_overlap_static(plane, lowered, highs, 0.0)
    body_lows, body_highs = np.vstack([lows, supports[0]]), np.vstack([highs, supports[1]])
    holds = _holds_up_pairs(body_lows, body_highs, lows, highs, jitter_threshold)  # [body, object]
    holds[np.arange(len(lows)), np.arange(len(lows))] = False
    centres = (lows[:, :2] + highs[:, :2]) / 2.0
    for k in np.flatnonzero(~stands & holds.any(axis=0)):
        under = holds[:, k]
        reach_low, reach_high = body_lows[under, :2].min(axis=0), body_highs[under, :2].max(axis=0)
        stands[k] = bool(np.all(reach_low <= centres[k]) and np.all(centres[k] <= reach_high))
    falling: NDArray[np.bool_] = ~stands
    return falling

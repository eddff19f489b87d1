"""Rule 1, volume separation: no two bodies overlap deeper than ``penetration_threshold`` (metres).

Only pairs involving an object count; static bodies may touch each other. Every pair's contacts
start from an empty contact cache and depend on the two bodies' poses alone, so a pair's depth
is the same whatever else is placed (:func:`contact_depths`) and whatever was checked before.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from physics_mapper.model.bullet import pybullet
from physics_mapper.model.geometry import Pose, Vector3
from physics_mapper.physics.world import PhysicsWorld


@dataclass(frozen=True)
class Collision:
    """Rule 1 violated: ``pair`` (object first) overlaps by ``depth`` metres."""

    pair: tuple[str, str]
    depth: float


@dataclass(frozen=True)
class Proximity:
    """The closest points of object ``first`` and a nearby body (object ``second``, or a static body: None).

    ``distance`` is their signed distance in metres, negative when they overlap (minus the
    penetration depth); ``normal`` is the unit vector along which moving ``first`` (or moving
    ``second`` the opposite way) increases it.
    """

    first: int
    second: int | None
    normal: Vector3
    distance: float


def deepest_collision(
    depths: Mapping[tuple[int, int], float], penetration_threshold: float, name: Callable[[int], str]
) -> Collision | None:
    """The deepest of body pairs' overlaps (m) beyond ``penetration_threshold``, or None.

    ``depths`` maps body index pairs, lower first (objects in scene order, then static bodies), to
    their deepest overlap; ``name`` names a body index. Of pairs that overlap equally deep the
    first in that order wins, so the answer does not depend on the order Bullet lists its contacts
    in (which depends on what the world held before).
    """
    deepest: tuple[float, tuple[int, int]] | None = None
    for pair in sorted(depths):
        depth = depths[pair]
        if depth > penetration_threshold and (deepest is None or depth > deepest[0]):
            deepest = (depth, pair)
    if deepest is None:
        return None
    depth, (first, second) = deepest
    return Collision((name(first), name(second)), depth)


def find_collision(world: PhysicsWorld, poses: Sequence[Pose], penetration_threshold: float) -> Collision | None:
    """Rule 1 with every object at ``poses``: the deepest overlap beyond ``penetration_threshold`` metres, or None."""
    world.place(poses)
    pybullet.performCollisionDetection(physicsClientId=world.client)
    return deepest_collision(_depths(world), penetration_threshold, world.body_name)


def contact_depths(world: PhysicsWorld, objects: Sequence[int], poses: Sequence[Pose]) -> dict[tuple[int, int], float]:
    """Rule 1 evidence with only ``objects`` (scene indices) placed at ``poses``, the others parked.

    Returns, for every pair of bodies with a contact point that involves one of ``objects``,
    the pair's deepest overlap in metres (a depth <= 0 is a gap within Bullet's contact
    threshold). A pair is named by body indices, lower first (:meth:`PhysicsWorld.body_name`).
    Each pair's depth is the one :func:`find_collision` sees with every object placed, bit for bit.
    """
    if len(poses) != len(objects):
        raise ValueError(f"{len(poses)} poses for {len(objects)} objects")
    world.save_kept()
    world.empty_contact_caches(world.placed)
    world.detect_only(tuple(objects))
    for index, pose in zip(objects, poses, strict=True):
        world.set_pose(index, pose)
    world.placed = tuple(objects)
    pybullet.performCollisionDetection(physicsClientId=world.client)
    return _depths(world)


def _depths(world: PhysicsWorld) -> dict[tuple[int, int], float]:
    """Every body pair's deepest overlap (m) among the world's contact points, pairs involving an object."""
    depths: dict[tuple[int, int], float] = {}
    bodies, object_count = world.body_index, len(world.object_uids)
    for contact in pybullet.getContactPoints(physicsClientId=world.client):
        body_a, body_b = bodies[contact[1]], bodies[contact[2]]
        pair = (body_a, body_b) if body_a < body_b else (body_b, body_a)
        if pair[0] >= object_count:
            continue  # two static bodies
        depth = -float(contact[8])
        if pair not in depths or depth > depths[pair]:
            depths[pair] = depth
    return depths


def proximities(
    world: PhysicsWorld, poses: Sequence[Pose], margin: float, objects: Sequence[int] | None = None
) -> tuple[Proximity, ...]:
    """Put ``objects`` (scene indices; None: all) at ``poses``, the others parked, and list their near bodies.

    One :class:`Proximity` per pair of a placed object and another placed object or a static
    body whose signed distance is below ``margin`` metres: Bullet's closest points (the
    deepest point and its normal for an overlap). Candidates come from the broadphase, the
    objects' bounding boxes grown by ``margin``. Each pair is listed once, in object order.
    """
    world.place(poses, objects)
    client = world.client
    indices = world.indices(objects)
    placed = set(indices)
    found: list[Proximity] = []
    for index in indices:
        uid = world.object_uids[index]
        low, high = pybullet.getAABB(uid, physicsClientId=client)
        grown = ([v - margin for v in low], [v + margin for v in high])
        near = pybullet.getOverlappingObjects(*grown, physicsClientId=client) or ()
        for other in sorted({body for body, _link in near}):
            other_index = world.object_index.get(other)
            if other_index is not None and (other_index not in placed or other_index <= index):
                continue  # itself, a parked object, or a pair already listed from the other side
            points = pybullet.getClosestPoints(uid, other, margin, physicsClientId=client)
            if points:
                closest = min(points, key=lambda point: float(point[8]))
                normal = (float(closest[7][0]), float(closest[7][1]), float(closest[7][2]))
                found.append(Proximity(index, other_index, normal, float(closest[8])))
    return tuple(found)


def clearance(world: PhysicsWorld, first: int, first_pose: Pose, second: int, second_pose: Pose, cap: float) -> float:
    """Metres between objects ``first`` and ``second`` (scene indices) were they at these poses, or ``cap``
    when they are at least that far apart; no body moves (Bullet's closest points of their collision
    shapes, placed at the poses). Negative: they would overlap.

    The shapes keep Bullet's default collision margin, which a mesh's body has not (a hull is
    inflated by up to 1 mm): the distance may fall short of the bodies' by a millimetre or two, never
    beyond it, so it errs towards the bodies touching.
    """
    points = pybullet.getClosestPoints(
        -1,
        -1,
        cap,
        collisionShapeA=world.object_shapes[first],
        collisionShapeB=world.object_shapes[second],
        collisionShapePositionA=first_pose.position,
        collisionShapeOrientationA=first_pose.orientation,
        collisionShapePositionB=second_pose.position,
        collisionShapeOrientationB=second_pose.orientation,
        physicsClientId=world.client,
    )
    return min((float(point[8]) for point in points), default=cap)


def static_overlap(world: PhysicsWorld, index: int, pose: Pose) -> float:
    """The deepest overlap, metres (0 if none), of object ``index`` at ``pose`` with the static bodies.

    Moves that object only (the world is reset by the next placement anyway); the other
    objects are not looked at, wherever they are.
    """
    deepest, _ = _deepest_static(world, index, pose, 0.0)
    return 0.0 if deepest is None else -float(deepest[8])


#: Moves :func:`moved_out_of_static` makes at most: one per static body a pose lies in (a floor, then a wall).
MOVES_OUT = 3


def moved_out_of_static(world: PhysicsWorld, index: int, pose: Pose, threshold: float, limit: float) -> Pose | None:
    """Object ``index`` at ``pose`` moved out of the static bodies it overlaps deeper than ``threshold`` metres,
    or None where it overlaps none that deep, or cannot be moved out.

    Each move is the deepest overlap's: along the static body's contact normal, by its depth, so that the
    two bodies touch (Bullet's shortest separating translation), at most :data:`MOVES_OUT` of them until no
    static body is overlapped deeper than ``threshold``. None where the moves add up to more than ``limit``
    metres, or where the body's centre (the middle of its axis-aligned box) lies behind the surface it
    would be moved out of: a body more inside the static body than out of it, such as a detection inside
    a wall, is not one seen a little too deep. The world is reset by the next placement.
    """
    seen = np.asarray(pose.position, dtype=float)
    moved = seen
    for move in range(MOVES_OUT):
        deepest, centre = _deepest_static(world, index, Pose(_vector(moved), pose.orientation), threshold)
        if deepest is None:
            return None if move == 0 else Pose(_vector(moved), pose.orientation)
        normal = np.asarray(deepest[7], dtype=float)  # the static body's, towards the object
        if float(np.dot(centre - np.asarray(deepest[6], dtype=float), normal)) <= 0.0:
            return None
        moved = moved - normal * float(deepest[8])
        if float(np.linalg.norm(moved - seen)) > limit:
            return None
    deepest, _ = _deepest_static(world, index, Pose(_vector(moved), pose.orientation), threshold)
    return Pose(_vector(moved), pose.orientation) if deepest is None else None


def _deepest_static(world: PhysicsWorld, index: int, pose: Pose, threshold: float) -> tuple[Any, np.ndarray]:
    """Object ``index`` put at ``pose``: its deepest closest point with a static body overlapped deeper than
    ``threshold`` metres (Bullet's tuple; None if none), and its body's centre (the middle of its box, m).
    Moves that object only: the world is reset by the next placement."""
    world.save_kept()
    if world.placed is not None and index not in world.placed:
        world.placed = (*world.placed, index)
    client, uid = world.client, world.object_uids[index]
    world.set_pose(index, pose)
    low, high = pybullet.getAABB(uid, physicsClientId=client)
    points = [
        point
        for other, _link in pybullet.getOverlappingObjects(low, high, physicsClientId=client) or ()
        if other not in world.object_index
        for point in pybullet.getClosestPoints(uid, other, 0.0, physicsClientId=client)
    ]
    deepest = min(points, key=lambda point: float(point[8]), default=None)
    centre = (np.asarray(low, dtype=float) + np.asarray(high, dtype=float)) / 2.0
    return (None if deepest is None or -float(deepest[8]) <= threshold else deepest), centre


def _vector(values: np.ndarray) -> Vector3:
    return (float(values[0]), float(values[1]), float(values[2]))

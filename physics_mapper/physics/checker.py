"""The two rigid-body rules of the paper, checked in one persistent pybullet world.

Rule 1, volume separation: no two bodies overlap deeper than a threshold (metres).
Rule 2, stability: under gravity for ``settle_time`` seconds, each object moves at
most ``jitter_threshold``, where object i's jitter is

    J_i = |p_i - p'_i| + angular_weight * angle(q_i, q'_i)

with p in metres and the rotation angle in radians (SPEC section 2).

The world is built once per :class:`PhysicsChecker`; configurations move the bodies,
restore a saved solver state and empty the contact caches, so no world is rebuilt per
configuration and the same configuration gives the same answer whatever was checked before
it: bit for bit on every configuration of the shipped problems at their settle times. Bullet
keeps a trace of earlier configurations that neither restoring the state nor emptying the
caches removes, visible only in long chaotic settlings (one pyramid configuration of 126,
settled 5 s, ends 1e-7 m apart in a fresh world).

A settling given a deadline (``stop_at``) that passes is interrupted, not abandoned: it returns
a :class:`PartialSettling` that :meth:`PhysicsChecker.resume_settling` continues where it
stopped, ending bit for bit where the same settling run uninterrupted on this checker ends.
Resumed at once, the world simply holds the interrupted simulation and goes on; if the world is
used for another configuration first, the interrupted simulation is saved (pybullet
``saveState``, about 0.5 ms) and restored on resume, positions, velocities and contact points,
measured bit for bit too (BENCHMARKS.md, "Interrupted settlings"). A checker keeps one
interrupted settling: interrupting another frees the first's saved state, and resuming the
first then simulates it again from its start (same result, more time); so does resuming after
other objects were parked or placed (see below).

The refinement (:mod:`physics_mapper.physics.refine`) and the grouped search's interaction groups
work on a subset of the objects: the others wait at their parking spots, far above and far apart,
where they touch nothing and are never reported, with their mass set to zero, which Bullet treats
as fixed: they are never integrated and cost almost nothing per step. An object placed again gets
its mass and inertia back before anything touches it. With every object placed, no mass changes
and the world steps exactly as it always did. Bullet re-enters a body whose mass changes into its
world, which changes the order it solves contacts in: box, sphere and cylinder settlings still end
bit for bit where a fresh world's do (measured on the pyramid's configurations over 5 s), mesh
settlings within a few micrometres (3.9e-6 m at most on the tabletop scene's ground truth).
:meth:`PhysicsChecker.proximities` lists the closest points of nearby bodies, and a settling may
cap the objects' speed (``max_speed``).

Early exit (:class:`EarlyExit`): a settling may stop before ``settle_time`` once every simulated
object has stayed at rest for :data:`REST_CHECKS` looks at it, or once an object has stayed at rest
with its jitter beyond the jitter threshold for as many looks. Beyond the threshold alone is not
enough: a rocking object's jitter passes the threshold and comes back (measured on the tabletop
mesh scene: 5 of 50 valid C11..1 were cut short as unstable). The state is looked at every
:data:`CLOCK_CHECK_STEPS` steps (the same instants as the clock), and looking does not change the
simulation, so a settling that does not stop early ends bit for bit where a full one does.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Literal, TypedDict, Unpack, overload

from physics_mapper.model.bullet import pybullet
from physics_mapper.model.geometry import (
    IDENTITY,
    ORIGIN,
    Pose,
    Vector3,
    compose_poses,
    inverse_pose,
    pose_displacement,
)
from physics_mapper.model.scene import Box, Cylinder, Mesh, Plane, Scene, SearchParams, Shape, Sphere

#: What pybullet raises when a world fails, e.g. once its physics server is disconnected: the
#: checker is unusable then, and a new one must be built (:class:`~physics_mapper.mapping.mapper.Mapper` does).
PhysicsEngineError: type[Exception] = pybullet.error

#: Bullet's default step, 240 Hz, in seconds.
TIME_STEP = 1.0 / 240.0
GRAVITY = -9.81  # m/s^2 along z
#: Simulation steps between two looks at the wall clock during settling: an interrupted settling
#: stops at most this many steps after its deadline, and a resumed one advances at least this many.
CLOCK_CHECK_STEPS = 8
#: Metres between the spots, far above any scene, where objects wait between configurations.
PARKING_SPACING = 1000.0
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
class Collision:
    """Rule 1 violated: ``pair`` (object first) overlaps by ``depth`` metres."""

    pair: tuple[str, str]
    depth: float


@dataclass(frozen=True)
class EarlyExit:
    """When a settling may stop before its ``settle_time``.

    ``rest_rate`` (m/s): an object is at rest while its jitter rate |v| + angular_weight * |omega|
    (linear speed in m/s, angular speed in rad/s) is at most this; once every simulated object has
    been at rest at :data:`REST_CHECKS` consecutive looks, the settling stops (``"rest"``).
    ``jitter_threshold`` (m + weighted rad): once an object has been at rest with its J_i beyond it at
    :data:`REST_CHECKS` consecutive looks, the settling stops (``"beyond_threshold"``): the object
    came to rest elsewhere. None keeps such a settling going (a complete settling).
    """

    rest_rate: float
    jitter_threshold: float | None


#: An object is at rest while its jitter rate (m/s, |v| + angular_weight * |omega|) would add at most
#: this share of ``jitter_threshold`` over a whole ``settle_time``.
REST_SHARE = 0.05


def early_exit_rule(params: SearchParams, complete: bool) -> EarlyExit | None:
    """When a settling may stop early under ``params`` (None: ``settle_exit: full``).

    At rest: jitter rate at most :data:`REST_SHARE` x jitter_threshold / settle_time (1 mm/s with
    the defaults). ``complete`` keeps a settling going past the jitter threshold (the settling a
    fallback may report), so it ends at rest or at ``settle_time``.
    """
    if params.settle_exit == "full" or params.settle_time <= 0.0:
        return None
    rest_rate = REST_SHARE * params.jitter_threshold / params.settle_time
    return EarlyExit(rest_rate, None if complete else params.jitter_threshold)


@dataclass(frozen=True)
class Settling:
    """Rule 2 measurement: poses after ``settle_time`` and each object's jitter J_i.

    ``stopped`` says why the settling ended before ``settle_time`` (None: it ran to the end);
    ``steps`` of ``steps_total`` :data:`TIME_STEP` steps were simulated. ``reach``, when the
    settling was asked to track it, is each object's :data:`PositionRange` over its start and every
    look at the world (every :data:`CLOCK_CHECK_STEPS` steps, and the end); ``extent`` the smallest
    box holding the object's body (Bullet's axis-aligned bounding box) at those moments.
    """

    settled_poses: tuple[Pose, ...]
    jitters: tuple[float, ...]
    stopped: SettleStop | None = None
    steps: int = 0
    steps_total: int = 0
    reach: tuple[PositionRange, ...] | None = None
    extent: tuple[PositionRange, ...] | None = None

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
    checker that interrupted it recognises it as the settling it kept. ``objects``,
    ``max_speed`` and ``early_exit`` are the settling's (see :meth:`PhysicsChecker.settle`), with
    ``fixed`` are objects held where they are (scene index, pose), with the consecutive looks so far
    with every object at rest (``rest_checks``) and with an object at rest beyond the jitter threshold
    (``beyond_checks``), and the ``reach`` and ``extent`` so far (None: not tracked; an extent not begun).
    """

    poses: tuple[Pose, ...]
    angular_weight: float
    steps_done: int
    steps_total: int
    objects: tuple[int, ...] | None = None
    max_speed: float | None = None
    early_exit: EarlyExit | None = None
    fixed: tuple[tuple[int, Pose], ...] = ()
    rest_checks: int = 0
    beyond_checks: int = 0
    reach: tuple[PositionRange, ...] | None = None
    extent: tuple[PositionRange, ...] | None = None

    def restarted(self) -> PartialSettling:
        """The same settling, not yet begun."""
        start = None if self.reach is None else _start_reach(self.poses)
        return replace(self, steps_done=0, rest_checks=0, beyond_checks=0, reach=start, extent=None)


def _start_reach(poses: Sequence[Pose]) -> tuple[PositionRange, ...]:
    return tuple((pose.position, pose.position) for pose in poses)


def _widened(reach: tuple[PositionRange, ...], poses: Sequence[Pose]) -> tuple[PositionRange, ...]:
    """Each range grown to hold the matching pose's position."""
    return _grown(reach, [(pose.position, pose.position) for pose in poses])


def _grown(ranges: tuple[PositionRange, ...], boxes: Sequence[PositionRange]) -> tuple[PositionRange, ...]:
    """Each range grown to hold the matching box."""
    grown = []
    for (low, high), (box_low, box_high) in zip(ranges, boxes, strict=True):
        p, q = box_low, box_high
        grown.append(
            (
                (min(low[0], p[0]), min(low[1], p[1]), min(low[2], p[2])),
                (max(high[0], q[0]), max(high[1], q[1]), max(high[2], q[2])),
            )
        )
    return tuple(grown)


class SettleOptions(TypedDict, total=False):
    """Keyword options of :meth:`PhysicsChecker.settle` (see there): which objects settle (scene
    indices; the others stay parked), a speed cap (m/s), an early exit, whether to record reach, and
    objects held fixed at given poses (scene index, pose) while the others settle."""

    objects: Sequence[int] | None
    max_speed: float | None
    early_exit: EarlyExit | None
    track_reach: bool
    fixed: Sequence[tuple[int, Pose]]


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


@dataclass(frozen=True)
class TrajectorySample:
    """The objects' poses ``time`` seconds into a simulation."""

    time: float
    poses: tuple[Pose, ...]


def inertial_frame(shape: Shape) -> Pose | None:
    """Where a body's centre of mass and principal axes are, in its own frame; None at its origin (primitives)."""
    if not isinstance(shape, Mesh) or shape.geometry.mass_properties is None:
        return None
    properties = shape.geometry.mass_properties
    return Pose(properties.centre_of_mass, properties.principal_axes)


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


class PhysicsChecker:
    """A pybullet (DIRECT) world holding a scene's static bodies and objects.

    Use as a context manager, or call :meth:`close`. Not thread-safe: one world per thread.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self._client = int(pybullet.connect(pybullet.DIRECT))
        if self._client < 0:
            raise PhysicsEngineError("pybullet could not start a world")
        self._bodies: list[int] = []
        self._names: dict[int, str] = {}
        # The interrupted settling a resume continues, and its saved state once the world was
        # used for something else (None while the world still holds that simulation).
        self._interrupted: PartialSettling | None = None
        self._interrupted_state: int | None = None
        # Objects (scene indices) waiting massless at their parking spots: not simulated; and those
        # that were when the kept interrupted settling stopped.
        self._massless: set[int] = set()
        self._interrupted_massless: set[int] = set()
        # Objects that may be away from their parking spots (None: any object may be).
        self._placed: tuple[int, ...] | None = None
        try:
            self._build()
        except Exception:
            self.close()
            raise

    def _build(self) -> None:
        client = self._client
        pybullet.setGravity(0.0, 0.0, GRAVITY, physicsClientId=client)
        pybullet.setTimeStep(TIME_STEP, physicsClientId=client)
        pybullet.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=client)
        statics = []
        for body in self.scene.static:
            uid = self._create(body.shape, 0.0, body.pose)
            pybullet.changeDynamics(uid, -1, lateralFriction=body.friction, physicsClientId=client)
            self._names[uid] = body.name
            statics.append(uid)
        # Per object, where its centre of mass frame is in its pose's frame (None: at the pose).
        self._inertial_frames: list[Pose | None] = []
        for model in self.scene.objects:
            uid = self._create(model.shape, model.mass, ORIGIN)
            pybullet.changeDynamics(
                uid,
                -1,
                lateralFriction=model.friction,
                rollingFriction=model.rolling_friction,
                physicsClientId=client,
            )
            self._names[uid] = model.name
            self._bodies.append(uid)
            self._inertial_frames.append(inertial_frame(model.shape))
        self._pose_frames = [None if frame is None else inverse_pose(frame) for frame in self._inertial_frames]
        # Object uid -> scene index: which contacts count for Rule 1, and how a pair is ordered.
        self._object_index = {uid: index for index, uid in enumerate(self._bodies)}
        # Every body's index as contact_depths names it: objects 0..N-1 in scene order, then statics.
        self._body_index = {uid: index for index, uid in enumerate(self._bodies + statics)}
        # Each object's mass and diagonal inertia, restored when it comes back from its parking spot.
        self._dynamics = [pybullet.getDynamicsInfo(uid, -1, physicsClientId=client)[:3:2] for uid in self._bodies]
        self._initial_state = pybullet.saveState(physicsClientId=client)

    def _create(self, shape: Shape, mass: float, pose: Pose) -> int:
        """A body of ``shape`` at ``pose`` (its own frame: a mesh's file frame), with ``mass`` kg (0: fixed).

        pybullet puts a body's centre of mass and principal axes at its *inertial frame*, given
        in the body's frame; the primitives' is the body frame. A mesh's comes from its mass
        properties, with its principal moments as the diagonal inertia (Bullet would otherwise
        use its bounding box's). pybullet then reports and sets the inertial frame's world pose,
        which :meth:`_place` and :meth:`_poses` convert.
        """
        client = self._client
        frame = inertial_frame(shape) if mass > 0.0 else None
        uid = int(
            pybullet.createMultiBody(
                baseMass=mass,
                baseCollisionShapeIndex=self._collision_shape(shape),
                basePosition=pose.position,
                baseOrientation=pose.orientation,
                baseInertialFramePosition=(frame or ORIGIN).position,
                baseInertialFrameOrientation=(frame or ORIGIN).orientation,
                physicsClientId=client,
            )
        )
        if isinstance(shape, Mesh):
            # Bullet inflates convex hulls by a 1 mm margin; the primitives are exact, and so are meshes.
            pybullet.changeDynamics(uid, -1, collisionMargin=0.0, physicsClientId=client)
            properties = shape.geometry.mass_properties
            if mass > 0.0 and properties is not None:
                inertia = [mass * moment for moment in properties.principal_moments]
                pybullet.changeDynamics(uid, -1, localInertiaDiagonal=inertia, physicsClientId=client)
        return uid

    def _collision_shape(self, shape: Shape) -> int:
        client = self._client
        if isinstance(shape, Box):
            half = [s / 2.0 for s in shape.size]
            return int(pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half, physicsClientId=client))
        if isinstance(shape, Sphere):
            return int(pybullet.createCollisionShape(pybullet.GEOM_SPHERE, radius=shape.radius, physicsClientId=client))
        if isinstance(shape, Cylinder):
            return int(
                pybullet.createCollisionShape(
                    pybullet.GEOM_CYLINDER, radius=shape.radius, height=shape.length, physicsClientId=client
                )
            )
        if isinstance(shape, Mesh):
            return self._mesh_collision_shape(shape)
        assert isinstance(shape, Plane)
        return int(pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=client))

    def _mesh_collision_shape(self, mesh: Mesh) -> int:
        """A triangle mesh, a convex hull, or a compound of convex parts loaded from the decomposition's OBJ."""
        client, geometry = self._client, mesh.geometry
        if mesh.collision == "triangle_mesh":
            vertices, indices = geometry.vertices.tolist(), geometry.faces.ravel().tolist()
            return int(
                pybullet.createCollisionShape(
                    pybullet.GEOM_MESH, vertices=vertices, indices=indices, physicsClientId=client
                )
            )
        if mesh.collision == "convex_hull":
            hull = geometry.parts[0].vertices.tolist()
            return int(pybullet.createCollisionShape(pybullet.GEOM_MESH, vertices=hull, physicsClientId=client))
        assert geometry.decomposition is not None
        return int(
            pybullet.createCollisionShape(
                pybullet.GEOM_MESH,
                fileName=str(geometry.decomposition.file),
                meshScale=list(mesh.scale),
                physicsClientId=client,
            )
        )

    @property
    def client_id(self) -> int:
        """pybullet's ``physicsClientId`` of this world (-1 once closed)."""
        return self._client

    def close(self) -> None:
        """Disconnect the pybullet world (idempotent; also after the world failed)."""
        if self._client >= 0:
            if pybullet.isConnected(physicsClientId=self._client):
                pybullet.disconnect(physicsClientId=self._client)  # frees every saved state
            self._client = -1
            self._interrupted = self._interrupted_state = None

    def __enter__(self) -> PhysicsChecker:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def _uids(self, objects: Sequence[int] | None) -> list[int]:
        """The bodies of the objects of these scene indices (None: every object, in scene order)."""
        return [self._bodies[index] for index in self._indices(objects)]

    def _indices(self, objects: Sequence[int] | None) -> Sequence[int]:
        """These scene indices, or (None) every object's, in scene order."""
        return range(len(self._bodies)) if objects is None else objects

    @property
    def all_objects(self) -> tuple[int, ...]:
        """Every object's scene index, in scene order."""
        return tuple(range(len(self._bodies)))

    def body_name(self, index: int) -> str:
        """Name of a body by the index :meth:`contact_depths` uses (objects, then static bodies)."""
        objects, statics = self.scene.objects, self.scene.static
        return objects[index].name if index < len(objects) else statics[index - len(objects)].name

    def _place(
        self, poses: Sequence[Pose], objects: Sequence[int] | None = None, fixed: Sequence[tuple[int, Pose]] = ()
    ) -> None:
        """Put ``objects`` (None: all) at ``poses``, from rest, and the ``fixed`` ones (scene index, pose)
        massless where given; every other object stays parked, massless."""
        indices = tuple(self._indices(objects))
        if len(poses) != len(indices):
            raise ValueError(f"{len(poses)} poses for {len(indices)} objects")
        self._save_interrupted()
        pybullet.restoreState(self._initial_state, physicsClientId=self._client)
        self._empty_contact_caches()
        self._simulate_only(indices)
        for index, pose in (*zip(indices, poses, strict=True), *fixed):
            self._set_pose(index, pose)
        self._placed = (*indices, *(index for index, _ in fixed))

    def _simulate_only(self, objects: tuple[int, ...]) -> None:
        """Give ``objects`` their masses back and every other object zero mass (no call when nothing changes)."""
        simulated = set(objects)
        for index, uid in enumerate(self._bodies):
            parked = index not in simulated
            if parked == (index in self._massless):
                continue
            if parked:
                pybullet.changeDynamics(uid, -1, mass=0.0, physicsClientId=self._client)
                self._massless.add(index)
            else:
                mass, inertia = self._dynamics[index]
                pybullet.changeDynamics(uid, -1, mass=mass, localInertiaDiagonal=inertia, physicsClientId=self._client)
                self._massless.discard(index)

    def _set_pose(self, index: int, pose: Pose) -> None:
        """Put object ``index``'s own frame at ``pose`` (pybullet places its inertial frame, see :meth:`_create`)."""
        frame = self._inertial_frames[index]
        placed = pose if frame is None else compose_poses(pose, frame)
        pybullet.resetBasePositionAndOrientation(
            self._bodies[index], placed.position, placed.orientation, physicsClientId=self._client
        )

    def _get_pose(self, index: int) -> Pose:
        """Object ``index``'s own frame's pose, from its inertial frame's pose that pybullet reports."""
        position, orientation = pybullet.getBasePositionAndOrientation(
            self._bodies[index], physicsClientId=self._client
        )
        pose = Pose((position[0], position[1], position[2]), tuple(orientation))
        frame = self._pose_frames[index]
        return pose if frame is None else compose_poses(pose, frame)

    def _empty_contact_caches(self, placed: Iterable[int] | None = None) -> None:
        """Drop every contact point, so that no simulation inherits another's.

        restoreState restores the contact points (and warm-start impulses) it saved and empties
        the other touching pairs', unless it saved none (Bullet skips empty manifolds, and the
        initial state has none): then it keeps every contact point the world holds. Parking the
        objects far apart and running collision detection empties them. ``placed``: only these
        objects are away from their parking spots (default: any may be).
        """
        for index in self.all_objects if placed is None else placed:
            parking = (PARKING_SPACING * (index + 1), PARKING_SPACING, PARKING_SPACING)
            uid = self._bodies[index]
            pybullet.resetBasePositionAndOrientation(uid, parking, IDENTITY, physicsClientId=self._client)
        pybullet.performCollisionDetection(physicsClientId=self._client)
        self._placed = ()

    def _save_interrupted(self) -> None:
        """Save the interrupted simulation the world holds, before the world is used for something else."""
        if self._interrupted is not None and self._interrupted_state is None:
            self._interrupted_state = pybullet.saveState(physicsClientId=self._client)

    def _forget_interrupted(self) -> None:
        if self._interrupted_state is not None:
            pybullet.removeState(self._interrupted_state, physicsClientId=self._client)
        self._interrupted = self._interrupted_state = None

    def _poses(self, objects: Sequence[int] | None = None) -> tuple[Pose, ...]:
        """The poses of ``objects`` (None: all), in their own frames."""
        return tuple(self._get_pose(index) for index in self._indices(objects))

    def find_collision(self, poses: Sequence[Pose], penetration_threshold: float) -> Collision | None:
        """Rule 1: the deepest overlap beyond ``penetration_threshold`` metres, or None.

        Only pairs involving an object count; static bodies may touch each other.
        """
        self._place(poses)
        pybullet.performCollisionDetection(physicsClientId=self._client)
        return deepest_collision(self._depths(), penetration_threshold, self.body_name)

    def contact_depths(self, objects: Sequence[int], poses: Sequence[Pose]) -> dict[tuple[int, int], float]:
        """Rule 1 evidence with only ``objects`` (scene indices) placed at ``poses``, the others parked.

        Returns, for every pair of bodies with a contact point that involves one of ``objects``,
        the pair's deepest overlap in metres (a depth <= 0 is a gap within Bullet's contact
        threshold). A pair is named by body indices, lower first: objects 0..N-1 in scene order,
        then static bodies N, N+1, ... (:meth:`body_name`). Each pair's depth is the one
        :meth:`find_collision` sees with every object placed, bit for bit: every pair's contacts
        start from an empty cache and depend on the two bodies' poses alone.
        """
        if len(poses) != len(objects):
            raise ValueError(f"{len(poses)} poses for {len(objects)} objects")
        self._save_interrupted()
        self._empty_contact_caches(self._placed)
        self._simulate_only(tuple(objects))  # Bullet skips pairs of two fixed bodies
        for index, pose in zip(objects, poses, strict=True):
            self._set_pose(index, pose)
        self._placed = tuple(objects)
        pybullet.performCollisionDetection(physicsClientId=self._client)
        return self._depths()

    def _depths(self) -> dict[tuple[int, int], float]:
        """Every body pair's deepest overlap (m) among the world's contact points, pairs involving an object."""
        depths: dict[tuple[int, int], float] = {}
        bodies = self._body_index
        for contact in pybullet.getContactPoints(physicsClientId=self._client):
            body_a, body_b = bodies[contact[1]], bodies[contact[2]]
            pair = (body_a, body_b) if body_a < body_b else (body_b, body_a)
            if pair[0] >= len(self._bodies):
                continue  # two static bodies
            depth = -float(contact[8])
            if pair not in depths or depth > depths[pair]:
                depths[pair] = depth
        return depths

    def proximities(
        self, poses: Sequence[Pose], margin: float, objects: Sequence[int] | None = None
    ) -> tuple[Proximity, ...]:
        """Put ``objects`` (scene indices; None: all) at ``poses``, the others parked, and list their near bodies.

        One :class:`Proximity` per pair of a placed object and another placed object or a static
        body whose signed distance is below ``margin`` metres: Bullet's closest points (the
        deepest point and its normal for an overlap). Candidates come from the broadphase, the
        objects' bounding boxes grown by ``margin``. Each pair is listed once, in object order.
        """
        self._place(poses, objects)
        client = self._client
        indices = self._indices(objects)
        placed = set(indices)
        found: list[Proximity] = []
        for index in indices:
            uid = self._bodies[index]
            low, high = pybullet.getAABB(uid, physicsClientId=client)
            grown = ([v - margin for v in low], [v + margin for v in high])
            near = pybullet.getOverlappingObjects(*grown, physicsClientId=client) or ()
            for other in sorted({body for body, _link in near}):
                other_index = self._object_index.get(other)
                if other_index is not None and (other_index not in placed or other_index <= index):
                    continue  # itself, a parked object, or a pair already listed from the other side
                points = pybullet.getClosestPoints(uid, other, margin, physicsClientId=client)
                if points:
                    closest = min(points, key=lambda point: float(point[8]))
                    normal = (float(closest[7][0]), float(closest[7][1]), float(closest[7][2]))
                    found.append(Proximity(index, other_index, normal, float(closest[8])))
        return tuple(found)

    def static_overlap(self, index: int, pose: Pose) -> float:
        """The deepest overlap, metres (0 if none), of object ``index`` at ``pose`` with the static bodies.

        Moves that object only (the world is reset by the next placement anyway); the other
        objects are not looked at, wherever they are.
        """
        self._save_interrupted()
        client, uid = self._client, self._bodies[index]
        self._set_pose(index, pose)
        self._placed = None if self._placed is None else (*self._placed, index)
        low, high = pybullet.getAABB(uid, physicsClientId=client)
        deepest = 0.0
        for other, _link in pybullet.getOverlappingObjects(low, high, physicsClientId=client) or ():
            if other not in self._object_index:
                for point in pybullet.getClosestPoints(uid, other, 0.0, physicsClientId=client):
                    deepest = max(deepest, -float(point[8]))
        return deepest

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
        object went (:attr:`Settling.reach`). ``fixed`` (scene index, pose) places further objects that
        do not move (massless, as parked ones) and are not measured: the others rest against them.
        """
        objects = options.get("objects")
        fixed = tuple(options.get("fixed", ()))
        self._place(poses, objects, fixed)
        plan = PartialSettling(
            poses=tuple(poses),
            angular_weight=angular_weight,
            steps_done=0,
            steps_total=round(settle_time / TIME_STEP),
            objects=None if objects is None else tuple(objects),
            max_speed=options.get("max_speed"),
            early_exit=options.get("early_exit"),
            fixed=fixed,
            reach=_start_reach(poses) if options.get("track_reach", False) else None,
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
        this checker no longer keeps (it interrupted another settling since, or the partial is
        another checker's, or objects were parked or placed since) is simulated again from its start.
        """
        if partial is not self._interrupted:
            self._place(partial.poses, partial.objects, partial.fixed)
            return self._simulate(partial.restarted(), stop_at)
        if self._interrupted_state is not None and self._massless != self._interrupted_massless:
            # Objects were parked or placed since (their masses changed): Bullet re-entered them into
            # its world, so the saved contact points would not come back as they were. Start over.
            self._forget_interrupted()
            self._place(partial.poses, partial.objects, partial.fixed)
            return self._simulate(partial.restarted(), stop_at)
        if self._interrupted_state is not None:
            self._empty_contact_caches()
            pybullet.restoreState(self._interrupted_state, physicsClientId=self._client)
            self._placed = (*self._indices(partial.objects), *(index for index, _ in partial.fixed))
        self._forget_interrupted()
        return self._simulate(partial, stop_at)

    def _simulate(self, plan: PartialSettling, stop_at: float | None) -> Settling | PartialSettling:
        """Step the world from ``plan.steps_done`` to ``plan.steps_total``, or until it may stop early
        or ``stop_at`` passes (:meth:`settle`)."""
        steps_done, steps_total = plan.steps_done, plan.steps_total
        uids = self._uids(plan.objects)
        watched = plan.early_exit is not None or plan.reach is not None
        rest_checks, beyond_checks, reach = plan.rest_checks, plan.beyond_checks, plan.reach
        extent = plan.extent
        if reach is not None and extent is None:
            extent = tuple(self._extents(uids))
        while steps_done < steps_total:
            batch_end = min(steps_done + CLOCK_CHECK_STEPS, steps_total)
            for _ in range(steps_done, batch_end):
                pybullet.stepSimulation(physicsClientId=self._client)
                if plan.max_speed is not None:
                    self._cap_speeds(uids, plan.max_speed)
            steps_done = batch_end
            if watched and steps_done < steps_total:
                poses = self._poses(plan.objects)
                if reach is not None and extent is not None:
                    reach, extent = _widened(reach, poses), _grown(extent, self._extents(uids))
                if plan.early_exit is not None:
                    jitters = self._jitters(plan.poses, poses, plan.angular_weight)
                    at_rest = self._at_rest(uids, plan.angular_weight, plan.early_exit.rest_rate)
                    threshold = plan.early_exit.jitter_threshold
                    beyond = threshold is not None and any(
                        resting and jitter > threshold for resting, jitter in zip(at_rest, jitters, strict=True)
                    )
                    beyond_checks = beyond_checks + 1 if beyond else 0
                    rest_checks = rest_checks + 1 if all(at_rest) else 0
                    if beyond_checks >= REST_CHECKS:
                        return Settling(poses, jitters, "beyond_threshold", steps_done, steps_total, reach, extent)
                    if rest_checks >= REST_CHECKS:
                        return Settling(poses, jitters, "rest", steps_done, steps_total, reach, extent)
            if stop_at is not None and steps_done < steps_total and time.monotonic() >= stop_at:
                self._forget_interrupted()
                self._interrupted = replace(
                    plan,
                    steps_done=steps_done,
                    rest_checks=rest_checks,
                    beyond_checks=beyond_checks,
                    reach=reach,
                    extent=extent,
                )
                self._interrupted_massless = set(self._massless)
                return self._interrupted
        settled = self._poses(plan.objects)
        if reach is not None and extent is not None:
            reach, extent = _widened(reach, settled), _grown(extent, self._extents(uids))
        jitters = self._jitters(plan.poses, settled, plan.angular_weight)
        return Settling(settled, jitters, None, steps_done, steps_total, reach, extent)

    def _extents(self, uids: Sequence[int]) -> list[PositionRange]:
        """Each body's axis-aligned bounding box now (metres)."""
        boxes: list[PositionRange] = []
        for uid in uids:
            low, high = pybullet.getAABB(uid, physicsClientId=self._client)
            boxes.append(((low[0], low[1], low[2]), (high[0], high[1], high[2])))
        return boxes

    @staticmethod
    def _jitters(start: Sequence[Pose], now: Sequence[Pose], angular_weight: float) -> tuple[float, ...]:
        return tuple(pose_displacement(a, b, angular_weight) for a, b in zip(start, now, strict=True))

    def _at_rest(self, uids: Sequence[int], angular_weight: float, rest_rate: float) -> list[bool]:
        """Per body, whether its jitter rate |v| + angular_weight * |omega| is at most ``rest_rate`` (m/s)."""
        resting = []
        for uid in uids:
            linear, angular = pybullet.getBaseVelocity(uid, physicsClientId=self._client)
            resting.append(math.hypot(*linear) + angular_weight * math.hypot(*angular) <= rest_rate)
        return resting

    def _cap_speeds(self, uids: Sequence[int], max_speed: float) -> None:
        """Scale down every linear velocity faster than ``max_speed`` m/s to that speed (same direction)."""
        for uid in uids:
            linear, angular = pybullet.getBaseVelocity(uid, physicsClientId=self._client)
            speed = math.hypot(*linear)
            if speed > max_speed:
                scale = max_speed / speed
                capped = [v * scale for v in linear]
                pybullet.resetBaseVelocity(uid, capped, angular, physicsClientId=self._client)

    def trajectory(
        self, poses: Sequence[Pose], duration: float, sample_interval: float
    ) -> tuple[TrajectorySample, ...]:
        """Simulate ``duration`` seconds from rest at ``poses``, recording the objects' poses.

        Returns a sample at time 0 and then every ``sample_interval`` seconds (rounded to
        whole :data:`TIME_STEP` steps, at least one). For plots and inspection; the rules use
        :meth:`settle`, which steps the same world the same way.
        """
        self._place(poses)
        steps_per_sample = max(1, round(sample_interval / TIME_STEP))
        samples = [TrajectorySample(0.0, self._poses())]
        for step in range(1, round(duration / TIME_STEP) + 1):
            pybullet.stepSimulation(physicsClientId=self._client)
            if step % steps_per_sample == 0:
                samples.append(TrajectorySample(step * TIME_STEP, self._poses()))
        return tuple(samples)

"""The two rigid-body rules of the paper, checked in one persistent pybullet world.

Rule 1, volume separation: no two bodies overlap deeper than a threshold (metres).
Rule 2, stability: under gravity for ``settle_time`` seconds, each object moves at
most ``jitter_threshold``, where object i's jitter is

    J_i = |p_i - p'_i| + angular_weight * angle(q_i, q'_i)

with p in metres and the rotation angle in radians (SPEC section 2).

The world is built once per :class:`PhysicsChecker`; configurations move the bodies,
restore a saved solver state and empty the contact caches, so no world is rebuilt per
configuration and the same configuration always gives the same answer, whatever was
checked before it.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import pybullet

from physics_mapper.geometry import IDENTITY, ORIGIN, Pose, pose_displacement
from physics_mapper.scene import Box, Cylinder, Plane, Scene, Shape, Sphere

#: Bullet's default step, 240 Hz, in seconds.
TIME_STEP = 1.0 / 240.0
GRAVITY = -9.81  # m/s^2 along z
#: Simulation steps between two looks at the wall clock during settling.
CLOCK_CHECK_STEPS = 8
#: Metres between the spots, far above any scene, where objects wait between configurations.
PARKING_SPACING = 1000.0


@dataclass(frozen=True)
class Collision:
    """Rule 1 violated: ``pair`` (object first) overlaps by ``depth`` metres."""

    pair: tuple[str, str]
    depth: float


@dataclass(frozen=True)
class Settling:
    """Rule 2 measurement: poses after ``settle_time`` and each object's jitter J_i."""

    settled_poses: tuple[Pose, ...]
    jitters: tuple[float, ...]

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


@dataclass(frozen=True)
class Snapshot:
    """The objects' poses ``time`` seconds into a simulation."""

    time: float
    poses: tuple[Pose, ...]


class PhysicsChecker:
    """A pybullet (DIRECT) world holding a scene's static bodies and objects.

    Use as a context manager, or call :meth:`close`. Not thread-safe: one world per thread.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self._client = pybullet.connect(pybullet.DIRECT)
        self._bodies: list[int] = []
        self._names: dict[int, str] = {}
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
        for body in self.scene.static:
            uid = self._create(body.shape, 0.0, body.pose)
            pybullet.changeDynamics(uid, -1, lateralFriction=body.friction, physicsClientId=client)
            self._names[uid] = body.name
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
        self._initial_state = pybullet.saveState(physicsClientId=client)

    def _create(self, shape: Shape, mass: float, pose: Pose) -> int:
        client = self._client
        if isinstance(shape, Box):
            half = [s / 2.0 for s in shape.size]
            collision = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half, physicsClientId=client)
        elif isinstance(shape, Sphere):
            collision = pybullet.createCollisionShape(pybullet.GEOM_SPHERE, radius=shape.radius, physicsClientId=client)
        elif isinstance(shape, Cylinder):
            collision = pybullet.createCollisionShape(
                pybullet.GEOM_CYLINDER, radius=shape.radius, height=shape.length, physicsClientId=client
            )
        else:
            assert isinstance(shape, Plane)
            collision = pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=client)
        return int(
            pybullet.createMultiBody(
                baseMass=mass,
                baseCollisionShapeIndex=collision,
                basePosition=pose.position,
                baseOrientation=pose.orientation,
                physicsClientId=client,
            )
        )

    def close(self) -> None:
        """Disconnect the pybullet world (idempotent)."""
        if self._client >= 0:
            pybullet.disconnect(physicsClientId=self._client)
            self._client = -1

    def __enter__(self) -> PhysicsChecker:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def _place(self, poses: Sequence[Pose]) -> None:
        if len(poses) != len(self._bodies):
            raise ValueError(f"{len(poses)} poses for {len(self._bodies)} objects")
        # Restoring the saved state resets velocities, but Bullet keeps its contact points (and
        # their warm-start impulses) across restoreState. Parking the objects far apart and
        # running collision detection empties them, so no configuration inherits its predecessor's.
        pybullet.restoreState(self._initial_state, physicsClientId=self._client)
        for index, uid in enumerate(self._bodies):
            parking = (PARKING_SPACING * (index + 1), PARKING_SPACING, PARKING_SPACING)
            pybullet.resetBasePositionAndOrientation(uid, parking, IDENTITY, physicsClientId=self._client)
        pybullet.performCollisionDetection(physicsClientId=self._client)
        for uid, pose in zip(self._bodies, poses, strict=True):
            pybullet.resetBasePositionAndOrientation(uid, pose.position, pose.orientation, physicsClientId=self._client)

    def _poses(self) -> tuple[Pose, ...]:
        poses = []
        for uid in self._bodies:
            position, orientation = pybullet.getBasePositionAndOrientation(uid, physicsClientId=self._client)
            poses.append(Pose((position[0], position[1], position[2]), tuple(orientation)))
        return tuple(poses)

    def find_collision(self, poses: Sequence[Pose], penetration_threshold: float) -> Collision | None:
        """Rule 1: the deepest overlap beyond ``penetration_threshold`` metres, or None.

        Only pairs involving an object count; static bodies may touch each other.
        """
        self._place(poses)
        pybullet.performCollisionDetection(physicsClientId=self._client)
        objects = set(self._bodies)
        deepest: Collision | None = None
        for contact in pybullet.getContactPoints(physicsClientId=self._client):
            body_a, body_b, distance = contact[1], contact[2], contact[8]
            if body_a not in objects and body_b not in objects:
                continue
            depth = -float(distance)
            if depth > penetration_threshold and (deepest is None or depth > deepest.depth):
                deepest = Collision(self._pair(body_a, body_b), depth)
        return deepest

    def _pair(self, body_a: int, body_b: int) -> tuple[str, str]:
        """Names of a colliding pair, objects before statics, objects in scene order."""
        order = {uid: i for i, uid in enumerate(self._bodies)}
        first, second = sorted((body_a, body_b), key=lambda uid: order.get(uid, len(order) + uid))
        return self._names[first], self._names[second]

    def settle(
        self, poses: Sequence[Pose], settle_time: float, angular_weight: float, stop_at: float | None = None
    ) -> Settling | None:
        """Rule 2: simulate ``settle_time`` seconds from rest at ``poses``; measure each J_i.

        ``stop_at`` is a ``time.monotonic()`` instant; if it passes before settling ends the
        simulation is abandoned and None is returned, so a caller never overruns its deadline
        by more than :data:`CLOCK_CHECK_STEPS` steps.
        """
        self._place(poses)
        steps = round(settle_time / TIME_STEP)
        for step in range(steps):
            if stop_at is not None and step % CLOCK_CHECK_STEPS == 0 and time.monotonic() >= stop_at:
                return None
            pybullet.stepSimulation(physicsClientId=self._client)
        settled = self._poses()
        jitters = tuple(pose_displacement(a, b, angular_weight) for a, b in zip(poses, settled, strict=True))
        return Settling(settled, jitters)

    def trajectory(self, poses: Sequence[Pose], duration: float, sample_interval: float) -> tuple[Snapshot, ...]:
        """Simulate ``duration`` seconds from rest at ``poses``, recording the objects' poses.

        Returns a snapshot at time 0 and then every ``sample_interval`` seconds (rounded to
        whole :data:`TIME_STEP` steps, at least one). For plots and inspection; the rules use
        :meth:`settle`, which steps the same world the same way.
        """
        self._place(poses)
        steps_per_sample = max(1, round(sample_interval / TIME_STEP))
        snapshots = [Snapshot(0.0, self._poses())]
        for step in range(1, round(duration / TIME_STEP) + 1):
            pybullet.stepSimulation(physicsClientId=self._client)
            if step % steps_per_sample == 0:
                snapshots.append(Snapshot(step * TIME_STEP, self._poses()))
        return tuple(snapshots)

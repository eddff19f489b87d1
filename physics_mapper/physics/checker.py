"""The paper's two rigid-body rules in one persistent pybullet world: :class:`PhysicsChecker`.

Rule 1 (:mod:`~physics_mapper.physics.collision`): no two bodies overlap deeper than a threshold
(metres). Rule 2 (:mod:`~physics_mapper.physics.settling`): under gravity for ``settle_time``
seconds, each object moves at most ``jitter_threshold``. The world they share
(:mod:`~physics_mapper.physics.world`) is built once per checker and posed per configuration.
"""

from __future__ import annotations

from collections.abc import Sequence

from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Scene
from physics_mapper.physics import collision
from physics_mapper.physics.collision import Collision, Proximity
from physics_mapper.physics.settling import Settler
from physics_mapper.physics.world import PhysicsWorld


class PhysicsChecker:
    """Rule 1 and Rule 2 of a scene, checked in its own pybullet world.

    Bodies are named by body indices: objects 0..N-1 in scene order, then static bodies. Use as a
    context manager, or call :meth:`close`. Not thread-safe: one checker per thread.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.world = PhysicsWorld(scene)
        settler = Settler(self.world)
        #: Rule 2 from rest at given poses, interrupted at ``stop_at`` (:meth:`Settler.settle`).
        self.settle = settler.settle
        #: Continue an interrupted settling (:meth:`Settler.resume_settling`).
        self.resume_settling = settler.resume_settling
        #: The objects' poses every ``sample_interval`` s of a simulation from rest (:meth:`Settler.trajectory`).
        self.trajectory = settler.trajectory

    @property
    def client_id(self) -> int:
        """pybullet's ``physicsClientId`` of this world (-1 once closed)."""
        return self.world.client

    @property
    def all_objects(self) -> tuple[int, ...]:
        """Every object's scene index, in scene order."""
        return self.world.all_objects

    def body_name(self, index: int) -> str:
        """Name of a body by its body index (objects, then static bodies)."""
        return self.world.body_name(index)

    def close(self) -> None:
        """Disconnect the pybullet world (idempotent; also after the world failed)."""
        self.world.close()

    def __enter__(self) -> PhysicsChecker:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def find_collision(self, poses: Sequence[Pose], penetration_threshold: float) -> Collision | None:
        """Rule 1: the deepest overlap beyond ``penetration_threshold`` metres, or None."""
        return collision.find_collision(self.world, poses, penetration_threshold)

    def contact_depths(self, objects: Sequence[int], poses: Sequence[Pose]) -> dict[tuple[int, int], float]:
        """Rule 1 evidence of ``objects`` at ``poses``, the others parked (:func:`~collision.contact_depths`)."""
        return collision.contact_depths(self.world, objects, poses)

    def proximities(
        self, poses: Sequence[Pose], margin: float, objects: Sequence[int] | None = None
    ) -> tuple[Proximity, ...]:
        """Pairs of placed bodies closer than ``margin`` metres (:func:`~collision.proximities`)."""
        return collision.proximities(self.world, poses, margin, objects)

    def clearance(self, first: int, first_pose: Pose, second: int, second_pose: Pose, cap: float) -> float:
        """Metres between two objects' bodies were they at these poses, at most ``cap``
        (:func:`~collision.clearance`)."""
        return collision.clearance(self.world, first, first_pose, second, second_pose, cap)

    def static_overlap(self, index: int, pose: Pose) -> float:
        """Object ``index``'s deepest overlap (m) at ``pose`` with the static bodies."""
        return collision.static_overlap(self.world, index, pose)

    def moved_out_of_static(self, index: int, pose: Pose, threshold: float, limit: float) -> Pose | None:
        """Object ``index`` at ``pose`` moved out of the static bodies it overlaps deeper than ``threshold``
        metres, by at most ``limit`` metres, or None (:func:`~collision.moved_out_of_static`)."""
        return collision.moved_out_of_static(self.world, index, pose, threshold, limit)

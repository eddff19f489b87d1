"""One persistent pybullet world holding a scene: its bodies built once, then posed, parked and stepped.

The world is built once per :class:`PhysicsWorld`; configurations move the bodies, restore a
saved solver state and empty the contact caches, so no world is rebuilt per configuration and
the same configuration gives the same answer whatever was checked before it: bit for bit on
every configuration of the shipped problems at their settle times. Bullet keeps a trace of
earlier configurations that neither restoring the state nor emptying the caches removes, visible
only in long chaotic settlings (one pyramid configuration of 126, settled 5 s, ends 1e-7 m apart
in a fresh world).

Parking. The refinement and the interaction groups work on a subset of the objects: the others
(and objects whose hypothesis is *absent*, :func:`~physics_mapper.model.hypotheses.absent_hypothesis`)
wait at their parking spots, far above and far apart, where they touch nothing and are never
reported, with their mass set to zero, which Bullet treats as fixed: they are never integrated
and cost almost nothing per step. An object placed again gets its mass and inertia back before
anything touches it. With every object placed, no mass changes and the world steps exactly as it
always did. Bullet re-enters a body whose mass changes into its world, and solves contacts in the
order bodies entered it; so every change of which objects are simulated re-enters all of them in one
order (:meth:`PhysicsWorld.simulate_only`), and a settling ends bit for bit where a fresh world's does,
whatever earlier work parked. Re-entering only the objects whose mass changed left settlings to the
history: mesh settlings a few micrometres apart mostly, but a part the tabletop's hypotheses put
rocking on an edge came to rest within the jitter threshold in a fresh world (J 0.6 cm) and 1.6 cm
beyond it after one collision pass of two other objects, a verdict no search could rely on. The
re-entry costs about 6 us per object and change (0.6 ms for 50 objects), so a collision pass, which
steps nothing, re-enters only the objects whose mass changes (:meth:`PhysicsWorld.detect_only`).

A kept simulation. A simulation interrupted by its deadline (Rule 2,
:mod:`physics_mapper.physics.settling`) may be continued later. While nothing else used the
world, the world simply holds it; before the world is used for anything else it is saved
(pybullet ``saveState``, about 0.5 ms): :meth:`PhysicsWorld.keep_simulation`,
:meth:`PhysicsWorld.restore_kept` and :meth:`PhysicsWorld.forget_kept`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from physics_mapper.model.bullet import pybullet
from physics_mapper.model.geometry import ORIGIN, Pose, Vector3, compose_poses, inverse_pose
from physics_mapper.model.hypotheses import parking_pose
from physics_mapper.model.scene import Box, Cylinder, Mesh, Plane, Scene, Shape, Sphere

#: What pybullet raises when a world fails, e.g. once its physics server is disconnected: the
#: world is unusable then, and a new one must be built (:class:`~physics_mapper.mapping.mapper.Mapper` does).
PhysicsEngineError: type[Exception] = pybullet.error

#: Bullet's default step, 240 Hz, in seconds.
TIME_STEP = 1.0 / 240.0
GRAVITY = -9.81  # m/s^2 along z
#: Iterations of Bullet's constraint solver per step: pybullet's default, which Rule 2 uses.
SOLVER_ITERATIONS = 50
#: The residual ((m/s)^2, 0.3 mm/s) at which Bullet's solver ends a step's iterations early: pybullet's default,
#: the largest velocity change the last iteration made to any contact, squared.
SOLVER_RESIDUAL = 1e-7


def inertial_frame(shape: Shape) -> Pose | None:
    """Where a body's centre of mass and principal axes are, in its own frame; None at its origin (primitives)."""
    if not isinstance(shape, Mesh) or shape.geometry.mass_properties is None:
        return None
    properties = shape.geometry.mass_properties
    return Pose(properties.centre_of_mass, properties.principal_axes)


class PhysicsWorld:
    """A pybullet (DIRECT) world holding a scene's static bodies and objects.

    Bodies are named by *body indices*: objects 0..N-1 in scene order, then the static bodies
    N, N+1, ... Use as a context manager, or call :meth:`close`. Not thread-safe: one world per thread.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.client = int(pybullet.connect(pybullet.DIRECT))
        if self.client < 0:
            raise PhysicsEngineError("pybullet could not start a world")
        self.object_uids: list[int] = []
        #: Each object's collision shape (scene order), in its own frame: distances at any pose without moving it.
        self.object_shapes: list[int] = []
        # A kept simulation (see the module docstring): whether the world holds one, and its
        # saved state once the world was used for something else.
        self._keeping = False
        self._kept_state: int | None = None
        # Objects (scene indices) waiting massless at their parking spots: not simulated.
        self.massless: set[int] = set()
        # Whether the objects entered Bullet's world in the order :meth:`simulate_only` gives them.
        self._entered_in_order = False
        #: How many times objects were re-entered into Bullet's world (a mass changed): a saved
        #: simulation comes back as it was only while this count is unchanged.
        self.entries = 0
        # Objects that may be away from their parking spots (None: any object may be).
        self.placed: tuple[int, ...] | None = None
        try:
            self._build()
        except Exception:
            self.close()
            raise

    def _build(self) -> None:
        client = self.client
        pybullet.setGravity(0.0, 0.0, GRAVITY, physicsClientId=client)
        pybullet.setTimeStep(TIME_STEP, physicsClientId=client)
        pybullet.setPhysicsEngineParameter(
            deterministicOverlappingPairs=1,
            numSolverIterations=SOLVER_ITERATIONS,
            solverResidualThreshold=SOLVER_RESIDUAL,
            physicsClientId=client,
        )
        statics = []
        for body in self.scene.static:
            uid = self._create(body.shape, self._collision_shape(body.shape), 0.0, body.pose)
            pybullet.changeDynamics(uid, -1, lateralFriction=body.friction, physicsClientId=client)
            statics.append(uid)
        # Per object, where its centre of mass frame is in its pose's frame (None: at the pose).
        self._inertial_frames: list[Pose | None] = []
        for model in self.scene.objects:
            self.object_shapes.append(self._collision_shape(model.shape))
            uid = self._create(model.shape, self.object_shapes[-1], model.mass, ORIGIN)
            pybullet.changeDynamics(
                uid, -1, lateralFriction=model.friction, rollingFriction=model.rolling_friction, physicsClientId=client
            )
            self.object_uids.append(uid)
            self._inertial_frames.append(inertial_frame(model.shape))
        self._pose_frames = [None if frame is None else inverse_pose(frame) for frame in self._inertial_frames]
        #: Object uid -> scene index: which contacts count for Rule 1, and how a pair is ordered.
        self.object_index = {uid: index for index, uid in enumerate(self.object_uids)}
        #: Every body's uid -> body index.
        self.body_index = {uid: index for index, uid in enumerate(self.object_uids + statics)}
        # Each object's mass and diagonal inertia, restored when it comes back from its parking spot.
        self._dynamics = [pybullet.getDynamicsInfo(uid, -1, physicsClientId=client)[:3:2] for uid in self.object_uids]
        self._initial_state = pybullet.saveState(physicsClientId=client)

    def _create(self, shape: Shape, collision_shape: int, mass: float, pose: Pose) -> int:
        """A body of ``shape`` (Bullet's ``collision_shape`` of it) at ``pose`` (its own frame: a mesh's file
        frame), with ``mass`` kg (0: fixed).

        pybullet puts a body's centre of mass and principal axes at its *inertial frame*, given
        in the body's frame; the primitives' is the body frame. A mesh's comes from its mass
        properties, with its principal moments as the diagonal inertia (Bullet would otherwise
        use its bounding box's). pybullet then reports and sets the inertial frame's world pose,
        which :meth:`set_pose` and :meth:`get_pose` convert.
        """
        client = self.client
        frame = inertial_frame(shape) if mass > 0.0 else None
        uid = int(
            pybullet.createMultiBody(
                baseMass=mass,
                baseCollisionShapeIndex=collision_shape,
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
        client = self.client
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
        client, geometry = self.client, mesh.geometry
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

    def close(self) -> None:
        """Disconnect the pybullet world (idempotent; also after the world failed)."""
        if self.client >= 0:
            if pybullet.isConnected(physicsClientId=self.client):
                pybullet.disconnect(physicsClientId=self.client)  # frees every saved state
            self.client = -1
            self._keeping, self._kept_state = False, None

    def __enter__(self) -> PhysicsWorld:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    @property
    def all_objects(self) -> tuple[int, ...]:
        """Every object's scene index, in scene order."""
        return tuple(range(len(self.object_uids)))

    def indices(self, objects: Sequence[int] | None) -> Sequence[int]:
        """These scene indices, or (None) every object's, in scene order."""
        return range(len(self.object_uids)) if objects is None else objects

    def uids(self, objects: Sequence[int] | None) -> list[int]:
        """The bodies of the objects of these scene indices (None: every object, in scene order)."""
        return [self.object_uids[index] for index in self.indices(objects)]

    def body_name(self, index: int) -> str:
        """Name of a body by its body index (objects, then static bodies)."""
        objects, statics = self.scene.objects, self.scene.static
        return objects[index].name if index < len(objects) else statics[index - len(objects)].name

    def place(
        self, poses: Sequence[Pose], objects: Sequence[int] | None = None, fixed: Sequence[tuple[int, Pose]] = ()
    ) -> None:
        """Put ``objects`` (None: all) at ``poses``, from rest, and the ``fixed`` ones (scene index, pose)
        massless where given; every other object stays parked, massless. An object posed at its
        parking spot (an *absent* hypothesis) stays there massless: it is not in the world."""
        indices = tuple(self.indices(objects))
        if len(poses) != len(indices):
            raise ValueError(f"{len(poses)} poses for {len(indices)} objects")
        self.save_kept()
        pybullet.restoreState(self._initial_state, physicsClientId=self.client)
        self.empty_contact_caches()
        self.simulate_only(tuple(i for i, pose in zip(indices, poses, strict=True) if pose != parking_pose(i)))
        for index, pose in (*zip(indices, poses, strict=True), *fixed):
            self.set_pose(index, pose)
        self.placed = (*indices, *(index for index, _ in fixed))

    def simulate_only(self, objects: tuple[int, ...]) -> None:
        """Give ``objects`` their masses and every other object zero mass, ready to step (no call when
        nothing changes).

        Bullet re-enters a body into its world whenever its mass changes, and solves contacts in the
        order bodies entered: had only the objects whose mass changes been re-entered, a settling would
        depend on which objects earlier work had parked (module docstring). So a change re-enters every
        object: each goes massless in scene order, then the simulated ones get their masses back in
        scene order, and the world's order depends on ``objects`` alone.
        """
        if self._massless_but(objects) and self._entered_in_order:
            return
        massless = set(self.all_objects).difference(objects)
        client = self.client
        for index, uid in enumerate(self.object_uids):
            if index in self.massless:  # re-entered too: give it its mass for a moment
                self._give_mass(index)
            pybullet.changeDynamics(uid, -1, mass=0.0, physicsClientId=client)
        for index in sorted(set(self.all_objects) - massless):
            self._give_mass(index)
        self.massless = massless
        self._entered_in_order = True
        self.entries += 1

    def detect_only(self, objects: tuple[int, ...]) -> None:
        """Give ``objects`` their masses and every other object zero mass for a collision pass, which steps
        nothing (Bullet skips pairs of two fixed bodies): only the objects whose mass changes are re-entered,
        since contact points do not depend on the order; the next :meth:`simulate_only` puts it right."""
        if self._massless_but(objects):
            return  # nothing to re-enter (a pair's ranks looked up one after another)
        simulated = set(objects)
        for index, uid in enumerate(self.object_uids):
            parked = index not in simulated
            if parked == (index in self.massless):
                continue
            if parked:
                pybullet.changeDynamics(uid, -1, mass=0.0, physicsClientId=self.client)
                self.massless.add(index)
            else:
                self._give_mass(index)
                self.massless.discard(index)
            self._entered_in_order = False
            self.entries += 1

    def _massless_but(self, objects: Sequence[int]) -> bool:
        """Whether every object but ``objects`` (scene indices), and none of them, is massless now."""
        simulated = set(objects)
        return self.massless.isdisjoint(simulated) and len(self.massless) + len(simulated) == len(self.object_uids)

    def _give_mass(self, index: int) -> None:
        mass, inertia = self._dynamics[index]
        pybullet.changeDynamics(
            self.object_uids[index], -1, mass=mass, localInertiaDiagonal=inertia, physicsClientId=self.client
        )

    def set_pose(self, index: int, pose: Pose) -> None:
        """Put object ``index``'s own frame at ``pose`` (pybullet places its inertial frame, see :meth:`_create`)."""
        frame = self._inertial_frames[index]
        placed = pose if frame is None else compose_poses(pose, frame)
        pybullet.resetBasePositionAndOrientation(
            self.object_uids[index], placed.position, placed.orientation, physicsClientId=self.client
        )

    def get_pose(self, index: int) -> Pose:
        """Object ``index``'s own frame's pose, from its inertial frame's pose that pybullet reports."""
        position, orientation = pybullet.getBasePositionAndOrientation(
            self.object_uids[index], physicsClientId=self.client
        )
        pose = Pose((position[0], position[1], position[2]), tuple(orientation))
        frame = self._pose_frames[index]
        return pose if frame is None else compose_poses(pose, frame)

    def poses(self, objects: Sequence[int] | None = None) -> tuple[Pose, ...]:
        """The poses of ``objects`` (None: all), in their own frames."""
        return tuple(self.get_pose(index) for index in self.indices(objects))

    def empty_contact_caches(self, placed: Iterable[int] | None = None) -> None:
        """Drop every contact point, so that no simulation inherits another's.

        restoreState restores the contact points (and warm-start impulses) it saved and empties
        the other touching pairs', unless it saved none (Bullet skips empty manifolds, and the
        initial state has none): then it keeps every contact point the world holds. Parking the
        objects far apart and running collision detection empties them. ``placed``: only these
        objects are away from their parking spots (default: any may be).
        """
        for index in self.all_objects if placed is None else placed:
            parking = parking_pose(index)
            uid = self.object_uids[index]
            pybullet.resetBasePositionAndOrientation(
                uid, parking.position, parking.orientation, physicsClientId=self.client
            )
        pybullet.performCollisionDetection(physicsClientId=self.client)
        self.placed = ()

    def keep_simulation(self) -> None:
        """The world now holds a simulation to continue later: save it before the world is used otherwise."""
        self.forget_kept()
        self._keeping = True

    def save_kept(self) -> None:
        """Save the kept simulation the world holds, before the world is used for something else."""
        if self._keeping and self._kept_state is None:
            self._kept_state = pybullet.saveState(physicsClientId=self.client)

    def kept_was_saved(self) -> bool:
        """True iff the kept simulation was saved: the world was used for something else since."""
        return self._kept_state is not None

    def restore_kept(self, objects: Sequence[int] | None, fixed: Sequence[tuple[int, Pose]] = ()) -> None:
        """Bring back the saved kept simulation of ``objects`` (None: all) and ``fixed``, placed then."""
        assert self._kept_state is not None
        self.empty_contact_caches()
        pybullet.restoreState(self._kept_state, physicsClientId=self.client)
        self.placed = (*self.indices(objects), *(index for index, _ in fixed))

    def forget_kept(self) -> None:
        """Drop the kept simulation and free its saved state, if any."""
        if self._kept_state is not None:
            pybullet.removeState(self._kept_state, physicsClientId=self.client)
        self._keeping, self._kept_state = False, None

    def extents(self, uids: Sequence[int]) -> list[tuple[Vector3, Vector3]]:
        """Each body's axis-aligned bounding box now (low and high corners, metres)."""
        boxes: list[tuple[Vector3, Vector3]] = []
        for uid in uids:
            low, high = pybullet.getAABB(uid, physicsClientId=self.client)
            boxes.append(((low[0], low[1], low[2]), (high[0], high[1], high[2])))
        return boxes

    def step(self) -> None:
        """Advance the simulation by one :data:`TIME_STEP`."""
        pybullet.stepSimulation(physicsClientId=self.client)

    def set_solver_iterations(self, iterations: int) -> None:
        """Iterations of the constraint solver in each later :meth:`step` (:data:`SOLVER_ITERATIONS` by default)."""
        pybullet.setPhysicsEngineParameter(numSolverIterations=iterations, physicsClientId=self.client)

    def set_solver_residual(self, residual: float) -> None:
        """The residual ((m/s)^2) at which the constraint solver ends each later :meth:`step`'s iterations
        (:data:`SOLVER_RESIDUAL` by default)."""
        pybullet.setPhysicsEngineParameter(solverResidualThreshold=residual, physicsClientId=self.client)

"""The scene model: bodies and their shapes, search parameters, scenes and problems.

A *scene* is the fixed environment, the movable objects (in the order used for configuration
codes and output arrays) and the search parameters. A *problem* is a scene plus weighted
hypotheses for every object. Lengths are metres, masses kilograms, times seconds. Loading and
validating the YAML files is :mod:`physics_mapper.model.scene_files`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import Literal, assert_never

from physics_mapper.model.geometry import ORIGIN, Pose, Vector3
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.meshes import MeshCollision, MeshGeometry

Fallback = Literal["none", "settled", "refine"]
FALLBACKS: tuple[Fallback, ...] = ("none", "settled", "refine")
#: ``conflict``: per interaction group, a conflict-directed best-first search (the default);
#: ``grouped``: Algorithm 1 per interaction group; ``joint``: the paper's single search.
Strategy = Literal["conflict", "grouped", "joint"]
STRATEGIES: tuple[Strategy, ...] = ("conflict", "grouped", "joint")
#: How T bounds a node: ``resolving`` p(C) / p(first valid) < T, per group (the default); ``relative``
#: p(C) / p(root) < T, per group; ``absolute`` p(C) < T (the paper's).
Bound = Literal["resolving", "relative", "absolute"]
BOUNDS: tuple[Bound, ...] = ("resolving", "relative", "absolute")
#: ``early``: a settling may stop at rest or once an object's jitter is beyond the threshold; ``full``: never.
SettleExit = Literal["early", "full"]
SETTLE_EXITS: tuple[SettleExit, ...] = ("early", "full")


@dataclass(frozen=True)
class Box:
    """Box with full edge lengths ``size`` (x, y, z) in metres, centred on its pose."""

    size: tuple[float, float, float]


@dataclass(frozen=True)
class Sphere:
    """Sphere of ``radius`` metres, centred on its pose."""

    radius: float


@dataclass(frozen=True)
class Cylinder:
    """Cylinder of ``radius`` and ``length`` metres along its local z axis, centred on its pose."""

    radius: float
    length: float


@dataclass(frozen=True)
class Plane:
    """Infinite plane through its pose, normal along its local +z (static bodies only)."""


#: How a movable object's mesh may collide; static bodies may also use a triangle mesh.
OBJECT_MESH_COLLISIONS: tuple[MeshCollision, ...] = ("convex_hull", "decomposition")
STATIC_MESH_COLLISIONS: tuple[MeshCollision, ...] = ("convex_hull", "decomposition", "triangle_mesh")


@dataclass(frozen=True)
class Mesh:
    """Triangle mesh read from ``file`` (OBJ or STL), posed in the file's own frame, scaled per axis.

    ``file`` is the absolute path read; ``uri`` how RViz finds it (``package://`` where the scene
    gave one, else ``file://``); ``collision`` how Bullet collides it (see
    :mod:`~physics_mapper.model.meshes`); ``geometry`` the loaded mesh: scaled surface, convex
    parts, mass properties.
    """

    file: Path
    uri: str
    scale: Vector3
    collision: MeshCollision
    geometry: MeshGeometry = field(compare=False, repr=False)


Shape = Box | Sphere | Cylinder | Plane | Mesh
ObjectShape = Box | Sphere | Cylinder | Mesh
OBJECT_SHAPES = ("box", "sphere", "cylinder", "mesh")
STATIC_SHAPES = ("plane", "box", "sphere", "cylinder", "mesh")


def shape_volume(shape: ObjectShape) -> float:
    """Volume in m^3 of a movable object's shape.

    A mesh's is its solid's if it is closed, else its collision geometry's (its mass properties').
    """
    if isinstance(shape, Box):
        return shape.size[0] * shape.size[1] * shape.size[2]
    if isinstance(shape, Sphere):
        return 4.0 / 3.0 * math.pi * shape.radius**3
    if isinstance(shape, Cylinder):
        return math.pi * shape.radius**2 * shape.length
    properties = shape.geometry.mass_properties
    if properties is None:
        raise ValueError(f"{shape.file}: loaded without mass properties (a static body's mesh)")
    return properties.volume


def bounding_radius(shape: Shape) -> float | None:
    """Radius (m) of the smallest sphere about the shape's pose that holds it; None for an unbounded plane.

    Rotation-invariant: a body posed anywhere stays within this distance of its pose's position. A
    mesh's pose is its file's origin, which need not be inside the mesh (the radius covers the mesh
    and its convex parts from there). Every shape must have a branch (mypy checks it): the default
    workspace is derived from these radii.
    """
    if isinstance(shape, Box):
        return math.hypot(*shape.size) / 2.0
    if isinstance(shape, Sphere):
        return shape.radius
    if isinstance(shape, Cylinder):
        return math.hypot(shape.radius, shape.length / 2.0)
    if isinstance(shape, Mesh):
        return shape.geometry.bounding_radius
    if isinstance(shape, Plane):
        return None
    assert_never(shape)


def object_radius(shape: Shape) -> float:
    """An object's bounding radius, metres (:func:`bounding_radius`: objects are bounded)."""
    radius = bounding_radius(shape)
    if radius is None:
        raise ValueError(f"{type(shape).__name__} is not a shape of a movable object")
    return radius


#: Metres the default workspace extends beyond the scene's bodies and ground truth on every side.
DEFAULT_WORKSPACE_MARGIN = 10.0


@dataclass(frozen=True)
class Workspace:
    """An axis-aligned box of the scene frame, corners in metres, that every hypothesis's position must lie in.

    Bounds are inclusive. ``derived`` marks the default a scene without ``workspace:`` gets
    (:func:`default_workspace`).
    """

    min_corner: Vector3
    max_corner: Vector3
    derived: bool = False

    def problem(self, position: Sequence[float]) -> str | None:
        """Say why ``position`` (m) lies outside the box, or return None when it lies inside."""
        bounds = zip(self.min_corner, position, self.max_corner, strict=True)
        if all(low <= value <= high for low, value, high in bounds):
            return None
        shown = ", ".join(f"{value:g}" for value in position)
        return f"({shown}) m is outside the workspace {self}"

    def __str__(self) -> str:
        ranges = ", ".join(
            f"{axis} [{low:g}, {high:g}]"
            for axis, low, high in zip("xyz", self.min_corner, self.max_corner, strict=True)
        )
        origin = f" (default: the scene's bodies plus {DEFAULT_WORKSPACE_MARGIN:g} m; set workspace: to change it)"
        return f"{ranges} m{origin if self.derived else ''}"


@dataclass(frozen=True)
class StaticBody:
    """A fixed body of the environment (floor, wall, groove side)."""

    name: str
    shape: Shape
    pose: Pose = ORIGIN
    friction: float = 0.8


@dataclass(frozen=True)
class FixedFrame:
    """A sensor frame fixed in the cell (the scene file's ``frames:``): ``pose`` is frame ``name``'s
    pose in frame ``parent``, as a static transform ``parent -> name`` on ``/tf_static`` would give it."""

    name: str
    parent: str
    pose: Pose


@dataclass(frozen=True)
class ObjectModel:
    """A movable rigid body; ``mass`` in kg, Coulomb ``friction`` coefficient.

    ``rolling_friction`` (Bullet's, in metres) lets round objects come to rest. The centre of
    mass and inertia are the shape's at uniform density: the pose's origin for the primitives,
    the mesh's own (:class:`~physics_mapper.model.meshes.MassProperties`) for a mesh.
    """

    name: str
    shape: ObjectShape
    mass: float = 0.5
    friction: float = 0.8
    rolling_friction: float = 0.0


def _doc(text: str) -> MappingProxyType[str, str]:
    """A dataclass field's metadata holding its description."""
    return MappingProxyType({"doc": text})


@dataclass(frozen=True)
class SearchParams:
    """Thresholds and budgets of the search; each field's meaning and unit is :func:`search_parameter_doc`'s.

    Scene files set them under ``search:``, the node declares each as a ROS parameter, and
    ``--set``/``--grid`` and ``solve --deadline`` override them, all through
    :func:`~physics_mapper.model.scene_files.search_with_overrides` within :data:`SEARCH_LIMITS`.
    """

    probability_threshold: float = field(
        default=0.0002, metadata=_doc("T: nodes with p(C) < T are checked, not expanded")
    )
    penetration_threshold: float = field(default=0.005, metadata=_doc("deepest allowed overlap of two bodies, metres"))
    jitter_threshold: float = field(
        default=0.01, metadata=_doc("largest per-object jitter J_i of a stable object, metres + weighted radians")
    )
    angular_weight: float = field(default=0.1, metadata=_doc("metres per radian of rotation in the jitter J_i"))
    settle_time: float = field(default=0.5, metadata=_doc("simulated seconds under gravity for the stability test"))
    deadline: float = field(
        default=0.2, metadata=_doc("wall-clock seconds a search may run (the node: per tick, below 1/rate_hz)")
    )
    fallback: Fallback = field(
        default="none", metadata=_doc(f"what is reported when no configuration is valid: {', '.join(FALLBACKS)}")
    )
    refine_max_speed: float = field(
        default=1.0,
        metadata=_doc(
            "fallback refine's speed cap, m/s: depenetration moves an object at most refine_max_speed * TIME_STEP "
            "metres per iteration, and its settling caps linear speeds"
        ),
    )
    refine_mean_radius: float = field(
        default=0.1,
        metadata=_doc(
            "fallback refine starts each object at the weighted mean position of its poses within this many "
            "metres of its most likely pose (0: at that pose)"
        ),
    )
    strategy: Strategy = field(
        default="conflict",
        metadata=_doc(
            f"{', '.join(STRATEGIES)}: per interaction group, a search that skips what known conflicts rule "
            "out; the paper's search per group; the paper's single search over all objects"
        ),
    )
    bound: Bound = field(
        default="resolving",
        metadata=_doc(
            f"{', '.join(BOUNDS)}: T bounds p(C) / p(the group's first valid configuration; nothing before "
            "one), p(C) / p(group root), or p(C) itself"
        ),
    )
    settle_exit: SettleExit = field(
        default="early",
        metadata=_doc(f"{' or '.join(SETTLE_EXITS)}: settlings may stop at rest or once unstable, or never early"),
    )
    interaction_margin: float = field(
        default=0.02,
        metadata=_doc("metres between two hypotheses' body boxes below which their objects share a group"),
    )
    queue_limit: int = field(
        default=20_000,
        metadata=_doc("nodes the search's queues hold at most (each group a share in proportion to its objects)"),
    )
    trace_limit: int | None = field(
        default=5_000, metadata=_doc("trace entries kept at most (None: all); later visits are counted, not recorded")
    )


def search_parameter_doc(name: str) -> str:
    """What search parameter ``name`` means, with its unit (a field of :class:`SearchParams`)."""
    return str(next(f for f in fields(SearchParams) if f.name == name).metadata["doc"])


@dataclass(frozen=True)
class Scene:
    """Environment, objects in code order, default search parameters and the workspace."""

    objects: tuple[ObjectModel, ...]
    static: tuple[StaticBody, ...] = ()
    search: SearchParams = field(default_factory=SearchParams)
    frame_id: str = "world"
    #: Optional true pose of each object, in object order (for generating data and scoring).
    ground_truth: tuple[Pose, ...] | None = None
    #: The scene file's ``workspace:`` box; None: the default (:attr:`workspace`).
    explicit_workspace: Workspace | None = None
    #: A pose estimator's class ids -> the objects they detect (``class_map:``; an object's own name
    #: is its class id unless it is mapped; a ``count:`` entry's name is the class id of its instances
    #: unless it is mapped). A class of several objects has instances.
    class_map: tuple[tuple[str, tuple[str, ...]], ...] = ()
    #: Objects that exist only once detected (the instances of ``count: {max: K}`` entries).
    optional: frozenset[str] = frozenset()
    #: Fixed sensor frames (``frames:``), for cells without TF.
    frames: tuple[FixedFrame, ...] = ()
    #: Warnings about what the file asks for (an extreme mass ratio), each as ``file: key: what``.
    notes: tuple[str, ...] = field(default=(), compare=False)

    @property
    def object_names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.objects)

    def class_of(self, name: str) -> str:
        """The class id a pose estimator gives object ``name`` (``class_map:``; else its name)."""
        return next((class_id for class_id, names in self.class_map if name in names), name)

    def objects_of_class(self, class_id: str) -> tuple[str, ...]:
        """The objects a detection of ``class_id`` may be (its instances, in order); () for an unknown class."""
        return self._classes.get(class_id, ())

    @cached_property
    def _classes(self) -> dict[str, tuple[str, ...]]:
        """Every class id -> its objects: ``class_map``'s, and each unmapped object's own name."""
        classes = dict(self.class_map)
        mapped = {name for _, names in self.class_map for name in names}
        for name in self.object_names:
            if name not in mapped and name not in classes:
                classes[name] = (name,)
        return classes

    def is_tracked(self, class_id: str) -> bool:
        """Whether detections of ``class_id`` are associated to instances across frames
        (:mod:`~physics_mapper.mapping.association`): a class of several objects, or of optional ones."""
        objects = self.objects_of_class(class_id)
        return len(objects) > 1 or any(name in self.optional for name in objects)

    def is_instance(self, name: str) -> bool:
        """Whether object ``name`` is an instance: of a class whose detections are associated (:meth:`is_tracked`)."""
        return self.is_tracked(self.class_of(name))

    @cached_property
    def workspace(self) -> Workspace:
        """The box hypotheses must lie in: :attr:`explicit_workspace`, else :func:`default_workspace`."""
        return self.explicit_workspace or default_workspace(self)


def default_workspace(scene: Scene) -> Workspace:
    """The workspace of a scene without ``workspace:``: what it holds, plus a margin.

    The smallest box holding every bounded static body and every ground-truth object (a sphere
    of :func:`bounding_radius` about its pose) and the pose of every plane, grown by
    :data:`DEFAULT_WORKSPACE_MARGIN` on every side. A scene with none of these is taken
    around the origin of its frame.
    """
    shapes = [(body.pose, body.shape) for body in scene.static]
    if scene.ground_truth is not None:
        shapes += zip(scene.ground_truth, (model.shape for model in scene.objects), strict=True)
    bodies = [(pose, bounding_radius(shape) or 0.0) for pose, shape in shapes]
    if not bodies:
        bodies = [(ORIGIN, 0.0)]
    reach = [(pose.position, radius + DEFAULT_WORKSPACE_MARGIN) for pose, radius in bodies]
    low = tuple(min(position[axis] - extra for position, extra in reach) for axis in range(3))
    high = tuple(max(position[axis] + extra for position, extra in reach) for axis in range(3))
    return Workspace((low[0], low[1], low[2]), (high[0], high[1], high[2]), derived=True)


@dataclass(frozen=True)
class Problem:
    """A scene and, for each of its objects in order, ranked hypotheses.

    ``notes`` say what loading the problem's file changed, each as ``file: key: what`` (an object
    with more hypotheses than a file may bring keeps the heaviest).
    """

    scene: Scene
    hypotheses: tuple[RankedHypotheses, ...]
    notes: tuple[str, ...] = ()


#: Inclusive range of each numeric search parameter: checked for files and for the node's
#: parameters alike (the node declares them as its parameter ranges).
SEARCH_LIMITS: dict[str, tuple[float, float]] = {
    "probability_threshold": (0.0, 1.0),
    "penetration_threshold": (0.0, 1.0),  # metres
    "jitter_threshold": (0.0, 10.0),  # metres + weighted radians
    "angular_weight": (0.0, 10.0),  # metres per radian
    "settle_time": (0.0, 10.0),  # simulated seconds
    "deadline": (0.0, 3600.0),  # wall-clock seconds, and positive
    "refine_max_speed": (0.001, 100.0),  # metres per second
    "refine_mean_radius": (0.0, 10.0),  # metres
    "interaction_margin": (0.0, 1.0),  # metres
    "queue_limit": (1, 100_000_000),  # nodes
    "trace_limit": (0, 100_000_000),  # trace entries
}
#: The search parameters that are whole numbers.
SEARCH_INTEGERS = ("queue_limit", "trace_limit")
#: The allowed values of each search parameter that is a word.
SEARCH_CHOICES: dict[str, tuple[str, ...]] = {
    "fallback": FALLBACKS,
    "strategy": STRATEGIES,
    "bound": BOUNDS,
    "settle_exit": SETTLE_EXITS,
}


def search_params_problem(params: SearchParams) -> str | None:
    """Say which search parameter is out of range (:data:`SEARCH_LIMITS`), or return None."""
    if params.deadline <= 0.0:
        return f"deadline must be positive, got {params.deadline:g}"
    for name, (low, high) in SEARCH_LIMITS.items():
        value = getattr(params, name)
        if value is None and name == "trace_limit":
            continue  # no limit: every visit recorded
        if not low <= value <= high:
            return f"{name} must be in [{low:g}, {high:g}], got {value:g}"
    for name in SEARCH_INTEGERS:
        value = getattr(params, name)
        if value is not None and value != int(value):
            return f"{name} must be a whole number, got {value:g}"
    for name, choices in SEARCH_CHOICES.items():
        if getattr(params, name) not in choices:
            return f"{name} must be one of {', '.join(choices)}, got {getattr(params, name)!r}"
    return None

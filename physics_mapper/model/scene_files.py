"""Scene and problem files: YAML loaded and validated into the scene model.

Every error names the file, the key path and the problem (:class:`SceneError`), so a bad file
gives one clear line and never a traceback. Files are read by :func:`~physics_mapper.model.yaml_files.read_yaml`
(size and nesting caps, UTF-8, YAML 1.2 float spellings); text quoted from a file is clipped to
:data:`~physics_mapper.model.limits.MAX_QUOTED_TEXT` characters.
"""

from __future__ import annotations

import math
import reprlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from physics_mapper.model.decomposition import (
    DECOMPOSITION_METHODS,
    THRESHOLD_LIMITS,
    DecompositionSettings,
    Progress,
    stderr_progress,
)
from physics_mapper.model.extents import shape_extents
from physics_mapper.model.geometry import IDENTITY, ORIGIN, Pose, make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.limits import (
    MAX_COORDINATE,
    MAX_DENSITY,
    MAX_HYPOTHESES_PER_OBJECT,
    MAX_MASS,
    MAX_MASS_RATIO,
    MAX_NAME_LENGTH,
    MAX_OBJECTS,
    MAX_QUOTED_TEXT,
    MAX_STATIC_BODIES,
    MAX_UNWARNED_MESH_EXTENT,
    MIN_DENSITY,
    MIN_MASS,
)
from physics_mapper.model.meshes import MeshCollision, MeshError, MeshGeometry, MeshRequest, load_mesh_geometry
from physics_mapper.model.names import object_name_problem, topic_clash
from physics_mapper.model.resources import ResourceError, file_problem, resolve_resource, resource_uri
from physics_mapper.model.scene import (
    OBJECT_MESH_COLLISIONS,
    OBJECT_SHAPES,
    SEARCH_CHOICES,
    SEARCH_INTEGERS,
    STATIC_MESH_COLLISIONS,
    STATIC_SHAPES,
    Box,
    Cylinder,
    FixedFrame,
    Mesh,
    ObjectModel,
    Plane,
    Problem,
    Scene,
    SearchParams,
    Shape,
    Sphere,
    StaticBody,
    Workspace,
    search_params_problem,
    shape_volume,
)
from physics_mapper.model.yaml_files import FileError, read_yaml

T = TypeVar("T")


class SceneError(FileError):
    """A scene or problem file is invalid: names the file, the key and the problem."""


class _Reader:
    """Typed access to YAML values that raises :class:`SceneError` naming the key path.

    ``notes`` collects what was accepted with a change (a capped hypothesis list), each as
    ``file: key: what``.
    """

    def __init__(self, source: str) -> None:
        self.source = source
        self.notes: list[str] = []

    def fail(self, key: str, problem: str) -> SceneError:
        return SceneError(self.source, key, problem)

    def note(self, key: str, what: str) -> None:
        self.notes.append(str(FileError(self.source, key, what)))  # one line, as an error is

    def mapping(self, value: Any, key: str) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(key, f"must be a mapping, got {_show(value)}")
        return value

    def sequence(self, value: Any, key: str) -> Sequence[Any]:
        if not isinstance(value, list):
            raise self.fail(key, f"must be a list, got {_show(value)}")
        return value

    def number(
        self,
        value: Any,
        key: str,
        *,
        positive: bool = False,
        minimum: float | None = None,
        magnitude: float | None = None,
    ) -> float:
        """A finite number; ``magnitude``: the largest absolute value allowed."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, f"must be a number, got {_show(value)}")
        try:
            number = float(value)
        except OverflowError:  # an integer beyond any float
            raise self.fail(key, f"must be finite, got {_show(value)}") from None
        if not math.isfinite(number):
            raise self.fail(key, f"must be finite, got {number}")
        if positive and number <= 0.0:
            raise self.fail(key, f"must be positive, got {number:g}")
        if minimum is not None and number < minimum:
            raise self.fail(key, f"must be at least {minimum:g}, got {number:g}")
        if magnitude is not None and abs(number) > magnitude:
            raise self.fail(key, f"must be within ±{magnitude:g} m (where the physics is trusted), got {number:g}")
        return number

    def vector(
        self, value: Any, key: str, length: int, *, positive: bool = False, magnitude: float | None = None
    ) -> tuple[float, ...]:
        items = self.sequence(value, key)
        if len(items) != length:
            raise self.fail(key, f"must have {length} numbers, got {len(items)}")
        return tuple(self.number(v, f"{key}[{i}]", positive=positive, magnitude=magnitude) for i, v in enumerate(items))

    def name(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value:
            raise self.fail(key, f"must be a non-empty string, got {_show(value)}")
        if len(value) > MAX_NAME_LENGTH:
            raise self.fail(key, f"longer than {MAX_NAME_LENGTH} characters: {_show(value)}")
        return value

    def known_keys(self, data: Mapping[str, Any], key: str, allowed: Sequence[str]) -> None:
        unknown = sorted(set(data) - set(allowed), key=str)  # keys may be of any type: 1, null, true
        if unknown:
            prefix = f"{key}." if key else ""
            raise self.fail(f"{prefix}{unknown[0]}", f"unknown key (expected one of: {', '.join(allowed)})")

    def required(self, data: Mapping[str, Any], name: str, key: str) -> Any:
        if name not in data:
            raise self.fail(f"{key}.{name}" if key else name, "missing")
        return data[name]


# Shows a value's start without walking all of it: aliases can make a small file hold a huge value.
_SHORT_REPR = reprlib.Repr()
_SHORT_REPR.maxlevel, _SHORT_REPR.maxlist, _SHORT_REPR.maxdict = 2, 4, 4
_SHORT_REPR.maxstring = _SHORT_REPR.maxother = MAX_QUOTED_TEXT


def _show(value: Any) -> str:
    text = _SHORT_REPR.repr(value)
    return text if len(text) <= MAX_QUOTED_TEXT else text[: MAX_QUOTED_TEXT - 3] + "..."


def _read_pose(reader: _Reader, value: Any, key: str, magnitude: float | None = MAX_COORDINATE) -> Pose:
    """A pose; ``magnitude`` bounds its coordinates (None: unbounded here, checked by the caller)."""
    data = reader.mapping(value, key)
    reader.known_keys(data, key, ("position", "orientation"))
    position = reader.vector(reader.required(data, "position", key), f"{key}.position", 3, magnitude=magnitude)
    orientation = reader.vector(data.get("orientation", list(IDENTITY)), f"{key}.orientation", 4)
    try:
        return make_pose(position, orientation)
    except ValueError as error:
        raise reader.fail(f"{key}.orientation", str(error)) from None


_SIZE: dict[str, Any] = {"positive": True, "magnitude": MAX_COORDINATE}
#: Longest mesh file path or URL, characters (Linux's PATH_MAX).
MAX_PATH_LENGTH = 4096


class _MeshLoader:
    """Loads the meshes of one scene file: paths relative to its folder, each mesh file read once.

    Bodies sharing a mesh file and its keys share one :class:`MeshGeometry`, so loading a scene
    never reads (or decomposes) the same mesh twice.
    """

    def __init__(self, reader: _Reader, base_dir: Path | None, progress: Progress) -> None:
        self.reader = reader
        self.base_dir = base_dir
        self.progress = progress
        self._loaded: dict[MeshRequest, MeshGeometry] = {}

    def resolve(self, value: Any, key: str) -> tuple[str, Path]:
        """The text of a file key and the path it names; a missing file is an error here."""
        if not isinstance(value, str) or not value:
            raise self.reader.fail(key, f"must be a file path or package:// URL, got {_show(value)}")
        if len(value) > MAX_PATH_LENGTH:
            raise self.reader.fail(key, f"longer than {MAX_PATH_LENGTH} characters: {_show(value)}")
        text = value
        try:
            path = resolve_resource(text, self.base_dir)
        except ResourceError as error:
            raise self.reader.fail(key, str(error)) from None
        problem = file_problem(path)
        if problem is not None:
            raise self.reader.fail(key, f"{path}: {problem}")
        return text, path.resolve()

    def load(self, data: Mapping[str, Any], key: str, collisions: Sequence[MeshCollision], *, movable: bool) -> Mesh:
        reader = self.reader
        text, path = self.resolve(reader.required(data, "file", key), f"{key}.file")
        collision = data.get("collision", "convex_hull")
        if collision not in collisions:
            raise reader.fail(f"{key}.collision", f"must be one of {', '.join(collisions)}, got {_show(collision)}")
        parts_file = None
        if "parts" in data:
            if collision != "decomposition" or "decomposition" in data:
                problem = "only with collision: decomposition, and instead of decomposition settings"
                raise reader.fail(f"{key}.parts", problem)
            parts_file = self.resolve(data["parts"], f"{key}.parts")[1]
        settings = DecompositionSettings()
        if "decomposition" in data:
            if collision != "decomposition":
                raise reader.fail(f"{key}.decomposition", "only with collision: decomposition")
            settings = _read_decomposition(reader, data["decomposition"], f"{key}.decomposition")
        request = MeshRequest(
            file=path,
            scale=_read_scale(reader, data.get("scale", 1.0), f"{key}.scale"),
            collision=collision,
            decomposition=settings,
            parts_file=parts_file,
            mass_properties=movable,
            needs_volume=movable and "density" in data,
        )
        if request not in self._loaded:
            try:
                self._loaded[request] = load_mesh_geometry(request, self.progress)
            except MeshError as error:
                raise reader.fail(f"{key}.parts" if error.path == parts_file else f"{key}.file", str(error)) from None
        return Mesh(path, resource_uri(text, path), request.scale, collision, self._loaded[request])


def _read_scale(reader: _Reader, value: Any, key: str) -> tuple[float, float, float]:
    """``scale``: one positive number for every axis, or three."""
    if isinstance(value, list):
        x, y, z = reader.vector(value, key, 3, **_SIZE)
        return (x, y, z)
    factor = reader.number(value, key, **_SIZE)
    return (factor, factor, factor)


def _read_decomposition(reader: _Reader, value: Any, key: str) -> DecompositionSettings:
    data = reader.mapping(value, key)
    reader.known_keys(data, key, ("method", "threshold"))
    method = data.get("method", "coacd")
    if method not in DECOMPOSITION_METHODS:
        raise reader.fail(f"{key}.method", f"must be one of {', '.join(DECOMPOSITION_METHODS)}, got {_show(method)}")
    if "threshold" not in data:
        return DecompositionSettings(method)
    if method != "coacd":
        raise reader.fail(f"{key}.threshold", "only for method: coacd (vhacd runs with pybullet's defaults)")
    threshold = reader.number(data["threshold"], f"{key}.threshold")
    low, high = THRESHOLD_LIMITS
    if not low <= threshold <= high:
        raise reader.fail(f"{key}.threshold", f"must be in [{low:g}, {high:g}], got {threshold:g}")
    return DecompositionSettings(method, threshold)


def _read_shape(
    reader: _Reader, data: Mapping[str, Any], key: str, allowed: Sequence[str], meshes: _MeshLoader, *, movable: bool
) -> Shape:
    kind = reader.required(data, "shape", key)
    if kind not in allowed:
        raise reader.fail(f"{key}.shape", f"unknown shape {_show(kind)} (expected one of: {', '.join(allowed)})")
    if kind != "mesh":
        for name in _MESH_KEYS:
            if name in data:
                raise reader.fail(f"{key}.{name}", "only for shape: mesh")
    if kind == "box":
        size = reader.vector(reader.required(data, "size", key), f"{key}.size", 3, **_SIZE)
        return Box((size[0], size[1], size[2]))
    if kind == "sphere":
        return Sphere(reader.number(reader.required(data, "radius", key), f"{key}.radius", **_SIZE))
    if kind == "cylinder":
        radius = reader.number(reader.required(data, "radius", key), f"{key}.radius", **_SIZE)
        length = reader.number(reader.required(data, "length", key), f"{key}.length", **_SIZE)
        return Cylinder(radius, length)
    if kind == "mesh":
        collisions = OBJECT_MESH_COLLISIONS if movable else STATIC_MESH_COLLISIONS
        return meshes.load(data, key, collisions, movable=movable)
    return Plane()


_MESH_KEYS = ("file", "scale", "collision", "decomposition", "parts")
_SHAPE_KEYS = ("shape", "size", "radius", "length", *_MESH_KEYS)


def _read_static(reader: _Reader, value: Any, key: str, meshes: _MeshLoader) -> StaticBody:
    data = reader.mapping(value, key)
    reader.known_keys(data, key, ("name", *_SHAPE_KEYS, "pose", "friction"))
    name = reader.name(reader.required(data, "name", key), f"{key}.name")
    shape = _read_shape(reader, data, key, STATIC_SHAPES, meshes, movable=False)
    pose = _read_pose(reader, data["pose"], f"{key}.pose") if "pose" in data else ORIGIN
    friction = reader.number(data.get("friction", 0.8), f"{key}.friction", minimum=0.0)
    return StaticBody(name, shape, pose, friction)


_OBJECT_KEYS = ("name", *_SHAPE_KEYS, "mass", "density", "friction", "rolling_friction", "count", "names")


@dataclass(frozen=True)
class _Entry:
    """One ``objects:`` entry: its name, its objects (one, or its instances) and whether they are optional."""

    name: str
    objects: tuple[ObjectModel, ...]
    counted: bool
    optional: bool


def _read_entry(reader: _Reader, value: Any, key: str, meshes: _MeshLoader) -> _Entry:
    """An object, or with ``count:``/``names:`` its identical instances: one shape (one mesh, one
    decomposition) shared by all, named ``<name>_1`` ... ``<name>_K`` unless ``names:`` lists them."""
    model = _read_object(reader, value, key, meshes)
    data = reader.mapping(value, key)
    if "count" not in data and "names" not in data:
        return _Entry(model.name, (model,), counted=False, optional=False)
    count, optional = _read_count(reader, data, key)
    if "names" in data:
        names = [
            reader.name(n, f"{key}.names[{i}]") for i, n in enumerate(reader.sequence(data["names"], f"{key}.names"))
        ]
        if count is not None and len(names) != count:
            raise reader.fail(f"{key}.names", f"lists {len(names)} names for count {count}")
    else:
        names = [f"{model.name}_{k}" for k in range(1, (count or 0) + 1)]
    if not names:
        raise reader.fail(f"{key}.names", "needs at least one name")
    for i, name in enumerate(names):
        problem = object_name_problem(name)
        if problem is not None:
            raise reader.fail(f"{key}.names[{i}]", f"{_show(name)}: {problem}")
    return _Entry(model.name, tuple(replace(model, name=name) for name in names), counted=True, optional=optional)


def _read_count(reader: _Reader, data: Mapping[str, Any], key: str) -> tuple[int | None, bool]:
    """``count: K`` (K instances) or ``count: {max: K}`` (up to K, optional): (K or None if absent, optional)."""
    if "count" not in data:
        return None, False
    value, at = data["count"], f"{key}.count"
    optional = isinstance(value, Mapping)
    if optional:
        reader.known_keys(value, at, ("max",))
        value, at = reader.required(value, "max", at), f"{at}.max"
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_OBJECTS:
        raise reader.fail(at, f"must be a whole number in [1, {MAX_OBJECTS}], got {_show(value)}")
    return value, optional


def _read_object(reader: _Reader, value: Any, key: str, meshes: _MeshLoader) -> ObjectModel:
    data = reader.mapping(value, key)
    reader.known_keys(data, key, _OBJECT_KEYS)
    name = reader.name(reader.required(data, "name", key), f"{key}.name")
    problem = object_name_problem(name)
    if problem is not None:
        raise reader.fail(f"{key}.name", f"{_show(name)}: {problem}")
    if "mass" in data and "density" in data:
        raise reader.fail(f"{key}.density", "give mass or density, not both")
    shape = _read_shape(reader, data, key, OBJECT_SHAPES, meshes, movable=True)
    assert not isinstance(shape, Plane)  # excluded by OBJECT_SHAPES
    if "density" in data:
        density = reader.number(data["density"], f"{key}.density", positive=True)
        if not MIN_DENSITY <= density <= MAX_DENSITY:
            problem = f"must be in [{MIN_DENSITY:g}, {MAX_DENSITY:g}] kg/m^3, got {density:g}"
            raise reader.fail(f"{key}.density", problem)
        mass = density * shape_volume(shape)
        if not MIN_MASS <= mass <= MAX_MASS:
            problem = f"gives a mass of {mass:g} kg, outside [{MIN_MASS:g}, {MAX_MASS:g}] kg where Bullet is trusted"
            raise reader.fail(f"{key}.density", problem)
    else:
        mass = reader.number(data.get("mass", 0.5), f"{key}.mass", positive=True)
        if not MIN_MASS <= mass <= MAX_MASS:
            problem = f"must be in [{MIN_MASS:g}, {MAX_MASS:g}] kg (where Bullet is trusted), got {mass:g}"
            raise reader.fail(f"{key}.mass", problem)
    return ObjectModel(
        name=name,
        shape=shape,
        mass=mass,
        friction=reader.number(data.get("friction", 0.8), f"{key}.friction", minimum=0.0),
        rolling_friction=reader.number(data.get("rolling_friction", 0.0), f"{key}.rolling_friction", minimum=0.0),
    )


def _read_search(reader: _Reader, value: Any, key: str) -> SearchParams:
    data = reader.mapping(value, key)
    names = [f.name for f in fields(SearchParams)]
    reader.known_keys(data, key, names)
    values: dict[str, Any] = {}
    for name in names:
        if name not in data:
            continue
        at = f"{key}.{name}" if key else name
        if name in SEARCH_CHOICES:
            if data[name] not in SEARCH_CHOICES[name]:
                choices = ", ".join(SEARCH_CHOICES[name])
                raise reader.fail(at, f"must be one of {choices}, got {_show(data[name])}")
            values[name] = data[name]
        else:
            values[name] = reader.number(data[name], at, minimum=0.0)
            if name in SEARCH_INTEGERS:
                if not values[name].is_integer():
                    raise reader.fail(at, f"must be a whole number, got {values[name]:g}")
                values[name] = int(values[name])
    params = replace(SearchParams(), **values)
    problem = search_params_problem(params)
    if problem is not None:
        raise reader.fail(key, problem)
    return params


def _read_workspace(reader: _Reader, value: Any, key: str) -> Workspace:
    data = reader.mapping(value, key)
    reader.known_keys(data, key, ("min", "max"))
    low, high = (
        reader.vector(reader.required(data, corner, key), f"{key}.{corner}", 3, magnitude=MAX_COORDINATE)
        for corner in ("min", "max")
    )
    for axis, a, b in zip("xyz", low, high, strict=True):
        if a >= b:
            raise reader.fail(key, f"min must be below max on every axis, but {axis}: {a:g} >= {b:g}")
    return Workspace((low[0], low[1], low[2]), (high[0], high[1], high[2]))


def search_with_overrides(
    params: SearchParams, overrides: Mapping[str, Any], source: str, key: str = "search"
) -> SearchParams:
    """``params`` with ``overrides`` (name -> value as YAML gives it) merged over them, validated as a
    scene file's ``search:`` section is; raises :class:`SceneError` naming ``source`` and ``key.name``
    (``name`` alone for an empty ``key``).

    The one way search parameters are overridden: by a problem file's ``search:``, ``solve
    --deadline``, ``evaluate``/``sweep --set/--grid`` and the node's parameters.
    """
    merged = {f.name: getattr(params, f.name) for f in fields(SearchParams)} | dict(overrides)
    return _read_search(_Reader(source), merged, key)


_SCENE_KEYS = ("frame_id", "static", "objects", "search", "ground_truth", "workspace", "class_map", "frames")
#: Fixed sensor frames a scene file may declare at most.
MAX_FIXED_FRAMES = 1000


def _read_frames(reader: _Reader, value: Any, key: str, scene_frame: str) -> tuple[FixedFrame, ...]:
    """``frames:`` frame name -> ``{parent, position, orientation}`` (parent: the scene's frame by default).

    A parent may be another fixed frame, the scene's frame, or a frame that ``/tf`` gives (a
    camera calibrated to a robot's flange); the parents must not loop.
    """
    data = reader.mapping(value, key)
    if len(data) > MAX_FIXED_FRAMES:
        raise reader.fail(key, f"{len(data)} frames (at most {MAX_FIXED_FRAMES})")
    frames = []
    for name, item in data.items():
        at = f"{key}.{name}"
        reader.name(name, key)
        entry = reader.mapping(item, at)
        reader.known_keys(entry, at, ("parent", "position", "orientation"))
        parent = reader.name(entry.get("parent", scene_frame), f"{at}.parent")
        if name == scene_frame:
            raise reader.fail(at, f"the scene's frame {scene_frame!r} is the root, not a fixed frame")
        pose = _read_pose(reader, {k: v for k, v in entry.items() if k != "parent"}, at)
        frames.append(FixedFrame(name, parent, pose))
    parents = {frame.name: frame.parent for frame in frames}
    for frame in frames:
        seen = [frame.name]
        while seen[-1] in parents:
            seen.append(parents[seen[-1]])
            if seen[-1] in seen[:-1]:
                raise reader.fail(f"{key}.{frame.name}", f"the parents loop: {' -> '.join(seen)}")
    return tuple(frames)


def _read_class_map(
    reader: _Reader, value: Any, key: str, names: Sequence[str], counted: Mapping[str, tuple[str, ...]]
) -> tuple[tuple[str, tuple[str, ...]], ...]:
    """``class_map:`` class id -> an object name or a list of them (instances); each object in one class.

    A ``count:`` entry's name stands for all its instances (``counted``: entry name -> instance names).
    A counted entry none of whose instances is mapped gets its own name as class id.
    """
    mapping: dict[str, tuple[str, ...]] = {}
    owner: dict[str, str] = {}
    for class_id, objects in reader.mapping(value, key).items():
        at = f"{key}.{class_id}"
        reader.name(class_id, key)
        listed = [objects] if isinstance(objects, str) else list(reader.sequence(objects, at))
        if not listed:
            raise reader.fail(at, "needs at least one object")
        expanded: list[str] = []
        for name in listed:
            if isinstance(name, str) and name in counted:
                expanded += counted[name]
            elif name in names:
                expanded.append(name)
            else:
                raise reader.fail(at, f"{_show(name)} is not an object of the scene")
        for name in expanded:
            if name in owner:
                raise reader.fail(at, f"{name!r} is already the object of class {owner[name]!r}")
            owner[name] = class_id
        mapping[class_id] = tuple(expanded)
    for entry, instances in counted.items():
        if entry not in mapping and not any(name in owner for name in instances):
            mapping[entry] = instances
    return tuple(mapping.items())


def scene_from_dict(
    data: Any, source: str, base_dir: Path | None = None, progress: Progress = stderr_progress
) -> Scene:
    """Build a validated :class:`Scene` from parsed YAML; ``source`` names it in errors.

    Relative mesh paths are taken relative to ``base_dir`` (the scene file's folder; None: the
    working directory). ``progress`` hears of convex decompositions being computed.
    """
    reader = _Reader(source)
    meshes = _MeshLoader(reader, base_dir, progress)
    top = reader.mapping(data, "")
    reader.known_keys(top, "", (*_SCENE_KEYS, "hypotheses", "scene"))
    frame_id = reader.name(top.get("frame_id", "world"), "frame_id")
    static_items = reader.sequence(top.get("static", []), "static")
    if len(static_items) > MAX_STATIC_BODIES:
        raise reader.fail("static", f"{len(static_items)} static bodies (at most {MAX_STATIC_BODIES})")
    static = tuple(_read_static(reader, item, f"static[{i}]", meshes) for i, item in enumerate(static_items))
    items = reader.sequence(reader.required(top, "objects", ""), "objects")
    if not items:
        raise reader.fail("objects", "needs at least one object")
    if len(items) > MAX_OBJECTS:
        raise reader.fail("objects", f"{len(items)} objects (at most {MAX_OBJECTS}: split the scene)")
    entries = tuple(_read_entry(reader, item, f"objects[{i}]", meshes) for i, item in enumerate(items))
    objects = tuple(model for entry in entries for model in entry.objects)
    if len(objects) > MAX_OBJECTS:
        raise reader.fail("objects", f"{len(objects)} objects with instances (at most {MAX_OBJECTS}: split the scene)")
    counted = {entry.name: tuple(o.name for o in entry.objects) for entry in entries if entry.counted}
    names = [o.name for o in objects] + [b.name for b in static]
    for entry in counted:
        if entry in names:
            raise reader.fail("objects", f"duplicate body name {entry!r} (the name of a count: entry)")
    for i, name in enumerate(names):
        if name in names[:i]:
            raise reader.fail("objects" if i < len(objects) else "static", f"duplicate body name {name!r}")
    clash = topic_clash([o.name for o in objects])
    if clash is not None:
        first, second, topic = clash
        raise reader.fail("objects", f"objects {first!r} and {second!r} would share the node's topic {topic!r}")
    _note_mass_ratio(reader, objects)
    _note_large_meshes(reader, objects)
    search = _read_search(reader, top.get("search", {}), "search")
    truth = None
    if "ground_truth" in top:
        truth = _read_per_object(reader, top["ground_truth"], "ground_truth", [o.name for o in objects], _read_pose)
    workspace = _read_workspace(reader, top["workspace"], "workspace") if "workspace" in top else None
    object_names = [o.name for o in objects]
    class_map = _read_class_map(reader, top.get("class_map", {}), "class_map", object_names, counted)
    optional = frozenset(o.name for entry in entries if entry.optional for o in entry.objects)
    frames = _read_frames(reader, top.get("frames", {}), "frames", frame_id)
    scene = Scene(
        objects,
        static,
        search,
        frame_id,
        ground_truth=truth,
        explicit_workspace=workspace,
        class_map=class_map,
        optional=optional,
        frames=frames,
        notes=tuple(reader.notes),
    )
    for model, pose in zip(objects, truth or (), strict=False):
        _check_inside(reader, scene.workspace, pose, f"ground_truth.{model.name}")
    return scene


def _note_mass_ratio(reader: _Reader, objects: Sequence[ObjectModel]) -> None:
    """Warn when the heaviest object outweighs the lightest by more than Bullet stacks reliably."""
    heaviest = max(objects, key=lambda o: o.mass)
    lightest = min(objects, key=lambda o: o.mass)
    ratio = heaviest.mass / lightest.mass
    if ratio > MAX_MASS_RATIO:
        reader.note(
            "objects",
            f"{heaviest.name} ({heaviest.mass:g} kg) is {ratio:.3g} times as heavy as {lightest.name} "
            f"({lightest.mass:g} kg): beyond a ratio of {MAX_MASS_RATIO:g}, a heavy object resting on a light one "
            "sinks into it in Bullet and a valid stack can be rejected as unstable",
        )


def _note_large_meshes(reader: _Reader, objects: Sequence[ObjectModel]) -> None:
    """Warn, once per shape, of a movable mesh larger than household objects are: a file not in metres."""
    noted: set[Mesh] = set()
    for model in objects:
        if not isinstance(model.shape, Mesh) or model.shape in noted:
            continue
        noted.add(model.shape)
        extent = float(np.max(shape_extents(model.shape)))
        if extent > MAX_UNWARNED_MESH_EXTENT:
            reader.note(
                "objects",
                f"{model.name}'s mesh is {extent:.3g} m across: if its file is not in metres, give it a scale "
                "(0.01 for centimetres, 0.001 for millimetres)",
            )


def _check_inside(reader: _Reader, workspace: Workspace, pose: Pose, key: str) -> None:
    problem = workspace.problem(pose.position)
    if problem is not None:
        raise reader.fail(f"{key}.position", problem)


def _read_per_object(
    reader: _Reader, value: Any, key: str, names: Sequence[str], read: Callable[[_Reader, Any, str], T]
) -> tuple[T, ...]:
    """Read a mapping object name -> item that must cover exactly the scene's objects, in object order."""
    given = reader.mapping(value, key)
    for name in given:
        if name not in names:
            raise reader.fail(f"{key}.{name}", f"no object of that name in the scene (objects: {', '.join(names)})")
    items = []
    for name in names:
        if name not in given:
            raise reader.fail(f"{key}.{name}", "missing: every object needs one")
        items.append(read(reader, given[name], f"{key}.{name}"))
    return tuple(items)


def _read_hypotheses(reader: _Reader, value: Any, key: str, workspace: Workspace) -> RankedHypotheses:
    """An object's hypotheses, each inside ``workspace``, ranked.

    More than :data:`~physics_mapper.model.limits.MAX_HYPOTHESES_PER_OBJECT` keep the heaviest, with a note.
    """
    items = reader.sequence(value, key)
    if not items:
        raise reader.fail(key, "needs at least one hypothesis")
    hypotheses = []
    for i, item in enumerate(items):
        item_key = f"{key}[{i}]"
        data = reader.mapping(item, item_key)
        reader.known_keys(data, item_key, ("position", "orientation", "weight"))
        pose = _read_pose(reader, {k: v for k, v in data.items() if k != "weight"}, item_key, magnitude=None)
        _check_inside(reader, workspace, pose, item_key)
        weight = reader.number(data.get("weight", 1.0), f"{item_key}.weight", minimum=0.0)
        hypotheses.append(Hypothesis(pose, weight))
    try:
        ranked = RankedHypotheses.from_weighted(hypotheses, keep_at_most=MAX_HYPOTHESES_PER_OBJECT)
    except ValueError as error:  # the weights as a whole: all zero, or a sum that overflows
        raise reader.fail(key, str(error)) from None
    if len(hypotheses) > len(ranked):
        reader.note(key, f"kept the {len(ranked)} heaviest of {len(hypotheses)} hypotheses")
    return ranked


def problem_from_dict(
    data: Any, source: str, base_dir: Path | None = None, progress: Progress = stderr_progress
) -> Problem:
    """Build a :class:`Problem`: an inline scene (or ``scene: path``) plus ``hypotheses``.

    A relative ``scene:`` path (and an inline scene's relative mesh paths) is taken relative to
    ``base_dir`` (the problem file's folder).
    """
    reader = _Reader(source)
    top = reader.mapping(data, "")
    if "scene" in top:
        reader.known_keys(top, "", ("scene", "hypotheses", "search"))
        scene_path = Path(reader.name(top["scene"], "scene"))
        if not scene_path.is_absolute() and base_dir is not None:
            scene_path = base_dir / scene_path
        scene = load_scene(scene_path, progress)
        if "search" in top:
            overrides = reader.mapping(top["search"], "search")
            scene = replace(scene, search=search_with_overrides(scene.search, overrides, source))
    else:
        scene = scene_from_dict(top, source, base_dir, progress)
    given = reader.required(top, "hypotheses", "")
    workspace = scene.workspace

    def read_hypotheses(reader: _Reader, value: Any, key: str) -> RankedHypotheses:
        return _read_hypotheses(reader, value, key, workspace)

    hypotheses = _read_per_object(reader, given, "hypotheses", scene.object_names, read_hypotheses)
    return Problem(scene, hypotheses, (*scene.notes, *reader.notes))


def _load_yaml(path: Path) -> Any:
    try:
        return read_yaml(path)
    except FileError as error:
        raise SceneError(error.source, error.key, error.problem) from None


def load_scene(path: str | Path, progress: Progress = stderr_progress) -> Scene:
    """Load and validate a scene file; raises :class:`SceneError`.

    ``progress`` hears of convex decompositions being computed (by default: a line on stderr).
    """
    path = Path(path)
    return scene_from_dict(_load_yaml(path), str(path), path.parent, progress)


def load_problem(path: str | Path, progress: Progress = stderr_progress) -> Problem:
    """Load and validate a problem file; raises :class:`SceneError`."""
    path = Path(path)
    return problem_from_dict(_load_yaml(path), str(path), path.parent, progress)

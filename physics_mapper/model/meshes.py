"""Mesh shapes: OBJ and STL files read with trimesh, checked, and turned into what the physics needs.

A mesh is posed in its file's own frame (as URDF and RViz do): a body at pose P puts the file's
origin at P. ``scale`` multiplies the file's coordinates per axis (metres = file units x scale).

Collision geometry, by ``collision``:

* ``convex_hull``: the convex hull of the vertices, one convex part. Right for convex objects
  (boxes, bottles, bricks); solid where a concave object is hollow.
* ``decomposition``: convex parts from :mod:`~physics_mapper.model.decomposition` (CoACD or V-HACD,
  cached), or read from a ``parts`` file (an OBJ of convex groups). Follows cavities and handles.
* ``triangle_mesh`` (static bodies only): the triangles themselves, a Bullet BVH triangle mesh.
  A surface, not a solid: a body wholly inside it touches no triangle and is not a collision.

Mass properties (movable objects), for a uniform density:

* volume V (m^3), centre of mass c (m, mesh frame) and the inertia tensor about c, from the mesh
  itself when it is closed (watertight, consistently wound; an inside-out mesh is turned), by
  trimesh's exact integration over the solid's tetrahedra;
* otherwise from the collision geometry (the hull, or the parts, an overlap counted twice), as
  Bullet will simulate it; ``density`` needs a closed mesh's volume and is refused otherwise.

The tensor is kept per kilogram, I_1 = I / m (m^2), factored as I_1 = R diag(l1, l2, l3) R^T with
R a proper rotation: the principal moments l and the principal axes R (as a quaternion) are what
pybullet takes (an inertial frame at c turned by R, and a diagonal inertia m * l).
"""

from __future__ import annotations

import functools
import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from physics_mapper.model.decomposition import (
    ConvexPart,
    Decomposition,
    DecompositionError,
    DecompositionSettings,
    FloatArray,
    IntArray,
    Progress,
    decompose,
    parts_from_file,
    stderr_progress,
)
from physics_mapper.model.geometry import Quaternion, Vector3
from physics_mapper.model.interrupts import signals_kept
from physics_mapper.model.limits import MAX_COORDINATE

if TYPE_CHECKING:
    import trimesh

#: How Bullet collides a mesh (module docstring).
MeshCollision = Literal["convex_hull", "decomposition", "triangle_mesh"]
#: Mesh file formats, by lower-case suffix.
MESH_FORMATS = {".obj": "obj", ".stl": "stl"}
#: Most vertices a mesh file may have (pybullet's own limit for a triangle mesh is 131072).
MAX_MESH_VERTICES = 100_000
#: Most triangles a mesh file may have: a closed surface has about twice as many triangles as vertices.
#: Counted in the file's text (or binary STL header) before trimesh parses it, since parsing is the cost
#: (measured, ``BENCHMARKS.md`` "Input caps": 4.2 million faces took 32 s and 1.9 GB); an OBJ polygon
#: counts as the triangles trimesh makes of it.
MAX_MESH_FACES = 2 * MAX_MESH_VERTICES
#: Largest mesh file read, bytes (100,000 vertices take about 5 MB as OBJ text).
MAX_MESH_FILE_BYTES = 64 * 1024 * 1024
#: A part or mesh whose hull is thinner than this many metres in some direction has no volume.
DEGENERATE_THICKNESS = 1e-9


class MeshError(ValueError):
    """A mesh file is unusable: the message names the file and what is wrong."""

    def __init__(self, path: Path, problem: str) -> None:
        super().__init__(f"{path}: {problem}")
        self.path = path
        self.problem = problem


@dataclass(frozen=True)
class MassProperties:
    """Mass properties of a rigid solid of uniform density, in the mesh frame (see the module docstring).

    ``volume`` m^3; ``centre_of_mass`` m; ``principal_moments`` m^2 (inertia per kilogram about
    the centre of mass along the principal axes); ``principal_axes`` the unit quaternion (x, y, z, w)
    turning the mesh frame's axes onto them; ``source`` what they were computed from
    (``mesh``, ``convex hull`` or ``decomposition``).
    """

    volume: float
    centre_of_mass: Vector3
    principal_moments: Vector3
    principal_axes: Quaternion
    source: str

    def inertia_tensor(self, mass: float) -> FloatArray:
        """The 3 x 3 inertia tensor (kg m^2) about the centre of mass, mesh frame axes, for ``mass`` kg."""
        from scipy.spatial.transform import Rotation  # here: scipy costs a node ~40 MB it rarely needs

        rotation = Rotation.from_quat(self.principal_axes).as_matrix()
        tensor: FloatArray = mass * rotation @ np.diag(self.principal_moments) @ rotation.T
        return tensor


@dataclass(frozen=True, eq=False)
class MeshGeometry:
    """A loaded mesh, scaled, in its file's frame: the surface, its collision parts, its mass properties.

    ``parts`` are the convex collision parts (the hull alone for ``convex_hull``; none for
    ``triangle_mesh``); ``decomposition`` the parts' provenance and the unscaled OBJ pybullet
    loads for ``decomposition``; ``mass_properties`` None for static bodies.
    """

    vertices: FloatArray
    faces: IntArray
    closed: bool
    parts: tuple[ConvexPart, ...]
    decomposition: Decomposition | None
    mass_properties: MassProperties | None

    # Cached: searches ask for every object's bounds and radius per group (mesh vertices, ~50 us a call).
    @functools.cached_property
    def bounds(self) -> tuple[Vector3, Vector3]:
        """Axis-aligned bounding box (min corner, max corner) of the mesh and its parts, m, mesh frame."""
        points = self.collision_points
        low, high = points.min(axis=0), points.max(axis=0)
        return (float(low[0]), float(low[1]), float(low[2])), (float(high[0]), float(high[1]), float(high[2]))

    @functools.cached_property
    def bounding_radius(self) -> float:
        """Largest distance (m) from the mesh frame's origin to a point of the mesh or of its parts."""
        return float(np.linalg.norm(self.collision_points, axis=1).max())

    @functools.cached_property
    def collision_points(self) -> FloatArray:
        """Every vertex of the surface and of the parts (K x 3, m, mesh frame)."""
        points: FloatArray = np.vstack([self.vertices, *(part.vertices for part in self.parts)])
        return points


@dataclass(frozen=True)
class MeshRequest:
    """What a body asks of its mesh file (the ``shape: mesh`` keys of a scene).

    ``parts_file``: an OBJ of convex parts used instead of computing a decomposition.
    ``mass_properties``: a movable object needs them; ``needs_volume``: its mass comes from
    ``density``, so the mesh must be closed.
    """

    file: Path
    scale: Vector3 = (1.0, 1.0, 1.0)
    collision: MeshCollision = "convex_hull"
    decomposition: DecompositionSettings = field(default_factory=DecompositionSettings)
    parts_file: Path | None = None
    mass_properties: bool = True
    needs_volume: bool = False


def load_mesh_geometry(request: MeshRequest, progress: Progress = stderr_progress) -> MeshGeometry:
    """Read, check and prepare a mesh (see the module docstring); raises :class:`MeshError`.

    ``progress`` hears of a decomposition being computed (the first load of a mesh only).
    """
    path = request.file
    raw = _read_surface(path)
    scale = np.asarray(request.scale, dtype=np.float64)
    surface = _scaled(raw, scale)
    _check_magnitude(path, np.asarray(surface.vertices), " (scaled)")
    parts: tuple[ConvexPart, ...] = ()
    decomposition = None
    if request.collision == "convex_hull":
        parts = (_convex_hull(surface.vertices, path, "mesh"),)
    elif request.collision == "decomposition":
        decomposition = _decomposition(request, raw, path, progress)
        parts = tuple(
            _convex_hull(part.vertices * scale, path, f"convex part {i}") for i, part in enumerate(decomposition.parts)
        )
    elif not (surface.area_faces > 0.0).any():
        raise MeshError(path, "degenerate: every triangle has zero area")
    closed = _is_closed(surface)
    mass = None
    if request.mass_properties:
        if request.needs_volume and not closed:
            edges = _open_edges(surface)
            raise MeshError(path, f"not a closed mesh ({edges} open edges): density needs its volume: give mass")
        mass = _mass_properties(surface, "mesh") if closed else _parts_mass_properties(parts, request.collision)
    return MeshGeometry(
        np.asarray(surface.vertices, dtype=np.float64),
        np.asarray(surface.faces, dtype=np.int64),
        closed,
        parts,
        decomposition,
        mass,
    )


def _read_surface(path: Path) -> trimesh.Trimesh:
    """The file's triangles with coincident vertices merged (texture seams do not open a surface)."""
    with signals_kept():  # trimesh's import guards catch BaseException: a Ctrl-C in them would be lost
        import trimesh

    kind = MESH_FORMATS.get(path.suffix.lower())
    if kind is None:
        raise MeshError(path, f"unsupported mesh format {path.suffix!r} (expected one of: {', '.join(MESH_FORMATS)})")
    try:
        size = path.stat().st_size
        if size > MAX_MESH_FILE_BYTES:
            raise MeshError(path, f"too large: {size} bytes (at most {MAX_MESH_FILE_BYTES}; simplify the mesh)")
        data = path.read_bytes()
    except OSError as error:
        raise MeshError(path, f"cannot read mesh file: {error.strerror or error}") from None
    if not data.strip():
        raise MeshError(path, "empty file")
    if kind == "obj":
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            raise MeshError(path, "not a mesh: an OBJ file is text, this is not") from None
    faces_given = _counted_faces(data, kind)
    if faces_given > MAX_MESH_FACES:
        raise MeshError(path, f"too many faces: {faces_given} (at most {MAX_MESH_FACES}; simplify the mesh)")
    vertices_given = data.count(b"\nv ") + data.count(b"\nv\t") + int(data.startswith((b"v ", b"v\t")))
    if kind == "obj" and vertices_given > MAX_MESH_VERTICES:
        raise MeshError(path, f"too many vertices: {vertices_given} (at most {MAX_MESH_VERTICES}; simplify the mesh)")
    try:
        with signals_kept():  # so do its parsers
            loaded: Any = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh", process=False)
        vertices = np.asarray(loaded.vertices, dtype=np.float64)
        faces = np.asarray(loaded.faces, dtype=np.int64)
    except Exception as error:  # trimesh's parsers raise anything on malformed input
        reason = f"not a mesh: trimesh cannot read it as {kind.upper()} ({type(error).__name__})"
        raise MeshError(path, reason) from None
    if len(faces) == 0:
        raise MeshError(path, f"not a mesh: no triangles in it ({len(vertices)} vertices)")
    if len(vertices) > MAX_MESH_VERTICES:
        raise MeshError(path, f"too many vertices: {len(vertices)} (at most {MAX_MESH_VERTICES}; simplify the mesh)")
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise MeshError(path, f"non-finite vertex coordinates (NaN or Inf) at vertex {int(np.argmax(bad)) + 1}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(path, "a face refers to a vertex that does not exist")
    if len(faces) > MAX_MESH_FACES:
        raise MeshError(path, f"too many faces: {len(faces)} (at most {MAX_MESH_FACES}; simplify the mesh)")
    _check_magnitude(path, vertices, "")
    surface = trimesh.Trimesh(vertices, faces, process=False)
    surface.merge_vertices(merge_tex=True, merge_norm=True)
    surface.update_faces(surface.nondegenerate_faces())
    if len(surface.faces) == 0:
        raise MeshError(path, "degenerate: every triangle has zero area")
    return surface


#: OBJ's whitespace within a line as a space, every other byte but a line break as ``x``: a token
#: starts wherever ``" x"`` stands in the translated text.
_TOKEN_STARTS = bytes(32 if chr(b) in " \t\r\v\f" else 10 if b == 10 else ord("x") for b in range(256))
#: Every line of an OBJ file but its faces (``f`` and whitespace), line break included.
_NOT_FACE_LINES = re.compile(rb"^(?!f[ \t]).*\n?", re.MULTILINE)


def _counted_faces(data: bytes, kind: str) -> int:
    """Triangles the file declares, counted without parsing it: an OBJ polygon of n corners is the n - 2
    triangles trimesh makes of it (so one line listing millions of corners counts as what it costs);
    STL facets."""
    if kind == "obj":
        faces = _NOT_FACE_LINES.sub(b"", data)
        corners = faces.translate(_TOKEN_STARTS).count(b" x")
        lines = faces.count(b"\n") + int(bool(faces) and not faces.endswith(b"\n"))
        return corners - 2 * lines
    if data[:5].lower() == b"solid" and b"facet" in data[:1024]:
        return data.count(b"facet normal")
    declared = int.from_bytes(data[80:84], "little") if len(data) >= 84 else 0  # binary STL's triangle count
    return declared if len(data) == 84 + 50 * declared else 0  # not binary STL: for trimesh to refuse


def _check_magnitude(path: Path, vertices: FloatArray, scaled: str) -> None:
    """Refuse coordinates beyond :data:`~physics_mapper.model.limits.MAX_COORDINATE` (the physics' trusted range)."""
    if len(vertices) == 0:
        return
    largest = float(np.abs(vertices).max())
    if largest > MAX_COORDINATE:
        index = int(np.argmax(np.abs(vertices).max(axis=1))) + 1
        raise MeshError(
            path,
            f"vertex {index}{scaled} is {largest:g} m from the origin, beyond the ±{MAX_COORDINATE:g} m "
            "where the physics is trusted",
        )


def _scaled(surface: trimesh.Trimesh, scale: NDArray[np.float64]) -> trimesh.Trimesh:
    import trimesh

    return trimesh.Trimesh(surface.vertices * scale, surface.faces, process=False)


def _is_closed(surface: trimesh.Trimesh) -> bool:
    """Watertight and consistently wound; an inside-out closed mesh is turned the right way out."""
    if not (surface.is_watertight and surface.is_winding_consistent):
        return False
    if surface.volume < 0.0:
        surface.invert()
    return bool(surface.volume > 0.0)


def _open_edges(surface: trimesh.Trimesh) -> int:
    """Edges that border fewer or more than two triangles."""
    edges = np.sort(surface.edges, axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int((counts != 2).sum())


def _convex_hull(points: FloatArray, path: Path, what: str) -> ConvexPart:
    """The convex hull of ``points`` as a part; MeshError if they span no volume."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError):
        reason = f"degenerate: the {what}'s vertices are coplanar or fewer than 4, so it has no volume"
        raise MeshError(path, reason) from None
    if hull.volume <= DEGENERATE_THICKNESS * max(float(np.ptp(points, axis=0).max()), 1e-3) ** 2:
        raise MeshError(path, f"degenerate: the {what} has no volume")
    used, inverse = np.unique(hull.simplices, return_inverse=True)
    faces = inverse.reshape(-1, 3).astype(np.int64)
    vertices = np.asarray(points[used], dtype=np.float64)
    # Qhull's simplices are not consistently oriented: turn each triangle's normal outwards.
    centre = vertices.mean(axis=0)
    corners = vertices[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    inward = np.einsum("ij,ij->i", normals, corners[:, 0] - centre) < 0.0
    faces[inward] = faces[inward][:, ::-1]
    return ConvexPart(vertices, faces)


def _decomposition(request: MeshRequest, raw: trimesh.Trimesh, path: Path, progress: Progress) -> Decomposition:
    try:
        if request.parts_file is not None:
            decomposition = parts_from_file(request.parts_file)
        else:
            vertices, faces = np.asarray(raw.vertices), np.asarray(raw.faces)
            decomposition = decompose(path, vertices, faces, request.decomposition, progress)
    except DecompositionError as error:
        raise MeshError(request.parts_file or path, str(error)) from None
    for part in decomposition.parts:
        if not np.isfinite(part.vertices).all():
            raise MeshError(decomposition.file, "non-finite vertex coordinates (NaN or Inf) in a convex part")
    return decomposition


def _mass_properties(solid: trimesh.Trimesh, source: str) -> MassProperties:
    """Volume, centre of mass and principal inertia per kilogram of a closed mesh (trimesh, density 1)."""
    properties = solid.mass_properties
    volume = float(properties.volume)
    return _principal(volume, properties.center_mass, np.asarray(properties.inertia) / volume, source)


def _parts_mass_properties(parts: tuple[ConvexPart, ...], collision: str) -> MassProperties:
    """Mass properties of the union of convex parts (overlaps counted twice), by the parallel axis theorem."""
    import trimesh

    solids = [trimesh.Trimesh(part.vertices, part.faces, process=False).mass_properties for part in parts]
    volume = sum(float(s.volume) for s in solids)
    centre = sum(float(s.volume) * np.asarray(s.center_mass) for s in solids) / volume
    tensor = np.zeros((3, 3))
    for solid in solids:
        offset = np.asarray(solid.center_mass) - centre
        # Each part's inertia (density 1) moved from its own centre of mass to the union's.
        shift = offset @ offset * np.eye(3) - np.outer(offset, offset)
        tensor += np.asarray(solid.inertia) + float(solid.volume) * shift
    source = "convex hull" if collision == "convex_hull" else "decomposition"
    return _principal(volume, centre, tensor / volume, source)


def _principal(volume: float, centre: Any, inertia_per_kg: FloatArray, source: str) -> MassProperties:
    """Factor a symmetric inertia tensor per kilogram into principal moments and a proper rotation."""
    moments, axes = np.linalg.eigh((inertia_per_kg + inertia_per_kg.T) / 2.0)
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    from scipy.spatial.transform import Rotation  # here: see MassProperties.inertia_tensor

    x, y, z, w = Rotation.from_matrix(axes).as_quat(canonical=True)
    cx, cy, cz = (float(v) for v in centre)
    l1, l2, l3 = (max(float(m), 0.0) for m in moments)
    return MassProperties(volume, (cx, cy, cz), (l1, l2, l3), (float(x), float(y), float(z), float(w)), source)

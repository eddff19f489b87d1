"""Search results -> map messages: chosen and settled PoseArrays, per-object PoseStamped, and RViz markers.

Marker namespaces (``ns``), each with ``id`` = the body's index in its scene list:

* ``objects``: every object in its true shape: CUBE, SPHERE, CYLINDER, or MESH_RESOURCE (the mesh
  file by a URI RViz resolves, scaled); green at the chosen poses, orange at the settled poses
  of a fallback;
* ``labels``: a text ``name`` / ``J=`` above each object;
* an object the map leaves out (*absent*) gets DELETE markers in both namespaces;
* ``static``: the fixed bodies (floor, walls, table, tray) in grey, so RViz shows the whole scene;
  a plane as a thin square of :data:`PLANE_MARKER_SIZE` whose top face is the plane.
"""

from __future__ import annotations

from collections.abc import Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseArray, PoseStamped, Vector3
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from physics_mapper.model.geometry import Pose, compose_poses
from physics_mapper.model.scene import Box, Cylinder, Mesh, Plane, Scene, Shape, Sphere
from physics_mapper.msg_adapters.hypotheses import pose_array_msg, pose_msg, stamp_from_nanoseconds
from physics_mapper.search.report import code_text
from physics_mapper.search.results import SearchResult

#: Marker namespaces (see the module docstring), ``id`` = the body's index in its scene list.
SHAPE_NAMESPACE = "objects"
LABEL_NAMESPACE = "labels"
STATIC_NAMESPACE = "static"
LABEL_HEIGHT = 0.04  # metres, height of an upper-case letter in RViz
#: Side and thickness, metres, of the square that stands for an infinite plane.
PLANE_MARKER_SIZE = 4.0
PLANE_MARKER_THICKNESS = 0.002
VALID_COLOR = ColorRGBA(r=0.2, g=0.7, b=0.3, a=0.8)
FALLBACK_COLOR = ColorRGBA(r=0.95, g=0.6, b=0.1, a=0.8)
LABEL_COLOR = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
STATIC_COLOR = ColorRGBA(r=0.6, g=0.6, b=0.62, a=0.6)


def configuration_msgs(
    result: SearchResult, *, frame_id: str, stamp_ns: int, present: Sequence[int] | None = None
) -> tuple[PoseArray, PoseArray] | None:
    """The chosen poses and their settled poses of the objects the map holds (``present``, scene indices;
    None: every object), in scene object order; None if nothing was chosen.

    ``stamp_ns``: the header stamp, integer nanoseconds (the newest input stamp used). Objects the map
    leaves out (*absent*) are not in the arrays: with instances that come and go, the arrays hold the
    present ones in scene order (``~/objects`` names them).
    """
    if result.poses is None or result.settled_poses is None:
        return None
    kept = range(len(result.poses)) if present is None else present
    return (
        pose_array_msg([result.poses[i] for i in kept], frame_id=frame_id, stamp_ns=stamp_ns),
        pose_array_msg([result.settled_poses[i] for i in kept], frame_id=frame_id, stamp_ns=stamp_ns),
    )


#: ``~/map_status``'s message for a valid map, and before the first map.
VALID_MAP = "valid"
NO_MAP_YET = "no map yet"


def map_status_msg(
    result: SearchResult | None,
    scene: Scene,
    *,
    name: str,
    hardware_id: str,
    stamp_ns: int,
    present: Sequence[int] | None = None,
) -> DiagnosticArray:
    """What the map published with the same stamp is: one status, OK for a valid map, WARN for a fallback.

    Its message is ``valid``, ``fallback settled`` or ``fallback refine`` (``no map yet`` before the
    first); its keys: ``valid`` (``true``/``false``), ``fallback`` (``none``, ``settled``,
    ``refine``), ``code`` (the configuration's code, ``-`` without one) and ``objects``: the names
    of the objects ``present`` (scene indices; None: every object), comma-separated, in the order of
    ``~/configuration``'s poses.
    """
    if result is None or result.poses is None:
        level, message, fallback, code = DiagnosticStatus.WARN, NO_MAP_YET, "none", "-"
    elif result.valid:
        level, message, fallback, code = DiagnosticStatus.OK, VALID_MAP, "none", code_text(result.code)
    else:
        fallback = str(result.fallback or "settled")
        level, message, code = DiagnosticStatus.WARN, f"fallback {fallback}", code_text(result.code)
    values = [
        KeyValue(key="valid", value="true" if result is not None and result.valid else "false"),
        KeyValue(key="fallback", value=fallback),
        KeyValue(key="code", value=code),
        KeyValue(key="objects", value=",".join(_present_names(scene, present))),
    ]
    status = DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id, values=values)
    return DiagnosticArray(header=Header(stamp=stamp_from_nanoseconds(stamp_ns)), status=[status])


def _present_names(scene: Scene, present: Sequence[int] | None) -> list[str]:
    """The names of the objects ``present`` (scene indices; None: every object), in ``~/configuration``'s order."""
    names = scene.object_names
    return list(names) if present is None else [names[index] for index in present]


def object_pose_msgs(
    result: SearchResult, *, frame_id: str, stamp_ns: int, present: Sequence[int] | None = None
) -> tuple[tuple[PoseStamped, PoseStamped] | None, ...] | None:
    """Per object, in scene order, its chosen and its settled pose (None for an object not in ``present``,
    scene indices; None: every object is); None if nothing was chosen.

    Same header as :func:`configuration_msgs`: a consumer of one object gets the map's frame and stamp.
    """
    if result.poses is None or result.settled_poses is None:
        return None
    header = Header(frame_id=frame_id, stamp=stamp_from_nanoseconds(stamp_ns))
    kept = set(range(len(result.poses)) if present is None else present)
    return tuple(
        (PoseStamped(header=header, pose=pose_msg(chosen)), PoseStamped(header=header, pose=pose_msg(settled)))
        if index in kept
        else None
        for index, (chosen, settled) in enumerate(zip(result.poses, result.settled_poses, strict=True))
    )


def _shape(marker: Marker, shape: Shape) -> None:
    """Set the marker type and scale (full extents, metres) to the shape's, and offset a plane's pose."""
    if isinstance(shape, Box):
        marker.type = Marker.CUBE
        marker.scale = Vector3(x=shape.size[0], y=shape.size[1], z=shape.size[2])
    elif isinstance(shape, Sphere):
        marker.type = Marker.SPHERE
        diameter = 2.0 * shape.radius
        marker.scale = Vector3(x=diameter, y=diameter, z=diameter)
    elif isinstance(shape, Cylinder):
        marker.type = Marker.CYLINDER  # RViz's cylinder is along local z, like pybullet's
        diameter = 2.0 * shape.radius
        marker.scale = Vector3(x=diameter, y=diameter, z=shape.length)
    elif isinstance(shape, Mesh):
        marker.type = Marker.MESH_RESOURCE  # posed in the file's frame, as pybullet and URDF do
        marker.mesh_resource = shape.uri
        marker.scale = Vector3(x=shape.scale[0], y=shape.scale[1], z=shape.scale[2])
    else:
        assert isinstance(shape, Plane)
        marker.type = Marker.CUBE
        marker.scale = Vector3(x=PLANE_MARKER_SIZE, y=PLANE_MARKER_SIZE, z=PLANE_MARKER_THICKNESS)


def _top(shape: Shape) -> float:
    """Height above the pose's origin (metres) of the shape's top, unrotated, to put a label above it."""
    if isinstance(shape, Box):
        return shape.size[2] / 2.0
    if isinstance(shape, Sphere):
        return shape.radius
    if isinstance(shape, Cylinder):
        return max(shape.length / 2.0, shape.radius)
    assert isinstance(shape, Mesh)
    return shape.geometry.bounds[1][2]


def _marker_pose(shape: Shape, pose: Pose) -> Pose:
    """Where the marker goes: the body's pose, or for a plane the centre of its thin square, below the plane."""
    if isinstance(shape, Plane):
        return compose_poses(pose, Pose((0.0, 0.0, -PLANE_MARKER_THICKNESS / 2.0)))
    return pose


def static_markers(scene: Scene, header: Header) -> list[Marker]:
    """The scene's fixed bodies in their shapes, grey, namespace ``static``."""
    markers = []
    for index, body in enumerate(scene.static):
        marker = Marker(header=header, ns=STATIC_NAMESPACE, id=index, action=Marker.ADD)
        marker.pose = pose_msg(_marker_pose(body.shape, body.pose))
        _shape(marker, body.shape)
        marker.color = STATIC_COLOR
        markers.append(marker)
    return markers


def static_markers_msg(scene: Scene, *, stamp_ns: int) -> MarkerArray:
    """The fixed bodies alone (:func:`static_markers`), so RViz shows the scene before the first map."""
    return MarkerArray(
        markers=static_markers(scene, Header(frame_id=scene.frame_id, stamp=stamp_from_nanoseconds(stamp_ns)))
    )


def markers_msg(
    result: SearchResult, scene: Scene, *, stamp_ns: int, present: Sequence[int] | None = None
) -> MarkerArray:
    """One marker per object present in its true shape, a text label ``name J=...``, and the fixed bodies.

    A valid configuration is drawn green at its chosen poses; a fallback orange at its settled
    poses, the corrected estimate. J is the object's jitter J_i. The fixed
    bodies come with every map, since RViz keeps only the last latched MarkerArray. An object not in
    ``present`` (scene indices; None: every object is), one the map leaves out, gets DELETE markers
    for its shape and label, so RViz drops it once it left. Empty if nothing was chosen. Headers are
    stamped ``stamp_ns`` (integer nanoseconds).
    """
    if result.poses is None or result.settled_poses is None or result.object_jitters is None:
        return MarkerArray()
    poses = result.settled_poses if result.fallback_used else result.poses
    header = Header(frame_id=scene.frame_id, stamp=stamp_from_nanoseconds(stamp_ns))
    jitters = result.object_jitters
    kept = set(range(len(poses)) if present is None else present)
    markers = []
    for index, (model, pose) in enumerate(zip(scene.objects, poses, strict=True)):
        if index not in kept:
            markers += [
                Marker(header=header, ns=namespace, id=index, action=Marker.DELETE)
                for namespace in (SHAPE_NAMESPACE, LABEL_NAMESPACE)
            ]
            continue
        shape = Marker(header=header, ns=SHAPE_NAMESPACE, id=index, action=Marker.ADD, pose=pose_msg(pose))
        _shape(shape, model.shape)
        shape.color = VALID_COLOR if result.valid else FALLBACK_COLOR
        label_height = pose.position[2] + _top(model.shape) + LABEL_HEIGHT
        label_pose = pose_msg(Pose((pose.position[0], pose.position[1], label_height)))
        label = Marker(header=header, ns=LABEL_NAMESPACE, id=index, action=Marker.ADD, pose=label_pose)
        label.type = Marker.TEXT_VIEW_FACING
        label.scale = Vector3(z=LABEL_HEIGHT)
        label.color = LABEL_COLOR
        label.text = f"{model.name}\nJ={jitters[index]:.4f}"
        markers += [shape, label]
    return MarkerArray(markers=markers + static_markers(scene, header))

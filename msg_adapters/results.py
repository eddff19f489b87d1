"""Search results -> map messages: chosen and settled PoseArrays, and RViz markers."""

from __future__ import annotations

from geometry_msgs.msg import PoseArray, Vector3
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from msg_adapters.hypotheses import pose_array_msg, pose_msg, stamp_from_nanoseconds
from physics_mapper.core.geometry import Pose
from physics_mapper.core.scene import Box, Cylinder, ObjectModel, Scene, Sphere
from physics_mapper.core.search import SearchResult

#: Marker namespaces: one shape and one label per object, ``id`` = object index.
SHAPE_NAMESPACE = "objects"
LABEL_NAMESPACE = "labels"
LABEL_HEIGHT = 0.04  # metres, height of an upper-case letter in RViz
VALID_COLOR = ColorRGBA(r=0.2, g=0.7, b=0.3, a=0.8)
FALLBACK_COLOR = ColorRGBA(r=0.95, g=0.6, b=0.1, a=0.8)
LABEL_COLOR = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)


def configuration_msgs(result: SearchResult, *, frame_id: str, stamp_ns: int) -> tuple[PoseArray, PoseArray] | None:
    """The chosen poses and their settled poses, in scene object order; None if nothing was chosen.

    ``stamp_ns``: the header stamp, integer nanoseconds (the newest input stamp used).
    """
    if result.poses is None or result.settled_poses is None:
        return None
    return (
        pose_array_msg(result.poses, frame_id=frame_id, stamp_ns=stamp_ns),
        pose_array_msg(result.settled_poses, frame_id=frame_id, stamp_ns=stamp_ns),
    )


def _shape(marker: Marker, model: ObjectModel) -> None:
    """Set the marker type and scale (full extents, metres) to the object's true shape."""
    shape = model.shape
    if isinstance(shape, Box):
        marker.type = Marker.CUBE
        marker.scale = Vector3(x=shape.size[0], y=shape.size[1], z=shape.size[2])
    elif isinstance(shape, Sphere):
        marker.type = Marker.SPHERE
        diameter = 2.0 * shape.radius
        marker.scale = Vector3(x=diameter, y=diameter, z=diameter)
    else:
        assert isinstance(shape, Cylinder)
        marker.type = Marker.CYLINDER  # RViz's cylinder is along local z, like pybullet's
        diameter = 2.0 * shape.radius
        marker.scale = Vector3(x=diameter, y=diameter, z=shape.length)


def _top(model: ObjectModel) -> float:
    """Half height of the object's bounding box (metres), to put its label above it."""
    shape = model.shape
    if isinstance(shape, Box):
        return shape.size[2] / 2.0
    if isinstance(shape, Sphere):
        return shape.radius
    return max(shape.length / 2.0, shape.radius)


def markers_msg(result: SearchResult, scene: Scene, *, stamp_ns: int) -> MarkerArray:
    """One marker per object in its true shape, plus a text label ``name J=...``.

    A valid configuration is drawn green at its chosen poses; a fallback orange at its settled
    poses, the corrected estimate (SPEC section 2). J is the object's jitter J_i. Empty if
    nothing was chosen. Headers are stamped ``stamp_ns`` (integer nanoseconds).
    """
    if result.poses is None or result.settled_poses is None or result.object_jitters is None:
        return MarkerArray()
    poses = result.settled_poses if result.fallback_used else result.poses
    header = Header(frame_id=scene.frame_id, stamp=stamp_from_nanoseconds(stamp_ns))
    jitters = result.object_jitters
    markers = []
    for index, (model, pose) in enumerate(zip(scene.objects, poses, strict=True)):
        shape = Marker(header=header, ns=SHAPE_NAMESPACE, id=index, action=Marker.ADD, pose=pose_msg(pose))
        _shape(shape, model)
        shape.color = VALID_COLOR if result.valid else FALLBACK_COLOR
        label_pose = pose_msg(Pose((pose.position[0], pose.position[1], pose.position[2] + _top(model) + LABEL_HEIGHT)))
        label = Marker(header=header, ns=LABEL_NAMESPACE, id=index, action=Marker.ADD, pose=label_pose)
        label.type = Marker.TEXT_VIEW_FACING
        label.scale = Vector3(z=LABEL_HEIGHT)
        label.color = LABEL_COLOR
        label.text = f"{model.name}\nJ={jitters[index]:.4f}"
        markers += [shape, label]
    return MarkerArray(markers=markers)

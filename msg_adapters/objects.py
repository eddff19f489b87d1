"""The map as ``vision_msgs/Detection3DArray`` (``~/objects``): one Detection3D per object present.

Imported only where vision_msgs is installed (the node checks first). Each Detection3D holds:

* ``id``: the object's name (an instance's name, ``box_3``), stable from tick to tick;
* one result: ``class_id`` the object's class (:meth:`~physics_mapper.model.scene.Scene.class_of`:
  the ``count:`` entry's name, the ``class_map`` id, or the object's name), ``score`` the chosen
  hypothesis's normalised weight (its share of p(C), the *absent* hypothesis included in the
  normalisation), and the object's map pose with a zero covariance: the pose the node's ``tf_pose``
  selects (``~/objects`` and ``/tf`` agree), its settled pose or its chosen hypothesis. The
  two differ by less than ``jitter_threshold`` in a valid map; in a fallback's map the settled pose is the
  corrected estimate (``fallback: refine``'s refined map) and the chosen one the hypothesis it started from;
* ``bbox``: the box of the shape in its own frame at that pose (a box's size, a sphere's or a
  cylinder's extents, a mesh's bounds, centred where they are in the mesh's frame).

Objects the map leaves out (*absent*) are not listed. The header carries the map's frame and stamp.
"""

from __future__ import annotations

from collections.abc import Sequence

from geometry_msgs.msg import PoseWithCovariance, Vector3
from std_msgs.msg import Header
from vision_msgs.msg import BoundingBox3D, Detection3D, Detection3DArray, ObjectHypothesis, ObjectHypothesisWithPose

from physics_mapper.mapping.mapper import TickReport
from physics_mapper.model.geometry import Pose, compose_poses
from physics_mapper.model.geometry import Vector3 as Point3
from physics_mapper.model.scene import Box, Cylinder, Mesh, ObjectShape, Scene, Sphere
from physics_mapper.msg_adapters.hypotheses import pose_msg, stamp_from_nanoseconds


def shape_box(shape: ObjectShape) -> tuple[Point3, Point3]:
    """The centre (in the body's frame) and full size, metres, of the shape's box in its own frame."""
    if isinstance(shape, Box):
        return (0.0, 0.0, 0.0), shape.size
    if isinstance(shape, Sphere):
        side = 2.0 * shape.radius
        return (0.0, 0.0, 0.0), (side, side, side)
    if isinstance(shape, Cylinder):
        side = 2.0 * shape.radius
        return (0.0, 0.0, 0.0), (side, side, shape.length)
    assert isinstance(shape, Mesh)
    low, high = shape.geometry.bounds
    centre = tuple(float(a + b) / 2.0 for a, b in zip(low, high, strict=True))
    size = tuple(float(b - a) for a, b in zip(low, high, strict=True))
    return (centre[0], centre[1], centre[2]), (size[0], size[1], size[2])


def objects_msg(
    report: TickReport, scene: Scene, poses: Sequence[Pose] | None, *, stamp_ns: int
) -> Detection3DArray | None:
    """The map of ``report`` as a Detection3DArray, its objects at ``poses`` (scene order: the settled poses
    or the chosen hypotheses, module docstring); None if nothing was chosen."""
    result = report.result
    if result is None or result.code is None or poses is None:
        return None
    header = Header(frame_id=scene.frame_id, stamp=stamp_from_nanoseconds(stamp_ns))
    detections = []
    for index in report.present:
        model, pose = scene.objects[index], poses[index]
        score = report.hypotheses[index].weight(result.code[index])
        centre, size = shape_box(model.shape)
        box = BoundingBox3D(
            center=pose_msg(compose_poses(pose, Pose(centre))), size=Vector3(x=size[0], y=size[1], z=size[2])
        )
        hypothesis = ObjectHypothesisWithPose(
            hypothesis=ObjectHypothesis(class_id=scene.class_of(model.name), score=score),
            pose=PoseWithCovariance(pose=pose_msg(pose)),
        )
        detections.append(Detection3D(header=header, results=[hypothesis], bbox=box, id=model.name))
    return Detection3DArray(header=header, detections=detections)

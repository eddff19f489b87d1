"""Transforms <-> core types: ``/tf`` and ``/tf_static`` in, each object's map pose on ``/tf`` out.

``tf2_msgs/TFMessage`` holds ``geometry_msgs/TransformStamped``: ``header.frame_id`` the parent,
``child_frame_id`` the child, ``transform`` the child's pose in the parent. Incoming messages are
read by attribute (:func:`stamped_transforms`), so this module needs only geometry_msgs; the node
wraps :func:`object_transforms` in a ``TFMessage`` where tf2_msgs is installed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
from std_msgs.msg import Header

from physics_mapper.mapping.frames import StampedTransform
from physics_mapper.mapping.stamps import to_nanoseconds
from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import FixedFrame
from physics_mapper.msg_adapters.hypotheses import stamp_from_nanoseconds


def stamped_transforms(message: Any) -> list[StampedTransform]:
    """The transforms of a ``tf2_msgs/TFMessage`` (rclpy's or a bag's), unchecked."""
    found = []
    for stamped in message.transforms:
        t, q = stamped.transform.translation, stamped.transform.rotation
        stamp = stamped.header.stamp
        found.append(
            StampedTransform(
                str(stamped.header.frame_id),
                str(stamped.child_frame_id),
                to_nanoseconds(stamp.sec, stamp.nanosec),
                (float(t.x), float(t.y), float(t.z)),
                (float(q.x), float(q.y), float(q.z), float(q.w)),
            )
        )
    return found


def fixed_frame_transform(frame: FixedFrame) -> StampedTransform:
    """A scene file's fixed frame as the static transform ``parent -> name`` it stands for."""
    return StampedTransform(frame.parent, frame.name, 0, frame.pose.position, frame.pose.orientation)


def object_transforms(
    poses: Sequence[Pose], names: Sequence[str], *, frame_id: str, prefix: str, stamp_ns: int
) -> list[TransformStamped]:
    """One ``TransformStamped`` per object: ``frame_id -> prefix + name`` at its pose, stamped ``stamp_ns``."""
    header = Header(frame_id=frame_id, stamp=stamp_from_nanoseconds(stamp_ns))
    transforms = []
    for name, pose in zip(names, poses, strict=True):
        (x, y, z), (qx, qy, qz, qw) = pose.position, pose.orientation
        transform = Transform(translation=Vector3(x=x, y=y, z=z), rotation=Quaternion(x=qx, y=qy, z=qz, w=qw))
        transforms.append(TransformStamped(header=header, child_frame_id=prefix + name, transform=transform))
    return transforms

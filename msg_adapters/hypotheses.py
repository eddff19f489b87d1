"""Hypothesis messages <-> core types: PoseArray and Float64MultiArray weights.

Incoming messages become :class:`~physics_mapper.mapping.inputs.ReceivedPoses` and
:class:`~physics_mapper.mapping.inputs.ReceivedWeights`, validated by the core (every problem
collected, none raised); the node receives PoseArrays serialised (:func:`received_pose_array`,
see :mod:`physics_mapper.msg_adapters.pose_array_cdr`); outgoing hypotheses become the same two message types. Header
stamps are integer nanoseconds (``stamp_ns``), exact both ways: a float of seconds since the
epoch resolves only about 0.2 microseconds, and outputs carry their input's stamp.
"""

from __future__ import annotations

from collections.abc import Sequence

from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import Point, PoseArray, Quaternion
from geometry_msgs.msg import Pose as PoseMsg
from rclpy.serialization import deserialize_message
from rclpy.time import Time
from std_msgs.msg import Float64MultiArray, Header

from physics_mapper.mapping.inputs import RawPose, ReceivedPoses, ReceivedWeights, check_poses, check_weights
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import RankedHypotheses
from physics_mapper.model.scene import Workspace
from physics_mapper.msg_adapters.pose_array_cdr import pose_array_view


def nanoseconds_from_stamp(stamp: TimeMsg) -> int:
    """A ``builtin_interfaces/Time`` as integer nanoseconds (rclpy's :class:`~rclpy.time.Time`)."""
    return int(Time.from_msg(stamp).nanoseconds)


def stamp_from_nanoseconds(stamp_ns: int) -> TimeMsg:
    """Integer nanoseconds as a ``builtin_interfaces/Time`` (rclpy's :class:`~rclpy.time.Time`)."""
    return Time(nanoseconds=stamp_ns).to_msg()


def raw_pose(msg: PoseMsg) -> RawPose:
    """Position (m) and orientation quaternion (x, y, z, w) of a pose message, unchecked."""
    p, q = msg.position, msg.orientation
    return (p.x, p.y, p.z), (q.x, q.y, q.z, q.w)


def received_poses(msg: PoseArray, *, expected_frame: str, workspace: Workspace, received: float) -> ReceivedPoses:
    """A PoseArray received at ``received`` seconds, checked against the scene's frame and workspace."""
    return check_poses(
        [raw_pose(pose) for pose in msg.poses],
        frame_id=msg.header.frame_id,
        expected_frame=expected_frame,
        workspace=workspace,
        stamp_ns=nanoseconds_from_stamp(msg.header.stamp),
        received=received,
    )


def received_pose_array(raw: bytes, *, expected_frame: str, workspace: Workspace, received: float) -> ReceivedPoses:
    """A serialised PoseArray (a raw subscription's message) received at ``received`` seconds.

    Read without building a Python object per pose; encodings other than plain CDR go through rclpy.
    """
    view = pose_array_view(raw)
    if view is None:
        message = deserialize_message(raw, PoseArray)
        return received_poses(message, expected_frame=expected_frame, workspace=workspace, received=received)
    return check_poses(
        view.poses,
        frame_id=view.frame_id,
        expected_frame=expected_frame,
        workspace=workspace,
        stamp_ns=view.stamp_ns,
        received=received,
    )


def received_weights(msg: Float64MultiArray, *, received: float) -> ReceivedWeights:
    """A weights message received at ``received`` seconds (``layout`` is ignored: one flat vector)."""
    return check_weights(msg.data, received=received)


def pose_msg(pose: Pose) -> PoseMsg:
    """A core pose as ``geometry_msgs/Pose``."""
    (x, y, z), (qx, qy, qz, qw) = pose.position, pose.orientation
    return PoseMsg(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def pose_array_msg(poses: Sequence[Pose], *, frame_id: str, stamp_ns: int) -> PoseArray:
    """Poses, in order, as one PoseArray in ``frame_id`` stamped ``stamp_ns`` nanoseconds."""
    header = Header(frame_id=frame_id, stamp=stamp_from_nanoseconds(stamp_ns))
    return PoseArray(header=header, poses=[pose_msg(p) for p in poses])


def weights_msg(weights: Sequence[float]) -> Float64MultiArray:
    """Weights, in pose order, as a flat Float64MultiArray."""
    return Float64MultiArray(data=[float(w) for w in weights])


def hypotheses_msgs(
    hypotheses: RankedHypotheses, *, frame_id: str, stamp_ns: int
) -> tuple[PoseArray, Float64MultiArray]:
    """An object's hypotheses as the two messages the node reads: poses in rank order, and their weights."""
    poses = pose_array_msg([h.pose for h in hypotheses.hypotheses], frame_id=frame_id, stamp_ns=stamp_ns)
    return poses, weights_msg([h.weight for h in hypotheses.hypotheses])

"""A serialised ``geometry_msgs/PoseArray`` read without a Python object per pose.

rclpy turns every pose of a PoseArray into three Python objects: for 9,000 poses that is about
80 ms, before the node has looked at any of them (BENCHMARKS.md, "Adopting large arrays"). The
node subscribes to the raw bytes instead and reads them here: the header, then every pose as
one row of a numpy array that views the message's bytes, of which it converts only those it keeps.

Layout (OMG CDR version 1, which rmw_fastrtps and rmw_cyclonedds write for ROS 2 messages): a
4-byte encapsulation header (representation identifier ``00 00`` big-endian or ``00 01``
little-endian, then two option bytes); then, aligned relative to the end of that header,
``int32 sec``, ``uint32 nanosec``, the ``frame_id`` as a ``uint32`` length counting its NUL and
its bytes, a 4-aligned ``uint32`` number of poses, and per pose seven 8-aligned ``float64``:
position x, y, z and orientation x, y, z, w. Another encapsulation, or lengths that overrun the
bytes, are left to rclpy's own deserialiser (:func:`physics_mapper.msg_adapters.hypotheses.received_pose_array`).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from physics_mapper.mapping.stamps import to_nanoseconds

ENCAPSULATION_BYTES = 4
#: Representation identifiers of plain CDR (version 1), and the byte order each stands for.
BYTE_ORDERS = {b"\x00\x00": ">", b"\x00\x01": "<"}
POSE_FLOATS = 7


@dataclass(frozen=True)
class PoseArrayView:
    """A PoseArray's header and its poses as an (M, 7) float array (x, y, z, qx, qy, qz, qw per row)."""

    stamp_ns: int
    frame_id: str
    poses: NDArray[np.float64]


def aligned(offset: int, size: int) -> int:
    """``offset`` rounded up to a multiple of ``size``: where CDR puts a value of ``size`` bytes."""
    return offset + (-offset % size)


def cdr_text(value: bytes) -> str:
    """A CDR string's bytes as text: its terminating NUL dropped (a last byte that is no NUL is kept, as
    rclpy keeps it), invalid UTF-8 replaced."""
    return value.removesuffix(b"\0").decode("utf-8", errors="replace")


def pose_array_view(raw: bytes) -> PoseArrayView | None:
    """A serialised PoseArray in plain CDR (either byte order), viewed; None for anything else or overrun lengths."""
    order = BYTE_ORDERS.get(bytes(raw[:2]))
    if order is None:
        return None
    body = memoryview(raw)[ENCAPSULATION_BYTES:]
    try:
        sec, nanosec, text_length = struct.unpack_from(f"{order}iII", body, 0)
        text_end = 12 + text_length
        frame_id = cdr_text(bytes(body[12:text_end]))
        count_at = aligned(text_end, 4)
        (count,) = struct.unpack_from(f"{order}I", body, count_at)
        poses_at = aligned(count_at + 4, 8)
        if count and poses_at + count * POSE_FLOATS * 8 > len(body):  # an empty array ends before the padding
            return None
        poses = np.frombuffer(body, dtype=f"{order}f8", count=count * POSE_FLOATS, offset=min(poses_at, len(body)))
    except struct.error:
        return None
    return PoseArrayView(to_nanoseconds(sec, nanosec), frame_id, poses.reshape(count, POSE_FLOATS))

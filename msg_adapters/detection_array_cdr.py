"""A serialised ``vision_msgs/Detection3DArray`` read without a Python object per result.

rclpy turns every result of a Detection3DArray into a tree of Python objects (hypothesis, pose,
position, orientation, a numpy array for the covariance), and reading them back by attribute
costs more again: for 100,000 results, seconds before the rules of detections have looked at any
(BENCHMARKS.md, "Detection arrays and association"). The node subscribes to the raw bytes instead
and reads them here into :class:`~physics_mapper.mapping.detection_data.DetectionArrayData`, the
arrays the rules read whichever reader made them.

Layout (OMG CDR version 1, as :mod:`~physics_mapper.msg_adapters.pose_array_cdr` describes its
encapsulation and alignment; vision_msgs 4): the array's header (``int32 sec``, ``uint32 nanosec``,
``string frame_id``: a ``uint32`` length counting its NUL, then its bytes), a ``uint32`` number of
detections, and per detection its header, a ``uint32`` number of results, the results, the
``BoundingBox3D`` (ten 8-aligned ``float64``: centre pose and size) and ``string id``. A result is
``string class_id``, then 8-aligned ``float64`` score, pose (x, y, z, qx, qy, qz, qw) and 36
covariance values: :data:`RESULT_BYTES` bytes after its class id.

Results whose class ids are all of one length (the usual case: one class per detection) lie at a
fixed stride from the second on, whose 8-aligned start the first result's end fixes: they are
viewed as strided numpy arrays, and the stride is verified by reading every result's length field
at its predicted place. Class ids of several lengths are walked one result at a time (a loop
reading a length and a string per result, the numbers still gathered in one numpy call).
Another encapsulation, lengths that overrun the bytes, or more than :data:`MAX_PADDING` bytes
left after the message are no view (None): :func:`received_detection_array` leaves those to
rclpy's deserialiser, and bytes that it cannot read either are refused with its reason. So are all
arrays where the installed vision_msgs lays its types out otherwise (:func:`reads_layout_of`).
"""

from __future__ import annotations

import importlib
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rclpy.serialization import deserialize_message

from physics_mapper.mapping.detection_data import (
    DetectionArrayData,
    DetectionData,
    detection_array_data,
    distinct_classes,
    given_covariances,
)
from physics_mapper.mapping.inputs import POSE_COLUMNS
from physics_mapper.mapping.stamps import to_nanoseconds
from physics_mapper.msg_adapters.pose_array_cdr import BYTE_ORDERS, ENCAPSULATION_BYTES, aligned, cdr_text

FLOAT_BYTES = 8
#: A result's float64 after its class id: score, pose (7), covariance (36).
RESULT_FLOATS = 1 + POSE_COLUMNS + 36
RESULT_BYTES = RESULT_FLOATS * FLOAT_BYTES
#: A BoundingBox3D: centre pose (7 float64) and size (3 float64).
BOX_BYTES = 10 * FLOAT_BYTES
#: Fewest bytes a result and a detection take: what a count of them must leave room for.
MIN_RESULT_BYTES = 4 + RESULT_BYTES
MIN_DETECTION_BYTES = 8 + 4 + 4 + BOX_BYTES + 4
#: Bytes a serialiser may leave after the message (padding to a multiple of 4).
MAX_PADDING = 3
#: The fields of the vision_msgs types read here, as rclpy's messages list them (vision_msgs 3 and 4).
LAYOUT = {
    "Detection3DArray": {"header": "std_msgs/Header", "detections": "sequence<vision_msgs/Detection3D>"},
    "Detection3D": {
        "header": "std_msgs/Header",
        "results": "sequence<vision_msgs/ObjectHypothesisWithPose>",
        "bbox": "vision_msgs/BoundingBox3D",
        "id": "string",
    },
    "ObjectHypothesisWithPose": {
        "hypothesis": "vision_msgs/ObjectHypothesis",
        "pose": "geometry_msgs/PoseWithCovariance",
    },
    "ObjectHypothesis": {"class_id": "string", "score": "double"},
    "BoundingBox3D": {"center": "geometry_msgs/Pose", "size": "geometry_msgs/Vector3"},
}


class _Overrun(Exception):
    """The bytes end before the message the lengths in them describe."""


@dataclass
class _Cursor:
    """Reads the message body (the bytes after the encapsulation header) in byte order ``order``."""

    body: memoryview
    order: str
    at: int = 0

    def skip(self, size: int) -> int:
        """Advance ``size`` bytes; where they start."""
        start, self.at = self.at, self.at + size
        if self.at > len(self.body):
            raise _Overrun
        return start

    def uint32(self) -> int:
        self.at = aligned(self.at, 4)
        return int(struct.unpack_from(f"{self.order}I", self.body, self.skip(4))[0])

    def count(self, min_bytes: int) -> int:
        """A sequence's length, each element taking at least ``min_bytes``."""
        count = self.uint32()
        if count * min_bytes > len(self.body) - self.at:
            raise _Overrun
        return count

    def text(self) -> str:
        """A string (its length counts its NUL)."""
        length = self.uint32()
        start = self.skip(length)
        return cdr_text(bytes(self.body[start : self.at]))

    def array(self, dtype: str, shape: tuple[int, ...], strides: tuple[int, ...]) -> NDArray[Any]:
        """A read-only numpy view of the body at the cursor (bounds checked by the caller's :meth:`skip`)."""
        return np.ndarray(shape, np.dtype(dtype), buffer=self.body, offset=self.at, strides=strides)


def reads_layout_of(message_type: type) -> bool:
    """Whether the message package of ``message_type`` (the installed ``vision_msgs.msg``) lays out a
    Detection3DArray's types as :data:`LAYOUT` says, the layout :func:`detection_array_view` reads."""
    package = importlib.import_module(message_type.__module__.rpartition(".")[0])
    types = {name: getattr(package, name, None) for name in LAYOUT}
    return all(t is not None and t.get_fields_and_field_types() == LAYOUT[name] for name, t in types.items())


def received_detection_array(raw: bytes, message_type: type, *, viewable: bool = True) -> DetectionArrayData | str:
    """A serialised Detection3DArray (a raw subscription's message) read: viewed (:func:`detection_array_view`)
    if ``viewable`` (:func:`reads_layout_of` ``message_type``), else or failing that deserialised by rclpy
    as ``message_type`` (vision_msgs' ``Detection3DArray``) and read by attribute; or why neither could."""
    view = detection_array_view(raw) if viewable else None
    if view is not None:
        return view
    try:
        message = deserialize_message(raw, message_type)
    except RuntimeError as error:  # rclpy's RMWError: bytes the middleware's deserialiser refuses
        return f"{len(raw)} bytes that are no Detection3DArray ({error})"
    return detection_array_data(message)


def detection_array_view(raw: bytes) -> DetectionArrayData | None:
    """A serialised Detection3DArray in plain CDR (either byte order), read; None for anything else."""
    order = BYTE_ORDERS.get(bytes(raw[:2]))
    if order is None:
        return None
    cursor = _Cursor(memoryview(raw)[ENCAPSULATION_BYTES:], order)
    try:
        sec, nanosec = _stamp(cursor)
        frame_id = cursor.text()
        detections = tuple(_detection(cursor) for _ in range(cursor.count(MIN_DETECTION_BYTES)))
    except (struct.error, _Overrun):
        return None
    if len(cursor.body) - cursor.at > MAX_PADDING:
        return None
    return DetectionArrayData(to_nanoseconds(sec, nanosec), frame_id, detections)


def _stamp(cursor: _Cursor) -> tuple[int, int]:
    cursor.at = aligned(cursor.at, 4)
    sec, nanosec = struct.unpack_from(f"{cursor.order}iI", cursor.body, cursor.skip(8))
    return int(sec), int(nanosec)


def _detection(cursor: _Cursor) -> DetectionData:
    _stamp(cursor)  # a detection's own stamp: the rules take the array's
    frame_id = cursor.text()
    count = cursor.count(MIN_RESULT_BYTES)
    parts = [_walked(cursor, min(count, 1))]
    if count > 1:  # the first result's end fixes the 8-aligned start of the others
        parts.append(_strided(cursor, count - 1) or _walked(cursor, count - 1))
    cursor.at = aligned(cursor.at, FLOAT_BYTES)
    cursor.skip(BOX_BYTES)
    key = cursor.text()
    names, classes, numbers, covariances = _joined(parts)
    class_ids, renamed = distinct_classes(names)
    return DetectionData(
        frame_id, key, class_ids, renamed[classes], numbers[:, 0], numbers[:, 1 : 1 + POSE_COLUMNS], covariances
    )


#: Results as read: class ids, each result's index among them, and its (score, pose, covariance) rows.
_Results = tuple[list[str], NDArray[np.intp], NDArray[np.float64]]


def _walked(cursor: _Cursor, count: int) -> _Results:
    """``count`` results read one at a time, their numbers gathered at once."""
    names: list[str] = []
    starts = np.empty(count, dtype=np.intp)
    for position in range(count):
        names.append(cursor.text())
        cursor.at = aligned(cursor.at, FLOAT_BYTES)
        starts[position] = cursor.skip(RESULT_BYTES)
    words = np.ndarray((len(cursor.body) // FLOAT_BYTES,), np.dtype(f"{cursor.order}f8"), buffer=cursor.body)
    rows = words[starts[:, None] // FLOAT_BYTES + np.arange(RESULT_FLOATS)]
    return names, np.arange(count, dtype=np.intp), rows


def _strided(cursor: _Cursor, count: int) -> _Results | None:
    """``count`` results starting 8-aligned at the cursor, viewed at a fixed stride if all their class
    ids have the first one's length (every length field read where the stride puts it); else None."""
    start = cursor.at
    (length,) = struct.unpack_from(f"{cursor.order}I", cursor.body, start)
    text_bytes = aligned(4 + length, FLOAT_BYTES)
    stride = text_bytes + RESULT_BYTES
    if start + count * stride > len(cursor.body):
        return None
    lengths = cursor.array(f"{cursor.order}u4", (count,), (stride,))
    if not bool((lengths == length).all()):
        return None
    cursor.at = start + 4
    texts = cursor.array("u1", (count, length), (stride, 1))
    cursor.at = start + text_bytes
    rows = cursor.array(f"{cursor.order}f8", (count, RESULT_FLOATS), (stride, FLOAT_BYTES))
    cursor.at = start + count * stride
    names, classes = _text_classes(texts)
    return names, classes, rows


def _joined(
    parts: list[_Results],
) -> tuple[list[str], NDArray[np.intp], NDArray[np.float64], NDArray[np.float64] | None]:
    """Results read in parts as one: class ids in order and each result's index among them; scores and
    poses (M, 8) copied into native floats; covariances (M, 6, 6) copied too, unless all are zero (None)."""
    names: list[str] = []
    classes = []
    for part_names, part_classes, _ in parts:
        classes.append(part_classes + len(names))
        names += part_names
    numbers = np.concatenate([rows[:, : 1 + POSE_COLUMNS] for _, _, rows in parts], dtype=np.float64)
    covariances = [rows[:, 1 + POSE_COLUMNS :] for _, _, rows in parts]
    # All bits zero is the estimator's "no covariance" (0.0 has no bit set): tested without reading floats.
    if not any(block.view(np.uint64).any() for block in covariances):
        return names, np.concatenate(classes), numbers, None
    return (
        names,
        np.concatenate(classes),
        numbers,
        given_covariances(np.concatenate(covariances, dtype=np.float64).reshape(-1, 6, 6)),
    )


def _text_classes(texts: NDArray[np.generic]) -> tuple[list[str], NDArray[np.intp]]:
    """Rows of equally long class id bytes as their distinct strings and each row's index among them."""
    if bool((texts == texts[0]).all()):
        return [cdr_text(bytes(texts[0]))], np.zeros(len(texts), dtype=np.intp)
    packed = np.ascontiguousarray(texts).view(np.dtype((np.void, texts.shape[1]))).ravel()
    distinct, classes = np.unique(packed, return_inverse=True)
    return [cdr_text(bytes(value)) for value in distinct], classes.astype(np.intp).ravel()

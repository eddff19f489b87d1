"""The serialised Detection3DArray reader against rclpy's own deserialiser, on messages rclpy serialises.

vision_msgs has no PyPI wheel: ``make test`` builds it into the venv (``test/vision_msgs/``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import Point, Pose, PoseWithCovariance, Quaternion
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header
from vision_msgs.msg import Detection3D, Detection3DArray, ObjectHypothesis, ObjectHypothesisWithPose

from physics_mapper.bags.storage import TYPESTORE
from physics_mapper.mapping.detection_data import DetectionArrayData, detection_array_data
from physics_mapper.mapping.detections import DETECTION_ARRAY, detection_inputs
from physics_mapper.model.scene_files import scene_from_dict
from physics_mapper.msg_adapters.detection_array_cdr import (
    MAX_PADDING,
    detection_array_view,
    reads_layout_of,
    received_detection_array,
)
from physics_mapper.msg_adapters.hypotheses import stamp_from_nanoseconds

RNG = np.random.default_rng(34)


def result(class_id: str, score: float, pose: Sequence[float] | None = None, covariance: bool = False) -> Any:
    x, y, z, qx, qy, qz, qw = RNG.normal(0.0, 1.0, 7).tolist() if pose is None else pose
    values = RNG.normal(0.0, 1.0, 36) if covariance else np.zeros(36)
    return ObjectHypothesisWithPose(
        hypothesis=ObjectHypothesis(class_id=class_id, score=score),
        pose=PoseWithCovariance(
            pose=Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw)),
            covariance=values,
        ),
    )


def detection(*results: ObjectHypothesisWithPose, key: str = "", frame_id: str = "") -> Detection3D:
    return Detection3D(header=Header(frame_id=frame_id), results=list(results), id=key)


def array(*detections: Detection3D, frame_id: str = "world", stamp_ns: int = 5_000_000_007) -> Detection3DArray:
    header = Header(frame_id=frame_id, stamp=stamp_from_nanoseconds(stamp_ns))
    return Detection3DArray(header=header, detections=list(detections))


NAN_POSE = (math.nan, 0.0, 0.1, 0.0, 0.0, 0.0, math.nan)
#: Messages as estimators send them, and as they should not.
MESSAGES = {
    "empty array": array(),
    "no frame": array(detection(result("box", 0.5)), frame_id=""),
    "empty detections and ids": array(detection(), detection(result("box", 0.9)), detection(key="")),
    "one class, many results": array(
        detection(*[result("mug", float(s), covariance=True) for s in RNG.random(50)], key="7", frame_id="camera"),
        detection(*[result("bowl", float(s)) for s in RNG.random(9)], key="a long key éé"),
    ),
    "class ids of several lengths in one detection": array(
        detection(result("a", 0.1), result("bb", 0.2), result("a", 0.3), result("cccc", 0.4), result("", 0.5))
    ),
    "first class id of another length": array(detection(result("a", 0.2), *[result("bb", 0.1)] * 6)),
    "several class ids of one length": array(detection(*[result(c, 0.5) for c in ("ab", "cd", "ab", "ef", "cd")])),
    "empty class ids": array(detection(result("", 0.5), result("", 0.6), result("", 0.7))),
    "non-finite numbers": array(
        detection(result("box", math.nan, NAN_POSE), result("box", math.inf), result("box", -1.0, NAN_POSE))
    ),
}


def read_by_rclpy(raw: bytes) -> DetectionArrayData:
    return detection_array_data(deserialize_message(raw, Detection3DArray))


def assert_same(read: DetectionArrayData, expected: DetectionArrayData) -> None:
    """The same header, and per detection the same frame, id, and per result class id and numbers."""
    assert (read.stamp_ns, read.frame_id) == (expected.stamp_ns, expected.frame_id)
    assert len(read.detections) == len(expected.detections)
    for mine, theirs in zip(read.detections, expected.detections, strict=True):
        assert (mine.frame_id, mine.key) == (theirs.frame_id, theirs.key)
        assert len(set(mine.class_ids)) == len(mine.class_ids)
        assert [mine.class_ids[c] for c in mine.result_classes] == [theirs.class_ids[c] for c in theirs.result_classes]
        np.testing.assert_array_equal(mine.scores, theirs.scores)
        np.testing.assert_array_equal(mine.poses, theirs.poses)
        np.testing.assert_array_equal(mine.covariances, theirs.covariances)


def big_endian(raw: bytes) -> bytes:
    """The same Detection3DArray serialised big-endian (rosbags; rclpy writes the machine's order)."""
    message = TYPESTORE.deserialize_cdr(raw, DETECTION_ARRAY)
    return bytes(TYPESTORE.serialize_cdr(message, DETECTION_ARRAY, little_endian=False))


@pytest.mark.parametrize("name", list(MESSAGES))
def test_the_view_reads_what_rclpy_deserialises(name: str) -> None:
    raw = serialize_message(MESSAGES[name])
    view = detection_array_view(raw)
    assert view is not None
    assert_same(view, read_by_rclpy(raw))
    swapped = big_endian(raw)
    assert swapped[:2] == b"\x00\x00" and swapped != raw
    big = detection_array_view(swapped)
    assert big is not None
    assert_same(big, read_by_rclpy(raw))


def test_a_thousand_results_of_one_class_are_read_at_a_stride_with_their_numbers() -> None:
    poses = RNG.normal(0.0, 1.0, (1000, 7))
    scores = RNG.random(1000)
    message = array(detection(*[result("box_12", float(s), p.tolist()) for s, p in zip(scores, poses, strict=True)]))
    view = detection_array_view(serialize_message(message))
    assert view is not None
    (read,) = view.detections
    assert read.class_ids == ("box_12",) and not read.result_classes.any()
    np.testing.assert_array_equal(read.poses, poses)
    np.testing.assert_array_equal(read.scores, scores)


def test_one_class_id_of_another_length_among_many_is_still_read_right() -> None:
    """The stride check finds the odd length field and reads those results one at a time."""
    results = [result("bb", 0.1)] * 20 + [result("ccc", 0.9)] + [result("bb", 0.2)] * 20
    raw = serialize_message(array(detection(*results)))
    view = detection_array_view(raw)
    assert view is not None
    assert_same(view, read_by_rclpy(raw))


def test_every_truncation_is_no_view_and_left_to_rclpy_which_refuses_or_reads_it() -> None:
    """rclpy's deserialiser refuses most cuts and reads some (a sequence cut short as empty): the node gets
    what a typed subscription would, and never an exception."""
    raw = serialize_message(MESSAGES["class ids of several lengths in one detection"])
    refused = []
    for length in range(len(raw)):
        assert detection_array_view(raw[:length]) is None
        read = received_detection_array(raw[:length], Detection3DArray)
        assert isinstance(read, str | DetectionArrayData)
        if isinstance(read, str):
            assert read.startswith(f"{length} bytes that are no Detection3DArray (")
            refused.append(length)
    assert refused[:4] == [0, 1, 2, 3] and len(refused) > len(raw) // 2


def test_lengths_that_overrun_the_bytes_are_no_view() -> None:
    raw = bytearray(serialize_message(MESSAGES["one class, many results"]))
    key_at = len(raw) - len("a long key éé".encode()) - 1 - 4  # the last detection's id: its length field
    assert raw[key_at : key_at + 4] == (16).to_bytes(4, "little")
    raw[key_at : key_at + 4] = (2**31).to_bytes(4, "little")  # claims 2 GB
    assert detection_array_view(bytes(raw)) is None
    assert isinstance(received_detection_array(bytes(raw), Detection3DArray), str)
    header_count = bytearray(serialize_message(MESSAGES["empty array"]))
    header_count[-4:] = (2**32 - 1).to_bytes(4, "little")  # 4 billion detections in 24 bytes
    assert detection_array_view(bytes(header_count)) is None


def test_bytes_the_view_does_not_take_go_to_rclpy_s_deserialiser() -> None:
    """Another encapsulation, or more bytes after the message than padding: rclpy decides."""
    raw = serialize_message(MESSAGES["one class, many results"])
    trailing = raw + bytes(MAX_PADDING + 1)
    assert detection_array_view(trailing) is None
    read = received_detection_array(trailing, Detection3DArray)
    assert isinstance(read, DetectionArrayData)
    assert_same(read, read_by_rclpy(raw))
    padded = detection_array_view(raw + bytes(MAX_PADDING))
    assert padded is not None
    assert_same(padded, read_by_rclpy(raw))
    other_encoding = b"\x00\x07" + raw[2:]
    assert detection_array_view(other_encoding) is None
    fallback = received_detection_array(other_encoding, Detection3DArray)
    assert isinstance(fallback, DetectionArrayData)
    assert_same(fallback, read_by_rclpy(other_encoding))


def test_bytes_changed_at_random_are_read_as_rclpy_reads_them_or_refused_never_raised() -> None:
    """A thousand messages with one to three bytes changed (seeded): whatever the view reads, rclpy reads
    the same (a string's terminator changed included); the rest rclpy reads or refuses."""
    rng = np.random.default_rng(2)
    originals = [serialize_message(message) for message in MESSAGES.values()]
    viewed = 0
    for attempt in range(1000):
        changed = bytearray(originals[attempt % len(originals)])
        for _ in range(int(rng.integers(1, 4))):
            changed[int(rng.integers(0, len(changed)))] = int(rng.integers(0, 256))
        raw = bytes(changed)
        read = received_detection_array(raw, Detection3DArray)
        assert isinstance(read, str | DetectionArrayData)
        view = detection_array_view(raw)
        if view is not None and isinstance(read, DetectionArrayData):
            assert_same(view, read_by_rclpy(raw))
            viewed += 1
    assert viewed > 500


def test_the_installed_vision_msgs_is_read_by_the_view_and_another_package_s_types_by_rclpy() -> None:
    """The view reads vision_msgs 3 and 4's layout; arrays of any other go to rclpy's deserialiser."""
    assert reads_layout_of(Detection3DArray)
    assert not reads_layout_of(Pose)  # geometry_msgs has no Detection3D: not the layout the view reads
    raw = serialize_message(MESSAGES["class ids of several lengths in one detection"])
    unviewed = received_detection_array(raw + bytes(MAX_PADDING + 1), Detection3DArray, viewable=False)
    assert isinstance(unviewed, DetectionArrayData)
    assert_same(unviewed, read_by_rclpy(raw))


def test_the_rules_make_the_same_inputs_from_the_view_as_from_the_message() -> None:
    box = {"shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2}
    scene = scene_from_dict({"objects": [{"name": "a", **box}, {"name": "box", "count": 2, **box}]}, "scene")
    message = array(
        detection(result("a", 0.3, (0.0, 0.0, 0.05, 0, 0, 0, 1)), result("box", 0.9, (0.5, 0.0, 0.05, 0, 0, 0, 1))),
        detection(result("box", 0.7, (0.3, 0.0, 0.05, 0, 0, 0, 1)), result("box", math.nan)),
        detection(result("a", 0.4, NAN_POSE), result("a", 0.6, (0.0, 0.0, 0.06, 0, 0, 0, 1)), result("cup", 1.0)),
        detection(),
    )
    raw = serialize_message(message)
    view = detection_array_view(raw)
    assert view is not None
    from_view = detection_inputs(view, scene, received=1.0)
    from_message = detection_inputs(deserialize_message(raw, Detection3DArray), scene, received=1.0)
    assert from_view.unused == from_message.unused
    assert "detection 1: result 1 refused: score nan" in from_view.unused
    assert from_view.association is not None and from_message.association is not None
    assert from_view.association.assigned == from_message.association.assigned
    assert list(from_view.objects) == list(from_message.objects) == ["a", "box_1", "box_2"]
    for name, poses in from_view.objects.items():
        expected = from_message.objects[name]
        np.testing.assert_array_equal(poses.poses, expected.poses)
        assert poses.weights is not None and expected.weights is not None
        np.testing.assert_array_equal(poses.weights.values, expected.weights.values)

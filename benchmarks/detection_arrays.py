"""What a pose estimator's ``Detection3DArray`` costs: rclpy's deserialiser, a bag's messages, the raw view.

Run: ``.venv/bin/python benchmarks/detection_arrays.py [--sizes NxM ...] [--arrays A]`` (needs
vision_msgs in the venv: ``make .venv/.vision_msgs``). Each array holds N detections of M results
each (positions scattered about N boxes of a bin, scores random, one class id per detection),
shuffled, serialised as CDR. Two scenes read the same arrays: a bin of N identical boxes
(``count: N``: each detection associated to an instance, :mod:`physics_mapper.mapping.association`)
and N named boxes with one class id each (no association). Three ways of reading each, side by side:

* ``rclpy``: what a typed subscription costs: rclpy's ``deserialize_message`` (a Python object per
  result and per pose, before a callback runs), then
  :func:`physics_mapper.mapping.detections.detection_inputs` reading the message by attribute;
* ``rosbags message``: what a bag replay costs once rosbags has decoded the array (decoding not
  timed): :func:`~physics_mapper.mapping.detections.detection_inputs` reading it by attribute;
* ``raw view``: what the node's raw subscription costs:
  :func:`physics_mapper.msg_adapters.detection_array_cdr.received_detection_array` views the bytes,
  then the same :func:`~physics_mapper.mapping.detections.detection_inputs` on its arrays.

Prints the median milliseconds per array of each (arrays read in order, one node's tracks per way)
and their ratio, and the machine's load average.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from rclpy.serialization import deserialize_message
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from vision_msgs.msg import Detection3DArray

from physics_mapper.bags.vision_msgs import DEFINITIONS
from physics_mapper.mapping.association import InstanceTracks
from physics_mapper.mapping.detections import DETECTION_ARRAY, detection_inputs
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import scene_from_dict
from physics_mapper.msg_adapters.detection_array_cdr import received_detection_array

BOX = {"shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2}
DEFAULT_SIZES = ("100x1000", "24x100", "6x5")


def typestore() -> Any:
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in DEFINITIONS.items():
        store.register(get_types_from_msg(text, name))
    return store


def arrays(count: int, detections: int, results: int, named: bool, seed: int) -> list[tuple[Any, bytes]]:
    """``count`` shuffled arrays, as rosbags' messages and serialised; class ids ``box`` (a bin) or
    ``box_<k>`` (named boxes)."""
    store = typestore()
    types = store.types
    rng = np.random.default_rng(seed)
    centres = [(0.11 * (k % 6), 0.11 * (k // 6), 0.05) for k in range(detections)]
    made = []
    for index in range(count):
        header = types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=index, nanosec=0), frame_id="world"
        )
        listed = []
        for k, centre in enumerate(centres):
            class_id = f"box_{k + 1}" if named else "box"
            found = []
            for score, offset in zip(rng.random(results), rng.normal(0.0, 0.003, (results, 3)), strict=True):
                x, y, z = (float(v) for v in np.asarray(centre) + offset)
                pose = types["geometry_msgs/msg/Pose"](
                    position=types["geometry_msgs/msg/Point"](x=x, y=y, z=z),
                    orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                )
                found.append(
                    types["vision_msgs/msg/ObjectHypothesisWithPose"](
                        hypothesis=types["vision_msgs/msg/ObjectHypothesis"](class_id=class_id, score=float(score)),
                        pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                    )
                )
            box = types["vision_msgs/msg/BoundingBox3D"](
                center=found[0].pose.pose, size=types["geometry_msgs/msg/Vector3"](x=0.1, y=0.1, z=0.1)
            )
            listed.append(types["vision_msgs/msg/Detection3D"](header=header, results=found, bbox=box, id=""))
        order = rng.permutation(len(listed))
        message = types[DETECTION_ARRAY](header=header, detections=[listed[i] for i in order])
        made.append((message, bytes(store.serialize_cdr(message, DETECTION_ARRAY))))
    return made


def by_rclpy(raw: bytes) -> Any:
    """The message a typed subscription hands its callback."""
    return deserialize_message(raw, Detection3DArray)


def by_view(raw: bytes) -> Any:
    """The arrays the node's raw subscription reads."""
    return received_detection_array(raw, Detection3DArray)


def as_decoded(message: Any) -> Any:
    """A message rosbags decoded already."""
    return message


def milliseconds(scene: Scene, messages: list[Any], read: Callable[[Any], Any]) -> float:
    """Median milliseconds per array, read by ``read`` then the rules, in order by one node's tracks."""
    tracks = InstanceTracks(scene)
    times = []
    for index, message in enumerate(messages):
        start = time.perf_counter()
        detection_inputs(read(message), scene, received=0.5 * index, tracks=tracks)
        times.append((time.perf_counter() - start) * 1000.0)
    return statistics.median(times)


def rows(detections: int, results: int, count: int) -> list[tuple[str, float, float, float]]:
    """(scene, rclpy ms, rosbags message ms, raw view ms) for the bin and the named boxes."""
    n = detections
    scenes = {
        f"bin of {n} identical boxes (associated)": (
            scene_from_dict({"objects": [{"name": "box", "count": n, **BOX}]}, "bin"),
            arrays(count, n, results, named=False, seed=0),
        ),
        f"{n} named boxes (no association)": (
            scene_from_dict({"objects": [{"name": f"box_{k + 1}", **BOX} for k in range(n)]}, "named"),
            arrays(count, n, results, named=True, seed=0),
        ),
    }
    made = []
    for label, (scene, pairs) in scenes.items():
        messages, raws = [message for message, _ in pairs], [raw for _, raw in pairs]
        ways = (
            milliseconds(scene, raws, by_rclpy),
            milliseconds(scene, messages, as_decoded),
            milliseconds(scene, raws, by_view),
        )
        made.append((label, *ways))
    return made


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=DEFAULT_SIZES, help="NxM: N detections of M results each")
    parser.add_argument("--arrays", type=int, default=5, help="arrays read per size and scene (default 5)")
    options = parser.parse_args()
    print(f"median of {options.arrays} arrays; load average before: {os.getloadavg()[0]:.1f}")
    print("| array | scene | rclpy deserialise + attributes | rosbags message | raw view | rclpy / raw view |")
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    for size in options.sizes:
        detections, results = (int(part) for part in size.split("x"))
        for label, rclpy_ms, decoded_ms, view_ms in rows(detections, results, options.arrays):
            print(
                f"| {detections} x {results} | {label} | {rclpy_ms:.1f} ms | {decoded_ms:.1f} ms | {view_ms:.1f} ms"
                f" | {rclpy_ms / view_ms:.0f} |"
            )
    print(f"load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()

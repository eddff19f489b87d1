"""What reading a pose estimator's ``Detection3DArray`` costs the node, with and without association.

Run: ``.venv/bin/python benchmarks/detection_arrays.py [--detections N] [--results M] [--arrays A]``.
Each array holds N detections of M results each (positions scattered about N boxes of a bin, scores
random), shuffled. Two scenes read the same arrays: a bin of N identical boxes (``count: N``: each
detection associated to an instance, :mod:`physics_mapper.mapping.association`) and N named boxes
with one class id each (no association). Prints the median milliseconds per array of
:func:`physics_mapper.mapping.detections.detection_inputs`, the call the node's subscription makes.
Messages are the ones rosbags decodes (the node reads rclpy's by the same attributes).
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from physics_mapper.bags.vision_msgs import DEFINITIONS
from physics_mapper.mapping.association import InstanceTracks
from physics_mapper.mapping.detections import DETECTION_ARRAY, detection_inputs
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import scene_from_dict

BOX = {"shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2}


def typestore() -> Any:
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in DEFINITIONS.items():
        store.register(get_types_from_msg(text, name))
    return store.types


def arrays(count: int, detections: int, results: int, named: bool, seed: int) -> list[Any]:
    """``count`` shuffled arrays; class ids ``box`` (a bin) or ``box_<k>`` (named boxes)."""
    types = typestore()
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
        made.append(types[DETECTION_ARRAY](header=header, detections=[listed[i] for i in order]))
    return made


def milliseconds(scene: Scene, messages: list[Any]) -> float:
    """Median milliseconds per array, arrays read in order by one node's tracks."""
    tracks = InstanceTracks(scene)
    times = []
    for index, message in enumerate(messages):
        start = time.perf_counter()
        detection_inputs(message, scene, received=0.5 * index, tracks=tracks)
        times.append((time.perf_counter() - start) * 1000.0)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--detections", type=int, default=24, help="detections per array (default 24)")
    parser.add_argument("--results", type=int, default=100, help="results per detection (default 100)")
    parser.add_argument("--arrays", type=int, default=20, help="arrays read (default 20)")
    options = parser.parse_args()
    n = options.detections
    bin_scene = scene_from_dict({"objects": [{"name": "box", "count": n, **BOX}]}, "bin")
    named_scene = scene_from_dict({"objects": [{"name": f"box_{k + 1}", **BOX} for k in range(n)]}, "named")
    tracked = milliseconds(bin_scene, arrays(options.arrays, n, options.results, named=False, seed=0))
    named = milliseconds(named_scene, arrays(options.arrays, n, options.results, named=True, seed=0))
    print(f"{n} detections x {options.results} results per array, median of {options.arrays} arrays:")
    print(f"  bin of {n} identical boxes (associated): {tracked:.1f} ms")
    print(f"  {n} named boxes (no association):        {named:.1f} ms")


if __name__ == "__main__":
    main()

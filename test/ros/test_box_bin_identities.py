"""The shipped box bin bag (six identical cubes, shuffled detections without ids, misses, false and double
detections) fed to the node over real DDS, array by array, gives the identities its offline replay gives:
each instance on the same true cube in every frame. vision_msgs comes from ``make .venv/.vision_msgs``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import REPO, SCENES
from rclpy.serialization import deserialize_message
from ros_helpers import NodeProcess, RosClient
from vision_msgs.msg import Detection3DArray

from physics_mapper.bags.storage import pose_array_from_cdr, read_bag
from physics_mapper.evaluation.identity import IDENTITY_GATE, objects_lain_on
from physics_mapper.evaluation.scoring import ObjectClasses
from physics_mapper.evaluation.snapshot_results import replay_offline, snapshot_result_dict
from physics_mapper.mapping.detections import RECORDED_DETECTIONS_TOPIC
from physics_mapper.mapping.topics import GROUND_TRUTH_TOPIC, OBJECTS_TOPIC, output_topic
from physics_mapper.model.scene_files import load_scene
from physics_mapper.msg_adapters.hypotheses import nanoseconds_from_stamp
from physics_mapper.ros.qos import MAP_QOS

BAG = REPO / "test" / "data" / "box_bin"
SCENE = SCENES / "box_bin.yaml"
NAMESPACE = "/box_bin"


def on_cubes(positions: dict[str, list[float]], truth: np.ndarray) -> dict[str, int | None]:
    """The true cube (index) within the identity gate of each map object's position, if any."""
    return objects_lain_on(truth, positions, None, IDENTITY_GATE)


def test_offline_and_live_replay_of_the_shipped_bag_give_the_same_identities(tmp_path: Path) -> None:
    bag = read_bag(BAG, (RECORDED_DETECTIONS_TOPIC, GROUND_TRUTH_TOPIC))
    truth = np.array([p.position for p in pose_array_from_cdr(bag.on(GROUND_TRUTH_TOPIC)[0].raw).checked_poses()])
    scene = load_scene(SCENE)
    offline: dict[int, dict[str, int | None]] = {}
    for result in replay_offline(bag, scene, scene.search.deadline):
        placed = snapshot_result_dict(result, ObjectClasses.of(scene))["positions"]["map"] or {}
        offline[result.snapshot.stamp_ns] = on_cubes(placed, truth)
    arrays = [deserialize_message(m.raw, Detection3DArray) for m in bag.on(RECORDED_DETECTIONS_TOPIC)]
    node = NodeProcess(SCENE, {"rate_hz": 2.0, "max_age": 60.0}, tmp_path / "node.log", NAMESPACE)
    client = RosClient(NAMESPACE)
    maps: dict[int, Detection3DArray] = {}
    try:
        publisher = client.node.create_publisher(Detection3DArray, "detections", 10)

        def on_objects(msg: Detection3DArray) -> None:
            maps[nanoseconds_from_stamp(msg.header.stamp)] = msg

        client.node.create_subscription(Detection3DArray, output_topic(OBJECTS_TOPIC, NAMESPACE), on_objects, MAP_QOS)
        for array in arrays:
            stamp = nanoseconds_from_stamp(array.header.stamp)
            client.keep_publishing(
                lambda array=array: publisher.publish(array),  # type: ignore[misc]
                lambda stamp=stamp: stamp in maps,  # type: ignore[misc]
                f"the map of the array stamped {stamp} ns",
            )
    finally:
        client.close()
        assert node.stop() == 0, node.output()
    live = {
        stamp: on_cubes({d.id: [(p := d.results[0].pose.pose.position).x, p.y, p.z] for d in message.detections}, truth)
        for stamp, message in maps.items()
    }
    compared = 0
    for stamp, names in offline.items():
        for name, cube in names.items():
            if name in live.get(stamp, {}):
                assert live[stamp][name] == cube, (stamp, name)
                compared += 1
    assert compared >= len(offline) * 4  # most instances of most frames are in both maps
    cubes = {
        name: {c for frame in offline.values() for n, c in frame.items() if n == name} for name in scene.object_names
    }
    assert all(len(on) == 1 for on in cubes.values() if on), cubes  # offline: each name on one cube throughout

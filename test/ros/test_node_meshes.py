"""The node on a mesh scene over real DDS: fixed bodies drawn at start-up, objects as their meshes in each map."""

from __future__ import annotations

import time
from pathlib import Path

from conftest import SCENES
from ros_helpers import NodeProcess, RosClient, stamp_ns_of
from visualization_msgs.msg import Marker, MarkerArray

from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene_files import load_scene
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs
from physics_mapper.msg_adapters.results import SHAPE_NAMESPACE, STATIC_NAMESPACE

TABLETOP = SCENES / "tabletop.yaml"


def in_namespace(message: MarkerArray, namespace: str) -> list[Marker]:
    return [marker for marker in message.markers if marker.ns == namespace]


def test_the_node_draws_the_fixed_bodies_at_start_and_every_object_as_its_mesh(tmp_path: Path) -> None:
    scene = load_scene(TABLETOP)
    assert scene.ground_truth is not None
    node = NodeProcess(TABLETOP, {"rate_hz": 2.0, "deadline": 0.4}, tmp_path / "node.log", "/meshes")
    client = RosClient("/meshes")
    try:
        # Latched before any hypothesis: the floor, the table top and its legs.
        client.wait_for(lambda: bool(client.markers), timeout=30.0, what="the fixed bodies' markers")
        fixed = in_namespace(client.markers[0], STATIC_NAMESPACE)
        assert [m.id for m in fixed] == list(range(len(scene.static)))
        table_top = fixed[1]
        assert table_top.type == Marker.MESH_RESOURCE
        assert table_top.mesh_resource.startswith("file:///") and table_top.mesh_resource.endswith("table/table.obj")
        assert (table_top.scale.x, table_top.scale.y, table_top.scale.z) == (1.2, 0.8, 0.05)
        assert in_namespace(client.markers[0], SHAPE_NAMESPACE) == []
        # One hypothesis per object, at the ground truth: a valid map of meshes.
        stamp_ns = time.time_ns()

        def publish() -> None:
            for name, pose in zip(scene.object_names, scene.ground_truth or (), strict=True):
                hypotheses = RankedHypotheses.from_weighted([Hypothesis(pose, 1.0)])
                client.publish(name, *hypotheses_msgs(hypotheses, frame_id=scene.frame_id, stamp_ns=stamp_ns))

        def whole_map(message: MarkerArray) -> bool:
            """Markers of a map of this stamp holding every object (a map made before every object's
            hypotheses came leaves the others out: DELETE markers)."""
            shapes = in_namespace(message, SHAPE_NAMESPACE)
            return bool(shapes) and stamp_ns_of(shapes[0]) == stamp_ns and all(m.action == Marker.ADD for m in shapes)

        client.keep_publishing(publish, lambda: any(whole_map(m) for m in client.markers), "markers of the map", 60.0)
        message = next(m for m in client.markers if whole_map(m))
        objects = in_namespace(message, SHAPE_NAMESPACE)
        assert [m.id for m in objects] == list(range(len(scene.objects)))
        assert all(m.type == Marker.MESH_RESOURCE for m in objects)
        assert objects[0].mesh_resource.endswith("objects/mug.obj")
        assert len(in_namespace(message, STATIC_NAMESPACE)) == len(scene.static)  # repeated with every map
    finally:
        client.close()
        assert node.stop() == 0, node.output()

"""The shipped RViz layout (config/rviz/physics_mapper.rviz) shows the node's map as the node publishes it."""

from __future__ import annotations

from typing import Any

import yaml
from conftest import REPO, SCENES

from physics_mapper.mapping.topics import (
    CONFIGURATION_TOPIC,
    MAP_TOPIC_QOS,
    MARKERS_TOPIC,
    SETTLED_TOPIC,
    output_topic,
)
from physics_mapper.model.scene_files import load_scene

RVIZ = REPO / "config" / "rviz" / "physics_mapper.rviz"
#: RViz's words for the QoS of a subscription.
RELIABILITY = {True: "Reliable", False: "Best Effort"}
DURABILITY = {True: "Transient Local", False: "Volatile"}


def displays() -> list[dict[str, Any]]:
    layout = yaml.safe_load(RVIZ.read_text())
    return list(layout["Visualization Manager"]["Displays"])


def test_the_fixed_frame_is_the_shipped_scenes_frame() -> None:
    layout = yaml.safe_load(RVIZ.read_text())
    frames = {load_scene(path).frame_id for path in SCENES.glob("*.yaml")}
    assert frames == {layout["Visualization Manager"]["Global Options"]["Fixed Frame"]}


def test_each_map_topic_has_its_display_subscribed_as_the_node_publishes() -> None:
    """Latched topics: a volatile display would show nothing when RViz starts after the node."""
    by_topic = {d["Topic"]["Value"]: d for d in displays() if "Topic" in d}
    expected = {
        output_topic(MARKERS_TOPIC): "rviz_default_plugins/MarkerArray",
        output_topic(CONFIGURATION_TOPIC): "rviz_default_plugins/PoseArray",
        output_topic(SETTLED_TOPIC): "rviz_default_plugins/PoseArray",
    }
    assert {topic: d["Class"] for topic, d in by_topic.items()} == expected
    for display in by_topic.values():
        topic = display["Topic"]
        assert topic["Reliability Policy"] == RELIABILITY[MAP_TOPIC_QOS.reliable]
        assert topic["Durability Policy"] == DURABILITY[MAP_TOPIC_QOS.transient_local]
        assert topic["Depth"] >= MAP_TOPIC_QOS.depth


def test_every_marker_namespace_is_shown_and_the_node_docs_name_the_layout() -> None:
    (markers,) = [d for d in displays() if d["Class"] == "rviz_default_plugins/MarkerArray"]
    assert markers["Namespaces"] == {}  # empty: RViz shows every namespace the node publishes
    assert "config/rviz/physics_mapper.rviz" in (REPO / "docs" / "node.md").read_text()

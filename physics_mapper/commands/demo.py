"""``physics-mapper demo``: the main job from nothing, as ``make demo`` runs it.

Starts the node on the pyramid scene (a child process, as a launch file would), replays the
shipped pyramid bag into it with ``physics-mapper replay --start-node``, prints the error of the
map against ground truth with and without physics, then the last map the node published and
the diagnostics that came with it, read back from the recorded bag.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from physics_mapper.commands import replay
from physics_mapper.commands.files import input_file
from physics_mapper.model.errors import EXIT_FAILURE

if TYPE_CHECKING:
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from geometry_msgs.msg import PoseArray

HELP = "start the node, replay the shipped pyramid bag into it, print the error with and without physics and the map"
SEARCH_STATUS = "physics_mapper: search"
#: The started node's fully qualified name, its statuses' ``hardware_id``: other nodes on the same
#: ROS domain publish on /diagnostics too, and only this node's statuses are the demo's.
DEMO_NODE = "/physics_mapper"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--scene", type=input_file, help="scene the node loads (default: the shipped config/scenes/pyramid.yaml)"
    )
    parser.add_argument(
        "--bag",
        type=Path,
        help="bag of hypotheses and ground truth (default: the shipped test/data/pyramid)",
    )
    parser.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default: 1.0)")


def _print_map(configuration: PoseArray, diagnostics: DiagnosticArray | None, names: tuple[str, ...]) -> None:
    print(f"last map on ~/configuration (frame {configuration.header.frame_id!r}):")
    for name, pose in zip(names, configuration.poses, strict=True):
        p, q = pose.position, pose.orientation
        print(
            f"  {name:<14} position [{p.x:+.4f}, {p.y:+.4f}, {p.z:+.4f}] m  "
            f"orientation [{q.x:.4f}, {q.y:.4f}, {q.z:.4f}, {q.w:.4f}]"
        )
    if diagnostics is None:
        return
    search = next(status for status in diagnostics.status if _is_demo_search(status))
    print(f"diagnostics: {search.message}")
    for value in search.values:
        print(f"  {value.key}: {value.value}")


def _is_demo_search(status: DiagnosticStatus) -> bool:
    return bool(status.name == SEARCH_STATUS and status.hardware_id == DEMO_NODE)


def _last_map(recorded: Path) -> tuple[PoseArray | None, DiagnosticArray | None]:
    """The node's last configuration in the recorded bag, and the last search diagnostics up to it."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseArray
    from rclpy.serialization import deserialize_message

    from physics_mapper.bags.storage import read_bag
    from physics_mapper.mapping.topics import DIAGNOSTICS_TOPIC, RECORDED_CONFIGURATION_TOPIC

    bag = read_bag(recorded)
    configurations = bag.on(RECORDED_CONFIGURATION_TOPIC)
    if not configurations:
        return None, None
    last = configurations[-1]
    configuration = deserialize_message(last.raw, PoseArray)
    diagnostics = None
    for message in bag.on(DIAGNOSTICS_TOPIC):
        array = deserialize_message(message.raw, DiagnosticArray)
        if message.time_ns <= last.time_ns and any(_is_demo_search(s) for s in array.status):
            diagnostics = array
    return configuration, diagnostics


def run(args: argparse.Namespace) -> int:
    from physics_mapper.model.scene_files import load_scene
    from physics_mapper.model.scene_loading import load_stoppably
    from physics_mapper.model.shipped import shipped_path

    scene = args.scene or shipped_path("config/scenes/pyramid.yaml")
    bag = args.bag or shipped_path("test/data/pyramid")
    names = load_stoppably(scene, load_scene).object_names
    with tempfile.TemporaryDirectory(prefix="physics_mapper_demo_") as folder:
        recorded = Path(folder) / "outputs"
        parser = argparse.ArgumentParser()
        replay.add_arguments(parser)
        replay_args = parser.parse_args(
            [str(bag), "--scene", str(scene), "--start-node", "--rate", str(args.rate), "-o", str(recorded)]
        )
        print(f"replaying {bag} into a node started on {scene} (progress on stderr)\n", flush=True)
        status = replay.run(replay_args)
        if status != 0:
            return status
        configuration, diagnostics = _last_map(recorded)
    print()
    if configuration is None:
        print("the node published no configuration")
        return EXIT_FAILURE
    _print_map(configuration, diagnostics, names)
    return 0

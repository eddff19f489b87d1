"""``physics-mapper replay``: a bag's hypotheses into the live node (or the core, ``--offline``); errors out."""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from physics_mapper.commands.files import check_output_folder, input_file, load_scene_file, write_output
from physics_mapper.model.errors import EXIT_FAILURE, InputError
from physics_mapper.model.limits import MAX_KEY_TEXT, clipped, printable

if TYPE_CHECKING:
    from physics_mapper.bags.storage import Bag
    from physics_mapper.evaluation.scoring import ObjectClasses
    from physics_mapper.evaluation.snapshot_results import SnapshotResult
    from physics_mapper.evaluation.snapshots import BagSnapshot
    from physics_mapper.model.scene import Scene

HELP = "play a bag's hypotheses into the running node and record its outputs, or search them offline"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", type=Path, help="rosbag2 bag (mcap or sqlite3 directory) with hypotheses topics")
    parser.add_argument("--scene", type=input_file, required=True, help="scene YAML the hypotheses are for")
    parser.add_argument(
        "-o",
        "--output",
        type=Path,
        metavar="OUT_BAG",
        help="bag to record the results into (live default: <bag>_replay_<date-time>; offline: none)",
    )
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap", help="output bag format")
    parser.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default: 1.0)")
    parser.add_argument("--offline", action="store_true", help="search each snapshot as the node would, no ROS graph")
    parser.add_argument("--start-node", action="store_true", help="start the node on --scene for the replay")
    parser.add_argument("--namespace", default="/", help="ROS namespace of the node (default: /)")
    parser.add_argument(
        "--node-name",
        default="physics_mapper",
        metavar="NAME",
        help="name of the node (a launch file's name=, -r __node:=NAME; default: physics_mapper)",
    )
    parser.add_argument(
        "--wait",
        type=float,
        default=15.0,
        metavar="SECONDS",
        help="wait this long for the node, and with --exhaustive for each of its searches (default: 15)",
    )
    parser.add_argument(
        "--tail",
        type=float,
        default=2.0,
        metavar="SECONDS",
        help="keep recording this long after the last message (default: 2)",
    )
    parser.add_argument(
        "--deadline", type=float, metavar="SECONDS", help="offline: override the scene's search.deadline"
    )
    parser.add_argument(
        "--exhaustive",
        action="store_true",
        help="results independent of the machine's speed: offline, visit every reachable node whatever the deadline; "
        "live, play on after each snapshot only once the node reports a finished search on it",
    )
    parser.add_argument(
        "--topics",
        nargs="+",
        default=[],
        metavar="TOPIC",
        help="live: also play these topics of the bag (default: only the node's /hypotheses/<object>[/weights])",
    )
    parser.add_argument(
        "--all-topics",
        action="store_true",
        help="live: play every topic of the bag, but /rosout, /parameter_events and /clock unless named in --topics",
    )
    parser.add_argument("--json", type=Path, metavar="FILE", help="write each snapshot's code and errors as JSON")
    parser.add_argument(
        "--identity-plot",
        type=Path,
        metavar="PNG",
        help="draw frames against instances, each cell coloured by the true object the instance is on",
    )


def _progress(text: str) -> None:
    print(f"replay: {printable(text)}", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    from physics_mapper.bags.storage import BagError, check_hypothesis_topics, read_bag
    from physics_mapper.evaluation.scoring import ObjectClasses
    from physics_mapper.evaluation.snapshot_results import evaluation_summary, snapshot_result_dict
    from physics_mapper.evaluation.snapshots import bag_snapshots, input_topics, no_snapshot_reason

    if not 0.0 < args.rate < math.inf:
        raise InputError(f"--rate must be positive and finite, got {args.rate}")
    for option, seconds in (("--wait", args.wait), ("--tail", args.tail)):
        if not 0.0 <= seconds < math.inf:
            raise InputError(f"{option} must be a finite number of seconds, 0 or more, got {seconds}")
    if args.offline and args.start_node:
        raise InputError("--start-node is for a live replay; --offline runs no node")
    if not args.offline and args.deadline is not None:
        raise InputError("--deadline is for --offline; a live node has its own deadline parameter")
    if args.offline and (args.topics or args.all_topics):
        raise InputError("--topics and --all-topics are for a live replay; --offline reads only the scene's topics")
    for path in (args.json, args.identity_plot):
        if path is not None:
            check_output_folder(path)
    scene = load_scene_file(args.scene, "replay")
    try:
        # Only the scene's topics are read into memory; a live replay streams what it plays.
        bag = read_bag(args.bag, input_topics(scene))
        check_hypothesis_topics(bag, scene.object_names)
        snapshots = bag_snapshots(bag, scene)
        _progress(f"{args.bag}: {len(bag.messages)} messages of the scene, {len(snapshots)} snapshots of hypotheses")
        if not snapshots:
            _progress(f"warning: {no_snapshot_reason(scene)}")
        results = _offline(args, scene, bag, len(snapshots)) if args.offline else _live(args, scene, bag, snapshots)
    except BagError as error:
        raise InputError(str(error)) from None
    if results is None:
        return EXIT_FAILURE
    objects = ObjectClasses.of(scene)
    records = [snapshot_result_dict(result, objects) for result in results]
    print(evaluation_summary(records, objects))
    if args.json is not None:
        _write_json(args.json, "offline" if args.offline else "live", records, objects)
    if args.identity_plot is not None:
        _write_identity_plot(args.identity_plot, args.bag, records, objects)
    return 0


def _offline(args: argparse.Namespace, scene: Scene, bag: Bag, expected: int) -> list[SnapshotResult]:
    """Each snapshot searched as it is taken (:func:`~physics_mapper.evaluation.snapshot_results.replay_offline`);
    ``expected``: the snapshots counted before, for the progress lines (with instances, the maps chosen may
    change them)."""
    from physics_mapper.bags.storage import BagWriter
    from physics_mapper.evaluation.snapshot_results import replay_offline, write_results
    from physics_mapper.model.scene_files import search_with_overrides
    from physics_mapper.search.report import code_text
    from physics_mapper.search.results import SearchResult

    if args.deadline is not None:
        search = search_with_overrides(scene.search, {"deadline": args.deadline}, "--deadline", key="")
        scene = replace(scene, search=search)
    budget = None if args.exhaustive else scene.search.deadline

    def progress(index: int, result: SearchResult) -> None:
        state = "valid" if result.valid else ("fallback" if result.code else "no configuration")
        _progress(
            f"snapshot {index + 1}/{expected}: {code_text(result.code)} {state}, "
            f"{result.stats.visited} visited in {result.stats.search_time * 1000:.0f} ms"
        )

    with ExitStack() as stack:
        # Opened first: an unusable output path is reported before the searches, not after.
        writer = None if args.output is None else stack.enter_context(BagWriter(args.output, args.storage))
        results = replay_offline(bag, scene, budget, progress=progress)
        if writer is not None:
            write_results(writer, results, scene.frame_id)
            _progress(f"results written to {args.output}")
    return results


def _live(
    args: argparse.Namespace, scene: Scene, bag: Bag, snapshots: Sequence[BagSnapshot]
) -> list[SnapshotResult] | None:
    from rclpy.exceptions import InvalidNamespaceException, InvalidNodeNameException
    from rclpy.validate_namespace import validate_namespace
    from rclpy.validate_node_name import validate_node_name

    from physics_mapper.bags.storage import BagWriter, bag_info, read_bag
    from physics_mapper.evaluation.snapshot_results import recorded_results
    from physics_mapper.mapping.topics import (
        NODE_NAME,
        RECORDED_CONFIGURATION_TOPIC,
        RECORDED_SETTLED_TOPIC,
        recorded_poses_topic,
        recorded_weights_topic,
    )
    from physics_mapper.ros.bag_player import Playback, ReplayError, play_and_record
    from physics_mapper.ros.child_process import start_node, stop_node

    try:
        validate_namespace(args.namespace)
    except InvalidNamespaceException as error:
        raise InputError(f"--namespace: {clipped(' '.join(str(error).split()).rstrip(' ^'), MAX_KEY_TEXT)}") from None
    try:
        validate_node_name(args.node_name)
    except InvalidNodeNameException as error:
        raise InputError(f"--node-name: {clipped(' '.join(str(error).split()).rstrip(' ^'), MAX_KEY_TEXT)}") from None
    output = args.output or Path(f"{args.bag.resolve().name}_replay_{time.strftime('%Y_%m_%d-%H_%M_%S')}")
    playback = Playback(
        rate=args.rate,
        wait=args.wait,
        tail=args.tail,
        namespace=args.namespace,
        topics=tuple("/" + topic.lstrip("/") for topic in args.topics),
        all_topics=args.all_topics,
        exhaustive=args.exhaustive,
        node_name=args.node_name,
    )
    names = scene.object_names
    inputs = [topic for name in names for topic in (recorded_poses_topic(name), recorded_weights_topic(name))]
    info = bag_info(bag.path, verify=False)  # read_bag has checked it
    with ExitStack() as stack:
        writer = stack.enter_context(BagWriter(output, args.storage))
        log = stack.enter_context(tempfile.TemporaryFile(mode="w+"))
        process = None
        if args.start_node:
            renamed = {"__node": args.node_name} if args.node_name != NODE_NAME else None
            process = start_node(args.scene.resolve(), namespace=args.namespace, output=log, remaps=renamed)
            stack.callback(stop_node, process)
            _progress(f"started the node on {args.scene}")

        def alive() -> bool:
            return process is None or process.poll() is None

        try:
            counts = play_and_record(info, inputs, writer, playback, _progress, alive, snapshots, names)
        except ReplayError as error:
            print(f"physics-mapper replay: error: {printable(str(error))}", file=sys.stderr)
            if not alive():
                log.seek(0)
                print(f"node output:\n{log.read()}", file=sys.stderr)
            return None
    _progress(f"recorded into {output}: " + ", ".join(f"{n} on {t}" for t, n in counts.items()))
    output_bag = read_bag(output, (RECORDED_CONFIGURATION_TOPIC, RECORDED_SETTLED_TOPIC))
    return recorded_results(snapshots, output_bag, scene)


def _write_identity_plot(path: Path, bag: Path, records: Sequence[dict[str, Any]], objects: ObjectClasses) -> None:
    import io

    from physics_mapper.evaluation.plots import identity_timeline
    from physics_mapper.model.atomic_files import write_atomically

    buffer = io.BytesIO()
    identity_timeline(records, objects, bag.name).savefig(buffer, format="png", dpi=120)
    write_atomically(path, buffer.getvalue())


def _write_json(path: Path, mode: str, records: Sequence[dict[str, Any]], objects: ObjectClasses) -> None:
    from physics_mapper.evaluation.identity import identity_metrics, record_frames
    from physics_mapper.evaluation.snapshot_results import mean_scored_errors

    data = {
        "mode": mode,
        "objects": list(objects.names),
        "mean_errors": mean_scored_errors(r["errors"] for r in records),
        "identity": identity_metrics(record_frames(records), objects),
        "snapshots": list(records),
    }
    write_output(path, json.dumps(data, indent=1) + "\n")

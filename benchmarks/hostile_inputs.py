"""What the caps on hostile inputs cost at the cap, and what refusing beyond it costs.

Run: ``.venv/bin/python benchmarks/hostile_inputs.py [NAME ...]``. Each measurement runs in a fresh
process (so that its peak RSS is its own) and prints one line: seconds and peak RSS added.

* ``obj_polygon``: a 64 MiB OBJ file of one polygon (32 million triangles), refused by its count;
* ``definition``: a bag's Detection3DArray definition of ``MAX_DEFINITION_BYTES`` bytes of fields, parsed;
* ``metadata``: a ``metadata.yaml`` of ``MAX_METADATA_BYTES`` bytes of topics, read; one of YAML aliases,
  refused (and read by rosbags alone, side by side);
* ``params_file``: a ``--params-file`` of ``MAX_PARAMS_FILE_BYTES`` bytes, parsed by rcl (``rclpy.init``);
* ``history``: what one object's input history holds (``tracemalloc``) after 16 large messages of each
  kind, with ``HISTORY_BYTES`` and without it, side by side;
* ``notes``: what the node's input notes hold after 1,100 unknown class ids of 100 kB each;
* ``typestores``: what the cached type stores hold after 16 bags with definitions of their own.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parent


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def obj_polygon(folder: Path) -> str:
    from physics_mapper.model.meshes import MAX_MESH_FILE_BYTES, MeshError, MeshRequest, load_mesh_geometry

    path = folder / "polygon.obj"
    corners = (MAX_MESH_FILE_BYTES - 100) // 6
    path.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf " + b"1 2 3 " * corners + b"\n")
    start = time.perf_counter()
    try:
        load_mesh_geometry(MeshRequest(path, mass_properties=False, collision="triangle_mesh"))
    except MeshError as error:
        seconds = time.perf_counter() - start
        size, reason = path.stat().st_size / 2**20, str(error).split(": ")[-1]
        return f"OBJ of one polygon, {size:.1f} MiB: refused ({reason}) in {seconds:.2f} s"
    raise AssertionError("the polygon was not refused")


def definition(folder: Path) -> str:
    from physics_mapper.bags.vision_msgs import DEFINITIONS, MAX_DEFINITION_BYTES, bag_typestore

    array = "vision_msgs/msg/Detection3DArray"
    fields, index = [DEFINITIONS[array]], 0
    while sum(map(len, fields)) + 20 < MAX_DEFINITION_BYTES:
        fields.append(f"float64 field_{index}\n")
        index += 1
    start = time.perf_counter()
    bag_typestore(((array, "".join(fields)),))
    seconds = time.perf_counter() - start
    return f"definition of {index} fields ({sum(map(len, fields))} bytes): parsed in {seconds:.2f} s"


def metadata(folder: Path) -> str:
    from rosbags.rosbag2 import Reader

    from physics_mapper.bags.storage import MAX_METADATA_BYTES, BagError, bag_info

    bag = folder / "bag"
    scene = BENCHMARKS.parent / "config" / "scenes" / "pyramid.yaml"
    subprocess.run(
        [sys.executable, "-m", "physics_mapper", "generate", str(scene), "-o", str(bag), "--iterations", "2"],
        check=True,
        capture_output=True,
    )
    text = (bag / "metadata.yaml").read_text(encoding="utf-8")
    head, marker, rest = text.partition("  topics_with_message_count:\n")
    entry = rest.split("  - message_count:")[1]  # one topic's entry, repeated under other names
    entries: list[str] = []
    while len(head) + sum(map(len, entries)) + len(rest) + len(entry) + 40 < MAX_METADATA_BYTES:
        entries.append(f"  - message_count:{entry}".replace("/hypotheses/cube_left", f"/topic_{len(entries)}", 1))
    (bag / "metadata.yaml").write_text(head + marker + "".join(entries) + rest, encoding="utf-8")
    start = time.perf_counter()
    bag_info(bag, verify=False)
    plain = time.perf_counter() - start
    aliases = ["x-anchors:", "  - &a [1, 2, 3, 4, 5, 6, 7, 8]"]
    aliases += ["  - [*a, *a, *a, *a, *a, *a, *a, *a]"] * ((MAX_METADATA_BYTES - len(text)) // 40)
    (bag / "metadata.yaml").write_text("\n".join(aliases) + "\n" + text, encoding="utf-8")
    start = time.perf_counter()
    try:
        bag_info(bag, verify=False)
    except BagError:
        refused = time.perf_counter() - start
    else:
        raise AssertionError("the aliases were not refused")
    start = time.perf_counter()
    with Reader(bag):
        pass
    expanded = time.perf_counter() - start
    return (
        f"metadata.yaml of {len(entries)} topics ({MAX_METADATA_BYTES // 1024} KiB): read in {plain:.2f} s; "
        f"of {len(aliases)} lines of aliases: refused in {refused:.2f} s (rosbags alone reads it in {expanded:.2f} s)"
    )


def params_file(folder: Path) -> str:
    import rclpy

    from physics_mapper.ros.run_node import MAX_PARAMS_FILE_BYTES

    lines = ["/**:", "  ros__parameters:"]
    while sum(len(line) + 1 for line in lines) + 30 < MAX_PARAMS_FILE_BYTES:
        lines.append(f"    parameter_{len(lines)}: {len(lines)}.5")
    path = folder / "params.yaml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    start = time.perf_counter()
    rclpy.init(args=["node", "--ros-args", "--params-file", str(path)])
    seconds = time.perf_counter() - start
    rclpy.shutdown()
    size = path.stat().st_size
    return f"--params-file of {size} bytes ({len(lines) - 2} parameters): parsed by rcl in {seconds:.2f} s"


def history(folder: Path) -> str:
    import tracemalloc

    import numpy as np

    from physics_mapper.mapping import inputs
    from physics_mapper.model.scene import Workspace

    workspace = Workspace((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))

    def held(history_bytes: int) -> float:
        inputs.HISTORY_BYTES = history_bytes
        tracemalloc.start()
        tracker = inputs.InputTracker(["cube"])
        for index in range(inputs.HISTORY_LENGTH):
            block = np.zeros((100_000, 7))  # each message its own array, as received
            block[:, 6] = 1.0
            poses = inputs.check_poses(
                block, frame_id="w", expected_frame="w", workspace=workspace, stamp_ns=0, received=float(index)
            )
            tracker.add_poses("cube", poses)
            tracker.add_weights("cube", inputs.check_weights(np.ones(1_000_000), received=float(index)))
        current = tracemalloc.get_traced_memory()[0] / 2**20
        tracemalloc.stop()
        return current

    capped, uncapped = held(inputs.HISTORY_BYTES), held(2**62)
    return (
        f"one object fed 16 arrays of 100,000 poses and 16 of 1M weights: {capped:.0f} MiB held "
        f"(HISTORY_BYTES), {uncapped:.0f} MiB without the byte cap"
    )


def notes(folder: Path) -> str:
    import tracemalloc

    from physics_mapper.ros.node_inputs import MAX_LOGGED_INPUT_NOTES, InputNotes

    class Discard:
        def warning(self, text: str, **options: object) -> None:
            pass

    tracemalloc.start()
    notes = InputNotes(Discard())
    for index in range(MAX_LOGGED_INPUT_NOTES + 100):
        notes.log_once("/detections", f"class id {str(index) + 'x' * 100_000!r} is no object of the scene")
    held = tracemalloc.get_traced_memory()[0] / 2**10
    tracemalloc.stop()
    return f"{MAX_LOGGED_INPUT_NOTES + 100} unknown class ids of 100 kB each: the input notes hold {held:.0f} KiB"


def typestores(folder: Path) -> str:
    import tracemalloc

    from physics_mapper.bags.vision_msgs import DEFINITIONS, TYPESTORES_CACHED, bag_typestore

    tracemalloc.start()
    for index in range(2 * TYPESTORES_CACHED):  # as many estimators, each its own Detection3D
        definition = DEFINITIONS["vision_msgs/msg/Detection3D"] + f"bool field_{index}\n"
        bag_typestore((("vision_msgs/msg/Detection3D", definition),))
    held = tracemalloc.get_traced_memory()[0] / 2**20
    tracemalloc.stop()
    return f"{2 * TYPESTORES_CACHED} bags' own definitions: the type stores cached hold {held:.1f} MiB"


MEASUREMENTS: dict[str, Callable[[Path], str]] = {
    "obj_polygon": obj_polygon,
    "definition": definition,
    "metadata": metadata,
    "params_file": params_file,
    "history": history,
    "notes": notes,
    "typestores": typestores,
}


def measure_here(name: str) -> None:
    import physics_mapper.model.meshes  # noqa: F401  # imports are not the cost measured

    with tempfile.TemporaryDirectory() as folder:
        before = peak_rss_mib()
        what = MEASUREMENTS[name](Path(folder))
        print(f"{what}, peak RSS +{peak_rss_mib() - before:.0f} MiB (the input's making included)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=list(MEASUREMENTS), help=", ".join(MEASUREMENTS))
    parser.add_argument("--here", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.here:
        measure_here(args.names[0])
        return
    with open("/proc/loadavg", encoding="ascii") as loadavg:
        print(f"python {sys.version.split()[0]}, load average {' '.join(loadavg.read().split()[:3])}")
    for name in args.names:
        subprocess.run([sys.executable, __file__, "--here", name], check=True)


if __name__ == "__main__":
    main()

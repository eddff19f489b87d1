"""What MCAP checksums cost: writing with CRCs vs rosbags' writer, and reading with the check vs without.

Each bag holds ``--messages`` PoseArrays of ``--poses`` poses on one topic (deterministic content).
Writing is timed for rosbags' own MCAP writer (no CRCs) and for :class:`~physics_mapper.bags.storage.BagWriter`
(the ``mcap`` library, chunk, data and summary CRCs); reading for rosbags' reader alone and for
:func:`~physics_mapper.bags.storage.read_bag`, which first checks every CRC. Run:

    .venv/bin/python benchmarks/bag_checksums.py
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from rosbags.rosbag2 import Reader, StoragePlugin, Writer

from physics_mapper.bags.mcap_storage import verify_checksums
from physics_mapper.bags.storage import BAG_VERSION, POSE_ARRAY, TYPESTORE, BagWriter, pose_array_cdr, read_bag
from physics_mapper.model.geometry import Pose

TOPIC = "/hypotheses/cube"


def seconds(action: Callable[[], object]) -> float:
    start = time.perf_counter()
    action()
    return time.perf_counter() - start


def write_plain(path: Path, messages: list[bytes]) -> None:
    with Writer(path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection(TOPIC, POSE_ARRAY, typestore=TYPESTORE)
        for index, raw in enumerate(messages):
            writer.write(connection, index + 1, raw)


def write_checksummed(path: Path, messages: list[bytes]) -> None:
    with BagWriter(path) as writer:
        for index, raw in enumerate(messages):
            writer.write(TOPIC, POSE_ARRAY, index + 1, raw)


def read_plain(path: Path) -> None:
    with Reader(path) as reader:
        for _ in reader.messages():
            pass


def measure(count: int, poses_per_message: int) -> str:
    """One table row: the times for a bag of ``count`` PoseArrays."""
    poses = [Pose((0.001 * i, 0.0, 0.1)) for i in range(poses_per_message)]
    messages = [pose_array_cdr(index, "world", poses) for index in range(count)]
    with tempfile.TemporaryDirectory() as folder:
        plain, checked = Path(folder) / "plain", Path(folder) / "checked"
        write_a = seconds(lambda: write_plain(plain, messages))
        write_b = seconds(lambda: write_checksummed(checked, messages))
        read_a = seconds(lambda: read_plain(checked))
        read_b = seconds(lambda: read_bag(checked))
        check = seconds(lambda: verify_checksums(checked / "checked.mcap"))
        size = (checked / "checked.mcap").stat().st_size / 1e6
    return (
        f"| {count} | {size:.1f} MB | {write_a:.2f} s | {write_b:.2f} s | {read_a:.2f} s | {read_b:.2f} s "
        f"| {check:.2f} s ({size / check:.0f} MB/s) |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--messages", type=int, nargs="+", default=[2_000, 20_000], help="messages per bag")
    parser.add_argument("--poses", type=int, default=100, help="poses per PoseArray")
    args = parser.parse_args()
    columns = ("messages", "bag size", "write: rosbags", "write: with CRCs", "read: rosbags", "read_bag", "check alone")
    print(f"| {' | '.join(columns)} |")
    print("|" + " ---: |" * len(columns))
    for count in args.messages:
        print(measure(count, args.poses))


if __name__ == "__main__":
    main()

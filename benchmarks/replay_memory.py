"""Memory of a live replay of a bag with camera images: streamed now, read whole before.

A bag like ``ros2 bag record -a`` makes on a robot: ``--megabytes`` of 640x480 RGB images at
30 Hz beside the pyramid's hypotheses (the shipped bag's, repeated). Printed: the peak resident
memory (VmHWM, MiB) of a process that reads the whole bag into memory, as live replay did before
(``read_bag`` of every topic), and of ``physics-mapper replay`` itself, live into a running node,
playing the images too (``--topics /camera/image_raw``) and not (the default: only what the node
consumes). Run:

    .venv/bin/python benchmarks/replay_memory.py [--megabytes 600]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from live_node import PYRAMID_SCENE, REPO, isolate_ros, load_average

from physics_mapper.bags.storage import TYPESTORE, BagWriter, read_bag
from physics_mapper.ros.child_process import start_node, stop_node

IMAGE = "sensor_msgs/msg/Image"
WIDTH, HEIGHT = 640, 480
CAMERA_PERIOD_NS = 33_333_333
READ_WHOLE = "import sys; from physics_mapper.bags.storage import read_bag; read_bag(sys.argv[1])"


def write_bag(path: Path, megabytes: float) -> int:
    """The shipped bag's hypotheses, repeated, and ``megabytes`` of camera images; the number of images."""
    shipped = read_bag(REPO / "test" / "data" / "pyramid")
    span = shipped.messages[-1].time_ns - shipped.messages[0].time_ns + 500_000_000
    images = int(megabytes * 1024 * 1024 / (WIDTH * HEIGHT * 3))
    types = TYPESTORE.types
    stamp = types["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
    header = types["std_msgs/msg/Header"](stamp=stamp, frame_id="camera")
    pixels = np.random.default_rng(0).integers(0, 256, WIDTH * HEIGHT * 3, dtype=np.uint8)
    image = types[IMAGE](
        header=header, height=HEIGHT, width=WIDTH, encoding="rgb8", is_bigendian=0, step=WIDTH * 3, data=pixels
    )
    raw = bytes(TYPESTORE.serialize_cdr(image, IMAGE))
    duration = images * CAMERA_PERIOD_NS
    with BagWriter(path) as writer:
        messages = [
            (m.time_ns + k * span, m.topic, m.msgtype, m.raw)
            for k in range(duration // span + 1)
            for m in shipped.messages
        ]
        messages += [(i * CAMERA_PERIOD_NS, "/camera/image_raw", IMAGE, raw) for i in range(images)]
        for time_ns, topic, msgtype, data in sorted(messages, key=lambda m: m[0]):
            writer.write(topic, msgtype, time_ns, data)
    return images


def peak_mb(command: list[str]) -> float:
    """Run ``command`` to its end; its own peak resident memory (it must start no children), MiB."""
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(process.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(command)} failed")
    return usage.ru_maxrss / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--megabytes", type=float, default=600.0, help="MB of camera images in the bag (default 600)")
    args = parser.parse_args()
    isolate_ros()
    with tempfile.TemporaryDirectory() as folder:
        bag = Path(folder) / "robot"
        images = write_bag(bag, args.megabytes)
        size = sum(f.stat().st_size for f in bag.iterdir()) / 1024 / 1024
        print(f"load average: {load_average()}; bag of {size:.0f} MiB: {images} images 640x480 RGB, hypotheses")
        print("| process | peak resident memory MiB |")
        print("| --- | ---: |")
        whole = peak_mb([sys.executable, "-c", READ_WHOLE, str(bag)])
        print(f"| read the whole bag (live replay before) | {whole:.0f} |", flush=True)
        with tempfile.TemporaryFile(mode="w+") as log:
            node = start_node(PYRAMID_SCENE, output=log)
            try:
                replay = [sys.executable, "-m", "physics_mapper", "replay", str(bag), "--scene", str(PYRAMID_SCENE)]
                replay += ["--rate", "4", "--wait", "60"]
                for label, extra in (("default topics", []), ("images too", ["--topics", "/camera/image_raw"])):
                    output = ["-o", str(Path(folder) / label.replace(" ", "_"))]
                    streamed = peak_mb([*replay, *output, *extra])
                    print(f"| physics-mapper replay, live, {label} | {streamed:.0f} |", flush=True)
            finally:
                stop_node(node)


if __name__ == "__main__":
    main()

"""Soak and load: a long live replay at 5x of noisy hypotheses, idle and with both cores busy.

A bag of noisy particle-filter hypotheses (``generate``: the pyramid, sigma 3 cm and 3 degrees,
10 hypotheses per cube, an iteration every 0.5 s of bag time) long enough for ``--minutes`` of
replay at ``--rate`` (5x: a new set of hypotheses every 0.1 s) is replayed live into the node
(rate_hz 5, deadline 0.15 s, diagnostics every second), once on an otherwise idle machine and
once with both cores kept busy by two spinning processes. The node's resident memory is sampled
every 5 s. Printed per run, from the node's own diagnostics (recorded by the replay): ticks,
search overruns (past deadline + 50 ms), late ticks (a timer slot lost), the longest tick and
search, and the node's memory one minute in and at the end (target: growth below 10 %); the
node's exit code on SIGINT. ``--plot FILE`` draws memory and the longest tick per second. Run
(about 2 x 10 minutes):

    .venv/bin/python benchmarks/soak.py [--minutes 10] [--rate 5] [--load idle busy] [--plot soak.png]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
from live_node import PYRAMID_SCENE, isolate_ros, load_average, memory_mb
from rclpy.serialization import deserialize_message

from physics_mapper.bags.storage import read_bag
from physics_mapper.mapping.topics import DIAGNOSTICS_TOPIC, NODE_NAME
from physics_mapper.ros.child_process import start_node, stop_node

NODE_PARAMETERS = {"rate_hz": 5.0, "deadline": 0.15, "diagnostics_period": 1.0}
ITERATION_PERIOD = 0.5  # seconds of bag time between two sets of hypotheses
ITERATIONS_PER_RUN = 10
SAMPLE_PERIOD = 5.0  # seconds between two memory samples
WARM_UP = 60.0  # seconds: the memory "at the start" is taken after the first minute
HOG = "while True: pass"


@dataclass
class Soak:
    """One run's figures."""

    load: str
    memory: list[tuple[float, float]] = field(default_factory=list)  # (seconds, MiB)
    tick_times: list[tuple[float, float]] = field(default_factory=list)  # (seconds, longest tick that second)
    last: dict[str, str] = field(default_factory=dict)
    exit_code: int | None = None
    seconds: float = 0.0


def generate(path: Path, minutes: float, rate: float) -> None:
    bag_seconds = minutes * 60.0 * rate
    runs = math.ceil(bag_seconds / (ITERATION_PERIOD * ITERATIONS_PER_RUN)) + 1
    command = [sys.executable, "-m", "physics_mapper", "generate", str(PYRAMID_SCENE), "-o", str(path)]
    command += ["--runs", str(runs), "--particles", "300", "--top-m", "10", "--period", str(ITERATION_PERIOD)]
    subprocess.run(command, check=True, capture_output=True, timeout=3600)


def sample_memory(pid: int, soak: Soak, done: threading.Event) -> None:
    start = time.monotonic()
    while not done.wait(SAMPLE_PERIOD):
        try:
            soak.memory.append((time.monotonic() - start, memory_mb(pid)))
        except (FileNotFoundError, ValueError):
            return


def read_diagnostics(output: Path, soak: Soak) -> None:
    """The node's search status in every recorded diagnostics message."""
    bag = read_bag(output, (DIAGNOSTICS_TOPIC,))
    first = bag.messages[0].time_ns if bag.messages else 0
    for message in bag.messages:
        array = deserialize_message(message.raw, DiagnosticArray)
        for status in array.status:
            if status.name == f"{NODE_NAME}: search" and status.hardware_id == f"/{NODE_NAME}":
                values = {kv.key: kv.value for kv in status.values}
                soak.last = values
                soak.tick_times.append(((message.time_ns - first) / 1e9, float(values["max tick time [s]"])))


def run(bag: Path, folder: Path, load: str, rate: float) -> Soak:
    soak = Soak(load)
    hogs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(2 if load == "busy" else 0)]
    with tempfile.TemporaryFile(mode="w+") as log:
        node = start_node(PYRAMID_SCENE, NODE_PARAMETERS, output=log)
        done = threading.Event()
        sampler = threading.Thread(target=sample_memory, args=(node.pid, soak, done))
        sampler.start()
        output = folder / f"out_{load}"
        command = [sys.executable, "-m", "physics_mapper", "replay", str(bag), "--scene", str(PYRAMID_SCENE)]
        command += ["--rate", f"{rate:g}", "--wait", "60", "-o", str(output)]
        start = time.monotonic()
        try:
            subprocess.run(command, check=True, capture_output=True, timeout=7200)
            soak.seconds = time.monotonic() - start
        finally:
            done.set()
            sampler.join()
            soak.exit_code = stop_node(node)
            for hog in hogs:
                hog.kill()
                hog.wait()
    read_diagnostics(output, soak)
    return soak


def memory_at(soak: Soak, seconds: float) -> float:
    return next((mb for t, mb in soak.memory if t >= seconds), soak.memory[-1][1])


def row(soak: Soak) -> str:
    last = soak.last
    longest_tick = max((t for _, t in soak.tick_times), default=float("nan")) * 1000.0
    start, end = memory_at(soak, WARM_UP), soak.memory[-1][1]
    counts = " | ".join(last.get(key, "-") for key in ("ticks", "search overruns", "late ticks"))
    growth = 100 * (end / start - 1)
    return (
        f"| {soak.load} | {soak.seconds / 60:.1f} | {counts} | {longest_tick:.0f} | {start:.1f} | {end:.1f} "
        f"| {growth:+.1f} % | {soak.exit_code} |"
    )


def plot(soaks: list[Soak], path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 5))
    FigureCanvasAgg(figure)
    memory, ticks = figure.subplots(2, 1, sharex=True)
    for soak in soaks:
        memory.plot([t / 60 for t, _ in soak.memory], [mb for _, mb in soak.memory], label=soak.load)
        ticks.plot([t / 60 for t, _ in soak.tick_times], [s * 1000 for _, s in soak.tick_times], label=soak.load)
    memory.set_ylabel("node resident memory, MiB")
    ticks.set_ylabel("longest tick per second, ms")
    ticks.axhline(NODE_PARAMETERS["deadline"] * 1000, color="grey", linestyle=":", label="deadline")
    ticks.set_xlabel("minutes")
    memory.legend()
    ticks.legend()
    figure.savefig(path, dpi=110, bbox_inches="tight")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, default=10.0, help="minutes of replay per run (default 10)")
    parser.add_argument("--rate", type=float, default=5.0, help="replay speed factor (default 5)")
    parser.add_argument("--load", nargs="+", choices=("idle", "busy"), default=["idle", "busy"], help="runs")
    parser.add_argument("--plot", type=Path, metavar="PNG", help="draw memory and tick times into this file")
    args = parser.parse_args()
    isolate_ros()
    print(f"load average: {load_average()}; {args.minutes:g} min of replay at {args.rate:g}x; node {NODE_PARAMETERS}")
    with tempfile.TemporaryDirectory() as folder:
        bag = Path(folder) / "noisy"
        generate(bag, args.minutes, args.rate)
        print(
            "| load | minutes | ticks | search overruns | late ticks | longest tick ms | memory MiB at 1 min "
            "| at the end | growth | exit code |"
        )
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        soaks = []
        for load in args.load:
            soaks.append(run(bag, Path(folder), load, args.rate))
            print(row(soaks[-1]), flush=True)
    if args.plot is not None:
        plot(soaks, args.plot)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()

"""The node's memory while it searches: its resident set size, sampled (the scale benchmark's node figure).

The node runs as a child process (:mod:`physics_mapper.ros.child_process`) and gets a problem's
hypotheses a few times from ``physics-mapper publish``, then nothing new: it keeps searching the same
inputs, resuming at every tick. Its RSS is read with psutil.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import psutil

from physics_mapper.ros.child_process import start_node, stop_node

#: Seconds the node gets to start and take its inputs before sampling starts.
WARM_UP = 15.0
NAMESPACE = "/memory_probe"


@dataclass(frozen=True)
class MemorySample:
    """The node's resident set size (bytes) ``elapsed`` seconds after its inputs were published."""

    elapsed: float
    rss: int


def resident_set_size(pid: int) -> int:
    """Bytes of a process's resident set now."""
    return int(psutil.Process(pid).memory_info().rss)


def sample_node_memory(
    scene_file: Path,
    problem_file: Path,
    parameters: Mapping[str, object],
    duration: float,
    interval: float,
    log: Path,
    progress: Callable[[MemorySample], None] | None = None,
) -> list[MemorySample]:
    """Run the node on ``scene_file``, publish ``problem_file`` three times, then sample its RSS every
    ``interval`` seconds for ``duration`` seconds. Raises RuntimeError if the node dies."""
    with log.open("w") as output:
        node = start_node(scene_file, parameters, namespace=NAMESPACE, output=output)
        try:
            time.sleep(2.0)
            publish = [sys.executable, "-m", "physics_mapper", "publish", str(problem_file)]
            subprocess.run(
                [*publish, "--count", "3", "--rate", "1", "--namespace", NAMESPACE],
                check=True,
                capture_output=True,
                timeout=120,
            )
            time.sleep(WARM_UP)
            samples: list[MemorySample] = []
            start = time.monotonic()
            while (elapsed := time.monotonic() - start) <= duration:
                if node.poll() is not None:
                    raise RuntimeError(f"the node exited with code {node.returncode}; see {log}")
                samples.append(MemorySample(elapsed, resident_set_size(node.pid)))
                if progress is not None:
                    progress(samples[-1])
                time.sleep(interval)
            return samples
        finally:
            stop_node(node)

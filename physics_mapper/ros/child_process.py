"""Start and stop the node as a child process, as a launch file would (for ``demo`` and the tests)."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import IO

#: Seconds a stopped node gets to exit after SIGINT before it is killed.
STOP_TIMEOUT = 5.0


def node_command(
    scene_file: str | Path,
    parameters: Mapping[str, object] | None = None,
    namespace: str = "",
    *,
    managed: bool = False,
    remaps: Mapping[str, str] | None = None,
) -> list[str]:
    """The command line running the node (``managed``: the lifecycle node) with ``scene_file``,
    further ``-p name:=value`` parameters, ``-r from:=to`` remaps and, if given, in ``namespace``."""
    command = [sys.executable, "-m", "physics_mapper", "node", *(["--managed"] if managed else [])]
    command += ["--ros-args", "-p", f"scene_file:={scene_file}"]
    if namespace:
        command += ["-r", f"__ns:={namespace}"]
    for source, target in (remaps or {}).items():
        command += ["-r", f"{source}:={target}"]
    for name, value in (parameters or {}).items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        command += ["-p", f"{name}:={text}"]
    return command


def start_node(
    scene_file: str | Path,
    parameters: Mapping[str, object] | None = None,
    *,
    namespace: str = "",
    output: IO[str] | None = None,
    managed: bool = False,
    remaps: Mapping[str, str] | None = None,
) -> subprocess.Popen[str]:
    """Start the node (``managed``: the lifecycle node); its output goes to ``output`` (default: inherited)."""
    command = node_command(scene_file, parameters, namespace, managed=managed, remaps=remaps)
    return subprocess.Popen(command, stdout=output, stderr=subprocess.STDOUT if output else None, text=True)


def stop_node(process: subprocess.Popen[str], timeout: float = STOP_TIMEOUT) -> int:
    """Send SIGINT (like Ctrl-C) and wait; kill it if it has not exited after ``timeout`` seconds."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode

"""Decompositions run in a child process with limits: stopped by a signal at any moment, an error line past a limit.

The thin plate (10 x 10 x 0.1 cm) is V-HACD's worst case: in this process it ran for minutes, past
gigabytes, deaf to SIGINT and SIGTERM. Each test starts a real command or node on it, waits until the
decomposition is under way (its progress line), and checks what the program decided, and that it left no
temporary file behind (each runs with a ``TMPDIR`` of its own).
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import trimesh
import yaml
from diagnostic_msgs.msg import DiagnosticStatus
from ros_helpers import PHYSICS_MAPPER, RosClient, search_status

from physics_mapper.model.decomposition import MEMORY_LIMIT_VARIABLE, TIME_LIMIT_VARIABLE
from physics_mapper.model.errors import EXIT_BAD_INPUT, EXIT_INTERRUPTED

#: Seconds a signalled process may take to exit: the decomposition's stop latency (``STOP_POLL``), then
#: the interpreter's own exit. Generous: a guard against a process that does not stop at all, not a measurement
#: (``BENCHMARKS.md`` has those).
STOP_GUARD = 10.0
PLATE = {"name": "plate", "shape": "mesh", "file": "plate.obj", "collision": "decomposition", "mass": 0.1}


@pytest.fixture
def plate(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A folder with the plate mesh, a scene and a problem using it with V-HACD, a cache and a ``TMPDIR``
    (``tmp``) of its own."""
    trimesh.creation.box((0.1, 0.1, 0.001)).export(tmp_path / "plate.obj")
    body = {**PLATE, "decomposition": {"method": "vhacd"}}
    scene = {"static": [{"name": "floor", "shape": "plane"}], "objects": [body]}
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(scene), encoding="utf-8")
    problem = {**scene, "hypotheses": {"plate": [{"position": [0.0, 0.0, 0.001], "weight": 1.0}]}}
    (tmp_path / "problem.yaml").write_text(yaml.safe_dump(problem), encoding="utf-8")
    monkeypatch.setenv("PHYSICS_MAPPER_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "tmp").mkdir()
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    yield tmp_path


def left_behind(folder: Path) -> list[str]:
    """What the commands left in the ``TMPDIR`` ``folder`` of :func:`plate` (the decomposition's child is killed:
    its scratch files must lie where the parent removes them)."""
    return sorted(str(path.relative_to(folder)) for path in (folder / "tmp").rglob("*"))


#: KiB a decomposition child's resident memory passes once V-HACD runs (its interpreter and numpy take
#: about 30 MiB; the plate's V-HACD grows by hundreds of MiB a second).
RUNNING_RSS_KIB = 100_000


def workers() -> dict[int, int]:
    """Decomposition child processes running now: pid -> resident memory, KiB. ``-ww``: unlimited width,
    or ps cuts a long command line (a checkout deep in /tmp) at 80 columns and the child goes unseen."""
    listed = subprocess.run(["ps", "-ww", "-eo", "pid,rss,args"], capture_output=True, text=True, check=True).stdout
    found = [line.split() for line in listed.splitlines() if "physics_mapper.model.decomposition_worker" in line]
    return {int(fields[0]): int(fields[1]) for fields in found}


def workers_end(before: dict[int, int]) -> bool:
    """Whether the decomposition children started since ``before`` end: killed, they are reaped in the
    background while their memory is freed, so ``ps`` may list them a moment longer (``STOP_GUARD``
    bounds the wait: a child left running fails)."""
    deadline = time.monotonic() + STOP_GUARD
    while set(workers()) - set(before):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def start_until_decomposing(command: list[str], cwd: Path, before: dict[int, int]) -> subprocess.Popen[str]:
    """Start ``command`` and return once it has said that it is decomposing the plate and its decomposition
    child is deep in V-HACD (a process beside ``before``, grown past :data:`RUNNING_RSS_KIB`): a signal
    then has a running child to kill, not only a line said or a child still starting."""
    process = subprocess.Popen(command, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert process.stdout is not None
    for line in process.stdout:
        if "decomposing" in line and "plate.obj" in line:
            break
    else:
        raise AssertionError(f"no decomposition started (exit {process.wait()})")
    deadline = time.monotonic() + STOP_GUARD
    while not any(rss > RUNNING_RSS_KIB for pid, rss in workers().items() if pid not in before):
        assert time.monotonic() < deadline, "no decomposition child running"
        time.sleep(0.05)
    return process


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_stops_solve_during_a_runaway_vhacd(plate: Path, stop_signal: signal.Signals) -> None:
    before = workers()
    process = start_until_decomposing([str(PHYSICS_MAPPER), "solve", "problem.yaml"], plate, before)
    process.send_signal(stop_signal)
    assert process.wait(timeout=STOP_GUARD) == EXIT_INTERRUPTED
    assert workers_end(before)  # the child was killed, not left running
    assert left_behind(plate) == []


def test_a_node_decomposing_at_start_up_reports_it_and_stops_on_sigint(plate: Path) -> None:
    before = workers()
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", "-p", f"scene_file:={plate / 'scene.yaml'}"]
    command += ["-r", "__ns:=/decomposing"]
    process = start_until_decomposing(command, plate, before)
    client = RosClient("/decomposing")
    try:
        found = client.next_diagnostics(lambda d: True, timeout=30.0, what="diagnostics while decomposing")
        status = search_status(found)
        assert status is not None and status.level == DiagnosticStatus.WARN
        assert "decomposing" in status.message and "plate.obj" in status.message
        assert status.message.endswith("the search starts when the geometry is ready")
    finally:
        client.close()
    process.send_signal(signal.SIGINT)
    assert process.wait(timeout=STOP_GUARD) == 0  # the node's signal: a clean stop
    assert workers_end(before)
    assert left_behind(plate) == []


def test_a_node_searches_once_its_geometry_is_ready(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A decomposition that finishes: the node reports it, then serves its inputs as usual."""
    trimesh.creation.annulus(0.03, 0.05, 0.04).export(tmp_path / "ring.obj")
    ring = {**PLATE, "name": "ring", "file": "ring.obj", "decomposition": {"method": "vhacd"}}
    scene = {"static": [{"name": "floor", "shape": "plane"}], "objects": [ring]}
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(scene), encoding="utf-8")
    monkeypatch.setenv("PHYSICS_MAPPER_CACHE_DIR", str(tmp_path / "cache"))
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", "-p", f"scene_file:={tmp_path / 'scene.yaml'}"]
    log = (tmp_path / "node.log").open("w")
    process = subprocess.Popen([*command, "-r", "__ns:=/ring"], stdout=log, stderr=subprocess.STDOUT)
    client = RosClient("/ring")
    try:
        client.next_diagnostics(lambda d: "waiting for hypotheses of: ring" in search_status(d).message, 120.0)  # type: ignore[union-attr]
    finally:
        client.close()
        process.send_signal(signal.SIGINT)
        process.wait(timeout=STOP_GUARD)
        log.close()
    # Logged as well as in the diagnostics: a short decomposition may end before a subscriber is matched.
    output = (tmp_path / "node.log").read_text()
    assert "decomposing " in output and "ring.obj with vhacd" in output, output


@pytest.mark.parametrize(
    ("variable", "value", "fragment"),
    [
        (MEMORY_LIMIT_VARIABLE, "300", "ran out of its 300 MiB memory limit"),
        (TIME_LIMIT_VARIABLE, "2", "took longer than its 2 s limit"),
    ],
)
def test_a_decomposition_past_its_limit_is_one_error_line_naming_the_mesh_and_the_limit(
    plate: Path, variable: str, value: str, fragment: str
) -> None:
    environment = {**os.environ, variable: value}
    completed = subprocess.run(
        [str(PHYSICS_MAPPER), "solve", "problem.yaml"],
        cwd=plate,
        env=environment,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert completed.returncode == EXIT_BAD_INPUT, completed.stderr
    error = completed.stderr.splitlines()[-1]
    assert error.startswith("physics-mapper solve: error: problem.yaml: objects[0].file: ")
    assert f"vhacd of {plate / 'plate.obj'} {fragment}" in error and "Traceback" not in completed.stderr
    assert not (plate / "cache" / "decompositions").exists() or not list((plate / "cache" / "decompositions").iterdir())
    assert left_behind(plate) == []

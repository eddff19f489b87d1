"""What the node cannot see from inside a tick: a simulated clock that is missing or jumps back, another node
of its name, and progress against totals that lie.

The node runs as a real process over DDS; the tracker and the progress line are tested without ROS.
"""

from __future__ import annotations

import io
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import SCENES
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ros_helpers import PHYSICS_MAPPER, RosClient, search_status

from physics_mapper.evaluation.progress import Progress
from physics_mapper.mapping.clock import SIM_CLOCK_SILENCE
from physics_mapper.mapping.inputs import InputSettings, InputTracker, Level, check_poses
from physics_mapper.model.scene import Workspace

SCENE = SCENES / "pyramid.yaml"


def start(namespace: str, log: Path, *parameters: str) -> subprocess.Popen[str]:
    arguments = [item for parameter in parameters for item in ("-p", parameter)]
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", "-p", f"scene_file:={SCENE}", *arguments]
    with log.open("a") as output:
        return subprocess.Popen(
            [*command, "-r", f"__ns:={namespace}"], stdout=output, stderr=subprocess.STDOUT, text=True
        )


def stop(process: subprocess.Popen[str]) -> None:
    process.send_signal(signal.SIGINT)
    process.wait(timeout=30)


@pytest.fixture
def client_of() -> Iterator[list[RosClient]]:
    clients: list[RosClient] = []
    yield clients
    for client in clients:
        client.close()


def warned(message: DiagnosticArray, text: str) -> bool:
    status = search_status(message)
    return status is not None and status.level[0] >= DiagnosticStatus.WARN[0] and text in status.message


def test_sim_time_without_clock_is_a_warn_diagnostic_and_a_log_line(tmp_path: Path, client_of: list[RosClient]) -> None:
    log = tmp_path / "node.log"
    process = start("/simtime", log, "use_sim_time:=true")
    try:
        client = RosClient("/simtime")
        client_of.append(client)
        text = f"use_sim_time is true and no /clock received for {SIM_CLOCK_SILENCE:g} s or more"
        client.next_diagnostics(lambda d: warned(d, text), timeout=30.0, what="the warning")
    finally:
        stop(process)
    assert log.read_text().count("[WARN] [") >= 1 and "no /clock received" in log.read_text()  # and logged


def test_a_second_node_of_the_same_name_is_reported_by_both(tmp_path: Path, client_of: list[RosClient]) -> None:
    log = tmp_path / "node.log"
    first = start("/twins", log)
    second = start("/twins", log)
    try:
        client = RosClient("/twins")
        client_of.append(client)
        text = "2 nodes named /twins/physics_mapper on this ROS domain"
        client.next_diagnostics(lambda d: warned(d, text), timeout=30.0, what="the duplicate name warning")
    finally:
        stop(first)
        stop(second)
    assert log.read_text().count(text) >= 2  # each node logged it


def test_a_single_node_reports_no_duplicate(tmp_path: Path, client_of: list[RosClient]) -> None:
    process = start("/single", tmp_path / "node.log", "diagnostics_period:=0.2")
    try:
        client = RosClient("/single")
        client_of.append(client)
        client.wait_for(lambda: len(client.diagnostics) >= 8, timeout=30.0, what="diagnostics for over a second")
        assert not any("nodes named" in (search_status(d).message or "") for d in client.diagnostics)  # type: ignore[union-attr]
    finally:
        stop(process)


# --- a clock that jumps back (the tracker, ROS-free) ----------------------------------------------------------

WORKSPACE = Workspace((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))
SETTINGS = InputSettings(max_age=5.0)


def test_a_clock_jumping_back_keeps_ages_going_and_hypotheses_go_stale() -> None:
    tracker = InputTracker(["cube"])
    raw = [((0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0))]
    arrival = check_poses(
        raw, frame_id="world", expected_frame="world", workspace=WORKSPACE, stamp_ns=0, received=999.0
    )
    tracker.add_poses("cube", arrival)
    assert object_age(tracker, 1000.0) == 1.0
    after_jump = object_age(tracker, 10.0)  # /clock restarted: 1000 s -> 10 s
    assert after_jump == 1.0  # not -989: the ages go on where they were
    assert ("clock jumped back", "990.000 s, to 10.000 s (1 jump(s) so far)") in details(tracker, 11.0)
    assert object_age(tracker, 12.0) == 3.0
    status = tracker.snapshot(16.5, SETTINGS).objects[0]
    assert status.level == Level.ERROR and status.message.startswith("stale: ")  # max_age after it arrived


def object_age(tracker: InputTracker, now: float) -> float:
    return float(dict(details(tracker, now))["age [s]"])


def details(tracker: InputTracker, now: float) -> tuple[tuple[str, str], ...]:
    return tracker.snapshot(now, SETTINGS).objects[0].details


# --- progress against totals that lie ----------------------------------------------------------------------------


def test_progress_never_shows_more_done_than_total_nor_a_negative_eta() -> None:
    now = [0.0]
    stream = io.StringIO()
    progress = Progress("evaluate", 101, 1, stream=stream, mode="bar", clock=lambda: now[0])
    now[0] = 10.0
    progress.snapshot_done(100)
    assert "100/101 snapshots" in progress.status() and "ETA 00:01" in progress.status()
    progress.snapshot_done(18)  # the bag's metadata said 101, it held 118
    line = progress.bar()
    assert "118/118+ snapshots (the metadata said 101)" in line and "ETA --" in line
    assert "100%" in line and "#" * 24 in line and "ETA -" not in line.replace("ETA --", "")


def test_a_matched_publisher_whose_arrays_never_arrive_is_warned(tmp_path: Path, client_of: list[RosClient]) -> None:
    """What a best-effort input cannot count (arrays lost whole) shows as a publisher matched and nothing received.

    The publisher here sends nothing: the node sees exactly what it sees when every array is too large.
    """
    from geometry_msgs.msg import PoseArray

    from physics_mapper.mapping.clock import SILENT_PUBLISHER_SECONDS
    from physics_mapper.mapping.topics import poses_topic

    process = start("/silent", tmp_path / "node.log")
    try:
        client = RosClient("/silent")
        client_of.append(client)
        client.node.create_publisher(PoseArray, poses_topic("cube_top"), 10)
        text = f"hypotheses/cube_top: 1 publisher(s) matched for {SILENT_PUBLISHER_SECONDS:g} s or more"
        found = client.next_diagnostics(lambda d: warned(d, text), timeout=30.0, what="the silent input warning")
        assert "set input_reliability: reliable" in search_status(found).message  # type: ignore[union-attr]
    finally:
        stop(process)

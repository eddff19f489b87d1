"""The node's grouped search over real DDS: an object's new hypotheses restart its group only.

A 20-cube scene (the scale suite's singletons: every cube its own interaction group) is fed once;
then one cube gets new hypotheses at every tick, and the diagnostics show the other 19 groups'
results kept, unchanged, while that cube's group is searched again.
"""

from __future__ import annotations

import time
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ros_helpers import NodeProcess, RosClient, search_status, values

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.msg_adapters.hypotheses import hypotheses_msgs
from physics_mapper.scenarios.scale_suite import CUBE_EDGE, CUBE_MASS, ScaleCase, scale_problem

CASE = ScaleCase("singletons", 20, 3, 7)
CHANGING = "cube_00"
TICKS = 5


def scene_yaml(names: tuple[str, ...]) -> str:
    """The suite's scene as a scene file: cubes on a floor, the node's default search."""
    cubes = "\n".join(
        f"  - {{name: {name}, shape: box, size: [{CUBE_EDGE}, {CUBE_EDGE}, {CUBE_EDGE}], mass: {CUBE_MASS}}}"
        for name in names
    )
    return f"frame_id: world\nstatic:\n  - {{name: floor, shape: plane}}\nobjects:\n{cubes}\n"


def nudged(hypotheses: RankedHypotheses, metres: float) -> RankedHypotheses:
    """The same hypotheses moved ``metres`` along x: new input, same outcomes."""
    moved = []
    for h in hypotheses.hypotheses:
        x, y, z = h.pose.position
        moved.append(Hypothesis(Pose((x + metres, y, z), h.pose.orientation), h.weight))
    return RankedHypotheses.from_weighted(moved)


def groups_of(msg: DiagnosticArray) -> dict[str, str]:
    """The search status's per-group key-values (``group <id>`` -> ``<objects>: <state>``)."""
    found = values(search_status(msg) or DiagnosticStatus())
    return {key: value for key, value in found.items() if key.startswith("group ")}


def changing_group(msg: DiagnosticArray) -> tuple[str, str]:
    """``(group <id>, <state>)`` of the changing cube's group."""
    return next((k, v) for k, v in groups_of(msg).items() if v.startswith(f"{CHANGING}:"))


def test_new_hypotheses_for_one_object_every_tick_restart_only_its_group(tmp_path: Path) -> None:
    problem = scale_problem(CASE).problem
    names = problem.scene.object_names
    scene_file = tmp_path / "twenty_cubes.yaml"
    scene_file.write_text(scene_yaml(names))
    # Diagnostics faster than ticks, so that every tick's report is seen.
    parameters = {"rate_hz": 4.0, "deadline": 0.2, "max_age": 600.0, "diagnostics_period": 0.05}
    node = NodeProcess(scene_file, parameters, tmp_path / "node.log", "/twenty")
    client = RosClient("/twenty")
    restarts = []
    try:
        client.next_diagnostics(lambda d: True, timeout=30.0, what="the node's first diagnostics")

        def publish_all() -> None:
            for name, hypotheses in zip(names, problem.hypotheses, strict=True):
                client.publish(name, *hypotheses_msgs(hypotheses, frame_id="world", stamp_ns=time.time_ns()))

        def all_solved() -> bool:
            last = values(search_status(client.diagnostics[-1]) or DiagnosticStatus()) if client.diagnostics else {}
            return last.get("groups solved") == "20"

        client.keep_publishing(publish_all, all_solved, "every group solved", timeout=30.0)
        client.next_diagnostics(
            lambda d: values(search_status(d) or DiagnosticStatus()).get("groups kept") == "20",
            what="a tick that resumed every group",
        )
        start = len(client.diagnostics) - 1
        restarts.append(changing_group(client.diagnostics[-1])[0])
        for tick in range(TICKS):
            changed = nudged(problem.hypotheses[0], 0.001 * (tick % 2 + 1))  # differs from the previous
            client.publish(CHANGING, *hypotheses_msgs(changed, frame_id="world", stamp_ns=time.time_ns()))
            solved_anew = client.next_diagnostics(
                lambda d: changing_group(d)[0] != restarts[-1] and ": solved C" in changing_group(d)[1],
                what="the changed cube's group searched anew and solved",
            )
            restarts.append(changing_group(solved_anew)[0])
        ticks = client.diagnostics[start:]
    finally:
        client.close()
        node.stop()
    assert node.output().count("Traceback") == 0

    searches = [values(search_status(msg) or DiagnosticStatus()) for msg in ticks]
    groups = [groups_of(msg) for msg in ticks]
    assert all(s["groups"] == "20" and s["groups solved"] == "20" for s in searches)
    others = [{key: value for key, value in g.items() if not value.startswith(f"{CHANGING}:")} for g in groups]
    # The other 19 groups: same ids, same answer, same visits, carried over at every tick.
    assert all(len(o) == 19 for o in others)
    assert all(o == others[0] for o in others)
    assert all(value.endswith(", kept") and ": solved C" in value for value in others[0].values())
    # The changing cube's group was searched anew at each change (a new id each time), and solved again.
    assert len(set(restarts)) == TICKS + 1
    assert any(changing_group(msg)[1].endswith(", new") for msg in ticks)
    assert any(s["groups kept"] == "19" for s in searches)
    assert any(s["search"].startswith("partly resumed (19 of 20 groups kept)") for s in searches)

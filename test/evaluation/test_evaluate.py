"""``evaluate`` and ``sweep``: many bags searched offline as the node would, on any executor, into one report.

The bags are small ones made by ``generate`` (three cubes, 3 hypotheses each, mcap and sqlite3, one
in a sub-folder), searched exhaustively, so that every executor must give the same numbers. Ray runs
as a local instance with 2 CPUs started once for this module (about 4 s).
"""

from __future__ import annotations

import io
import json
import logging
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import batch_faults
import numpy as np
import pytest
import yaml
from conftest import REPO, SCENES
from rclpy.parameter import parameter_value_to_python
from ros_helpers import PHYSICS_MAPPER, RosClient

from physics_mapper.bags.storage import POSE_ARRAY, WEIGHTS, BagWriter, pose_array_cdr, weights_cdr
from physics_mapper.cli import main
from physics_mapper.commands.evaluate import exit_code, sigterm_as_interrupt
from physics_mapper.evaluation.executors import ATTEMPTS, ProcessPool, RayCluster, TaskFailure
from physics_mapper.evaluation.progress import Progress, duration_text
from physics_mapper.evaluation.reports import CRITERIA, ReportContext, best_setting, write_evaluation
from physics_mapper.evaluation.runner import run_batch, survey_bags
from physics_mapper.evaluation.settings import (
    grid_settings,
    node_parameters_yaml,
    node_rate_hz,
    parse_value,
    with_overrides,
)
from physics_mapper.evaluation.sources import find_bags
from physics_mapper.model.errors import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_INCOMPLETE, EXIT_INTERRUPTED, InputError
from physics_mapper.model.geometry import make_pose
from physics_mapper.model.scene import FALLBACKS, SearchParams
from physics_mapper.model.scene_files import SceneError, load_scene

SCENE = SCENES / "pyramid.yaml"


def generate(path: Path, iterations: int, seed: int, storage: str) -> None:
    arguments = ["generate", str(SCENE), "-o", str(path), "--runs", "1", "--iterations", str(iterations)]
    arguments += ["--top-m", "3", "--particles", "100", "--sigma", "0.005", "--sigma-rotation", "0.005"]
    assert main([*arguments, "--seed", str(seed), "--storage", storage]) == 0


@pytest.fixture(scope="module")
def bag_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two bags: 2 snapshots (mcap) and, one folder down, 3 snapshots (sqlite3)."""
    root = tmp_path_factory.mktemp("bags")
    generate(root / "a_pyramid", 2, 1, "mcap")
    generate(root / "nested" / batch_faults.FATAL_BAG, 3, 2, "sqlite3")
    return root


def evaluate(output: Path, *arguments: str) -> tuple[int, dict[str, Any]]:
    status = main(["evaluate", *arguments, "--scene", str(SCENE), "-o", str(output)])
    return status, json.loads((output / "report.json").read_text())


@pytest.fixture(scope="module")
def serial(bag_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    status, data = evaluate(tmp_path_factory.mktemp("serial"), str(bag_dir), "--exhaustive", "--workers", "0")
    assert status == 0
    return data


@pytest.fixture(scope="module")
def local_ray() -> Iterator[None]:
    """A local Ray instance with 2 CPUs; ``--ray`` in this process uses it."""
    import ray

    # address="local": a new instance even where a cluster was started on this machine (ray start).
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level=logging.ERROR)
    # Ray's workers do not have the test folder on sys.path: the fault functions travel by value.
    ray.cloudpickle.register_pickle_by_value(batch_faults)  # type: ignore[no-untyped-call]
    yield
    ray.shutdown()


def results(report: dict[str, Any]) -> dict[str, Any]:
    """A report without ``run``: what must not depend on the executor."""
    return {key: value for key, value in report.items() if key != "run"}


# --- evaluate ---------------------------------------------------------------------------------------------


def test_evaluate_matches_replay_offline_bag_by_bag(serial: dict[str, Any], tmp_path: Path) -> None:
    assert [bag["storage"] for bag in serial["bags"]] == ["mcap", "sqlite3"]
    scored: list[dict[str, Any]] = []
    for bag in serial["bags"]:
        replay_json = tmp_path / f"{Path(bag['path']).name}.json"
        arguments = ["replay", bag["path"], "--scene", str(SCENE), "--offline", "--exhaustive", "--json"]
        assert main([*arguments, str(replay_json)]) == 0
        replayed = json.loads(replay_json.read_text())
        assert bag["status"] == "evaluated"
        assert bag["records"] == replayed["snapshots"]
        means = bag["summary"]["mean_m"]
        assert {estimate: list(means[estimate]["per_object"].values()) for estimate in means} == replayed["mean_errors"]
        assert bag["summary"]["valid"] == sum(1 for record in replayed["snapshots"] if record["valid"])
        scored += [r["errors"] for r in replayed["snapshots"] if r["errors"] and r["errors"]["chosen"] is not None]
    overall = serial["overall"]
    assert overall["snapshots"] == 5 and overall["scored"] == len(scored) > 0
    for estimate in ("top", "chosen", "settled"):
        assert overall["mean_m"][estimate]["total"] == pytest.approx(np.mean([sum(e[estimate]) for e in scored]))
    assert overall["tests"]["unit"] == "bag" and overall["tests"]["settled_vs_top"]["total"]["pairs"] == 2


def test_evaluate_report_says_how_it_ran(serial: dict[str, Any]) -> None:
    assert serial["search_mode"] == "exhaustive"
    assert serial["run"]["executor"] == {"executor": "in-process", "workers": 0}
    assert serial["run"]["snapshots_evaluated"] == 5
    assert set(serial["run"]["time_to_answer"]["overall"]) >= {"p50_s", "p90_s", "p99_s", "max_s"}


def test_serial_pool_and_ray_give_identical_reports(
    bag_dir: Path, serial: dict[str, Any], local_ray: None, tmp_path: Path
) -> None:
    pool_status, pool = evaluate(tmp_path / "pool", str(bag_dir), "--exhaustive", "--workers", "2")
    ray_status, on_ray = evaluate(tmp_path / "ray", str(bag_dir), "--exhaustive", "--ray", "auto")
    assert pool_status == ray_status == 0
    assert results(pool) == results(serial)
    assert results(on_ray) == results(serial)
    assert pool["run"]["executor"] == {"executor": "process pool", "workers": 2}
    assert pool["run"]["worker_processes"] == 2  # one bag each, in their own worlds
    assert on_ray["run"]["executor"] == {"executor": "ray", "address": "auto", "nodes": 1, "cpus": 2}
    assert "- Run: ray (address auto, nodes 1, cpus 2)" in (tmp_path / "ray" / "report.md").read_text()


def write_bag(path: Path, hypotheses: dict[str, tuple[str, bytes]]) -> Path:
    """A bag with one message per topic: topic -> (type, CDR bytes)."""
    with BagWriter(path) as writer:
        for time_ns, (topic, (msgtype, raw)) in enumerate(hypotheses.items(), start=1):
            writer.write(topic, msgtype, time_ns, raw)
    return path


def test_unreadable_bags_are_listed_and_the_others_evaluated(
    bag_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "mixed"
    shutil.copytree(bag_dir, root)
    truncated = root / "c_truncated"
    shutil.copytree(root / "a_pyramid", truncated)
    storage_file = next(truncated.glob("*.mcap"))
    storage_file.write_bytes(storage_file.read_bytes()[: storage_file.stat().st_size // 2])
    (root / "d_no_metadata").mkdir()
    shutil.copy(storage_file, root / "d_no_metadata")
    poses = pose_array_cdr(1, "world", [make_pose((0.0, 0.0, 0.1))])
    hypotheses = {f"/hypotheses/{name}": (POSE_ARRAY, poses) for name in ("cube_left", "cube_right")}
    write_bag(root / "e_mistyped", hypotheses | {"/hypotheses/cube_top": (WEIGHTS, weights_cdr([1.0]))})
    write_bag(root / "f_truth_only", {"/ground_truth": (POSE_ARRAY, poses)})
    capsys.readouterr()
    status, data = evaluate(tmp_path / "report", str(root))  # the default executor, each search to its deadline
    captured = capsys.readouterr()
    assert status == EXIT_INCOMPLETE
    assert "Traceback" not in captured.err
    errors = {Path(bag["path"]).name: bag["error"] for bag in data["bags"]}
    statuses = {Path(bag["path"]).name: bag["status"] for bag in data["bags"]}
    assert statuses == {
        "a_pyramid": "evaluated",
        "b_pyramid_sqlite3": "evaluated",
        "c_truncated": "unreadable",
        "d_no_metadata": "unreadable",
        "e_mistyped": "unusable",
        "f_truth_only": "unusable",
    }
    assert errors["c_truncated"].startswith("cannot read bag (corrupt or truncated?)")
    assert errors["d_no_metadata"].startswith("no metadata.yaml: not a rosbag2 bag, or its recording did not end")
    assert errors["e_mistyped"] == (
        "topic /hypotheses/cube_top has type std_msgs/msg/Float64MultiArray, expected geometry_msgs/msg/PoseArray"
    )
    assert errors["f_truth_only"].startswith("no messages on /hypotheses/cube_left, /hypotheses/cube_right")
    assert data["counts"] == {
        "bags": 6,
        "evaluated": 2,
        "unreadable": 2,
        "unusable": 2,
        "failed": 0,
        "not_evaluated": 0,
    }
    assert data["overall"]["snapshots"] == 5
    markdown = (tmp_path / "report" / "report.md").read_text()
    assert "## Bags not evaluated" in markdown and "| `" + str(root / "e_mistyped") + "` | unusable |" in markdown
    assert data["search_mode"] == "deadline" and "deadline 0.2 s per snapshot, as the node's tick" in markdown
    assert captured.out.startswith(
        "evaluated 2 of 6 bag(s) (2 unreadable, 2 unusable, 0 failed, 0 not evaluated), 5 snapshots"
    )
    # A bag found unusable only when read (its metadata opens) makes the run incomplete too.
    assert evaluate(tmp_path / "alone", str(root / "e_mistyped"), "--workers", "0")[0] == EXIT_INCOMPLETE


@pytest.mark.parametrize("executor", ["pool", "ray"])
def test_a_task_whose_worker_dies_runs_once_more_then_is_reported(
    executor: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    behaviours = {"fine": "ok", "flaky": "die_once", "doomed": "die", "broken": "raise"}
    calls = [(str(tmp_path), name, behaviour) for name, behaviour in behaviours.items()]
    finished: dict[int, Any] = {}
    failed: dict[int, TaskFailure] = {}
    progressed: list[int] = []

    class Events:
        def progress(self, index: int) -> None:
            progressed.append(index)

        def finished(self, index: int, output: Any) -> None:
            finished[index] = output

        def failed(self, index: int, failure: TaskFailure) -> None:
            failed[index] = failure

    if executor == "ray":
        request.getfixturevalue("local_ray")
    with ProcessPool(2) if executor == "pool" else RayCluster("auto") as runner:
        runner.run(batch_faults.behave, calls, Events())
    assert finished == {0: "fine done in run 1", 1: "flaky done in run 2"}
    assert set(failed) == {2, 3}
    assert failed[2].attempts == ATTEMPTS and "died" in failed[2].error
    assert failed[3].attempts == 1 and failed[3].error.startswith("ValueError: broken cannot be used")
    runs = {name: len(list(tmp_path.glob(f"{name}.*"))) for name in behaviours}
    assert runs == {"fine": 1, "flaky": 2, "doomed": ATTEMPTS, "broken": 1}
    assert sorted(progressed) == ([0, 1] if executor == "pool" else [])  # Ray reports per task only


def test_a_bag_whose_worker_dies_twice_is_reported_failed_and_the_others_evaluated(
    bag_dir: Path, tmp_path: Path
) -> None:
    scene = load_scene(SCENE)
    bags, _ = survey_bags(find_bags([bag_dir]), scene)
    settings = grid_settings(scene.search, ["settle_time=0.5"])
    with ProcessPool(1) as pool:  # the bags one after the other: the dead worker's is the second
        run = run_batch(
            scene,
            settings,
            bags,
            True,
            pool,
            progress_prefix="t",
            progress_mode="off",
            function=batch_faults.die_on_bag,
        )
    assert exit_code(run) == EXIT_INCOMPLETE
    data = write_evaluation(run, ReportContext("test", SCENE), tmp_path).summary
    (fine, doomed) = data["bags"]
    assert fine["status"] == "evaluated" and fine["summary"]["snapshots"] == 2
    assert doomed["status"] == "failed"
    assert doomed["error"] == f"worker process died (killed by SIGKILL) in each of {ATTEMPTS} runs"
    assert data["counts"]["failed"] == 1 and data["overall"]["bags"] == 1


def test_ctrl_c_writes_the_report_of_what_finished(bag_dir: Path, tmp_path: Path) -> None:
    """Two workers: the small bag is done in a second, the shipped one (20 snapshots, exhaustive) takes longer."""
    command = [str(PHYSICS_MAPPER), "evaluate", str(bag_dir / "a_pyramid"), str(REPO / "test" / "data" / "pyramid")]
    command += ["--scene", str(SCENE), "--exhaustive", "--workers", "2", "--progress", "lines", "-o", str(tmp_path)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stderr is not None
    lines = []
    for line in process.stderr:
        lines.append(line)
        if line.startswith("evaluate: 1/2 "):
            process.send_signal(signal.SIGINT)
            break
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == EXIT_INTERRUPTED, "".join(lines) + stderr
    assert "interrupted: writing the report of what finished" in stderr and "Traceback" not in stderr
    data = json.loads((tmp_path / "report.json").read_text())
    assert data["interrupted"] is True
    assert [bag["status"] for bag in data["bags"]] == ["evaluated", "not evaluated"]
    assert data["overall"]["snapshots"] == 2
    assert (tmp_path / "report.md").read_text().startswith("# Evaluation (interrupted: partial) of 2 bag(s)")
    assert "interrupted" in stdout


def test_sigterm_stops_a_run_as_ctrl_c_does() -> None:
    """A batch system's time limit or ``kill`` ends the run with its partial report, like Ctrl-C."""
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt), sigterm_as_interrupt():
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5.0)  # the signal arrives first; should it not, the test fails
    assert signal.getsignal(signal.SIGTERM) is before


# --- sweep ----------------------------------------------------------------------------------------------

GRID = ["--grid", "jitter_threshold=0.01,0.03", "--grid", "fallback=none,settled"]


@pytest.fixture(scope="module")
def sweep(bag_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[int, Path]:
    output = tmp_path_factory.mktemp("sweep")
    arguments = ["sweep", str(bag_dir), "--scene", str(SCENE), "--exhaustive", "--workers", "0", *GRID]
    return main([*arguments, "-o", str(output)]), output


def test_sweep_tables_every_setting_and_picks_the_best_by_its_criterion(sweep: tuple[int, Path]) -> None:
    status, output = sweep
    assert status == 0
    data = json.loads((output / "sweep.json").read_text())
    settings = data["settings"]
    assert [s["varied"] for s in settings] == [
        {"jitter_threshold": j, "fallback": f} for j in (0.01, 0.03) for f in ("none", "settled")
    ]
    assert all(s["complete"] and s["counts"]["evaluated"] == 2 for s in settings)
    rank = [(s["overall"]["map_error_m"]["settled_or_top"], -s["overall"]["valid_share"], s["index"]) for s in settings]
    best = min(rank)[2]
    assert data["best"] == {"index": best, "label": settings[best]["label"], "params_file": "best_params.yaml"}
    assert data["criterion"] == {"name": "settled", "asked": "settled", "text": CRITERIA["settled"]}
    markdown = (output / "sweep.md").read_text()
    rows = [line for line in markdown.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == 4 and sum("**best**" in row for row in rows) == 1
    assert (output / "sweep.png").stat().st_size > 10_000


def test_the_node_starts_with_the_sweep_s_parameters_file(sweep: tuple[int, Path], tmp_path: Path) -> None:
    _, output = sweep
    data = json.loads((output / "sweep.json").read_text())
    best = data["settings"][data["best"]["index"]]["search"]
    params_file = output / "best_params.yaml"
    written = yaml.safe_load(params_file.read_text())["/**"]["ros__parameters"]
    assert {key: written[key] for key in best} == best
    log = (tmp_path / "node.log").open("w")
    command = [str(PHYSICS_MAPPER), "node", "--ros-args", "--params-file", str(params_file), "-r", "__ns:=/sweep"]
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, text=True, cwd=tmp_path)
    client = RosClient("/sweep")
    try:
        client.next_diagnostics(lambda d: True, timeout=30.0)
        future = client.parameters.get_parameters([*best, "scene_file", "rate_hz"])
        client.wait_for(future.done, what="get_parameters")
        values = [parameter_value_to_python(value) for value in future.result().values]  # type: ignore[no-untyped-call]
    finally:
        client.close()
        process.send_signal(signal.SIGINT)
        code = process.wait(timeout=10)
        log.close()
    assert dict(zip([*best, "scene_file", "rate_hz"], values, strict=True)) == best | {
        "scene_file": str(SCENE),
        "rate_hz": 2.0,
    }
    assert code == 0, (tmp_path / "node.log").read_text()


# --- settings, bags, progress, arguments ------------------------------------------------------------------


def test_values_read_as_in_a_scene_file_with_every_number_a_number() -> None:
    assert parse_value("1e-4", "--set") == 0.0001  # YAML 1.1 would give the string "1e-4"
    assert parse_value("settled", "--set") == "settled" and parse_value("3", "--set") == 3
    with pytest.raises(InputError, match="--set x: not valid YAML"):
        parse_value("[", "--set x")
    params = with_overrides(SearchParams(), ["probability_threshold=1e-4", "fallback=settled", "settle_time=1"])
    assert (params.probability_threshold, params.fallback, params.settle_time) == (0.0001, "settled", 1.0)


@pytest.mark.parametrize(
    ("assignments", "message"),
    [
        (["bogus=1"], "--set: search.bogus: unknown key (expected one of: probability_threshold,"),
        (["jitter_threshold=-1"], "--set: search.jitter_threshold: must be at least 0, got -1"),
        (["fallback=sometimes"], f"--set: search.fallback: must be one of {', '.join(FALLBACKS)}, got 'sometimes'"),
        (["settle_time=20"], "--set: search: settle_time must be in [0, 10], got 20"),
        (["deadline"], "--set 'deadline': expected KEY=VALUE"),
        (["deadline=0.1", "deadline=0.2"], "--set deadline is given twice"),
    ],
)
def test_set_refuses_what_a_scene_file_refuses(assignments: list[str], message: str) -> None:
    with pytest.raises((SceneError, InputError)) as raised:
        with_overrides(SearchParams(), assignments)
    assert str(raised.value).startswith(message)


def test_grid_is_every_combination_in_order_checked_like_a_scene_file() -> None:
    settings = grid_settings(SearchParams(), ["settle_time=0.5,1", "fallback=none,settled"])
    assert [s.label for s in settings] == [
        "settle_time=0.5, fallback=none",
        "settle_time=0.5, fallback=settled",
        "settle_time=1, fallback=none",
        "settle_time=1, fallback=settled",
    ]
    assert settings[3].params == SearchParams(settle_time=1.0, fallback="settled")
    with pytest.raises(InputError, match="a value is repeated"):
        grid_settings(SearchParams(), ["settle_time=1,1.0"])
    with pytest.raises(InputError, match="also given with --set"):
        grid_settings(SearchParams(), ["deadline=0.1,0.2"], fixed=["deadline"])
    with pytest.raises(SceneError, match="--grid deadline=0: search: deadline must be positive"):
        grid_settings(SearchParams(), ["deadline=0.1,0"])


def test_parameters_file_fits_the_node_s_tick() -> None:
    assert node_rate_hz(0.2) == 2.0
    assert node_rate_hz(0.6) == 1.5 and node_rate_hz(0.7) == 1.2 and 1 / node_rate_hz(7.0) > 7.0
    text = node_parameters_yaml(SCENE, SearchParams(probability_threshold=1e-5, deadline=0.6), ["made by a test"])
    assert text.startswith("# made by a test\n/**:\n  ros__parameters:\n")
    written = yaml.safe_load(text)["/**"]["ros__parameters"]
    assert written["probability_threshold"] == 1e-5  # a float in YAML 1.1 too (1.0e-05)
    assert (written["deadline"], written["rate_hz"]) == (0.6, 1.5)


def test_best_setting_needs_a_complete_evaluation_and_falls_back_to_validity_without_ground_truth() -> None:
    def setting(index: int, error: float | None, valid: float, complete: bool = True) -> dict[str, Any]:
        maps = None if error is None else {"settled_or_top": error, "chosen_or_top": error}
        return {"index": index, "complete": complete, "overall": {"map_error_m": maps, "valid_share": valid}}

    assert best_setting([setting(0, 0.02, 0.5), setting(1, 0.01, 0.4), setting(2, 0.0, 1.0, False)], "settled") == (
        1,
        "settled",
    )
    assert best_setting([setting(0, 0.01, 0.5), setting(1, 0.01, 0.6)], "settled") == (1, "settled")  # tie
    assert best_setting([setting(0, 0.02, 0.5), setting(1, 0.01, 0.4)], "valid") == (0, "valid")
    assert best_setting([setting(0, None, 0.5), setting(1, None, 0.7)], "chosen") == (1, "valid")


def test_bags_are_found_in_folders_once_each(bag_dir: Path, tmp_path: Path) -> None:
    a, b = bag_dir / "a_pyramid", bag_dir / "nested" / "b_pyramid_sqlite3"
    assert find_bags([bag_dir]) == [a, b]
    assert find_bags([b, bag_dir, next(a.glob("*.mcap"))]) == [b, a]
    with pytest.raises(InputError, match="no such file or folder"):
        find_bags([tmp_path / "nothing"])
    with pytest.raises(InputError, match="no rosbag2 bag in it"):
        find_bags([tmp_path])


def test_progress_is_a_bar_on_a_terminal_and_lines_in_a_log() -> None:
    now = [0.0]
    log = io.StringIO()
    progress = Progress("evaluate", 10, 2, log, clock=lambda: now[0])  # a StringIO is no TTY: lines
    now[0] = 2.0
    progress.snapshot_done(4)
    progress.task_done("bag_a: 4 snapshots")
    assert log.getvalue() == "evaluate: 1/2 bag_a: 4 snapshots; 4/10 snapshots, 2.0/s, ETA 00:03\n"
    terminal = io.StringIO()
    bar = Progress("sweep", 10, 2, terminal, mode="bar", clock=lambda: now[0])
    now[0] = 4.0
    bar.snapshot_done(5)
    bar.close()
    line = "sweep  50% [############            ], 0/2 tasks, 5/10 snapshots, 2.5/s, ETA 00:02"
    drawn = terminal.getvalue()
    assert drawn.endswith(line + "\n") and drawn.count("\r") >= 2  # drawn, then drawn again as it is closed
    assert duration_text(3725.2) == "1:02:06"


@pytest.mark.parametrize(
    ("arguments", "status", "message"),
    [
        (["nowhere"], EXIT_BAD_INPUT, "nowhere: no such file or folder"),
        (["--set", "bogus=1"], EXIT_BAD_INPUT, "--set: search.bogus: unknown key"),
        (["--workers", "-1"], EXIT_BAD_INPUT, "--workers must not be negative"),
        (["--ray", "127.0.0.1:1", "--workers", "2"], EXIT_BAD_INPUT, "--workers is for the local pool"),
        (["--ray", "not an address"], EXIT_BAD_INPUT, "--ray not an address: expected auto, local, HOST:PORT"),
        (["--ray", "127.0.0.1:1"], EXIT_FAILURE, "cannot connect to Ray at 127.0.0.1:1: Connection refused"),
    ],
)
def test_bad_arguments_are_one_error_line(
    arguments: list[str], status: int, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = str(REPO / "test" / "data" / "pyramid")
    bags = arguments[:1] if not arguments[0].startswith("-") else [bag]
    options = arguments[1:] if not arguments[0].startswith("-") else arguments
    code = main(["evaluate", *bags, "--scene", str(SCENE), "-o", str(tmp_path / "out"), *options])
    errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert code == status
    assert len(errors) == 1 and message in errors[0], errors

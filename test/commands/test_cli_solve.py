"""``physics-mapper solve`` on the four shipped problems: the paper's qualitative outcomes, from the CLI."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from typing import Any

import pytest
from conftest import PROBLEMS
from core_builders import FIG4_ORDER, cli, ground_truth, shipped_scene, solve_json

SHIPPED = ("stack", "pyramid", "peg_in_hole", "sphere_groove")
RESULT_KEYS = {
    "valid",
    "code",
    "probability",
    "jitter",
    "fallback_used",
    "fallback",
    "refinement",
    "poses",
    "settled_poses",
    "object_jitters",
    "stats",
    "groups",
    "trace",
}


@functools.cache
def solved(name: str) -> dict[str, Any]:
    """The JSON result of solving a shipped problem (one subprocess per problem per test run)."""
    return solve_json(f"{name}.yaml")


def by_code(result: dict[str, Any]) -> dict[tuple[int, ...], dict[str, Any]]:
    return {tuple(entry["code"]): entry for entry in result["trace"]}


def distance_to_truth(result: dict[str, Any], scene_name: str, object_name: str) -> float:
    """Metres between an object's settled position and the scene's ground truth."""
    scene = shipped_scene(f"{scene_name}.yaml")
    truth = ground_truth(scene)[scene.object_names.index(object_name)]
    return math.dist(result["settled_poses"][object_name]["position"], truth.position)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_problem_is_searched_completely_within_its_deadline(name: str) -> None:
    result = solved(name)
    assert set(result) == RESULT_KEYS
    stats = result["stats"]
    # The queue emptied: every configuration visited, or every one the bound allows (the stack's T).
    assert stats["end"] == ("bounded" if name == "stack" else "exhausted") and not stats["stopped_at_deadline"]
    assert stats["visited"] == len(result["trace"]) > 0
    assert all({"code", "probability", "outcome", "bounded"} <= set(entry) for entry in result["trace"])


def test_stack_reproduces_the_paper_fig4_tree() -> None:
    result = solved("stack")
    codes = [tuple(entry["code"]) for entry in result["trace"]]
    assert tuple(codes[: len(FIG4_ORDER)]) == FIG4_ORDER
    nodes = by_code(result)
    assert nodes[(1, 1, 1)]["outcome"] == "collision"
    assert nodes[(1, 1, 1)]["pair"] == ["cube_bottom", "cube_middle"]
    for unstable in ((2, 1, 2), (2, 2, 2)):
        assert nodes[unstable]["outcome"] == "unstable" and nodes[unstable]["moved"] == "cube_top"
    first_bounded = next(entry for entry in result["trace"] if entry["bounded"])
    assert tuple(first_bounded["code"]) == (2, 2, 2)
    first_valid = next(entry for entry in result["trace"] if entry["outcome"] == "valid")
    assert tuple(first_valid["code"]) == (2, 1, 1)
    # C311, found later, jitters less than C211 and is the solution.
    assert nodes[(3, 1, 1)]["outcome"] == "valid"
    assert nodes[(3, 1, 1)]["jitter"] < nodes[(2, 1, 1)]["jitter"]
    assert result["valid"] and result["code"] == [3, 1, 1] and not result["fallback_used"]
    assert result["stats"]["bounded"] > 0


def test_pyramid_c111_collides_and_a_later_code_is_valid() -> None:
    result = solved("pyramid")
    nodes = by_code(result)
    assert nodes[(1, 1, 1)]["outcome"] == "collision"
    assert nodes[(1, 1, 1)]["pair"] == ["cube_left", "cube_right"]
    # cube_top's best estimate floats: with the right bottom cubes it falls.
    assert nodes[(5, 4, 1)]["outcome"] == "unstable" and nodes[(5, 4, 1)]["moved"] == "cube_top"
    first_valid = next(entry for entry in result["trace"] if entry["outcome"] == "valid")
    assert first_valid["code"] == [5, 4, 4]
    assert result["valid"] and result["code"] == [5, 4, 4]
    assert result["jitter"] < shipped_scene("pyramid.yaml").search.jitter_threshold
    assert result["jitter"] == min(entry["jitter"] for entry in result["trace"] if entry["outcome"] == "valid")
    assert sum(result["object_jitters"].values()) == pytest.approx(result["jitter"])


def test_peg_poses_in_the_walls_are_rejected_and_the_dropped_peg_ends_in_the_hole() -> None:
    result = solved("peg_in_hole")
    outcomes = [(entry["outcome"], entry.get("pair")) for entry in result["trace"]]
    assert outcomes == [("collision", ["peg", "wall_left"]), ("collision", ["peg", "wall_back"]), ("unstable", None)]
    assert not result["valid"] and result["fallback_used"] and result["code"] == [3]
    assert distance_to_truth(result, "peg_in_hole", "peg") < 0.005


def test_sphere_on_the_slope_has_no_valid_configuration_and_settles_at_the_groove_bottom() -> None:
    result = solved("sphere_groove")
    assert {entry["outcome"] for entry in result["trace"]} == {"unstable"}
    assert not result["valid"] and result["fallback_used"] and result["code"] == [1]
    assert result["poses"]["ball"] != result["settled_poses"]["ball"]
    assert distance_to_truth(result, "sphere_groove", "ball") < 0.01


def test_trace_file_holds_the_visited_nodes_in_order(tmp_path: Path) -> None:
    trace_file = tmp_path / "trace.json"
    result = solve_json("stack.yaml", "--trace", trace_file)
    assert json.loads(trace_file.read_text()) == result["trace"]


def test_text_output_and_tree_are_readable() -> None:
    completed = cli("solve", PROBLEMS / "pyramid.yaml", "--tree")
    assert completed.returncode == 0, completed.stderr
    lines = completed.stdout.splitlines()
    assert lines[0].startswith("C111  #1  p=0.03696  collision cube_left-cube_right")
    assert any("└─ C544  #" in line and "valid J=" in line for line in lines)
    assert "valid C544  p=0.002352" in completed.stdout
    assert "visited 125 (expanded 125, bounded 0)" in completed.stdout
    assert "all nodes visited" in completed.stdout

    plain = cli("solve", PROBLEMS / "sphere_groove.yaml")
    assert plain.returncode == 0, plain.stderr
    assert plain.stdout.startswith("no valid configuration; fallback settled C1")
    assert "C1  #1" not in plain.stdout  # the tree only with --tree


def test_tiny_deadline_stops_the_search_and_says_so() -> None:
    result = solve_json("pyramid.yaml", "--deadline", "1e-9")
    assert result["stats"]["stopped_at_deadline"] and not result["stats"]["exhausted"]
    assert result["stats"]["visited"] < 125


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--deadline", "0"), "error: --deadline: deadline must be positive, got 0"),
        (("--deadline", "-1"), "error: --deadline: deadline: must be at least 0, got -1"),
        (("--deadline", "soon"), "error: argument --deadline: invalid float value: 'soon'"),
    ],
)
def test_bad_deadline_exits_2_with_one_line(args: tuple[str, ...], message: str) -> None:
    completed = cli("solve", PROBLEMS / "pyramid.yaml", *args)
    assert completed.returncode == 2
    assert message in completed.stderr.strip().splitlines()[-1]
    assert "Traceback" not in completed.stderr


@pytest.mark.parametrize(
    ("trace", "problem"),
    [
        ("/dev/null/dir/trace.json", "folder /dev/null/dir does not exist"),  # refused before the search
        (str(PROBLEMS), "Is a directory"),  # found when writing, after the search
    ],
)
def test_unwritable_trace_file_exits_2_without_traceback(trace: str, problem: str) -> None:
    completed = cli("solve", PROBLEMS / "stack.yaml", "--trace", trace)
    assert completed.returncode == 2
    # pybullet's import banner may precede; the error is the last line.
    assert completed.stderr.strip().splitlines()[-1] == f"physics-mapper solve: error: cannot write {trace}: {problem}"
    assert "Traceback" not in completed.stderr


def test_missing_argument_is_a_usage_error() -> None:
    completed = cli("solve")
    assert completed.returncode == 2 and "usage:" in completed.stderr

"""Bad scene and problem files: each class of error names the file, the key and the problem.

Every case is checked twice: ``load_problem`` raises :class:`SceneError` with that file, key
and problem, and ``physics-mapper solve`` prints exactly that as one line and exits 2.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import PROBLEMS, SCENES
from core_builders import cli

from physics_mapper.core.scene_files import SceneError, load_problem, load_scene
from physics_mapper.mapping.inputs import InputSettings
from physics_mapper.mapping.mapper import MapperSettings, mapper_settings_problem

Key = tuple[str | int, ...]


def valid_problem() -> dict[str, Any]:
    """A small inline problem that loads and solves: two cubes on a floor."""
    return {
        "frame_id": "world",
        "static": [{"name": "floor", "shape": "plane"}],
        "objects": [
            {"name": "cube_a", "shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.3},
            {"name": "cube_b", "shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.3},
        ],
        "search": {"deadline": 5.0},
        "hypotheses": {
            "cube_a": [
                {"position": [0.0, 0.0, 0.05], "orientation": [0, 0, 0, 1], "weight": 0.7},
                {"position": [0.0, 0.01, 0.05], "weight": 0.3},
            ],
            "cube_b": [{"position": [0.5, 0.0, 0.05], "orientation": [0, 0, 0, 1], "weight": 1.0}],
        },
    }


@dataclass(frozen=True)
class BadFile:
    """A change to :func:`valid_problem` and the error it must give."""

    key: str  # the key path the error names ("" for the whole file)
    problem: str  # text the error's problem contains
    change: Key = ()
    value: Any = None
    delete: bool = False
    raw_text: str | None = None  # the file's whole text instead of a changed valid_problem()

    def text(self) -> str:
        if self.raw_text is not None:
            return self.raw_text
        data = valid_problem()
        *parents, last = self.change
        target: Any = data
        for part in parents:
            target = target[part]
        if self.delete:
            del target[last]
        else:
            target[last] = copy.deepcopy(self.value)
        return yaml.safe_dump(data, sort_keys=False)


BAD_FILES = {
    "unknown shape": BadFile("objects[0].shape", "unknown shape 'pyramid'", ("objects", 0, "shape"), "pyramid"),
    "negative size": BadFile(
        "objects[1].size[2]", "must be positive, got -0.1", ("objects", 1, "size"), [0.1, 0.1, -0.1]
    ),
    "zero radius": BadFile(
        "static[0].radius", "must be positive, got 0", ("static", 0), {"name": "post", "shape": "sphere", "radius": 0}
    ),
    "missing object hypotheses": BadFile(
        "hypotheses.cube_b", "missing: every object needs one", ("hypotheses", "cube_b"), delete=True
    ),
    "empty hypotheses": BadFile("hypotheses.cube_b", "needs at least one hypothesis", ("hypotheses", "cube_b"), []),
    "NaN position": BadFile(
        "hypotheses.cube_a[0].position[1]",
        "must be finite, got nan",
        ("hypotheses", "cube_a", 0, "position"),
        [0.0, math.nan, 0.05],
    ),
    "Inf mass": BadFile("objects[0].mass", "must be finite, got inf", ("objects", 0, "mass"), math.inf),
    "unknown top-level key": BadFile("gravity", "unknown key (expected one of: ", ("gravity",), -9.81),
    "unknown object key": BadFile("objects[0].colour", "unknown key", ("objects", 0, "colour"), "red"),
    "bad YAML": BadFile("", "not valid YAML at line 2, column 10", raw_text="frame_id: world\nobjects: : x\n"),
    "not a mapping": BadFile("", "must be a mapping, got ['cube_a']", raw_text="- cube_a\n"),
    "missing objects": BadFile("objects", "missing", ("objects",), delete=True),
    "non-unit quaternion": BadFile(
        "hypotheses.cube_a[0].orientation",
        "quaternion norm 2 is not 1",
        ("hypotheses", "cube_a", 0, "orientation"),
        [0, 0, 0, 2],
    ),
    "zero quaternion": BadFile(
        "hypotheses.cube_a[0].orientation", "zero quaternion", ("hypotheses", "cube_a", 0, "orientation"), [0, 0, 0, 0]
    ),
    "negative weight": BadFile(
        "hypotheses.cube_a[1].weight", "must be at least 0, got -0.5", ("hypotheses", "cube_a", 1, "weight"), -0.5
    ),
    "all-zero weights": BadFile("hypotheses.cube_b", "weights sum to zero", ("hypotheses", "cube_b", 0, "weight"), 0.0),
    "unknown object in hypotheses": BadFile(
        "hypotheses.cube_z",
        "no object of that name in the scene (objects: cube_a, cube_b)",
        ("hypotheses", "cube_z"),
        [{"position": [0, 0, 0.05]}],
    ),
    "duplicate name": BadFile("static", "duplicate body name 'cube_a'", ("static", 0, "name"), "cube_a"),
    "search value not a number": BadFile(
        "search.jitter_threshold", "must be a number, got 'high'", ("search", "jitter_threshold"), "high"
    ),
    "negative search value": BadFile("search.settle_time", "must be at least 0, got -1", ("search", "settle_time"), -1),
    "probability threshold above 1": BadFile(
        "search", "probability_threshold must be in [0, 1], got 2", ("search", "probability_threshold"), 2
    ),
    "zero deadline": BadFile("search", "deadline must be positive, got 0", ("search", "deadline"), 0),
    "unknown fallback": BadFile(
        "search.fallback", "must be one of none, settled, refine, got 'guess'", ("search", "fallback"), "guess"
    ),
    "unknown search key": BadFile("search.timeout", "unknown key", ("search", "timeout"), 1.0),
}


@pytest.fixture(params=sorted(BAD_FILES), ids=lambda name: name.replace(" ", "-"))
def bad_file(request: pytest.FixtureRequest, tmp_path: Path) -> tuple[Path, BadFile]:
    case = BAD_FILES[request.param]
    path = tmp_path / "problem.yaml"
    path.write_text(case.text(), encoding="utf-8")
    return path, case


def test_valid_base_problem_loads_and_solves(tmp_path: Path) -> None:
    path = tmp_path / "problem.yaml"
    path.write_text(yaml.safe_dump(valid_problem(), sort_keys=False), encoding="utf-8")
    problem = load_problem(path)
    assert problem.scene.object_names == ("cube_a", "cube_b")
    assert [h.weight(1) for h in problem.hypotheses] == [0.7, 1.0]
    completed = cli("solve", path)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.startswith("valid C")


def test_loader_names_file_key_and_problem(bad_file: tuple[Path, BadFile]) -> None:
    path, case = bad_file
    with pytest.raises(SceneError) as raised:
        load_problem(path)
    error = raised.value
    assert (error.source, error.key) == (str(path), case.key)
    assert case.problem in error.problem
    assert str(error) == (f"{path}: {case.key}: {error.problem}" if case.key else f"{path}: {error.problem}")


def test_cli_prints_one_error_line_and_exits_2(bad_file: tuple[Path, BadFile]) -> None:
    path, case = bad_file
    completed = cli("solve", path)
    assert completed.returncode == 2
    assert completed.stdout == ""
    prefix = f"physics-mapper solve: error: {path}: " + (f"{case.key}: " if case.key else "")
    assert completed.stderr.startswith(prefix)
    assert case.problem in completed.stderr
    assert completed.stderr.count("\n") == 1  # one line, no traceback


def test_missing_problem_file(tmp_path: Path) -> None:
    path = tmp_path / "absent.yaml"
    with pytest.raises(SceneError, match="cannot read file: No such file or directory"):
        load_problem(path)
    completed = cli("solve", path)
    assert completed.returncode == 2
    assert completed.stderr == f"physics-mapper solve: error: {path}: cannot read file: No such file or directory\n"


def test_problem_naming_a_missing_scene_file_names_that_file(tmp_path: Path) -> None:
    path = tmp_path / "problem.yaml"
    path.write_text("scene: ../no_such_scene.yaml\nhypotheses: {}\n", encoding="utf-8")
    with pytest.raises(SceneError) as raised:
        load_problem(path)
    assert raised.value.source == str(tmp_path / ".." / "no_such_scene.yaml")
    assert "cannot read file" in raised.value.problem


def test_error_inside_a_referenced_scene_names_the_scene_file(tmp_path: Path) -> None:
    scene = tmp_path / "scene.yaml"
    scene.write_text("objects:\n  - {name: ball, shape: sphere, radius: -0.05}\n", encoding="utf-8")
    problem = tmp_path / "problem.yaml"
    problem.write_text("scene: scene.yaml\nhypotheses:\n  ball: [{position: [0, 0, 0.05]}]\n", encoding="utf-8")
    completed = cli("solve", problem)
    assert completed.returncode == 2
    assert completed.stderr == (
        f"physics-mapper solve: error: {scene}: objects[0].radius: must be positive, got -0.05\n"
    )


def test_problem_search_overrides_merge_with_the_scene_and_are_validated(tmp_path: Path) -> None:
    problem = load_problem(PROBLEMS / "stack.yaml")
    scene = load_scene(SCENES / "stack.yaml")
    assert problem.scene.search.probability_threshold == 0.016
    assert problem.scene.search.jitter_threshold == scene.search.jitter_threshold
    path = tmp_path / "problem.yaml"
    path.write_text(
        f"scene: {SCENES / 'stack.yaml'}\nsearch: {{angular_weight: -0.1}}\nhypotheses: {{}}\n", encoding="utf-8"
    )
    with pytest.raises(SceneError) as raised:
        load_problem(path)
    assert (raised.value.key, raised.value.problem) == ("search.angular_weight", "must be at least 0, got -0.1")


@pytest.mark.parametrize("path", sorted(SCENES.glob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_scene_starts_the_node_at_its_default_rate(path: Path) -> None:
    """The node refuses a scene whose deadline does not fit in one tick at the default rate_hz."""
    scene = load_scene(path)
    assert mapper_settings_problem(MapperSettings(scene.search, InputSettings())) is None

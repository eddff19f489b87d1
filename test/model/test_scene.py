"""Bad scene and problem files: each class of error names the file, the key and the problem.

Every case is checked twice: ``load_problem`` raises :class:`SceneError` with that file, key
and problem, and ``physics-mapper solve`` prints exactly that as one line and exits 2.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml
from conftest import PROBLEMS, REPO, SCENES
from core_builders import cli

from physics_mapper.cli import main
from physics_mapper.mapping.inputs import InputSettings
from physics_mapper.mapping.mapper import MapperSettings, mapper_settings_problem
from physics_mapper.model.errors import EXIT_BAD_INPUT
from physics_mapper.model.limits import MAX_FILE_BYTES, MAX_HYPOTHESES_PER_OBJECT, MAX_NAME_LENGTH, MAX_YAML_DEPTH
from physics_mapper.model.scene import DEFAULT_WORKSPACE_MARGIN, Box, Scene, Workspace, bounding_radius
from physics_mapper.model.scene_files import SceneError, load_problem, load_scene

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
    raw: bytes | None = None  # the file's whole content instead of a changed valid_problem()

    def content(self) -> bytes:
        if self.raw is not None:
            return self.raw
        data = valid_problem()
        *parents, last = self.change
        target: Any = data
        for part in parents:
            target = target[part]
        if self.delete:
            del target[last]
        else:
            target[last] = copy.deepcopy(self.value)
        return yaml.safe_dump(data, sort_keys=False).encode()


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
    "bad YAML": BadFile("", "not valid YAML at line 2, column 10", raw=b"frame_id: world\nobjects: : x\n"),
    "not a mapping": BadFile("", "must be a mapping, got ['cube_a']", raw=b"- cube_a\n"),
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
    "not UTF-8": BadFile("", "not UTF-8 text (byte 0xe9 at line 2, column 12)", raw=b"# x\nframe_id: w\xe9rld\n"),
    "NUL character": BadFile("", "not valid YAML: unacceptable character #x0000", raw=b"frame_id: w\x00rld\n"),
    "deeply nested lists": BadFile(
        "", f"nested deeper than {MAX_YAML_DEPTH} levels", raw=b"objects: " + b"[" * 5000 + b"]" * 5000 + b"\n"
    ),
    "deeply nested mappings": BadFile(
        "", f"nested deeper than {MAX_YAML_DEPTH} levels", raw=b"objects: " + b"{a: " * 5000 + b"}" * 5000 + b"\n"
    ),
    "larger than the cap": BadFile(
        "", f"larger than the {MAX_FILE_BYTES // 2**20} MiB allowed", raw=b"#" * MAX_FILE_BYTES + b"\n"
    ),
    # Aliases nest 10 levels of 10: a value of 10^10 strings, which an error must not print whole.
    "alias bomb as a name": BadFile(
        "frame_id",
        "must be a non-empty string, got [['x', 'x', 'x', 'x', ...], [[...], [...], [...], [...], ...], [[...],",
        raw=b"frame_id: [&l0 [x, x, x, x, x, x, x, x, x, x], "
        + b", ".join(b"&l%d [" % k + b", ".join([b"*l%d" % (k - 1)] * 10) + b"]" for k in range(1, 10))
        + b"]\n",
    ),
    "hypothesis 1e15 m up": BadFile(
        "hypotheses.cube_a[1].position",
        "(0, 0.01, 1e+15) m is outside the workspace x [-10, 10], y [-10, 10], z [-10, 10] m "
        "(default: the scene's bodies plus 10 m; set workspace: to change it)",
        ("hypotheses", "cube_a", 1, "position"),
        [0.0, 0.01, 1e15],
    ),
    "hypothesis at 1e300 m": BadFile(
        "hypotheses.cube_b[0].position",
        "(1e+300, 0, 0.05) m is outside the workspace",
        ("hypotheses", "cube_b", 0, "position"),
        [1e300, 0.0, 0.05],
    ),
    "hypothesis outside an explicit workspace": BadFile(
        "hypotheses.cube_b[0].position",
        "(0.5, 0, 0.05) m is outside the workspace x [-0.3, 0.3], y [-0.3, 0.3], z [0, 0.5] m",
        ("workspace",),
        {"min": [-0.3, -0.3, 0.0], "max": [0.3, 0.3, 0.5]},
    ),
    "empty workspace": BadFile(
        "workspace",
        "min must be below max on every axis, but z: 0.5 >= 0.5",
        ("workspace",),
        {"min": [-1, -1, 0.5], "max": [1, 1, 0.5]},
    ),
    "workspace beyond the trusted range": BadFile(
        "workspace.max[0]",
        "must be within ±1e+07 m (where the physics is trusted), got 1e+15",
        ("workspace",),
        {"min": [-1, -1, 0], "max": [1e15, 1, 1]},
    ),
    "workspace without max": BadFile("workspace.max", "missing", ("workspace",), {"min": [-1, -1, 0]}),
    "static body 1e15 m away": BadFile(
        "static[0].pose.position[0]",
        "must be within ±1e+07 m (where the physics is trusted), got 1e+15",
        ("static", 0, "pose"),
        {"position": [1e15, 0, 0]},
    ),
    "huge box": BadFile(
        "objects[0].size[0]",
        "must be within ±1e+07 m (where the physics is trusted), got 1e+09",
        ("objects", 0, "size"),
        [1e9, 0.1, 0.1],
    ),
    "overlong name": BadFile(
        "objects[0].name",
        f"longer than {MAX_NAME_LENGTH} characters",
        ("objects", 0, "name"),
        "cube" * MAX_NAME_LENGTH,
    ),
    "unknown strategy": BadFile(
        "search.strategy", "must be one of conflict, grouped, joint, got 'fast'", ("search", "strategy"), "fast"
    ),
    "fractional queue limit": BadFile(
        "search.queue_limit", "must be a whole number, got 10.5", ("search", "queue_limit"), 10.5
    ),
}


@pytest.fixture(params=sorted(BAD_FILES), ids=lambda name: name.replace(" ", "-"))
def bad_file(request: pytest.FixtureRequest, tmp_path: Path) -> tuple[Path, BadFile]:
    case = BAD_FILES[request.param]
    path = tmp_path / "problem.yaml"
    path.write_bytes(case.content())
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


def test_cli_prints_one_error_line_and_exits_2(
    bad_file: tuple[Path, BadFile], capsys: pytest.CaptureFixture[str]
) -> None:
    """In process, for speed: an exception escaping ``main`` fails the test as a traceback would
    (the installed command runs in a child process in the tests below)."""
    path, case = bad_file
    assert main(["solve", str(path)]) == EXIT_BAD_INPUT
    captured = capsys.readouterr()
    assert captured.out == ""
    prefix = f"physics-mapper solve: error: {path}: " + (f"{case.key}: " if case.key else "")
    assert captured.err.startswith(prefix)
    assert case.problem in captured.err
    assert captured.err.count("\n") == 1  # one line, no traceback


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


def test_the_default_workspace_holds_the_scene_and_its_ground_truth_plus_a_margin() -> None:
    """Pyramid: a floor plane at the origin and three 20 cm cubes (bounding radius sqrt(3) x 0.1 m)."""
    scene = load_scene(SCENES / "pyramid.yaml")
    radius = math.sqrt(3.0) * 0.1
    assert bounding_radius(scene.objects[0].shape) == pytest.approx(radius)
    workspace = scene.workspace
    assert workspace.derived and scene.explicit_workspace is None
    margin = DEFAULT_WORKSPACE_MARGIN + radius
    assert workspace.min_corner == pytest.approx((-0.105 - margin, -margin, 0.1 - margin))
    assert workspace.max_corner == pytest.approx((0.105 + margin, margin, 0.3 + margin))
    bare = Scene(objects=scene.objects)  # nothing placed: around the origin
    assert (bare.workspace.min_corner, bare.workspace.max_corner) == ((-10.0,) * 3, (10.0,) * 3)


def test_an_explicit_workspace_is_used_and_holds_the_ground_truth(tmp_path: Path) -> None:
    text = (SCENES / "pyramid.yaml").read_text(encoding="utf-8")
    path = tmp_path / "scene.yaml"
    path.write_text(text + "workspace: {min: [-0.5, -0.5, 0], max: [0.5, 0.5, 1]}\n", encoding="utf-8")
    scene = load_scene(path)
    assert scene.workspace == Workspace((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0))
    assert str(scene.workspace) == "x [-0.5, 0.5], y [-0.5, 0.5], z [0, 1] m"
    path.write_text(text + "workspace: {min: [-0.5, -0.5, 0], max: [0.5, 0.5, 0.25]}\n", encoding="utf-8")
    with pytest.raises(SceneError) as raised:
        load_scene(path)
    assert (raised.value.key, raised.value.problem) == (
        "ground_truth.cube_top.position",
        "(0, 0, 0.3) m is outside the workspace x [-0.5, 0.5], y [-0.5, 0.5], z [0, 0.25] m",
    )


def test_numbers_are_read_in_every_usual_spelling(tmp_path: Path) -> None:
    """YAML 1.1 reads 1e-4 and 1E+9 as strings; files take them as people write them."""
    path = tmp_path / "problem.yaml"
    path.write_text(
        "objects:\n"
        "  - {name: cube_a, shape: box, size: [1e-1, 1E-1, .1], mass: 3e-1, friction: 8E-1}\n"
        "search: {probability_threshold: 1e-4, deadline: 1E+1, settle_time: .5, jitter_threshold: 1.0e-2,"
        " angular_weight: +1e-1, penetration_threshold: 5e-3}\n"
        "hypotheses:\n"
        "  cube_a: [{position: [0, 0, 5e-2], weight: 1E+0}, {position: [-.5e-1, 1.0e0, 5E-2], weight: 2e0}]\n",
        encoding="utf-8",
    )
    problem = load_problem(path)
    search = problem.scene.search
    assert (search.probability_threshold, search.deadline, search.settle_time) == (1e-4, 10.0, 0.5)
    assert (search.jitter_threshold, search.angular_weight, search.penetration_threshold) == (0.01, 0.1, 0.005)
    model = problem.scene.objects[0]
    assert (model.shape, model.mass, model.friction) == (Box((0.1, 0.1, 0.1)), 0.3, 0.8)
    assert [h.pose.position for h in problem.hypotheses[0].hypotheses] == [(-0.05, 1.0, 0.05), (0.0, 0.0, 0.05)]


def test_strings_that_only_look_like_numbers_stay_strings(tmp_path: Path) -> None:
    path = tmp_path / "scene.yaml"
    text = "frame_id: 1e5x\nstatic: [{name: 1.5e, shape: plane}]\nobjects: [{name: b, shape: sphere, radius: 1e-1}]\n"
    path.write_text(text, encoding="utf-8")
    scene = load_scene(path)
    assert (scene.frame_id, scene.static[0].name) == ("1e5x", "1.5e")


def test_more_hypotheses_than_the_cap_keep_the_heaviest_with_a_note(tmp_path: Path) -> None:
    data = valid_problem()
    count = MAX_HYPOTHESES_PER_OBJECT + 20
    data["hypotheses"]["cube_b"] = [{"position": [0.5, 0.001 * i, 0.05], "weight": 1.0 + i} for i in range(count)]
    path = tmp_path / "problem.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    problem = load_problem(path)
    kept = problem.hypotheses[1]
    assert len(kept) == MAX_HYPOTHESES_PER_OBJECT
    assert kept.pose(1).position == (0.5, 0.001 * (count - 1), 0.05)  # the heaviest, ranked first
    assert problem.notes == (
        f"{path}: hypotheses.cube_b: kept the {MAX_HYPOTHESES_PER_OBJECT} heaviest of {count} hypotheses",
    )
    completed = cli("solve", path)
    assert completed.returncode == 0
    assert completed.stderr == f"physics-mapper solve: warning: {problem.notes[0]}\n"


#: Files no YAML parser should be handed whole: each must give one error line naming the file, exit 2.
UNREADABLE = {
    "not-UTF-8": (b"frame_id: w\xe9rld\n", "not UTF-8 text (byte 0xe9 at line 1, column 12)"),
    "nested-5000-deep": (
        b"objects: " + b"[" * 5000 + b"]" * 5000 + b"\n",
        f"not valid YAML at line 1, column 41: nested deeper than {MAX_YAML_DEPTH} levels",
    ),
}
#: Every subcommand that reads a scene or problem file, as arguments around that file's path.
FILE_COMMANDS: dict[str, Callable[[Path, Path], list[str]]] = {
    "solve": lambda bad, tmp: ["solve", str(bad)],
    "solve, problem naming the scene": lambda bad, tmp: ["solve", str(problem_naming(bad, tmp))],
    "publish": lambda bad, tmp: ["publish", str(bad)],
    "bench": lambda bad, tmp: ["bench", "physics_costs", str(bad)],
    "generate": lambda bad, tmp: ["generate", str(bad), "-o", str(tmp / "bag")],
    "replay --offline": lambda bad, tmp: ["replay", str(REPO / "test/data/pyramid"), "--scene", str(bad), "--offline"],
    "replay": lambda bad, tmp: ["replay", str(REPO / "test/data/pyramid"), "--scene", str(bad)],
    "demo": lambda bad, tmp: ["demo", "--scene", str(bad)],
    "experiment": lambda bad, tmp: ["experiment", "peg", "--scenes", str(bad.parent), "-o", str(tmp / "reports")],
}


def problem_naming(scene: Path, folder: Path) -> Path:
    problem = folder / "problem.yaml"
    problem.write_text(f"scene: {scene}\nhypotheses: {{}}\n", encoding="utf-8")
    return problem


@pytest.mark.parametrize("content", sorted(UNREADABLE))
@pytest.mark.parametrize("command", sorted(FILE_COMMANDS))
def test_every_command_reports_an_unreadable_file_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, content: str
) -> None:
    raw, problem = UNREADABLE[content]
    bad = tmp_path / "scenes" / "peg_in_hole.yaml"  # the name `experiment peg` reads from --scenes
    bad.parent.mkdir()
    bad.write_bytes(raw)
    arguments = FILE_COMMANDS[command](bad, tmp_path)
    assert main(arguments) == EXIT_BAD_INPUT
    captured = capsys.readouterr()
    assert captured.err == f"physics-mapper {arguments[0]}: error: {bad}: {problem}\n"


@pytest.mark.parametrize("content", sorted(UNREADABLE))
def test_the_node_reports_an_unreadable_scene_file_in_one_line(tmp_path: Path, content: str) -> None:
    raw, problem = UNREADABLE[content]
    bad = tmp_path / "scene.yaml"
    bad.write_bytes(raw)
    completed = cli("node", "--ros-args", "-p", f"scene_file:={bad}")
    assert completed.returncode == EXIT_BAD_INPUT
    lines = [line for line in completed.stderr.splitlines() if not line.startswith("pybullet build time")]
    assert lines == [f"physics_mapper node: error: {bad}: {problem}"]


def test_the_search_strategy_bound_settling_and_limits_are_read(tmp_path: Path) -> None:
    data = valid_problem()
    data["search"] = {
        "strategy": "joint",
        "bound": "absolute",
        "settle_exit": "full",
        "interaction_margin": 0.05,
        "queue_limit": 500,
        "trace_limit": 0,
    }
    path = tmp_path / "problem.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    params = load_problem(path).scene.search
    assert (params.strategy, params.bound, params.settle_exit) == ("joint", "absolute", "full")
    assert (params.interaction_margin, params.queue_limit, params.trace_limit) == (0.05, 500, 0)
    assert isinstance(params.queue_limit, int) and isinstance(params.trace_limit, int)


@pytest.mark.parametrize("path", sorted(SCENES.glob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_scene_starts_the_node_at_its_default_rate(path: Path) -> None:
    """The node refuses a scene whose deadline does not fit in one tick at the default rate_hz."""
    scene = load_scene(path)
    assert mapper_settings_problem(MapperSettings(scene.search, InputSettings())) is None

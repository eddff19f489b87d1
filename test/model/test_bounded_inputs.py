"""Inputs that must be refused or bounded, and files written whole: YAML keys, special files, names, meshes,
masses, the decomposition cache, and every output on a full disk.

Real files, real meshes, a real (small) filesystem: a tmpfs mounted for the test, so that writes fail as
they do on a full disk.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mesh_builders import floor_scene_dict, load_inline, mesh_object, trough_mesh, write_mesh
from ros_helpers import last_error_line, one_error_line, run_cli

from physics_mapper.evaluation.outputs import lock_report_folder
from physics_mapper.mapping import topics
from physics_mapper.model.decomposition import (
    CACHE_ENVIRONMENT_VARIABLE,
    MAX_CONVEX_PARTS,
    read_cached_parts,
)
from physics_mapper.model.errors import InputError
from physics_mapper.model.limits import MAX_MASS, MAX_MASS_RATIO, MAX_OBJECTS
from physics_mapper.model.meshes import MAX_MESH_FACES
from physics_mapper.model.names import DERIVED_TOPICS, derived_topics, object_name_problem
from physics_mapper.model.scene import Mesh, Scene
from physics_mapper.model.scene_files import SceneError, load_problem, load_scene

REPO = Path(__file__).resolve().parents[2]
PYRAMID_PROBLEM = REPO / "config" / "problems" / "pyramid.yaml"


def problem_text(objects: list[dict[str, Any]], heights: list[float] | None = None) -> str:
    heights = heights or [0.05 + 0.1 * i for i in range(len(objects))]
    document = {
        "static": [{"name": "floor", "shape": "plane"}],
        "objects": objects,
        "hypotheses": {
            o["name"]: [{"position": [0.0, 0.0, z], "weight": 1.0}] for o, z in zip(objects, heights, strict=True)
        },
    }
    return yaml.safe_dump(document, sort_keys=False)


def cube(name: str, **keys: Any) -> dict[str, Any]:
    return {"name": name, "shape": "box", "size": [0.1, 0.1, 0.1], **keys}


# --- YAML files -------------------------------------------------------------------------------------------


def test_duplicate_yaml_keys_are_refused_naming_both_positions(tmp_path: Path) -> None:
    path = tmp_path / "problem.yaml"
    text = problem_text([cube("a")])
    path.write_text(text + "objects:\n  - {name: b, shape: sphere, radius: 0.1}\n", encoding="utf-8")
    with pytest.raises(SceneError, match=r"duplicate key 'objects' \(first at line \d+, column 1\)"):
        load_problem(path)
    last = len(text.splitlines()) + 1
    one_error_line(run_cli("solve", str(path)), f"line {last}, column 1", "duplicate key 'objects'")


def test_duplicate_keys_inside_a_mapping_are_refused_and_merge_keys_still_override(tmp_path: Path) -> None:
    path = tmp_path / "scene.yaml"
    path.write_text("objects:\n  - {name: a, shape: box, shape: sphere, radius: 0.1}\n", encoding="utf-8")
    with pytest.raises(SceneError, match="duplicate key 'shape'"):
        load_scene(path)
    merged = "base: &b {shape: box, size: [0.1, 0.1, 0.1]}\n"
    path.write_text(merged + "objects:\n  - {<<: *b, name: a, size: [0.2, 0.2, 0.2]}\n", encoding="utf-8")
    with pytest.raises(SceneError, match="base: unknown key"):  # parsed: the merge is no duplicate
        load_scene(path)


def test_a_fifo_as_a_scene_or_problem_file_is_refused_without_blocking(tmp_path: Path) -> None:
    fifo = tmp_path / "problem.yaml"
    os.mkfifo(fifo)
    with pytest.raises(SceneError, match=r"not a regular file \(a FIFO\)"):
        load_problem(fifo)
    one_error_line(run_cli("solve", str(fifo)), "not a regular file (a FIFO)")
    problem = tmp_path / "uses_fifo.yaml"
    problem.write_text(f"scene: {fifo}\nhypotheses: {{}}\n", encoding="utf-8")
    one_error_line(run_cli("solve", str(problem)), str(fifo), "not a regular file")
    one_error_line(run_cli("solve", str(tmp_path)), "not a regular file (a directory)")


# --- object names -------------------------------------------------------------------------------------------

BAD_NAMES = ["{sub}", "a b", "é", "a.b", "1a", "a/", "/a", "a//b", "~a", "x" * 129]
GOOD_NAMES = ["a", "cube_1", "shelf/cube", "_a", "A__b", "x" * 128]


@pytest.mark.parametrize("name", BAD_NAMES + GOOD_NAMES)
def test_object_names_are_accepted_exactly_when_rclpy_accepts_every_topic_made_of_them(name: str) -> None:
    from rclpy.exceptions import InvalidTopicNameException
    from rclpy.validate_full_topic_name import validate_full_topic_name

    namespace = "/" + "n" * 81  # the longest namespace object names leave room for
    try:
        for topic in derived_topics(name):
            validate_full_topic_name(f"{namespace}/{topics.NODE_NAME}/{topic}")
        # rcl expands "{...}" as a substitution: the node's create_subscription refuses it.
        ros_accepts = "{" not in name and "}" not in name
    except InvalidTopicNameException:
        ros_accepts = False
    assert (object_name_problem(name) is None) == ros_accepts == (name in GOOD_NAMES)


def test_the_derived_topics_are_the_node_s() -> None:
    name = "cube"
    made = {
        topics.poses_topic(name),
        topics.weights_topic(name),
        topics.object_pose_topic(name).removeprefix("~/"),
        topics.object_settled_pose_topic(name).removeprefix("~/"),
    }
    assert made == set(derived_topics(name)) and len(DERIVED_TOPICS) == 4


@pytest.mark.parametrize(("names", "fragment"), [(["{sub}"], "'{' is not allowed"), (["a", "a/weights"], "share")])
def test_names_the_node_cannot_use_are_refused_by_solve_and_the_node_alike(
    tmp_path: Path, names: list[str], fragment: str
) -> None:
    problem = tmp_path / "problem.yaml"
    problem.write_text(problem_text([cube(n) for n in names]), encoding="utf-8")
    one_error_line(run_cli("solve", str(problem)), fragment)
    scene = tmp_path / "scene.yaml"
    scene.write_text(yaml.safe_dump({"objects": [cube(n) for n in names]}), encoding="utf-8")
    node = run_cli("node", "--ros-args", "-p", f"scene_file:={scene}", timeout=60)
    one_error_line(node, fragment)


def test_a_scene_with_more_objects_than_the_cap_is_refused(tmp_path: Path) -> None:
    scene = tmp_path / "scene.yaml"
    scene.write_text(yaml.safe_dump({"objects": [cube(f"c{i}") for i in range(MAX_OBJECTS + 1)]}), encoding="utf-8")
    with pytest.raises(SceneError, match=f"objects: {MAX_OBJECTS + 1} objects \\(at most {MAX_OBJECTS}"):
        load_scene(scene)
    scene.write_text(yaml.safe_dump({"objects": [cube(f"c{i}") for i in range(MAX_OBJECTS)]}), encoding="utf-8")
    assert len(load_scene(scene).objects) == MAX_OBJECTS


# --- meshes ---------------------------------------------------------------------------------------------------


def test_mesh_vertices_beyond_the_coordinate_bound_are_refused(tmp_path: Path) -> None:
    lines = ["v 0 0 0", "v 1e30 0 0", "v 0 1 0", "v 0 0 1", "f 1 2 3", "f 1 2 4", "f 1 3 4", "f 2 3 4"]
    (tmp_path / "far.obj").write_text("\n".join(lines) + "\n", encoding="ascii")
    problem = tmp_path / "problem.yaml"
    problem.write_text(problem_text([{"name": "m", "shape": "mesh", "file": "far.obj"}]), encoding="utf-8")
    line = one_error_line(run_cli("solve", str(problem)), "objects[0].file", "vertex 2 is 1e+30 m", "±1e+07 m")
    assert "trimesh" not in line
    (tmp_path / "near.obj").write_text("\n".join(lines).replace("1e30", "1e4") + "\n", encoding="ascii")
    scaled = {"name": "m", "shape": "mesh", "file": "near.obj", "scale": 1e4}
    problem.write_text(problem_text([scaled]), encoding="utf-8")
    one_error_line(run_cli("solve", str(problem)), "vertex 2 (scaled) is 1e+08 m")


def test_a_mesh_with_more_faces_than_the_cap_is_refused_before_it_is_parsed(tmp_path: Path) -> None:
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n" + "f 1 2 3\n" * (MAX_MESH_FACES + 1)
    (tmp_path / "many.obj").write_text(text, encoding="ascii")
    data = floor_scene_dict(mesh_object("m", "many.obj", mass=0.1))
    with pytest.raises(SceneError, match=f"too many faces: {MAX_MESH_FACES + 1} \\(at most {MAX_MESH_FACES}"):
        load_inline(data, tmp_path)


def test_a_parts_file_with_more_parts_than_the_cap_is_refused(tmp_path: Path) -> None:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    lines = []
    for index in range(MAX_CONVEX_PARTS + 1):
        base = 4 * index
        lines += [f"o p{index}", f"v {index} 0 0", f"v {index + 0.5} 0 0", f"v {index} 0.5 0", f"v {index} 0 0.5"]
        lines += [f"f {base + 1} {base + 2} {base + 3}", f"f {base + 1} {base + 2} {base + 4}"]
    (tmp_path / "parts.obj").write_text("\n".join(lines) + "\n", encoding="ascii")
    data = floor_scene_dict(mesh_object("t", "trough.obj", collision="decomposition", parts="parts.obj", mass=0.4))
    with pytest.raises(SceneError, match=f"objects\\[0\\].parts: .*more than {MAX_CONVEX_PARTS} convex parts"):
        load_inline(data, tmp_path)


# --- masses -----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("keys", "fragment"),
    [
        ({"mass": 1.0e12}, f"mass: must be in [1e-06, {MAX_MASS:g}] kg"),
        ({"mass": 1.0e-9}, "mass: must be in [1e-06"),
        ({"density": 1e-300}, "density: must be in [0.1, 100000] kg/m^3"),
    ],
)
def test_masses_and_densities_outside_the_measured_bounds_are_refused(
    tmp_path: Path, keys: dict[str, float], fragment: str
) -> None:
    shape = cube("c", **keys) if "mass" in keys else {"name": "c", "shape": "mesh", "file": "box.obj", **keys}
    if "density" in keys:
        import trimesh

        write_mesh(trimesh.creation.box((0.1, 0.1, 0.1)), tmp_path / "box.obj")
    problem = tmp_path / "problem.yaml"
    problem.write_text(problem_text([shape]), encoding="utf-8")
    one_error_line(run_cli("solve", str(problem)), "objects[0].", fragment)


def test_a_mass_ratio_bullet_cannot_stack_is_warned(tmp_path: Path) -> None:
    problem = tmp_path / "problem.yaml"
    problem.write_text(problem_text([cube("light", mass=0.01), cube("heavy", mass=1.0)]), encoding="utf-8")
    completed = run_cli("solve", str(problem))
    assert completed.returncode == 0, completed.stderr
    warning = f"heavy (1 kg) is 100 times as heavy as light (0.01 kg): beyond a ratio of {MAX_MASS_RATIO:g}"
    assert completed.stderr.startswith("physics-mapper solve: warning: ") and warning in completed.stderr
    problem.write_text(problem_text([cube("a", mass=0.1), cube("b", mass=1.0)]), encoding="utf-8")
    assert run_cli("solve", str(problem)).stderr == ""


def test_a_mesh_too_large_to_be_in_metres_is_warned_once_per_shape(tmp_path: Path) -> None:
    """A 10 cm box written in centimetres, read without a scale, is a 10 m box: solve warns, once for the two
    instances; given its scale, nothing."""
    import trimesh

    write_mesh(trimesh.creation.box((10.0, 10.0, 10.0)), tmp_path / "box_cm.obj")
    problem = tmp_path / "problem.yaml"
    parts = {"shape": "mesh", "file": "box_cm.obj", "mass": 0.2}
    problem.write_text(problem_text([{"name": "a", **parts}, {"name": "b", **parts}], [5.0, 5.0]), encoding="utf-8")
    completed = run_cli("solve", str(problem))
    assert completed.returncode == 0, completed.stderr
    warning = "a's mesh is 10 m across: if its file is not in metres, give it a scale"
    assert completed.stderr.startswith("physics-mapper solve: warning: ") and completed.stderr.count(warning) == 1
    # A scene file warns alike where a command loads one (generate, replay, evaluate, sweep).
    scene = tmp_path / "scene.yaml"
    document = {
        "static": [{"name": "floor", "shape": "plane"}],
        "objects": [{"name": "a", **parts}],
        "ground_truth": {"a": {"position": [0.0, 0.0, 5.0]}},
    }
    scene.write_text(yaml.safe_dump(document), encoding="utf-8")
    generated = run_cli("generate", str(scene), "-o", str(tmp_path / "bag"), "--iterations", "1", "--particles", "10")
    assert generated.returncode == 0 and f"physics-mapper generate: warning: {scene}: objects: {warning}" in (
        generated.stderr
    )
    parts["scale"] = 0.01
    problem.write_text(problem_text([{"name": "a", **parts}, {"name": "b", **parts}]), encoding="utf-8")
    assert run_cli("solve", str(problem)).stderr == ""


# --- the decomposition cache ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def trough_decomposition(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A trough mesh and its cache file, computed once (V-HACD: a second)."""
    folder = tmp_path_factory.mktemp("trough")
    write_mesh(trough_mesh(), folder / "trough.obj")
    previous = os.environ.get(CACHE_ENVIRONMENT_VARIABLE)
    os.environ[CACHE_ENVIRONMENT_VARIABLE] = str(folder / "cache")
    try:
        scene = load_trough(folder)
    finally:
        os.environ[CACHE_ENVIRONMENT_VARIABLE] = previous or ""
    decomposition = mesh(scene).geometry.decomposition
    assert decomposition is not None and len(decomposition.parts) >= 2
    return folder / "trough.obj", decomposition.file


def load_trough(folder: Path, lines: list[str] | None = None) -> Scene:
    keys = {"collision": "decomposition", "decomposition": {"method": "vhacd"}, "mass": 0.4}
    data = floor_scene_dict(mesh_object("t", folder / "trough.obj", **keys))
    return load_inline(data, folder, (lines if lines is not None else []).append)


def mesh(scene: Scene) -> Mesh:
    shape = scene.objects[0].shape
    assert isinstance(shape, Mesh)
    return shape


def damaged_cache(
    trough_decomposition: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, damage: Any
) -> tuple[Path, int]:
    """This test's cache holding the trough's decomposition file, damaged by ``damage(lines)``; its part count."""
    mesh_file, cached = trough_decomposition
    shutil.copy(mesh_file, tmp_path / "trough.obj")
    monkeypatch.setenv(CACHE_ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))
    target = tmp_path / "cache" / "decompositions" / cached.name
    target.parent.mkdir(parents=True)
    lines = cached.read_text(encoding="ascii").splitlines()
    target.write_text("\n".join(damage(lines)) + "\n", encoding="ascii")
    return target, len(read_cached_parts(cached))


def truncated(lines: list[str]) -> list[str]:
    """The file cut before its last part, as a full disk leaves it: header and checksum intact."""
    last = max(i for i, line in enumerate(lines) if line.startswith("o "))
    return lines[:last]


def with_nan(lines: list[str]) -> list[str]:
    first = next(i for i, line in enumerate(lines) if line.startswith("v "))
    return [*lines[:first], "v nan 0 0", *lines[first + 1 :]]


def flattened(lines: list[str]) -> list[str]:
    """Every vertex of the first part moved into the plane z = 0."""
    end = next(i for i, line in enumerate(lines) if line.startswith("o ") and i > 3)
    flat = [
        " ".join([*line.split()[:3], "0.0"]) if line.startswith("v ") and i < end else line
        for i, line in enumerate(lines)
    ]
    return flat


@pytest.mark.parametrize("damage", [truncated, with_nan, flattened], ids=["truncated", "nan", "flat"])
def test_a_damaged_cache_file_is_recomputed_not_blamed_on_the_mesh(
    trough_decomposition: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, damage: Any
) -> None:
    target, parts = damaged_cache(trough_decomposition, tmp_path, monkeypatch, damage)
    lines: list[str] = []
    decomposition = mesh(load_trough(tmp_path, lines)).geometry.decomposition
    assert decomposition is not None and not decomposition.from_cache and len(decomposition.parts) == parts
    assert len(lines) == 2 and "the cached file was damaged" in lines[0]
    assert len(read_cached_parts(target)) == parts  # replaced by a sound file


def test_a_cache_file_whose_header_miscounts_its_parts_is_recomputed(
    trough_decomposition: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The header's count is checked on its own too: a file cut at a part boundary and re-summed."""
    import hashlib

    def recounted(lines: list[str]) -> list[str]:
        body = truncated(lines)[2:]
        digest = hashlib.sha256(("\n".join(body) + "\n").encode("ascii")).hexdigest()
        return [lines[0], f"# sha256 {digest}", *body]

    damaged_cache(trough_decomposition, tmp_path, monkeypatch, recounted)
    lines: list[str] = []
    load_trough(tmp_path, lines)
    assert "convex parts, its header says" in lines[0]


def test_cache_files_are_written_with_the_user_s_umask(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    write_mesh(trough_mesh(), tmp_path / "trough.obj")
    monkeypatch.setenv(CACHE_ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))
    previous = os.umask(0o022)
    try:
        decomposition = mesh(load_trough(tmp_path)).geometry.decomposition
    finally:
        os.umask(previous)
    assert decomposition is not None
    assert stat.S_IMODE(decomposition.file.stat().st_mode) == 0o644
    assert [p.name for p in decomposition.file.parent.iterdir()] == [decomposition.file.name]  # no temporary left


# --- outputs on a full disk ----------------------------------------------------------------------------------


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 256 KiB tmpfs mounted for the test: writes beyond it fail with ENOSPC, as on a full disk."""
    folder = tmp_path / "disk"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(folder)], check=False)
    assert mounted.returncode == 0, "mounting a tmpfs needs root (the test suite runs as root here)"
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def fill(disk: Path, leave: int = 0) -> None:
    """Fill the disk with a file as large as it takes (the write stops at ENOSPC), then free ``leave`` bytes."""
    descriptor = os.open(disk / "filler", os.O_WRONLY | os.O_CREAT, 0o644)
    try:
        while os.write(descriptor, b"\0" * 4096):
            pass
    except OSError:
        pass
    finally:
        os.close(descriptor)
    if leave:
        os.truncate(disk / "filler", max(0, (disk / "filler").stat().st_size - leave))


def test_solve_trace_and_json_onto_a_full_disk_leave_the_previous_files_and_no_empty_ones(small_disk: Path) -> None:
    trace = small_disk / "trace.json"
    trace.write_text('["previous"]\n', encoding="utf-8")
    fill(small_disk)
    one_error_line(run_cli("solve", str(PYRAMID_PROBLEM), "--trace", str(trace)), f"cannot write {trace}")
    assert trace.read_text(encoding="utf-8") == '["previous"]\n'
    new = small_disk / "new.json"
    one_error_line(run_cli("solve", str(PYRAMID_PROBLEM), "--trace", str(new)), "No space left on device")
    assert sorted(p.name for p in small_disk.iterdir()) == ["filler", "trace.json"]  # no 0-byte file, no temporary


def test_solve_json_onto_a_full_stdout_is_one_error_line() -> None:
    with open("/dev/full", "w") as full:
        completed = subprocess.run(
            [str(REPO / ".venv" / "bin" / "physics-mapper"), "solve", str(PYRAMID_PROBLEM), "--json"],
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
            check=False,
        )
    one_error_line(completed, "cannot write to standard output: No space left on device")


def generate_bag(path: Path, runs: int = 1) -> subprocess.CompletedProcess[str]:
    scene = REPO / "config" / "scenes" / "pyramid.yaml"
    arguments = ["--runs", str(runs), "--iterations", "2", "--top-m", "3", "--particles", "50", "--seed", "1"]
    return run_cli("generate", str(scene), "-o", str(path), *arguments)


def test_a_bag_written_onto_a_full_disk_leaves_nothing_behind(small_disk: Path) -> None:
    fill(small_disk, leave=32 * 1024)  # room for a few runs, not for 40
    completed = generate_bag(small_disk / "out", runs=40)
    last_error_line(completed, "cannot write bag", "No space left on device")
    assert "run 1/40 written" in completed.stderr  # it failed while writing, not before
    assert [p.name for p in small_disk.iterdir()] == ["filler"]  # no partial bag without metadata, no temporary


def test_evaluate_onto_a_full_disk_leaves_the_previous_report_intact(small_disk: Path, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    assert generate_bag(bag).returncode == 0
    scene = REPO / "config" / "scenes" / "pyramid.yaml"
    report = small_disk / "report"
    arguments = ["evaluate", str(bag), "--scene", str(scene), "--workers", "0", "-o", str(report)]
    assert run_cli(*arguments).returncode == 0
    before = {p.name: p.read_bytes() for p in report.iterdir() if not p.name.startswith(".")}
    assert {"report.json", "report.md", "report.png"} <= set(before)
    json.loads(before["report.json"])
    fill(small_disk)
    last_error_line(run_cli(*arguments), f"cannot write the report into {report}", "previous files are untouched")
    after = {p.name: p.read_bytes() for p in report.iterdir() if not p.name.startswith(".")}
    assert after == before


def test_a_second_writer_into_a_report_folder_is_refused(tmp_path: Path) -> None:
    assert generate_bag(tmp_path / "bag").returncode == 0
    report = tmp_path / "report"
    report.mkdir()
    holder = lock_report_folder(report, "evaluate")  # as a running evaluate holds it
    try:
        with pytest.raises(InputError, match="in use by physics-mapper evaluate"):
            lock_report_folder(report, "sweep")
        scene = REPO / "config" / "scenes" / "pyramid.yaml"
        completed = run_cli(
            "evaluate", str(tmp_path / "bag"), "--scene", str(scene), "--workers", "0", "-o", str(report)
        )
        last_error_line(completed, f"{report} is in use by physics-mapper evaluate (pid {os.getpid()})")
    finally:
        holder.close()
    lock_report_folder(report, "evaluate").close()  # released: the next run may write


def test_meshes_at_the_limits_still_load(tmp_path: Path) -> None:
    """The bounds refuse what they must and no more: a 1e7 m vertex, and a mass at the bound."""
    lines = ["v 0 0 0", "v 1e7 0 0", "v 0 1 0", "v 0 0 1", "f 1 2 3", "f 1 2 4", "f 1 3 4", "f 2 3 4"]
    (tmp_path / "edge.obj").write_text("\n".join(lines) + "\n", encoding="ascii")
    scene = load_inline(floor_scene_dict(mesh_object("m", "edge.obj", mass=MAX_MASS)), tmp_path)
    assert np.isclose(mesh(scene).geometry.bounds[1][0], 1e7)


# --- pairwise work on hypotheses ------------------------------------------------------------------------------


def test_box_overlaps_compared_in_chunks_agree_with_the_whole_comparison(monkeypatch: pytest.MonkeyPatch) -> None:
    from physics_mapper.search import groups

    rng = np.random.default_rng(3)
    for trial in range(200):
        lows_a, lows_b = (
            rng.uniform(-1.0, 1.0, size=(int(rng.integers(1, 40)), 3)),
            rng.uniform(-1.0, 1.0, size=(30, 3)),
        )
        highs_a, highs_b = (
            lows_a + rng.uniform(0.0, 0.2, size=lows_a.shape),
            lows_b + rng.uniform(0.0, 0.2, size=(30, 3)),
        )
        meets = (lows_a[:, None, :] <= highs_b[None, :, :]) & (highs_a[:, None, :] >= lows_b[None, :, :])
        whole = bool(np.any(np.all(meets, axis=2)))
        monkeypatch.setattr(groups, "PAIRS_PER_CHUNK", int(rng.integers(1, 100)))
        assert groups._boxes_meet(lows_a, highs_a, lows_b, highs_b) == whole, trial


def test_a_search_takes_at_most_the_hard_cap_of_hypotheses_per_object() -> None:
    from physics_mapper.model.geometry import Pose
    from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
    from physics_mapper.model.limits import MAX_SEARCHED_HYPOTHESES
    from physics_mapper.physics.checker import PhysicsChecker
    from physics_mapper.search.strategy import make_search

    problem = load_problem(PYRAMID_PROBLEM)
    many = MAX_SEARCHED_HYPOTHESES * 3
    hypotheses = [
        RankedHypotheses.from_weighted(
            [Hypothesis(Pose((0.001 * i, 0.0, 0.1 + 0.3 * o)), 1.0 + i) for i in range(many)]
        )
        for o in range(len(problem.scene.objects))
    ]
    with PhysicsChecker(problem.scene) as checker:
        search = make_search(checker, hypotheses, problem.scene.search)
        kept = search.hypotheses
    assert [len(ranked) for ranked in kept] == [MAX_SEARCHED_HYPOTHESES] * len(hypotheses)
    assert kept[0].pose(1) == hypotheses[0].pose(1) and abs(sum(h.weight for h in kept[0].hypotheses) - 1.0) < 1e-9

"""Every refusal path of the command line, under ``LC_ALL=C``: exit 2, an error line naming the problem, no
traceback, and no control character on stderr but line breaks, whatever bytes the input names hold.

The cases are the commands' own checks of their arguments and the files they read or write, with file
and bag names made to hurt a terminal (ESC, BEL, a line break forging an error line, bytes that are not
UTF-8).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from conftest import PROBLEMS, SCENES
from ros_helpers import PHYSICS_MAPPER

from physics_mapper.model.errors import EXIT_BAD_INPUT
from physics_mapper.ros.run_node import MAX_PARAMS_FILE_BYTES

REPO = Path(__file__).resolve().parents[2]
PYRAMID_BAG = REPO / "test" / "data" / "pyramid"
PYRAMID_SCENE = SCENES / "pyramid.yaml"
PYRAMID_PROBLEM = PROBLEMS / "pyramid.yaml"
HOSTILE = "x\x1b[2J\x07\nphysics-mapper solve: error: forged"
#: Any control character but a line break (C0, DEL, C1).
CONTROL = re.compile(r"[\x00-\x09\x0b-\x1f\x7f-\x9f]")


def problem_with_mesh(folder: Path, mesh: str) -> Path:
    """A problem file of one mesh object whose file is ``mesh``."""
    scene = (
        "static:\n  - {name: floor, shape: plane}\n"
        f"objects:\n  - {{name: m, shape: mesh, file: {mesh!r}, mass: 0.1}}\n"
        "hypotheses:\n  m:\n    - {position: [0, 0, 0.1], weight: 1.0}\n"
    )
    path = folder / f"mesh_{len(list(folder.iterdir()))}.yaml"
    path.write_text(scene, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """The hostile files the cases name, made once."""
    folder = tmp_path_factory.mktemp("refusals")
    (folder / "loop.obj").symlink_to(folder / "loop.obj")
    (folder / "plain").write_text("a file, not a folder\n", encoding="utf-8")
    hostile_yaml = folder / f"{HOSTILE}.yaml"
    hostile_yaml.write_text("objects: [\x1b]2;title\x07\n", encoding="utf-8")
    not_utf8 = os.fsdecode(bytes(folder) + b"/caf\xe9\x1b.yaml")
    Path(not_utf8).write_bytes(b"objects: [\xff\n")
    locked = folder / "locked"
    locked.mkdir()
    bag_without_metadata = folder / f"{HOSTILE}_bag"
    bag_without_metadata.mkdir()
    (bag_without_metadata / "x.mcap").write_bytes(b"\x89MCAP0\r\n")
    empty_list_params = folder / "empty_list.yaml"
    empty_list_params.write_text(f"/**:\n  ros__parameters:\n    scene_file: {PYRAMID_SCENE}\n    frames: []\n")
    large_params = folder / "large.yaml"
    entries = "".join(f"    unknown_{i}: {i}\n" for i in range(MAX_PARAMS_FILE_BYTES // 14))
    large_params.write_text(f"/**:\n  ros__parameters:\n{entries}", encoding="utf-8")
    big_metadata = Path(shutil.copytree(PYRAMID_BAG, folder / "big_metadata"))
    with (big_metadata / "metadata.yaml").open("a", encoding="utf-8") as metadata:
        metadata.write(f"# {'x' * (1 << 20)}\n")
    return {
        "folder": str(folder),
        "loop_mesh": str(problem_with_mesh(folder, "loop.obj")),
        "file_as_folder_mesh": str(problem_with_mesh(folder, "plain/m.obj")),
        "outside_package": str(problem_with_mesh(folder, "package://physics_mapper/../../../etc/hostname")),
        "hostile_yaml": str(hostile_yaml),
        "not_utf8": not_utf8,
        "hostile_missing": str(folder / HOSTILE),
        "plain": str(folder / "plain"),
        "bag_without_metadata": str(bag_without_metadata),
        "big_metadata": str(big_metadata),
        "empty_list_params": str(empty_list_params),
        "large_params": str(large_params),
    }


#: ``sweep`` of the shipped bag on its scene (``evaluate`` takes the same after its name).
BATCH = ["sweep", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE)]
#: (arguments with {placeholders} of the ``files`` fixture, a fragment of the error line).
CASES: dict[str, tuple[list[str], str]] = {
    "solve: missing problem, hostile name": (["solve", "{hostile_missing}"], "x\\x1b[2J\\x07\\nphysics-mapper"),
    "solve: hostile YAML": (["solve", "{hostile_yaml}"], "\\x1b"),
    "solve: not UTF-8": (["solve", "{not_utf8}"], "not UTF-8"),
    "solve: mesh symlink loop": (["solve", "{loop_mesh}"], "loop.obj: a symbolic link loop"),
    "solve: mesh below a file": (["solve", "{file_as_folder_mesh}"], "a part of its path is a file, not a folder"),
    "solve: package:// leaving its folder": (["solve", "{outside_package}"], "must stay inside the package's folder"),
    "solve: trace below a file": (
        ["solve", str(PYRAMID_PROBLEM), "--trace", "{plain}/t.json"],
        "folder {plain} is a file, not a folder",
    ),
    "solve: trace onto a folder": (["solve", str(PYRAMID_PROBLEM), "--trace", "{folder}"], "Is a directory"),
    "solve: no problem (argparse)": (["solve"], "the following arguments are required: problem"),
    "replay: --tail nan": (["replay", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--tail", "nan"], "--tail"),
    "replay: --wait nan": (["replay", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--wait", "nan"], "--wait"),
    "replay: --wait -1": (["replay", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--wait", "-1"], "--wait"),
    "replay: --rate inf": (["replay", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--rate", "inf"], "--rate"),
    "replay: --start-node offline": (
        ["replay", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--offline", "--start-node"],
        "--start-node is for a live replay",
    ),
    "replay: bag without metadata": (
        ["replay", "{bag_without_metadata}", "--scene", str(PYRAMID_SCENE), "--offline"],
        "no metadata.yaml",
    ),
    "replay: metadata.yaml too large": (
        ["replay", "{big_metadata}", "--scene", str(PYRAMID_SCENE), "--offline"],
        "metadata.yaml has",
    ),
    "replay: long namespace": (
        ["replay", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--namespace", "/" + "n" * 5000],
        "--namespace",
    ),
    "evaluate: --workers beyond the ceiling": (
        ["evaluate", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--workers", "100000", "-o", "{folder}/e"],
        "--workers must be at most 64",
    ),
    "evaluate: --workers -1": (
        ["evaluate", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--workers", "-1", "-o", "{folder}/e"],
        "--workers must not be negative",
    ),
    "evaluate: missing bag, hostile name": (
        ["evaluate", "{hostile_missing}", "--scene", str(PYRAMID_SCENE), "-o", "{folder}/e"],
        "no such file or folder",
    ),
    "evaluate: output is a file": (
        ["evaluate", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "-o", "{plain}"],
        "exists and is not a folder",
    ),
    "evaluate: --set unknown key": (
        ["evaluate", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--set", "bogus\x1b=1", "-o", "{folder}/e"],
        "unknown key",
    ),
    "sweep: --grid repeated value": (
        ["sweep", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--grid", "deadline=0.1,0.1", "-o", "{folder}/s"],
        "a value is repeated",
    ),
    "generate: no ground truth": (["generate", "{hostile_yaml}", "-o", "{folder}/g"], "\\x1b"),
    "generate: --period nan": (["generate", str(PYRAMID_SCENE), "-o", "{folder}/g", "--period", "nan"], "--period"),
    "sweep: --grid key twice": (
        [*BATCH, "--grid", "deadline=0.1", "--grid", "deadline=0.2", "-o", "{folder}/s"],
        "--grid deadline is given twice",
    ),
    "evaluate: --set key twice": (
        ["evaluate", *BATCH[1:], "--set", "deadline=0.1", "--set", "deadline=1", "-o", "{folder}/e"],
        "--set deadline is given twice",
    ),
    "evaluate: --set bad value": (
        ["evaluate", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--set", "deadline=\x1b", "-o", "{folder}/e"],
        "--set deadline: not valid YAML: unacceptable character #x001b",
    ),
    "evaluate: --set without =": (
        ["evaluate", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--set", "rate\n", "-o", "{folder}/e"],
        "expected KEY=VALUE",
    ),
    "experiment: --seed -1": (["experiment", "fig4", "--seed", "-1", "-o", "{folder}/x"], "--seed must not be"),
    "experiment: --search-budget 0": (["experiment", "fig4", "--search-budget", "0", "-o", "{folder}/x"], "budget"),
    "publish: --count -1": (["publish", str(PYRAMID_PROBLEM), "--count", "-1"], "--count must not be negative"),
    "replay: --topics offline": (
        ["replay", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--offline", "--topics", "/x"],
        "are for a live replay",
    ),
    "replay: --deadline live": (
        ["replay", str(PYRAMID_BAG), "--scene", str(PYRAMID_SCENE), "--deadline", "1"],
        "--deadline is for --offline",
    ),
    "publish: --rate 0": (["publish", str(PYRAMID_PROBLEM), "--rate", "0"], "--rate must be positive"),
    "publish: bad namespace": (["publish", str(PYRAMID_PROBLEM), "--namespace", "/a\nb"], "--namespace"),
    "publish: long namespace": (["publish", str(PYRAMID_PROBLEM), "--namespace", "/" + "n" * 5000], "characters)"),
    "experiment: --runs 0": (["experiment", "fig4", "--runs", "0", "-o", "{folder}/x"], "--runs must be at least 1"),
    "bench: --repeats 0": (["bench", "physics_costs", "--repeats", "0"], "--repeats must be at least 1"),
    "decompose: hostile scene": (["decompose", "{hostile_yaml}"], "\\x1b"),
    "node: no scene_file": (["node"], "parameter scene_file is required"),
    "node: unreadable params file, hostile name": (
        ["node", "--ros-args", "--params-file", "{hostile_missing}"],
        "x\\x1b[2J\\x07\\nphysics-mapper",
    ),
    "node: params file with an empty list": (
        ["node", "--ros-args", "--params-file", "{empty_list_params}"],
        "an empty list ([]): ROS cannot declare it",
    ),
    "node: params file too large": (["node", "--ros-args", "--params-file", "{large_params}"], "bytes in all"),
    "node: namespace too long": (
        ["node", "--ros-args", "-p", f"scene_file:={PYRAMID_SCENE}", "-r", "__ns:=/" + "n" * 300],
        "cannot create the node: invalid node namespace",
    ),
    "node: name too long": (
        ["node", "--managed", "--ros-args", "-r", "__node:=" + "n" * 300],
        "cannot create the node: invalid node name",
    ),
    "unknown command (argparse)": (["bogus\x1b"], "invalid choice"),
}


@pytest.mark.parametrize("case", CASES)
def test_every_refusal_is_an_escaped_error_line_exit_2_under_lc_all_c(files: dict[str, str], case: str) -> None:
    arguments, fragment = CASES[case]
    command = [str(PHYSICS_MAPPER), *(argument.format(**files) for argument in arguments)]
    environment = {**os.environ, "LC_ALL": "C"}
    completed = subprocess.run(command, capture_output=True, timeout=120, env=environment, check=False)
    stderr = completed.stderr.decode("utf-8")  # strict: whatever the locale, what is written decodes
    assert completed.returncode == EXIT_BAD_INPUT, stderr
    assert "Traceback" not in stderr and not CONTROL.search(stderr), stderr
    error_lines = [line for line in stderr.splitlines() if "error: " in line]
    assert len(error_lines) == 1 and fragment.format(**files) in error_lines[0], stderr
    assert not any(line.startswith("physics-mapper solve: error: forged") for line in stderr.splitlines())
    assert all(len(line) < 600 for line in error_lines), stderr  # input quoted clipped, never whole
    assert not (Path(files["folder"]) / "e").exists() and not (Path(files["folder"]) / "s").exists()

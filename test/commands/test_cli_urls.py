"""Every command that reads a scene or problem file takes a ``package://`` URL, as the node's scene_file does."""

from __future__ import annotations

import json

import pytest
from conftest import PROBLEMS, SCENES

from physics_mapper.cli import build_parser, main

PYRAMID_SCENE_URL = "package://physics_mapper/config/scenes/pyramid.yaml"


@pytest.mark.parametrize(
    "arguments",
    [
        ["replay", "bag", "--scene", PYRAMID_SCENE_URL],
        ["evaluate", "bag", "--scene", PYRAMID_SCENE_URL],
        ["sweep", "bag", "--scene", PYRAMID_SCENE_URL, "--grid", "deadline=0.1,0.2"],
        ["generate", PYRAMID_SCENE_URL, "-o", "out"],
        ["decompose", PYRAMID_SCENE_URL],
        ["demo", "--scene", PYRAMID_SCENE_URL],
    ],
    ids=lambda arguments: arguments[0],
)
def test_a_scene_url_names_the_shipped_file(arguments: list[str]) -> None:
    args = build_parser().parse_args(arguments)
    scene = args.scene if arguments[0] != "decompose" else args.scenes[0]
    assert scene.samefile(SCENES / "pyramid.yaml")


def test_solve_takes_a_problem_url_and_solves_the_same_problem(capsys: pytest.CaptureFixture[str]) -> None:
    answers = []
    for problem in ("package://physics_mapper/config/problems/pyramid.yaml", str(PROBLEMS / "pyramid.yaml")):
        assert main(["solve", problem, "--json"]) == 0
        result = json.loads(capsys.readouterr().out)
        answers.append((result["code"], result["valid"], result["stats"]["visited"]))
    assert answers[0] == answers[1]


def test_an_unknown_package_is_one_error_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["solve", "package://no_such_package/problem.yaml"])
    assert exit_info.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert error.startswith("physics-mapper solve: error: argument problem: package://no_such_package/problem.yaml")

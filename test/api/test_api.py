"""The package's top-level Python API: a few names, imported on first use, that solve a problem in five lines."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest
from conftest import PROBLEMS, REPO

import physics_mapper as pm
from physics_mapper.cli import main


def test_every_public_name_resolves_and_nothing_else_does() -> None:
    assert all(getattr(pm, name) is not None for name in pm.__all__)
    assert set(pm.__all__) <= set(dir(pm))
    with pytest.raises(AttributeError, match="no attribute 'nothing_here'"):
        _ = pm.nothing_here


def test_importing_the_package_loads_neither_numpy_nor_pybullet() -> None:
    code = "import sys, physics_mapper; print(sorted({'numpy', 'pybullet'} & set(sys.modules)))"
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60)
    assert completed.stdout.strip() == "[]"


def docstring_example() -> str:
    """The package docstring's ``::`` code block, dedented."""
    block = (pm.__doc__ or "").split("::\n\n", 1)[1]
    lines = []
    for line in block.splitlines():
        if line and not line.startswith("    "):
            break
        lines.append(line)
    return textwrap.dedent("\n".join(lines))


def test_the_docstring_example_solves_as_the_command_line_does(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(REPO)
    exec(compile(docstring_example(), "physics_mapper.__doc__", "exec"), {})  # the package's own example
    printed = capsys.readouterr().out.strip()
    assert main(["solve", str(PROBLEMS / "pyramid.yaml"), "--json"]) == 0
    expected = json.loads(capsys.readouterr().out)
    assert expected["stats"]["exhausted"]  # the problem's deadline lets both searches finish: same answer
    assert printed == f"{tuple(expected['code'])} {expected['valid']} {expected['probability']} {expected['jitter']}"

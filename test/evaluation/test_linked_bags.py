"""A bag that is a symbolic link in a folder of bags is evaluated, as the bag it points at; a link back up
the tree is walked once."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import SCENES
from ros_helpers import run_cli

REPO = Path(__file__).resolve().parents[2]


def test_a_symlinked_bag_is_evaluated_and_a_loop_walked_once(tmp_path: Path) -> None:
    bags = tmp_path / "bags"
    bags.mkdir()
    (bags / "pyramid").symlink_to(REPO / "test" / "data" / "pyramid")
    (bags / "up").symlink_to(bags)  # a loop
    report = tmp_path / "report"
    arguments = ["evaluate", str(bags), "--scene", str(SCENES / "pyramid.yaml"), "--workers", "0", "-o", str(report)]
    completed = run_cli(*arguments)
    assert completed.returncode == 0, completed.stderr
    data = json.loads((report / "report.json").read_text(encoding="utf-8"))
    assert [bag["path"] for bag in data["bags"]] == [str(bags / "pyramid")]
    assert data["counts"]["evaluated"] == 1

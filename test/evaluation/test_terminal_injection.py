"""Input-controlled text never reaches a terminal or a report unescaped: a bag folder named with ESC, BEL
and a line break forging an error line shows as one escaped name in the progress lines and in ``report.md``,
whether the bag is evaluated or unreadable."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from conftest import SCENES
from ros_helpers import run_cli

from physics_mapper.model.errors import EXIT_INCOMPLETE

REPO = Path(__file__).resolve().parents[2]
FORGED = "physics-mapper evaluate: error: forged"
HOSTILE_NAME = f"bag\x1b[31m\x07\n{FORGED}"
#: Any control character but a line break (C0, DEL, C1).
CONTROL = re.compile(r"[\x00-\x09\x0b-\x1f\x7f-\x9f]")


def test_a_hostile_bag_name_is_escaped_on_stderr_and_in_the_report(tmp_path: Path) -> None:
    bags = tmp_path / "bags"
    shutil.copytree(REPO / "test" / "data" / "pyramid", bags / "good")
    shutil.copytree(bags / "good", bags / HOSTILE_NAME)  # evaluated: named in its progress line
    unreadable = shutil.copytree(bags / "good", bags / f"{HOSTILE_NAME}.2")  # named in the report's table
    (unreadable / "metadata.yaml").write_text("rosbag2_bagfile_information: [\x1b]2;title\x07\n", encoding="utf-8")
    report = tmp_path / "report"
    arguments = ["evaluate", str(bags), "--scene", str(SCENES / "pyramid.yaml"), "--workers", "0", "-o", str(report)]
    completed = run_cli(*arguments, "--progress", "lines")
    assert completed.returncode == EXIT_INCOMPLETE, completed.stderr
    markdown = (report / "report.md").read_text(encoding="utf-8")
    for text in (completed.stderr, completed.stdout, markdown):
        assert not CONTROL.search(text), text
        assert not any(line.startswith(FORGED) for line in text.splitlines()), text
    assert "bag\\x1b[31m\\x07\\nphysics-mapper" in markdown  # the name, escaped as in a Python literal
    assert "bag\\x1b[31m\\x07\\nphysics-mapper" in completed.stderr

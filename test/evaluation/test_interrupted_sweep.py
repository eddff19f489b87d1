"""An interrupted sweep's parameters file says of how many settings it is the best, and that the run was
interrupted; it is renamed into place with the report, never before. A large grid's report is drawn
without what made it slow (a label on every heat-map cell), so an interrupted sweep writes it at once."""

from __future__ import annotations

import json
import re
import signal
import subprocess
from pathlib import Path
from typing import Any

from conftest import SCENES
from ros_helpers import PHYSICS_MAPPER, run_cli

from physics_mapper.evaluation.plots import MAX_LABELLED_CELLS, MAX_TICK_LABELS, sweep_figure
from physics_mapper.model.errors import EXIT_INTERRUPTED

SETTINGS = 40
#: A large grid's side: LARGE_SIDE x LARGE_SIDE settings, more cells than a heat map labels.
LARGE_SIDE = 40


def interrupted_sweep(tmp_path: Path, grid: list[str], settings: int) -> dict[str, Any]:
    """``sweep`` over ``grid`` (``settings`` settings) on a two-snapshot bag, SIGTERM after its second
    task: its exit code checked, its ``sweep.json`` returned."""
    scene = SCENES / "pyramid.yaml"
    bag = tmp_path / "bag"
    generated = run_cli("generate", str(scene), "-o", str(bag), "--iterations", "2", "--particles", "30")
    assert generated.returncode == 0, generated.stderr
    command = [str(PHYSICS_MAPPER), "sweep", str(bag), "--scene", str(scene), "--workers", "0"]
    command += [*grid, "--progress", "lines", "-o", str(tmp_path / "sweep")]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stderr is not None
    seen = []
    for line in process.stderr:
        seen.append(line)
        if line.startswith(f"sweep: 2/{settings} "):
            process.send_signal(signal.SIGTERM)
            break
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == EXIT_INTERRUPTED, "".join(seen) + stderr
    data: dict[str, Any] = json.loads((tmp_path / "sweep" / "sweep.json").read_text(encoding="utf-8"))
    return data


def test_sigterm_during_a_sweep_gives_a_parameters_file_of_what_finished(tmp_path: Path) -> None:
    thresholds = ",".join(f"{0.01 + 0.001 * i:.3f}" for i in range(SETTINGS))
    data = interrupted_sweep(tmp_path, ["--grid", f"jitter_threshold={thresholds}"], SETTINGS)
    output = tmp_path / "sweep"
    finished = sum(1 for setting in data["settings"] if setting["complete"])
    assert data["interrupted"] and 2 <= finished < SETTINGS
    first = (output / "best_params.yaml").read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith(
        f"# physics-mapper sweep: the best of {finished} of {SETTINGS} search settings (interrupted"
    )


def test_sigterm_during_a_large_sweep_leaves_a_complete_report_of_what_finished(tmp_path: Path) -> None:
    jitter = ",".join(f"{0.01 + 0.0001 * i:.4f}" for i in range(LARGE_SIDE))
    angular = ",".join(f"{0.1 + 0.001 * i:.3f}" for i in range(LARGE_SIDE))
    settings = LARGE_SIDE * LARGE_SIDE
    grid = ["--grid", f"jitter_threshold={jitter}", "--grid", f"angular_weight={angular}"]
    data = interrupted_sweep(tmp_path, grid, settings)
    output = tmp_path / "sweep"
    finished = [setting["index"] for setting in data["settings"] if setting["complete"]]
    assert data["interrupted"] and len(data["settings"]) == settings and 2 <= len(finished) < settings
    assert all(data["settings"][index]["overall"] is not None for index in finished)
    assert data["best"] is not None and data["best"]["index"] in finished
    markdown = (output / "sweep.md").read_text(encoding="utf-8")
    assert markdown.startswith(f"# Sweep (interrupted: partial) of {settings} search settings")
    rows = re.findall(r"^\| (\d+)(?: \*\*best\*\*)?( \(incomplete\))? \|", markdown, flags=re.MULTILINE)
    assert [int(index) for index, _ in rows] == list(range(settings))
    assert [int(index) for index, incomplete in rows if not incomplete] == finished
    assert (output / "sweep.png").read_bytes().startswith(b"\x89PNG")
    first = (output / "best_params.yaml").read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith(f"# physics-mapper sweep: the best of {len(finished)} of {settings} search settings")


def heat_map_data(side: int) -> dict[str, Any]:
    """A sweep report's data over a ``side`` x ``side`` grid, every setting finished."""
    values = [0.01 * (i + 1) for i in range(side)]
    settings = [
        {
            "index": side * r + c,
            "varied": {"a": row, "b": column},
            "overall": {"map_error_m": {"settled_or_top": 0.001 * (r + c)}, "valid_share": 0.5},
        }
        for (r, row) in enumerate(values)
        for (c, column) in enumerate(values)
    ]
    return {"grid": {"a": values, "b": values}, "settings": settings, "best": {"index": 0}}


def test_a_large_grid_heat_map_has_no_cell_labels_and_few_tick_labels() -> None:
    small, large = 4, LARGE_SIDE
    assert small * small <= MAX_LABELLED_CELLS < large * large
    labelled = sweep_figure(heat_map_data(small)).axes
    assert sum(len(axes.texts) for axes in labelled) == 2 * small * small  # the two maps, every cell
    unlabelled = [axes for axes in sweep_figure(heat_map_data(large)).axes if axes.images]
    assert len(unlabelled) == 2 and all(not axes.texts for axes in unlabelled)
    for axes in unlabelled:
        assert 2 <= len(axes.get_xticks()) <= MAX_TICK_LABELS and 2 <= len(axes.get_yticks()) <= MAX_TICK_LABELS
        assert axes.get_xticklabels()[0].get_text() == "0.01"

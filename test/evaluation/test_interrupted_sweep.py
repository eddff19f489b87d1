"""An interrupted sweep's parameters file says of how many settings it is the best, and that the run was
interrupted; it is renamed into place with the report, never before."""

from __future__ import annotations

import json
import signal
import subprocess
from pathlib import Path

from conftest import SCENES
from ros_helpers import PHYSICS_MAPPER, run_cli

from physics_mapper.model.errors import EXIT_INTERRUPTED

SETTINGS = 40


def test_sigterm_during_a_sweep_gives_a_parameters_file_of_what_finished(tmp_path: Path) -> None:
    scene = SCENES / "pyramid.yaml"
    bag = tmp_path / "bag"
    generated = run_cli("generate", str(scene), "-o", str(bag), "--iterations", "2", "--particles", "30")
    assert generated.returncode == 0, generated.stderr
    thresholds = ",".join(f"{0.01 + 0.001 * i:.3f}" for i in range(SETTINGS))
    output = tmp_path / "sweep"
    command = [str(PHYSICS_MAPPER), "sweep", str(bag), "--scene", str(scene), "--workers", "0"]
    command += ["--grid", f"jitter_threshold={thresholds}", "--progress", "lines", "-o", str(output)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stderr is not None
    seen = []
    for line in process.stderr:
        seen.append(line)
        if line.startswith(f"sweep: 2/{SETTINGS} "):
            process.send_signal(signal.SIGTERM)
            break
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == EXIT_INTERRUPTED, "".join(seen) + stderr
    data = json.loads((output / "sweep.json").read_text(encoding="utf-8"))
    finished = sum(1 for setting in data["settings"] if setting["complete"])
    assert data["interrupted"] and 2 <= finished < SETTINGS
    first = (output / "best_params.yaml").read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith(
        f"# physics-mapper sweep: the best of {finished} of {SETTINGS} search settings (interrupted"
    )

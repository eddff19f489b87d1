"""How fast an interrupted large sweep stops: SIGTERM to ``sweep`` over a 10,000-setting grid.

Run: ``.venv/bin/python benchmarks/interrupted_sweep.py [--runs 3] [--settings 10000] [--workers 0]``.
A two-iteration bag of the pyramid scene is generated, then ``sweep`` runs over a grid of
``jitter_threshold`` (100 values) x ``angular_weight`` (settings / 100 values); after its 20th
finished task it gets SIGTERM. Printed: the seconds from the signal until the process has exited
(median / max, the interrupted report written in between), its exit codes, and how many settings
the report counts as finished. Beside it the same for a 100-setting grid, for scale.
"""

from __future__ import annotations

import argparse
import json
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PHYSICS_MAPPER = Path(sys.executable).parent / "physics-mapper"
SCENE = Path(__file__).resolve().parent.parent / "config" / "scenes" / "pyramid.yaml"
#: Finished tasks before the signal.
TASKS_BEFORE_SIGNAL = 20


def grid(settings: int) -> list[str]:
    """``--grid`` arguments of ``settings`` settings (a multiple of 100), 100 values of the first key."""
    jitter = ",".join(f"{0.01 + 0.00001 * i:.5f}" for i in range(100))
    angular = ",".join(f"{0.1 + 0.001 * i:.3f}" for i in range(settings // 100))
    return ["--grid", f"jitter_threshold={jitter}", "--grid", f"angular_weight={angular}"]


def stop_once(bag: Path, output: Path, settings: int, workers: int) -> tuple[float, int, int]:
    """Seconds from SIGTERM to exit, the exit code, and the settings the report counts as finished."""
    command = [str(PHYSICS_MAPPER), "sweep", str(bag), "--scene", str(SCENE), "--workers", str(workers)]
    command += [*grid(settings), "--progress", "lines", "-o", str(output)]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert process.stderr is not None
    for line in process.stderr:
        if line.startswith(f"sweep: {TASKS_BEFORE_SIGNAL}/"):
            break
    start = time.monotonic()
    process.send_signal(signal.SIGTERM)
    process.communicate()
    elapsed = time.monotonic() - start
    data = json.loads((output / "sweep.json").read_text(encoding="utf-8"))
    return elapsed, process.returncode, sum(1 for setting in data["settings"] if setting["complete"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="interrupted sweeps per grid (default: 3)")
    parser.add_argument("--settings", type=int, default=10000, help="grid size, a multiple of 100")
    parser.add_argument("--workers", type=int, default=0, help="sweep's --workers (0: in the command's process)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        bag = Path(folder) / "bag"
        command = [str(PHYSICS_MAPPER), "generate", str(SCENE), "-o", str(bag), "--iterations", "2"]
        subprocess.run([*command, "--particles", "30"], check=True, capture_output=True)
        for settings in (100, args.settings):
            runs = [stop_once(bag, Path(folder) / f"out{settings}", settings, args.workers) for _ in range(args.runs)]
            seconds = [elapsed for elapsed, _, _ in runs]
            print(
                f"{settings:6d} settings, --workers {args.workers}: SIGTERM to exit {statistics.median(seconds):.2f} s "
                f"median, {max(seconds):.2f} s max; exit codes {sorted({code for _, code, _ in runs})}; "
                f"finished settings in the report {[finished for _, _, finished in runs]}"
            )


if __name__ == "__main__":
    main()

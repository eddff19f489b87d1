"""Live replay of the shipped pyramid bag against offline search: what the timed live searches find at each speed.

The figures ``make demo`` and the live replay tests used to assert: the
node's searches are timed, so which snapshots get a configuration, and which, depends on the
machine and the replay speed. Per ``--rate``, the bag is replayed live into a node started for
it (default parameters: 2 Hz, deadline 0.2 s), and compared with the offline ``--exhaustive``
replay: snapshots with a configuration, codes equal to the offline ones, and the mean total
position error of C111, the chosen and the settled poses. The last row is the live
``--exhaustive`` replay, which waits for the node's finished search on every snapshot. Run:

    .venv/bin/python benchmarks/live_replay.py [--rates 1 2 4 8]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from live_node import PYRAMID_SCENE, REPO, isolate_ros, load_average

BAG = REPO / "test" / "data" / "pyramid"


def replay(folder: Path, name: str, *options: str) -> tuple[dict[str, Any], float]:
    """Run ``physics-mapper replay`` on the shipped bag; its JSON results and the seconds it took."""
    output = folder / f"{name}.json"
    command = [sys.executable, "-m", "physics_mapper", "replay", str(BAG), "--scene", str(PYRAMID_SCENE)]
    command += ["--json", str(output), *options]
    start = time.monotonic()
    subprocess.run(command, check=True, capture_output=True, text=True, timeout=600)
    return json.loads(output.read_text()), time.monotonic() - start


def row(label: str, results: dict[str, Any], offline: list[Any], seconds: float) -> str:
    codes = [snapshot["code"] for snapshot in results["snapshots"]]
    configured = sum(code is not None for code in codes)
    same = sum(code == expected for code, expected in zip(codes, offline, strict=True))
    mean = results["mean_errors"] or {}
    totals = " | ".join(f"{sum(mean[key]) * 100:.2f}" if key in mean else "-" for key in ("top", "chosen", "settled"))
    return f"| {label} | {configured}/{len(codes)} | {same}/{len(codes)} | {totals} | {seconds:.1f} |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rates", type=float, nargs="+", default=[1.0, 2.0, 4.0, 8.0], help="replay speeds")
    args = parser.parse_args()
    isolate_ros()
    print(f"load average: {load_average()}; {BAG.relative_to(REPO)}, node at its defaults (2 Hz, deadline 0.2 s)")
    with tempfile.TemporaryDirectory() as folder:
        offline, seconds = replay(Path(folder), "offline", "--offline", "--exhaustive")
        expected = [snapshot["code"] for snapshot in offline["snapshots"]]
        print(
            "| replay | snapshots with a configuration | codes as offline | total error cm: C111 | chosen | settled "
            "| seconds |"
        )
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
        print(row("offline --exhaustive", offline, expected, seconds), flush=True)
        for rate in args.rates:
            output = str(Path(folder) / f"live{rate:g}")
            results, seconds = replay(
                Path(folder), f"live{rate:g}", "--start-node", "--rate", f"{rate:g}", "-o", output
            )
            print(row(f"live --rate {rate:g}", results, expected, seconds), flush=True)
        output = str(Path(folder) / "lockstep")
        results, seconds = replay(Path(folder), "lockstep", "--start-node", "--exhaustive", "--rate", "8", "-o", output)
        print(row("live --exhaustive --rate 8", results, expected, seconds), flush=True)


if __name__ == "__main__":
    main()

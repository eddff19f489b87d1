"""Cost of the physics checks, and of the persistent world against a world rebuilt per configuration.

Run: ``.venv/bin/python benchmarks/physics_costs.py [--repeats N]`` (the same as
``physics-mapper bench``) on each shipped problem. Prints per-operation figures measured side by
side in one run, and the ratio the persistent world buys.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from physics_mapper.bench.physics_costs import costs_text, measure
from physics_mapper.model.scene_files import load_problem

PROBLEMS = Path(__file__).resolve().parent.parent / "config" / "problems"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args()
    for name in ("stack", "pyramid", "peg_in_hole", "sphere_groove"):
        problem = load_problem(PROBLEMS / f"{name}.yaml")
        print(f"\n{name}: {len(problem.scene.objects)} objects, settle_time {problem.scene.search.settle_time} s")
        print(costs_text(measure(problem, args.repeats)))


if __name__ == "__main__":
    main()

"""Where Bullet stops being trustworthy for masses: the measurements behind the mass and density bounds.

Run: ``.venv/bin/python benchmarks/mass_bounds.py``. Prints, for a 10 cm cube resting on the floor,
its jitter J (m) after the default settling for masses from 1e-9 kg to 1e12 kg; then, for a
10 cm cube resting on another, J for mass ratios (top / bottom) from 1e-4 to 1e4 at a 1 kg bottom.
A resting cube should move by well under the default jitter threshold (0.01).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from physics_mapper.model.scene_files import problem_from_dict
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.strategy import solve


def _jitter(objects: list[dict[str, Any]], heights: list[float]) -> float:
    # Masses are set after loading: the loader's bounds are what is measured here.
    masses = [o["mass"] for o in objects]
    objects = [{k: v for k, v in o.items() if k != "mass"} for o in objects]
    document = {
        "static": [{"name": "floor", "shape": "plane"}],
        "objects": objects,
        "search": {"settle_time": 0.5, "bound": "absolute", "settle_exit": "full"},
        "hypotheses": {
            o["name"]: [{"position": [0.0, 0.0, z], "orientation": [0, 0, 0, 1], "weight": 1.0}]
            for o, z in zip(objects, heights, strict=True)
        },
    }
    problem = problem_from_dict(document, "<bench>")
    models = tuple(replace(m, mass=mass) for m, mass in zip(problem.scene.objects, masses, strict=True))
    problem = replace(problem, scene=replace(problem.scene, objects=models))
    with PhysicsChecker(problem.scene) as checker:
        result = solve(checker, problem.hypotheses, problem.scene.search)
    entry = result.trace[0]
    return float(entry.jitter if entry.jitter is not None else float("nan"))


def main() -> None:
    print("one 10 cm cube on the floor: mass (kg) -> J")
    for exponent in (-9, -6, -3, 0, 3, 6, 9, 10, 10.5, 11, 11.5, 12):
        mass = 10.0**exponent
        cube = {"name": "cube", "shape": "box", "size": [0.1, 0.1, 0.1], "mass": mass}
        print(f"  {mass:8.0e}  J = {_jitter([cube], [0.05]):.4g}")
    print("a 10 cm cube on a 1 kg 10 cm cube: mass ratio top/bottom -> J")
    for exponent in (-4, -3, -2, -1, 0, 1, 1.25, 1.5, 1.75, 2, 3, 4):
        ratio = 10.0**exponent
        bottom = {"name": "bottom", "shape": "box", "size": [0.1, 0.1, 0.1], "mass": 1.0}
        top = {"name": "top", "shape": "box", "size": [0.1, 0.1, 0.1], "mass": ratio}
        print(f"  {ratio:8.0e}  J = {_jitter([bottom, top], [0.05, 0.15]):.4g}")


if __name__ == "__main__":
    main()

"""Builders shared by the core's tests: hand-made scenes, hypotheses, searches and CLI runs.

Lengths in metres, times in seconds, as in the core.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from conftest import PROBLEMS, SCENES

from physics_mapper.model.geometry import IDENTITY, Pose, make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Box, ObjectModel, Plane, Scene, SearchParams, StaticBody
from physics_mapper.model.scene_files import load_scene
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import Code, SearchResult
from physics_mapper.search.strategy import paper_search

#: Edge length of the test cubes.
CUBE_SIZE = 0.1
#: Centre height of a test cube resting on the floor.
ON_FLOOR = CUBE_SIZE / 2.0
#: Distance between the test cubes of :func:`far_apart_cubes`: they can never touch.
FAR_APART = 0.5

#: Per-object weights whose products give the paper's Fig. 4 visiting order when
#: T = :data:`FIG4_THRESHOLD` (between p(C222) = 0.01448 and p(C311) = 0.01693).
FIG4_WEIGHTS = ((0.754, 0.195, 0.051), (0.679, 0.238, 0.083), (0.489, 0.312, 0.199))
FIG4_THRESHOLD = 0.016
FIG4_ORDER: tuple[Code, ...] = tuple(
    tuple(int(rank) for rank in code)
    for code in ("111", "112", "113", "121", "211", "122", "212", "123", "131", "213", "221", "132", "311", "222")
)

#: The console script installed next to the interpreter running the tests (.venv/bin).
PHYSICS_MAPPER = str(Path(sys.executable).with_name("physics-mapper"))


def cube(name: str) -> ObjectModel:
    """A movable 0.3 kg test cube of edge :data:`CUBE_SIZE`."""
    return ObjectModel(name, Box((CUBE_SIZE, CUBE_SIZE, CUBE_SIZE)), mass=0.3)


def floor_scene(*objects: ObjectModel) -> Scene:
    """The given objects over an infinite floor at z = 0."""
    return Scene(objects=objects, static=(StaticBody("floor", Plane()),))


def far_apart_cubes(count: int) -> Scene:
    """``count`` test cubes on a floor; :func:`floor_hypotheses` keeps them apart."""
    return floor_scene(*(cube(f"cube_{i}") for i in range(count)))


def ranked(poses: Sequence[Pose], weights: Sequence[float]) -> RankedHypotheses:
    """Ranked hypotheses from poses and their (unnormalised) weights."""
    return RankedHypotheses.from_weighted([Hypothesis(p, w) for p, w in zip(poses, weights, strict=True)])


def floor_hypotheses(weights: Sequence[Sequence[float]], lift: float = 0.0) -> tuple[RankedHypotheses, ...]:
    """Hypotheses for :func:`far_apart_cubes` under which every configuration is valid.

    Object i's cubes stand around x = i * FAR_APART; hypothesis j (input order) is shifted
    1 cm along y and floats ``lift * j`` metres above the floor, so the poses and jitters
    differ but no object ever touches another (keep ``lift * j`` under the jitter threshold).
    """
    return tuple(
        ranked([make_pose((i * FAR_APART, 0.01 * j, ON_FLOOR + lift * j)) for j in range(len(ws))], ws)
        for i, ws in enumerate(weights)
    )


def run_search(
    scene: Scene, hypotheses: Sequence[RankedHypotheses], params: SearchParams | None = None
) -> SearchResult:
    """Search until the queue is empty (no deadline) in a fresh checker."""
    with PhysicsChecker(scene) as checker:
        return paper_search(checker, hypotheses, params or SearchParams()).run(None)


def shipped_scene(scene_file: str) -> Scene:
    """A shipped scene, for direct physics checks."""
    return load_scene(SCENES / scene_file)


def ground_truth(scene: Scene) -> tuple[Pose, ...]:
    """The scene's ground-truth poses (every shipped scene has them)."""
    assert scene.ground_truth is not None
    return scene.ground_truth


def moved(pose: Pose, dx: float = 0.0, dy: float = 0.0, dz: float = 0.0) -> Pose:
    """``pose`` translated by (dx, dy, dz) metres."""
    x, y, z = pose.position
    return replace(pose, position=(x + dx, y + dy, z + dz))


def unrotated(x: float, y: float, z: float) -> Pose:
    """An axis-aligned pose at (x, y, z)."""
    return Pose((x, y, z), IDENTITY)


def cli(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """Run ``physics-mapper ARGS`` in a subprocess; output captured as text."""
    return subprocess.run(
        [PHYSICS_MAPPER, *(str(a) for a in args)], capture_output=True, text=True, timeout=120, check=False
    )


def solve_json(problem: str | Path, *args: str | Path) -> dict[str, Any]:
    """``physics-mapper solve PROBLEM --json ARGS`` parsed; fails the test on a non-zero exit."""
    path = problem if isinstance(problem, Path) else PROBLEMS / problem
    completed = cli("solve", path, "--json", *args)
    assert completed.returncode == 0, completed.stderr
    result: dict[str, Any] = json.loads(completed.stdout)
    return result

"""The seeded scale suite: tabletops of 10 cm cubes in piles, with one valid configuration by construction.

A problem is N cubes on a floor in piles of 1 to 3 placed on a grid 0.4 m apart (far enough that
piles are separate interaction groups): ``singletons``, stacked ``pairs``, small ``pyramids`` (two
cubes 5 mm apart and one on top) or ``mixed`` piles of 1 to 3. The true poses are the piles settled
for :data:`TRUTH_SETTLE_TIME`. Each cube gets M hypotheses: its true pose and M - 1 wrong ones, sunk
1.5 to 3 cm (into the floor or the cube below: Rule 1) or floating 2 to 4 cm (it falls: Rule 2),
moved up to 5 mm sideways. A share :data:`WRONG_SHARE` of the cubes, chosen at random, rank their
true pose 2nd or 3rd; the others rank it 1st. Any configuration with a wrong hypothesis breaks a
rule, so the true configuration is the only valid one and every search's answer is known.
Weights are a sorted Dirichlet(2) draw per cube. Everything follows from the case's seed.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Literal

import numpy as np

from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Box, ObjectModel, Plane, Problem, Scene, SearchParams, StaticBody
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.scenarios.problems import SuiteCase, SuiteProblem

Layout = Literal["singletons", "pairs", "pyramids", "mixed"]
LAYOUTS: tuple[Layout, ...] = ("singletons", "pairs", "pyramids", "mixed")
#: Edge of the cubes, metres, and their mass, kg.
CUBE_EDGE = 0.1
CUBE_MASS = 0.3
#: Metres between the centres of neighbouring piles.
PILE_SPACING = 0.4
#: Metres between the two bottom cubes of a pyramid.
PYRAMID_GAP = 0.005
#: Share of the cubes whose most likely hypothesis is wrong.
WRONG_SHARE = 0.3
#: Simulated seconds the true piles settle before they are used.
TRUTH_SETTLE_TIME = 1.0


#: One problem of the suite, and a problem with its only valid configuration.
ScaleCase = SuiteCase[Layout]
ScaleProblem = SuiteProblem[Layout]


def pile_sizes(layout: Layout, objects: int, rng: np.random.Generator) -> list[int]:
    """How many cubes each pile holds (1 to 3), adding up to ``objects``."""
    if layout == "singletons":
        return [1] * objects
    if layout in ("pairs", "pyramids"):
        size = 2 if layout == "pairs" else 3
        sizes = [size] * (objects // size)
        return sizes + ([objects % size] if objects % size else [])
    sizes = []
    while sum(sizes) < objects:
        sizes.append(min(int(rng.integers(1, 4)), objects - sum(sizes)))
    return sizes


def pile_poses(size: int, x: float, y: float) -> list[Pose]:
    """A pile's cubes, touching, bottom ones on the floor: 1 cube, a stacked pair or a pyramid of 3."""
    half = CUBE_EDGE / 2.0
    if size == 1:
        return [Pose((x, y, half))]
    if size == 2:
        return [Pose((x, y, half)), Pose((x, y, 3 * half))]
    offset = (CUBE_EDGE + PYRAMID_GAP) / 2.0
    return [Pose((x - offset, y, half)), Pose((x + offset, y, half)), Pose((x, y, 3 * half))]


def suite_scene(objects: int, params: SearchParams) -> Scene:
    """``objects`` 10 cm cubes over a floor."""
    cubes = tuple(ObjectModel(f"cube_{i:02d}", Box((CUBE_EDGE,) * 3), mass=CUBE_MASS) for i in range(objects))
    return Scene(objects=cubes, static=(StaticBody("floor", Plane()),), search=params)


def settled_truth(scene: Scene, poses: list[Pose]) -> tuple[Pose, ...]:
    with PhysicsChecker(scene) as checker:
        return checker.settle(poses, TRUTH_SETTLE_TIME, scene.search.angular_weight).settled_poses


def wrong_pose(truth: Pose, rng: np.random.Generator) -> Pose:
    """Sunk 1.5-3 cm or floating 2-4 cm, moved up to 5 mm sideways: always against a rule (module docstring)."""
    dz = -rng.uniform(0.015, 0.03) if rng.random() < 0.5 else rng.uniform(0.02, 0.04)
    dx, dy = rng.uniform(-0.005, 0.005, size=2)
    x, y, z = truth.position
    return replace(truth, position=(x + float(dx), y + float(dy), z + float(dz)))


def scale_problem(case: ScaleCase, params: SearchParams | None = None) -> ScaleProblem:
    """Build the suite's problem for ``case`` (module docstring), searched with ``params`` (default: the defaults)."""
    rng = np.random.default_rng(case.seed)
    scene = suite_scene(case.objects, params or SearchParams())
    sizes = pile_sizes(case.layout, case.objects, rng)
    columns = math.ceil(math.sqrt(len(sizes)))
    poses = [
        pose
        for pile, size in enumerate(sizes)
        for pose in pile_poses(size, PILE_SPACING * (pile % columns), PILE_SPACING * (pile // columns))
    ]
    truth = settled_truth(scene, poses)
    wrong = set(rng.choice(case.objects, size=round(WRONG_SHARE * case.objects), replace=False).tolist())
    ranked, answer = [], []
    for index, true_pose in enumerate(truth):
        weights = sorted(rng.dirichlet([2.0] * case.hypotheses), reverse=True)
        rank = int(rng.integers(2, min(3, case.hypotheses) + 1)) if index in wrong else 1
        poses_of = [wrong_pose(true_pose, rng) for _ in range(case.hypotheses)]
        poses_of[rank - 1] = true_pose
        ranked.append(
            RankedHypotheses.from_weighted([Hypothesis(p, float(w)) for p, w in zip(poses_of, weights, strict=True)])
        )
        answer.append(rank)
    return ScaleProblem(case, Problem(scene, tuple(ranked)), tuple(answer))


def problem_document(problem: Problem) -> dict[str, object]:
    """A problem as the YAML document a problem file holds (scene inline, hypotheses by object name)."""
    scene = problem.scene

    def pose(p: Pose) -> dict[str, list[float]]:
        return {"position": list(p.position), "orientation": list(p.orientation)}

    objects = []
    for model in scene.objects:
        assert isinstance(model.shape, Box)  # the suite's objects are cubes
        objects.append({"name": model.name, "shape": "box", "size": list(model.shape.size), "mass": model.mass})
    hypotheses = {
        model.name: [{**pose(h.pose), "weight": h.weight} for h in ranked.hypotheses]
        for model, ranked in zip(scene.objects, problem.hypotheses, strict=True)
    }
    return {
        "frame_id": scene.frame_id,
        "static": [{"name": body.name, "shape": "plane"} for body in scene.static],
        "objects": objects,
        "hypotheses": hypotheses,
    }

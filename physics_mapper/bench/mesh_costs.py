"""What meshes cost: the two rules on a mesh scene against the same scene made of boxes, and decompositions.

The *box twin* of a scene replaces every mesh (objects, and fixed bodies that collide as a hull or
parts) by the box of its axis-aligned bounds in its own frame, posed where that box is; a fixed
triangle mesh (a tray) stays. The configuration checked is the scene's ground truth, in both.
Figures are medians of wall-clock seconds (:func:`~physics_mapper.bench.physics_costs.median_seconds`).
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from physics_mapper.bench.physics_costs import median_seconds
from physics_mapper.model.decomposition import (
    CACHE_ENVIRONMENT_VARIABLE,
    DecompositionSettings,
)
from physics_mapper.model.geometry import Pose, compose_poses
from physics_mapper.model.meshes import MeshRequest, load_mesh_geometry
from physics_mapper.model.scene import Box, Mesh, ObjectModel, Plane, Scene, StaticBody
from physics_mapper.physics.checker import PhysicsChecker


@dataclass(frozen=True)
class RuleCosts:
    """Median seconds of one collision check (Rule 1) and one settling (Rule 2) of a configuration."""

    collision_check: float
    settle: float


@dataclass(frozen=True)
class SceneCosts:
    """The two rules on a mesh scene and on its box twin."""

    meshes: RuleCosts
    boxes: RuleCosts
    convex_parts: int  # convex pieces Bullet collides among the objects (a hull is one)


def _bounds_box(mesh: Mesh, pose: Pose) -> tuple[Box, Pose]:
    """A mesh's bounding box in its own frame, and that box's pose when the mesh is at ``pose``."""
    low, high = np.array(mesh.geometry.bounds[0]), np.array(mesh.geometry.bounds[1])
    x, y, z = (float(v) for v in (low + high) / 2.0)
    sx, sy, sz = (float(v) for v in high - low)
    return Box((sx, sy, sz)), compose_poses(pose, Pose((x, y, z)))


def box_twin(scene: Scene, poses: Sequence[Pose]) -> tuple[Scene, tuple[Pose, ...]]:
    """The scene with its meshes replaced by their bounding boxes, and ``poses`` moved to those boxes."""
    objects, twin_poses = [], []
    for model, pose in zip(scene.objects, poses, strict=True):
        if isinstance(model.shape, Mesh):
            box, pose = _bounds_box(model.shape, pose)
            model = replace(model, shape=box)
        objects.append(model)
        twin_poses.append(pose)
    static = []
    for body in scene.static:
        if isinstance(body.shape, Mesh) and body.shape.collision != "triangle_mesh":
            box, pose = _bounds_box(body.shape, body.pose)
            body = replace(body, shape=box, pose=pose)
        static.append(body)
    return replace(scene, objects=tuple(objects), static=tuple(static), ground_truth=None), tuple(twin_poses)


def rule_costs(scene: Scene, poses: Sequence[Pose], repeats: int) -> RuleCosts:
    """Median seconds of Rule 1 and of Rule 2 on ``poses``, in one persistent world."""
    params = scene.search
    with PhysicsChecker(scene) as checker:
        return RuleCosts(
            collision_check=median_seconds(
                lambda: checker.find_collision(poses, params.penetration_threshold), repeats
            ),
            settle=median_seconds(
                lambda: checker.settle(poses, params.settle_time, params.angular_weight), max(3, repeats // 5)
            ),
        )


def scene_costs(scene: Scene, repeats: int = 200) -> SceneCosts:
    """The two rules on the scene's ground truth, with its meshes and with its box twin."""
    if scene.ground_truth is None:
        raise ValueError("the scene needs a ground_truth to measure on")
    twin, twin_poses = box_twin(scene, scene.ground_truth)
    parts = sum(len(model.shape.geometry.parts) if isinstance(model.shape, Mesh) else 1 for model in scene.objects)
    return SceneCosts(rule_costs(scene, scene.ground_truth, repeats), rule_costs(twin, twin_poses, repeats), parts)


def resting_costs(mesh: Mesh, repeats: int) -> RuleCosts:
    """The two rules on ``mesh`` as a 0.3 kg object standing on a floor, unturned, its lowest point on it."""
    lowest = min(float(part.vertices[:, 2].min()) for part in mesh.geometry.parts)
    scene = Scene(objects=(ObjectModel("object", mesh, mass=0.3),), static=(StaticBody("floor", Plane()),))
    return rule_costs(scene, (Pose((0.0, 0.0, -lowest)),), repeats)


@dataclass(frozen=True)
class DecompositionCost:
    """One decomposition computed from scratch: wall-clock seconds, convex parts, their vertices and volume
    (m^3), and the two rules on the object standing on a floor (:func:`resting_costs`)."""

    method: str
    seconds: float
    parts: int
    vertices: int
    volume: float
    rules: RuleCosts


def decomposition_cost(
    mesh_file: Path, scale: float, settings: DecompositionSettings, repeats: int = 200
) -> DecompositionCost:
    """Decompose ``mesh_file`` with an empty cache of its own (so it is computed, not read)."""
    saved = os.environ.get(CACHE_ENVIRONMENT_VARIABLE)
    with tempfile.TemporaryDirectory(prefix="physics_mapper_bench_") as folder:
        os.environ[CACHE_ENVIRONMENT_VARIABLE] = folder
        try:
            start = time.perf_counter()
            request = MeshRequest(mesh_file, (scale, scale, scale), "decomposition", settings)
            geometry = load_mesh_geometry(request, lambda _: None)
            seconds = time.perf_counter() - start
            mesh = Mesh(mesh_file, mesh_file.as_uri(), request.scale, "decomposition", geometry)
            rules = resting_costs(mesh, repeats)  # while the cache file pybullet loads exists
        finally:
            if saved is None:
                del os.environ[CACHE_ENVIRONMENT_VARIABLE]
            else:
                os.environ[CACHE_ENVIRONMENT_VARIABLE] = saved
    vertices = sum(len(part.vertices) for part in geometry.parts)
    volume = sum(ConvexHull(part.vertices).volume for part in geometry.parts)
    return DecompositionCost(settings.method, seconds, len(geometry.parts), vertices, float(volume), rules)

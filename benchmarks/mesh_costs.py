"""What meshes cost: the two rules on the shipped mesh scenes against their box twins, and decompositions.

Run: ``physics-mapper bench mesh_costs [--repeats N] [--no-decompositions]``. Prints, for
each shipped mesh scene, the median cost of a collision check (Rule 1) and of a settling (Rule 2) of
its ground truth with the meshes and with every mesh replaced by its bounding box (side by side, in
one run), and then, for pybullet_data's mug and duck, CoACD against V-HACD computed from scratch
(seconds, convex parts, their vertices and volume), pybullet's own decomposition of each, and the
time to load the CoACD decomposition again from the cache. CoACD takes minutes in all.

The *box twin* of a scene replaces every mesh (objects, and fixed bodies that collide as a hull or
parts) by the box of its axis-aligned bounds in its own frame, posed where that box is; a fixed
triangle mesh (a tray) stays. The configuration checked is the scene's ground truth, in both.
Figures are medians of wall-clock seconds (``median_seconds`` of ``benchmarks/physics_costs.py``).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from physics_costs import median_seconds
from scipy.spatial import ConvexHull

from physics_mapper.model.decomposition import (
    CACHE_ENVIRONMENT_VARIABLE,
    DecompositionSettings,
)
from physics_mapper.model.geometry import Pose, compose_poses
from physics_mapper.model.meshes import MeshRequest, load_mesh_geometry
from physics_mapper.model.resources import resolve_resource
from physics_mapper.model.scene import Box, Mesh, ObjectModel, Plane, Scene, StaticBody
from physics_mapper.model.scene_files import load_scene
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


SCENES = Path(__file__).resolve().parent.parent / "config" / "scenes"
MESH_SCENES = ("tabletop", "tray_pile", "jenga_tower")
#: (label, mesh, scale, pybullet's own decomposition of it)
DECOMPOSED = (
    ("mug", "package://pybullet_data/objects/mug.obj", 1.0, "package://pybullet_data/objects/mug_col.obj"),
    ("duck", "package://pybullet_data/duck.obj", 0.05, "package://pybullet_data/duck_vhacd.obj"),
)


def rules_table(repeats: int) -> None:
    rules = "Rule 1, meshes | Rule 1, boxes | ratio | Rule 2, meshes | Rule 2, boxes | ratio"
    print(f"| scene | objects | convex parts | {rules} |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name in MESH_SCENES:
        scene = load_scene(SCENES / f"{name}.yaml")
        costs = scene_costs(scene, repeats)
        meshes, boxes = costs.meshes, costs.boxes
        print(
            f"| {name} | {len(scene.objects)} | {costs.convex_parts} "
            f"| {meshes.collision_check * 1e6:.0f} µs | {boxes.collision_check * 1e6:.0f} µs "
            f"| {meshes.collision_check / boxes.collision_check:.1f} x "
            f"| {meshes.settle * 1e3:.1f} ms | {boxes.settle * 1e3:.1f} ms | {meshes.settle / boxes.settle:.1f} x |",
            flush=True,
        )


def decompositions_table(repeats: int) -> None:
    """Per mesh: CoACD and V-HACD computed from scratch, then the hull and pybullet's own decomposition for scale."""
    print("\n| mesh | collision | seconds | convex parts | vertices | parts' volume (cm³) | Rule 1 | Rule 2 |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for label, url, factor, shipped in DECOMPOSED:
        path, scale = resolve_resource(url, None), (factor, factor, factor)
        for settings in (DecompositionSettings("coacd"), DecompositionSettings("vhacd")):
            cost = decomposition_cost(path, factor, settings, repeats)
            method = f"coacd (threshold {settings.threshold:g})" if cost.method == "coacd" else cost.method
            figures = f"{cost.seconds:.1f} | {cost.parts} | {cost.vertices} | {cost.volume * 1e6:.0f}"
            print(f"| {label} | {method} | {figures} | {_rules(cost.rules)} |", flush=True)
        for name, request in (
            ("convex hull", MeshRequest(path, scale)),
            (
                f"pybullet_data's {Path(shipped).name}",
                MeshRequest(path, scale, "decomposition", parts_file=resolve_resource(shipped, None)),
            ),
        ):
            geometry = load_mesh_geometry(request, lambda _: None)
            rules = resting_costs(Mesh(path, "", scale, request.collision, geometry), repeats)
            vertices = sum(len(part.vertices) for part in geometry.parts)
            volume = sum(ConvexHull(part.vertices).volume for part in geometry.parts) * 1e6
            print(f"| {label} | {name} | - | {len(geometry.parts)} | {vertices} | {volume:.0f} | {_rules(rules)} |")


def _rules(costs: RuleCosts) -> str:
    return f"{costs.collision_check * 1e6:.0f} µs | {costs.settle * 1e3:.2f} ms"


def cache_reload() -> None:
    """Seconds to load the mug with CoACD twice in a fresh cache: decomposed, then read back."""
    mug = resolve_resource(DECOMPOSED[0][1], None)
    with tempfile.TemporaryDirectory(prefix="physics_mapper_bench_") as folder:
        os.environ[CACHE_ENVIRONMENT_VARIABLE] = folder
        seconds = []
        for _ in range(2):
            start = time.perf_counter()
            load_mesh_geometry(MeshRequest(mug, collision="decomposition"), lambda _: None)
            seconds.append(time.perf_counter() - start)
    print(
        f"\nmug with coacd: first load {seconds[0]:.1f} s (decomposed), second load {seconds[1] * 1e3:.1f} ms (cache)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(prog="physics-mapper bench mesh_costs", description=__doc__)
    parser.add_argument("--repeats", type=int, default=200, help="collision checks per median (settlings: a fifth)")
    parser.add_argument("--no-decompositions", action="store_true", help="only the rules (seconds, not minutes)")
    args = parser.parse_args()
    print(f"load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}\n")
    rules_table(args.repeats)
    if not args.no_decompositions:
        decompositions_table(args.repeats)
        cache_reload()


if __name__ == "__main__":
    main()

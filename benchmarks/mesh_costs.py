"""What meshes cost: the two rules on the shipped mesh scenes against their box twins, and decompositions.

Run: ``.venv/bin/python benchmarks/mesh_costs.py [--repeats N] [--no-decompositions]``. Prints, for
each shipped mesh scene, the median cost of a collision check (Rule 1) and of a settling (Rule 2) of
its ground truth with the meshes and with every mesh replaced by its bounding box (side by side, in
one run), and then, for pybullet_data's mug and duck, CoACD against V-HACD computed from scratch
(seconds, convex parts, their vertices and volume), pybullet's own decomposition of each, and the
time to load the CoACD decomposition again from the cache. CoACD takes minutes in all.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from scipy.spatial import ConvexHull

from physics_mapper.bench.mesh_costs import RuleCosts, decomposition_cost, resting_costs, scene_costs
from physics_mapper.model.decomposition import CACHE_ENVIRONMENT_VARIABLE, DecompositionSettings
from physics_mapper.model.meshes import MeshRequest, load_mesh_geometry
from physics_mapper.model.resources import resolve_resource
from physics_mapper.model.scene import Mesh
from physics_mapper.model.scene_files import load_scene

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
    parser = argparse.ArgumentParser(description=__doc__)
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

"""``physics-mapper decompose``: compute (or find) the convex decompositions a scene needs, and say where they are."""

from __future__ import annotations

import argparse
import sys

from physics_mapper.commands.files import input_file, load_scene_file

HELP = "compute the convex decompositions of a scene's meshes into the cache now (the first load can take minutes)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenes", type=input_file, nargs="+", metavar="SCENE", help="scene or problem YAML files")


def run(args: argparse.Namespace) -> int:
    from physics_mapper.model.decomposition import cache_directory
    from physics_mapper.model.scene import Mesh

    print(f"decomposition cache: {cache_directory()}")
    for path in args.scenes:
        scene = load_scene_file(path, "decompose")
        bodies = [(o.name, o.shape) for o in scene.objects] + [(b.name, b.shape) for b in scene.static]
        meshes = [(name, shape) for name, shape in bodies if isinstance(shape, Mesh)]
        decomposed = [(name, shape) for name, shape in meshes if shape.geometry.decomposition is not None]
        print(f"{path}: {len(meshes)} mesh bodies, {len(decomposed)} with a convex decomposition")
        for name, shape in decomposed:
            decomposition = shape.geometry.decomposition
            assert decomposition is not None
            if decomposition.method == "parts file":
                how = "given by its parts file"
            elif decomposition.computed_seconds is None:
                how = f"{decomposition.method}, from the cache"
            else:
                how = f"{decomposition.method}, computed in {decomposition.computed_seconds:.1f} s"
            print(f"  {name}: {shape.file.name}: {len(decomposition.parts)} convex parts ({how}): {decomposition.file}")
    sys.stdout.flush()
    return 0

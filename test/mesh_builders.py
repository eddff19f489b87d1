"""Builders for the mesh tests: small meshes written with trimesh, and scenes holding them.

Lengths in metres. The meshes are made here, so the tests need no asset but pybullet_data's.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from physics_mapper.model.geometry import Pose
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import scene_from_dict

#: The trough of :func:`trough_mesh`: outer width (x) and length (y), height, wall and floor thickness.
TROUGH_WIDTH, TROUGH_LENGTH, TROUGH_HEIGHT, TROUGH_WALL = 0.12, 0.12, 0.05, 0.01
#: pybullet's own mug (8.2 cm wide, 10 cm tall, handle along +y) and its convex decomposition.
MUG_FILE = "package://pybullet_data/objects/mug.obj"
MUG_PARTS = "package://pybullet_data/objects/mug_col.obj"


def box_mesh(size: tuple[float, float, float], pose: Pose | None = None) -> trimesh.Trimesh:
    """A closed box mesh of full edge lengths ``size``, centred on the origin or placed at ``pose``."""
    mesh = trimesh.creation.box(size)
    if pose is not None:
        transform = np.eye(4)
        transform[:3, :3] = Rotation.from_quat(pose.orientation).as_matrix()
        transform[:3, 3] = pose.position
        mesh.apply_transform(transform)
    assert isinstance(mesh, trimesh.Trimesh)
    return mesh


def trough_mesh() -> trimesh.Trimesh:
    """A closed U-shaped channel, open at the top: a concave object whose hull fills its cavity.

    Its U cross-section (in x-z) is extruded along y; the floor is :data:`TROUGH_WALL` thick at
    z = 0, so the cavity spans |x| < TROUGH_WIDTH / 2 - TROUGH_WALL, TROUGH_WALL < z < TROUGH_HEIGHT.
    """
    w, h, t = TROUGH_WIDTH / 2.0, TROUGH_HEIGHT, TROUGH_WALL
    section = [(-w, 0.0), (w, 0.0), (w, h), (w - t, h), (w - t, t), (-w + t, t), (-w + t, h), (-w, h)]
    count = len(section)
    vertices = [(x, y, z) for y in (-TROUGH_LENGTH / 2.0, TROUGH_LENGTH / 2.0) for x, z in section]
    cap = [(0, 1, 4), (0, 4, 5), (1, 2, 3), (1, 3, 4), (0, 5, 6), (0, 6, 7)]  # the U, as triangles
    faces = [(a, b, c) for a, b, c in cap] + [(count + a, count + c, count + b) for a, b, c in cap]
    for i in range(count):
        j = (i + 1) % count
        faces += [(i, i + count, j), (j, i + count, j + count)]
    # Counter-clockwise seen from outside: the caps as listed, the far cap and the sides reversed.
    return trimesh.Trimesh(np.array(vertices), np.array(faces), process=True)


def write_mesh(mesh: trimesh.Trimesh, path: Path) -> Path:
    """Write ``mesh`` in the format of ``path``'s suffix (OBJ or STL)."""
    mesh.export(path)
    return path


def mesh_object(name: str, file: str | Path, **keys: Any) -> dict[str, Any]:
    """A ``shape: mesh`` object entry of a scene file."""
    return {"name": name, "shape": "mesh", "file": str(file), **keys}


def floor_scene_dict(*objects: dict[str, Any], static: tuple[dict[str, Any], ...] = ()) -> dict[str, Any]:
    """A scene file's content: a floor, the given static bodies and objects."""
    return {"static": [{"name": "floor", "shape": "plane"}, *static], "objects": list(objects)}


def load_inline(data: dict[str, Any], base_dir: Path, progress: Callable[[str], None] | None = None) -> Scene:
    """A scene from a dict, mesh paths relative to ``base_dir``; progress lines dropped unless collected."""
    return scene_from_dict(data, "scene.yaml", base_dir, progress or (lambda _: None))

"""The mesh caps hold before a file is parsed, however its faces are written: an OBJ polygon of n corners
counts as the n - 2 triangles it becomes, a vertex as its ``v`` line.

The refused files refer to vertices that do not exist, so a file that reached the parser would be
refused for that instead: the reason given shows where the refusal was made.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from mesh_builders import floor_scene_dict, load_inline, mesh_object

from physics_mapper.model.meshes import MAX_MESH_FACES, MAX_MESH_VERTICES
from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import SceneError


def load_obj(folder: Path, text: str) -> Scene:
    (folder / "m.obj").write_text(text, encoding="ascii")
    return load_inline(floor_scene_dict(mesh_object("m", "m.obj", mass=0.1)), folder)


def test_one_polygon_of_many_corners_counts_as_its_triangles(tmp_path: Path) -> None:
    corners = " ".join(str(i) for i in range(1, MAX_MESH_FACES + 4))  # MAX_MESH_FACES + 1 triangles
    with pytest.raises(SceneError, match=f"too many faces: {MAX_MESH_FACES + 1} \\(at most {MAX_MESH_FACES}"):
        load_obj(tmp_path, f"v 0 0 0\nv 1 0 0\nv 0 1 0\nf {corners}\n")


def test_polygons_at_the_cap_load(tmp_path: Path) -> None:
    quads = "f 1  2\t3 4\r\n" * (MAX_MESH_FACES // 2)  # CRLF lines of two triangles each: the cap exactly
    load_obj(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n" + quads)


def test_more_vertices_than_the_cap_are_refused_before_parsing(tmp_path: Path) -> None:
    vertices = "v 0 0 0\n" * (MAX_MESH_VERTICES + 1)
    with pytest.raises(SceneError, match=f"too many vertices: {MAX_MESH_VERTICES + 1} \\(at most"):
        load_obj(tmp_path, vertices + f"f 1 2 {MAX_MESH_VERTICES + 7}\n")

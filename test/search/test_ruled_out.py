"""Ranks ruled out before the search are explained: with Rule 1's reason, the other body and the depth."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from core_builders import CUBE_SIZE, ON_FLOOR, cli, cube, floor_scene, ranked, solve_json, unrotated

from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.results import RuledOut
from physics_mapper.search.strategy import make_search

#: pybullet's own mug (its frame at the bottom), collided as its own convex decomposition.
MUG = {
    "name": "mug",
    "shape": "mesh",
    "file": "package://pybullet_data/objects/mug.obj",
    "collision": "decomposition",
    "parts": "package://pybullet_data/objects/mug_col.obj",
    "mass": 0.3,
}


@pytest.fixture(scope="module")
def sunk_mug(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A problem whose only hypothesis puts the mug 2 cm into the floor."""
    problem = {
        "static": [{"name": "floor", "shape": "plane"}],
        "objects": [MUG],
        "hypotheses": {"mug": [{"position": [0.0, 0.0, -0.02], "orientation": [0, 0, 0, 1], "weight": 1.0}]},
    }
    path = tmp_path_factory.mktemp("sunk") / "sunk_mug.yaml"
    path.write_text(yaml.safe_dump(problem))
    return path


def test_the_sunk_mug_is_ruled_out_in_json_with_the_floor_and_the_depth(sunk_mug: Path) -> None:
    result = solve_json(sunk_mug)
    assert not result["valid"] and result["stats"]["visited"] == 0
    (ruling,) = result["ruled_out"]
    assert {key: ruling[key] for key in ("object", "rank", "reason", "other", "every_rank")} == {
        "object": "mug",
        "rank": 1,
        "reason": "collision",
        "other": "floor",
        "every_rank": False,
    }
    assert ruling["depth"] == pytest.approx(0.02, abs=1e-3)
    assert result["stats"]["ruled_out"] == 1


def test_the_sunk_mug_is_ruled_out_in_the_tree(sunk_mug: Path) -> None:
    completed = cli("solve", sunk_mug, "--tree")
    assert completed.returncode == 0, completed.stderr
    assert "ruled out before the search: mug #1: collision with floor, 20 mm" in completed.stdout.splitlines()


def test_a_rank_overlapping_a_neighbour_at_each_of_its_ranks_is_ruled_out_with_that_neighbour() -> None:
    """Seven cubes in a row 1 cm apart (the pairwise rule needs a group of seven): cube_0's second
    hypothesis cuts 3 cm into cube_1's first and 2 cm into its second (1 cm further on, touching cube_2);
    nothing else overlaps."""
    pitch = CUBE_SIZE + 0.01
    scene = floor_scene(*(cube(f"cube_{i}") for i in range(7)))
    hypotheses = [
        ranked([unrotated(i * pitch, 0.0, ON_FLOOR), unrotated(i * pitch, 0.05, ON_FLOOR)], [2, 1]) for i in range(7)
    ]
    hypotheses[1] = ranked([unrotated(pitch, 0.0, ON_FLOOR), unrotated(pitch + 0.01, 0.05, ON_FLOOR)], [2, 1])
    hypotheses[0] = ranked([unrotated(0.0, 0.0, ON_FLOOR), unrotated(pitch - CUBE_SIZE + 0.03, 0.02, ON_FLOOR)], [2, 1])
    with PhysicsChecker(scene) as checker:
        result = make_search(checker, hypotheses, SearchParams()).run(None)
    (ruling,) = result.ruled_out
    assert (ruling.object, ruling.rank, ruling.other, ruling.every_rank, ruling.reason) == (
        "cube_0",
        2,
        "cube_1",
        True,
        "collision",
    )
    assert ruling.depth == pytest.approx(0.02, abs=1e-3)  # the shallower overlap, with cube_1's second
    assert result.valid and result.code is not None and result.code[0] == 1
    assert result.stats.ruled_out == 1 and isinstance(ruling, RuledOut)

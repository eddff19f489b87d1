"""Ranks ruled out before the search are explained: with Rule 1's reason, the other body and the depth, or
Rule 2's free fall."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
import yaml
from core_builders import CUBE_SIZE, ON_FLOOR, cli, cube, floor_scene, ranked, solve_json, unrotated

from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses, absent_hypothesis
from physics_mapper.model.scene import SearchParams
from physics_mapper.physics.checker import PhysicsChecker
from physics_mapper.search.groups import interaction_groups
from physics_mapper.search.report import ruled_out_text
from physics_mapper.search.results import RuledOut
from physics_mapper.search.ruling_out import Grounds
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
    assert result.stats.part_counters["ruled_out"] == 1 and isinstance(ruling, RuledOut)


def test_a_rank_in_free_fall_is_ruled_out_and_one_in_reach_of_a_neighbour_is_not() -> None:
    """Two cubes 1 cm apart on the floor, each also seen 5 cm up (in the air); a third seen 30 cm up only
    beside its floor pose. With the default 0.5 s settling (a fall of 1.2 m) the air pose far from
    everything is ruled out as floating; the ones 5 cm up stay (the other cube's air pose is in reach,
    so the search decides them); with a settling too short to fall out of the envelope, nothing is."""
    pitch = CUBE_SIZE + 0.01
    scene = floor_scene(cube("a"), cube("b"), cube("c"))
    hypotheses = [
        ranked([unrotated(0.0, 0.0, ON_FLOOR), unrotated(0.0, 0.0, ON_FLOOR + 0.05)], [2, 1]),
        ranked([unrotated(pitch, 0.0, ON_FLOOR), unrotated(pitch, 0.0, ON_FLOOR + 0.05)], [2, 1]),
        ranked([unrotated(0.6, 0.0, ON_FLOOR), unrotated(0.6, 0.0, 0.3)], [1, 2]),  # the air pose first
    ]
    with PhysicsChecker(scene) as checker:
        result = make_search(checker, hypotheses, SearchParams()).run(None)
        brief = make_search(checker, hypotheses, SearchParams(settle_time=0.02)).run(None)
    (ruling,) = result.ruled_out
    assert (ruling.object, ruling.rank, ruling.reason, ruling.other, ruling.depth) == ("c", 1, "floating", "", 0.0)
    assert result.valid and result.code == (1, 1, 2)
    assert brief.ruled_out == ()
    with PhysicsChecker(scene) as checker:  # sound: every configuration holding c in the air is unstable
        for code in ((1, 1, 1), (2, 2, 1), (1, 2, 1), (2, 1, 1)):
            poses = [h.pose(rank) for h, rank in zip(hypotheses, code, strict=True)]
            assert not checker.settle(poses, 0.5, SearchParams().angular_weight).is_stable(
                SearchParams().jitter_threshold
            )


def test_the_ground_is_made_once_per_grouping_for_all_its_groups() -> None:
    """Three cubes far apart, three groups: the free-fall pass of each reads one ground, made again only for a
    new grouping (a merge), and the same there: c's air pose alone is not grounded."""
    scene = floor_scene(cube("a"), cube("b"), cube("c"))
    hypotheses = [
        ranked([unrotated(0.0, 0.0, ON_FLOOR)], [1]),
        ranked([unrotated(0.4, 0.0, ON_FLOOR)], [1]),
        ranked([unrotated(0.8, 0.0, ON_FLOOR), unrotated(0.8, 0.4, 0.3)], [1, 1]),
    ]
    params = SearchParams()
    grouping = interaction_groups(scene, hypotheses, params.interaction_margin)
    assert len(grouping.groups) == 3
    grounds = Grounds(scene, hypotheses, params)
    ground = grounds.of(grouping)
    assert grounds.of(grouping) is ground
    regrouped = grounds.of(interaction_groups(scene, hypotheses, params.interaction_margin))
    assert regrouped is not ground
    for made in (ground, regrouped):
        assert [grounded.tolist() for grounded in made.grounded] == [[True], [True], [True, False]]


def test_detections_in_the_air_side_by_side_are_ruled_out_and_a_column_standing_on_the_floor_is_not() -> None:
    """Two cubes that may be absent, each seen only 30 cm up, 1 cm apart: each envelope meets the other's,
    but neither meets anything that rests on something, so both are ruled out as floating and the map
    leaves them out. A column of three cubes, each seen 3 mm above the one below, is grounded through the
    floor, the top one through the two below it: nothing of it is ruled out."""
    pitch = CUBE_SIZE + 0.01
    lift = CUBE_SIZE + 0.003
    scene = floor_scene(cube("x"), cube("y"), cube("z"), cube("a"), cube("b"))
    hypotheses = [ranked([unrotated(0.0, 0.0, ON_FLOOR + k * lift)], [1]) for k in range(3)] + [
        RankedHypotheses.from_weighted(
            [Hypothesis(unrotated(0.6 + k * pitch, 0.0, 0.3), 0.6), absent_hypothesis(3 + k, 0.4)]
        )
        for k in range(2)
    ]
    with PhysicsChecker(scene) as checker:
        result = make_search(checker, hypotheses, SearchParams()).run(None)
    assert {(r.object, r.rank, r.reason) for r in result.ruled_out} == {("a", 1, "floating"), ("b", 1, "floating")}
    assert result.valid and result.code == (1, 1, 1, 2, 2)
    with PhysicsChecker(scene) as checker:  # sound: the two in the air fall together
        poses = [h.pose(1) for h in hypotheses]
        assert not checker.settle(poses, 0.5, SearchParams().angular_weight).is_stable(SearchParams().jitter_threshold)


def test_a_floating_ruling_reads_as_one_line() -> None:
    ruling = RuledOut("c", 1, "", 0.0, reason="floating")
    assert ruled_out_text(ruling) == "c #1: floating, nothing within reach to rest on"


def test_an_object_every_rank_of_which_falls_keeps_them_for_the_settled_fallback() -> None:
    """A cube seen only in the air (it cannot be absent): nothing is ruled out, every configuration is
    found unstable, and the ``settled`` fallback reports it fallen onto the floor."""
    scene = floor_scene(cube("a"))
    hypotheses = [ranked([unrotated(0.0, 0.0, 0.3), unrotated(0.0, 0.0, 0.4)], [2, 1])]
    with PhysicsChecker(scene) as checker:
        result = make_search(checker, hypotheses, SearchParams(fallback="settled")).run(None)
    assert result.ruled_out == () and result.stats.unstable == 2
    assert not result.valid and result.fallback == "settled" and result.settled_poses is not None
    assert result.settled_poses[0].position[2] == pytest.approx(ON_FLOOR, abs=0.005)


def test_the_refined_map_leaves_out_a_detection_in_free_fall_that_may_be_absent() -> None:
    """Two cubes estimated 4 cm into each other (no valid configuration: the ``refine`` fallback's map),
    and a third that may be absent, seen 30 cm up only: its air ranks are ruled out, so the refined map
    starts from its *absent* rank (the live root) and leaves it out instead of dropping it onto the others;
    the paper's search, which rules nothing out, refines it in (C11..1), drops it 25 cm, farther than half
    its size from where it was seen, and so leaves it out of the map too."""
    scene = floor_scene(cube("a"), cube("b"), cube("c"))
    hypotheses = [
        ranked([unrotated(0.0, 0.0, ON_FLOOR)], [1]),
        ranked([unrotated(CUBE_SIZE - 0.04, 0.0, ON_FLOOR)], [1]),
        RankedHypotheses.from_weighted(
            [
                Hypothesis(unrotated(0.05, 0.0, 0.3), 0.6),
                Hypothesis(unrotated(0.05, 0.0, 0.31), 0.3),
                absent_hypothesis(2, 0.1),
            ]
        ),
    ]
    with PhysicsChecker(scene) as checker:
        default = make_search(checker, hypotheses, SearchParams(fallback="refine")).run(None)
        joint = make_search(checker, hypotheses, SearchParams(fallback="refine", strategy="joint")).run(None)
    assert {(r.object, r.rank, r.reason) for r in default.ruled_out} == {("c", 1, "floating"), ("c", 2, "floating")}
    assert not default.valid and default.fallback == "refine" and default.code == (1, 1, 3)
    assert hypotheses[2].is_absent(3)
    assert not joint.valid and joint.fallback == "refine" and joint.code == (1, 1, 3) and joint.ruled_out == ()
    assert joint.refinement is not None and joint.refinement.settled_poses[2].position[2] < 0.2  # onto the others


def test_the_refined_map_keeps_a_sunk_detection_that_may_be_absent_where_another_rests_on_it() -> None:
    """A bottom cube that may be absent, seen only 1.5 cm into the floor (ruled out: the live root has it
    absent), and a top cube on it. Left out, the top cube would fall into its place: the refined map puts
    it back, lifted out of the floor, and the top cube stays on it."""
    scene = floor_scene(cube("bottom"), cube("top"))
    hypotheses = [
        RankedHypotheses.from_weighted(
            [Hypothesis(unrotated(0.0, 0.0, ON_FLOOR - 0.015), 0.9), absent_hypothesis(0, 0.1)]
        ),
        ranked([unrotated(0.0, 0.0, ON_FLOOR + CUBE_SIZE)], [1]),
    ]
    with PhysicsChecker(scene) as checker:
        result = make_search(checker, hypotheses, SearchParams(fallback="refine")).run(None)
    assert [(r.object, r.rank, r.reason) for r in result.ruled_out] == [("bottom", 1, "collision")]
    assert not result.valid and result.fallback == "refine" and result.code == (1, 1)
    assert result.settled_poses is not None
    assert [pose.position[2] for pose in result.settled_poses] == pytest.approx(
        [ON_FLOOR, ON_FLOOR + CUBE_SIZE], abs=0.003
    )


@pytest.mark.parametrize("top", ["may be absent", "named", "confirmed instance"])
def test_the_refined_map_holds_nothing_where_it_moved_away_from_where_it_was_seen(top: str) -> None:
    """A cube seen 2 cm into the floor (every rank ruled out) and a top cube on its edge, its centre 6 cm
    aside: lifted out of the floor, the bottom cube tips the top one off onto the floor, 10 cm from where it
    was seen. The map leaves it out where it may be absent (nothing rests on it), holds a confirmed instance
    of a tracked class where it was seen (depenetrated, overlapping nothing), and a named cube where it fell."""
    seen = unrotated(0.0, 0.0, ON_FLOOR + CUBE_SIZE - 0.02)
    hypotheses = [
        ranked([unrotated(0.06, 0.0, ON_FLOOR - 0.02)], [1]),
        RankedHypotheses.from_weighted([Hypothesis(seen, 0.9), absent_hypothesis(1, 0.1)])
        if top == "may be absent"
        else ranked([seen], [1]),
    ]
    scene = floor_scene(cube("sunk"), cube("top"))
    if top == "confirmed instance":
        scene = replace(scene, class_map=(("cube", ("sunk", "top")),))
    with PhysicsChecker(scene) as checker:
        result = make_search(checker, hypotheses, SearchParams(fallback="refine")).run(None)
    assert [(r.object, r.rank) for r in result.ruled_out] == [("sunk", 1)]  # the top cube is not in free fall
    assert not result.valid and result.fallback == "refine" and result.settled_poses is not None
    assert result.refinement is not None and result.refinement.settled_poses[1].position[2] == pytest.approx(
        ON_FLOOR, abs=0.003
    )  # the top cube fell
    assert result.settled_poses[0].position[2] == pytest.approx(ON_FLOOR, abs=0.003)
    assert result.code == ((1, 2) if top == "may be absent" else (1, 1))
    if top == "named":
        assert result.settled_poses[1] == result.refinement.settled_poses[1]
    if top == "confirmed instance":
        assert result.settled_poses[1] == result.refinement.depenetrated_poses[1]
        assert result.settled_poses[1].position[2] > ON_FLOOR + CUBE_SIZE - 0.025


def test_the_refined_map_holds_an_object_more_likely_there_than_not_though_absent_ranks_first() -> None:
    """Nothing is valid (a cube 2 cm into the floor, its only pose); a second cube 5 mm beside it (one group)
    may be absent, weight 0.25, and its four poses share 0.75: absent ranks first, yet the refined map holds
    it, at its first pose. With absent at 0.6 it stays out."""
    on_floor = [unrotated(CUBE_SIZE + 0.005 + 0.002 * k, 0.0, ON_FLOOR) for k in range(4)]

    def refined_code(absent: float) -> tuple[int, ...] | None:
        present = [Hypothesis(pose, (1.0 - absent) / 4) for pose in on_floor]
        hypotheses = [
            ranked([unrotated(0.0, 0.0, ON_FLOOR - 0.02)], [1]),
            RankedHypotheses.from_weighted([*present, absent_hypothesis(1, absent)]),
        ]
        assert hypotheses[1].is_absent(1)
        with PhysicsChecker(floor_scene(cube("sunk"), cube("maybe"))) as checker:
            result = make_search(checker, hypotheses, SearchParams(fallback="refine")).run(None)
        assert not result.valid and result.fallback == "refine"
        return result.code

    assert refined_code(0.25) == (1, 2)
    assert refined_code(0.6) == (1, 1)

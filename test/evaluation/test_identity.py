"""Identity metrics over a bag (identity switches, IDF1, MOTA/MOTP, position error by identity) on cases
whose answer is known by hand, and as replay and evaluate report them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import REPO, SCENES

from physics_mapper.bags.storage import POSE_ARRAY, BagWriter, pose_array_cdr, read_bag
from physics_mapper.cli import main
from physics_mapper.evaluation.identity import (
    IdentityFrame,
    identity_metrics,
    objects_lain_on,
    overall_identity_metrics,
    record_frames,
)
from physics_mapper.evaluation.scoring import ObjectClasses, matched_errors
from physics_mapper.evaluation.settings import PARAMS_FILE_NODE_KEY, grid_settings
from physics_mapper.evaluation.snapshot_results import replay_offline, snapshot_result_dict
from physics_mapper.evaluation.snapshots import bag_snapshots, input_topics
from physics_mapper.mapping.association import AssociationSettings
from physics_mapper.mapping.topics import GROUND_TRUTH_TOPIC, poses_topic
from physics_mapper.model.errors import InputError
from physics_mapper.model.geometry import make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene_files import load_scene

TRUTH = [(0.0, 0.0, 0.05), (0.2, 0.0, 0.05)]


def frame(**names: tuple[float, float, float]) -> IdentityFrame:
    return IdentityFrame(TRUTH, names)


def test_a_perfect_track_has_idf1_one_and_no_switch() -> None:
    frames = [frame(a=(0.01, 0.0, 0.05), b=(0.2, 0.02, 0.05)) for _ in range(10)]
    figures = identity_metrics(frames)
    assert figures is not None
    assert figures["idf1"] == 1.0 and figures["mota"] == 1.0 and figures["switches"] == 0
    assert figures["motp_m"] == pytest.approx(0.015)
    assert [(i["truth"], i["name"]) for i in figures["identities"]] == [(0, "a"), (1, "b")]
    assert [i["mean_error_m"] for i in figures["identities"]] == pytest.approx([0.01, 0.02])
    assert figures["identity_error_m"] == pytest.approx(0.015)


def test_an_identity_switch_is_counted_once() -> None:
    """Object 0 is named a for four frames, then c for six: one switch; IDF1 = 2 * 16 / 40."""
    frames = [frame(a=TRUTH[0], b=TRUTH[1])] * 4 + [frame(c=TRUTH[0], b=TRUTH[1])] * 6
    figures = identity_metrics(frames)
    assert figures is not None
    assert figures["switches"] == 1
    assert figures["idf1"] == pytest.approx(2 * 16 / 40)
    assert figures["mota"] == pytest.approx(1 - 1 / 20)
    assert [i["name"] for i in figures["identities"]] == ["c", "b"]


def test_a_swap_of_two_names_is_a_switch_of_each() -> None:
    frames = [frame(a=TRUTH[0], b=TRUTH[1])] * 5 + [frame(a=TRUTH[1], b=TRUTH[0])] * 5
    figures = identity_metrics(frames)
    assert figures is not None and figures["switches"] == 2 and figures["idf1"] == pytest.approx(0.5)


def test_misses_false_positives_and_frames_without_a_map() -> None:
    """A second name on object 1 (a double detection kept), a name nowhere near an object (a false
    positive in the air), a frame without a map: misses and false positives, matched within the gate."""
    frames = [
        frame(a=TRUTH[0], b=TRUTH[1], b2=(0.206, 0.0, 0.05)),
        frame(a=TRUTH[0], b=TRUTH[1], air=(0.1, 0.0, 0.4)),
        IdentityFrame(TRUTH, None),
        frame(a=(0.0, 0.0, 0.11), b=TRUTH[1]),  # 6 cm off: beyond the 5 cm gate
    ]
    figures = identity_metrics(frames)
    assert figures is not None
    assert figures["false_positives"] == 3 and figures["misses"] == 3 and figures["switches"] == 0
    assert figures["true_objects"] == 8 and figures["matches"] == 5
    assert figures["mota"] == pytest.approx(1 - 6 / 8)
    # By identity a stays object 0's name, and its error counts the frame outside the gate too.
    assert figures["identities"][0]["mean_error_m"] == pytest.approx(0.06 / 3)


def test_bags_together_sum_their_counts_and_keep_their_own_names() -> None:
    perfect = [frame(a=TRUTH[0], b=TRUTH[1])] * 4
    switching = [frame(a=TRUTH[0], b=TRUTH[1])] * 2 + [frame(c=TRUTH[0], b=TRUTH[1])] * 2
    overall = overall_identity_metrics([perfect, switching])
    assert overall is not None
    assert overall["switches"] == 1 and overall["switches_max"] == 1 and overall["frames"] == 8
    assert overall["idf1"] == pytest.approx((16 + 12) / 32)
    assert identity_metrics([]) is None and overall_identity_metrics([]) is None


PARTS = ObjectClasses(("part_1", "part_2", "part_3"), ("part", "part", "part"))
ROW = [(0.0, 0.0, 0.01), (0.03, 0.0, 0.01), (0.06, 0.0, 0.01)]  # identical parts 3 cm apart


def test_identical_parts_closer_than_the_gate_are_matched_to_their_own_object() -> None:
    """Parts 3 cm apart, each instance 2 mm off its own: within 5 cm of its neighbours too, so the gate is half
    the spacing, and each true part is given the instance on it, its error 2 mm, not the spacing."""
    placed = {"part_1": (0.062, 0.0, 0.01), "part_2": (0.002, 0.0, 0.01), "part_3": (0.032, 0.0, 0.01)}
    figures = identity_metrics([IdentityFrame(ROW, placed)] * 5, PARTS)
    assert figures is not None
    assert figures["gate_m"] == pytest.approx(0.015)
    assert [i["name"] for i in figures["identities"]] == ["part_2", "part_3", "part_1"]
    assert figures["identity_error_m"] == pytest.approx(0.002)
    assert figures["idf1"] == 1.0 and figures["switches"] == 0


def test_a_named_object_matches_only_its_own_true_object() -> None:
    """Named objects are their own class: a name on the other object's place is a miss of its own (beyond the
    gate) and a false positive, not a match of the other; its object has no name by identity."""
    named = ObjectClasses.named(["a", "b"])
    figures = identity_metrics([frame(a=TRUTH[1], b=TRUTH[1])] * 3, named)
    assert figures is not None
    assert (figures["matches"], figures["misses"], figures["false_positives"]) == (3, 3, 3)
    assert [i["name"] for i in figures["identities"]] == [None, "b"]


def test_instances_are_scored_against_the_true_object_they_are_matched_to() -> None:
    """Per class, least total distance: part_1 lies on part 3, part_2 on part 1; a part left out has no error;
    a named object is scored against its own true pose, wherever the others are."""
    objects = ObjectClasses(("part_1", "part_2", "part_3", "tray"), ("part", "part", "part", "tray"))
    truth = [make_pose(p) for p in [*ROW, (0.5, 0.0, 0.0)]]
    estimate = [make_pose(p) for p in [(0.061, 0.0, 0.01), (0.0, 0.003, 0.01), (0.0, 0.0, 0.5), (0.5, 0.0, 0.01)]]
    errors = matched_errors(estimate, truth, objects, (True, True, False, True))
    assert errors[0] == pytest.approx(0.001) and errors[1] == pytest.approx(0.003) and errors[2] is None
    assert errors[3] == pytest.approx(0.01)
    assert matched_errors(estimate, truth, ObjectClasses.named(objects.names), (True,) * 4)[0] == pytest.approx(0.061)


def test_a_map_object_lies_on_the_nearest_true_object_of_its_class_within_the_gate() -> None:
    """part_1 lies on part 3 (1 mm), part_2 nearest the tray's true pose but on no part within the gate (part_3
    left out of the map), the tray on its own; without classes, part_2 lies on the tray."""
    objects = ObjectClasses(("part_1", "part_2", "part_3", "tray"), ("part", "part", "part", "tray"))
    truth = np.array([*ROW, (0.5, 0.0, 0.0)])
    estimate = {"part_1": [0.061, 0.0, 0.01], "part_2": [0.5, 0.002, 0.0], "tray": [0.5, 0.0, 0.003]}
    assert objects_lain_on(truth, estimate, objects, 0.02) == {"part_1": 2, "part_2": None, "tray": 3}
    assert objects_lain_on(truth, estimate, None, 0.02) == {"part_1": 2, "part_2": 3, "tray": 3}


def test_the_shipped_box_bin_s_errors_are_those_of_each_box_s_true_cube(tmp_path: Path) -> None:
    """The box bin's instances take their names from the order their tracks began, not from the truth's: scored
    by name, the mean errors of replay and evaluate were the spacing of the cubes (11-16 cm); matched, each is the
    estimator's (5 mm of noise per axis; under 1 cm at the default deadline, a wrong pose chosen now and then
    adds to it)."""
    data = tmp_path / "replay.json"
    bag, scene = str(REPO / "test" / "data" / "box_bin"), str(SCENES / "box_bin.yaml")
    assert main(["replay", bag, "--scene", scene, "--offline", "--json", str(data)]) == 0
    means = json.loads(data.read_text())["mean_errors"]
    assert all(error < 0.05 for estimate in ("top", "chosen", "settled") for error in means[estimate])
    assert main(["evaluate", bag, "--scene", scene, "--workers", "0", "-o", str(tmp_path / "e")]) == 0
    report = json.loads((tmp_path / "e" / "report.json").read_text())
    assert report["classes"] == ["box"] * 6
    assert all(error < 0.05 for error in report["overall"]["mean_m"]["settled"]["per_object"].values())
    assert "identical instances against the true object matched" in (tmp_path / "e" / "report.md").read_text()


def test_replay_and_evaluate_report_identity(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The pyramid's named cubes keep their names: no switch; replay's JSON and evaluate's report agree."""
    scene = str(SCENES / "pyramid.yaml")
    bag = str(REPO / "test" / "data" / "pyramid")
    replayed = tmp_path / "replay.json"
    assert main(["replay", bag, "--scene", scene, "--offline", "--exhaustive", "--json", str(replayed)]) == 0
    assert "0 identity switches" in capsys.readouterr().out
    identity = json.loads(replayed.read_text())["identity"]
    assert identity["switches"] == 0 and identity["false_positives"] == 0
    assert [i["name"] for i in identity["identities"]] == ["cube_left", "cube_right", "cube_top"]
    assert main(["evaluate", bag, "--scene", scene, "--exhaustive", "--workers", "0", "-o", str(tmp_path / "e")]) == 0
    report = json.loads((tmp_path / "e" / "report.json").read_text())
    assert report["bags"][0]["summary"]["identity"]["idf1"] == pytest.approx(identity["idf1"])
    assert report["overall"]["identity"]["switches"] == 0
    assert "identity switches" in (tmp_path / "e" / "report.md").read_text()


def test_the_shipped_box_bin_gives_each_instance_one_detection_and_draws_the_picture(tmp_path: Path) -> None:
    """Offline, each instance takes at most one detection of a frame and no detection goes to two instances;
    the picture is written as a PNG."""
    scene = str(SCENES / "box_bin.yaml")
    bag = str(REPO / "test" / "data" / "box_bin")
    data, picture = tmp_path / "replay.json", tmp_path / "identities.png"
    arguments = ["replay", bag, "--scene", scene, "--offline", "--json", str(data), "--identity-plot", str(picture)]
    assert main(arguments) == 0
    snapshots = json.loads(data.read_text())["snapshots"]
    assert len(snapshots) == 10
    for snapshot in snapshots:
        taken = snapshot["detections"]
        assert len(set(taken.values())) == len(taken) >= 4  # six cubes, about one missed per frame
    assert picture.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")


def test_sweep_grids_over_the_association_settings(tmp_path: Path) -> None:
    scene = str(SCENES / "box_bin.yaml")
    bag = str(REPO / "test" / "data" / "box_bin")
    output = tmp_path / "sweep"
    grid = ["--grid", "association.gate=0.002,0.04", "--grid", "association.confirm_hits=1"]
    assert main(["sweep", bag, "--scene", scene, *grid, "--workers", "0", "--progress", "off", "-o", str(output)]) == 0
    settings = json.loads((output / "sweep.json").read_text())["settings"]
    assert [s["varied"] for s in settings] == [
        {"association.gate": 0.002, "association.confirm_hits": 1},
        {"association.gate": 0.04, "association.confirm_hits": 1},
    ]
    assert [(s["association"]["gate"], s["association"]["confirm_hits"]) for s in settings] == [(0.002, 1), (0.04, 1)]
    assert all(s["overall"]["identity"]["frames"] > 0 for s in settings)
    assert "| switches | IDF1 |" in (output / "sweep.md").read_text()
    parameters = yaml.safe_load((output / "best_params.yaml").read_text())[PARAMS_FILE_NODE_KEY]["ros__parameters"]
    assert parameters["confirm_hits"] == 1 and parameters["association_gate"] in (0.002, 0.04)


def test_the_association_settings_reach_the_bag_s_snapshots() -> None:
    """A 2 mm gate is narrower than the estimator's noise: detections miss their tracks and start new ones
    on the instances of tracks they take over, so from the second frame on the instances' detections
    differ from those of the default gate (half the extent of a cube, 5 cm)."""
    scene = load_scene(SCENES / "box_bin.yaml")
    bag = read_bag(REPO / "test" / "data" / "box_bin")
    default = bag_snapshots(bag, scene)
    narrow = bag_snapshots(bag, scene, association=AssociationSettings(gate=0.002))
    assert all(len(s.detections) >= 5 for s in default)
    assert narrow[0].detections == default[0].detections  # the first frame's births
    later = [s.detections for s in default[1:]]
    assert sum(a != b for a, b in zip([s.detections for s in narrow[1:]], later, strict=False)) > len(later) / 2


@pytest.mark.parametrize(
    ("grid", "message"),
    [
        ("association.nope=1", "association.nope is no association setting"),
        ("association.gate=-0.1", "association.gate must be a non-negative number"),
        ("association.confirm_hits=0.5", "association.confirm_hits must be a whole number of at least 1"),
        ("association.tentative_misses=0", "association.tentative_misses must be a whole number of at least 1"),
    ],
)
def test_a_bad_association_setting_is_refused(grid: str, message: str) -> None:
    with pytest.raises(InputError, match=message):
        grid_settings(load_scene(SCENES / "box_bin.yaml").search, [grid])


SUNK_BOX_SCENE = """\
static:
  - {name: floor, shape: plane}
objects:
  - {name: box, shape: box, size: [0.1, 0.1, 0.1], mass: 0.2}
search:
  fallback: refine
"""


def test_the_map_scored_is_the_settled_one_a_refined_map_not_the_hypotheses_it_started_from(tmp_path: Path) -> None:
    """A box detected 2 cm into the floor, its only hypothesis: no valid configuration, so the map is
    ``fallback: refine``'s, the box on the floor. Identity metrics score that map, as the node publishes it on
    ``/tf`` and ``~/objects`` by default, not the hypothesis it started from (1.5 cm from the truth: beyond a
    1 cm gate, a miss and a false positive)."""
    (tmp_path / "scene.yaml").write_text(SUNK_BOX_SCENE)
    scene = load_scene(tmp_path / "scene.yaml")
    with BagWriter(tmp_path / "bag") as writer:
        writer.write(GROUND_TRUTH_TOPIC, POSE_ARRAY, 1, pose_array_cdr(1, "world", [make_pose((0.0, 0.0, 0.05))]))
        writer.write(poses_topic("box"), POSE_ARRAY, 2, pose_array_cdr(2, "world", [make_pose((0.0, 0.0, 0.035))]))
    (result,) = replay_offline(read_bag(tmp_path / "bag", input_topics(scene)), scene, None)
    assert result.search is not None and result.search.fallback == "refine"
    assert result.settled is not None and result.settled[0].position[2] == pytest.approx(0.05, abs=0.002)
    frame = record_frames([snapshot_result_dict(result, ObjectClasses.of(scene))])
    assert frame[0].estimate == {"box": list(result.settled[0].position)}
    figures = identity_metrics(frame, gate=0.01)
    assert figures is not None and (figures["misses"], figures["false_positives"]) == (0, 0)


TWO_BOXES_SCENE = """\
static:
  - {name: floor, shape: plane}
objects:
  - {name: box, shape: box, size: [0.1, 0.1, 0.1], mass: 0.2, count: {max: 2}}
search:
  fallback: refine
  strategy: joint
  bound: absolute
  probability_threshold: 0.95
"""


def test_the_offline_replay_follows_a_first_map_made_at_held_poses(tmp_path: Path) -> None:
    """Two boxes side by side, each pose of each 1-1.3 cm into the other, in two arrays. The search checks its root
    alone (its bound); the first snapshot's map is the check's, the boxes where the refined map rests them (their
    *held* poses), valid. The replay scores that map with the check's hypotheses, whose held ranks its code names,
    and learns from it as the node does: the next snapshot starts from a valid map, not a refined one."""
    (tmp_path / "scene.yaml").write_text(TWO_BOXES_SCENE)
    scene = load_scene(tmp_path / "scene.yaml")
    left = RankedHypotheses.from_weighted(
        [Hypothesis(make_pose((0.0, 0.0, 0.05)), 0.9), Hypothesis(make_pose((0.003, 0.0, 0.05)), 0.1)]
    )
    right = RankedHypotheses.from_weighted(
        [Hypothesis(make_pose((0.09, 0.0, 0.05)), 0.9), Hypothesis(make_pose((0.088, 0.0, 0.05)), 0.1)]
    )
    truth = [make_pose((-0.005, 0.0, 0.05)), make_pose((0.095, 0.0, 0.05))]
    with BagWriter(tmp_path / "bag") as writer:
        writer.write(GROUND_TRUTH_TOPIC, POSE_ARRAY, 1, pose_array_cdr(1, "world", truth))
        for time_ns in (1_000_000_000, 2_000_000_000):
            writer.write_detections(time_ns, time_ns, "world", [("box", left, ""), ("box", right, "")])
    first, second = replay_offline(read_bag(tmp_path / "bag", input_topics(scene)), scene, None)
    assert first.search is not None and first.search.valid and first.search.previous_map and first.code is not None
    ranked = first.snapshot.hypotheses
    assert all(hypotheses.held_rank() == rank for hypotheses, rank in zip(ranked, first.code, strict=True))
    figures = identity_metrics(record_frames([snapshot_result_dict(first, ObjectClasses.of(scene))]))
    assert figures is not None and (figures["misses"], figures["false_positives"]) == (0, 0)
    assert second.snapshot.remembered and not second.snapshot.remembered_refined

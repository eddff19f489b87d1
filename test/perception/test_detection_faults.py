"""The simulated estimator's faults (``generate --format detections``): each option does what it says, seeded.

Hypotheses are built by hand around the box bin's true poses, so these tests need no physics; the last
ones run ``generate`` itself.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import SCENES

from physics_mapper.bags.storage import detections_from_cdr, read_bag
from physics_mapper.cli import main
from physics_mapper.mapping.detections import RECORDED_DETECTIONS_TOPIC
from physics_mapper.model.extents import body_box, inside_static
from physics_mapper.model.geometry import make_pose, translation_distance
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses
from physics_mapper.model.scene import Scene, object_radius
from physics_mapper.model.scene_files import load_scene, scene_from_dict
from physics_mapper.perception.detection_faults import DetectionFaults, DetectionSimulator, SimulatedDetection

BIN = SCENES / "box_bin.yaml"
LEGO = "package://pybullet_data/lego/lego.obj"
FRAMES = 200


@pytest.fixture(scope="module")
def scene() -> Scene:
    return load_scene(BIN)


def hypotheses(scene: Scene) -> tuple[RankedHypotheses, ...]:
    """Five hypotheses per object, 1 mm apart along x, weights 5:4:3:2:1."""
    assert scene.ground_truth is not None
    return tuple(
        RankedHypotheses.from_weighted(
            [
                Hypothesis(make_pose((p.position[0] + k * 0.001, *p.position[1:]), p.orientation), 5.0 - k)
                for k in range(5)
            ]
        )
        for p in scene.ground_truth
    )


def frames(scene: Scene, faults: DetectionFaults, seed: int = 0, count: int = FRAMES) -> list[list[SimulatedDetection]]:
    assert scene.ground_truth is not None
    simulator = DetectionSimulator(scene, scene.ground_truth, faults, np.random.default_rng(seed), top_m=5)
    given = hypotheses(scene)
    return [simulator.frame(given) for _ in range(count)]


def test_without_faults_every_object_once_in_scene_order_as_given(scene: Scene) -> None:
    for frame in frames(scene, DetectionFaults(), count=3):
        assert [d.source for d in frame] == list(range(6))
        assert {d.kind for d in frame} == {"object"} and {d.id for d in frame} == {""}
        assert {d.class_id for d in frame} == {"box"}
        assert [d.hypotheses for d in frame] == list(hypotheses(scene))


def test_shuffle_reorders_the_same_detections_and_a_seed_repeats_it(scene: Scene) -> None:
    shuffled = frames(scene, DetectionFaults(shuffle=True), count=20)
    orders = {tuple(d.source for d in frame) for frame in shuffled}
    assert len(orders) > 10 and all(sorted(o for o in order if o is not None) == list(range(6)) for order in orders)
    assert all(None not in order for order in orders)
    assert frames(scene, DetectionFaults(shuffle=True), count=20) == shuffled
    assert frames(scene, DetectionFaults(shuffle=True), seed=1, count=20) != shuffled


def test_misses_leave_out_objects_at_their_rate(scene: Scene) -> None:
    detected = sum(len(frame) for frame in frames(scene, DetectionFaults(miss=0.1)))
    assert 0.85 < detected / (6 * FRAMES) < 0.95
    assert all(frame == [] for frame in frames(scene, DetectionFaults(miss=1.0), count=5))


def test_false_positives_float_in_the_air_or_lie_inside_a_static_body(scene: Scene) -> None:
    assert scene.ground_truth is not None
    radius = object_radius(scene.objects[0].shape)
    top = max(p.position[2] for p in scene.ground_truth)
    walls = {body.pose.position for body in scene.static if body.name != "floor"}
    found = [d for frame in frames(scene, DetectionFaults(false_positive=0.1)) for d in frame if d.source is None]
    assert 0.05 < len(found) / (6 * FRAMES) < 0.15
    kinds = Counter(d.kind for d in found)
    assert set(kinds) == {"air", "static"} and 0.35 < kinds["air"] / len(found) < 0.65
    for detection in found:
        assert detection.class_id == "box" and 1 <= len(detection.hypotheses) <= 5
        x, y, z = np.mean([h.pose.position for h in detection.hypotheses.hypotheses], axis=0)
        if detection.kind == "air":
            assert z > top + 1.5 * radius
        else:  # a wall's centre, or half a radius under the floor
            near_wall = any(np.linalg.norm(np.subtract((x, y, z), wall)) < 0.03 for wall in walls)
            assert near_wall or z < -radius / 2 + 0.03
    only_air = [
        d.kind
        for frame in frames(scene, DetectionFaults(false_positive=0.5, air_share=1.0), count=20)
        for d in frame
        if d.source is None
    ]
    assert only_air and set(only_air) == {"air"}


def test_a_double_detection_is_the_object_again_moved_sideways(scene: Scene) -> None:
    found = 0
    for frame in frames(scene, DetectionFaults(double=0.05, double_offset=0.006)):
        for index, detection in enumerate(frame):
            if detection.kind != "double":
                continue
            found += 1
            original = frame[index - 1]
            assert original.kind == "object" and original.source == detection.source
            for moved, kept in zip(detection.hypotheses.hypotheses, original.hypotheses.hypotheses, strict=True):
                assert moved.weight == kept.weight
                assert translation_distance(moved.pose, kept.pose) == pytest.approx(0.006)
                assert moved.pose.position[2] == kept.pose.position[2]
    assert 0.03 < found / (6 * FRAMES) < 0.07


def test_a_wrong_pose_ranks_first_at_its_rate_and_the_result_counts_stay_in_range(scene: Scene) -> None:
    given = hypotheses(scene)
    wrong = counted = 0
    counts: Counter[int] = Counter()
    for frame in frames(scene, DetectionFaults(wrong_first=0.25, wrong_offset=0.03, results_min=3, results_max=5)):
        for detection in frame:
            counted += 1
            counts[len(detection.hypotheses)] += 1
            first = detection.hypotheses.pose(1)
            assert detection.source is not None
            distance = translation_distance(first, given[detection.source].pose(1))
            if distance > 1e-9:
                wrong += 1
                assert distance == pytest.approx(0.03)
    assert set(counts) == {3, 4, 5}
    assert 0.2 < wrong / counted < 0.3


def test_confidence_scales_each_detection_s_scores_and_keeps_their_ratios(scene: Scene) -> None:
    faults = DetectionFaults(confidence=(0.7, 0.95), false_positive=0.2)
    tops = []
    for frame in frames(scene, faults, count=50):
        for detection in frame:
            ranked = detection.hypotheses
            tops.append(ranked.weight(1))
            if detection.source is not None:
                original = hypotheses(scene)[detection.source]
                ratios = [h.weight / ranked.weight(1) for h in ranked.hypotheses]
                assert ratios == pytest.approx([h.weight / original.weight(1) for h in original.hypotheses])
    assert min(tops) >= 0.7 and max(tops) <= 0.95 and max(tops) - min(tops) > 0.2


def test_ids_none_stable_and_reassigned(scene: Scene) -> None:
    faults = DetectionFaults(double=0.1, false_positive=0.1, miss=0.1, shuffle=True)
    assert {d.id for f in frames(scene, faults, count=20) for d in f} == {""}
    stable = frames(scene, DetectionFaults(**{**faults.__dict__, "ids": "stable"}), count=50)
    of_object: dict[int, set[str]] = {}
    others: list[str] = []
    for frame in stable:
        for d in frame:
            if d.kind == "object":
                assert d.source is not None
                of_object.setdefault(d.source, set()).add(d.id)
            else:
                others.append(d.id)
    assert all(len(ids) == 1 for ids in of_object.values()) and len(of_object) == 6
    object_ids = set.union(*of_object.values())
    assert len(object_ids) == 6 and not object_ids & set(others) and len(set(others)) == len(others)
    changing = frames(scene, DetectionFaults(ids="reassigned", id_change=1.0), count=5)
    ids = [d.id for frame in changing for d in frame]
    assert len(set(ids)) == len(ids) == 30
    some = frames(scene, DetectionFaults(ids="reassigned", id_change=0.1), count=50)
    per_object = Counter(len({d.id for f in some for d in f if d.source == i}) for i in range(6))
    assert sum(n * c for n, c in per_object.items()) > 6  # some objects got new ids


def test_generate_writes_the_faults_into_the_bag_and_a_seed_repeats_it(tmp_path: Path) -> None:
    arguments = [
        "generate", str(BIN), "--format", "detections", "--iterations", "6", "--particles", "100",
        "--sigma", "0.005", "--shuffle", "--miss", "0.2", "--false-positives", "0.2", "--double", "0.2",
        "--wrong-first", "0.25", "--results", "3-5", "--ids", "stable", "--seed", "4",
    ]  # fmt: skip
    assert main([*arguments, "-o", str(tmp_path / "a")]) == 0
    assert main([*arguments, "-o", str(tmp_path / "b")]) == 0
    bags = [read_bag(tmp_path / name, (RECORDED_DETECTIONS_TOPIC,)) for name in ("a", "b")]
    raws = [[m.raw for m in bag.messages] for bag in bags]
    assert raws[0] == raws[1] and len(raws[0]) == 6
    arrays = [detections_from_cdr(raw, bags[0].definitions) for raw in raws[0]]
    sizes = [len(a.detections) for a in arrays]
    assert sizes != [6] * 6  # misses, doubles and false positives change the count
    assert all(3 <= len(d.results) <= 5 and d.id.startswith("track_") for a in arrays for d in a.detections)


def test_fault_options_need_the_detections_format_and_rates_are_checked(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["generate", str(BIN), "-o", str(tmp_path / "a"), "--miss", "0.1"]) == 2
    assert "--miss is for --format detections" in capsys.readouterr().err
    assert main(["generate", str(BIN), "-o", str(tmp_path / "b"), "--format", "detections", "--double", "1.5"]) == 2
    assert "double must be a probability in [0, 1], got 1.5" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_a_false_positive_inside_a_static_body_has_its_body_there_whatever_its_origin(scene: Scene) -> None:
    """pybullet_data's lego part has its origin at a corner of its body: a false positive inside a wall or under
    the floor has the middle of its body there, not its origin (which would leave the body mostly outside)."""
    lego = scene_from_dict(
        {"objects": [{"name": "lego", "shape": "mesh", "file": LEGO, "scale": 0.1}], "static": []}, "lego"
    ).objects[0]
    legos = replace(scene, objects=tuple(replace(o, shape=lego.shape) for o in scene.objects))
    faults = DetectionFaults(false_positive=0.5, air_share=0.0, sigma_position=0.0)
    found = [d for frame in frames(legos, faults, count=20) for d in frame if d.source is None]
    assert found
    for detection in found:
        low, high = body_box(lego.shape, detection.hypotheses.pose(1))
        middle = (low + high) / 2.0
        assert any(inside_static(body, middle) for body in scene.static)

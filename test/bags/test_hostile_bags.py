"""Bags written to hurt: definitions that redefine a standard type, do not parse or are too long, and a
``metadata.yaml`` beyond its cap. Each is one error line naming the bag, exit 2, offline and live alike
(both read the bag, definitions included, before anything else).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import SCENES
from ros_helpers import one_error_line, run_cli
from rosbags.rosbag2 import Writer

from physics_mapper.bags.storage import MAX_METADATA_BYTES, detections_cdr
from physics_mapper.bags.vision_msgs import DEFINITIONS, MAX_DEFINITION_BYTES
from physics_mapper.mapping.detections import DETECTION_ARRAY, RECORDED_DETECTIONS_TOPIC
from physics_mapper.model.geometry import Pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses

PYRAMID = SCENES / "pyramid.yaml"
SEPARATOR = "=" * 80
#: Every vision type the array uses, below it, as rosbag2 records a definition's tree.
TREE = "".join(
    f"{SEPARATOR}\nMSG: {name.replace('/msg/', '/')}\n{text}"
    for name, text in DEFINITIONS.items()
    if name != DETECTION_ARRAY
)


def detections_bag(path: Path, definition: str) -> Path:
    """A bag of one Detection3DArray (the pyramid's top cube) recorded with ``definition`` as its type's."""
    top = RankedHypotheses.from_weighted([Hypothesis(Pose((0.0, 0.0, 0.1)), 1.0)])
    with Writer(path, version=8) as writer:
        connection = writer.add_connection(
            RECORDED_DETECTIONS_TOPIC, DETECTION_ARRAY, msgdef=definition, rihs01="RIHS01_" + "0" * 64
        )
        writer.write(connection, 1_000, detections_cdr(1_000, "world", [("cube_top", top, "")]))
    return path


def replay(bag: Path) -> str:
    return one_error_line(run_cli("replay", str(bag), "--scene", str(PYRAMID), "--offline"), f"error: {bag}: ")


HOSTILE = {
    "redefines a standard type": (
        DEFINITIONS[DETECTION_ARRAY] + TREE + f"{SEPARATOR}\nMSG: geometry_msgs/PoseWithCovariance\nint32 nothing\n",
        "cannot be used: Type 'geometry_msgs/msg/PoseWithCovariance' is already present with different definition",
    ),
    "does not parse": ("int32[ x\n\x1b[31mfloat64 y = = 2\n", "cannot be used: Could not parse"),
    "is too long": (
        DEFINITIONS[DETECTION_ARRAY] + "# " + "x" * MAX_DEFINITION_BYTES + "\n" + TREE,
        f"bytes (at most {MAX_DEFINITION_BYTES})",
    ),
}


@pytest.mark.parametrize("case", HOSTILE)
def test_a_hostile_definition_is_one_error_line(tmp_path: Path, case: str) -> None:
    definition, fragment = HOSTILE[case]
    line = replay(detections_bag(tmp_path / "bag", definition))
    assert f"its definition of {DETECTION_ARRAY} " in line and fragment in line
    assert "\x1b" not in line


def test_the_bag_s_own_good_definition_still_decodes(tmp_path: Path) -> None:
    bag = detections_bag(tmp_path / "bag", DEFINITIONS[DETECTION_ARRAY] + TREE)
    completed = run_cli("replay", str(bag), "--scene", str(PYRAMID), "--offline")
    assert completed.returncode == 0, completed.stderr


def test_a_metadata_file_with_yaml_aliases_is_one_error_line(tmp_path: Path) -> None:
    bag = detections_bag(tmp_path / "bag", DEFINITIONS[DETECTION_ARRAY] + TREE)
    text = (bag / "metadata.yaml").read_text(encoding="utf-8")
    bomb = "x-anchors:\n  - &a [1, 2, 3]\n" + "  - [*a, *a, *a]\n" * 100
    (bag / "metadata.yaml").write_text(bomb + text, encoding="utf-8")
    assert "its metadata.yaml has YAML anchors or aliases" in replay(bag)


def test_a_metadata_file_beyond_its_cap_is_one_error_line(tmp_path: Path) -> None:
    bag = detections_bag(tmp_path / "bag", DEFINITIONS[DETECTION_ARRAY] + TREE)
    with (bag / "metadata.yaml").open("a", encoding="utf-8") as metadata:
        metadata.write(f"# {'x' * MAX_METADATA_BYTES}\n")
    assert f"metadata.yaml has {(bag / 'metadata.yaml').stat().st_size} bytes (at most {MAX_METADATA_BYTES})" in (
        replay(bag)
    )

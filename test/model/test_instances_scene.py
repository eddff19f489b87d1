"""Instances in scene files: ``count: K``, ``count: {max: K}``, ``names:``, and class maps of them."""

from __future__ import annotations

from typing import Any

import pytest

from physics_mapper.model.scene import Scene
from physics_mapper.model.scene_files import SceneError, scene_from_dict

BOX = {"shape": "box", "size": [0.1, 0.1, 0.1], "mass": 0.2}


def scene(*objects: dict[str, Any], **extra: Any) -> Scene:
    return scene_from_dict({"objects": list(objects), "static": [{"name": "floor", "shape": "plane"}], **extra}, "s")


def test_count_declares_identical_instances_named_after_the_entry() -> None:
    loaded = scene({"name": "box", "count": 3, **BOX}, {"name": "mug", "shape": "sphere", "radius": 0.05})
    assert loaded.object_names == ("box_1", "box_2", "box_3", "mug")
    assert len({id(o.shape) for o in loaded.objects[:3]}) == 1  # one shape shared by every instance
    assert loaded.objects_of_class("box") == ("box_1", "box_2", "box_3")
    assert loaded.is_tracked("box") and not loaded.is_tracked("mug")
    assert loaded.objects_of_class("mug") == ("mug",) and loaded.optional == frozenset()


def test_count_max_declares_optional_instances_and_names_may_be_listed() -> None:
    loaded = scene({"name": "part", "count": {"max": 2}, "names": ["left", "right"], **BOX})
    assert loaded.object_names == ("left", "right")
    assert loaded.optional == {"left", "right"}
    assert loaded.objects_of_class("part") == ("left", "right")
    single = scene({"name": "part", "count": {"max": 1}, **BOX})
    assert single.is_tracked("part")  # an optional object may be there or not: its detections are tracked


def test_a_class_map_may_name_a_count_entry_or_list_separate_objects() -> None:
    mapped = scene({"name": "box", "count": 2, **BOX}, class_map={"obj_000001": "box"})
    assert mapped.objects_of_class("obj_000001") == ("box_1", "box_2") and mapped.objects_of_class("box") == ()
    listed = scene({"name": "a", **BOX}, {"name": "b", **BOX}, class_map={"cube": ["a", "b"]})
    assert listed.is_tracked("cube") and listed.objects_of_class("cube") == ("a", "b")


def test_named_objects_keep_their_meaning() -> None:
    loaded = scene({"name": "a", **BOX}, {"name": "b", **BOX})
    assert loaded.class_map == () and not loaded.is_tracked("a") and loaded.objects_of_class("b") == ("b",)


@pytest.mark.parametrize(
    ("entry", "problem"),
    [
        ({"count": 0}, r"objects\[0\]\.count: must be a whole number in \[1, "),
        ({"count": {"max": 2.5}}, r"objects\[0\]\.count\.max: must be a whole number"),
        ({"count": {"least": 2}}, r"objects\[0\]\.count\.least: unknown key"),
        ({"count": 2, "names": ["x"]}, r"objects\[0\]\.names: lists 1 names for count 2"),
        ({"names": ["x", "9y"]}, r"objects\[0\]\.names\[1\]: '9y': not a ROS topic name"),
    ],
)
def test_a_bad_count_is_one_error(entry: dict[str, Any], problem: str) -> None:
    with pytest.raises(SceneError, match="^s: " + problem):
        scene({"name": "box", **BOX, **entry})


def test_an_instance_name_may_not_clash_with_another_body() -> None:
    with pytest.raises(SceneError, match="duplicate body name 'box_1'"):
        scene({"name": "box", "count": 2, **BOX}, {"name": "box_1", **BOX})

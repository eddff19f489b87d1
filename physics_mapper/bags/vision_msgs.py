"""The ``vision_msgs`` 4.x (ROS 2 Jazzy) message definitions, for bags on machines without the package.

rosbags' Jazzy type store has no vision types. Bags recorded by rosbag2 carry their message
definitions, and those are what a bag's messages are decoded with (:func:`bag_typestore`); these
definitions serve bags without them (sqlite3 bags of older rosbag2) and the bags we write, which
then carry them too, as ``ros2 bag record`` would.
"""

from __future__ import annotations

from functools import lru_cache

from rosbags.interfaces import Connection, MessageDefinitionFormat
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from physics_mapper.model.limits import MAX_KEY_TEXT, clipped, printable

#: Message type -> its definition (``.msg``), dependencies before the types that use them.
DEFINITIONS = {
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/ObjectHypothesisWithPose": (
        "vision_msgs/ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n"
    ),
    "vision_msgs/msg/BoundingBox3D": "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
    "vision_msgs/msg/Detection3D": (
        "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
        "vision_msgs/BoundingBox3D bbox\nstring id\n"
    ),
    "vision_msgs/msg/Detection3DArray": "std_msgs/Header header\nvision_msgs/Detection3D[] detections\n",
}


def jazzy_typestore() -> Typestore:
    """rosbags' ROS 2 Jazzy type store with the vision types registered."""
    return _with_definitions(get_typestore(Stores.ROS2_JAZZY))


def _with_definitions(typestore: Typestore) -> Typestore:
    """``typestore`` with those of :data:`DEFINITIONS` it does not define yet."""
    for name, text in DEFINITIONS.items():
        if name not in typestore.types:
            typestore.register(get_types_from_msg(text, name))
    return typestore


#: A bag's own definitions of the vision types it records: (message type, ``.msg`` text) pairs.
BagDefinitions = tuple[tuple[str, str], ...]

#: Longest definition a bag may carry for one type, bytes. rosbag2 records a Detection3DArray's whole
#: tree of definitions, comments included, in a few kB (2 kB without); rosbags' parser takes time and memory
#: growing faster than the text (60,000 fields: 47 s, 752 MiB), measured at this cap in
#: ``BENCHMARKS.md`` ("Hostile inputs").
MAX_DEFINITION_BYTES = 32 * 1024


class DefinitionError(ValueError):
    """A bag's definition of a vision type cannot be used: too long, not ``.msg`` text, or redefining a
    standard type (its message is one line, naming the type)."""


def bag_definitions(connections: list[Connection]) -> BagDefinitions:
    """The ``.msg`` definitions a bag carries (as rosbag2 records them) of the vision types decoded here.

    Definitions of other types are never parsed: their messages are not decoded. Plain text, so that
    a bag in memory can be sent to another process (a pool or Ray worker).
    """
    found = {
        (c.msgtype, c.msgdef.data)
        for c in connections
        if c.msgtype in DEFINITIONS and c.msgdef.format == MessageDefinitionFormat.MSG and c.msgdef.data
    }
    return tuple(sorted(found))


#: Type stores kept for the bags' definitions last used: a process evaluating bags of many estimators
#: keeps at most this many (2.8 MiB, ``BENCHMARKS.md``, "Hostile inputs").
TYPESTORES_CACHED = 8


@lru_cache(maxsize=TYPESTORES_CACHED)
def bag_typestore(definitions: BagDefinitions) -> Typestore:
    """A store decoding the types of ``definitions`` as they say, the others as Jazzy and :data:`DEFINITIONS` do.

    Raises DefinitionError for a definition that is too long, cannot be parsed, or changes a type the
    store has (a standard type, or one of two definitions of the same type).
    """
    typestore = get_typestore(Stores.ROS2_JAZZY)
    for msgtype, text in definitions:
        size = len(text.encode("utf-8", "surrogateescape"))
        if size > MAX_DEFINITION_BYTES:
            raise DefinitionError(f"its definition of {msgtype} has {size} bytes (at most {MAX_DEFINITION_BYTES})")
        try:
            typestore.register(get_types_from_msg(text, msgtype))
        except Exception as error:  # rosbags' parser and store raise TypesysError, and others on garbage
            reason = clipped(printable(" ".join(str(error).split())), MAX_KEY_TEXT)
            raise DefinitionError(f"its definition of {msgtype} cannot be used: {reason}") from None
    return _with_definitions(typestore)

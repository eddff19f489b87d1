"""rosbag2 bags of hypotheses and results, written and read with the ``rosbags`` library.

Bags are mcap (the Jazzy default) or sqlite3, metadata version 9, messages CDR-serialised with
the ROS 2 Jazzy type store, so ``ros2 bag play`` / ``ros2 bag record`` on a ROS machine and
this module read each other's bags. Topics (absolute names, as ``ros2 bag record`` writes them):

* ``/hypotheses/<object>``: ``geometry_msgs/msg/PoseArray``, an object's hypotheses, ranked;
* ``/hypotheses/<object>/weights``: ``std_msgs/msg/Float64MultiArray``, one weight per pose;
* ``/ground_truth``: ``geometry_msgs/msg/PoseArray``, every object's true pose, in scene order.

Messages are kept as raw CDR bytes (what a publisher sends); :func:`pose_array_from_cdr` and
:func:`weights_from_cdr` turn one into core values, the only conversion from bag messages here;
:func:`decoding` names the bag, topic and time of a message that cannot be used. Reading is in
memory (:func:`read_bag`), of every topic or only of the topics a caller needs, or streamed
(:func:`stream_messages`, chunk by chunk, for a live replay of a bag of any size); :func:`bag_info`
reads a bag's topics, counts and offered QoS without its messages. Time stamps are integer nanoseconds.

Offered QoS: a topic is written with the QoS profiles its publishers offered (rosbag2's
``offered_qos_profiles``), so that ``ros2 bag play`` gives a latched topic to late subscribers
again; :func:`offered_qos` writes one of the node's :class:`~physics_mapper.mapping.topics.TopicQos`.

MCAP files written here carry CRCs of every chunk, of the data section and of the summary
(:mod:`physics_mapper.bags.mcap_storage`), and every CRC an MCAP file carries is checked before it
is read, so a damaged bag is reported rather than read as other messages. SQLite has no checksums.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sqlite3
from collections.abc import Collection, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType, TracebackType
from typing import Any, Final, Literal

import numpy as np
import yaml
from rosbags.interfaces import (
    Connection,
    ConnectionExtRosbag2,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Reader, ReaderError, StoragePlugin, Writer, WriterError
from rosbags.typesys.store import Typestore

from physics_mapper.bags.mcap_storage import ROS_DISTRO, ChecksummedMcapStorage, verify_checksums
from physics_mapper.bags.vision_msgs import (
    BagDefinitions,
    DefinitionError,
    bag_definitions,
    bag_typestore,
    jazzy_typestore,
)
from physics_mapper.mapping.detections import DETECTION_ARRAY, RECORDED_DETECTIONS_TOPIC
from physics_mapper.mapping.stamps import time_parts, to_nanoseconds
from physics_mapper.mapping.topics import (
    GROUND_TRUTH_TOPIC,
    TopicQos,
    recorded,
    recorded_poses_topic,
    recorded_weights_topic,
)
from physics_mapper.model.atomic_files import temporary_sibling
from physics_mapper.model.errors import InputError
from physics_mapper.model.geometry import Pose, Quaternion, Vector3, make_pose
from physics_mapper.model.hypotheses import Hypothesis, RankedHypotheses

Storage = Literal["mcap", "sqlite3"]
_PLUGINS = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
#: rosbag2 metadata version written (the one ROS 2 Jazzy writes).
BAG_VERSION: Final = 9
#: Largest ``metadata.yaml`` read, bytes. A bag of 300 topics (the node's inputs at 128 objects and
#: its outputs) with rosbag2's offered QoS profiles has about 210 kB of it (700 bytes a topic); rosbags
#: reads YAML in pure Python, about 0.07 MB/s on a loaded machine (8 MB of aliases: 23 s, 406 MiB;
#: aliases are refused now), measured at this cap in ``BENCHMARKS.md``, "Hostile inputs".
MAX_METADATA_BYTES = 256 * 1024

POSE_ARRAY = "geometry_msgs/msg/PoseArray"
WEIGHTS = "std_msgs/msg/Float64MultiArray"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"

TYPESTORE = jazzy_typestore()
_Time = TYPESTORE.types["builtin_interfaces/msg/Time"]
_Header = TYPESTORE.types["std_msgs/msg/Header"]
_Point = TYPESTORE.types["geometry_msgs/msg/Point"]
_Quaternion = TYPESTORE.types["geometry_msgs/msg/Quaternion"]
_Pose = TYPESTORE.types["geometry_msgs/msg/Pose"]
_PoseArray = TYPESTORE.types[POSE_ARRAY]
_Dimension = TYPESTORE.types["std_msgs/msg/MultiArrayDimension"]
_Layout = TYPESTORE.types["std_msgs/msg/MultiArrayLayout"]
_Float64MultiArray = TYPESTORE.types[WEIGHTS]


#: How rosbag2 writes an infinite (the default) deadline, lifespan or liveliness lease duration.
INFINITE = QosTime(9_223_372_036, 854_775_807)


class BagError(InputError, ValueError):
    """A bag cannot be used, read or written: unreadable, corrupt, truncated, mistyped topics, a full disk."""


def offered_qos(qos: TopicQos) -> Qos:
    """One of the node's topic QoS (:mod:`physics_mapper.mapping.topics`) as rosbag2 records an offered profile."""
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=qos.depth,
        reliability=QosReliability.RELIABLE if qos.reliable else QosReliability.BEST_EFFORT,
        durability=QosDurability.TRANSIENT_LOCAL if qos.transient_local else QosDurability.VOLATILE,
        deadline=INFINITE,
        lifespan=INFINITE,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=INFINITE,
        avoid_ros_namespace_conventions=False,
    )


@dataclass(frozen=True)
class BagMessage:
    """One recorded message: absolute ``topic``, ROS ``msgtype``, receive ``time_ns`` and raw CDR bytes."""

    topic: str
    msgtype: str
    time_ns: int
    raw: bytes


@dataclass(frozen=True)
class Bag:
    """A bag in memory: every topic's type (even without messages) and the messages read, by time."""

    path: Path
    topics: dict[str, str]
    messages: tuple[BagMessage, ...]
    #: The bag's own definitions of types Jazzy's store lacks, which decode its messages
    #: (:func:`~physics_mapper.bags.vision_msgs.bag_typestore`).
    definitions: BagDefinitions = ()

    def on(self, topic: str) -> tuple[BagMessage, ...]:
        """The messages of one topic, in time order."""
        return tuple(m for m in self.messages if m.topic == topic)


@dataclass(frozen=True)
class PoseArrayData:
    """A PoseArray's content as recorded: header ``stamp_ns``, ``frame_id`` and the poses unchecked.

    Each pose is ``((x, y, z), (qx, qy, qz, qw))``; a recorded pose may be invalid (NaN, zero
    quaternion), which the node's input rules, not the bag reader, decide about.
    """

    stamp_ns: int
    frame_id: str
    poses: tuple[tuple[Vector3, Quaternion], ...]

    def checked_poses(self) -> tuple[Pose, ...]:
        """The poses validated and normalised; raises BagError naming the first bad one."""
        checked = []
        for index, (position, orientation) in enumerate(self.poses):
            try:
                checked.append(make_pose(position, orientation))
            except ValueError as error:
                raise BagError(f"pose {index} of a PoseArray stamped {self.stamp_ns} ns: {error}") from None
        return tuple(checked)


def _deserialize(raw: bytes, msgtype: str, typestore: Typestore = TYPESTORE) -> Any:
    try:
        return typestore.deserialize_cdr(raw, msgtype)
    except Exception as error:
        # Garbage bytes fail in many ways inside the deserialiser (SerdeError, struct.error, IndexError, ...).
        raise BagError(f"a {msgtype} message is not valid CDR ({error})") from None


def pose_array_from_cdr(raw: bytes) -> PoseArrayData:
    """Deserialise a CDR ``geometry_msgs/msg/PoseArray``; raises BagError for bytes that are not one."""
    message = _deserialize(raw, POSE_ARRAY)
    stamp = message.header.stamp
    poses = tuple(
        (
            (p.position.x, p.position.y, p.position.z),
            (p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w),
        )
        for p in message.poses
    )
    return PoseArrayData(to_nanoseconds(stamp.sec, stamp.nanosec), message.header.frame_id, poses)


def detections_from_cdr(raw: bytes, definitions: BagDefinitions = ()) -> Any:
    """Deserialise a CDR ``vision_msgs/msg/Detection3DArray`` as a bag's ``definitions`` define it (none: as
    Jazzy's vision_msgs does); BagError for bad bytes."""
    return _deserialize(raw, DETECTION_ARRAY, bag_typestore(definitions))


def weights_from_cdr(raw: bytes) -> tuple[float, ...]:
    """Deserialise a CDR ``std_msgs/msg/Float64MultiArray`` into its data; raises BagError for bad bytes."""
    return tuple(float(w) for w in _deserialize(raw, WEIGHTS).data)


def pose_array_cdr(stamp_ns: int, frame_id: str, poses: Sequence[Pose]) -> bytes:
    """A CDR ``geometry_msgs/msg/PoseArray`` with header stamp ``stamp_ns`` and ``frame_id``."""
    sec, nanosec = time_parts(stamp_ns)
    stamp = _Time(sec=sec, nanosec=nanosec)
    header = _Header(stamp=stamp, frame_id=frame_id)
    message = _PoseArray(
        header=header,
        poses=[_Pose(position=_Point(*pose.position), orientation=_Quaternion(*pose.orientation)) for pose in poses],
    )
    return bytes(TYPESTORE.serialize_cdr(message, POSE_ARRAY))


def detections_cdr(stamp_ns: int, frame_id: str, detections: Sequence[tuple[str, RankedHypotheses, str]]) -> bytes:
    """A CDR ``vision_msgs/msg/Detection3DArray``: one Detection3D per (class id, hypotheses, id), as a pose
    estimator would publish them (no covariance, the box centred on the most likely pose, of size 0; an
    empty id as estimators without a tracker leave it)."""
    types = TYPESTORE.types
    sec, nanosec = time_parts(stamp_ns)
    header = _Header(stamp=_Time(sec=sec, nanosec=nanosec), frame_id=frame_id)

    def pose(value: Pose) -> Any:
        return _Pose(position=_Point(*value.position), orientation=_Quaternion(*value.orientation))

    def result(class_id: str, hypothesis: Hypothesis) -> Any:
        return types["vision_msgs/msg/ObjectHypothesisWithPose"](
            hypothesis=types["vision_msgs/msg/ObjectHypothesis"](class_id=class_id, score=hypothesis.weight),
            pose=types["geometry_msgs/msg/PoseWithCovariance"](
                pose=pose(hypothesis.pose), covariance=np.zeros(36, dtype=np.float64)
            ),
        )

    box = types["vision_msgs/msg/BoundingBox3D"]
    size = types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    message = types[DETECTION_ARRAY](
        header=header,
        detections=[
            types["vision_msgs/msg/Detection3D"](
                header=header,
                results=[result(class_id, h) for h in hypotheses.hypotheses],
                bbox=box(center=pose(hypotheses.pose(1)), size=size),
                id=detection_id,
            )
            for class_id, hypotheses, detection_id in detections
        ],
    )
    return bytes(TYPESTORE.serialize_cdr(message, DETECTION_ARRAY))


def weights_cdr(weights: Sequence[float]) -> bytes:
    """A CDR ``std_msgs/msg/Float64MultiArray`` with one dimension labelled ``hypotheses``."""
    layout = _Layout(dim=[_Dimension(label="hypotheses", size=len(weights), stride=len(weights))], data_offset=0)
    message = _Float64MultiArray(layout=layout, data=np.asarray(weights, dtype=np.float64))
    return bytes(TYPESTORE.serialize_cdr(message, WEIGHTS))


class _ChecksummedWriter(Writer):
    """rosbags' rosbag2 writer, its MCAP files written with checksums."""

    STORAGE_PLUGINS = MappingProxyType({**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: ChecksummedMcapStorage})


def _name_ros_distro(path: Path, storage: Storage) -> None:
    """Name :data:`ROS_DISTRO` as the recorder's distribution, as ``ros2 bag record`` does: in
    ``metadata.yaml`` and, for sqlite3, the schema table (the MCAP metadata record already names it)."""
    metadata = path / "metadata.yaml"
    document = yaml.safe_load(metadata.read_text(encoding="utf-8"))
    document["rosbag2_bagfile_information"]["ros_distro"] = ROS_DISTRO
    partial = metadata.with_suffix(".yaml.tmp")
    partial.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    partial.replace(metadata)
    if storage == "sqlite3":
        for database in path.glob("*.db3"):
            with contextlib.closing(sqlite3.connect(database)) as connection, connection:
                connection.execute("UPDATE schema SET ros_distro = ?", (ROS_DISTRO,))


class BagWriter:
    """Writes a new bag (mcap, with checksums, or sqlite3); topics are added on their first message.

    Use as a context manager; refuses (BagError) a path that already exists. The bag is written
    whole or not at all: into a hidden folder beside ``path``, moved to ``path`` once its metadata
    is written; a failure (a full disk, an exception in the block) removes it, and ``path`` never
    holds a bag without metadata. Write errors are BagErrors naming the bag.
    """

    def __init__(self, path: str | Path, storage: Storage = "mcap") -> None:
        self.path = Path(path)
        if self.path.exists() or self.path.is_symlink():
            raise BagError(f"cannot write bag {self.path}: it exists already")
        self._holder = temporary_sibling(self.path, "partial")
        try:
            self._storage = storage
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._holder.mkdir(mode=0o777)
            self._writer = _ChecksummedWriter(
                self._holder / self.path.name, version=BAG_VERSION, storage_plugin=_PLUGINS[storage]
            )
            self._writer.open()
        except (WriterError, OSError) as error:
            shutil.rmtree(self._holder, ignore_errors=True)
            raise BagError(f"cannot write bag {self.path}: {_reason(error)}") from None
        self._connections: dict[str, Connection] = {}
        self._closed = False

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, traceback: TracebackType | None
    ) -> None:
        if kind is None:
            self.close()
        else:
            self.discard()

    def close(self) -> None:
        """Write the metadata, close the storage file and move the bag into place (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._writer.storage is not None:
                self._writer.close()
                _name_ros_distro(self._holder / self.path.name, self._storage)
            if self.path.exists():
                raise FileExistsError(f"{self.path} appeared while the bag was written")
            os.rename(self._holder / self.path.name, self.path)
        except (WriterError, OSError) as error:
            raise BagError(f"cannot write bag {self.path}: {_reason(error)} (nothing written)") from None
        finally:
            shutil.rmtree(self._holder, ignore_errors=True)

    def discard(self) -> None:
        """Stop writing and remove what was written: ``path`` is left as it was (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._writer.storage is not None:
                self._writer.close()
        except Exception:  # the partial bag is removed whatever closing it raised
            pass
        finally:
            shutil.rmtree(self._holder, ignore_errors=True)

    def add_topic(self, topic: str, msgtype: str, offered: Sequence[Qos] = ()) -> None:
        """Add a topic with the QoS profiles its publishers offered (rosbag2's ``offered_qos_profiles``)."""
        if topic in self._connections:
            raise BagError(f"topic {topic} is already in {self.path}")
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=TYPESTORE, offered_qos_profiles=offered
        )

    def write(self, topic: str, msgtype: str, time_ns: int, raw: bytes) -> None:
        """Append one raw CDR message received at ``time_ns`` (a new topic is added without offered QoS)."""
        if topic not in self._connections:
            self.add_topic(topic, msgtype)
        connection = self._connections[topic]
        if connection.msgtype != msgtype:
            raise BagError(f"topic {topic} was written as {connection.msgtype}, not {msgtype}")
        try:
            self._writer.write(connection, time_ns, raw)
        except (WriterError, OSError) as error:
            raise BagError(f"cannot write bag {self.path}: {_reason(error)}") from None

    def write_detections(
        self, time_ns: int, stamp_ns: int, frame_id: str, detections: Sequence[tuple[str, RankedHypotheses, str]]
    ) -> None:
        """At ``time_ns``, one ``vision_msgs/Detection3DArray`` stamped ``stamp_ns``: a Detection3D per
        (class id, hypotheses, id), its results the hypotheses with their weights as scores."""
        raw = detections_cdr(stamp_ns, frame_id, detections)
        self.write(RECORDED_DETECTIONS_TOPIC, DETECTION_ARRAY, time_ns, raw)

    def write_hypotheses(
        self, time_ns: int, stamp_ns: int, frame_id: str, object_name: str, hypotheses: RankedHypotheses
    ) -> None:
        """At ``time_ns``, an object's ranked hypotheses (a PoseArray stamped ``stamp_ns``); 1 ns later its weights."""
        poses = [h.pose for h in hypotheses.hypotheses]
        self.write(recorded_poses_topic(object_name), POSE_ARRAY, time_ns, pose_array_cdr(stamp_ns, frame_id, poses))
        weights = [h.weight for h in hypotheses.hypotheses]
        self.write(recorded_weights_topic(object_name), WEIGHTS, time_ns + 1, weights_cdr(weights))


def _reason(error: BaseException) -> str:
    """An OS or writer error on one line: ``No space left on device``."""
    if isinstance(error, OSError) and error.strerror:
        return error.strerror
    return " ".join(str(error).split())


@contextmanager
def _reading(path: Path, verify: bool = True) -> Iterator[Reader]:
    """An open reader of the bag at ``path`` whose MCAP checksums (if ``verify``) matched; BagError otherwise.

    Any error while the reader is in use becomes a one-line BagError naming the bag.
    """
    if not path.exists():
        raise BagError(f"{path}: no such bag")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise BagError(
            f"{path}: no metadata.yaml: not a rosbag2 bag, or its recording did not end cleanly "
            "(`ros2 bag reindex` rebuilds it)"
        )
    if path.is_dir():
        _check_metadata(path)
    try:
        if verify:
            for storage_file in sorted(path.glob("*.mcap")) if path.is_dir() else [path]:
                if storage_file.suffix == ".mcap":
                    verify_checksums(storage_file)
        with Reader(path) as reader:
            yield reader
    except BagError:
        raise
    except Exception as error:
        # A damaged file surfaces as whatever layer notices it first (a ChecksumError, ReaderError,
        # apsw's CorruptError, struct.error, OverflowError, ...); the try holds only bag-reading calls.
        raise _unreadable(path, error) from None


def _check_metadata(bag: Path) -> None:
    """Refuse (BagError) a ``metadata.yaml`` over :data:`MAX_METADATA_BYTES` or with YAML anchors or aliases
    (rosbag2 writes none; expanding them is what makes a small file cost minutes), before rosbags reads it.

    Its tokens are scanned by libyaml (no document is built: 0.04 s for 500 kB); text that does not
    scan is left for rosbags to report.
    """
    metadata = bag / "metadata.yaml"
    size = metadata.stat().st_size
    if size > MAX_METADATA_BYTES:
        raise BagError(f"{bag}: its metadata.yaml has {size} bytes (at most {MAX_METADATA_BYTES})")
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        tokens = yaml.scan(metadata.read_text(encoding="utf-8"), Loader=loader)
        if any(isinstance(token, yaml.AnchorToken | yaml.AliasToken) for token in tokens):
            raise BagError(f"{bag}: its metadata.yaml has YAML anchors or aliases, which rosbag2 never writes")
    except (yaml.YAMLError, UnicodeDecodeError):
        return


def _unreadable(path: Path, error: Exception) -> BagError:
    """The error of a bag that cannot be read, on one line (YAML errors span several)."""
    text = " ".join(str(error).split())
    if isinstance(error, ReaderError) and text.startswith("Serialization format"):
        return BagError(f"{path}: cannot read bag: {text} (only cdr, rosbag2's default, is)")
    return BagError(f"{path}: cannot read bag (corrupt or truncated?): {text}")


def _wanted(reader: Reader, topics: Collection[str] | None) -> list[Connection]:
    return [c for c in reader.connections if topics is None or recorded(c.topic) in topics]


def read_bag(path: str | Path, topics: Collection[str] | None = None) -> Bag:
    """Read an mcap or sqlite3 bag: the messages of ``topics`` (absolute names; None: of every topic).

    :attr:`Bag.topics` lists every topic of the bag with its type, read or not. Raises BagError
    if the bag is missing, corrupt or truncated, or an MCAP file's bytes fail a checksum it carries.
    """
    path = Path(path)
    with _reading(path) as reader:
        types = {recorded(c.topic): c.msgtype for c in reader.connections}
        definitions = bag_definitions(list(reader.connections))
        try:
            bag_typestore(definitions)  # parsed once here, so that a bad one is the bag's error
        except DefinitionError as error:
            raise BagError(f"{path}: {error}") from None
        wanted = _wanted(reader, topics)
        # rosbags reads every connection when given none; no wanted connection means no message.
        messages = (
            [
                BagMessage(recorded(connection.topic), connection.msgtype, time_ns, bytes(raw))
                for connection, time_ns, raw in reader.messages(connections=wanted)
            ]
            if wanted
            else []
        )
    messages.sort(key=lambda m: m.time_ns)
    return Bag(path, types, tuple(messages), definitions)


def stream_messages(path: str | Path, topics: Collection[str], *, verify: bool = True) -> Iterator[BagMessage]:
    """The messages of ``topics`` in time order, read from the bag as they are asked for.

    rosbags reads an MCAP bag chunk by chunk (and SQLite row by row), so memory does not grow with
    the bag. ``verify`` checks the MCAP checksums first (a pass over the files); pass False for a
    bag :func:`read_bag` or :func:`bag_info` has just checked. Raises BagError as :func:`read_bag`.
    """
    path = Path(path)
    with _reading(path, verify) as reader:
        wanted = _wanted(reader, topics)
        if not wanted:
            return
        for connection, time_ns, raw in reader.messages(connections=wanted):
            yield BagMessage(recorded(connection.topic), connection.msgtype, time_ns, bytes(raw))


@dataclass(frozen=True)
class BagInfo:
    """A bag without its messages: each topic's type, message count and offered QoS profiles (absolute names)."""

    path: Path
    topics: dict[str, str]
    counts: dict[str, int]
    offered_qos: dict[str, tuple[Qos, ...]]


def bag_info(path: str | Path, *, verify: bool = True) -> BagInfo:
    """Read a bag's topics, message counts and offered QoS (checksums checked if ``verify``); BagError if unusable."""
    path = Path(path)
    topics: dict[str, str] = {}
    counts: dict[str, int] = {}
    offered: dict[str, tuple[Qos, ...]] = {}
    with _reading(path, verify) as reader:
        for connection in reader.connections:
            topic = recorded(connection.topic)
            topics[topic] = connection.msgtype
            counts[topic] = counts.get(topic, 0) + connection.msgcount
            if isinstance(connection.ext, ConnectionExtRosbag2):
                offered[topic] = (*offered.get(topic, ()), *connection.ext.offered_qos_profiles)
    return BagInfo(path, topics, counts, offered)


def message_counts(path: str | Path) -> dict[str, int]:
    """Each topic's message count (absolute names) as the bag's metadata states it, without reading messages.

    Raises BagError if the bag is missing or its metadata or storage cannot be opened.
    """
    return bag_info(path, verify=False).counts


@contextmanager
def decoding(bag: Bag, message: BagMessage) -> Iterator[None]:
    """Re-raise a BagError raised while using ``message`` as one naming the bag, the topic and the time."""
    try:
        yield
    except BagError as error:
        raise BagError(f"{bag.path}: {message.topic} at {message.time_ns} ns: {error}") from None


class BagMismatch(BagError):
    """A bag that reads fine but is not one of the scene's: its hypothesis topics are missing or mistyped."""


def check_hypothesis_topics(bag: Bag, object_names: Sequence[str]) -> None:
    """Require a PoseArray topic with messages for every object; weights and ground truth, if there, typed right.

    Raises BagMismatch naming the bag, the topic and the problem.
    """
    expected = {GROUND_TRUTH_TOPIC: POSE_ARRAY}
    for name in object_names:
        expected[recorded_poses_topic(name)] = POSE_ARRAY
        expected[recorded_weights_topic(name)] = WEIGHTS
    for topic, msgtype in expected.items():
        found = bag.topics.get(topic)
        if found is not None and found != msgtype:
            raise BagMismatch(f"{bag.path}: topic {topic} has type {found}, expected {msgtype}")
    found = bag.topics.get(RECORDED_DETECTIONS_TOPIC)
    if found is not None and found != DETECTION_ARRAY:
        topic = RECORDED_DETECTIONS_TOPIC
        raise BagMismatch(f"{bag.path}: topic {topic} has type {found}, expected {DETECTION_ARRAY}")
    if bag.on(RECORDED_DETECTIONS_TOPIC):
        return  # which objects the detections hold is known once they are decoded (the snapshots)
    missing = [recorded_poses_topic(name) for name in object_names if not bag.on(recorded_poses_topic(name))]
    if missing:
        present = ", ".join(sorted(bag.topics)) or "none"
        raise BagMismatch(f"{bag.path}: no messages on {', '.join(missing)} (topics in the bag: {present})")

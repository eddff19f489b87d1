"""MCAP files with checksums: written with the official ``mcap`` library, every checksum verified on read.

rosbags writes MCAP chunks without their CRC (the field is 0, "not computed"), and reads a chunk's
CRC only when it reads that chunk, never the data-section or summary CRC. So damaged bytes in a
bag could be read as different messages, or a damaged chunk index could drop messages, silently.

Writing: :class:`ChecksummedMcapStorage` is a storage back end for rosbags' ``Writer`` (its
``STORAGE_PLUGINS`` protocol), so rosbags still writes the rosbag2 ``metadata.yaml`` and the
connections, while the ``mcap`` library writes the ``.mcap`` file with a CRC-32 of every chunk,
of the whole data section and of the summary (chunk indexes, statistics).

Reading: :func:`verify_checksums` reads the whole file with the ``mcap`` library, checking every
chunk CRC and the data-section CRC, and checks the summary CRC (MCAP specification: the summary
section and the footer up to its ``summary_crc`` field). A CRC of 0 means "not computed" and is
skipped: ``ros2 bag record`` (rosbag2's MCAP plugin) writes chunk and summary CRCs but no data CRC.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import IO

import yaml
from mcap.records import Chunk, DataEnd, Footer
from mcap.stream_reader import CRCValidationError, StreamReader, get_chunk_data_stream
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.interfaces import Connection, ConnectionExtRosbag2, MessageDefinitionFormat
from rosbags.rosbag2 import CompressionMode

#: The ROS distribution written bags name as their recorder's (rosbags would write "rosbags").
ROS_DISTRO = "jazzy"
#: Uncompressed bytes per chunk (rosbags' and the mcap library's choice too).
CHUNK_SIZE = 1024 * 1024
#: MCAP's magic bytes, which open and close a file.
_MAGIC_SIZE = 8
#: Bytes of the footer record: opcode (1), length (8), summary_start (8), summary_offset_start (8), summary_crc (4).
_FOOTER_SIZE = 29
_CRC_SIZE = 4


class ChecksummedMcapStorage:
    """Storage back end for rosbags' ``Writer``: the ``.mcap`` file written with CRCs by the ``mcap`` library."""

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        self.path = path / f"{path.name}.mcap"
        self._file: IO[bytes] = self.path.open("xb")
        self._writer = McapWriter(
            self._file,
            chunk_size=CHUNK_SIZE,
            compression=CompressionType.ZSTD if compression == CompressionMode.STORAGE else CompressionType.NONE,
            enable_crcs=True,  # chunks and summary
            enable_data_crcs=True,
        )
        self._writer.start(profile="ros2", library=f"physics_mapper (mcap {version('mcap')})")
        self._schemas: dict[str, int] = {}  # message type -> schema id
        self._channels: dict[int, int] = {}  # rosbags connection id -> channel id

    def add_msgtype(self, connection: Connection) -> None:
        msgdef = connection.msgdef
        encoding = "ros2msg" if msgdef.format == MessageDefinitionFormat.MSG else "ros2idl"
        schema_id = self._writer.register_schema(connection.msgtype, encoding, msgdef.data.encode())
        self._schemas[connection.msgtype] = schema_id

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        assert isinstance(connection.ext, ConnectionExtRosbag2)
        self._channels[connection.id] = self._writer.register_channel(
            connection.topic,
            connection.ext.serialization_format,
            self._schemas[connection.msgtype],
            {"offered_qos_profiles": offered_qos_profiles},
        )

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        self._writer.add_message(self._channels[connection.id], timestamp, bytes(data), timestamp)

    def close(self, version: int, metadata: str) -> None:
        """Write the rosbag2 metadata record (as ``ros2 bag record`` does), the summary and the footer."""
        self._writer.add_metadata("rosbag2", {"serialized_metadata": with_ros_distro(metadata)})
        self._writer.finish()  # type: ignore[no-untyped-call]  # unannotated in mcap 1.6
        self._file.close()

    def abort(self) -> None:
        self._file.close()


def with_ros_distro(metadata: str) -> str:
    """rosbag2 metadata YAML naming :data:`ROS_DISTRO` as the distribution that recorded it."""
    data = yaml.safe_load(metadata)
    data["ros_distro"] = ROS_DISTRO
    return str(yaml.safe_dump(data, sort_keys=False))


@dataclass(frozen=True)
class VerifiedChecksums:
    """Which checksums an MCAP file carried, all of which matched: chunks with a CRC (of ``chunks``), data, summary."""

    chunks: int
    chunks_with_crc: int
    data_section: bool
    summary: bool


class ChecksumError(ValueError):
    """An MCAP file's bytes do not match a checksum it carries, or it is not MCAP at all."""


def verify_checksums(path: Path) -> VerifiedChecksums:
    """Read ``path`` whole and check every CRC it carries; raise :class:`ChecksumError` at the first mismatch."""
    chunks = chunks_with_crc = 0
    data_section = False
    footer: Footer | None = None
    with path.open("rb") as file:
        # No record is longer than the file: a damaged length field must not make the reader allocate more.
        reader = StreamReader(file, validate_crcs=True, emit_chunks=True, record_size_limit=path.stat().st_size)
        try:
            # Chunks are emitted whole and checked here: cheaper than parsing every message record.
            for record in reader.records:
                if isinstance(record, Chunk):
                    chunks += 1
                    chunks_with_crc += record.uncompressed_crc != 0
                    get_chunk_data_stream(record, validate_crc=True)
                elif isinstance(record, DataEnd):
                    data_section = record.data_section_crc != 0
                elif isinstance(record, Footer):
                    footer = record
        except CRCValidationError as error:
            what = "chunk" if isinstance(error.record, Chunk) else "data section"
            raise ChecksumError(f"{path.name}: {what} checksum mismatch: the file is damaged") from None
        except Exception as error:  # a damaged structure surfaces as whatever the parser meets first
            raise ChecksumError(f"{path.name}: not a readable MCAP file ({' '.join(str(error).split())})") from None
        if footer is None:
            raise ChecksumError(f"{path.name}: no MCAP footer: the file is truncated")
        summary = footer.summary_crc != 0
        if summary and _summary_crc(file, footer) != footer.summary_crc:
            raise ChecksumError(f"{path.name}: summary checksum mismatch: the file's index is damaged")
    return VerifiedChecksums(chunks, chunks_with_crc, data_section, summary)


def _summary_crc(file: IO[bytes], footer: Footer) -> int:
    """CRC-32 of the summary section and the footer up to its summary_crc field (all of the footer's
    fields before it when there is no summary)."""
    size = file.seek(0, 2)
    start = footer.summary_start or size - _MAGIC_SIZE - _FOOTER_SIZE
    file.seek(start)
    return zlib.crc32(file.read(size - _MAGIC_SIZE - _CRC_SIZE - start))

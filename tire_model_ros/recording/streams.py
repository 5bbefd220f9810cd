"""The storages ``BagWriter`` streams messages into, one class per storage (``STORAGES``).

Each writes one rosbag2 bag folder ``bag`` (created by the storage) holding ``<name>.mcap`` or
``<name>.db3`` and, on ``close``, metadata.yaml. Both keep what was written safe from a
SIGKILL up to their last ``flush_due`` period: the MCAP storage writes complete chunks (with
their CRCs) at least every ``mcap_stream.FLUSH_S`` seconds, the sqlite3 storage commits its
transaction as often. A killed writer's folder has no metadata.yaml; ``read_raw(...,
salvage=True)`` reads it.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from tire_model_ros.recording import cdr
from tire_model_ros.recording.mcap_stream import FLUSH_S, McapStreamWriter
from tire_model_ros.recording.metadata import TopicStats, rosbag2_metadata

if TYPE_CHECKING:
    from rosbags.interfaces import Connection


class Storage(Protocol):
    """What ``BagWriter`` needs of a storage."""

    file: Path  # the storage file inside the bag folder

    def add_topic(self, topic: str, msgtype: str, msgdef: str) -> None: ...

    def write(self, topic: str, log_ns: int, data: bytes | memoryview) -> None: ...

    def flush_due(self) -> None: ...

    def close(self, topics: list[TopicStats]) -> None: ...

    def abort(self) -> None: ...


class McapStorage:
    """MCAP through this package's streaming writer (chunk and data CRCs, flushed chunks)."""

    def __init__(self, bag: Path, chunk_bytes: int) -> None:
        bag.mkdir()
        self.bag = bag
        self.file = bag / f"{bag.name}.mcap"
        self.writer = McapStreamWriter(self.file, chunk_bytes=chunk_bytes)
        self.ids: dict[str, int] = {}

    def add_topic(self, topic: str, msgtype: str, msgdef: str) -> None:
        self.ids[topic] = self.writer.add_channel(topic, msgtype, msgdef)

    def write(self, topic: str, log_ns: int, data: bytes | memoryview) -> None:
        self.writer.write(self.ids[topic], log_ns, data)

    def flush_due(self) -> None:
        self.writer.flush_due()

    def close(self, topics: list[TopicStats]) -> None:
        import yaml

        info = rosbag2_metadata(self.file.name, topics)
        self.writer.close(yaml.safe_dump(info, sort_keys=False).strip())
        text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False)
        (self.bag / "metadata.yaml").write_text(text)

    def abort(self) -> None:
        self.writer.abort()


class Sqlite3Storage:
    """sqlite3 through rosbags' writer, its transaction committed every ``FLUSH_S`` seconds."""

    def __init__(self, bag: Path, chunk_bytes: int) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        del chunk_bytes  # sqlite3 has no chunks
        self.writer = Writer(bag, version=9, storage_plugin=StoragePlugin.SQLITE3)
        self.writer.open()
        self.file = bag / f"{bag.name}.db3"
        self.connections: dict[str, Connection] = {}
        self.committed = time.monotonic()

    def add_topic(self, topic: str, msgtype: str, msgdef: str) -> None:
        del msgdef  # rosbags takes the definition from the typestore
        self.connections[topic] = self.writer.add_connection(
            topic, msgtype, typestore=cdr.typestore()
        )

    def write(self, topic: str, log_ns: int, data: bytes | memoryview) -> None:
        self.writer.write(self.connections[topic], log_ns, data)

    def flush_due(self) -> None:
        if time.monotonic() - self.committed >= FLUSH_S:
            # rosbags commits only on close; its sqlite3 connection is an attribute of its
            # storage writer (rosbags 0.11)
            self.writer.storage.conn.commit()  # type: ignore[union-attr]
            self.committed = time.monotonic()

    def close(self, topics: list[TopicStats]) -> None:
        del topics  # rosbags writes metadata.yaml itself
        self.writer.close()

    def abort(self) -> None:
        self.writer.close()


#: storage name -> its class.
STORAGES: dict[str, type[McapStorage] | type[Sqlite3Storage]] = {
    "mcap": McapStorage,
    "sqlite3": Sqlite3Storage,
}

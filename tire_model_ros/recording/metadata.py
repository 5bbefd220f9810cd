"""A rosbag2 folder's metadata.yaml, and whether it agrees with the storage files.

metadata.yaml lists the storage files (``relative_file_paths``) and counts messages (in all,
per topic, per file in ``files`` from version 5). A file listed twice would be read twice (a
doubled recording), so it is an error, as is a count that disagrees with what the storage
files hold: the reader says which file or topic and both numbers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class BagMetadata:
    """The parts of metadata.yaml the reader checks (see the module docstring)."""

    path: Path  # the metadata.yaml
    version: int
    storage: str  # storage_identifier
    compressed: bool  # rosbag2 compression_mode set (file or message)
    files: tuple[str, ...]  # relative_file_paths as written
    message_count: int
    topic_counts: dict[str, int]
    file_counts: tuple[tuple[str, int], ...] | None  # ``files`` entries: (path, message_count)

    @staticmethod
    def load(folder: Path) -> BagMetadata | None:
        """The folder's metadata.yaml, or None when it lacks what is checked here (rosbags then
        validates it and says what is wrong)."""
        import yaml

        try:
            loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
            path = folder / "metadata.yaml"
            info = yaml.load(path.read_text(), Loader=loader)["rosbag2_bagfile_information"]
            return BagMetadata(
                path,
                int(info.get("version", 1)),
                str(info["storage_identifier"]),
                str(info.get("compression_mode") or "none").lower() != "none",
                tuple(str(f) for f in info["relative_file_paths"]),
                int(info["message_count"]),
                _topic_counts(info["topics_with_message_count"]),
                _file_counts(info.get("files")),
            )
        except Exception:  # any surprise: rosbags reads it and reports
            return None

    def storage_files(self) -> list[Path]:
        """The listed files, each once, in the order listed."""
        folder = self.path.parent
        return list(dict.fromkeys(folder / Path(f).name for f in self.files))

    def duplicates(self) -> list[str]:
        """One line per storage file listed more than once (the caller names metadata.yaml)."""
        lines = []
        names = [Path(f).name for f in self.files]
        for name in dict.fromkeys(names):
            if (k := names.count(name)) > 1:
                lines.append(
                    f"lists the data file {name} {k} times in relative_file_paths "
                    "(reading it each time would multiply the recording)"
                )
        entries = [Path(f).name for f, _ in self.file_counts or ()]
        for name in dict.fromkeys(entries):
            if (k := entries.count(name)) > 1:
                lines.append(f"lists the data file {name} {k} times in files")
        return lines

    def disagreements(
        self, total: int, topics: dict[str, int], per_file: dict[str, int] | None
    ) -> list[str]:
        """One line per count of metadata.yaml that the storage files do not hold (the caller
        names metadata.yaml).

        ``topics``: messages per topic found; ``per_file``: messages per file name found
        (None: not known per file).
        """
        lines = []
        if total != self.message_count:
            lines.append(f"message_count is {self.message_count}, the data files hold {total}")
        for topic in sorted(set(self.topic_counts) | set(topics)):
            said, held = self.topic_counts.get(topic, 0), topics.get(topic, 0)
            if said != held:
                lines.append(f"topic {topic}: message_count is {said}, the data files hold {held}")
        if self.file_counts is not None and per_file is not None:
            for name, said in self.file_counts:
                in_file = per_file.get(Path(name).name)
                if in_file is None:
                    lines.append(f"files lists {name}, not in relative_file_paths")
                elif said != in_file:
                    lines.append(f"file {name}: message_count is {said}, it holds {in_file}")
        return lines

    def simple_mcap(self) -> bool:
        """Uncompressed MCAP whose files all exist: read by this package's MCAP reader alone."""
        files = self.storage_files()
        return (
            self.version <= 9
            and self.storage == "mcap"
            and not self.compressed
            and bool(files)
            and all(f.is_file() and f.suffix == ".mcap" for f in files)
        )


def _topic_counts(entries: list[dict[str, Any]]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for entry in entries:
        name = str(entry["topic_metadata"]["name"])
        counts[name] = counts.get(name, 0) + int(entry["message_count"])
    return counts


def _file_counts(entries: list[dict[str, Any]] | None) -> tuple[tuple[str, int], ...] | None:
    if not entries:
        return None
    return tuple((str(e["path"]), int(e["message_count"])) for e in entries)


@dataclass(frozen=True)
class TopicStats:
    """What metadata.yaml says of one topic written: type, messages, first/last log time [ns]."""

    topic: str
    msgtype: str
    count: int
    first_ns: int
    last_ns: int


def _type_hash(msgtype: str) -> str:
    """RIHS01 hash of a type of the ROS 2 Jazzy typestore; "" for a type not in it."""
    from tire_model_ros.recording import cdr

    try:
        return str(cdr.typestore().hash_rihs01(msgtype))
    except Exception:  # a custom type (a salvaged bag's): rosbag2 accepts an empty hash
        return ""


def rosbag2_metadata(file_name: str, topics: Sequence[TopicStats]) -> dict[str, Any]:
    """metadata.yaml content (version 9) of one storage file, as rosbag2 / rosbags write it."""
    written = [t for t in topics if t.count]
    start = min((t.first_ns for t in written), default=0)
    duration = max((t.last_ns for t in written), default=0) - start if written else 0
    count = sum(t.count for t in topics)
    return {
        "version": 9,
        "storage_identifier": "sqlite3" if file_name.endswith(".db3") else "mcap",
        "relative_file_paths": [file_name],
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": count,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": t.topic,
                    "type": t.msgtype,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": [],
                    "type_description_hash": _type_hash(t.msgtype),
                },
                "message_count": t.count,
            }
            for t in topics
        ],
        "compression_format": "",
        "compression_mode": "",
        "files": [
            {
                "path": file_name,
                "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration},
                "message_count": count,
            }
        ],
        "custom_data": None,
        "ros_distro": "jazzy",
    }

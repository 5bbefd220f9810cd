"""A rosbag2 folder read whole: its metadata.yaml checked against its storage files, or (with
salvage) every readable storage file of it, a recorder's temporary folder included.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tire_model_ros.recording.errors import Damage, RecordingError
from tire_model_ros.recording.metadata import BagMetadata
from tire_model_ros.recording.raw import (
    Collector,
    Part,
    RawBag,
    Select,
    bag_of,
    msgdefs_of,
    read_storage_file,
)


def _one_line(lines: list[str]) -> str:
    return lines[0] + (f" (and {len(lines) - 1} more)" if len(lines) > 1 else "")


def _read_with_rosbags(path: Path, select: Select) -> tuple[RawBag, list[Part]]:
    """A folder through rosbags' Reader (sqlite3, rosbag2-compressed, metadata this package
    does not parse); uncompressed MCAP files then through this package's reader."""
    from rosbags.rosbag2 import Reader

    with Reader(path) as reader:  # validates metadata.yaml (version, files, plugin)
        # One storage reader per file of a split bag (an attribute of rosbags' concrete class).
        storages: list[Any] = reader.storage.storages  # type: ignore[attr-defined]
        plugin = type(storages[0]).__name__ if storages else ""
        storage = "sqlite3" if "Sqlite" in plugin else "mcap"
        connections = list(reader.connections)
        announced = reader.message_count
        compressed = reader.compression_mode
        files = [Path(s.path) for s in storages]
        collector: Collector | None = None
        if storage != "mcap" or compressed:
            collector = Collector(select)
            collector.add(reader.messages())
    if collector is not None and (collector.count >= announced or compressed):
        bag = RawBag(
            path,
            storage,
            collector.topics(),
            collector.table(connections),
            announced,
            collector.count,
            msgdefs=msgdefs_of(connections),
        )
        return bag, []
    # Uncompressed MCAP: read the files through their own index (fast). Also the fallback when
    # rosbags' metadata.yaml route yields too few messages: it matches the metadata's topics to
    # the storage file's including QoS, and yields nothing for a topic whose QoS differ.
    parts = [read_storage_file(f, select, salvage=False) for f in files]
    return bag_of(path, storage, parts, announced, fallback=collector is not None), parts


def read_folder(path: Path, select: Select, salvage: bool) -> RawBag:
    meta = BagMetadata.load(path)
    if salvage:
        return _salvage_dir(path, select, meta)
    if meta is not None and (duplicates := meta.duplicates()):
        raise RecordingError(f"{meta.path}: {_one_line(duplicates)}")
    if meta is not None and meta.simple_mcap():
        parts = [read_storage_file(f, select, False) for f in meta.storage_files()]
        bag = bag_of(path, "mcap", parts, meta.message_count)
    else:
        bag, parts = _read_with_rosbags(path, select)
    if meta is not None:
        per_file = {p.file.name: p.found for p in parts} if parts else None
        topics = {t: n for t, (_, n) in bag.all_topics.items()}
        if disagree := meta.disagreements(bag.messages_read, topics, per_file):
            raise RecordingError(f"{meta.path}: {_one_line(disagree)}")
    return bag


def storage_files_in(folder: Path) -> list[Path]:
    """Storage files of a folder without metadata.yaml: its own, else its subfolders' (the
    temporary folder of a recorder holds the bag folder)."""
    for pattern in ("", "*/"):
        files = sorted(folder.glob(f"{pattern}*.mcap")) + sorted(folder.glob(f"{pattern}*.db3"))
        if files:
            return files
    return []


def _count_notes(meta: BagMetadata, bag: RawBag, parts: list[Part]) -> list[Damage]:
    """What metadata.yaml counts that a salvaged bag does not hold: one line when parts were
    skipped (that explains it), else one per count."""
    topics = {t: n for t, (_, n) in bag.all_topics.items()}
    per_file = {p.file.name: p.found for p in parts}
    disagree = meta.disagreements(bag.messages_read, topics, per_file)
    if disagree and bag.damages:
        said = f"message_count is {meta.message_count}, {bag.messages_read} were recovered"
        return [Damage(meta.path, "metadata", f"{said} (the rest was skipped)")]
    return [
        Damage(meta.path, "metadata", f"{line} (the files' counts are used)") for line in disagree
    ]


def _salvage_dir(path: Path, select: Select, meta: BagMetadata | None) -> RawBag:
    """Every readable storage file of a folder, each once; what disagrees is noted."""
    notes: list[Damage] = []
    if meta is not None:
        notes += [Damage(meta.path, "metadata", f"{line}: read once") for line in meta.duplicates()]
        files = meta.storage_files()
        missing = [f for f in files if not f.is_file()]
        notes += [Damage(f, "file", "listed in metadata.yaml, missing") for f in missing]
        files = [f for f in files if f.is_file()]
    else:
        files = storage_files_in(path)
        what = f"no metadata.yaml: read {len(files)} storage file(s)"
        notes.append(Damage(path, "metadata", what))
    if not files:
        raise RecordingError(f"{path}: no storage file (.mcap, .db3) to salvage")
    parts = [read_storage_file(f, select, salvage=True) for f in files]
    storage = "sqlite3" if all(f.suffix == ".db3" for f in files) else "mcap"
    bag = bag_of(path, storage, parts, meta.message_count if meta else None)
    counts = _count_notes(meta, bag, parts) if meta is not None else []
    bag.damages = notes + bag.damages + counts
    bag.salvaged = True
    return bag

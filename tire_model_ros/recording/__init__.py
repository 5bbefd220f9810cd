"""Recordings (rosbag2 bags) as first-class data: read into aligned ``WheelSeries``, write back.

:mod:`.read` reads bags (MCAP, sqlite3) into raw and decoded topics and aligned wheels
(through :mod:`.raw` for storage files, :mod:`.folder` for rosbag2 folders and
:mod:`.mcap_scan` / :mod:`.mcap_index` for MCAP), checking every CRC the files carry and
metadata.yaml against them (a damaged bag is refused, or salvaged: ``salvage=True``; then
:mod:`.salvage` writes what was recovered as a new bag),
:mod:`.align` holds the one alignment rule of INTERFACE.md on stamp arrays, :mod:`.write`
writes bags atomically, :mod:`.info` summarises one, :mod:`.open` opens a bag or a
measurement file (TTC, TYDEX, CSV, imported on the fly) alike. No ROS import.
"""

from tire_model_ros.recording.align import hold_latest, latest_at_or_before, nearest
from tire_model_ros.recording.open import open_recording
from tire_model_ros.recording.read import (
    Channel,
    Damage,
    DamagedBagError,
    RawBag,
    RawTopic,
    RecordingError,
    decode_topic,
    find_wheels,
    read_raw,
    read_recording,
    wheels_from_raw,
)
from tire_model_ros.recording.series import WheelSeries
from tire_model_ros.recording.write import BagWriter, decimate_mask, write_recording, write_topics

__all__ = [
    "BagWriter",
    "Channel",
    "Damage",
    "DamagedBagError",
    "RawBag",
    "RawTopic",
    "RecordingError",
    "WheelSeries",
    "decimate_mask",
    "decode_topic",
    "find_wheels",
    "hold_latest",
    "latest_at_or_before",
    "nearest",
    "open_recording",
    "read_raw",
    "read_recording",
    "wheels_from_raw",
    "write_recording",
    "write_topics",
]

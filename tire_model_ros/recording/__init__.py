"""Recordings: rosbag2 read/write, alignment into ``WheelSeries``, and opening measurement
files in their place (``open_recording``)."""

from tire_model_ros.recording.bag import RecordingError, read_recording, write_recording
from tire_model_ros.recording.open import open_recording
from tire_model_ros.recording.series import WheelSeries

__all__ = ["RecordingError", "WheelSeries", "open_recording", "read_recording", "write_recording"]

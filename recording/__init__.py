"""Recordings in the EuRoC/ASL style: read, write (`docs/recording.md`)."""

from recording.reader import (
    FrameEntry,
    Recording,
    RecordingError,
    iter_timeline,
    read_groundtruth,
    read_groundtruth_file,
    read_recording,
)
from recording.writer import RecordingWriter

__all__ = [
    "FrameEntry",
    "Recording",
    "RecordingError",
    "RecordingWriter",
    "iter_timeline",
    "read_groundtruth",
    "read_groundtruth_file",
    "read_recording",
]

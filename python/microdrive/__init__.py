"""The microdrive firmware's spike tracker for SpikeInterface recordings.

    import microdrive
    sorting = microdrive.run_mhtc(recording, channel=0, interval_s=10.0, tracker="mhtc")
    sorting, intervals = microdrive.run_mhtc(recording, return_intervals=True)
    rec = microdrive.read_recording("out/session/recording.json")   # a recording in the project's format

run_mhtc writes the channel as a recording in the project's format, runs mhtc-replay on it and returns
a NumpySorting whose unit ids are the track IDs (docs/mhtc.md, python/README.md).
"""
from .recording import MicrodriveError, read_recording, read_sidecar, traces_uv, write_recording, write_samples
from .replay import (TRACKERS, find_replay, read_intervals, read_labels, run_mhtc, run_replay,
                     sorting_from_labels)

__all__ = ["MicrodriveError", "TRACKERS", "find_replay", "read_intervals", "read_labels", "read_recording",
           "read_sidecar", "run_mhtc", "run_replay", "sorting_from_labels", "traces_uv", "write_recording",
           "write_samples"]

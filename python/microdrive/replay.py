"""mhtc-replay from Python: find the executable, run it, read what it writes (docs/mhtc.md:
labels.csv `sample_index,interval,cluster,track_id`, intervals.jsonl, summary.json)."""
import csv
import json
import os
import shutil
import subprocess
import tempfile

import numpy as np

from .recording import MicrodriveError, read_sidecar, write_recording

TRACKERS = ("mhtc", "map-nn", "ml-nn", "gnn")
# package folder -> python/ -> the checkout; the build presets' bin folders, in order of preference
_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_BUILDS = ("release", "dev", "dev-asan")


def _runnable(p):
    return os.path.isfile(p) and os.access(p, os.X_OK)


def find_replay(executable=None):
    """Path of mhtc-replay: `executable` (a file or the folder holding it), else $MICRODRIVE_BIN (same),
    else ROOT/build/{release,dev,dev-asan}/bin next to this package, else PATH."""
    tried = []
    for given, what in ((executable, "executable argument"), (os.environ.get("MICRODRIVE_BIN"), "$MICRODRIVE_BIN")):
        if given:
            p = os.path.join(given, "mhtc-replay") if os.path.isdir(given) else given
            if _runnable(p):
                return p
            raise MicrodriveError(f"{p} ({what}): not an executable mhtc-replay")
    for b in _BUILDS:
        p = os.path.join(_ROOT, "build", b, "bin", "mhtc-replay")
        tried.append(p)
        if _runnable(p):
            return p
    p = shutil.which("mhtc-replay")
    if p:
        return p
    raise MicrodriveError("no mhtc-replay executable: tried " + ", ".join(tried) + " and PATH; build it "
                          f"(cd {_ROOT} && cmake --preset release && cmake --build --preset release -j2) or pass "
                          "executable= / set MICRODRIVE_BIN to build/<preset>/bin")


def run_replay(sidecar, out, tracker="mhtc", interval_s=None, channel=None, executable=None, extra=()):
    """Runs mhtc-replay on `sidecar` (a recording.json) into the folder `out` (created, emptied first).
    interval_s / channel: its --interval / --channel (None: its defaults). Returns the seconds it took.
    A failure raises MicrodriveError with the last lines of its output."""
    import time
    if tracker not in TRACKERS:
        raise MicrodriveError(f"tracker {tracker!r}: one of {', '.join(TRACKERS)}")
    exe = find_replay(executable)
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    cmd = [exe, "--recording", str(sidecar), "--out", str(out), "--tracker", tracker, "--quiet"]
    if interval_s is not None:
        cmd += ["--interval", repr(float(interval_s))]
    if channel is not None:
        cmd += ["--channel", str(int(channel))]
    cmd += list(extra)
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        tail = (p.stderr or p.stdout).strip().splitlines()[-5:]
        raise MicrodriveError(f"mhtc-replay exit {p.returncode}: {' | '.join(tail)} (command: {' '.join(cmd)})")
    return time.perf_counter() - t


def read_labels(out, online=False):
    """labels.csv (or labels_online.csv) of a replay folder: (sample_index, interval, cluster, track_id)
    as four int64 arrays."""
    path = os.path.join(out, "labels_online.csv" if online else "labels.csv")
    try:
        with open(path, newline="") as f:
            r = csv.reader(f)
            head = next(r, None)
            if head != ["sample_index", "interval", "cluster", "track_id"]:
                raise MicrodriveError(f"{path}: header {head!r}, expected sample_index,interval,cluster,track_id")
            rows = [tuple(int(v) for v in row) for row in r]
    except OSError as e:
        raise MicrodriveError(f"{path}: cannot read ({e})")
    except ValueError as e:
        raise MicrodriveError(f"{path}: not integers ({e})")
    a = np.array(rows, dtype=np.int64).reshape(-1, 4)
    return a[:, 0], a[:, 1], a[:, 2], a[:, 3]


def read_intervals(out):
    """intervals.jsonl of a replay folder: one dict per interval."""
    path = os.path.join(out, "intervals.jsonl")
    try:
        with open(path) as f:
            return [json.loads(line) for line in f if line.strip()]
    except (OSError, ValueError) as e:
        raise MicrodriveError(f"{path}: cannot read ({e})")


def sorting_from_labels(out, sampling_frequency, online=False):
    """A SpikeInterface NumpySorting of a replay folder's labels: one unit per track ID (spikes that no
    track took, track_id -1, are left out)."""
    import spikeinterface.core as si
    samples, _, _, tracks = read_labels(out, online)
    keep = tracks >= 0
    samples, tracks = samples[keep], tracks[keep]
    order = np.lexsort((tracks, samples))
    unit_ids = sorted(set(int(t) for t in tracks))
    return si.NumpySorting.from_samples_and_labels([samples[order]], [tracks[order]], sampling_frequency,
                                                   unit_ids=unit_ids)


def run_mhtc(recording, channel=0, interval_s=10.0, tracker="mhtc", executable=None, return_intervals=False,
             workdir=None, segment_index=0):
    """The firmware's tracker on one channel of a recording.

    recording: a SpikeInterface BaseRecording (any dtype; scaled to uV with its gains, or taken as uV
    without gains), written as a float32 recording in uV into a temporary folder; or the path of a
    recording in the project's format (recording.json or its folder), replayed as it is, with its own
    interval list when it has one.
    channel: the channel index (of the BaseRecording, or of the recording.json).
    interval_s: interval length where the recording has no interval list.
    tracker: mhtc, map-nn, ml-nn or gnn. executable: see find_replay.
    workdir: keep the recording and mhtc-replay's output there (default: a temporary folder, removed).

    Returns a NumpySorting (unit ids = track IDs, spike times in samples of the recording); with
    return_intervals=True, (sorting, intervals) where intervals is mhtc-replay's per-interval table
    (intervals.jsonl: start_sample, duration_s, n_spikes, clusters with their track IDs, ...)."""
    tmp = None
    if workdir is None:
        tmp = tempfile.mkdtemp(prefix="microdrive-")
        workdir = tmp
    try:
        if isinstance(recording, (str, os.PathLike)):
            side = read_sidecar(os.fspath(recording))
            sidecar, fs, ch = side["_path"], float(side["sampling_frequency"]), channel
        else:
            sidecar = write_recording(recording, os.path.join(workdir, "recording"), channel, segment_index)
            fs, ch = float(recording.get_sampling_frequency()), 0
        out = os.path.join(workdir, "replay")
        run_replay(sidecar, out, tracker, interval_s, ch, executable)
        sorting = sorting_from_labels(out, fs)
        if return_intervals:
            return sorting, read_intervals(out)
        return sorting
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)

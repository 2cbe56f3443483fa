"""A session's saved recording (docs/session.md "The recording").

microdrive-session in-process, 3 cycles of scenarios/single_neuron.yaml with --candump-samples, so that
candump.log also holds every REC_DATA frame. Then:
  - recording.bin is exactly the samples of those frames, in order;
  - recording.json: the FE_INFO sampling rate and gain, one interval per REC_REQ with its length and
    IntervalId, the TLM_STATUS cycle and depth after it, the last HALL_READING before its REC_END;
  - mhtc-replay opens it and finds, interval by interval, the spikes the controller reported;
  - SpikeInterface opens it (microdrive.read_recording) with the right rate, length, boundaries and uV.
The executables are $MD_BUILD_DIR/bin (ctest sets it), else build/release/bin.
"""
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import microdrive
from microdrive import canlog

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = pathlib.Path(os.environ.get("MD_BUILD_DIR", ROOT / "build" / "release")) / "bin"
CYCLES = 3
NAMES = ("FE_INFO", "REC_REQ", "REC_DATA", "REC_END", "HALL_READING", "TLM_STATUS")


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    out = tmp_path_factory.mktemp("session")
    p = subprocess.run([str(BIN / "microdrive-session"), "--scenario", str(ROOT / "scenarios" / "single_neuron.yaml"),
                        "--seed", "3", "--bus", "inproc", "--cycles", str(CYCLES), "--out", str(out),
                        "--candump-samples", "--no-lcm", "--no-score", "--quiet"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return out


@pytest.fixture(scope="module")
def frames(session):
    """(frame name, decoded signals, raw bytes) of candump.log in order, for the messages in NAMES."""
    db = canlog.load_dbc()
    return [(fr.name, canlog.decode(db, fr) if fr.name != "REC_DATA" else None, fr.data)
            for fr in canlog.frames(str(session / "candump.log"), NAMES, db)]


@pytest.fixture(scope="module")
def sidecar(session):
    with open(session / "recording.json") as f:
        return json.load(f)


def test_binary_is_the_recorded_samples(session, frames):
    want = b"".join(raw[4:4 + 2 * raw[1]] for name, _, raw in frames if name == "REC_DATA")
    got = (session / "recording.bin").read_bytes()
    assert len(got) == len(want) > 0
    assert got == want


def test_sidecar_rate_gain_and_intervals(session, frames, sidecar):
    info = next(m for name, m, _ in frames if name == "FE_INFO")
    assert sidecar["sampling_frequency"] == info["SampleRate_hz"]
    assert sidecar["gain_uV"] == pytest.approx(info["Gain_uV_per_lsb"], rel=1e-6)
    assert sidecar["dtype"] == "int16" and sidecar["num_channels"] == 1
    reqs = [m for name, m, _ in frames if name == "REC_REQ"]
    status = [m for name, m, _ in frames if name == "TLM_STATUS"]
    ivs = sidecar["intervals"]
    assert len(ivs) == len(reqs) == len(status) == CYCLES
    start = 0
    for iv, req, st in zip(ivs, reqs, status):
        assert iv["start_sample"] == start
        assert iv["num_samples"] == req["NumSamples"]
        assert iv["duration_s"] == pytest.approx(req["NumSamples"] / info["SampleRate_hz"])
        assert iv["interval_id"] == req["IntervalId"]
        assert iv["cycle"] == st["Cycle"]
        assert iv["depth_um"] == pytest.approx(st["Depth_um"], abs=1e-3)
        assert iv["complete"] is True
        start += iv["num_samples"]
    assert sidecar["num_samples"] == start
    # the Hall reading of each interval: the last HALL_READING before its REC_END
    hall, k = None, 0
    for name, m, _ in frames:
        if name == "HALL_READING":
            hall = m["RawCode"]
        elif name == "REC_END":
            assert ivs[k]["hall_code"] == hall is not None
            k += 1
    assert k == CYCLES
    # depth moves between cycles in this scenario (the controller steps down): the fields are per interval
    assert len({iv["depth_um"] for iv in ivs}) > 1


def test_replay_opens_it_and_sees_what_the_controller_saw(session, frames, tmp_path):
    out = tmp_path / "replay"
    microdrive.run_replay(session / "recording.json", out, executable=str(BIN))
    rows = microdrive.read_intervals(out)
    ivs = json.load(open(session / "recording.json"))["intervals"]
    assert [r["start_sample"] for r in rows] == [iv["start_sample"] for iv in ivs]
    assert [r["depth_um"] for r in rows] == pytest.approx([iv["depth_um"] for iv in ivs])
    assert [r["hall_code"] for r in rows] == [iv["hall_code"] for iv in ivs]
    # the same firmware chain on the same samples: the spikes the controller reported per cycle
    spikes = [m["NumSpikes"] for name, m, _ in frames if name == "TLM_STATUS"]
    assert [r["n_spikes"] for r in rows] == spikes


def test_spikeinterface_opens_it(session, sidecar):
    rec = microdrive.read_recording(session / "recording.json")
    assert rec.get_sampling_frequency() == sidecar["sampling_frequency"]
    assert rec.get_num_samples() == sidecar["num_samples"]
    assert rec.get_num_channels() == 1
    bounds = [(iv["start_sample"], iv["num_samples"]) for iv in rec.get_annotation("intervals")]
    assert bounds == [(iv["start_sample"], iv["num_samples"]) for iv in sidecar["intervals"]]
    raw = np.fromfile(session / "recording.bin", dtype="<i2")
    s0, n = bounds[1]
    uv = rec.get_traces(start_frame=s0, end_frame=s0 + n, return_in_uV=True)[:, 0]
    assert np.allclose(uv, raw[s0:s0 + n] * sidecar["gain_uV"], atol=1e-3)


def test_default_candump_has_no_samples_but_the_same_recording(session, tmp_path):
    out = tmp_path / "default"
    p = subprocess.run([str(BIN / "microdrive-session"), "--scenario", str(ROOT / "scenarios" / "single_neuron.yaml"),
                        "--seed", "3", "--bus", "inproc", "--cycles", str(CYCLES), "--out", str(out),
                        "--no-lcm", "--no-score", "--quiet"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    log = (out / "candump.log").read_text()
    assert " 400##" not in log and " 220#" in log and " 500##" in log
    assert (out / "recording.bin").read_bytes() == (session / "recording.bin").read_bytes()
    assert (out / "recording.json").read_text() == (session / "recording.json").read_text()

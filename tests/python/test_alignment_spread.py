"""tools/alignment/alignment_spread.py on a recording of known misalignment.

One unit with a sharp trough (3 samples wide) fires at random sampling
phases in white noise: cut on the sample of the minimum its windows spread
far beyond the noise along the slope, the parabola removes part of that and
the template step nearly all of it. A recording whose truth names no spike
of the unit is refused with the file and the reason.
"""
import json
import pathlib
import subprocess
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
TOOL = ROOT / "tools" / "alignment" / "alignment_spread.py"
FS = 30000


def _write(d, spikes_per_unit):
    rng = np.random.default_rng(3)
    n = FS * 20
    x = 10.0 * rng.standard_normal(n)
    rows = []
    k = np.arange(-12, 24)
    for i, t in enumerate(range(300, n - 300, 900)):
        phase = rng.uniform(-0.5, 0.5)
        u = (k - phase) / 3.0
        x[t + k] += -250.0 * np.exp(-0.5 * u * u) + 70.0 * np.exp(-0.5 * (u - 2.5) ** 2)
        if i < spikes_per_unit:
            rows.append(f"{t},0")
    np.round(x).astype("<i2").tofile(d / "recording.bin")
    (d / "recording.json").write_text(json.dumps({
        "sampling_frequency": FS, "num_channels": 1, "num_samples": n, "dtype": "int16",
        "gain_uV": 1.0, "offset_uV": 0.0, "file": "recording.bin"}))
    (d / "ground_truth.csv").write_text("sample_index,unit_id\n" + "\n".join(rows) + "\n")


def _run(d):
    return subprocess.run([sys.executable, str(TOOL), str(d), "--units", "0"], capture_output=True, text=True)


def test_template_step_removes_the_spread_along_the_slope(tmp_path):
    _write(tmp_path, 10000)
    r = _run(tmp_path)
    assert r.returncode == 0, r.stderr
    row = [line.split() for line in r.stdout.splitlines() if line.split()[:1] == ["0"]][0]
    # unit, spikes, then "largest / second" for minimum, parabola, template
    largest = [float(row[2]), float(row[5]), float(row[8])]
    assert int(row[1]) > 500
    assert largest[0] > 5.0            # half a sample of jitter on a sharp trough
    assert largest[1] < largest[0]     # the parabola helps
    assert largest[2] < 2.0            # the template step leaves about the noise
    assert largest[2] < 0.5 * largest[1]


def test_too_few_spikes_are_refused(tmp_path):
    _write(tmp_path, 3)
    r = _run(tmp_path)
    assert r.returncode != 0
    assert "unit 0: 3 spikes, at least 10 needed" in r.stderr

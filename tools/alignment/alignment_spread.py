#!/usr/bin/env python3
"""How far each unit's spike windows still spread along the waveform's slope
after sub-sample alignment, on a recording with ground truth.

A window cut a fraction of a sample early or late differs from the unit's
mean waveform along the waveform's time derivative (its slope). This program
cuts every ground-truth spike of the chosen units around its trough and
aligns the windows three ways: on the sample of the minimum (the thesis),
on the vertex of the parabola through the minimum and its neighbours (the
extractor's `subsample`), and with one Gauss-Newton step against the
windows' common template (firmware/core/signal/spike_align.h, the chain's).
The last two are numpy copies of the firmware's methods (Keys' cubic
convolution, a = -1/2). For each unit it prints the two largest eigenvalues
of its window covariance whitened by the noise covariance: the spread in the
unit's two most spread directions, in units of the noise there (1: no spread
beyond the noise). Misalignment shows as one large eigenvalue along the
slope; the amplitude's own variation (bursts, drift) is the other.

Recordings: the project's format (recording.json + recording.bin). Ground
truth: the simulator's truth.jsonl beside it (neurons by index, mapped onto
the recording's samples through the intervals of both files), or
SpikeInterface's ground_truth.csv (sample_index,unit_id; the external
evaluation's).

  alignment_spread.py DIR --units 0 [--intervals 100:170]
  alignment_spread.py out/external-eval/static-1004 --units 0,4,5,7
"""
import argparse
import csv
import json
import os
import sys

import numpy as np

D_W_MS = 1.15      # window length (sx_config_default)
PRE_MS = 0.4       # samples before the trough
MARGIN = 2         # raw samples on each side (SA_MARGIN)
SEARCH = (-10, 30)  # trough search around a ground-truth time, samples
MAX_SPIKES = 2000  # per unit, spread over the recording
PRE = [12]         # samples before the trough at the recording's rate (set in main)


def read_recording(d):
    meta = json.load(open(os.path.join(d, "recording.json")))
    if meta.get("num_channels", 1) != 1 or meta.get("dtype", "int16") != "int16":
        sys.exit(f"{d}/recording.json: one int16 channel expected")
    x = np.fromfile(os.path.join(d, meta.get("file", "recording.bin")), dtype="<i2").astype(float)
    return meta, x


def truth_spikes(d, meta, units, intervals):
    """Recording sample indices of every ground-truth spike of each unit."""
    spikes = {u: [] for u in units}
    gt_csv = os.path.join(d, "ground_truth.csv")
    if os.path.isfile(gt_csv):
        with open(gt_csv) as f:
            for r in csv.DictReader(f):
                if r["unit_id"] in spikes:
                    spikes[r["unit_id"]].append(int(r["sample_index"]))
        return {u: np.array(sorted(v)) for u, v in spikes.items()}
    truth = [json.loads(line) for line in open(os.path.join(d, "truth.jsonl"))]
    t_start = {r["interval"] - 1: r["start_sample"] for r in truth if r.get("type") == "interval"}
    rec = {iv["index"]: iv for iv in meta["intervals"]}
    lo, hi = intervals
    by_unit = {u: [] for u in units}
    for r in truth:
        if r.get("type") == "spike" and str(r["neuron"]) in by_unit:
            by_unit[str(r["neuron"])].append(r["sample"])
    for u, ts in by_unit.items():
        ts = np.array(sorted(ts))
        for k in range(lo, min(hi, len(rec))):
            if k not in t_start:
                continue
            a, n = t_start[k], rec[k]["num_samples"]
            inside = ts[(ts >= a) & (ts < a + n)]
            spikes[u].extend(list(inside - a + rec[k]["start_sample"]))
    return {u: np.array(sorted(v)) for u, v in spikes.items()}


def keys(raw, d_w, delta):
    """The raw row (MARGIN samples before the window) at j + delta, Keys' cubic convolution."""
    base = MARGIN - 1 if delta < 0 else MARGIN
    f = 1.0 + delta if delta < 0 else delta
    j = np.arange(d_w) + base
    p0, p1, p2, p3 = raw[j - 1], raw[j], raw[j + 1], raw[j + 2]
    return p1 + 0.5 * f * ((p2 - p0) + f * ((2 * p0 - 5 * p1 + 4 * p2 - p3) + f * (3 * (p1 - p2) + p3 - p0)))


def parabola(raw, i):
    a, b, c = raw[i - 1], raw[i], raw[i + 1]
    curv = a - 2 * b + c
    return float(np.clip(0.5 * (a - c) / curv, -0.5, 0.5)) if curv > 0 else 0.0


def slope(t):
    """Central differences, one-sided at the ends (as spike_align.c)."""
    s = np.zeros_like(t)
    s[1:-1] = 0.5 * (t[2:] - t[:-2])
    s[0], s[-1] = t[1] - t[0], t[-1] - t[-2]
    return s


def raw_rows(x, times, d_w, pre):
    rows = []
    for s in times:
        if s + SEARCH[0] < pre + MARGIN + 2 or s + SEARCH[1] + d_w + MARGIN + 2 > len(x):
            continue
        t = s + SEARCH[0] + int(np.argmin(x[s + SEARCH[0]:s + SEARCH[1]]))
        rows.append(x[t - pre - MARGIN:t - pre + d_w + MARGIN])
    return np.array(rows)


def on_minimum_and_parabola(rows, d_w):
    """The windows on the sample of the minimum and on the parabola's vertex."""
    at_min = rows[:, MARGIN:MARGIN + d_w]
    return at_min, np.array([keys(r, d_w, parabola(r, MARGIN + PRE[0])) for r in rows])


def template_step(rows, tmpl, d_w):
    """One Gauss-Newton step of each window's shift against a * tmpl, from the parabola's vertex."""
    ts = slope(tmpl)
    out = []
    for r in rows:
        d = parabola(r, MARGIN + PRE[0])
        w = keys(r, d_w, d)
        a = w @ tmpl / (tmpl @ tmpl)
        dd = d if a <= 0 else float(np.clip(d + ((a * tmpl - w) @ ts) / (a * (ts @ ts)), -1.0, 0.999))
        out.append(keys(r, d_w, dd))
    return np.array(out)


def noise_covariance(x, d_w, count):
    """Covariance of random windows that stay below 4 sigma (median(|x|)/0.6745): spike-free."""
    sigma = np.median(np.abs(x)) / 0.6745
    rng = np.random.default_rng(1)
    windows = []
    for _ in range(50 * count):
        s = int(rng.integers(0, len(x) - d_w))
        w = x[s:s + d_w]
        if np.max(np.abs(w)) < 4.0 * sigma:
            windows.append(w)
            if len(windows) == count:
                break
    return np.cov(np.array(windows).T)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recording", help="directory with recording.json and truth.jsonl or ground_truth.csv")
    ap.add_argument("--units", required=True, help="comma-separated unit ids (simulator: neuron index)")
    ap.add_argument("--intervals", default="0:1000000",
                    help="first:last interval of a simulator recording (default all)")
    ap.add_argument("--noise-windows", type=int, default=3000)
    args = ap.parse_args()
    meta, x = read_recording(args.recording)
    fs = float(meta["sampling_frequency"])
    d_w, pre = int(D_W_MS * 1e-3 * fs + 0.5), int(PRE_MS * 1e-3 * fs + 0.5)  # lround, as the firmware
    PRE[0] = pre
    lo, hi = (int(v) for v in args.intervals.split(":"))
    units = args.units.split(",")
    spikes = truth_spikes(args.recording, meta, units, (lo, hi))
    rows = {}
    for u in units:
        ts = spikes[u]
        if len(ts) > MAX_SPIKES:
            ts = ts[np.linspace(0, len(ts) - 1, MAX_SPIKES).astype(int)]
        rows[u] = raw_rows(x, ts, d_w, pre)
        if len(rows[u]) < 10:
            sys.exit(f"{args.recording}: unit {u}: {len(rows[u])} spikes, at least 10 needed")
    # the template is the mean of every unit's windows on the parabola's vertex, as in the firmware
    tmpl = on_minimum_and_parabola(np.vstack([rows[u] for u in units]), d_w)[1].mean(axis=0)
    noise_cov = noise_covariance(x, d_w, args.noise_windows)
    chol = np.linalg.cholesky(noise_cov)
    print(f"{args.recording}: {d_w}-sample windows; the two largest eigenvalues of each unit's window")
    print("covariance over the noise covariance (1: no spread beyond the noise in that direction)")
    print(f"{'unit':>6} {'spikes':>7} {'minimum':>13} {'parabola':>13} {'template':>13}")
    for u in units:
        at_min, par = on_minimum_and_parabola(rows[u], d_w)
        cells = []
        for w in (at_min, par, template_step(rows[u], tmpl, d_w)):
            white = np.linalg.solve(chol, np.linalg.solve(chol, np.cov(w.T)).T)
            top = np.sort(np.linalg.eigvalsh(white))[-2:]
            cells.append(f"{top[1]:.2f} / {top[0]:.2f}")
        print(f"{u:>6} {len(rows[u]):>7} {cells[0]:>13} {cells[1]:>13} {cells[2]:>13}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""External ground-truth evaluation: every tracker on recordings made by SpikeInterface's generators.

    .venv/bin/python tools/external_eval/external_eval.py run --build-dir build/release \\
        [--work out/external-eval] [--static 8] [--drifting 4] [--jobs 2] [--md docs/external-eval.md]
    .venv/bin/python tools/external_eval/external_eval.py report [--work DIR] --md PATH  # from results.json
    .venv/bin/python tools/external_eval/external_eval.py measure --build-dir DIR [--work DIR]  # CI bounds
    .venv/bin/python tools/external_eval/external_eval.py check   --build-dir DIR [--work DIR]  # CI check

`run` makes --static recordings with spikeinterface.core.generate_ground_truth_recording (seeds from
--static-seed, default 1000, upward) and --drifting ones with
spikeinterface.generation.generate_drifting_recording (seeds from --drifting-seed, default 2000), each
reduced to one channel with 2..5 visible units (recordings.py; a seed without such a channel is skipped
and reported), runs mhtc-replay with every tracker it offers (mhtc, map-nn, ml-nn, gnn; MHTC scored by
its final-lineage labels.csv and by labels_online.csv), the reference peer (peer_stonesoup.py, in this
Python unless --peer-python) and the whole-session oracle (scoring.py), scores them all against the
ground truth of the visible units, prints one line per recording and tracker, and writes WORK/results.json
and, with --md, the report (docs/external-eval.md).

`measure` / `check` run the CI subset (SUBSET below: one 60 s static recording, MHTC and the oracle) and
write / compare the bounds in tools/external_eval/thresholds.json with the evaluation suite's regression
mechanism (microdrive.evaluation: make_bounds, write_thresholds, check_bounds). Exit status: 0 ok, 1 a check
failed, 2 bad input or a failed tool run (the message names the file and the reason).
"""
import argparse
import concurrent.futures
import datetime
import json
import os
import platform
import shutil
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

import microdrive
import recordings  # this folder's: the script's own folder is on the path
import scoring
from microdrive import evaluation  # the bounds mechanism, shared with tools/eval/regression.py

REPLAY_TRACKERS = ["mhtc", "map-nn", "ml-nn", "gnn"]
TRACKERS = ["mhtc", "mhtc-online", "map-nn", "ml-nn", "gnn", "peer", "oracle", "oracle-thr"]
MAX_SPIKES = 512            # MD_MAX_SPIKES: detections the firmware stores per interval
DEFAULT_PEER = os.path.join(os.path.dirname(ROOT), "shared", "peers", "peer_stonesoup.py")
THRESHOLDS = os.path.join(HERE, "thresholds.json")

# CI subset: one short static recording, the first seed from 3000 up with 2..5 visible units whose mean
# waveforms are >= 10 noise levels apart (L2) on the channel, so that a merge of two look-alike units
# does not pin every figure at 0 and hide a regression.
SUBSET = {"kind": "static", "duration_s": 60.0, "seed_start": 3000, "min_nearest_x_noise": 10.0,
          "trackers": ["mhtc", "mhtc-online", "oracle"]}
# figure -> (direction, margin), the same rule as tools/eval/regression.py MARGINS
CI_MARGINS = {
    "mean_accuracy": ("min", 0.05),
    "min_unit_accuracy": ("min", 0.10),
    "tracks_issued": ("max", 2.0),
    "update_errors": ("max", 0.0),
    "visible_units": ("min", 0.0),
}


class EvalError(Exception):
    pass


def log(msg):
    print(msg, flush=True)


# ---------------------------------------------------------------------------------------------- runs

def replay_bin(args):
    """--replay, else BUILD_DIR/bin/mhtc-replay (microdrive.find_replay: the same clear error)."""
    try:
        return microdrive.find_replay(args.replay or os.path.join(args.build_dir, "bin"))
    except microdrive.MicrodriveError as e:
        raise EvalError(str(e))


def run_tool(cmd, what):
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        tail = (p.stderr or p.stdout).strip().splitlines()[-5:]
        raise EvalError(f"{what}: exit {p.returncode}: {' | '.join(tail)} (command: {' '.join(cmd)})")
    return time.perf_counter() - t


def run_replay(binary, recdir, tracker):
    try:
        s = microdrive.run_replay(os.path.join(recdir, "recording.json"), os.path.join(recdir, tracker), tracker,
                                  executable=binary)
    except microdrive.MicrodriveError as e:
        raise EvalError(f"mhtc-replay --tracker {tracker} on {recdir}: {e}")
    return tracker, s


def run_peer(python, peer, recdir):
    out = os.path.join(recdir, "peer")
    shutil.rmtree(out, ignore_errors=True)
    s = run_tool([python, peer, recdir, out], f"{peer} on {recdir}")
    return "peer", s


def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        raise EvalError(f"{path}: cannot read ({e})")


def replay_info(recdir, tracker):
    d = os.path.join(recdir, tracker)
    summ = read_json(os.path.join(d, "summary.json"))
    n_spikes, cap = [], 0
    with open(os.path.join(d, "intervals.jsonl")) as f:
        for ln, line in enumerate(f, start=1):
            try:
                n = json.loads(line)["n_spikes"]
            except (ValueError, KeyError):
                raise EvalError(f"{d}/intervals.jsonl:{ln}: not a JSON object with n_spikes")
            n_spikes.append(n)
            cap += n >= MAX_SPIKES
    return {"tracks_issued": summ.get("track_ids_issued"), "stats": summ.get("stats", {}),
            "step_ms_median": summ.get("step_ms_median"), "intervals": summ.get("intervals"),
            "intervals_at_spike_cap": cap}


# ------------------------------------------------------------------------------------ one recording

def evaluate_recording(rec, args, binary, trackers, prefix):
    """Run and score every tracker on one written recording directory. Returns the per-recording dict."""
    recdir = rec["dir"]
    side, raw, gt, units = recordings.load(recdir)
    fs, gain = float(side["sampling_frequency"]), float(side["gain_uV"])
    visible = [u["unit_id"] for u in units["units"] if u["visible"]]
    res = {"trackers": {}}
    jobs = [t for t in REPLAY_TRACKERS if t in trackers or (t == "mhtc" and
                                                              ("mhtc-online" in trackers or "oracle" in trackers))]
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as ex:
        futs = [ex.submit(run_replay, binary, recdir, t) for t in jobs]
        if "peer" in trackers:
            futs.append(ex.submit(run_peer, args.peer_python, args.peer, recdir))
        secs = {}
        for f in concurrent.futures.as_completed(futs):
            name, s = f.result()
            secs[name] = s

    def add(name, samples, ids, extra, s):
        sc = scoring.score(gt, visible, samples, ids, fs)
        accs = [sc[u]["accuracy"] for u in visible]
        res["trackers"][name] = dict(extra, units=sc, mean_accuracy=float(np.mean(accs)),
                                     ids_in_labels=int(len(np.unique(ids[ids >= 0]))), seconds=round(s, 2))
        log(f"{prefix} {name:<11} {s:6.1f} s  mean accuracy {np.mean(accs):.3f}  units "
            f"[{' '.join('%.2f' % a for a in accs)}]  tracks {extra.get('tracks_issued')}")

    for t in trackers:
        if t in REPLAY_TRACKERS or t == "mhtc-online":
            base = "mhtc" if t == "mhtc-online" else t
            fname = "labels_online.csv" if t == "mhtc-online" else "labels.csv"
            samples, ids = scoring.read_labels(os.path.join(recdir, base, fname))
            add(t, samples, ids, replay_info(recdir, base), secs[base])
        elif t == "peer":
            samples, ids = scoring.read_labels(os.path.join(recdir, "peer", "labels.csv"))
            ps = read_json(os.path.join(recdir, "peer", "summary.json"))["summary"]
            add(t, samples, ids, {"tracks_issued": ps.get("tracks_created")}, secs["peer"])
        elif t in ("oracle", "oracle-thr"):  # the oracle on MHTC's detections, or on the peer's threshold ones
            det = "mhtc" if t == "oracle" else "peer"
            tic = time.perf_counter()
            samples, _ = scoring.read_labels(os.path.join(recdir, det, "labels.csv"))
            ids = scoring.oracle(raw, gain, fs, samples, len(visible))
            add(t, samples, ids, {"tracks_issued": len(visible), "detections": det}, time.perf_counter() - tic)
    return res


def make_recording(kind, seed, duration, work, reuse):
    params = (recordings.static_params if kind == "static" else recordings.drifting_params)(duration, seed)
    d = os.path.join(work, f"{kind}-{seed}")
    uj = os.path.join(d, "units.json")
    if reuse and os.path.isfile(uj) and read_json(uj).get("params") == params:
        return d, read_json(uj)
    shutil.rmtree(d, ignore_errors=True)
    try:
        info = recordings.make(params, d)
    except recordings.RecordingError:
        raise
    except Exception as e:  # a generator failure: say which seed and why
        raise EvalError(f"{params['generator']} seed {seed}: {type(e).__name__}: {e}")
    return (d, info) if info is not None else (None, None)


def collect(kind, count, seed0, duration, args, binary, trackers, min_nearest=None):
    out, skipped, seed = [], [], seed0
    while len(out) < count:
        if seed >= seed0 + 20 * max(count, 1):
            raise EvalError(f"{kind}: only {len(out)} of {count} seeds from {seed0} have a channel with "
                            f"{recordings.MIN_VISIBLE}..{recordings.MAX_VISIBLE} visible units")
        tic = time.perf_counter()
        d, info = make_recording(kind, seed, duration, args.work, args.reuse)
        gen_s = time.perf_counter() - tic
        if d is None:
            skipped.append(seed)
            log(f"[{kind} seed {seed}] no channel with {recordings.MIN_VISIBLE}..{recordings.MAX_VISIBLE} "
                f"visible units ({gen_s:.1f} s), skipped")
            seed += 1
            continue
        vis = [u for u in info["units"] if u["visible"]]
        if min_nearest is not None and min(u["nearest_visible_x_noise"] for u in vis) < min_nearest:
            skipped.append(seed)
            log(f"[{kind} seed {seed}] two visible units closer than {min_nearest:g} noise levels, skipped")
            seed += 1
            continue
        prefix = f"[{kind} {len(out) + 1}/{count} seed {seed} ch {info['channel']}, {len(vis)} visible]"
        log(f"{prefix} generated in {gen_s:.1f} s, visible units at "
            f"{', '.join('%.1f' % u['amplitude_x_noise'] for u in vis)} x noise")
        rec = {"kind": kind, "seed": seed, "dir": d, "channel": info["channel"], "noise_uV": info["noise_uV"],
               "units": info["units"], "generate_s": round(gen_s, 2), "params": info["params"]}
        rec.update(evaluate_recording(rec, args, binary, trackers, prefix))
        out.append(rec)
        seed += 1
    return out, skipped


# --------------------------------------------------------------------------------------- summaries

def kind_summary(recs, trackers):
    s = {}
    for t in trackers:
        per_rec = [r["trackers"][t]["mean_accuracy"] for r in recs]
        units = [u["accuracy"] for r in recs for u in r["trackers"][t]["units"].values()]
        s[t] = {"mean_accuracy": float(np.mean(per_rec)) if per_rec else None,
                "unit_mean_accuracy": float(np.mean(units)) if units else None,
                "min_recording": float(np.min(per_rec)) if per_rec else None,
                "max_recording": float(np.max(per_rec)) if per_rec else None,
                "tracks_issued": int(sum(r["trackers"][t]["tracks_issued"] or 0 for r in recs)),
                "detected": float(np.mean([u["detected"] for r in recs for u in r["trackers"][t]["units"].values()]))
                if units else None,
                "labelled": float(np.mean([u["labelled"] for r in recs for u in r["trackers"][t]["units"].values()]))
                if units else None,
                "split_units": int(sum(u["ids"] > 1 for r in recs for u in r["trackers"][t]["units"].values())),
                "units": len(units)}
    return s


def acceptance(static, drifting, summ):
    """The project's acceptance targets as (label, measured text, pass) lines; None pass = not measurable."""
    lines = []

    def m(kind, t):
        v = summ.get(kind, {}).get(t, {})
        return v.get("mean_accuracy")

    def line(label, text, ok):
        lines.append({"target": label, "measured": text, "pass": ok})

    n_static = len(static)
    line("static: >= 8 recordings with 2-5 visible units", f"{n_static}", n_static >= 8)
    mh, orc, peer = m("static", "mhtc"), m("static", "oracle"), m("static", "peer")
    if None not in (mh, orc):
        line("static: MHTC mean accuracy >= 0.9 x oracle", f"{mh:.3f} vs 0.9 x {orc:.3f} = {0.9 * orc:.3f}",
             mh >= 0.9 * orc)
    if None not in (mh, peer):
        line("static: MHTC mean accuracy >= peer + 0.10", f"{mh:.3f} vs {peer:.3f} + 0.10 = {peer + 0.10:.3f}",
             mh >= peer + 0.10)
        bad = [f"seed {r['seed']} unit {u}: MHTC {r['trackers']['mhtc']['units'][u]['accuracy']:.2f}, peer "
               f"{r['trackers']['peer']['units'][u]['accuracy']:.2f}"
               for r in static for u in r["trackers"]["mhtc"]["units"]
               if r["trackers"]["mhtc"]["units"][u]["accuracy"] < 0.3
               and r["trackers"]["peer"]["units"][u]["accuracy"] > 0.5]
        line("static: no visible unit with MHTC < 0.3 where the peer > 0.5",
             "none" if not bad else "; ".join(bad), not bad)
    n_drift = len(drifting)
    line("drifting: >= 4 recordings", f"{n_drift}", n_drift >= 4)
    mh, orc, peer = m("drifting", "mhtc"), m("drifting", "oracle"), m("drifting", "peer")
    if mh is not None:
        line("drifting: MHTC mean accuracy >= 0.75", f"{mh:.3f}", mh >= 0.75)
    if None not in (mh, orc):
        line("drifting: MHTC mean accuracy > oracle", f"{mh:.3f} vs {orc:.3f}", mh > orc)
    if None not in (mh, peer):
        line("drifting: MHTC mean accuracy > peer", f"{mh:.3f} vs {peer:.3f}", mh > peer)
    return lines


# ------------------------------------------------------------------------------------------ report

def fmt(v, n=3):
    return "" if v is None else (f"{v:.{n}f}" if isinstance(v, float) else str(v))


def md_intro(a, data):
    """The title, what runs and how to regenerate."""
    a("# External evaluation: the trackers on SpikeInterface-generated recordings\n")
    a("Every tracker of `mhtc-replay` (MHTC and its baselines), the reference peer "
      "(`shared/peers/peer_stonesoup.py`: per-interval scikit-learn GMM + Stone Soup GNN tracker) and a "
      "whole-session oracle, side by side in one run, on one-channel recordings made by SpikeInterface's "
      "own generators (not by the project's simulator), scored with SpikeInterface's ground-truth "
      "comparison. This file is written by the tool; do not edit it by hand.\n")
    a("## Regenerate\n")
    a("```")
    a("cmake --preset release && cmake --build --preset release -j2 --target mhtc-replay")
    a("scripts/setup-venv.sh")
    a(data["command"])
    a("```\n")
    a(f"This run: {data['run_s'] / 60:.1f} min wall time on {data['machine']} ({data['jobs']} jobs; "
      f"generation {data['generate_s']:.0f} s, tracker runs and scoring the rest), "
      f"{data['date_utc']}, {data.get('tree', 'tree state not recorded')}, SpikeInterface {data['versions']['spikeinterface']}, "
      f"scikit-learn {data['versions']['sklearn']}, Stone Soup {data['versions']['stonesoup']}. "
      f"Per-run figures: `WORK/results.json`; the recordings and every tracker's outputs stay in WORK "
      f"(`{{static,drifting}}-SEED/`).\n")


def md_recordings(a, data):
    """The recordings: generators, channel, visibility, rates."""
    a("## Recordings\n")
    sp = recordings.static_params(data["duration_s"], 0)
    dp = recordings.drifting_params(data["duration_s"], 0)
    a(f"- **static**: `spikeinterface.core.generate_ground_truth_recording`, {sp['duration_s']:.0f} s, "
      f"{sp['sampling_frequency'] / 1000:.0f} kHz, {sp['num_units']} units on an 8-contact probe (2 columns × 4, "
      f"20 µm pitch), noise {sp['noise_uV']:.0f} µV (`noise_levels`), firing rates uniform in "
      f"{sp['firing_rates_hz'][0]:.0f}–{sp['firing_rates_hz'][1]:.0f} Hz per unit; seeds from "
      f"{data['static_seed']} up.")
    a(f"- **drifting**: `spikeinterface.generation.generate_drifting_recording`, same duration, rate, probe and "
      f"rates, {dp['num_units']} units, noise {dp['noise_uV']:.0f} µV (spatial decay 25 µm), rigid "
      f"±{dp['drift_um']:.0f} µm {dp['drift_mode']} along the probe from {dp['drift_start_s']:.0f} s, period "
      f"{dp['drift_period_s']:.0f} s (the generator's default schedule); seeds from {data['drifting_seed']} up.")
    a("- **Channel**: the first channel (lowest index) with 2–5 visible units; a seed without one is skipped "
      "(skipped seeds: static " + (", ".join(map(str, data["skipped"]["static"])) or "none") + "; drifting "
      + (", ".join(map(str, data["skipped"]["drifting"])) or "none") + "). Written as `recording.bin` (int16 "
      f"little-endian, gain {recordings.GAIN_UV} µV, the simulator's) + `recording.json` (`sampling_frequency`, "
      "`num_channels` 1, `num_samples`, `dtype`, `gain_uV`, `offset_uV`, `clipped_samples`; mhtc-replay "
      "reads the first four it needs and `gain_uV`; written by `microdrive.write_samples`, python/) + "
      "`ground_truth.csv` (`sample_index,unit_id`, every unit).")
    a(f"- **Visible**: the unit's mean waveform on the channel (average of the trace over its ground-truth spike "
      f"times, up to {recordings.MAX_MEAN_SPIKES} spread over the session, −1..+2 ms; with drift the session "
      f"mean) reaches {recordings.VISIBLE_X:.0f}× the channel's noise level, largest |value|. **Noise level** = "
      "median(|x|)/0.6745 of the whole channel in µV (spikes included; the peer's and most sorters' "
      "estimator). Only visible units are scored; the others stay in the signal as background spikes.")
    a("- Firing rates: SpikeInterface's static generator defaults to 15 Hz per unit; the range of its "
      "drifting generator (2–8 Hz) is used for both so that 5 visible units plus background stay inside the "
      f"firmware's {MAX_SPIKES} stored detections per 10 s interval (`MD_MAX_SPIKES`; detections beyond it "
      "are counted, not stored, so they are never labelled). The column `at cap` below counts intervals "
      "that still hit it.\n")


def md_method(a, data):
    """The trackers and how they are scored."""
    a("## Trackers and scoring\n")
    a("- `mhtc`, `map-nn`, `ml-nn`, `gnn`: `mhtc-replay --tracker T` with its defaults (10 s intervals, "
      "wavelet detection, 1.15 ms windows, d = 2 PCA per interval, q = 10 µV, docs/mhtc.md). `mhtc` is "
      "scored by `labels.csv` (the final best hypothesis traced back through its parents), `mhtc-online` by "
      "`labels_online.csv` of the same run (the leading hypothesis of each interval as it was then, with "
      "provisional IDs for the clusters it has not yet decided on: docs/mhtc.md).")
    a("- `peer`: `peer_stonesoup.py RECDIR OUT` with its defaults (5 MAD-σ threshold, PCA fitted on interval "
      "0, GMM G = 1..4 by BIC per interval, Stone Soup GNN Kalman tracker), run in the project venv "
      "(its pins, Stone Soup 1.9.1 and scikit-learn, are in requirements.txt).")
    a("- `oracle`: told the true number K of visible units; on **MHTC's detections** (the `sample_index` "
      "rows of mhtc-replay's labels.csv, so it shares the firmware's detection and its per-interval cap), "
      "the firmware's window (x[t−12 : t+23], 1.15 ms at 30 kHz) around each, one 2-D PCA over the whole "
      "session, scikit-learn `GaussianMixture(K, covariance_type='full', n_init=5, random_state=0)`; each "
      "component is one ID for the whole session. Not causal and not possible online: a reference for "
      "what whole-session clustering of the same spikes gives. The acceptance targets use this one.")
    a("- `oracle-thr`: the same oracle on the **peer's threshold detections** (5 MAD-σ, local minimum, 1 ms "
      "dead time, no per-interval cap; the `sample_index` rows of the peer's labels.csv), same window.")
    a("- Score: `spikeinterface.comparison.compare_sorter_to_ground_truth` (delta_time 0.4 ms, Hungarian "
      "matching), ground truth = the visible units only, tested units = track IDs (spikes with track −1 are "
      "unlabelled); per-unit **accuracy** = tp / (tp + fn + fp) of the matched track, 0 when none matched. "
      "A track is matched only if its agreement score with the unit is ≥ 0.5 (SpikeInterface's default "
      "`match_score`), so a unit split about evenly over two track IDs (an ID switch half-way), or merged "
      "with another unit or with background spikes of similar count, scores 0. "
      "Means: per recording over its visible units, then over recordings (`mean`); `unit mean` pools all "
      "visible units.")
    a("- Loss split (same 0.4 ms): `detected` = share of a unit's spikes with a row in the tracker's labels, "
      "`labelled` = with a track ID ≥ 0, `split` = visible units whose labelled spikes carry ≥ 2 track IDs "
      "with ≥ 10 % each.\n")


def md_headline(a, data):
    """Headline accuracies, the acceptance targets and where the accuracy goes."""
    tr = data["trackers"]
    a("## Headline\n")
    a("| tracker | static mean | static unit mean | static range | drifting mean | drifting unit mean | "
      "drifting range | tracks issued (static / drifting) |")
    a("|---|---:|---:|---|---:|---:|---|---:|")
    S, D = data["summary"].get("static", {}), data["summary"].get("drifting", {})
    for t in tr:
        s, d = S.get(t, {}), D.get(t, {})
        a(f"| {t} | **{fmt(s.get('mean_accuracy'))}** | {fmt(s.get('unit_mean_accuracy'))} | "
          f"{fmt(s.get('min_recording'), 2)}–{fmt(s.get('max_recording'), 2)} | **{fmt(d.get('mean_accuracy'))}** | "
          f"{fmt(d.get('unit_mean_accuracy'))} | {fmt(d.get('min_recording'), 2)}–{fmt(d.get('max_recording'), 2)} | "
          f"{s.get('tracks_issued', '')} / {d.get('tracks_issued', '')} |")
    a(f"\n({len(data['static'])} static recordings, {S.get('mhtc', {}).get('units', 0)} visible units; "
      f"{len(data['drifting'])} drifting, {D.get('mhtc', {}).get('units', 0)} visible units. Tracks issued: "
      "track IDs the tracker allocated (mhtc-replay `track_ids_issued`, the peer's `tracks_created`, K for the "
      "oracle), summed over recordings.)\n")
    a("## Acceptance targets\n")
    a("```")
    for ln in data["acceptance"]:
        ok = "PASS" if ln["pass"] else "FAIL"
        a(f"{ok}  {ln['target']}: {ln['measured']}")
    a("```\n")
    a("## Where the accuracy goes (means over visible units)\n")
    a("| tracker | kind | detected | labelled | accuracy | split units |")
    a("|---|---|---:|---:|---:|---:|")
    for t in tr:
        for kind, K in (("static", S), ("drifting", D)):
            k = K.get(t)
            if k:
                a(f"| {t} | {kind} | {fmt(k['detected'])} | {fmt(k['labelled'])} | {fmt(k['unit_mean_accuracy'])} "
                  f"| {k['split_units']} of {k['units']} |")
    a("")


def md_behind(a, data):
    """The visible units where MHTC trails the best other tracker by 0.2 or more."""
    tr = data["trackers"]
    a("## Units where MHTC is behind\n")
    a("Visible units whose MHTC accuracy is at least 0.2 below the best of the other trackers (the online "
      "MHTC labels excluded), with MHTC's loss split.\n")
    behind = []
    for r in data["static"] + data["drifting"]:
        if "mhtc" not in r["trackers"]:
            continue
        near = {u["unit_id"]: u for u in r["units"]}
        for uid, m in r["trackers"]["mhtc"]["units"].items():
            others = {t: r["trackers"][t]["units"][uid]["accuracy"] for t in tr if t not in ("mhtc", "mhtc-online")}
            if not others:
                continue
            best = max(others, key=others.get)
            if m["accuracy"] <= others[best] - 0.2:
                behind.append(f"| {r['kind']} {r['seed']} | {uid} | {near[uid]['amplitude_x_noise']:.1f} | "
                              f"{fmt(near[uid].get('nearest_visible_x_noise'), 1)} | {m['accuracy']:.2f} | "
                              f"{best} {others[best]:.2f} | {m['detected']:.2f} / {m['labelled']:.2f} / {m['ids']} |")
    if behind:
        a("| recording | unit | × noise | nearest | MHTC | best other | MHTC det / lab / IDs |")
        a("|---|---|---:|---:|---:|---|---|")
        for row in behind:
            a(row)
    else:
        a("None.")
    a("")


def md_per_recording(a, data):
    """Accuracy per recording and per unit."""
    tr = data["trackers"]
    a("## Per recording\n")
    a("Mean accuracy over the recording's visible units; tracks issued in brackets.\n")
    a("| recording | ch | visible (× noise) | " + " | ".join(tr) + " |")
    a("|---|---:|---|" + "---:|" * len(tr))
    for r in data["static"] + data["drifting"]:
        vis = [u for u in r["units"] if u["visible"]]
        a(f"| {r['kind']} {r['seed']} | {r['channel']} | {len(vis)} ({', '.join('%.1f' % u['amplitude_x_noise'] for u in vis)}) | "
          + " | ".join(f"{r['trackers'][t]['mean_accuracy']:.3f} ({r['trackers'][t]['tracks_issued']})" for t in tr)
          + " |")
    a("")
    a("## Per unit\n")
    a("Accuracy per tracker; for MHTC also detected / labelled / track IDs carrying ≥ 10 % of its labelled "
      "spikes.\n")
    a("`nearest`: L2 distance of the unit's mean waveform on the channel (−1..+2 ms) to the nearest other "
      "visible unit's, in noise levels (a small value: two units that look alike on this channel).\n")
    a("| recording | unit | × noise | nearest | rate (Hz) | " + " | ".join(tr) + " | MHTC det / lab / IDs |")
    a("|---|---|---:|---:|---:|" + "---:|" * len(tr) + "---|")
    for r in data["static"] + data["drifting"]:
        for u in r["units"]:
            if not u["visible"]:
                continue
            uid = u["unit_id"]
            m = r["trackers"]["mhtc"]["units"][uid] if "mhtc" in r["trackers"] else None
            a(f"| {r['kind']} {r['seed']} | {uid} | {u['amplitude_x_noise']:.1f} | "
              f"{fmt(u.get('nearest_visible_x_noise'), 1)} | {u['rate_hz']:.1f} | "
              + " | ".join(f"{r['trackers'][t]['units'][uid]['accuracy']:.2f}" for t in tr)
              + (f" | {m['detected']:.2f} / {m['labelled']:.2f} / {m['ids']} |" if m else " | |"))
    a("")


def md_counters(a, data):
    """MHTC's counters per recording, and the caveats."""
    if any("mhtc" in r["trackers"] for r in data["static"] + data["drifting"]):
        a("## MHTC counters (mhtc-replay summary.json `stats`)\n")
        keys = ["models_pruned", "models_failed", "evidence_fallbacks", "empty_intervals", "dup_pruned",
                "target_overflow", "pool_drops", "kf_failures", "tracks_deleted", "update_errors"]
        a("| recording | " + " | ".join(keys) + " | at cap | step median (ms) |")
        a("|---|" + "---:|" * (len(keys) + 2))
        tot = {k: 0 for k in keys}
        for r in data["static"] + data["drifting"]:
            m = r["trackers"]["mhtc"]
            for k in keys:
                tot[k] += m["stats"].get(k, 0)
            a(f"| {r['kind']} {r['seed']} | " + " | ".join(str(m["stats"].get(k, "")) for k in keys)
              + f" | {m['intervals_at_spike_cap']} | {fmt(m['step_ms_median'], 1)} |")
        a("| **all** | " + " | ".join(str(tot[k]) for k in keys) + " | | |")
        a("\n`at cap`: intervals whose stored detections reached MD_MAX_SPIKES = 512. Counter meanings: "
          "docs/mhtc.md (`pool_drops`: children dropped because their new track records did not fit the "
          "pool of 20; `models_failed`: model classes EM could not fit; `evidence_fallbacks`: Laplace → BIC/2).\n")
    a("## Caveats\n")
    a("- One generator family and one probe geometry; templates, noise and drift are SpikeInterface's "
      "models, not tissue. The visibility rule (6× MAD noise) and the channel rule decide which units "
      "count.")
    a("- The oracle sees the whole session and the true K; it can still merge a visible unit with background "
      "spikes or split one unit over two components when two invisible units form a denser cloud.")
    a("- The peer has its own detector (5 MAD-σ threshold), so its `detected` differs from the project's "
      "trackers, which share one signal chain.")
    a("- Differences of a few hundredths between trackers on this many units are within recording-to-recording "
      "spread; the per-recording table shows it.")


def report_md(data):
    L = []
    for section in (md_intro, md_recordings, md_method, md_headline, md_behind, md_per_recording, md_counters):
        section(L.append, data)
    return "\n".join(L) + "\n"


# -------------------------------------------------------------------------------------------- modes

def versions():
    import sklearn
    import spikeinterface
    try:
        import stonesoup
        ss = stonesoup.__version__
    except ImportError:
        ss = "not installed"
    return {"spikeinterface": spikeinterface.__version__, "sklearn": sklearn.__version__, "stonesoup": ss,
            "numpy": np.__version__}


def tree_state():
    """Whether the checkout the run starts from has uncommitted changes (the report names no commit)."""
    p = subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                       text=True)
    if p.returncode != 0:
        return "tree state unknown"
    return "a tree with uncommitted changes" if p.stdout.strip() else "a clean tree"


def check_args(args, trackers):
    if args.jobs < 1:
        raise EvalError("--jobs must be >= 1")
    if "peer" in trackers:
        if not os.path.isfile(args.peer):
            raise EvalError(f"{args.peer}: no such file (the reference peer; pass --peer PATH or --no-peer)")
    os.makedirs(args.work, exist_ok=True)


def cmd_run(args):
    trackers = [t for t in TRACKERS if not (args.no_peer and t in ("peer", "oracle-thr"))]
    check_args(args, trackers)
    binary = replay_bin(args)
    tree = tree_state()      # the tree the run starts from
    t0 = time.perf_counter()
    static, sk_s = collect("static", args.static, args.static_seed, args.duration, args, binary, trackers)
    drifting, sk_d = collect("drifting", args.drifting, args.drifting_seed, args.duration, args, binary, trackers)
    run_s = time.perf_counter() - t0
    summ = {"static": kind_summary(static, trackers), "drifting": kind_summary(drifting, trackers)}
    cmd = (".venv/bin/python tools/external_eval/external_eval.py run --build-dir build/release --work "
           "out/external-eval" + (f" --static {args.static}" if args.static != 8 else "")
           + (f" --drifting {args.drifting}" if args.drifting != 4 else "")
           + (f" --duration {args.duration:g}" if args.duration != 300.0 else "")
           + f" --jobs {args.jobs}" + (" --no-peer" if args.no_peer else "")
           + " --md docs/external-eval.md")
    data = {"command": cmd, "run_s": run_s, "generate_s": sum(r["generate_s"] for r in static + drifting),
            "jobs": args.jobs, "machine": f"{os.cpu_count()} cores, {platform.machine()}",
            "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="minutes"),
            "tree": tree, "versions": versions(), "duration_s": args.duration,
            "static_seed": args.static_seed, "drifting_seed": args.drifting_seed,
            "skipped": {"static": sk_s, "drifting": sk_d}, "trackers": trackers,
            "static": static, "drifting": drifting, "summary": summ,
            "acceptance": acceptance(static, drifting, summ) if "peer" in trackers else []}
    with open(os.path.join(args.work, "results.json"), "w") as f:
        json.dump(data, f, indent=1)
    log(f"\nwhole run: {run_s:.0f} s ({run_s / 60:.1f} min)")
    for kind in ("static", "drifting"):
        for t in trackers:
            log(f"{kind:<8} {t:<11} mean accuracy {fmt(summ[kind][t]['mean_accuracy'])}  "
                f"tracks issued {summ[kind][t]['tracks_issued']}")
    for ln in data["acceptance"]:
        log(f"{'PASS' if ln['pass'] else 'FAIL'}  {ln['target']}: {ln['measured']}")
    if args.md:
        with open(args.md, "w") as f:
            f.write(report_md(data))
        log(f"wrote {args.md}")
    return 0


def cmd_report(args):
    """Rewrite the report from WORK/results.json of an earlier run (no generation, no tracker runs)."""
    data = read_json(os.path.join(args.work, "results.json"))
    if not args.md:
        raise EvalError("report: --md PATH is required")
    with open(args.md, "w") as f:
        f.write(report_md(data))
    log(f"wrote {args.md}")
    return 0


def ci_figures(args):
    """Run the CI subset; returns ({key: value}, the recording)."""
    args.reuse, args.jobs, args.no_peer = False, 2, True
    binary = replay_bin(args)
    recs, _ = collect(SUBSET["kind"], 1, SUBSET["seed_start"], SUBSET["duration_s"], args, binary,
                      SUBSET["trackers"], min_nearest=SUBSET["min_nearest_x_noise"])
    r = recs[0]
    key = f"{r['kind']}-{r['seed']}-{SUBSET['duration_s']:g}s"
    fig = {f"{key}/visible_units": sum(u["visible"] for u in r["units"])}
    for t in SUBSET["trackers"]:
        x = r["trackers"][t]
        fig[f"{key}/{t}/mean_accuracy"] = x["mean_accuracy"]
        if t != "oracle":
            fig[f"{key}/{t}/min_unit_accuracy"] = min(u["accuracy"] for u in x["units"].values())
        if t == "mhtc":
            fig[f"{key}/{t}/tracks_issued"] = x["tracks_issued"]
            fig[f"{key}/{t}/update_errors"] = x["stats"].get("update_errors")
    return fig, r


def cmd_measure(args):
    os.makedirs(args.work, exist_ok=True)
    fig, r = ci_figures(args)
    checks = evaluation.make_bounds(fig, lambda k: CI_MARGINS[k.rsplit("/", 1)[1]])
    evaluation.write_thresholds(
        THRESHOLDS,
        "CI subset of the external evaluation (docs/external-eval.md): one short SpikeInterface-generated "
        "recording, MHTC and the whole-session oracle, accuracy against the ground truth, bounds a little "
        "worse than measured. Regenerate on purpose, never to make a failing check pass: .venv/bin/python "
        "tools/external_eval/external_eval.py measure --build-dir build/release",
        ".venv/bin/python tools/external_eval/external_eval.py check --build-dir BUILD",
        [{"tree": tree_state(), "versions": versions()}], checks)
    log(f"external-eval: wrote {len(checks)} bounds to {THRESHOLDS}")
    return 0


def cmd_check(args):
    try:
        with open(THRESHOLDS) as f:
            doc = json.load(f)
        checks = doc["checks"]
    except (OSError, ValueError, KeyError) as e:
        raise EvalError(f"{THRESHOLDS}: cannot read the bounds ({e}); measure them first")
    os.makedirs(args.work, exist_ok=True)
    fig, _ = ci_figures(args)
    return 1 if evaluation.check_bounds(checks, fig, prefix="external-eval") else 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", choices=["run", "report", "measure", "check"])
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build", "release"))
    ap.add_argument("--replay", default=None, help="the mhtc-replay executable (default BUILD/bin/mhtc-replay)")
    ap.add_argument("--work", default=None, help="recordings and outputs (default out/external-eval[-ci])")
    ap.add_argument("--static", type=int, default=8, help="static recordings (run)")
    ap.add_argument("--drifting", type=int, default=4, help="drifting recordings (run)")
    ap.add_argument("--static-seed", type=int, default=1000)
    ap.add_argument("--drifting-seed", type=int, default=2000)
    ap.add_argument("--duration", type=float, default=300.0, help="seconds per recording (run)")
    ap.add_argument("--jobs", type=int, default=2, help="tracker runs in parallel per recording")
    ap.add_argument("--peer", default=DEFAULT_PEER, help="peer_stonesoup.py")
    ap.add_argument("--peer-python", default=sys.executable, help="Python with Stone Soup for the peer")
    ap.add_argument("--no-peer", action="store_true", help="leave the peer out (no acceptance lines then)")
    ap.add_argument("--reuse", action="store_true", help="reuse recordings already in WORK with the same "
                    "parameters (trackers are always run)")
    ap.add_argument("--md", default=None, help="write the report here (run)")
    args = ap.parse_args(argv)
    if args.work is None:
        args.work = os.path.join(ROOT, "out", "external-eval" + ("" if args.mode in ("run", "report") else "-ci"))
    for name in ("static_seed", "drifting_seed"):
        if getattr(args, name) < 1000:
            ap.error(f"--{name.replace('_', '-')} must be >= 1000 (lower generator seeds are reserved for "
                     "independent evaluation)")
    if args.static < 0 or args.drifting < 0 or not args.duration >= 20.0:
        ap.error("--static/--drifting must be >= 0 and --duration >= 20 s")
    try:
        return {"run": cmd_run, "report": cmd_report, "measure": cmd_measure, "check": cmd_check}[args.mode](args)
    except (EvalError, recordings.RecordingError, scoring.LabelsError) as e:
        print(f"external-eval: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

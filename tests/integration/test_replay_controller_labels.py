#!/usr/bin/env python3
"""mhtc-replay gives the controller's labels (docs/mhtc.md "Offline replay").

One recording through both: microdrive-session runs the controller in the
closed loop (in-process) and leaves the samples it recorded (recording.json +
recording.bin) and its telemetry (candump.log); mhtc-replay then runs over the
recording with its defaults, which are the controller's tracker parameters
(MHTC, q = 10 uV, unimodal ratio 0.9). Both run firmware/core/pipeline/
interval_chain, so per interval the spikes (sample index of each window's
minimum) and their track IDs must be identical: the controller's are the
TLM_SPIKES frames of the interval's cycle (read by microdrive.session, by
DBC message name), the replay's the rows of
labels_online.csv (the leading hypothesis after each interval).

Spikes the controller sent unlabelled (a skipped cycle, or fewer than 2
windows: nothing for the tracker) must have no row in the replay. The test
fails at the first interval that differs and says how.

With --tracker map-nn|ml-nn|gnn the controller runs that baseline
(--param tracker=N) and the replay too (--tracker NAME).

usage: test_replay_controller_labels.py --bin DIR --scenario YAML --work DIR [--seed N] [--cycles N]
                                        [--tracker mhtc|map-nn|ml-nn|gnn]
"""
import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
from collections import defaultdict

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from microdrive import session  # the one reader of a session's telemetry

TRACK_UNLABELLED = session.TRACK_UNLABELLED
TLM_F_SKIPPED = 0x0001            # firmware/app/md_cycle.h MD_TLM_F_SKIPPED
TRACKER_PARAM = {"mhtc": 0, "map-nn": 1, "ml-nn": 2, "gnn": 3}   # md_interval_tracker


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"FAIL: {' '.join(cmd)} exited {p.returncode}\n{p.stderr}")
    return p


def controller_labels(session_dir, electrode):
    """cycle -> [(sample in the interval, track)] of the electrode, parts in order; cycle -> TLM_STATUS."""
    status, _, spikes, _ = session.read_telemetry(os.path.join(session_dir, "candump.log"))
    labels = {}
    for (e, cycle), parts in spikes.items():
        if e == electrode:
            labels[cycle] = [pair for _, pairs in sorted(parts) for pair in pairs]
    return labels, {int(s["Cycle"]): s for s in status[electrode]}


def replay_labels(out_dir):
    """interval -> [(sample_index, track_id)] in file order."""
    rows = defaultdict(list)
    with open(os.path.join(out_dir, "labels_online.csv")) as f:
        for r in csv.DictReader(f):
            rows[int(r["interval"])].append((int(r["sample_index"]), int(r["track_id"])))
    return rows


def first_difference(ctl, rep):
    for i, (a, b) in enumerate(zip(ctl, rep)):
        if a != b:
            return (f"spike {i}: controller sample {a[0]} track {a[1]}, replay sample {b[0]} track {b[1]}; "
                    f"{sum(x[0] != y[0] for x, y in zip(ctl, rep))} sample(s) and "
                    f"{sum(x[1] != y[1] for x, y in zip(ctl, rep))} track label(s) differ")
    return f"the first {min(len(ctl), len(rep))} agree, then one list ends"


def compare(side, ctl, status, rep):
    """Counts of what agreed; exits with the first difference."""
    n_iv = n_spikes = n_tracked = n_skipped = n_unreported = 0
    ids = set()
    for k, iv in enumerate(side["intervals"]):
        cycle, start = iv.get("cycle"), iv["start_sample"]
        if cycle is None:   # recorded but never reported: only the session's last interval may be
            n_unreported += 1
            continue
        if n_unreported:
            sys.exit(f"FAIL: interval {k - 1} has no reporting cycle but later intervals do")
        c = ctl.get(cycle, [])
        r = [(s - start, t) for s, t in rep.get(k, [])]
        labelled = [p for p in c if p[1] != TRACK_UNLABELLED]
        if len(labelled) != len(c) and labelled:
            sys.exit(f"FAIL: interval {k} (cycle {cycle}): controller sent {len(c) - len(labelled)} unlabelled "
                     f"spike(s) among {len(c)}")
        if not labelled:
            skipped = int(status.get(cycle, {}).get("Flags", 0)) & TLM_F_SKIPPED
            if r:
                sys.exit(f"FAIL: interval {k} (cycle {cycle}): the controller labelled no spike ({len(c)} sent "
                         f"unlabelled{', cycle skipped' if skipped else ''}) but the replay labelled {len(r)}")
            n_skipped += 1
            continue
        if labelled != r:
            sys.exit(f"FAIL: interval {k} (cycle {cycle}, start sample {start}) is the first that differs: "
                     f"controller {len(labelled)} spikes, replay {len(r)}; {first_difference(labelled, r)}")
        n_iv += 1
        n_spikes += len(labelled)
        n_tracked += sum(1 for _, t in labelled if t > 0)
        ids.update(t for _, t in labelled if t > 0)
    return n_iv, n_spikes, n_tracked, ids, n_skipped, n_unreported


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True, help="folder of microdrive-session and mhtc-replay")
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cycles", type=int, default=12)
    ap.add_argument("--tracker", choices=sorted(TRACKER_PARAM), default="mhtc")
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    session_dir, out_dir = os.path.join(a.work, "session"), os.path.join(a.work, "replay")
    run([os.path.join(a.bin, "microdrive-session"), "--scenario", a.scenario, "--seed", str(a.seed),
         "--bus", "inproc", "--out", session_dir, "--no-lcm", "--no-plots", "--no-score", "--quiet",
         "--cycles", str(a.cycles), "--param", f"tracker={TRACKER_PARAM[a.tracker]}"])
    run([os.path.join(a.bin, "mhtc-replay"), "--recording", os.path.join(session_dir, "recording.json"),
         "--out", out_dir, "--tracker", a.tracker, "--quiet"])
    with open(os.path.join(session_dir, "recording.json")) as f:
        side = json.load(f)
    with open(os.path.join(out_dir, "summary.json")) as f:
        summary = json.load(f)
    # the controller's tracker parameters (md_params.c defaults) are the replay's defaults
    want = {"tracker": a.tracker, "q_uv": 10.0, "init_uv": 10.0, "unimodal_ratio": 0.9, "L": 8}
    got = {k: summary[k] for k in want}
    if got != want:
        sys.exit(f"FAIL: replay's tracker parameters {got}, the controller's {want}")
    ctl, status = controller_labels(session_dir, side["electrode"])
    n_iv, n_spikes, n_tracked, ids, n_skipped, n_unreported = compare(side, ctl, status, replay_labels(out_dir))
    if n_iv < a.cycles - 2 or n_tracked < 100 or not ids:
        sys.exit(f"FAIL: too little compared: {n_iv} intervals, {n_spikes} spikes, {n_tracked} on a track")
    print(f"{a.tracker}: identical labels: {n_iv} intervals, {n_spikes} spikes ({n_tracked} on tracks {sorted(ids)}); "
          f"{n_skipped} interval(s) without labels on both sides, {n_unreported} recorded but not reported")


if __name__ == "__main__":
    main()

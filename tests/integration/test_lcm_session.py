#!/usr/bin/env python3
"""microdrive-session records every session's LCM log and plots it by default.

    PYTHONPATH=<build>/common/lcm/python test_lcm_session.py --bin DIR --scenario FILE --work DIR

Proves, on short in-process sessions (3 cycles of single_neuron):
  * default: DIR/session.lcmlog exists, decodes with LCM's Python bindings and the lcm-gen -p types (mdlcm)
    (one MD_STATUS per cycle, MD_TRACKS/MD_HYPOTHESES/MD_SPIKES per cycle, ground truth, every HALL_READING
    of candump.log in MD_HALL, at least 10 per message), is byte-identical
    on a rerun of the same seed, and the five PNGs exist with their session label;
  * --no-plots: the log but no PNG; --no-lcm: neither, and a message saying why there are no plots;
  * a failing bridge or plotter: exit 5 and a message naming the step, report.json still written;
  * --param tracker=1 reaches the controller (one hypothesis per cycle, MHTC keeps several), an unknown
    name or an out-of-range value is a usage error (exit 2) before anything starts;
  * microdrive-fw --param: a valid one runs, an unknown name or a bad value exits 2 at once.
"""
import argparse
import filecmp
import os
import shutil
import signal
import subprocess
import sys
import time

import lcm

import mdlcm
from microdrive import canlog

PNGS = ["tracks_pc.png", "waveforms.png", "status.png", "hypotheses.png", "truth.png"]
CYCLES = 3


def session(a, out, *extra, env=None):
    shutil.rmtree(out, ignore_errors=True)
    cmd = [os.path.join(a.bin, "microdrive-session"), "--scenario", a.scenario, "--seed", "3", "--bus", "inproc",
           "--cycles", str(CYCLES), "--out", out, "--quiet", "--no-recording", *extra]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    return p.returncode, p.stderr


def decode(path):
    types = {"MD_STATUS": mdlcm.status_t, "MD_TRACKS": mdlcm.tracks_t, "MD_HYPOTHESES": mdlcm.hypotheses_t,
             "MD_SPIKES": mdlcm.spikes_t, "MD_TRUTH_STATE": mdlcm.truth_state_t,
             "MD_TRUTH_SESSION": mdlcm.truth_session_t, "MD_HALL": mdlcm.hall_t}
    got = {ch: [] for ch in types}
    for ev in lcm.EventLog(path, "r"):
        if ev.channel in types:
            got[ev.channel].append(types[ev.channel].decode(ev.data))
    return got


def check_default(a, fails):
    out = os.path.join(a.work, "default")
    rc, err = session(a, out)
    if rc != 0:
        fails.append(f"default session exit {rc}: {err[-800:]}")
        return
    log = os.path.join(out, "session.lcmlog")
    if "LCM log" not in err or "plots" not in err:
        fails.append(f"default session does not name its LCM log and plots: {err[-400:]}")
    got = decode(log)
    n = {ch: len(v) for ch, v in got.items()}
    print(f"  default: {n}")
    for ch in ("MD_STATUS", "MD_TRACKS", "MD_HYPOTHESES", "MD_SPIKES"):
        if n[ch] != CYCLES:
            fails.append(f"{ch}: {n[ch]} messages, expected one per cycle ({CYCLES})")
    if [m.cycle for m in got["MD_STATUS"]] != sorted(m.cycle for m in got["MD_STATUS"]):
        fails.append("MD_STATUS cycles out of order")
    if n["MD_TRUTH_SESSION"] != 1 or n["MD_TRUTH_STATE"] < CYCLES:
        fails.append("ground truth missing from the LCM log")
    check_hall(got["MD_HALL"], os.path.join(out, "candump.log"), fails)
    for png in PNGS:
        if not os.path.exists(os.path.join(out, png)) or os.path.getsize(os.path.join(out, png)) < 10000:
            fails.append(f"default session: {png} missing or tiny")
    again = os.path.join(a.work, "default-again")
    rc, err = session(a, again)
    if rc != 0 or not filecmp.cmp(log, os.path.join(again, "session.lcmlog"), shallow=False):
        fails.append(f"rerun of the same seed: exit {rc}, LCM logs differ")


def check_hall(msgs, candump, fails):
    """Every HALL_READING of candump.log is in MD_HALL once, in order, with its fields, batched (the bridge
    collects an electrode's readings between two SIM_CLOCK frames, docs/telemetry.md "Hall readings")."""
    frames = [(m.signals["Electrode"], m.signals["Seq"], m.signals["RawCode"], m.signals["SampleTime_ms"])
              for m in canlog.messages(candump, {"HALL_READING"})]
    readings = [(m.electrode, m.seq[k], m.raw_code[k], m.sample_time_ms[k])
                for m in msgs for k in range(m.num_readings)]
    key = lambda r: r[0]  # noqa: E731  (order per electrode; electrodes interleave differently)
    print(f"  MD_HALL: {len(readings)} readings in {len(msgs)} messages, candump.log {len(frames)} HALL_READING")
    if not frames or sorted(readings, key=key) != sorted(frames, key=key):
        fails.append(f"MD_HALL readings differ from candump.log's HALL_READING frames ({len(readings)} vs "
                     f"{len(frames)})")
    if len(msgs) * 10 > len(readings):
        fails.append(f"MD_HALL: {len(msgs)} messages for {len(readings)} readings: not batched")


def check_switches(a, fails):
    out = os.path.join(a.work, "no-plots")
    rc, err = session(a, out, "--no-plots")
    pngs = [p for p in PNGS if os.path.exists(os.path.join(out, p))]
    if rc != 0 or not os.path.exists(os.path.join(out, "session.lcmlog")) or pngs:
        fails.append(f"--no-plots: exit {rc}, log {os.path.exists(os.path.join(out, 'session.lcmlog'))}, {pngs}")
    out = os.path.join(a.work, "no-lcm")
    rc, err = session(a, out, "--no-lcm")
    pngs = [p for p in PNGS if os.path.exists(os.path.join(out, p))]
    if rc != 0 or os.path.exists(os.path.join(out, "session.lcmlog")) or pngs or "no plots" not in err:
        fails.append(f"--no-lcm: exit {rc}, log {os.path.exists(os.path.join(out, 'session.lcmlog'))}, {pngs}, "
                     f"{err[-300:]}")
    print("  --no-plots, --no-lcm: checked")


def check_failures(a, fails):
    for var, val, word in (("MD_SESSION_BRIDGE", "/bin/false", "LCM log failed"),
                           ("MD_SESSION_PLOTTER", os.path.join(a.work, "no-such-plotter.py"), "plots failed")):
        env = dict(os.environ, **{var: val})
        out = os.path.join(a.work, "fail-" + var.lower())
        rc, err = session(a, out, env=env)
        print(f"  {var}={val}: exit {rc}")
        if rc != 5 or word not in err or not os.path.exists(os.path.join(out, "report.json")):
            fails.append(f"{var}={val}: exit {rc} (expected 5), message {word!r} in {err[-300:]!r}")


def check_params(a, fails):
    hyps = {}
    for tracker in (0, 1):
        out = os.path.join(a.work, f"tracker-{tracker}")
        rc, err = session(a, out, "--param", f"tracker={tracker}", "--no-plots")
        if rc != 0:
            fails.append(f"--param tracker={tracker}: exit {rc}: {err[-400:]}")
            continue
        hyps[tracker] = [m.num_hypotheses for m in decode(os.path.join(out, "session.lcmlog"))["MD_STATUS"]]
    print(f"  hypotheses per cycle: {hyps}")
    if hyps.get(1) and max(hyps[1]) > 1:
        fails.append(f"--param tracker=1 (MAP-NN) kept {max(hyps[1])} hypotheses: not applied")
    if hyps.get(0) and max(hyps[0]) <= 1:
        fails.append("MHTC kept one hypothesis: the comparison proves nothing")
    for bad in ("no_such_param=1", "tracker=9", "tracker=abc", "tracker"):
        rc, err = session(a, os.path.join(a.work, "bad-param"), "--param", bad)
        if rc != 2 or "--param" not in err:
            fails.append(f"--param {bad}: exit {rc} (expected 2): {err[-300:]}")
    fw = os.path.join(a.bin, "microdrive-fw")
    for bad in ("no_such_param=1", "tracker=9", "tracker=1.5"):
        p = subprocess.run([fw, "--bus", "inproc:tlm-test", "--param", bad], capture_output=True, text=True,
                           timeout=20)
        if p.returncode != 2 or "--param" not in p.stderr and "tracker" not in p.stderr:
            fails.append(f"microdrive-fw --param {bad}: exit {p.returncode} (expected 2): {p.stderr[-300:]}")
    p = subprocess.Popen([fw, "--bus", "inproc:tlm-test", "--param", "tracker=3", "--param", "sfsm_wait_r=2"],
                         stderr=subprocess.PIPE, text=True)
    time.sleep(0.5)
    alive = p.poll() is None
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=20)
    if not alive or p.returncode != 0:
        fails.append(f"microdrive-fw --param tracker=3 --param sfsm_wait_r=2: alive {alive}, exit {p.returncode}: "
                     f"{err[-300:]}")
    print("  bad --param values refused by microdrive-session and microdrive-fw; good ones accepted")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    fails = []
    for check in (check_default, check_switches, check_failures, check_params):
        check(a, fails)
    for f in fails:
        print("FAIL:", f)
    print(f"{'FAILED' if fails else 'passed'}: {len(fails)} failures")
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""md-lcm-bridge on a crafted session (docs/telemetry.md, "Tests").

    PYTHONPATH=<build>/common/lcm/python test_lcm_bridge.py --bridge BIN --dbc DBC --work DIR

The session comes from test_lcm_fixture.py (frames encoded with cantools from
the DBC). The bridge replays its candump log with the truth file and writes an
LCM event log; the log is decoded with LCM's own Python bindings and the
lcm-gen -p types (package mdlcm, on PYTHONPATH as ctest sets it), and every message is compared with what the fixture encoded:
every telemetry frame kind (TLM_STATUS, TLM_CYCLE, TLM_TRACK + TLM_WAVE,
TLM_HYP, TLM_SPIKES, ACT_STATUS, HALL_READING with calibrated depth, batched
per electrode and SIM_CLOCK time, HALL_CALIB) and every truth record kind (session, neuron, spike, state,
death). Also: the log is byte-identical on a second run and when the bridge
also publishes on memq://, event timestamps never decrease, malformed input
is counted and not fatal, usage errors exit 2 and a missing file exits 1.
"""
import json
import math
import os
import re
import subprocess
import sys

import lcm

import mdlcm as md
from microdrive.lcmlog import hall_readings
from test_lcm_fixture import parse_args, write_session

FAILS = []


def check(cond, what):
    if not cond:
        FAILS.append(what)
        print("FAIL:", what)


def close(a, b, tol=1e-3):
    return abs(float(a) - float(b)) <= tol * max(1.0, abs(float(b)))


def run_bridge(bridge, *args):
    p = subprocess.run([bridge] + list(args), capture_output=True, text=True, timeout=60)
    return p.returncode, p.stderr


def stats_of(stderr):
    """The counters of the bridge's summary line."""
    names = ("frames", "telemetry", "ignored", "malformed", "dropped", "late", "bad log lines", "truth records",
             "messages")
    out = {}
    for k in names:
        m = re.search(r"\b" + k + r" (\d+)", stderr)
        if m:
            out[k] = int(m.group(1))
    return out


def decode_log(path):
    classes = {"MD_STATUS": md.status_t, "MD_CYCLE": md.cycle_t, "MD_TRACKS": md.tracks_t,
               "MD_HYPOTHESES": md.hypotheses_t, "MD_SPIKES": md.spikes_t, "MD_ACTUATOR": md.actuator_t,
               "MD_HALL": md.hall_t, "MD_HALL_CALIB": md.hall_calib_t, "MD_TRUTH_SESSION": md.truth_session_t,
               "MD_TRUTH_STATE": md.truth_state_t, "MD_TRUTH_SPIKES": md.truth_spikes_t,
               "MD_TRUTH_DEATH": md.truth_death_t}
    out = {ch: [] for ch in classes}
    last = -1
    for ev in lcm.EventLog(path, "r"):
        check(ev.channel in classes, f"unknown channel {ev.channel}")
        check(ev.timestamp >= last, f"event timestamp decreases at event {ev.eventnum}")
        last = ev.timestamp
        out[ev.channel].append(classes[ev.channel].decode(ev.data))
    return out


def compare_fields(ch, got, exp, keys):
    check(len(got) == len(exp), f"{ch}: {len(got)} messages, expected {len(exp)}")
    for i, (g, x) in enumerate(zip(got, exp)):
        for k in keys:
            gv, xv = getattr(g, k), x[k]
            ok = close(gv, xv) if isinstance(xv, float) else gv == xv
            check(ok, f"{ch}[{i}].{k} = {gv!r}, expected {xv!r}")


def check_tracks(got, exp):
    check(len(got) == len(exp), f"MD_TRACKS: {len(got)} messages, expected {len(exp)}")
    for g, x in zip(got, exp):
        where = f"MD_TRACKS e{x['electrode']} c{x['cycle']}"
        check(g.electrode == x["electrode"] and g.cycle == x["cycle"] and g.utime == x["utime"], where + " header")
        check(list(g.track_id) == x["track_id"], f"{where} ids {list(g.track_id)} != {x['track_id']}")
        check(list(g.spike_count) == x["spike_count"], where + " spike counts")
        check(list(g.missed) == x["missed"], where + " missed")
        check(g.pc_dim == 2, where + " pc_dim")
        for k in range(g.num_tracks):
            check(all(close(a, b) for a, b in zip(g.mean_pc[k], x["mean_pc"][k])), f"{where} mean_pc[{k}]")
            check(close(g.snr[k], x["snr"][k]), f"{where} snr[{k}]")
            check(g.wave_samples[k] == 56 and g.wave_len == 56, f"{where} wave length {g.wave_samples[k]}")
            check([int(v) for v in g.mean_wave_uv[k]] == x["wave"][k], f"{where} waveform {k}")


def check_hyps(got, exp):
    check(len(got) == len(exp), "MD_HYPOTHESES count")
    for g, x in zip(got, exp):
        where = f"MD_HYPOTHESES e{x['electrode']} c{x['cycle']}"
        check(list(g.rank) == x["rank"] and list(g.hyp_id) == x["hyp_id"], where + " ranks/ids")
        check(all(close(a, b) for a, b in zip(g.log_prob, x["log_prob"])), where + " log_prob")
        check(list(g.model_g) == x["model_g"], where + " model_g")
        check(math.isclose(sum(math.exp(v) for v in g.log_prob), 1.0, rel_tol=1e-3), where + " probabilities sum")


def check_spikes(got, exp):
    check(len(got) == len(exp), "MD_SPIKES count")
    for g, x in zip(got, exp):
        where = f"MD_SPIKES e{x['electrode']} c{x['cycle']}"
        check(list(g.sample) == x["sample"], where + " samples")
        check(list(g.track_id) == x["track_id"], where + " labels")
        check(g.interval_start_us == x["interval_start_us"] and g.sample_rate_hz == x["sample_rate_hz"],
              where + " interval start / rate")


def check_hall(got, exp):
    """Every reading once, in order per electrode, with its fields; one message per electrode and utime (the
    fixture's readings between two SIM_CLOCK frames)."""
    readings = hall_readings(got)
    for e in sorted({x["electrode"] for x in exp}):
        compare_fields(f"MD_HALL e{e}", [r for r in readings if r.electrode == e],
                       [x for x in exp if x["electrode"] == e], ["utime", "seq", "raw_code", "sample_time_ms"])
    check(all(r.calibrated and close(r.depth_um, x["depth_um"], 1e-6)
              for r, x in zip(sorted(readings, key=lambda r: r.electrode), sorted(exp, key=lambda x: x["electrode"]))),
          "Hall depth from the calibration")
    runs = {(x["electrode"], x["utime"]) for x in exp}
    check(len(got) == len(runs) and all(0 < m.num_readings <= m.MAX_READINGS for m in got),
          f"MD_HALL: {len(got)} messages for {len(runs)} (electrode, utime) runs")


def check_truth(got, truth_path, exp):
    recs = [json.loads(line) for line in open(truth_path)]
    sess = got["MD_TRUTH_SESSION"]
    check(len(sess) == 1, "one MD_TRUTH_SESSION")
    neurons = [r for r in recs if r["type"] == "neuron"]
    if sess:
        s = sess[0]
        check(s.seed == recs[0]["seed"] and s.sample_rate_hz == recs[0]["sample_rate_hz"], "truth session header")
        check(s.num_neurons == len(neurons) and list(s.neuron) == [n["neuron"] for n in neurons], "truth neurons")
        check(list(s.shape) == [n["shape"] for n in neurons], "truth neuron shapes")
    spikes = [r for r in recs if r["type"] == "spike"]
    got_spikes = [(m.electrode, smp, n) for m in got["MD_TRUTH_SPIKES"] for smp, n in zip(m.sample, m.neuron)]
    check(got_spikes == [(r["electrode"], r["sample"], r["neuron"]) for r in spikes],
          f"truth spikes: {len(got_spikes)} vs {len(spikes)} in the file, in order")
    check(all(m.num_spikes <= 256 for m in got["MD_TRUTH_SPIKES"]), "truth spike batches <= MAX_SPIKES")
    states = got["MD_TRUTH_STATE"]
    check(len(states) == len(exp["MD_TRUTH_STATE"]), "truth state count")
    for g, x in zip(states, exp["MD_TRUTH_STATE"]):
        check(g.label == x["label"] and close(g.tip_um, x["tip_um"]) and g.utime == round(x["t_s"] * 1e6),
              f"truth state {x['label']}")
        check([bool(a) for a in g.alive] == [n["alive"] for n in x["neurons"]], f"truth alive {x['label']}")
        check(all(close(a, n["snr"]) for a, n in zip(g.snr, x["neurons"])), f"truth snr {x['label']}")
        check(all(close(a, n["snr_peak_depth_um"]) for a, n in zip(g.snr_peak_depth_um, x["neurons"])),
              f"truth snr peak depth {x['label']}")
    compare_fields("MD_TRUTH_DEATH", got["MD_TRUTH_DEATH"], exp["MD_TRUTH_DEATH"], ["electrode", "neuron", "utime"])


def check_errors(bridge, work):
    rc, err = run_bridge(bridge, "--from-log", os.path.join(work, "missing.log"), "--write-log",
                         os.path.join(work, "x.lcmlog"))
    check(rc == 1 and "cannot open" in err, f"missing log: exit {rc}")
    rc, _ = run_bridge(bridge, "--write-log", os.path.join(work, "x.lcmlog"))
    check(rc == 2, f"neither --bus nor --from-log: exit {rc}")
    rc, _ = run_bridge(bridge, "--from-log", "a", "--time", "wall")
    check(rc == 2, f"bad --time: exit {rc}")
    # malformed input: a short TLM_STATUS, a garbage line, a REC_DATA-like unknown frame, a bad truth line
    bad = os.path.join(work, "bad.log")
    with open(bad, "w") as f:
        f.write("(1.000000) vcan0 500##50001\n")
        f.write("this is not a candump line\n")
        f.write("(1.000001) vcan0 123#00\n")
    truth = os.path.join(work, "bad_truth.jsonl")
    with open(truth, "w") as f:
        f.write('{"type":"spike","electrode":0}\n{not json\n\n')
    rc, err = run_bridge(bridge, "--from-log", bad, "--truth", truth, "--write-log", os.path.join(work, "bad.lcmlog"))
    st = stats_of(err)
    check(rc == 0, f"malformed input is not fatal: exit {rc} {err}")
    check(st.get("malformed") == 1 and st.get("ignored") == 1 and st.get("bad log lines") == 1,
          f"malformed input counted: {err.strip()}")
    check("truth records 0 (errors 2, ignored 0)" in err, f"bad truth lines counted: {err.strip()}")


def main():
    a = parse_args(__doc__.split("\n")[0])
    write_session(a)
    cand, truth = os.path.join(a.work, "candump.log"), os.path.join(a.work, "truth.jsonl")
    exp = json.load(open(os.path.join(a.work, "expected.json")))
    log1, log2, log3 = (os.path.join(a.work, f"session{i}.lcmlog") for i in (1, 2, 3))
    rc, err = run_bridge(a.bridge, "--from-log", cand, "--truth", truth, "--write-log", log1)
    print(err.strip())
    st = stats_of(err)
    check(rc == 0, f"bridge exit {rc}")
    check(st.get("malformed") == 0 and st.get("dropped") == 0 and st.get("late") == 0 and st.get("ignored") == 0,
          "clean session: nothing malformed, dropped, late or ignored")

    got = decode_log(log1)
    compare_fields("MD_STATUS", got["MD_STATUS"], exp["MD_STATUS"],
                   ["electrode", "cycle", "utime", "sfsm_state", "depth_um", "target_depth_um", "snr", "num_tracks",
                    "num_hypotheses", "num_spikes", "dominant_track"])
    compare_fields("MD_CYCLE", got["MD_CYCLE"], exp["MD_CYCLE"],
                   ["electrode", "phase", "cycle", "interval_id", "utime", "start_time_us", "num_samples",
                    "sample_rate_hz"])
    check_tracks(got["MD_TRACKS"], exp["MD_TRACKS"])
    check_hyps(got["MD_HYPOTHESES"], exp["MD_HYPOTHESES"])
    check_spikes(got["MD_SPIKES"], exp["MD_SPIKES"])
    compare_fields("MD_ACTUATOR", got["MD_ACTUATOR"], exp["MD_ACTUATOR"],
                   ["electrode", "utime", "state", "cmd_seq", "steps_done", "steps_remaining"])
    check_hall(got["MD_HALL"], exp["MD_HALL"])
    calib = got["MD_HALL_CALIB"]
    check(len(calib) == 2 and all(list(c.coeff_um) == x["coeff_um"] and c.code_mid == x["code_mid"]
                                  for c, x in zip(calib, exp["MD_HALL_CALIB"])), "one Hall calibration per electrode")
    check_truth(got, truth, exp)

    rc2, _ = run_bridge(a.bridge, "--from-log", cand, "--truth", truth, "--write-log", log2)
    rc3, err3 = run_bridge(a.bridge, "--from-log", cand, "--truth", truth, "--write-log", log3, "--lcm-url", "memq://")
    same = open(log1, "rb").read() == open(log2, "rb").read() == open(log3, "rb").read()
    check(rc2 == 0 and rc3 == 0 and same, f"deterministic log, also when publishing on memq:// ({err3.strip()})")
    check_errors(a.bridge, a.work)
    n = sum(len(v) for v in got.values())
    print(f"test_lcm_bridge: {n} messages checked on {len(got)} channels, {len(FAILS)} failures")
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""A crafted telemetry session for the LCM tests (docs/telemetry.md, "Tests").

Besides the real sessions of test_lcm_session, the bridge, the LCM log and the
plots are tested on this synthetic session, whose every value is known: every
frame is encoded with cantools from common/protocol/microdrive.dbc (not with
the project's C packing code), written as a candump -L log, together with a
ground-truth JSON-lines file in the simulator's format (docs/simulator.md
section 6).

    test_lcm_fixture.py --dbc DBC --out DIR [--cycles N] [--seed S]

writes DIR/candump.log, DIR/truth.jsonl and DIR/expected.json (the values the
bridge must reproduce, per LCM channel). Deterministic for a given seed.

The LCM tests that run this session through md-lcm-bridge (test_lcm_bridge,
test_lcm_logplayer, test_lcm_plots) import their common part from here:
parse_args (--bridge BIN --dbc DBC --work DIR), write_session and
bridge_session.

The story: two electrodes, 10 s intervals every 12 s. Electrode 0 advances
towards two neurons (SNR peaks at 1200 and 1250 um): the SFSM goes spike
search -> gradient search -> isolate -> isolated, track 1 follows neuron 0,
track 2 appears later for neuron 1 and misses two intervals. Electrode 1 finds
one neuron, which the simulator then kills: its track is missed K_miss = 5
times and deleted.
"""
import argparse
import json
import math
import os
import random
import subprocess

import cantools

FS = 30000
INTERVAL_S = 10.0
CYCLE_S = 12.0
WAVE_LEN = 48          # d_w: two TLM_WAVE parts, the second padded with zeros
K_MISS = 5
CALIB = {"mid": 32768.0, "half": 16384.0, "c": [1000.0, 400.0]}  # depth = 1000 + 400 x
CYCLES = 24            # the session's length and seed unless told
SEED = 7


def truth_snr(peak, peak_depth, depth):
    """True SNR of a neuron against tip depth: a bump around its SNR peak."""
    return 1.0 + (peak - 1.0) * math.exp(-((depth - peak_depth) / 45.0) ** 2)


def peak_depth(n, k):
    """SNR-peak depth of a neuron in cycle k: the tissue drifts deeper from cycle 8 on."""
    return n["peak_depth"] + n.get("drift", 0.0) * max(0, k - 8)


def waveform(shape_seed, amp):
    """A biphasic mean waveform, uV, WAVE_LEN samples."""
    out = []
    for i in range(WAVE_LEN):
        t = (i - 14) / 4.0
        w = -math.exp(-t * t) + 0.45 * shape_seed * math.exp(-((i - 24) / 6.0) ** 2)
        out.append(int(round(amp * w)))
    return out


class Writer:
    """Encodes frames with cantools and writes candump -L lines."""

    def __init__(self, db, path):
        self.db = db
        self.f = open(path, "w")
        self.fd_ids = {m.frame_id for m in db.messages if m.length > 8}
        self.held = None

    def hold(self):
        """Frames from now on are kept back until release() (to send TLM_STATUS first)."""
        self.held = []

    def release(self):
        lines, self.held = self.held, None
        self.f.writelines(lines)

    def frame(self, t_us, name, **signals):
        msg = self.db.get_message_by_name(name)
        data = msg.encode(signals, strict=True)
        data = data.ljust(msg.length, b"\0")
        ident = f"{msg.frame_id:03X}"
        sep = "##5" if msg.frame_id in self.fd_ids else "#"
        # wall-clock stamps of a fictional recording: 1.7e9 s + sim time
        line = f"({1700000000 + t_us // 1000000}.{t_us % 1000000:06d}) vcan0 {ident}{sep}{data.hex().upper()}\n"
        (self.f.write if self.held is None else self.held.append)(line)

    def clock(self, t_us):
        self.frame(t_us, "SIM_CLOCK", SimTime_us=t_us)


class Electrode:
    def __init__(self, index, start_depth, neurons, kill_cycle=None):
        self.index = index
        self.depth = start_depth
        self.neurons = neurons            # dicts: id, peak, peak_depth, rate, pc, amp, shape
        self.kill_cycle = kill_cycle
        self.tracks = {}                  # neuron id -> dict(id, missed)
        self.next_track = 1
        self.state = 0
        self.hyp_id = 100 * (index + 1)
        self.act_seq = 0
        self.hall_seq = 0


def make_session(db, out, cycles, seed):
    rnd = random.Random(seed)
    w = Writer(db, os.path.join(out, "candump.log"))
    truth = open(os.path.join(out, "truth.jsonl"), "w")
    exp = {k: [] for k in ("MD_STATUS", "MD_CYCLE", "MD_TRACKS", "MD_HYPOTHESES", "MD_SPIKES", "MD_ACTUATOR",
                           "MD_HALL", "MD_HALL_CALIB", "MD_TRUTH_STATE", "MD_TRUTH_DEATH")}
    els = [
        Electrode(0, 1100.0, [dict(id=0, peak=14.0, peak_depth=1200.0, rate=6.0, pc=(-40.0, 10.0), amp=160, shape=1.0,
                                   drift=4.0),
                              dict(id=1, peak=10.0, peak_depth=1220.0, rate=4.0, pc=(25.0, -20.0), amp=110, shape=0.3,
                                   drift=4.0)]),
        Electrode(1, 1300.0, [dict(id=0, peak=11.0, peak_depth=1340.0, rate=8.0, pc=(10.0, 30.0), amp=130,
                                   shape=0.6)], kill_cycle=cycles // 2),
    ]
    alive = {(e.index, n["id"]): True for e in els for n in e.neurons}
    truth.write(json.dumps({"type": "session", "seed": seed, "sample_rate_hz": float(FS), "electrodes": len(els),
                            "bg_rms_uv": [7.0, 7.5]}) + "\n")
    for e in els:
        for n in e.neurons:
            truth.write(json.dumps({"type": "neuron", "electrode": e.index, "neuron": n["id"], "x_um": 20.0,
                                    "y_um": 0.0, "depth_um": n["peak_depth"], "amp_uv": float(n["amp"]),
                                    "rate_hz": n["rate"], "shape": "biphasic"}) + "\n")
    w.clock(0)
    for e in els:
        for k, c in enumerate(CALIB["c"]):
            w.frame(0, "HALL_CALIB", Electrode=e.index, CoeffIndex=k, CoeffCount=2, CoeffValue=c)
        w.frame(0, "HALL_CALIB", Electrode=e.index, CoeffIndex=0xF0, CoeffCount=2, CoeffValue=CALIB["mid"])
        w.frame(0, "HALL_CALIB", Electrode=e.index, CoeffIndex=0xF1, CoeffCount=2, CoeffValue=CALIB["half"])
        exp["MD_HALL_CALIB"].append({"electrode": e.index, "code_mid": CALIB["mid"], "code_half": CALIB["half"],
                                     "coeff_um": CALIB["c"]})
    for k in range(cycles):
        t0 = int(round(k * CYCLE_S * 1e6))
        t1 = t0 + int(INTERVAL_S * 1e6)
        w.clock(t0)
        for e in els:
            cycle_frames_start(w, e, k, t0, exp)
            truth_state(truth, e, k, t0, alive, exp)
        spikes = {e.index: truth_spikes(truth, rnd, e, k, t0, alive) for e in els}
        w.clock(t1)
        for e in els:
            cycle_frames_end(w, rnd, e, k, t0, t1, spikes[e.index], alive, exp)
            if e.kill_cycle == k:
                alive[(e.index, 0)] = False
                truth.write(json.dumps({"type": "death", "electrode": e.index, "neuron": 0,
                                        "t_s": t1 / 1e6, "distance_um": 9.5}) + "\n")
                exp["MD_TRUTH_DEATH"].append({"electrode": e.index, "neuron": 0, "utime": t1})
        plant_frames(w, els, k, t1, exp)
    w.f.close()
    truth.close()
    with open(os.path.join(out, "expected.json"), "w") as f:
        json.dump(exp, f)


def cycle_frames_start(w, e, k, t0, exp):
    w.frame(t0, "TLM_CYCLE", Electrode=e.index, Phase=0, Cycle=k, IntervalId=k, SampleRate_hz=FS,
            NumSamples=int(INTERVAL_S * FS), StartTime_us=t0)
    exp["MD_CYCLE"].append({"electrode": e.index, "phase": 0, "cycle": k, "interval_id": k, "utime": t0,
                            "start_time_us": t0, "num_samples": int(INTERVAL_S * FS), "sample_rate_hz": FS})


def truth_state(truth, e, k, t0, alive, exp):
    rows = []
    for n in e.neurons:
        a = alive[(e.index, n["id"])]
        pd = peak_depth(n, k)
        rows.append({"neuron": n["id"], "depth_um": pd, "alive": a, "distance_um": abs(pd - e.depth) + 20.0,
                     "snr": round(truth_snr(n["peak"], pd, e.depth) if a else 0.0, 4),
                     "snr_peak_depth_um": pd, "snr_peak": n["peak"]})
    rec = {"type": "state", "t_s": t0 / 1e6, "label": f"interval {k}", "electrode": e.index,
           "tip_um": round(e.depth, 4), "neurons": rows}
    truth.write(json.dumps(rec) + "\n")
    exp["MD_TRUTH_STATE"].append(rec)


def truth_spikes(truth, rnd, e, k, t0, alive):
    """Poisson spikes of every live neuron in the interval; (sample, neuron) in time order."""
    start = int(round(t0 * 1e-6 * FS))
    out = []
    for n in e.neurons:
        if not alive[(e.index, n["id"])]:
            continue
        t = rnd.expovariate(n["rate"])
        while t < INTERVAL_S - 0.01:
            out.append((start + int(t * FS), n["id"]))
            t += rnd.expovariate(n["rate"]) + 0.003
    out.sort()
    for s, nid in out:
        truth.write(json.dumps({"type": "spike", "electrode": e.index, "sample": s, "neuron": nid,
                                "amp_uv": 100.0}) + "\n")
    return [(s - start, nid) for s, nid in out]


def update_tracks(rnd, e, k, alive):
    """Tracks of this cycle: (neuron, track dict, detected, snr)."""
    rows = []
    for n in e.neurons:
        a = alive[(e.index, n["id"])]
        snr = truth_snr(n["peak"], peak_depth(n, k), e.depth) * (1.0 + rnd.gauss(0.0, 0.06)) if a else 0.0
        detected = a and snr > 3.0 and not (n["id"] == 1 and e.index == 0 and k in (16, 17))
        tr = e.tracks.get(n["id"])
        if tr is None and detected:
            tr = e.tracks[n["id"]] = {"id": e.next_track, "missed": 0}
            e.next_track += 1
        if tr is None:
            continue
        tr["missed"] = 0 if detected else tr["missed"] + 1
        if tr["missed"] > K_MISS:
            del e.tracks[n["id"]]
            continue
        rows.append((n, tr, detected, snr))
    return rows


def sfsm_decide(e, rows):
    best = max((r[3] for r in rows if r[2]), default=0.0)
    e.best_seen = max(getattr(e, "best_seen", 0.0), best)
    if e.state in (3, 5) and best < 3.0:
        e.state = 0
    elif e.state == 3 and best < 0.85 * e.best_seen:
        e.state = 5
    elif e.state == 5 and best > 0.95 * e.best_seen:
        e.state = 3
    elif e.state == 5:
        pass
    elif not rows:
        e.state = 0
    elif e.state in (0, 1) and best > 6.0:
        e.state = 2
    elif e.state == 0:
        e.state = 1
    elif e.state == 2 and best > 12.0:
        e.state = 3
    step = {0: 20.0, 1: 12.0, 2: 6.0, 3: 0.0, 5: 8.0}[e.state]
    return best, step


def cycle_frames_end(w, rnd, e, k, t0, t1, spikes, alive, exp):
    w.frame(t1, "TLM_CYCLE", Electrode=e.index, Phase=1, Cycle=k, IntervalId=k, SampleRate_hz=FS,
            NumSamples=int(INTERVAL_S * FS), StartTime_us=t0)
    exp["MD_CYCLE"].append({"electrode": e.index, "phase": 1, "cycle": k, "interval_id": k, "utime": t1,
                            "start_time_us": t0, "num_samples": int(INTERVAL_S * FS), "sample_rate_hz": FS})
    w.hold()  # the controller sends TLM_STATUS before the tracks (firmware/app/md_telemetry.c)
    rows = update_tracks(rnd, e, k, alive)
    best, step = sfsm_decide(e, rows)
    tracks = {"electrode": e.index, "cycle": k, "utime": t1, "track_id": [], "spike_count": [], "mean_pc": [],
              "snr": [], "missed": [], "wave": []}
    label = {}
    for idx, (n, tr, detected, snr) in enumerate(rows):
        drift = 0.2 * (e.depth - peak_depth(n, k))
        pc = (round(n["pc"][0] + drift + rnd.gauss(0, 0.6), 2), round(n["pc"][1] - 0.5 * drift + rnd.gauss(0, 0.6), 2))
        count = sum(1 for _, nid in spikes if nid == n["id"]) if detected else 0
        w.frame(t1, "TLM_TRACK", Electrode=e.index, Index=idx, TrackId=tr["id"], Cycle=k, SpikeCount=count,
                MeanPc1=pc[0], MeanPc2=pc[1], Snr=round(snr, 3), Missed=tr["missed"])
        wave = waveform(n["shape"], n["amp"] * min(1.0, snr / n["peak"]) if snr > 0 else 20)
        padded = wave + [0] * (56 - WAVE_LEN)
        for part in range(2):
            w.frame(t1, "TLM_WAVE", Electrode=e.index, Part=part, TrackId=tr["id"],
                    **{f"Wave{i:02d}": padded[28 * part + i] for i in range(28)})
        for key, v in (("track_id", tr["id"]), ("spike_count", count), ("mean_pc", list(pc)), ("snr", round(snr, 3)),
                       ("missed", tr["missed"]), ("wave", padded)):
            tracks[key].append(v)
        if detected:
            label[n["id"]] = tr["id"]
    exp["MD_TRACKS"].append(tracks)
    hyps = hypotheses(w, rnd, e, k, t1, len(rows))
    exp["MD_HYPOTHESES"].append(hyps)
    sp = spikes_frames(w, rnd, e, k, t0, t1, spikes, label)
    exp["MD_SPIKES"].append(sp)
    target = e.depth + step
    iqm = round(1.0 - math.exp(-best / 4.0) - 0.05 * rnd.random(), 3) if best > 0 else 0.0
    dom = rows[0][1]["id"] if rows and rows[0][2] else 0  # 0 = no dominant track
    held, w.held = w.held, None
    w.frame(t1, "TLM_STATUS", Electrode=e.index, SfsmState=e.state, Cycle=k, Depth_um=round(e.depth, 2),
            TargetDepth_um=round(target, 2), Snr=round(best, 3), Iqm=iqm,
            DominantTrack=dom, NumTracks=len(rows), NumHypotheses=len(hyps["rank"]), Flags=0,
            NumSpikes=len(sp["sample"]), GuardAmp=round(best + 3.0, 2), CycleCost=0, ProcessCost=0)
    w.held = held
    w.release()
    exp["MD_STATUS"].append({"electrode": e.index, "cycle": k, "utime": t1, "sfsm_state": e.state,
                             "depth_um": round(e.depth, 2), "target_depth_um": round(target, 2),
                             "snr": round(best, 3), "num_tracks": len(rows), "num_hypotheses": len(hyps["rank"]),
                             "num_spikes": len(sp["sample"]), "dominant_track": dom})
    e.step = step


def hypotheses(w, rnd, e, k, t1, ntracks):
    n = 8 if ntracks else 1
    ratio = 0.2 + 0.6 * rnd.random()
    lp = [math.log(p) for p in normalised([ratio ** r for r in range(n)])]
    out = {"electrode": e.index, "cycle": k, "utime": t1, "rank": [], "hyp_id": [], "log_prob": [], "model_g": []}
    for r in range(n):
        e.hyp_id += 1
        g = max(0, ntracks + (r % 3) - 1)
        w.frame(t1, "TLM_HYP", Electrode=e.index, Rank=r, Cycle=k, HypId=e.hyp_id, LogProb=round(lp[r], 4),
                NumTracks=ntracks, ModelG=g)
        for key, v in (("rank", r), ("hyp_id", e.hyp_id), ("log_prob", round(lp[r], 4)), ("model_g", g)):
            out[key].append(v)
    return out


def normalised(v):
    s = sum(v)
    return [x / s for x in v]


def spikes_frames(w, rnd, e, k, t0, t1, spikes, label):
    det = []
    for s, nid in spikes:
        if nid in label and rnd.random() < 0.92:
            det.append((s + rnd.randint(-3, 3), label[nid]))
        elif nid in label:
            continue
        elif rnd.random() < 0.3:
            det.append((s, -1))
    det.sort()
    for part in range(max(1, (len(det) + 10) // 11)):  # one empty part when nothing was detected
        chunk = det[11 * part: 11 * part + 11]
        sig = {"Electrode": e.index, "Count": len(chunk), "Cycle": k, "Part": part}
        for i in range(11):
            s, t = chunk[i] if i < len(chunk) else (0, 0)
            sig[f"Sample{i:02d}"] = max(0, s)
            sig[f"Track{i:02d}"] = t
        w.frame(t1, "TLM_SPIKES", **sig)
    return {"electrode": e.index, "cycle": k, "utime": t1, "interval_start_us": t0, "sample_rate_hz": FS,
            "sample": [max(0, s) for s, _ in det], "track_id": [t for _, t in det]}


def plant_frames(w, els, k, t1, exp):
    """The move after the cycle (ACT_STATUS moving/idle), then Hall readings every 0.1 s for 1 s with a SIM_CLOCK
    every 0.5 s (readings outnumber clock frames, as on the simulator's bus): the bridge's time, and so each
    reading's utime, is the last SIM_CLOCK's."""
    for e in els:
        e.act_seq = (e.act_seq + 1) % 256
        e.steps = int(round(getattr(e, "step", 0.0) / 2.0))
    for dt, state in ((100000, 1), (1000000, 0)):
        t = t1 + dt
        w.clock(t)
        for e in els:
            done = 0 if state == 1 else e.steps
            w.frame(t, "ACT_STATUS", Electrode=e.index, State=state, CmdSeq=e.act_seq, EndStops=0,
                    StepsDone=done, StepsRemaining=e.steps - done)
            exp["MD_ACTUATOR"].append({"electrode": e.index, "utime": t, "state": state, "cmd_seq": e.act_seq,
                                       "steps_done": done, "steps_remaining": e.steps - done})
    for e in els:
        e.depth += getattr(e, "step", 0.0)
    for i in range(10):
        t = t1 + 1000000 + i * 100000
        if i % 5 == 0:
            w.clock(t)
            t_clock = t
        for e in els:
            code = int(round(CALIB["mid"] + CALIB["half"] * (e.depth - CALIB["c"][0]) / CALIB["c"][1]))
            w.frame(t, "HALL_READING", Electrode=e.index, Seq=e.hall_seq, RawCode=code, SampleTime_ms=t // 1000)
            depth = CALIB["c"][0] + CALIB["c"][1] * (code - CALIB["mid"]) / CALIB["half"]
            exp["MD_HALL"].append({"electrode": e.index, "utime": t_clock, "seq": e.hall_seq, "raw_code": code,
                                   "sample_time_ms": t // 1000, "depth_um": depth})
            e.hall_seq = (e.hall_seq + 1) % 256


def parse_args(description):
    """The command line of the LCM tests on this session: --bridge BIN --dbc DBC --work DIR (made if missing)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--bridge", required=True, help="md-lcm-bridge")
    ap.add_argument("--dbc", required=True, help="common/protocol/microdrive.dbc")
    ap.add_argument("--work", required=True, help="folder for the session and what is made of it")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    return a


def write_session(a):
    """The session (CYCLES, SEED) into a.work: candump.log, truth.jsonl, expected.json."""
    make_session(cantools.database.load_file(a.dbc), a.work, CYCLES, SEED)


def bridge_session(a, name="session.lcmlog"):
    """The session written into a.work and run through md-lcm-bridge into the LCM log a.work/name; its path."""
    write_session(a)
    log = os.path.join(a.work, name)
    subprocess.run([a.bridge, "--quiet", "--from-log", os.path.join(a.work, "candump.log"), "--truth",
                    os.path.join(a.work, "truth.jsonl"), "--write-log", log], check=True)
    return log


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dbc", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--cycles", type=int, default=CYCLES)
    ap.add_argument("--seed", type=int, default=SEED)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    make_session(cantools.database.load_file(a.dbc), a.out, a.cycles, a.seed)


if __name__ == "__main__":
    main()

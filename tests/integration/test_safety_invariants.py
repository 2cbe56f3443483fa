#!/usr/bin/env python3
"""tools/safety/check_invariants.py on crafted candump logs: a clean session
passes; each invariant violated once is detected (and only that one)."""
import json
import os
import subprocess
import sys
import tempfile

import cantools

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
DBC = os.path.join(ROOT, "common", "protocol", "microdrive.dbc")
CHECK = os.path.join(ROOT, "tools", "safety", "check_invariants.py")
db = cantools.database.load_file(DBC, strict=False)


class Log:
    def __init__(self):
        self.t, self.lines = 0.0, []

    def frame(self, name, **sig):
        m = db.get_message_by_name(name)
        full = {s.name: 0 for s in m.signals}
        full.update(sig)
        data = m.encode(full, scaling=True, strict=False)
        sep = "##0" if m.length > 8 else "#"
        self.lines.append(f"({self.t:.6f}) vcan0 {m.frame_id:03X}{sep}{data.hex().upper()}")

    def raw(self, fid, hexdata):
        self.lines.append(f"({self.t:.6f}) vcan0 {fid:03X}#{hexdata}")

    def heartbeats(self, ctrl_state=5, skip=()):
        for node, name in ((1, "HEARTBEAT_CTRL"), (2, "HEARTBEAT_ACT"), (3, "HEARTBEAT_HALL"), (4, "HEARTBEAT_FE")):
            if node not in skip:
                self.frame(name, NodeState=ctrl_state if node == 1 else 5, ProtocolVersion=1)

    def advance(self, dt, ctrl_state=5, skip=()):
        """Lets dt seconds pass with heartbeats every 100 ms."""
        end = self.t + dt
        while self.t + 0.1 <= end + 1e-9:
            self.t += 0.1
            self.heartbeats(ctrl_state, skip)
        self.t = end

    def boot(self):
        self.frame("HEARTBEAT_CTRL", NodeState=0, ProtocolVersion=1)
        self.advance(0.2, ctrl_state=127)
        for k, v in ((0, 2500.0), (1, 2500.0), (0xF0, 32768.0), (0xF1, 32768.0)):
            self.frame("HALL_CALIB", Electrode=0, CoeffIndex=k, CoeffCount=2, CoeffValue=v)
        self.frame("NMT", NmtCommand=1, NmtTarget=0)
        self.advance(0.2)

    def cycle(self, depth, target, steps=None, direction=0, rec_step=False):
        self.frame("REC_REQ", Electrode=0, IntervalId=1, NumSamples=30000)
        self.advance(0.3)
        if rec_step:
            self.frame("ACT_CMD", Electrode=0, Command=1, Direction=0, Seq=1, StepCount=10, StepRate_hz=1000)
        self.advance(0.3)
        self.frame("REC_END", Electrode=0, Status=0, IntervalId=1, TotalSamples=30000)
        self.frame("TLM_STATUS", Electrode=0, Depth_um=depth, TargetDepth_um=target)
        if steps is None:
            steps = int(round(abs(target - depth) / 0.04))
        if steps > 0:
            self.frame("ACT_CMD", Electrode=0, Command=1, Direction=direction, Seq=2, StepCount=steps, StepRate_hz=1000)
        code = min(65535, max(0, int(32768 + (target - 2500.0) / 2500.0 * 32768)))
        self.frame("HALL_READING", Electrode=0, Seq=1, RawCode=code, SampleTime_ms=int(self.t * 1000))
        self.advance(0.2)

    def write(self, d, name):
        path = os.path.join(d, name)
        with open(path, "w") as f:
            f.write("\n".join(self.lines) + "\n")
        return path


def clean():
    g = Log()
    g.boot()
    g.cycle(1000.0, 1010.0)
    g.cycle(1010.0, 1010.0)
    g.cycle(1010.0, 1000.0, direction=1)
    return g


def run(path, *extra):
    p = subprocess.run([sys.executable, CHECK, path, *extra], capture_output=True, text=True)
    return p.returncode, json.loads(p.stdout) if p.stdout.strip() else {}


def violation_cases():
    """One crafted log per invariant, each breaking that invariant once."""
    cases = {}
    cases["window"] = clean()
    cases["window"].cycle(1000.0, 6000.0, steps=0)
    cases["step_cmd"] = clean()
    cases["step_cmd"].cycle(1000.0, 1020.0, steps=1000)          # 40 um of steps for a 20 um move
    cases["step_meas"] = clean()
    cases["step_meas"].cycle(1100.0, 1100.0)                     # 90 um since the last cycle
    cases["rec_motion"] = clean()
    cases["rec_motion"].cycle(1000.0, 1000.0, steps=0, rec_step=True)
    cases["unasked"] = clean()
    cases["unasked"].cycle(1000.0, 1000.0, steps=50)
    g = clean()
    g.advance(1.0, skip=(3,))                                     # Hall node silent 1 s, no EMCY
    cases["hb_lost"] = g
    g = clean()
    g.frame("ESTOP", EstopSource=5, EstopReason=1)
    g.cycle(1000.0, 1010.0)
    cases["estop"] = g
    g = clean()
    g.frame("HEARTBEAT_CTRL", NodeState=0, ProtocolVersion=1)     # restart, no NMT start
    g.advance(0.2, ctrl_state=127)
    g.cycle(1000.0, 1010.0)
    cases["restart"] = g
    return cases


def check_clean_and_handled(d, failures):
    """A clean log, and one whose heartbeat loss and e-stop are handled right, pass."""
    rc, s = run(clean().write(d, "clean.log"))
    if rc != 0 or not s.get("ok"):
        failures.append(f"clean log: rc {rc}, {s.get('violations')}")
    # heartbeat loss handled right: EMCY in time, no motion until back, then motion again
    g = clean()
    g.advance(0.6, skip=(3,))
    g.frame("EMCY_CTRL", ErrorCode=0x8130, ErrorRegister=0x10, Electrode=255, Info=3)
    g.advance(0.3, skip=(3,))
    g.advance(0.2)
    g.cycle(1000.0, 1010.0)
    # e-stop handled right: cleared by NMT before the next step
    g.frame("ESTOP", EstopSource=5, EstopReason=1)
    g.advance(0.3)
    g.frame("NMT", NmtCommand=131, NmtTarget=0)
    g.cycle(1010.0, 1020.0)
    rc, s = run(g.write(d, "handled.log"))
    if rc != 0:
        failures.append(f"handled faults flagged: {s.get('violations')}")


def check_violations(d, failures):
    """Each crafted violation is detected, and only that one."""
    for inv, g in violation_cases().items():
        rc, s = run(g.write(d, f"{inv}.log"))
        by = s.get("violations_by_invariant", {})
        others = {k: v for k, v in by.items() if v and k != inv}
        if rc != 1 or by.get(inv, 0) < 1 or others:
            failures.append(f"{inv}: rc {rc}, by invariant {by}")
        else:
            print(f"ok: {inv} detected ({by[inv]})")


def check_start_and_steps(d, failures):
    """--auto-start, the retract/advance step counts, the true-tip jump, a missing log."""
    # --auto-start: preop then operational heartbeat counts as the start
    g = Log()
    g.frame("HEARTBEAT_CTRL", NodeState=0, ProtocolVersion=1)
    g.advance(0.2, ctrl_state=127)
    g.advance(0.2)
    g.cycle(1000.0, 1010.0)
    p = g.write(d, "auto.log")
    if run(p, "--auto-start")[0] != 0 or run(p)[0] != 1:
        failures.append("auto-start handling")
    # a full Delta_max retract takes more steps than an advance (retract steps are shorter)
    g = clean()
    g.cycle(1010.0, 980.0, steps=880, direction=1)
    rc, s = run(g.write(d, "retract.log"))
    if rc != 0:
        failures.append(f"30 um retract in 880 steps flagged: {s.get('violations')}")
    g = clean()
    g.cycle(1000.0, 1030.0, steps=880)                            # 35 um of advance steps
    rc, s = run(g.write(d, "advance.log"))
    if rc != 1 or s["violations_by_invariant"].get("step_cmd", 0) < 1:
        failures.append(f"35 um advance not flagged: {s.get('violations_by_invariant')}")
    check_true_tip(d, failures)
    if subprocess.run([sys.executable, CHECK, os.path.join(d, "missing.log")], capture_output=True).returncode != 2:
        failures.append("unreadable log must exit 2")


def check_true_tip(d, failures):
    """step_true: the true tip (truth.jsonl) jumps 40 um between two recordings."""
    tp = os.path.join(d, "truth.jsonl")
    with open(tp, "w") as f:
        f.write('{"type":"neuron","electrode":0,"neuron":0,"depth_um":1200.0}\n')
        for t, tip in ((0.0, 1000.0), (10.0, 1020.0), (20.0, 1060.0)):
            f.write(json.dumps({"type": "state", "t_s": t, "electrode": 0, "tip_um": tip}) + "\n")
    rc, s = run(clean().write(d, "clean2.log"), "--truth", tp)
    by = s.get("violations_by_invariant", {})
    if rc != 1 or by.get("step_true") != 1 or any(v for k, v in by.items() if k != "step_true"):
        failures.append(f"step_true: rc {rc}, {by}")
    else:
        print("ok: step_true detected (1)")


def main():
    failures = []
    with tempfile.TemporaryDirectory() as d:
        check_clean_and_handled(d, failures)
        check_violations(d, failures)
        check_start_and_steps(d, failures)
    for f in failures:
        print("FAIL:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Integration tests of microdrive-fw on the UDP bus (label integration).

Run inside a private network namespace (scripts/netns-run.sh), one scenario
per ctest:

    netns-run.sh PYTHON test_fw_node.py SCENARIO --fw BIN --mdcan BIN --dbc DBC

The firmware runs as its own process; `mdcan dump` records the bus (candump -L
lines, read and decoded by DBC message name with microdrive.canlog and the
project DBC) and `mdcan send` plays
the other nodes: a fake actuator heartbeat, the operator's NMT, e-stop and
parameter requests, and deliberately malformed frames.

Scenarios: params, heartbeat_lost, estop, malformed. heartbeat_lost prints the
measured EMCY latency (line "EMCY latency: ...").
"""
import argparse
import subprocess
import sys
import threading
import time

from microdrive import canlog

HB_MS = 100
RUNNING = []  # firmware processes to kill if a scenario fails
TIMEOUT_MS = 300


class Bus:
    """A running `mdcan dump` plus helpers to send and to wait for frames, named as in the DBC."""

    def __init__(self, mdcan, db):
        self.mdcan = mdcan
        self.db = db
        self.names = {m.frame_id: m.name for m in db.messages}
        self.frames = []  # canlog.Frame (name None: an id the DBC does not define)
        self.lock = threading.Lock()
        self.proc = subprocess.Popen([mdcan, "dump", "--bus", "udp", "--timeout-ms", "60000"],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = self.proc.stderr.readline()
        if "listening on" not in line:
            raise SystemExit(f"mdcan dump did not start: {line!r}")
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            r = canlog.parse_line(line)
            if r is None:
                continue
            t, frame_id, data = r
            with self.lock:
                self.frames.append(canlog.Frame(t, frame_id, self.names.get(frame_id), data))

    def close(self):
        self.proc.terminate()
        self.proc.wait(timeout=5)

    def send(self, *frames):
        """Sends candump-syntax frames; returns (time before, time after)."""
        t0 = time.time()
        subprocess.run([self.mdcan, "send", "--bus", "udp", *frames], check=True)
        return t0, time.time()

    def mark(self):
        with self.lock:
            return len(self.frames)

    def since(self, mark, name=None):
        """Frames after mark (only the DBC message `name` if given)."""
        if name is not None and name not in self.names.values():
            raise KeyError(f"{name} is no message of the DBC")
        with self.lock:
            return [f for f in self.frames[mark:] if name is None or f.name == name]

    def wait_for(self, mark, name, pred=lambda m: True, timeout_s=3.0):
        """First frame of message `name` after mark whose decoded signals satisfy pred."""
        deadline = time.time() + timeout_s
        while time.time() < deadline:
            for f in self.since(mark, name):
                msg = self.decode(f)
                if msg is not None and pred(msg):
                    return f, msg
            time.sleep(0.005)
        raise AssertionError(f"no {name} frame matching within {timeout_s} s")

    def decode(self, f):
        """The frame's signals (raw enumeration values), None if its data does not decode."""
        return canlog.decode(self.db, f)


def check(cond, what):
    if not cond:
        raise AssertionError(what)
    print(f"ok: {what}")


# Frame builders (candump syntax), packed with the DBC so layouts come from one place.
def frame(db, name, **sig):
    m = db.get_message_by_name(name)
    data = m.encode(sig, strict=False)  # some tests send values the DBC forbids
    sep = "##0" if m.is_fd else "#"
    return f"{m.frame_id:03X}{sep}{data.hex().upper()}"


def param_req(db, op, index, value=0.0):
    return frame(db, "PARAM_REQ_CTRL", Op=op, Reserved=0, Index=index, Value=value)


def nmt(db, cmd, target=0):
    return frame(db, "NMT", NmtCommand=cmd, NmtTarget=target)


def act_heartbeat(db, state=5):
    return frame(db, "HEARTBEAT_ACT", NodeState=state, ProtocolVersion=1, Flags=0, Electrodes=3, Uptime_s=1)


def param(bus, db, op, index, value=0.0):
    m = bus.mark()
    bus.send(param_req(db, op, index, value))
    _, resp = bus.wait_for(m, "PARAM_RESP_CTRL", lambda r: r["Index"] == index)
    return resp


def start_fw(args, bus, *extra):
    m = bus.mark()
    fw = subprocess.Popen([args.fw, "--bus", "udp", "--heartbeat-ms", str(HB_MS),
                           "--heartbeat-timeout-ms", str(TIMEOUT_MS), *extra],
                          stderr=subprocess.PIPE, text=True)
    RUNNING.append(fw)
    bus.wait_for(m, "HEARTBEAT_CTRL", lambda h: h["NodeState"] == 0)  # boot-up
    bus.wait_for(m, "HEARTBEAT_CTRL", lambda h: h["NodeState"] == 127)
    return fw


def stop_fw(fw):
    fw.send_signal(2)  # SIGINT: clean exit with a summary on stderr
    rc = fw.wait(timeout=5)
    err = fw.stderr.read()
    sys.stdout.write(err)
    check(rc == 0, f"microdrive-fw exits 0 on SIGINT (got {rc})")
    check("bus udp" in err, "microdrive-fw reports the bus it chose")
    return err


def next_heartbeat(bus):
    m = bus.mark()
    return bus.wait_for(m, "HEARTBEAT_CTRL", timeout_s=1.0)[1]


# ---------------------------------------------------------------- scenarios

def scenario_params(args, bus, db):
    fw = start_fw(args, bus)
    m = bus.mark()
    time.sleep(1.05)
    hbs = bus.since(m, "HEARTBEAT_CTRL")
    gaps = [b.t - a.t for a, b in zip(hbs, hbs[1:])]
    check(len(hbs) >= 9, f"about 10 heartbeats in 1 s (got {len(hbs)})")
    mean_ms = 1000 * sum(gaps) / len(gaps)
    check(abs(mean_ms - HB_MS) < 10, f"mean heartbeat period {mean_ms:.1f} ms ~ {HB_MS} ms")
    hb = bus.decode(hbs[-1])
    check(hb["ProtocolVersion"] == 1 and hb["Electrodes"] == 3, "heartbeat carries protocol version and electrodes")
    r = param(bus, db, 1, 0x1017)
    check(r["Status"] == 0 and r["Value"] == HB_MS, f"get heartbeat_period_ms -> ok {r['Value']}")
    r = param(bus, db, 2, 0x1017, 200.0)
    check(r["Status"] == 0 and r["Value"] == 200.0, "set heartbeat_period_ms 200 -> ok")
    m = bus.mark()
    time.sleep(1.05)
    n = len(bus.since(m, "HEARTBEAT_CTRL"))
    check(4 <= n <= 6, f"heartbeat follows the new period (5 expected in 1 s, got {n})")
    check(param(bus, db, 2, 0x1017, 1.0)["Status"] == 2, "out of range -> status 2")
    check(param(bus, db, 2, 0x1017, float("nan"))["Status"] == 2, "NaN -> status 2")
    check(param(bus, db, 2, 0x3010, 0.0)["Status"] == 3, "read-only counter -> status 3")
    check(param(bus, db, 1, 0x7777)["Status"] == 1, "unknown index -> status 1")
    check(param(bus, db, 7, 0x1017)["Status"] == 5, "bad op -> status 5")
    r = param(bus, db, 1, 0x3010)
    check(r["Status"] == 0 and r["Value"] >= 7, f"rx_frames readable ({r['Value']})")
    stop_fw(fw)


def scenario_heartbeat_lost(args, bus, db):
    fw = start_fw(args, bus)
    bus.send(nmt(db, 1))
    last = None
    for _ in range(10):
        last = bus.send(act_heartbeat(db))
        time.sleep(HB_MS / 1000)
    check(next_heartbeat(bus)["NodeState"] == 5, "operational with the actuator alive")
    m = bus.mark()
    # silence from here: the last heartbeat left between last[0] and last[1]
    emcy_frame, emcy = bus.wait_for(m, "EMCY_CTRL", lambda e: e["ErrorCode"] == 0x8130, timeout_s=2.0)
    latency_ms = 1000 * (emcy_frame.t - last[0])
    latency_hi_ms = 1000 * (emcy_frame.t - last[1])
    print(f"EMCY latency: {latency_hi_ms:.1f}..{latency_ms:.1f} ms after the last actuator heartbeat "
          f"(timeout {TIMEOUT_MS} ms)")
    check(emcy["Info"] == 2, "EMCY HEARTBEAT_LOST names the actuator (Info 2)")
    check(latency_ms >= TIMEOUT_MS, "EMCY not before the timeout")
    check(latency_hi_ms <= TIMEOUT_MS + 50, "EMCY within timeout + 50 ms")
    halts = [bus.decode(f) for f in bus.since(m, "ACT_CMD")]
    check(sorted(h["Electrode"] for h in halts if h["Command"] == 0) == [0, 1, 2], "halt sent to every electrode")
    time.sleep(1.0)
    check(len([f for f in bus.since(m, "EMCY_CTRL") if bus.decode(f)["ErrorCode"] == 0x8130]) == 1, "exactly one EMCY")
    check(next_heartbeat(bus)["Flags"] & 2, "heartbeat flags fault present")
    m = bus.mark()
    bus.send(act_heartbeat(db))
    _, back = bus.wait_for(m, "EMCY_CTRL", lambda e: e["ErrorCode"] == 0 and e["Info"] == 2)
    check(True, "node back noted with EMCY 0x0000 Info 2")
    check(param(bus, db, 1, 0x3030)["Value"] == 1 and param(bus, db, 1, 0x3031)["Value"] == 1,
          "heartbeat_lost and node_back counters are 1")
    stop_fw(fw)


def scenario_estop(args, bus, db):
    fw = start_fw(args, bus)
    bus.send(nmt(db, 1))
    check(next_heartbeat(bus)["NodeState"] == 5, "operational")
    m = bus.mark()
    bus.send(frame(db, "ESTOP", EstopSource=5, EstopReason=1))
    _, e = bus.wait_for(m, "EMCY_CTRL", lambda e: e["ErrorCode"] == 0x6200)
    check(e["Info"] == 5, "EMCY ESTOP names the source")
    time.sleep(0.1)
    halts = [bus.decode(f) for f in bus.since(m, "ACT_CMD")]
    check(sorted(h["Electrode"] for h in halts if h["Command"] == 0) == [0, 1, 2], "halt sent to every electrode")
    hb = next_heartbeat(bus)
    check(hb["Flags"] & 1 and hb["NodeState"] == 127, "latched flag, pre-operational")
    bus.send(nmt(db, 1))
    check(next_heartbeat(bus)["NodeState"] == 127, "NMT start refused while latched")
    check(param(bus, db, 2, 0x2001, 40.0)["Status"] == 4, "motion parameter set refused (status 4)")
    time.sleep(1.0)
    check(next_heartbeat(bus)["Flags"] & 1, "still latched after a second")
    m = bus.mark()
    bus.send(nmt(db, 129, 1))
    _, boot = bus.wait_for(m, "HEARTBEAT_CTRL", lambda h: h["NodeState"] == 0)
    check(boot["Flags"] & 1, "reset-node reboots with the e-stop still latched")
    check(next_heartbeat(bus)["Flags"] & 1, "still latched after reset-node")
    bus.send(nmt(db, 131, 1))
    hb = next_heartbeat(bus)
    check(not hb["Flags"] & 1 and hb["NodeState"] == 127, "clear-e-stop unlatches, stays pre-operational")
    bus.send(nmt(db, 1, 1))
    check(next_heartbeat(bus)["NodeState"] == 5, "start accepted after the clear")
    stop_fw(fw)


def scenario_malformed(args, bus, db):
    fw = start_fw(args, bus)
    good = param_req(db, 2, 0x1017, 500.0)
    ident, data = good.split("#")
    m = bus.mark()
    bus.send(f"{ident}#{data[:14]}",          # 7 bytes: bad length
             f"{ident}##0{data}",             # FD flag on a classic frame: bad length
             "123#0011",                      # unknown id
             "12345678#00",                   # 29-bit id: unknown
             nmt(db, 7),                      # NMT command 7: bad range
             frame(db, "HEARTBEAT_ACT", NodeState=5, ProtocolVersion=9, Flags=0, Electrodes=3, Uptime_s=0),
             frame(db, "HALL_READING", Electrode=0, Seq=0, RawCode=1, SampleTime_ms=0),
             frame(db, "HALL_READING", Electrode=0, Seq=5, RawCode=1, SampleTime_ms=0),  # bad sequence
             frame(db, "ACT_CMD", Electrode=0, Command=1, Direction=0, Seq=0, StepCount=1,
                   StepRate_hz=1))            # ACT_CMD from someone else: id conflict
    time.sleep(0.3)
    check(not bus.since(m, "PARAM_RESP_CTRL"), "no parameter response to a malformed request")
    check(param(bus, db, 1, 0x1017)["Value"] == HB_MS, "heartbeat period unchanged")
    expect = {0x3011: 4, 0x3012: 2, 0x3013: 2, 0x3014: 2, 0x3015: 1, 0x3016: 1}
    for index, want in expect.items():
        got = param(bus, db, 1, index)["Value"]
        check(got == want, f"counter 0x{index:04X} = {got} (want {want})")
    emcys = [bus.decode(f) for f in bus.since(m, "EMCY_CTRL")]
    check(len(emcys) == 1 and emcys[0]["ErrorCode"] == 0x8200, "one protocol EMCY (inhibited after the first)")
    check(len(bus.since(m, "ACT_CMD")) == 1, "no motion command (the one ACT_CMD on the bus is ours)")
    check(next_heartbeat(bus)["NodeState"] == 127 and next_heartbeat(bus)["Flags"] == 0, "state unchanged")
    err = stop_fw(fw)
    check("malformed 4" in err, "exit summary counts the malformed frames")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", choices=["params", "heartbeat_lost", "estop", "malformed"])
    ap.add_argument("--fw", required=True)
    ap.add_argument("--mdcan", required=True)
    ap.add_argument("--dbc", required=True)
    args = ap.parse_args()
    db = canlog.load_dbc(args.dbc)
    bus = Bus(args.mdcan, db)
    try:
        globals()["scenario_" + args.scenario](args, bus, db)
    finally:
        for fw in RUNNING:
            if fw.poll() is None:
                fw.kill()
                fw.wait()
        bus.close()
    print(f"test_fw_node {args.scenario}: OK")


if __name__ == "__main__":
    main()

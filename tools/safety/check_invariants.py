#!/usr/bin/env python3
"""Safety invariants of a microdrive session, checked on its frame log.

usage: check_invariants.py LOG [--truth truth.jsonl] [--dbc microdrive.dbc]
                           [--depth-min-um 0] [--depth-max-um 5000] [--move-max-um 30]
                           [--step-len-um 0.040] [--tol-um 3] [--hb-timeout-ms 500]
                           [--auto-start] [--json OUT]

LOG is candump -L format ("(t) iface ID#HEX" or "ID##<flags>HEX"). Frames are
read by message name and decoded with the project DBC (microdrive.canlog). Invariants (docs/safety.md):

  window        TLM_STATUS depth and target, and the Hall-derived depth (HALL_CALIB
                + HALL_READING), stay inside [depth_min, depth_max] (+ tol)
  step_cmd      per move (ACT_CMDs after a TLM_STATUS), |net commanded travel| <= step_max
                + tol, the travel of a step being step_len deeper (advance) and
                step_len x retract_ratio shallower (retract: stick-slip drives retract by
                less per step, host_sim/model/actuator.h)
  step_meas     consecutive TLM_STATUS depths of an electrode differ by <= step_max + tol
  rec_motion    no ACT_CMD step for an electrode between its REC_REQ and REC_END
  unasked       an ACT_CMD step only after a TLM_STATUS whose target != depth
  hb_lost       a monitored node (2, 3, 4) silent longer than the timeout -> EMCY 0x8130
                (Info = node) within timeout + grace, and no ACT_CMD step until its
                heartbeat is back
  estop         after an ESTOP frame, no ACT_CMD step until NMT clear-e-stop (131)
  restart       after a controller boot (HEARTBEAT_CTRL state 0), its heartbeats are
                not operational and no ACT_CMD step happens until NMT start (or, with
                --auto-start, an operational heartbeat following a pre-operational one)

With --truth, the true tip depth of every electrode in truth.jsonl is also
checked against the window (`window`), and the true tip may move by at most
step_max + tol between consecutive recordings of an electrode (`step_true`:
what the electrode really did, whatever the sensor said), and no neuron may
die (`neuron_damaged`: a truth `death` record, the tip came closer than the
simulator's damage radius). Exit status: 0 all hold, 1 a violation, 2 the
log cannot be read. A JSON summary goes to stdout (and --json OUT).
"""
import argparse
import json
import sys
from collections import defaultdict

from microdrive import canlog

DBC_DEFAULT = canlog.DBC

HB_NODE = {"HEARTBEAT_CTRL": 1, "HEARTBEAT_ACT": 2, "HEARTBEAT_HALL": 3, "HEARTBEAT_FE": 4}  # the nodes watched
TLM_F_NO_DEPTH = 0x0100   # MD_TLM_F_NO_DEPTH (firmware/app/md_cycle.h): no calibrated Hall depth in this status
MONITORED = (2, 3, 4)
NMT_START, NMT_CLEAR_ESTOP = 1, 131
EMCY_HB_LOST = 0x8130
STATE_BOOT, STATE_OPERATIONAL, STATE_PREOP = 0, 5, 127
CALIB_MID, CALIB_HALF = 0xF0, 0xF1
INVARIANTS = ("window", "step_cmd", "step_meas", "step_true", "rec_motion", "unasked", "hb_lost", "estop", "restart",
              "neuron_damaged")


class Checker:
    def __init__(self, db, a):
        self.db, self.a = db, a
        self.violations = []
        self.counts = defaultdict(int)
        self.recording = defaultdict(bool)          # e -> between REC_REQ and REC_END
        self.asked = defaultdict(bool)              # e -> last TLM_STATUS asked for motion
        self.net_um = defaultdict(float)            # e -> signed commanded travel of the current move
        self.last_depth = {}                        # e -> last TLM_STATUS depth
        self.calib = defaultdict(dict)              # e -> {index: value}
        self.hb_last = {}                           # node -> t of last heartbeat
        self.hb_lost = {}                           # node -> t when its timeout expired
        self.emcy_due = {}                          # node -> deadline for EMCY 0x8130
        self.estop = False
        self.booted_at = None                       # t of the last controller boot, until started
        self.saw_preop = False

    def violate(self, inv, t, msg):
        self.violations.append({"invariant": inv, "t": round(t, 6), "what": msg})

    def in_window(self, d):
        return self.a.depth_min_um - self.a.tol_um <= d <= self.a.depth_max_um + self.a.tol_um

    # -- heartbeats ---------------------------------------------------------
    def tick(self, t):
        timeout = self.a.hb_timeout_ms / 1000.0
        for node, last in self.hb_last.items():
            if node not in self.hb_lost and t - last > timeout:
                self.hb_lost[node] = last + timeout
                self.emcy_due[node] = last + timeout + self.a.emcy_grace_ms / 1000.0
                self.counts["hb_lost_events"] += 1
        for node, due in list(self.emcy_due.items()):
            if t > due:
                self.violate("hb_lost", due, f"no EMCY 0x8130 for node {node} within the timeout")
                del self.emcy_due[node]

    def heartbeat(self, t, node, m):
        if node == 1:
            st = int(m["NodeState"])
            if st == STATE_BOOT:
                self.booted_at, self.saw_preop = t, False
                self.counts["controller_boots"] += 1
                self.counts["tlm_status_since_last_boot"] = 0   # resumed? (controller_restart)
                self.recording.clear()
                self.asked.clear()
            elif self.booted_at is not None:
                if st == STATE_PREOP:
                    self.saw_preop = True
                elif st == STATE_OPERATIONAL:
                    if self.a.auto_start and self.saw_preop:
                        self.booted_at = None
                    elif not self.saw_preop:
                        self.violate("restart", t, "controller operational right after boot")
                        self.booted_at = None
            return
        if node in MONITORED:
            self.hb_last[node] = t
            self.hb_lost.pop(node, None)

    # -- motion ---------------------------------------------------------------
    def act_cmd(self, t, m):
        e = int(m["Electrode"])
        if int(m["Command"]) != 1 or int(m["StepCount"]) == 0:
            return
        self.counts["act_steps_cmds"] += 1
        if self.recording[e]:
            self.violate("rec_motion", t, f"ACT_CMD step on electrode {e} while it records")
        if not self.asked[e]:
            self.violate("unasked", t, f"ACT_CMD step on electrode {e} without an SFSM request")
        for node, since in self.hb_lost.items():
            self.violate("hb_lost", t, f"ACT_CMD step on electrode {e} while node {node} is lost (since {since:.3f})")
        if self.estop:
            self.violate("estop", t, f"ACT_CMD step on electrode {e} after an ESTOP")
        if self.booted_at is not None:
            self.violate("restart", t, f"ACT_CMD step on electrode {e} before start after the boot at {self.booted_at:.3f}")
        retract = int(m["Direction"]) == 1
        step_um = self.a.step_len_um * (self.a.retract_ratio if retract else 1.0)
        self.net_um[e] += (-1.0 if retract else 1.0) * int(m["StepCount"]) * step_um
        if abs(self.net_um[e]) > self.a.move_max_um + self.a.tol_um:
            self.violate("step_cmd", t, f"electrode {e}: {abs(self.net_um[e]):.2f} um commanded in one move "
                         f"(> {self.a.move_max_um} um; {self.a.step_len_um} um/step, retract x{self.a.retract_ratio})")
            self.net_um[e] = 0.0

    def status(self, t, m):
        e = int(m["Electrode"])
        d, tg = float(m["Depth_um"]), float(m["TargetDepth_um"])
        self.counts["tlm_status"] += 1
        if int(m["Flags"]) & TLM_F_NO_DEPTH:
            self.counts["tlm_status_no_depth"] += 1   # no Hall depth yet: the fields hold no measurement
            self.asked[e] = False
            self.net_um[e] = 0.0
            return
        self.counts["tlm_status_since_last_boot"] += 1
        for what, v in (("depth", d), ("target", tg)):
            if not self.in_window(v):
                self.violate("window", t, f"electrode {e}: TLM_STATUS {what} {v:.2f} um outside the window")
        if e in self.last_depth and abs(d - self.last_depth[e]) > self.a.move_max_um + self.a.tol_um:
            self.violate("step_meas", t, f"electrode {e}: depth moved {d - self.last_depth[e]:.2f} um in one cycle")
        self.last_depth[e] = d
        self.asked[e] = abs(tg - d) > 1e-3
        self.net_um[e] = 0.0

    def hall(self, t, name, m):
        e = int(m["Electrode"])
        if name == "HALL_CALIB":
            self.calib[e][int(m["CoeffIndex"])] = float(m["CoeffValue"])
            self.calib[e]["n"] = int(m["CoeffCount"])
            return
        c = self.calib[e]
        if "n" not in c or CALIB_MID not in c or CALIB_HALF not in c or any(k not in c for k in range(c["n"])):
            return
        x = (float(m["RawCode"]) - c[CALIB_MID]) / c[CALIB_HALF]
        depth = sum(c[k] * x ** k for k in range(c["n"]))
        self.counts["hall_readings"] += 1
        if not self.in_window(depth):
            self.counts["hall_outside_window"] += 1   # a glitch is a sensor fault, not a motion
            if self.a.strict_hall:
                self.violate("window", t, f"electrode {e}: Hall depth {depth:.2f} um outside the window")

    def frame(self, t, name, m):
        """One frame of the log: name None for an id the DBC does not define, m None if it does not decode."""
        self.tick(t)
        self.counts["frames"] += 1
        if name == "ESTOP":
            self.estop = True
            self.counts["estops"] += 1
            return
        if name is None:
            return
        if m is None:
            self.counts["undecodable"] += 1
            return
        if name == "NMT":
            cmd, target = int(m["NmtCommand"]), int(m["NmtTarget"])
            if target in (0, 1) and cmd == NMT_CLEAR_ESTOP:
                self.estop = False
            if target in (0, 1) and cmd == NMT_START:
                self.booted_at = None
        elif name == "EMCY_CTRL":
            if int(m["ErrorCode"]) == EMCY_HB_LOST:
                self.emcy_due.pop(int(m["Info"]), None)
                self.counts["emcy_hb_lost"] += 1
        elif name in HB_NODE:
            self.heartbeat(t, HB_NODE[name], m)
        elif name == "ACT_CMD":
            self.act_cmd(t, m)
        elif name == "REC_REQ":
            self.recording[int(m["Electrode"])] = True
        elif name == "REC_END":
            self.recording[int(m["Electrode"])] = False
        elif name == "TLM_STATUS":
            self.status(t, m)
        elif name in ("HALL_READING", "HALL_CALIB"):
            self.hall(t, name, m)


def check_truth(path, a, violations):
    """True tip depths of truth.jsonl against the window (records with a tip depth), the
    true motion between consecutive tip records of an electrode against step_max, and
    every neuron death."""
    n = 0
    last = {}
    with open(path) as f:
        for line in f:
            try:
                r = json.loads(line)
            except ValueError:
                continue
            if r.get("type") == "death":
                violations.append({"invariant": "neuron_damaged", "t": r.get("t_s", 0.0),
                                   "what": f"electrode {r.get('electrode')}: neuron {r.get('neuron')} died, tip "
                                           f"{r.get('distance_um')} um from it"})
                continue
            for key in ("tip_um", "tip_depth_um", "depth_um"):
                if key in r and "electrode" in r:
                    n += 1
                    d = float(r[key])
                    t = r.get("t", r.get("t_s", 0.0))
                    if not (a.depth_min_um - a.tol_um <= d <= a.depth_max_um + a.tol_um):
                        violations.append({"invariant": "window", "t": t,
                                           "what": f"electrode {r['electrode']}: true tip {d:.2f} um outside"})
                    e = r["electrode"]
                    if key == "depth_um":
                        break   # a neuron's depth, not the tip
                    if e in last and abs(d - last[e]) > a.move_max_um + a.tol_um:
                        violations.append({"invariant": "step_true", "t": t,
                                           "what": f"electrode {e}: true tip moved {d - last[e]:.2f} um between "
                                                   f"recordings (> {a.move_max_um} um)"})
                    last[e] = d
                    break
    return n


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("log")
    p.add_argument("--truth")
    p.add_argument("--dbc", default=DBC_DEFAULT)
    p.add_argument("--depth-min-um", type=float, default=0.0)
    p.add_argument("--depth-max-um", type=float, default=5000.0)
    p.add_argument("--move-max-um", type=float, default=30.0, help="Delta_max (controller move_max_um)")
    p.add_argument("--step-len-um", type=float, default=0.040, help="advance step length the command bound assumes")
    p.add_argument("--retract-ratio", type=float, default=0.85,
                   help="retract step / advance step (host_sim/model/actuator.h default)")
    p.add_argument("--tol-um", type=float, default=3.0, help="servo tolerance + Hall noise allowance")
    p.add_argument("--hb-timeout-ms", type=float, default=500.0)
    p.add_argument("--emcy-grace-ms", type=float, default=100.0, help="allowed lateness of the EMCY")
    p.add_argument("--auto-start", action="store_true", help="controller starts itself (no NMT start needed)")
    p.add_argument("--strict-hall", action="store_true", help="a Hall-derived depth outside the window is a violation")
    p.add_argument("--json", help="also write the summary here")
    a = p.parse_args(argv)
    db = canlog.load_dbc(a.dbc)
    ck = Checker(db, a)
    try:
        for fr in canlog.frames(a.log, db=db):
            ck.frame(fr.t, fr.name, canlog.decode(db, fr) if fr.name not in (None, "ESTOP") else None)
    except OSError as e:
        print(f"check_invariants: {e}", file=sys.stderr)
        return 2
    truth_n = check_truth(a.truth, a, ck.violations) if a.truth else 0
    by = {k: 0 for k in INVARIANTS}
    for v in ck.violations:
        by[v["invariant"]] += 1
    summary = {"log": a.log, "ok": not ck.violations, "violations_by_invariant": by,
               "violations": ck.violations[:100], "n_violations": len(ck.violations),
               "counts": dict(ck.counts), "truth_records": truth_n}
    text = json.dumps(summary, indent=1)
    print(text)
    if a.json:
        with open(a.json, "w") as f:
            f.write(text + "\n")
    return 0 if summary["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())

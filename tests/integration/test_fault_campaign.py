#!/usr/bin/env python3
"""CI fault campaign: one seed x every fault kind in scenarios/faults/ through the
in-process session, each frame log and truth checked by tools/safety/check_invariants.py.

usage: test_fault_campaign.py --session BIN/microdrive-session --work DIR [--seeds N] [--cycles N]

Fails if any run violates an invariant, leaves no log, shows no trace of its fault (a fault
whose counter microdrive-session prints stayed at zero: the hook is not wired), or, after a
controller_restart, the controller does not resume its cycles, EXCEPT the
violations listed in KNOWN_OPEN below: findings of the campaign in units this test does not own
(docs/fault-campaign.md, "Open"; tools/safety/campaign_findings.md), tolerated by
(kind, invariant) exactly, so that every other invariant keeps
guarding. A known-open entry that does not occur is printed as a NOTE (fixed? remove it) but
does not fail the test: the fix belongs to a unit this test does not own.
~1-2 s per run on the shared 2-core VM: 15 runs well under a minute.
"""
import argparse
import os
import subprocess
import sys
import json

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
CAMPAIGN = os.path.join(ROOT, "tools", "safety", "campaign.py")

# (kind, invariant) -> violations tolerated per run, for open findings in units this test does
# not own. Empty: every run must hold every invariant.
KNOWN_OPEN = {}
# after a controller_restart the controller must come back and run cycles again: status frames
# with a measured depth after its last boot (check_invariants.py counts them)
RESUME_MIN_STATUS = 2
# faults whose hook prints a counter: at least one must be non-zero
COUNTED = {"bus_loss": "loss", "bus_corrupt": "corrupt", "bus_dup": "dup", "bus_delay": "delay",
           "bus_reorder": "reorder", "node_silent_act": "silenced heartbeats",
           "node_silent_hall": "silenced heartbeats", "node_silent_fe": "silenced heartbeats",
           "controller_restart": "restarts", "hall_glitch": "hall glitches", "hall_stuck": "hall stuck reads",
           "actuator_stall": "actuator stalls", "actuator_slip": "actuator slips",
           "artifact_storm": "storm events", "adc_saturation": "saturated samples"}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--session", required=True)
    p.add_argument("--work", required=True)
    p.add_argument("--seeds", type=int, default=1)
    p.add_argument("--cycles", type=int, default=12)
    a = p.parse_args()
    os.makedirs(a.work, exist_ok=True)
    cmd = [sys.executable, CAMPAIGN, "--seeds", str(a.seeds), "--cycles", str(a.cycles), "--session", a.session,
           "--out", a.work, "--no-doc", "--timeout-s", "120"]
    print(" ".join(cmd), flush=True)
    subprocess.run(cmd, check=False)   # its exit status is re-derived below, with KNOWN_OPEN
    with open(os.path.join(a.work, "campaign.json")) as f:
        rows = json.load(f)
    fails, seen_open = [], set()
    for kind, runs in rows.items():
        for r in runs:
            s = r["summary"]
            if s is None:
                fails.append(f"{kind} seed {r['seed']}: no log or checker failure ({r['end']})")
                continue
            for inv, n in s["violations_by_invariant"].items():
                if n == 0:
                    continue
                if n <= KNOWN_OPEN.get((kind, inv), 0):
                    seen_open.add((kind, inv))
                    print(f"KNOWN OPEN {kind} seed {r['seed']}: {inv} x{n} (<= {KNOWN_OPEN[(kind, inv)]})")
                else:
                    first = next(v for v in s["violations"] if v["invariant"] == inv)
                    fails.append(f"{kind} seed {r['seed']}: {inv} x{n}, first at {first['t']} s: {first['what']}")
            if kind == "controller_restart":
                resumed = s["counts"].get("tlm_status_since_last_boot", 0)
                if s["counts"].get("controller_boots", 0) < 2 or resumed < RESUME_MIN_STATUS:
                    fails.append(f"{kind} seed {r['seed']}: did not resume after the restart "
                                 f"({s['counts'].get('controller_boots', 0)} boots, {resumed} status frames "
                                 f"with a depth since the last one)")
            if kind in COUNTED and r["injected"].get(COUNTED[kind], 0) == 0:
                fails.append(f"{kind} seed {r['seed']}: no {COUNTED[kind]} counted: the fault was not injected")
    for ko in sorted(set(KNOWN_OPEN) - seen_open):
        if ko[0] in rows:
            print(f"NOTE {ko[0]}: known-open {ko[1]} no longer violated: fixed? remove it from KNOWN_OPEN")
    for f in fails:
        print("FAIL", f)
    print(f"{sum(len(r) for r in rows.values())} runs, {len(fails)} failures, "
          f"{len(seen_open)} known-open findings seen")
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Compares the controller's decisions in two sessions of the same scenario and
seed (e.g. the host build in-process and the Cortex-M7 image under QEMU,
docs/pil.md): every frame the controller sent about an electrode (REC_REQ,
ACT_CMD, TLM_CYCLE, TLM_STATUS, TLM_TRACK, TLM_WAVE, TLM_HYP, TLM_SPIKES) and
every SIM_ADVANCE, in order, byte for byte, apart from TLM_STATUS CycleCost and
ProcessCost (the platform's work counter); then report.json apart from "bus"
and each electrode's "cost".

    compare_sessions.py DIR_A DIR_B [--cycles N] [--json OUT]

The first differing electrode cycle is named with its interval (IntervalId,
start time) and the decoded fields that differ; then every differing cycle is
counted by frame and field, so that a difference confined to one field shows
as such. Only the cycles both sessions
completed are compared (--cycles N: the first N), each with the telemetry the
controller sent after its TLM_STATUS (TLM_TRACK, TLM_WAVE, TLM_HYP,
TLM_SPIKES: for the last compared cycle, what the logs hold after that
TLM_STATUS; the report is scored from it). Also printed, not compared:
the controller's heartbeat-loss EMCYs (0x8130) in each session, the usual
cause of a difference that is the link's and not the computation's.

Exit status: 0 same, 1 different, 2 usage or unreadable input.
"""
import argparse
import json
import os
import sys
from collections import defaultdict

from microdrive import canlog

DBC = canlog.DBC

PER_ELECTRODE = ("ACT_CMD", "REC_REQ", "TLM_STATUS", "TLM_CYCLE", "TLM_TRACK", "TLM_WAVE", "TLM_HYP", "TLM_SPIKES")
# What the controller sends about a cycle after its TLM_STATUS (md_tlm_interval).
TAIL = {"TLM_TRACK", "TLM_WAVE", "TLM_HYP", "TLM_SPIKES"}
EMCY_HB_LOST = 0x8130
READ = PER_ELECTRODE + ("SIM_ADVANCE", "EMCY_CTRL")


def cost_bytes(db):
    """The bytes of TLM_STATUS's CycleCost and ProcessCost (the DBC's layout), which the comparison zeroes."""
    sig = [db.get_message_by_name("TLM_STATUS").get_signal_by_name(n) for n in ("CycleCost", "ProcessCost")]
    return slice(min(s.start for s in sig) // 8, max(s.start + s.length for s in sig) // 8)


def read_frames(path, db):
    """Per electrode: [cycle] -> [(name, data)] in log order; SIM_ADVANCEs; EMCY 0x8130 count."""
    per_el = defaultdict(lambda: [[]])       # e -> list of cycles, each a frame list (last one open)
    cycle_info = defaultdict(list)           # e -> [(IntervalId, StartTime_us)] per closed cycle
    advances, lost = [], 0
    pending_cycle = {}
    cost = cost_bytes(db)
    for fr in canlog.frames(path, READ, db):
        name, raw = fr.name, fr.data
        if name == "SIM_ADVANCE":
            advances.append(raw)
        elif name == "EMCY_CTRL":
            m = canlog.decode(db, fr)
            lost += m is not None and int(m["ErrorCode"]) == EMCY_HB_LOST
        elif raw:
            e = raw[0]                       # Electrode: the first byte of every per-electrode frame
            if name == "TLM_STATUS":
                raw = raw[:cost.start] + bytes(cost.stop - cost.start) + raw[cost.stop:]
            per_el[e][-1].append((name, raw))
            m = canlog.decode(db, fr) if name == "TLM_CYCLE" else None
            if m is not None and int(m["Phase"]) == 1:
                pending_cycle[e] = (int(m["IntervalId"]), int(m["StartTime_us"]))
            if name == "TLM_STATUS":
                cycle_info[e].append(pending_cycle.get(e, (None, None)))
                per_el[e].append([])         # TLM_STATUS closes the cycle's decision
    return per_el, cycle_info, advances, lost


def decode_diff(db, name, a, b):
    try:
        m = db.get_message_by_name(name)
        da = m.decode(a, decode_choices=False)
        dbb = m.decode(b, decode_choices=False)
        return {k: (da[k], dbb.get(k)) for k in da if da[k] != dbb.get(k)}
    except Exception as exc:                 # an undecodable frame is still a difference
        return {"raw": (a.hex(), b.hex()), "decode": str(exc)}


def telemetry_tail(frames):
    """The leading frames of a list that are a cycle's telemetry after its TLM_STATUS."""
    n = 0
    while n < len(frames) and frames[n][0] in TAIL:
        n += 1
    return frames[:n]


def compared(a, b, e, cycles):
    """Per electrode: the closed cycles to compare (as pairs of frame lists), each
    followed by the telemetry that came after its TLM_STATUS (the head of the
    next list; of the open list after the last closed cycle), which the
    controller sends right after the TLM_STATUS."""
    la, lb = a.get(e, [[]]), b.get(e, [[]])
    n = min(len(la), len(lb)) - 1                       # closed cycles of both
    if cycles:
        n = min(n, cycles)
    pairs = [(la[k], lb[k]) for k in range(n)]
    tail = (telemetry_tail(la[n]), telemetry_tail(lb[n])) if n >= 0 else ([], [])
    return pairs, tail


def frame_diff(db, fa_list, fb_list):
    """(index, name, fields) of the first differing frame of two lists, or None."""
    for j, (fa, fb) in enumerate(zip(fa_list, fb_list)):
        if fa != fb:
            name = fa[0] if fa[0] == fb[0] else f"{fa[0]} vs {fb[0]}"
            return j, name, (decode_diff(db, fa[0], fa[1], fb[1]) if fa[0] == fb[0] else None)
    if len(fa_list) != len(fb_list):
        return min(len(fa_list), len(fb_list)), f"frame count {len(fa_list)} vs {len(fb_list)}", None
    return None


def first_difference(db, a, b, info_a, cycles):
    for e in sorted(set(a) | set(b)):
        pairs, tail = compared(a, b, e, cycles)
        for k, (ca, cb) in enumerate(pairs + [tail]):
            if ca == cb:
                continue
            last = k == len(pairs)                      # the tail: telemetry after the last compared TLM_STATUS
            c = k - 1 if last else k
            interval, start = info_a.get(e, [])[c] if 0 <= c < len(info_a.get(e, [])) else (None, None)
            out = {"electrode": e, "cycle_index": c, "interval_id": interval,
                   "start_time_s": None if start is None else start / 1e6}
            j, name, fields = frame_diff(db, ca, cb)
            out["frame"] = name + (" (telemetry after the cycle's TLM_STATUS)" if last else "")
            out["frame_index"] = j
            if fields is not None:
                out["fields"] = fields
            return out
    return None


def all_differences(db, a, b, cycles):
    """(frame.field -> cycles in which it differs), differing cycles in total."""
    fields, n_cycles = defaultdict(int), 0
    for e in sorted(set(a) | set(b)):
        pairs, tail = compared(a, b, e, cycles)
        for k, (ca, cb) in enumerate(pairs + [tail]):
            if ca == cb:
                continue
            n_cycles += 1
            seen = set()
            if len(ca) != len(cb):
                seen.add("frame count")
            for fa, fb in zip(ca, cb):
                if fa == fb:
                    continue
                if fa[0] != fb[0]:
                    seen.add("frame order")
                    continue
                for name in decode_diff(db, fa[0], fa[1], fb[1]):
                    seen.add(f"{fa[0]}.{name}")
            if k == len(pairs):
                seen = {f"{x} (last cycle's telemetry)" for x in seen}
            for name in seen:
                fields[name] += 1
    return dict(fields), n_cycles


def load_report(path):
    with open(path) as f:
        r = json.load(f)
    r.pop("bus", None)
    for e in r.get("electrodes", []):
        e.pop("cost", None)
    return r


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--cycles", type=int, default=0, help="compare the first N cycles of every electrode")
    ap.add_argument("--dbc", default=DBC)
    ap.add_argument("--json", help="write the verdict here")
    args = ap.parse_args(argv)
    db = canlog.load_dbc(args.dbc)
    try:
        fa, info_a, advances_a, lost_a = read_frames(os.path.join(args.a, "candump.log"), db)
        fb, _, advances_b, lost_b = read_frames(os.path.join(args.b, "candump.log"), db)
    except OSError as exc:
        print(f"compare_sessions: {exc}", file=sys.stderr)
        return 2
    counts = {e: (len(fa.get(e, [[]])) - 1, len(fb.get(e, [[]])) - 1) for e in sorted(set(fa) | set(fb))}
    diff = first_difference(db, fa, fb, info_a, args.cycles)
    n_advances = min(len(advances_a), len(advances_b))
    advance_diff = next((i for i in range(n_advances) if advances_a[i] != advances_b[i]), None)
    fields, n_diff = all_differences(db, fa, fb, args.cycles)
    verdict = {"cycles": {str(e): c for e, c in counts.items()}, "first_difference": diff,
               "differing_cycles": n_diff, "differing_fields": fields,
               "sim_advance_difference": advance_diff, "heartbeat_lost_emcy": [lost_a, lost_b]}
    rep_same = None
    ra, rb = os.path.join(args.a, "report.json"), os.path.join(args.b, "report.json")
    if not args.cycles and os.path.exists(ra) and os.path.exists(rb):
        a_rep, b_rep = load_report(ra), load_report(rb)
        rep_same = a_rep == b_rep
        if not rep_same:
            ja, jb = json.dumps(a_rep, indent=1).splitlines(), json.dumps(b_rep, indent=1).splitlines()
            verdict["report_lines"] = [f"{x.strip()}  <->  {y.strip()}" for x, y in zip(ja, jb) if x != y]
    verdict["report_same"] = rep_same
    print(f"compare_sessions: cycles per electrode (A, B): {counts}; controller heartbeat-loss EMCYs: "
          f"A {lost_a}, B {lost_b}")
    if diff is None and advance_diff is None:
        print("compare_sessions: every decision frame of the compared cycles is identical "
              "(TLM_STATUS cost fields aside)")
    else:
        if diff is not None:
            print(f"compare_sessions: FIRST DIFFERENCE: electrode {diff['electrode']}, cycle #{diff['cycle_index']}, "
                  f"interval {diff['interval_id']} starting at {diff['start_time_s']} s: {diff['frame']} "
                  f"{diff.get('fields', '')}")
        if advance_diff is not None:
            print(f"compare_sessions: SIM_ADVANCE #{advance_diff} differs")
        print(f"compare_sessions: {n_diff} cycles differ; by frame.field (cycles): {fields}")
    if rep_same is not None:
        print(f"compare_sessions: report.json {'identical' if rep_same else 'DIFFERENT'} apart from bus and cost")
        for line in verdict.get("report_lines", [])[:20]:
            print(f"  {line}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(verdict, f, indent=2, default=str)
            f.write("\n")
    same = diff is None and advance_diff is None and rep_same is not False
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())

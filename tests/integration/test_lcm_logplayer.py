#!/usr/bin/env python3
"""A session's LCM log replays with lcm-logplayer and records with lcm-logger.

Run inside a private network namespace (LCM's UDP multicast stays on its
loopback):

    PYTHONPATH=<build>/common/lcm/python netns-run.sh PYTHON test_lcm_logplayer.py --bridge BIN --dbc DBC --work DIR

The crafted session (test_lcm_fixture.py) goes through md-lcm-bridge into an
event log; lcm-logplayer plays it (100x speed) on udpm://239.255.76.67:7667?ttl=0
while a Python subscriber (LCM's bindings) and lcm-logger listen. Passes when
the subscriber received every event of the log, in order and byte-identical,
each one decoding with its lcm-gen type (package mdlcm), and lcm-logger's file holds the same
events.
"""
import os
import signal
import subprocess
import sys
import threading
import time

import lcm

import mdlcm as md
from microdrive.lcmlog import CHANNELS
from test_lcm_fixture import bridge_session, parse_args

URL = "udpm://239.255.76.67:7667?ttl=0"
SPEED = "100"


def events(path):
    return [(ev.channel, bytes(ev.data)) for ev in lcm.EventLog(path, "r")]


def play(log, recorded, want):
    """lcm-logplayer plays `log` while lcm-logger writes `recorded` and a
    subscriber collects (channel, bytes); returns (player, seconds, got, decode errors)."""
    # lcm-logger 1.3.1 documents -l but only accepts the long form
    logger = subprocess.Popen(["lcm-logger", "-q", "-f", "-c", "MD_.*", f"--lcm-url={URL}", recorded])
    lc = lcm.LCM(URL)
    got, decode_errors = [], []

    def on_msg(channel, data):
        got.append((channel, bytes(data)))
        try:
            getattr(md, CHANNELS[channel]).decode(data)
        except Exception as exc:  # noqa: BLE001 - any decode failure is a test failure
            decode_errors.append(f"{channel}: {exc}")

    lc.subscribe("MD_.*", on_msg)  # not LCM_SELF_TEST (udpm provider start-up)
    stop = threading.Event()

    def loop():
        while not stop.is_set():
            lc.handle_timeout(50)

    th = threading.Thread(target=loop)
    th.start()
    time.sleep(0.5)  # logger and subscriber joined
    t0 = time.monotonic()
    player = subprocess.run(["lcm-logplayer", "-s", SPEED, "-l", URL, log], capture_output=True, text=True)
    played_s = time.monotonic() - t0
    deadline = time.monotonic() + 5.0
    while len(got) < len(want) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.3)
    stop.set()
    th.join()
    logger.send_signal(signal.SIGINT)
    logger.wait(timeout=10)
    return player, played_s, got, decode_errors


def main():
    a = parse_args(__doc__.split("\n")[0])
    log = bridge_session(a)
    want = events(log)
    recorded = os.path.join(a.work, "recorded.lcmlog")
    player, played_s, got, decode_errors = play(log, recorded, want)

    fails = []
    if player.returncode != 0:
        fails.append(f"lcm-logplayer exit {player.returncode}: {player.stderr}")
    if got != want:
        fails.append(f"subscriber got {len(got)} events, the log has {len(want)} (or order/bytes differ)")
    if decode_errors:
        fails.append(f"{len(decode_errors)} messages failed to decode: {decode_errors[:3]}")
    rec = events(recorded) if os.path.exists(recorded) else []
    if rec != want:
        fails.append(f"lcm-logger recorded {len(rec)} events, the log has {len(want)}")
    channels = sorted({c for c, _ in got})
    print(f"test_lcm_logplayer: {len(want)} events played in {played_s:.1f} s at {SPEED}x on {len(channels)} "
          f"channels; subscriber {len(got)}, lcm-logger {len(rec)}")
    for f in fails:
        print("FAIL:", f)
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""tools/plots/plot_session.py draws every figure from a session's LCM log.

    PYTHONPATH=<build>/common/lcm/python test_lcm_plots.py --bridge BIN --dbc DBC --work DIR

The crafted session (test_lcm_fixture.py) goes through md-lcm-bridge; the
plot script must write tracks_pc.png, waveforms.png, status.png,
hypotheses.png and truth.png, each a real PNG with ink on it (not a blank
canvas) whose titles and legends fit inside it (plot_session.check_layout,
with a session label as long as a real one), once given the build's lcm-gen -p types with --types (the
folder of the package mdlcm that ctest puts on PYTHONPATH) and once generating them itself with lcm-gen
(neither --types, PYTHONPATH nor MD_LCM_TYPES); a log without telemetry must exit 1.
"""
import os
import struct
import subprocess
import sys

import matplotlib.image as mpimg
import numpy as np

import mdlcm
from test_lcm_fixture import bridge_session, parse_args

HERE = os.path.dirname(os.path.abspath(__file__))
PLOT = os.path.join(HERE, "..", "..", "tools", "plots", "plot_session.py")
BUILD_TYPES = os.path.dirname(os.path.dirname(os.path.abspath(mdlcm.__file__)))
PNGS = ["tracks_pc.png", "waveforms.png", "status.png", "hypotheses.png", "truth.png"]


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    return struct.unpack(">II", head[16:24])


def ink(path):
    """Fraction of pixels that are not white."""
    img = mpimg.imread(path)[..., :3]
    return float(np.mean(np.any(img < 0.95, axis=2)))


def check_pngs(out, fails):
    for name in PNGS:
        p = os.path.join(out, name)
        size = png_size(p) if os.path.exists(p) else None
        if size is None:
            fails.append(f"{name}: missing or not a PNG")
            continue
        frac = ink(p)
        print(f"  {name}: {size[0]}x{size[1]} px, {100 * frac:.1f} % ink")
        if size[0] < 400 or size[1] < 250 or frac < 0.03:
            fails.append(f"{name}: {size} px, {frac:.3f} ink: looks empty")


def main():
    a = parse_args(__doc__.split("\n")[0])
    log = bridge_session(a)
    fails = []
    no_types = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "MD_LCM_TYPES")}
    for label, extra in (("build types", ["--types", BUILD_TYPES]), ("lcm-gen on the fly", [])):
        out = os.path.join(a.work, "plots-" + label.split()[0])
        p = subprocess.run([sys.executable, PLOT, log, "--out", out, "--label", "single_neuron seed 1"] + extra,
                           capture_output=True, text=True, env=no_types)
        print(f"plot_session ({label}): exit {p.returncode}")
        if p.returncode != 0:
            fails.append(f"plot_session ({label}) exit {p.returncode}: {p.stderr[-800:]}")
            continue
        printed = [os.path.basename(x) for x in p.stdout.split()]
        if printed != PNGS:
            fails.append(f"plot_session ({label}) printed {printed}")
        check_pngs(out, fails)
    empty = os.path.join(a.work, "empty.lcmlog")
    subprocess.run([a.bridge, "--quiet", "--from-log", "/dev/null", "--write-log", empty], check=True)
    p = subprocess.run([sys.executable, PLOT, empty, "--out", os.path.join(a.work, "plots-empty")],
                       capture_output=True, text=True)
    if p.returncode != 1:
        fails.append(f"empty log: exit {p.returncode}, expected 1")
    for f in fails:
        print("FAIL:", f)
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())

"""A session's LCM log (docs/telemetry.md) read into Python objects.

    from microdrive import lcmlog
    s = lcmlog.read_log("out/session/session.lcmlog")   # {channel: [message, ...]}
    for r in lcmlog.hall_readings(s["MD_HALL"]):
        print(r.utime, r.electrode, r.depth_um)

The message classes are the LCM package `mdlcm` that `lcm-gen -p` makes of common/lcm/*.lcm (the build
writes it to <build>/common/lcm/python). import_types finds it: in the folder it is given (--types of
tools/plots/plot_session.py) or $MD_LCM_TYPES, else on the import path (PYTHONPATH, as ctest sets it for
the LCM tests), else it is generated into a temporary folder with the lcm-gen on PATH (Debian
liblcm-bin). LCM's Python bindings come from requirements.txt (scripts/setup-venv.sh installs both).
"""
import glob
import importlib
import os
import shutil
import subprocess
import sys
import tempfile
import types

# The package is installed editable from python/ of the checkout (scripts/setup-venv.sh).
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PACKAGE = "mdlcm"  # the LCM package of common/lcm/*.lcm

# LCM channel -> type name in package mdlcm (one type per channel).
CHANNELS = {
    "MD_STATUS": "status_t",
    "MD_CYCLE": "cycle_t",
    "MD_TRACKS": "tracks_t",
    "MD_HYPOTHESES": "hypotheses_t",
    "MD_SPIKES": "spikes_t",
    "MD_ACTUATOR": "actuator_t",
    "MD_HALL": "hall_t",
    "MD_HALL_CALIB": "hall_calib_t",
    "MD_TRUTH_SESSION": "truth_session_t",
    "MD_TRUTH_STATE": "truth_state_t",
    "MD_TRUTH_SPIKES": "truth_spikes_t",
    "MD_TRUTH_DEATH": "truth_death_t",
}

SFSM_STATES = ["spike search", "gradient search", "isolate neuron", "neuron isolated", "re-estimate gradient",
               "re-isolate neuron", "window limit", "halted"]


def generate_types():
    """Runs lcm-gen -p over common/lcm/*.lcm into a new temporary folder; returns the folder."""
    lcm_files = sorted(glob.glob(os.path.join(ROOT, "common", "lcm", "*.lcm")))
    gen = shutil.which("lcm-gen")
    if not lcm_files or gen is None:
        raise SystemExit("lcmlog: no LCM types: pass --types <build>/common/lcm/python, or install "
                         "lcm-gen (Debian liblcm-bin)")
    types_dir = tempfile.mkdtemp(prefix="md-lcmtypes-")
    subprocess.run([gen, "-p", "--ppath", types_dir] + lcm_files, check=True)
    return types_dir


def import_types(types_dir=None):
    """The `mdlcm` package of lcm-gen -p: from types_dir (else $MD_LCM_TYPES) if given, else the one on the
    import path, else generated now (generate_types)."""
    types_dir = types_dir or os.environ.get("MD_LCM_TYPES")
    if not types_dir:
        try:
            return importlib.import_module(PACKAGE)
        except ModuleNotFoundError:
            types_dir = generate_types()
    if types_dir not in sys.path:
        sys.path.insert(0, types_dir)
    return importlib.import_module(PACKAGE)


def read_log(path, types_dir=None):
    """Decodes every event of an LCM log: {channel: [message, ...]} in log order.
    Events on channels without a type of mdlcm are counted under None."""
    import lcm

    md = import_types(types_dir)
    classes = {ch: getattr(md, name) for ch, name in CHANNELS.items()}
    out = {ch: [] for ch in CHANNELS}
    out[None] = 0
    for ev in lcm.EventLog(path, "r"):
        cls = classes.get(ev.channel)
        if cls is None:
            out[None] += 1
            continue
        out[ev.channel].append(cls.decode(ev.data))
    return out


HALL_FIELDS = ("seq", "raw_code", "sample_time_ms", "depth_um")


def hall_readings(msgs):
    """MD_HALL messages (each a batch of one electrode's readings at one utime) as one object per reading, in log
    order, with the fields utime, electrode, calibrated, seq, raw_code, sample_time_ms, depth_um."""
    return [types.SimpleNamespace(utime=m.utime, electrode=m.electrode, calibrated=m.calibrated,
                                  **{f: getattr(m, f)[k] for f in HALL_FIELDS})
            for m in msgs for k in range(m.num_readings)]

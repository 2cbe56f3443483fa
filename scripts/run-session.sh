#!/usr/bin/env bash
# A host-in-loop session: the simulator (plant nodes 2-4) and the controller
# firmware (node 1) on one bus, progress per cycle and a report. A thin
# wrapper over microdrive-session (docs/session.md).
#
#   scripts/run-session.sh [--scenario FILE] [--seed N] [--seconds S | --cycles N]
#                          [--bus auto|udp|vcan0|IFACE|inproc] [--out DIR]
#                          [--build-dir DIR] [--idle-s S] [--param NAME=VALUE]...
#                          [--no-lcm] [--no-plots] [--no-recording] [--candump-samples]
#                          [--controller host|m7]
#
# --seconds S is simulated time (default: the scenario's duration_s). First
# installs what is missing (Debian packages as root or through sudo, the
# project venv: scripts/deps.sh), builds the release preset when --build-dir
# has no binaries. Leaves in DIR: recording.bin + recording.json (the samples
# the controller recorded, per interval its depth and Hall reading; replay
# with mhtc-replay or microdrive.read_recording), candump.log (every frame
# but the samples, candump -L format), truth.jsonl (ground truth),
# report.json, session.lcmlog (LCM log: lcm-logplayer, docs/telemetry.md),
# tracks_pc.png waveforms.png status.png hypotheses.png truth.png, and
# sim.log/fw.log for a socket bus. --param sets a controller parameter before
# the start (e.g. tracker=1); --no-lcm/--no-plots/--no-recording leave the
# log/plots/recording out; --candump-samples logs the samples in candump.log too.
# --controller m7: the Cortex-M7 image under QEMU is the controller
# (docs/pil.md; builds the cortex-m7 preset if its image is missing; needs a
# socket bus: udp, vcan0 or auto).
# Exit 0 when the session reached its goal, or ended idle with every node's
# heartbeat seen, no node reported lost (EMCY 0x8130) and no frame rejected
# (EMCY 0x8200); else 1 (also when the LCM log or the plots failed).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)

scenario="$root/scenarios/single_neuron.yaml"
seed=""
goal=()
bus=auto
out=""
idle=""   # default 20 s (300 s with --controller m7: the emulated link is slow)
build="$root/build/release"
controller=host

usage() { sed -n '2,29p' "$0" | sed 's/^# \{0,1\}//'; }
extra=()
while [ $# -gt 0 ]; do
    case "$1" in
        --scenario) scenario=$2; shift 2 ;;
        --seed) seed=$2; shift 2 ;;
        --seconds) goal=(--duration-s "$2"); shift 2 ;;
        --cycles) goal=(--cycles "$2"); shift 2 ;;
        --bus) bus=$2; shift 2 ;;
        --out) out=$2; shift 2 ;;
        --build-dir) build=$2; shift 2 ;;
        --idle-s) idle=$2; shift 2 ;;
        --param) extra+=(--param "$2"); shift 2 ;;
        --no-lcm|--no-plots|--no-recording|--candump-samples) extra+=("$1"); shift ;;
        --controller) extra+=(--controller "$2"); controller=$2; shift 2 ;;
        -h|--help) usage; exit 0 ;;
        *) echo "run-session: unknown option '$1' (see --help)" >&2; exit 2 ;;
    esac
done
[ -f "$scenario" ] || { echo "run-session: no scenario file '$scenario'" >&2; exit 2; }

# What the build and the session need: Debian packages (installed when
# missing, scripts/deps.sh), then the project venv (scoring and plots).
. "$root/scripts/deps.sh"
md_deps_install run-session build || exit 1
md_venv_ready run-session || exit 1

bin="$build/bin"
if [ ! -x "$bin/microdrive-session" ] || [ ! -x "$bin/microdrive-fw" ] || [ ! -x "$bin/microdrive-sim" ]; then
    echo "run-session: building the release preset into $root/build/release" >&2
    (cd "$root" && cmake --preset release >/dev/null && cmake --build --preset release -j "$(nproc)")
    bin="$root/build/release/bin"
fi
if [ "$controller" = m7 ]; then
    [ "$bus" != inproc ] || { echo "run-session: --controller m7 needs a socket bus (udp, vcan0, auto)" >&2; exit 2; }
    md_deps_install run-session target || exit 1
    if [ ! -f "$root/build/cortex-m7/bin/microdrive-fw-m7.elf" ]; then
        echo "run-session: building the cortex-m7 preset into $root/build/cortex-m7" >&2
        (cd "$root" && cmake --preset cortex-m7 >/dev/null && cmake --build --preset cortex-m7)
    fi
    extra+=(--m7-image "$root/build/cortex-m7/bin/microdrive-fw-m7.elf")
fi

out=${out:-"$root/out/session-$(date +%Y%m%d-%H%M%S)"}
[ -n "$idle" ] || { [ "$controller" = m7 ] && idle=300 || idle=20; }
args=(--scenario "$scenario" --bus "$bus" --out "$out" --idle-s "$idle" "${goal[@]}" "${extra[@]}")
[ -n "$seed" ] && args+=(--seed "$seed")
set +e
"$bin/microdrive-session" "${args[@]}"
rc=$?
set -e
[ "$rc" -eq 0 ] && { echo "run-session: goal reached; report: $out/report.json, LCM log and plots in $out"; exit 0; }
[ "$rc" -eq 5 ] && { echo "run-session: the session is fine but its LCM log or plots failed (see above)" >&2; exit 1; }
[ "$rc" -eq 4 ] || exit 1

# Ended idle before its goal: healthy only if every node was heard and the
# controller lost no node and rejected no frame.
python3 - "$out/candump.log" <<'PY'
import sys
heard, lost, rejected = set(), 0, 0
for line in open(sys.argv[1]):
    parts = line.split()
    if len(parts) < 3 or "#" not in parts[2]:
        continue
    cid, _, data = parts[2].partition("#")
    if cid in ("701", "702", "703", "704"):
        heard.add(cid)
    elif cid == "081" and len(data) >= 4:
        code = int(data[2:4] + data[0:2], 16)
        lost += code == 0x8130
        rejected += code == 0x8200
ok = len(heard) == 4 and lost == 0 and rejected == 0
print(f"run-session: ended idle before its goal; heartbeats of {sorted(heard)}, lost nodes {lost}, "
      f"rejected-frame EMCYs {rejected}: {'healthy' if ok else 'NOT healthy'}")
sys.exit(0 if ok else 1)
PY

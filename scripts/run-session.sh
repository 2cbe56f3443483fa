#!/usr/bin/env bash
# A host-in-loop session: the simulator (plant nodes 2-4) and the controller
# firmware (node 1) on one CAN bus, with progress every second and a summary.
#
#   scripts/run-session.sh [--scenario FILE] [--seed N] [--seconds S]
#                          [--bus auto|udp|vcan0|IFACE] [--out DIR] [--build-dir DIR]
#
# Builds the release preset first when --build-dir has no binaries. Leaves in
# DIR: candump.log (every frame, candump -L format), sim.log, fw.log and
# summary.json. Exit 0 when every node's heartbeat was seen, no node was
# reported lost, and the controller rejected no frame of the session.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)

scenario="$root/scenarios/single_neuron.yaml"
seed=1
seconds=5
bus=auto
out=""
build="$root/build/release"

usage() { sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
    case "$1" in
        --scenario) scenario=$2; shift 2 ;;
        --seed) seed=$2; shift 2 ;;
        --seconds) seconds=$2; shift 2 ;;
        --bus) bus=$2; shift 2 ;;
        --out) out=$2; shift 2 ;;
        --build-dir) build=$2; shift 2 ;;
        -h|--help) usage; exit 0 ;;
        *) echo "run-session: unknown option '$1' (see --help)" >&2; exit 2 ;;
    esac
done
[ -f "$scenario" ] || { echo "run-session: no scenario file '$scenario'" >&2; exit 2; }
case "$seconds" in ''|*[!0-9]*) echo "run-session: --seconds needs a whole number" >&2; exit 2 ;; esac

bin="$build/bin"
if [ ! -x "$bin/microdrive-fw" ] || [ ! -x "$bin/microdrive-sim" ] || [ ! -x "$bin/mdcan" ]; then
    echo "run-session: building the release preset into $build" >&2
    (cd "$root" && cmake --preset release >/dev/null && cmake --build --preset release)
    bin="$root/build/release/bin"
fi

out=${out:-"$root/out/session-$(date +%Y%m%d-%H%M%S)"}
mkdir -p "$out"
log="$out/candump.log"

pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
}
trap cleanup EXIT

# The recorder joins first so it sees every node's boot-up heartbeat.
"$bin/mdcan" dump --bus "$bus" >"$log" 2>"$out/dump.err" &
pids+=($!)
sleep 0.3
"$bin/microdrive-sim" --scenario "$scenario" --seed "$seed" --bus "$bus" --duration-s 0 2>"$out/sim.log" &
pids+=($!)
"$bin/microdrive-fw" --bus "$bus" --auto-start 2>"$out/fw.log" &
pids+=($!)

# candump -L lines look like "(1700000000.000000) udp 701#0501...".
count_id() { grep -c " $1#" "$log" 2>/dev/null || true; }
for ((t = 1; t <= seconds; t++)); do
    sleep 1
    printf 'session t=%2ds frames=%-6s heartbeats ctrl=%s act=%s hall=%s fe=%s emcy=%s\n' "$t" \
        "$(wc -l <"$log")" "$(count_id 701)" "$(count_id 702)" "$(count_id 703)" "$(count_id 704)" \
        "$(grep -cE ' 08[1-5]#' "$log" || true)"
done

# Read the controller's frame counters over the bus (PARAM_REQ get, see docs/protocol.md).
for index in 3010 3011 3012 3015 3030; do
    "$bin/mdcan" send --bus "$bus" "601#0100${index:2:2}${index:0:2}00000000"
    sleep 0.1
done
sleep 0.5
cleanup
trap - EXIT

bus_line=$(grep -m1 -iE 'bus' "$out/fw.log" || true)
python3 - "$log" "$out/summary.json" "$scenario" "$seed" "$bus" "$bus_line" <<'PY'
import json, struct, sys
log, dest, scenario, seed, bus, bus_line = sys.argv[1:7]
names = {0x3010: "rx_frames", 0x3011: "rx_malformed", 0x3012: "rx_unknown_id",
         0x3015: "rx_bad_sequence", 0x3030: "heartbeat_lost"}
heartbeats = {n: 0 for n in ("ctrl", "act", "hall", "fe")}
hb_ids = {"701": "ctrl", "702": "act", "703": "hall", "704": "fe"}
counters, emcys, frames = {}, [], 0
for line in open(log):
    parts = line.split()
    if len(parts) < 3 or "#" not in parts[2]:
        continue
    frames += 1
    can_id, data = parts[2].split("#", 1)
    data = data.lstrip("#")[1:] if parts[2].count("#") == 2 else data
    payload = bytes.fromhex(data)
    if can_id in hb_ids:
        heartbeats[hb_ids[can_id]] += 1
    elif can_id.startswith("08") and len(can_id) == 3 and len(payload) == 8:
        code, = struct.unpack_from("<H", payload, 0)
        emcys.append({"node": int(can_id, 16) - 0x80, "code": f"0x{code:04X}",
                      "info": struct.unpack_from("<I", payload, 4)[0]})
    elif can_id == "581" and len(payload) == 8 and payload[1] == 0:
        index, = struct.unpack_from("<H", payload, 2)
        if index in names:
            counters[names[index]] = int(struct.unpack_from("<f", payload, 4)[0])
lost = [e for e in emcys if e["code"] == "0x8130"]
ok = all(v > 0 for v in heartbeats.values()) and not lost and counters.get("rx_malformed", 1) == 0 \
    and counters.get("rx_unknown_id", 1) == 0 and counters.get("rx_bad_sequence", 1) == 0
summary = {"scenario": scenario, "seed": int(seed), "bus": bus, "bus_choice": bus_line, "frames": frames,
           "heartbeats": heartbeats, "emcy": emcys, "controller_counters": counters, "ok": ok}
json.dump(summary, open(dest, "w"), indent=2)
print(json.dumps(summary, indent=2))
sys.exit(0 if ok else 1)
PY

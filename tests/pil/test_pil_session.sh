#!/bin/sh
# Processor in the loop, short: the same scenario, seed and cycles run by the
# host build's controller (in-process) and by the Cortex-M7 image under QEMU
# (microdrive-session --controller m7, UDP bus in a private network
# namespace); every decision frame and report.json must be identical
# (tools/session/compare_sessions.py names the first differing interval), the
# image must report its per-cycle work, and its work counter must measure the
# start-up calibration loop exactly. docs/pil.md.
#
#   test_pil_session.sh BIN_DIR M7_IMAGE SCENARIO PYTHON [CYCLES]
set -eu
if [ "$#" -lt 4 ]; then
    echo "usage: $0 BIN_DIR M7_IMAGE SCENARIO PYTHON [CYCLES]" >&2
    exit 2
fi
bin=$1
image=$2
scenario=$3
py=$4
cycles=${5:-3}
root=$(cd "$(dirname "$0")/../.." && pwd)
if [ ! -f "$image" ]; then
    echo "test_pil_session: no Cortex-M7 image $image: build the cortex-m7 preset first" >&2
    exit 1
fi
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

"$bin/microdrive-session" --scenario "$scenario" --seed 1 --cycles "$cycles" --bus inproc \
    --out "$out/host" --no-lcm --quiet
"$root/scripts/netns-run.sh" "$bin/microdrive-session" --scenario "$scenario" --seed 1 --cycles "$cycles" \
    --bus udp --controller m7 --m7-image "$image" --out "$out/m7" --no-lcm --quiet --idle-s 60 || {
    echo "test_pil_session: the M7 session failed; its logs:" >&2
    tail -n 20 "$out/m7/fw.log" "$out/m7/bridge.log" "$out/m7/sim.log" >&2 || true
    exit 1
}
"$py" "$root/tools/session/compare_sessions.py" "$out/host" "$out/m7"

# The image's work counter: the calibration loop of 2 000 000 instructions
# measured within one SysTick tick (20 instructions at -icount shift=1).
grep -Eq "calibration loop of 2000000 instructions measured as (1999[89][0-9]{2}|2000[01][0-9]{2})$" "$out/m7/fw.log" || {
    echo "test_pil_session: work counter calibration off:" >&2
    grep calibration "$out/m7/fw.log" >&2 || true
    exit 1
}
# Every counted cycle of the image reports its work; the host reports none.
"$py" - "$out/m7/report.json" "$out/host/report.json" "$cycles" <<'PY'
import json, sys
m7, host, cycles = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), int(sys.argv[3])
for e in m7["electrodes"]:
    c = e.get("cost")
    assert c is not None, f"electrode {e['electrode']}: no cost in the M7 report"
    assert c["unit"] == "instructions" and c["cycles_measured"] >= 1, c
    assert 0 < c["process_median"] <= c["median"] <= c["max"], c
    print(f"test_pil_session: e{e['electrode']} cost over {c['cycles_measured']} cycles: median {c['median']:.0f}, "
          f"max {c['max']} instructions (budget {c['budget']})")
assert all("cost" not in e for e in host["electrodes"]), "the host build has no work counter"
PY

# Like for like: md-bench-m7 replays the session's recording under QEMU
# (tools/bench/replay_cost.py; exit 1 if any interval's spikes, tracks or SNR
# differ from the session's TLM_STATUS) and each cycle's CycleCost must be
# within 10 % of the replay's instructions for the same interval.
bench="$(dirname "$image")/md-bench-m7.elf"
if [ ! -f "$bench" ]; then
    echo "test_pil_session: no $bench: build the cortex-m7 preset (target md-bench-m7)" >&2
    exit 1
fi
"$py" "$root/tools/bench/replay_cost.py" "$out/m7" --image "$bench" --out "$out/replay" --json "$out/replay/cost.json"
"$py" - "$out/replay/cost.json" <<'PY'
import json, sys
rep = json.load(open(sys.argv[1]))
rows = rep["intervals"]
assert len(rows) >= 1, "no interval replayed"
for x in rows:
    r = x["session_cycle"] / x["replay_cycle"]
    assert abs(r - 1.0) <= 0.10, f"cycle {x['cycle']}: CycleCost {x['session_cycle']} vs replay {x['replay_cycle']}"
print(f"test_pil_session: {len(rows)} intervals: CycleCost within 10 % of md-bench-m7's replay")
PY
echo "test_pil_session: $cycles cycles: host and Cortex-M7 decisions and report identical"

#!/usr/bin/env python3
"""The approach guard saves the neuron a tracker misses: a CI subset of the
safety sweep (tools/eval/run_suite.py --safety; its results: docs/sfsm.md "Approach guard").

    test_guard_safety.py BUILD_DIR SCENARIO_DIR OUT_DIR

Three stress scenarios, seeds 101 and 102, full length, in-process, MHTC: a
loud sparse burster 3 um off the track (sparse_burster_on_path), two neurons
a few tens of um apart (close_pair) and a neuron that drifts towards the tip
(drift_towards_tip). Without the guard (guard_enable=0) each kills a neuron in
both seeds (the scenario still stresses what it should); with the guard
(guard_enable=1) no neuron is damaged, the closest approach stays above the
damage radius and the electrode still isolates.
"""
import concurrent.futures
import json
import os
import subprocess
import sys

SEEDS = (101, 102)
SCENARIOS = ("sparse_burster_on_path", "close_pair", "drift_towards_tip")
DAMAGE_UM = 12.0  # docs/simulator.md, neuron_model.damage_um default


def run(build_dir, scenario, seed, guard, out_root):
    name = os.path.splitext(os.path.basename(scenario))[0]
    out = os.path.join(out_root, f"{name}-guard{guard}-seed{seed}")
    cmd = [os.path.join(build_dir, "bin", "microdrive-session"), "--scenario", scenario, "--seed", str(seed),
           "--bus", "inproc", "--out", out, "--quiet", "--no-lcm", "--no-plots", "--no-recording",
           "--param", f"guard_enable={guard}"]
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    path = os.path.join(out, "report.json")
    if p.returncode not in (0, 4) or not os.path.exists(path):
        return name, seed, guard, None, p.stdout[-2000:]
    with open(path) as f:
        return name, seed, guard, json.load(f)["electrodes"][0], ""


def main():
    build_dir, scen_dir, out_root = sys.argv[1:4]
    os.makedirs(out_root, exist_ok=True)
    jobs = [(os.path.join(scen_dir, "stress", f"{n}.yaml"), s, g) for n in SCENARIOS for s in SEEDS for g in (0, 1)]
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as ex:
        results = list(ex.map(lambda j: run(build_dir, j[0], j[1], j[2], out_root), jobs))
    failures = []
    for name, seed, guard, e, tail in results:
        if e is None:
            failures.append(f"{name} seed {seed} guard {guard}: no report\n{tail}")
            continue
        line = (f"{name} seed {seed} guard_enable={guard}: damaged {e['neurons_damaged']}, closest approach "
                f"{e['closest_approach_um']} um, isolated {e['isolated']}, guard limited "
                f"{e['guard_limited_cycles']} cycles, retractions {e['guard_retractions']}")
        print(line)
        if guard == 0 and e["neurons_damaged"] == 0:
            failures.append(f"{line}: the scenario no longer kills without the guard (it must stress it)")
        if guard == 1 and (e["neurons_damaged"] != 0 or not e["closest_approach_um"] > DAMAGE_UM
                           or not e["isolated"]):
            failures.append(f"{line}: expected no damage, closest > {DAMAGE_UM} um and an isolation")
    for f in failures:
        print("FAIL:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

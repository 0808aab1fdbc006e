#!/usr/bin/env python3
"""evoloop's rigid-body algorithms beside Pinocchio's (C++), per call, in interleaved rounds.

Builds scripts/pinocchio_bench.cpp against the `pin` wheel (Pinocchio's headers and libraries)
and `cmeel-eigen` (Eigen's headers) with g++ -O3 -DNDEBUG, then alternates
`evoloop bench dynamics --robot FILE --json` and the C++ program, round by round, on each robot,
and prints the median ns per call of each side and the ratio evoloop / Pinocchio. Interleaving
is what makes the ratio mean something on a shared machine: both sides see the same noise.

    pip install -r scripts/pinocchio_bench.txt   # pin==4.1.0 cmeel-eigen cmeel-urdfdom-headers
    cargo build --release
    python3 scripts/pinocchio_bench.py [--rounds 7] [--calls 200000] [--json] [ROBOT.urdf ...]

Default robots: config/robots/arm7.urdf (Panda inertials, 7 joints) and
tests/robots/ur5_style.urdf (6 joints). Pinocchio's `crba` fills the upper triangle only,
evoloop's the whole matrix; `aba` is compared with both of evoloop's forward dynamics.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import sysconfig

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROBOTS = ["config/robots/arm7.urdf", "tests/robots/ur5_style.urdf"]


def cmeel_prefix():
    prefix = os.path.join(sysconfig.get_paths()["purelib"], "cmeel.prefix")
    for needed in ["include/pinocchio", "include/eigen3", "include/urdfdom_headers/urdf_model", "lib/libpinocchio_parsers.so"]:
        if not os.path.exists(os.path.join(prefix, needed)):
            sys.exit(f"error: {prefix}/{needed} is missing: pip install -r scripts/pinocchio_bench.txt")
    return prefix


def build(out):
    prefix = cmeel_prefix()
    src = os.path.join(ROOT, "scripts", "pinocchio_bench.cpp")
    if os.path.exists(out) and os.path.getmtime(out) > os.path.getmtime(src):
        return out
    cmd = [
        "g++", "-std=c++17", "-O3", "-DNDEBUG", src, "-o", out,
        # The definitions Pinocchio's CMake package exports to its users.
        "-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
        "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
        "-DPINOCCHIO_WITH_URDFDOM", "-DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3",
        "-DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0", "-DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0",
        f"-I{prefix}/include", f"-I{prefix}/include/eigen3", f"-I{prefix}/include/urdfdom_headers",
        f"-L{prefix}/lib", f"-Wl,-rpath,{prefix}/lib",
        "-lpinocchio_parsers", "-lpinocchio_default", "-lurdfdom_model",
        "-lconsole_bridge", "-ltinyxml2", "-lboost_filesystem", "-lboost_serialization",
    ]
    print("building the Pinocchio side (about a minute)...", file=sys.stderr)
    subprocess.run(cmd, check=True)
    return out


def run_json(cmd):
    return json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("robots", nargs="*", default=ROBOTS)
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--calls", type=int, default=200_000)
    ap.add_argument("--evoloop", default=os.path.join(ROOT, "target", "release", "evoloop"))
    ap.add_argument("--binary", default=os.path.join(ROOT, "target", "pinocchio_bench"))
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    pin_bin = build(a.binary)
    results = {}
    for robot in a.robots:
        path = os.path.join(ROOT, robot) if not os.path.isabs(robot) else robot
        ours, theirs = [], []
        for r in range(a.rounds):
            print(f"{robot}: round {r + 1} of {a.rounds}", file=sys.stderr)
            ours.append(run_json([a.evoloop, "bench", "dynamics", "--robot", path,
                                  "--calls", str(a.calls), "--json"])["ns_per_call"])
            theirs.append(run_json([pin_bin, path, str(a.calls)])["ns_per_call"])
        med = lambda rows, k: statistics.median(row[k] for row in rows)
        pairs = [("rnea", "rnea"), ("crba", "crba"), ("aba", "aba"), ("forward_crba", "aba")]
        results[robot] = {
            "rounds": a.rounds,
            "calls": a.calls,
            "evoloop_ns": {k: med(ours, k) for k in ours[0]},
            "pinocchio_ns": {k: med(theirs, k) for k in theirs[0]},
            "ratio": {f"{ok}/{pk}": med(ours, ok) / med(theirs, pk) for ok, pk in pairs},
            "ratio_per_round": {
                f"{ok}/{pk}": [o[ok] / p[pk] for o, p in zip(ours, theirs)] for ok, pk in pairs
            },
        }
    if a.json:
        print(json.dumps(results, indent=2))
        return
    for robot, r in results.items():
        print(f"{robot}: median of {r['rounds']} interleaved rounds, {r['calls']} calls each (ns)")
        print(f"  {'evoloop':<22} {'ns':>8}   {'Pinocchio':<10} {'ns':>8}   ratio (rounds min-max)")
        for key, ratio in r["ratio"].items():
            ok, pk = key.split("/")
            rounds = r["ratio_per_round"][key]
            print(f"  {ok:<22} {r['evoloop_ns'][ok]:>8.1f}   {pk:<10} {r['pinocchio_ns'][pk]:>8.1f}"
                  f"   {ratio:.2f} ({min(rounds):.2f}-{max(rounds):.2f})")


if __name__ == "__main__":
    main()

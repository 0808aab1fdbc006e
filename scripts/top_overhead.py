#!/usr/bin/env python3
"""Does `evoloop top` slow the loop it watches? One realtime run, with `top` (the real screen,
on a pseudo-terminal made by util-linux `script`) attached in every other window of it and
detached in the others; the controller's own timing.csv then gives, per window, the cycles that
missed deadlines (flag 4), overran (flag 2) and the lateness percentiles. Same run, so the
machine's state is shared; compare the "on" windows with the "off" ones.

    python3 scripts/top_overhead.py [--evoloop target/release/evoloop]
        [--scenario config/two_mass/two_mass_indirect.toml] [--windows 6] [--window 10] [--out runs/top_overhead]

Prints a table and writes top_overhead.json in --out. Needs `script` (util-linux).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time


def percentile(xs, p):
    xs = sorted(xs)
    if not xs:
        return float("nan")
    k = min(len(xs) - 1, max(0, int(round(p / 100 * (len(xs) - 1)))))
    return xs[k]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--evoloop", default="target/release/evoloop")
    ap.add_argument("--scenario", default="config/two_mass/two_mass_indirect.toml")
    ap.add_argument("--windows", type=int, default=6)
    ap.add_argument("--window", type=float, default=10.0)
    ap.add_argument("--out", default="runs/top_overhead")
    a = ap.parse_args()
    run_id = f"topoh{os.getpid()}"
    duration = a.windows * a.window
    run = subprocess.Popen(
        [a.evoloop, "run", a.scenario, "--mode", "realtime", "--duration", str(duration),
         "--run-id", run_id, "--out", os.path.join(a.out, "run"), "--quiet"],
        stdout=subprocess.DEVNULL)
    t0 = time.monotonic()
    # The run's clock starts once its processes are up; a second is ample here.
    time.sleep(1.0)
    for w in range(a.windows):
        if w % 2 == 1:
            left = (1.0 + (w + 1) * a.window) - (time.monotonic() - t0)
            subprocess.run(
                ["script", "-qc",
                 f"stty cols 110 rows 32; {a.evoloop} top --run {run_id} --duration {left:.2f}",
                 "/dev/null"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        else:
            time.sleep(max(0.0, (1.0 + (w + 1) * a.window) - (time.monotonic() - t0)))
    run.wait()
    if run.returncode != 0:
        sys.exit(f"the run failed ({run.returncode})")
    summary = json.load(open(os.path.join(a.out, "run", "summary.json")))
    period = summary["period_s"]
    rows = []
    with open(os.path.join(a.out, "run", "timing.csv")) as f:
        next(f)
        for line in f:
            cycle, lateness, compute, age, flags = line.strip().split(",")
            rows.append((int(float(cycle)), float(lateness), int(float(flags))))
    per = int(round(a.window / period))
    # Windows by cycle number (the run's own time), the first second of start-up left out of
    # the first window's attach timing but counted in its cycles.
    out = []
    for w in range(a.windows):
        sel = [r for r in rows if w * per <= r[0] < (w + 1) * per]
        lat = [r[1] for r in sel]
        out.append({
            "window": w, "top": "on" if w % 2 == 1 else "off", "cycles": len(sel),
            "missed_cycles": sum(1 for r in sel if r[2] & 4),
            "overruns": sum(1 for r in sel if r[2] & 2),
            "lateness_p50_us": percentile(lat, 50) / 1e3,
            "lateness_p99_us": percentile(lat, 99) / 1e3,
            "lateness_p99_9_us": percentile(lat, 99.9) / 1e3,
        })
    print(f"{'window':>6} {'top':>4} {'cycles':>7} {'missed':>7} {'overruns':>8} "
          f"{'p50 us':>8} {'p99 us':>8} {'p99.9 us':>9}")
    for r in out:
        print(f"{r['window']:>6} {r['top']:>4} {r['cycles']:>7} {r['missed_cycles']:>7} "
              f"{r['overruns']:>8} {r['lateness_p50_us']:>8.1f} {r['lateness_p99_us']:>8.1f} "
              f"{r['lateness_p99_9_us']:>9.1f}")
    for state in ("off", "on"):
        ws = [r for r in out if r["top"] == state]
        print(f"top {state}: missed {[r['missed_cycles'] for r in ws]}, "
              f"p99 median {statistics.median(r['lateness_p99_us'] for r in ws):.1f} us")
    json.dump({"run_id": run_id, "scenario": a.scenario, "window_s": a.window,
               "realtime_privileges": summary.get("realtime_privileges"), "windows": out},
              open(os.path.join(a.out, "top_overhead.json"), "w"), indent=2)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The RKGNN identification ablation over seeds (issue 41): on the paper's Section 5 study
(`evoloop rkgnn study`, arm3 unless --robot), each seed identifies both models four ways and
tracks the new trajectory with fuzzy computed torque (the paper's max rule):

  ea       the paper's EA alone from the paper's start (--start random --evaluations E)
  ls       least squares alone (the shipped recipe)
  ls+ea    least squares, then E EA evaluations
  ls+lm    least squares, then R Levenberg-Marquardt steps

It prints a Markdown table: per variant the median whole-run rms of fuzzy CT (max) and of each
model alone, the models' smallest M-hat eigenvalue along the new trajectory, and each variant
against least squares alone paired over the seeds (lower on k of n, exact two-sided Wilcoxon
signed-rank p). Usage:

  python3 scripts/rkgnn_ablation.py [--bin target/release/evoloop] [--seeds 10]
      [--evaluations 2000] [--refine 20] [--servo known|unknown] [--robot FILE] [--json OUT]
"""
import argparse
import itertools
import json
import math
import statistics
import subprocess
import sys
import tempfile


def overall(per_joint):
    return math.sqrt(sum(x * x for x in per_joint) / len(per_joint))


def wilcoxon_p(a, b):
    """Exact two-sided Wilcoxon signed-rank p of the paired differences a - b (zeros dropped,
    average ranks for ties), by enumerating every sign assignment (n <= 20)."""
    d = [x - y for x, y in zip(a, b) if x != y]
    n = len(d)
    if n == 0:
        return 1.0
    order = sorted(range(n), key=lambda i: abs(d[i]))
    ranks = [0.0] * n
    i = 0
    while i < n:
        j = i
        while j + 1 < n and abs(d[order[j + 1]]) == abs(d[order[i]]):
            j += 1
        for k in range(i, j + 1):
            ranks[order[k]] = (i + j) / 2 + 1
        i = j + 1
    w = sum(r for r, x in zip(ranks, d) if x > 0)
    mean = sum(ranks) / 2
    extreme = 0
    for signs in itertools.product((0, 1), repeat=n):
        s = sum(r for r, bit in zip(ranks, signs) if bit)
        if abs(s - mean) >= abs(w - mean) - 1e-12:
            extreme += 1
    return extreme / 2 ** n


def study(binary, robot, seed, servo, extra):
    with tempfile.TemporaryDirectory() as out:
        cmd = [binary, "rkgnn", "study", "--out", out, "--seed", str(seed), "--servo", servo,
               "--json", "-q"] + (["--robot", robot] if robot else []) + extra
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            return {"error": p.stderr.strip().splitlines()[-1] if p.stderr.strip() else "failed"}
        return json.loads(p.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/evoloop")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--evaluations", type=int, default=2000)
    ap.add_argument("--refine", type=int, default=20)
    ap.add_argument("--servo", default="known", choices=["known", "unknown"])
    ap.add_argument("--robot")
    ap.add_argument("--json")
    a = ap.parse_args()
    variants = {
        "ea": ["--start", "random", "--evaluations", str(a.evaluations)],
        "ls": [],
        "ls+ea": ["--evaluations", str(a.evaluations)],
        "ls+lm": ["--refine", str(a.refine)],
    }
    runs = {v: [] for v in variants}
    for seed in range(1, a.seeds + 1):
        for v, extra in variants.items():
            r = study(a.bin, a.robot, seed, a.servo, extra)
            runs[v].append(r)
            print(f"seed {seed} {v}: " + (r["error"] if "error" in r else
                  f"fuzzy max {overall(r['tracking_rms']['ct_fuzzy_max']):.4f} rad"), file=sys.stderr)
    def col(v, key):
        return [overall(r["tracking_rms"][key]) if "error" not in r else math.nan for r in runs[v]]
    print(f"RKGNN identification ablation: {a.seeds} seeds, servo {a.servo}, EA {a.evaluations} "
          f"evaluations, LM {a.refine} steps; whole-run rms on the new trajectory (rad), medians\n")
    print("| variant | models identified | fuzzy CT (max) | model 1 alone | model 2 alone | "
          "min eig M-hat on the new trajectory | fuzzy vs least squares: lower on | Wilcoxon p |")
    print("|---|---|---|---|---|---|---|---|")
    base = col("ls", "ct_fuzzy_max")
    table = {}
    for v in variants:
        ok = [r for r in runs[v] if "error" not in r]
        fz = col(v, "ct_fuzzy_max")
        med = lambda xs: statistics.median([x for x in xs if not math.isnan(x)]) if any(not math.isnan(x) for x in xs) else math.nan
        eig = [m["min_eig_on_reference"] for r in ok for m in r["models"]]
        pairs = [(x, y) for x, y in zip(fz, base) if not (math.isnan(x) or math.isnan(y))]
        lower = sum(1 for x, y in pairs if x < y)
        p = wilcoxon_p([x for x, _ in pairs], [y for _, y in pairs]) if v != "ls" else math.nan
        row = {
            "identified": f"{len(ok)} of {len(runs[v])}",
            "fuzzy_max": med(fz), "model_1": med(col(v, "ct_model_1")), "model_2": med(col(v, "ct_model_2")),
            "min_eig_on_reference": min(eig) if eig else math.nan,
            "lower_than_ls": f"{lower} of {len(pairs)}", "wilcoxon_p": p,
        }
        table[v] = row
        print(f"| {v} | {row['identified']} | {row['fuzzy_max']:.4f} | {row['model_1']:.4f} | "
              f"{row['model_2']:.4f} | {row['min_eig_on_reference']:.4f} | "
              f"{'-' if v == 'ls' else row['lower_than_ls']} | {'-' if v == 'ls' else f'{p:.3g}'} |")
    # The servo's runs do not depend on the identification: any variant's that ran.
    pd_runs = [overall(r["tracking_rms"]["pd"]) for rs in runs.values() for r in rs if "error" not in r]
    pd = statistics.median(pd_runs) if pd_runs else math.nan
    print(f"\nP-D servo alone: {pd:.4f} rad (the same runs for every variant).")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"settings": vars(a), "table": table,
                       "runs": {v: [r if "error" in r else {"tracking_rms": r["tracking_rms"], "models": r["models"]}
                                    for r in rs] for v, rs in runs.items()}}, f, indent=1)


if __name__ == "__main__":
    main()

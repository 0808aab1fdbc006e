#!/usr/bin/env python3
"""The established Python optimisers on evoloop's benchmark suite, at the study's budget.

Every library minimises exactly the study's functions: each candidate is evaluated by
`evoloop optim serve --function KEY` (a pipe, points in, values out), so no function is written
twice. Each run records the best value among its first `--evaluations` evaluations, whatever the
library does after that. Library defaults are kept except what fixes the budget:

  scipy_de        scipy.optimize.differential_evolution: best1bin, popsize 15 x D, dithered F,
                  CR 0.7 (defaults); polish=False and tol=0 so it neither spends evaluations
                  beyond the budget on L-BFGS-B nor stops before it.
  pyswarms_gbest  pyswarms GlobalBestPSO, 30 particles, c1 0.5, c2 0.3, w 0.9 (the options of
                  its documentation's first example: it has no defaults), no velocity clamp.
  pymoo_de        pymoo DE (DE/rand/1/bin, population 100, CR 0.5, dithered F: defaults).
  pymoo_ga        pymoo GA (population 100, SBX, polynomial mutation: defaults).
  pymoo_pso       pymoo PSO (adaptive, swarm 25: defaults).
  mealpy_jade     mealpy JADE (adaptive DE), population 30.
  mealpy_gwo      mealpy OriginalGWO, population 30.
  mealpy_woa      mealpy OriginalWOA, population 30.

Writes CSV rows `function,algorithm,seed,best_value,error,evaluations` (the study's runs.csv
format); `evoloop optim study --peers FILE` reads them and compares. Needs numpy, scipy,
pyswarms, pymoo and mealpy (`pip install -r scripts/python_peers.txt`).

    python3 scripts/python_peers.py --evoloop target/release/evoloop --out runs/python_peers.csv
"""

import argparse
import csv
import json
import os
import struct
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

ALGORITHMS = [
    "scipy_de",
    "pyswarms_gbest",
    "pymoo_de",
    "pymoo_ga",
    "pymoo_pso",
    "mealpy_jade",
    "mealpy_gwo",
    "mealpy_woa",
]


class Served:
    """One function of the suite, evaluated by an `evoloop optim serve` child."""

    def __init__(self, evoloop, key, dim, budget):
        self.proc = subprocess.Popen(
            [evoloop, "optim", "serve", "--function", key],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )
        self.dim, self.budget = dim, budget
        self.count, self.best = 0, float("inf")

    def batch(self, x):
        x = np.ascontiguousarray(np.atleast_2d(x), dtype="<f8")
        n = x.shape[0]
        assert x.shape[1] == self.dim, x.shape
        self.proc.stdin.write(struct.pack("<I", n) + x.tobytes())
        self.proc.stdin.flush()
        raw = self.proc.stdout.read(8 * n)
        values = np.frombuffer(raw, dtype="<f8").copy()
        left = max(0, self.budget - self.count)
        if left > 0:
            self.best = min(self.best, float(np.min(values[:left])))
        self.count += n
        return values

    def one(self, x):
        return float(self.batch(np.asarray(x, dtype=float))[0])

    def close(self):
        self.proc.stdin.close()
        self.proc.wait()


def run(algorithm, f, lower, upper, budget, seed):
    d = len(lower)
    if algorithm == "scipy_de":
        from scipy.optimize import differential_evolution

        pop = 15 * d
        differential_evolution(
            lambda xs: f.batch(xs.T),
            list(zip(lower, upper)),
            maxiter=max(1, budget // pop - 1),
            polish=False,
            tol=0,
            vectorized=True,
            updating="deferred",
            rng=np.random.default_rng(seed),
        )
    elif algorithm == "pyswarms_gbest":
        import pyswarms as ps

        np.random.seed(seed)
        opt = ps.single.GlobalBestPSO(
            n_particles=30,
            dimensions=d,
            options={"c1": 0.5, "c2": 0.3, "w": 0.9},
            bounds=(np.array(lower), np.array(upper)),
        )
        opt.optimize(f.batch, iters=budget // 30, verbose=False)
    elif algorithm.startswith("pymoo_"):
        from pymoo.core.problem import Problem
        from pymoo.optimize import minimize

        class P(Problem):
            def __init__(self):
                super().__init__(n_var=d, n_obj=1, xl=np.array(lower), xu=np.array(upper))

            def _evaluate(self, x, out, *args, **kwargs):
                out["F"] = f.batch(x)

        if algorithm == "pymoo_de":
            from pymoo.algorithms.soo.nonconvex.de import DE as A
        elif algorithm == "pymoo_ga":
            from pymoo.algorithms.soo.nonconvex.ga import GA as A
        else:
            from pymoo.algorithms.soo.nonconvex.pso import PSO as A
        minimize(P(), A(), ("n_eval", budget), seed=seed, verbose=False)
    elif algorithm.startswith("mealpy_"):
        from mealpy import DE, GWO, WOA, FloatVar

        make = {
            "mealpy_jade": DE.JADE,
            "mealpy_gwo": GWO.OriginalGWO,
            "mealpy_woa": WOA.OriginalWOA,
        }[algorithm]
        model = make(epoch=budget // 30 - 1, pop_size=30)
        problem = {
            "obj_func": f.one,
            "bounds": FloatVar(lb=list(lower), ub=list(upper)),
            "minmax": "min",
            "log_to": None,
        }
        model.solve(problem, seed=seed)
    else:
        raise SystemExit(f"unknown algorithm {algorithm}")


def job(args):
    evoloop, fn, algorithm, seed, budget = args
    f = Served(evoloop, fn["key"], fn["dim"], budget)
    try:
        run(algorithm, f, fn["lower"], fn["upper"], budget, seed)
    finally:
        f.close()
    return (fn["key"], algorithm, seed, f.best, f.best - fn["f_min"], min(f.count, budget))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--evoloop", default="target/release/evoloop")
    ap.add_argument("--out", required=True)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--evaluations", type=int, default=30000)
    ap.add_argument("--functions", help="comma-separated keys (default: all, with the shifted copies)")
    ap.add_argument("--algorithms", default=",".join(ALGORITHMS))
    ap.add_argument("--jobs", type=int, default=os.cpu_count())
    a = ap.parse_args()
    a.evoloop, a.out = os.path.abspath(a.evoloop), os.path.abspath(a.out)
    # pyswarms writes report.log into the working directory: keep it out of the user's.
    os.chdir(tempfile.mkdtemp(prefix="python_peers_"))
    listing = subprocess.run(
        [a.evoloop, "optim", "functions", "--json"], check=True, capture_output=True, text=True
    ).stdout
    functions = json.loads(listing)
    if a.functions:
        keep = a.functions.split(",")
        unknown = set(keep) - {f["key"] for f in functions}
        if unknown:
            raise SystemExit(f"unknown functions: {sorted(unknown)}")
        functions = [f for f in functions if f["key"] in keep]
    algorithms = a.algorithms.split(",")
    for name in algorithms:
        if name not in ALGORITHMS:
            raise SystemExit(f"unknown algorithm {name} (known: {', '.join(ALGORITHMS)})")
    jobs = [
        (a.evoloop, fn, alg, seed, a.evaluations)
        for fn in functions
        for alg in algorithms
        for seed in range(a.runs)
    ]
    started = time.time()
    rows = []
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        for i, row in enumerate(pool.map(job, jobs, chunksize=1), 1):
            rows.append(row)
            if sys.stderr.isatty() or i % 50 == 0 or i == len(jobs):
                print(f"\r{i}/{len(jobs)} runs, {time.time() - started:.0f} s", end="", file=sys.stderr)
    print(file=sys.stderr)
    with open(a.out, "w", newline="") as out:
        w = csv.writer(out)
        w.writerow(["function", "algorithm", "seed", "best_value", "error", "evaluations"])
        for key, alg, seed, best, err, n in rows:
            w.writerow([key, alg, seed, repr(best), repr(err), n])
    print(f"{len(rows)} runs in {time.time() - started:.0f} s: wrote {a.out}", file=sys.stderr)


if __name__ == "__main__":
    main()

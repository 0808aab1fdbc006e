#!/usr/bin/env python3
"""evoloop's robust-control computations beside slycot (SLICOT's AB13DD, python-control's
H-infinity norm) and scipy, measured in the same sitting.

    python3 -m pip install --only-binary :all: -r scripts/robust_peers.txt
    python3 scripts/robust_peers.py --evoloop target/release/evoloop --out runs/robust_peers.json

Three parts, each printed as a Markdown table and all of them written as JSON to --out:

1. Agreement. The augmented two-mass closed loop A_cl = Â - B̂ K, Ê = diag(0,0,1,1,0),
   Ĥ = diag(1,1,0,0,0) is rebuilt here in NumPy exactly as
   crates/evoloop-schemes/src/robust/problem.rs builds it (state [x_meas, x_act, v_meas, v_act, xi],
   xi' = r - x_meas, force on the actuated body, u = -K x̂, m1 = m2 = 1, k = 0.5). For each gain
   set, r_c = 1 / ||Ĥ (sI - A_cl)^-1 Ê||_inf from slycot.ab13dd (0 when A_cl is not Hurwitz: AB13DD
   computes the L-infinity norm, finite for an unstable loop too, so the Hurwitz test is made
   here, as evoloop makes it) is set beside `evoloop robust radius --json`, with a third,
   independent value from a dense frequency sweep refined by bounded Brent searches (NumPy only)
   to say which is right where the two differ; then --scan random Hurwitz gain sets of the
   +-50 box, the sweep run on the three that differ most. Exit status 1 when slycot and evoloop
   differ by more than --tolerance (relative) on any set.
2. Per-call costs, interleaved (Python block, evoloop block, x --rounds). Python: slycot's norm
   call alone on prebuilt matrices (median of --calls calls) at Table 9's gains and over the
   candidates named below, python-control's `control.norm` on a fresh StateSpace, and the whole
   cost a Python optimiser pays per candidate (build A_cl, eigenvalues, wedge distance, and AB13DD
   for a feasible one). evoloop cannot time one r_c call without a rebuild (its per-call
   numbers come from `cargo bench --bench hot_paths`), so its side is what its CLI reports:
   `robust tune --seed 1 --target 0.3489 --threads 1` gives seconds / evaluations, a DE-run
   average that includes DE's own work, the cheap infeasible candidates and the feasible trials
   `value_below` rejects on a one-frequency lower bound before the full norm; `robust tune --np N
   --target=-1e300 --threads 1` stops after the random initial population, all infeasible at
   the paper's wedge (checked: best F(X) > 0): the infeasible path (eigenvalues + wedge) alone.
   To split the DE run, it is replayed here exactly (evoloop's xoshiro256++ and rand 0.8 draws,
   its DE/rand/1/bin and stopping, its early-rejection test; checked: same iterations,
   evaluations and final gains as evoloop's), which counts its infeasible, early-rejected and
   full-norm evaluations. With DE's own cost per evaluation c_de from `evoloop optim bench` and
   c_inf <= c_early <= c_full, evoloop's cost of one full feasible candidate lies between
   (seconds - n c_de - n_inf c_inf) / (n_early + n_full) and
   (seconds - n c_de - (n_inf + n_early) c_inf) / n_full; Python is timed on the same full-norm
   candidates. The table states which ratios compare like with like.
3. The DE to r_c >= --target, interleaved per seed: scipy.optimize.differential_evolution
   (rand1bin, mutation 0.5, recombination 0.9, popsize 20 x 5 parameters = 100 members,
   updating='deferred' and init='random' as evoloop's generation-synchronous DE with a uniform
   initial population, polish=False, tol=0, bounds +-50 as `robust tune`'s --bound) on the
   paper's DOCHM objective (infeasible: the summed pole distance F(X) > 0 to the wedge zeta 0.7,
   rho 1, written as pole_region.rs; feasible: -r_c from slycot, so a feasible candidate is always
   better, no offset needed; an AB13DD failure is +inf, as evoloop refuses a candidate whose norm
   fails), stopped by a callback once r_c >= --target, against `evoloop robust tune --f 0.5 --cr
   0.9 --np 100 --seed S --target T` (2 threads, the default) and the same with --threads 1.
   scipy is capped at --de-maxiter generations (evoloop's own default limit) and --de-timeout
   seconds; a run that stops short of the target is reported as such.

BLAS threads are pinned to 1 (OPENBLAS_NUM_THREADS etc., unless set): the Python side runs on one
core. Run it on an otherwise quiet machine; the interleaving evens out a background load.
"""

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

try:
    import numpy as np
    import scipy
    import scipy.optimize
    import slycot
    import control
except ImportError as e:  # pragma: no cover - the message is the point
    sys.exit(f"error: {e}. Install the pinned packages first:\n"
             "    python3 -m pip install --only-binary :all: -r scripts/robust_peers.txt")

# Table 9 as printed (crates/evoloop-schemes/src/robust/study.rs).
PAPER_DEFC = [18.49, 19.04, 47.27, 7.30, -10.54]
PAPER_LQR1 = [1.57, 5.76, 3.23, 3.54, -3.16]
PAPER_LQR2 = [8.96, 20.89, 5.95, 6.54, -31.62]
# The optimum a DE run finds (benches/hot_paths.rs: two frequency peaks tie there).
DE_OPTIMUM = [13.7496, 21.7200, 49.9987, 8.1792, -8.3732]
# Found by a search of random Hurwitz gains in the +-50 box (rounded): outside the wedge.
RANDOM_A = [4.73, 15.93, 47.29, 3.3, -6.4]
RANDOM_B = [-18.6, 26.4, 4.1, 39.53, -1.2]
LIGHTLY_DAMPED = [43.43, 47.43, 48.5, 19.03, -29.75]


# --------------------------------------------------------------------------------------------
# The model, as problem.rs and plant/two_mass.rs build it
# --------------------------------------------------------------------------------------------

class Model:
    """Â, B̂, Ê, Ĥ of the paper's problem (m1 = m2 = 1, far sensor, spring structure) and the
    wedge; E and H also reduced to their nonzero columns / rows (the same transfer matrix, what
    evoloop's `Transfer` and a careful slycot caller use)."""

    def __init__(self, k=0.5, zeta=0.7, rho=1.0):
        a = np.array([[0.0, 0.0, 1.0, 0.0],
                      [0.0, 0.0, 0.0, 1.0],
                      [-k, k, 0.0, 0.0],
                      [k, -k, 0.0, 0.0]])
        c = np.array([1.0, 0.0, 0.0, 0.0])
        self.a_hat = np.zeros((5, 5))
        self.a_hat[:4, :4] = a
        self.a_hat[4, :4] = -c  # xi' = r - y
        self.b_hat = np.array([0.0, 0.0, 0.0, 1.0, 0.0])
        self.e = np.diag([0.0, 0.0, 1.0, 1.0, 0.0])
        self.h = np.diag([1.0, 1.0, 0.0, 0.0, 0.0])
        self.e_r = np.ascontiguousarray(self.e[:, 2:4])
        self.h_r = np.ascontiguousarray(self.h[:2, :])
        self.eye = np.eye(5)
        self.d_r = np.zeros((2, 2))
        self.d_full = np.zeros((5, 5))
        self.k, self.zeta, self.rho = k, zeta, rho
        # Wedge constants (pole_region.rs).
        t = math.sqrt(1.0 - zeta * zeta) / zeta
        n = math.sqrt(1.0 + t * t)
        self.w = (t, -rho, t * rho, -1.0 / n, t / n)

    def closed_loop(self, gains):
        return self.a_hat - np.outer(self.b_hat, gains)

    def wedge_distance(self, poles):
        """F(X): the poles' summed Euclidean distance to the wedge (pole_region.rs, verbatim)."""
        t, x0, y0, dx, dy = self.w
        rho = self.rho
        total = 0.0
        for z in poles.tolist():
            x, y = z.real, z.imag
            if x <= -rho and abs(y) <= t * (-x):
                continue
            y = abs(y)
            d_seg = math.sqrt((x - x0) ** 2 + (y - min(y, y0)) ** 2)
            s = max((x - x0) * dx + (y - y0) * dy, 0.0)
            d_ray = math.sqrt((x - x0 - s * dx) ** 2 + (y - y0 - s * dy) ** 2)
            total += min(d_seg, d_ray)
        return total

    def hinf_slycot(self, acl, full=False):
        """slycot.ab13dd (continuous, E = I, no equilibration, D = 0, tol 1e-10): (norm, w)."""
        if full:
            return slycot.ab13dd("C", "I", "N", "Z", 5, 5, 5, acl, self.eye, self.e, self.h,
                                 self.d_full, 1e-10)
        return slycot.ab13dd("C", "I", "N", "Z", 5, 2, 2, acl, self.eye, self.e_r, self.h_r,
                             self.d_r, 1e-10)

    def rc_slycot(self, gains):
        """r_c by slycot: 0 unless A_cl is Hurwitz (as evoloop: any Re >= 0 is unstable)."""
        acl = self.closed_loop(gains)
        poles = np.linalg.eigvals(acl)
        if np.any(poles.real >= 0.0):
            return 0.0, float("nan"), poles
        g, w = self.hinf_slycot(acl)
        return (1.0 / g if g > 0 else math.inf), float(w), poles

    def gains_at(self, acl, ws):
        """sigma_max(Ĥ (jwI - A_cl)^-1 Ê) at each w (batched solve + SVD)."""
        ws = np.atleast_1d(np.asarray(ws, dtype=float))
        m = 1j * ws[:, None, None] * self.eye[None] - acl[None]
        x = np.linalg.solve(m, np.broadcast_to(self.e_r, (len(ws), 5, 2)).astype(complex))
        g = self.h_r[None] @ x
        return np.linalg.svd(g, compute_uv=False)[:, 0]

    def rc_sweep(self, gains, points=40001):
        """Independent reference: sigma_max on w = 0, a log grid 1e-4..1e4 and the poles'
        natural and damped frequencies, every local maximum refined by a bounded Brent search."""
        acl = self.closed_loop(gains)
        poles = np.linalg.eigvals(acl)
        if np.any(poles.real >= 0.0):
            return 0.0, float("nan")
        extra = np.concatenate([np.abs(poles), np.abs(poles.imag)])
        extra = np.concatenate([extra, extra * (1 + 1e-6), extra * (1 - 1e-6)])
        ws = np.unique(np.concatenate([[0.0], np.logspace(-4, 4, points), extra[extra > 0]]))
        vals = self.gains_at(acl, ws)
        best, best_w = float(vals.max()), float(ws[vals.argmax()])
        for i in range(1, len(ws) - 1):
            if vals[i] >= vals[i - 1] and vals[i] >= vals[i + 1]:
                lo, hi = ws[i - 1], ws[i + 1]
                r = scipy.optimize.minimize_scalar(
                    lambda w: -self.gains_at(acl, w)[0], bounds=(lo, hi), method="bounded",
                    options={"xatol": 1e-13 * max(hi, 1e-3), "maxiter": 500})
                v = float(-r.fun)
                if v > best:
                    best, best_w = v, float(r.x)
        return 1.0 / best, best_w


# --------------------------------------------------------------------------------------------
# evoloop
# --------------------------------------------------------------------------------------------

def run_json(cmd):
    """Run an evoloop command that prints one JSON line; (parsed, process wall seconds)."""
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        sys.exit(f"error: `{' '.join(cmd)}` exited {p.returncode}:\n{p.stderr.strip()}")
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
    if not line:
        sys.exit(f"error: `{' '.join(cmd)}` printed no JSON:\n{p.stdout[:500]}")
    return json.loads(line[-1]), wall


def evoloop_radius(evoloop, gains):
    d, _ = run_json([evoloop, "robust", "radius", "--gains", ",".join(repr(float(g)) for g in gains),
                     "--json"])
    return d


def evoloop_lqr(evoloop, q, r):
    d, _ = run_json([evoloop, "robust", "lqr", "--q", ",".join(str(v) for v in q), "--r", str(r),
                     "--json"])
    return d["gains"]


def evoloop_tune(evoloop, seed, target, threads=None, np_=100):
    cmd = [evoloop, "robust", "tune", "--f", "0.5", "--cr", "0.9", "--np", str(np_), "--seed",
           str(seed), f"--target={target}", "--json"]
    if threads is not None:
        cmd += ["--threads", str(threads)]
    return run_json(cmd)


# --------------------------------------------------------------------------------------------
# Part 1: agreement
# --------------------------------------------------------------------------------------------

def rel(a, b):
    if a == b:
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def pole_mismatch(ev_poles, np_poles):
    """Largest distance between evoloop's poles and NumPy's, matched greedily."""
    left = [complex(re, im) for re, im in ev_poles]
    worst = 0.0
    for p in np_poles.tolist():
        j = min(range(len(left)), key=lambda i: abs(left[i] - p))
        worst = max(worst, abs(left[j] - p))
        left.pop(j)
    return worst


def agreement(model, evoloop):
    sets = [
        ("Table 9 DEFC", PAPER_DEFC),
        ("DE optimum (peaks tie)", DE_OPTIMUM),
        ("LQR q=100,1,1,1,1000", evoloop_lqr(evoloop, [100, 1, 1, 1, 1000], 1)),
        ("LQR q=1,1,1,1,1", evoloop_lqr(evoloop, [1, 1, 1, 1, 1], 1)),
        ("random Hurwitz A", RANDOM_A),
        ("random Hurwitz B", RANDOM_B),
        ("lightly damped", LIGHTLY_DAMPED),
        ("Table 9 LQR1 as printed", PAPER_LQR1),
        ("Table 9 LQR2 as printed", PAPER_LQR2),
        ("unstable 1,1,1,1,1", [1.0] * 5),
    ]
    rows = []
    for name, gains in sets:
        ev = evoloop_radius(evoloop, gains)
        rc_s, w_s, poles = model.rc_slycot(gains)
        rc_w, w_w = model.rc_sweep(gains)
        f_py = model.wedge_distance(poles)
        rows.append({
            "name": name, "gains": [float(g) for g in gains],
            "hurwitz": bool(np.all(poles.real < 0)),
            "max_re_pole": float(poles.real.max()),
            "rc_evoloop": ev["stability_radius"], "rc_slycot": rc_s, "rc_sweep": rc_w,
            "peak_w_slycot": w_s, "peak_w_sweep": w_w,
            "rel_slycot_evoloop": rel(rc_s, ev["stability_radius"]),
            "rel_sweep_evoloop": rel(rc_w, ev["stability_radius"]),
            "rel_sweep_slycot": rel(rc_w, rc_s),
            "wedge_distance_evoloop": ev["wedge_distance"], "wedge_distance_python": f_py,
            "in_wedge": ev["in_wedge"],
            "pole_mismatch": pole_mismatch(ev["poles"], poles),
        })
    return rows


def random_hurwitz(model, count, bound, seed=2024):
    """`count` gain vectors drawn uniformly in the +-bound box whose loop is Hurwitz (about
    0.7 % of the box is)."""
    rng = np.random.default_rng(seed)
    found = []
    while len(found) < count:
        k = rng.uniform(-bound, bound, size=(20000, 5))
        acl = model.a_hat[None] - model.b_hat[None, :, None] * k[:, None, :]
        ok = np.all(np.linalg.eigvals(acl).real < 0, axis=1)
        found.extend(k[ok][: count - len(found)])
    return found


def scan(model, evoloop, count, bound):
    """r_c of `count` random Hurwitz loops by slycot and evoloop; the sweep adjudicates the
    three largest differences."""
    rows = []
    for k in random_hurwitz(model, count, bound):
        gains = [float(round(x, 6)) for x in k]
        ev = evoloop_radius(evoloop, gains)
        rc_s = model.rc_slycot(gains)[0]
        rows.append({"gains": gains, "rc_evoloop": ev["stability_radius"], "rc_slycot": rc_s,
                     "rel": rel(rc_s, ev["stability_radius"])})
    rels = sorted(r["rel"] for r in rows)
    worst = sorted(rows, key=lambda r: -r["rel"])[:3]
    for r in worst:
        r["rc_sweep"] = model.rc_sweep(r["gains"])[0]
        # Which is nearer the sweep (a lower bound on the norm, so an upper bound on r_c)?
        r["sweep_sides_with"] = ("slycot" if abs(r["rc_sweep"] - r["rc_slycot"])
                                 < abs(r["rc_sweep"] - r["rc_evoloop"]) else "evoloop")
        # evoloop's norm is a lower bound too: its r_c is never below the true one.
        r["evoloop_above_slycot"] = r["rc_evoloop"] > r["rc_slycot"]
    return {
        "count": len(rows), "max_rel": rels[-1], "median_rel": rels[len(rels) // 2],
        "p99_rel": rels[min(len(rels) - 1, int(0.99 * len(rels)))],
        "over_1e_12": sum(x > 1e-12 for x in rels), "over_1e_9": sum(x > 1e-9 for x in rels),
        "worst": worst, "rows": rows,
    }


# --------------------------------------------------------------------------------------------
# evoloop's DE, replayed: which of its evaluations were feasible and took the full norm
# --------------------------------------------------------------------------------------------

MASK = (1 << 64) - 1
ONE_BITS = 0x3FF0000000000000


def bits_to_f64(b):
    return float(np.array([b], dtype=np.uint64).view(np.float64)[0])


class Xoshiro256pp:
    """crates/evoloop-optim/src/rng.rs, with rand 0.8's gen_range for f64 and usize."""

    def __init__(self, seed):
        z, s = seed & MASK, []
        for _ in range(4):
            z = (z + 0x9E3779B97F4A7C15) & MASK
            x = z
            x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & MASK
            x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & MASK
            s.append(x ^ (x >> 31))
        self.s = s

    def next_u64(self):
        s0, s1, s2, s3 = self.s
        x = (s0 + s3) & MASK
        r = ((((x << 23) | (x >> 41)) & MASK) + s0) & MASK
        t = (s1 << 17) & MASK
        s2 ^= s0
        s3 ^= s1
        s1 ^= s2
        s0 ^= s3
        s2 ^= t
        s3 = ((s3 << 45) | (s3 >> 19)) & MASK
        self.s = [s0, s1, s2, s3]
        return r

    def uniform(self, lo, hi):
        """rand 0.8 UniformFloat::sample_single."""
        while True:
            v = bits_to_f64((self.next_u64() >> 12) | ONE_BITS) - 1.0
            r = v * (hi - lo) + lo
            if r < hi:
                return r

    def below(self, n):
        """rand 0.8 UniformInt<usize>::sample_single(0, n): widening multiply, rejection zone."""
        zone = ((n << (64 - n.bit_length())) & MASK) - 1
        while True:
            p = self.next_u64() * n
            if p & MASK <= zone:
                return p >> 64

    @staticmethod
    def halves(x):
        hi = bits_to_f64(ONE_BITS | ((x >> 32) << 20)) - 1.0
        lo = bits_to_f64(ONE_BITS | ((x & 0xFFFFFFFF) << 20)) - 1.0
        return hi, lo


def sigma_2x2(model, acl, w):
    return float(model.gains_at(acl, [w])[0])


def early_rejected(model, acl, poles, level):
    """Whether evoloop's `hinf_from_poles` stops before the level-set iteration (stage 1: the
    gains at DC and at each pole's natural and damped frequency; stage 2: `refine_peak`), for a
    feasible trial whose target has norm `level`. 0: full norm, 1 or 2: the stage."""
    ws = [0.0]
    for p in poles.tolist():
        ws += [abs(p), abs(p.imag)]
    vals = model.gains_at(acl, ws)
    bv, bw = float(vals[0]), 0.0
    for v, w in zip(vals.tolist()[1:], ws[1:]):
        if v > bv:
            bv, bw = v, w
    if bv == 0.0:
        return 0
    if bv > level:
        return 1
    if bw > 0.0:  # refine_peak, verbatim
        d = 0.02 * bw
        for _ in range(6):
            w0 = bw
            a, c = max(w0 - d, 0.0), w0 + d
            ga, gc = sigma_2x2(model, acl, a), sigma_2x2(model, acl, c)
            denom = ga - 2.0 * bv + gc
            if denom < 0.0:
                w_new = min(max(w0 - 0.5 * d * (gc - ga) / denom, a), c)
            elif ga > gc:
                w_new = a
            else:
                w_new = c
            for v, w in ((ga, a), (gc, c), (sigma_2x2(model, acl, w_new), w_new)):
                if v > bv:
                    bv, bw = v, w
            d = max(abs(bw - w0) * 0.5, d * 0.05)
            if d < 1e-9 * max(bw, 1e-12):
                break
        if bv > level:
            return 2
    return 0


def replay_evoloop(model, seed, target, bound, np_=100, f=0.5, cr=0.9, max_iter=1000):
    """evoloop's `robust tune` run (crates/evoloop-optim/src/de.rs: uniform initial population,
    DE/rand/1/bin with a uniform redraw of a mutant component outside the box, a trial replaces
    its target when not worse, stop after the generation that reaches the target) replayed with
    slycot's r_c, counting what each evaluation cost evoloop: infeasible (eigenvalues + wedge),
    feasible and stopped by a one-frequency bound (`value_below`), or feasible with the full
    norm. The caller checks the replay against evoloop's own result."""
    rng = Xoshiro256pp(seed)
    d, lo, hi = 5, -bound, bound
    obj = Dochm(model)
    pop = [[rng.uniform(lo, hi) for _ in range(d)] for _ in range(np_)]
    vals = [obj(np.array(x)) for x in pop]
    counts = {"infeasible": sum(v > 0 for v in vals), "early": 0, "full": np_ - sum(v > 0 for v in vals)}
    full = [x for x, v in zip(pop, vals) if v <= 0]
    gen = 0
    while min(vals) > -target and gen < max_iter:
        trials = []
        for i in range(np_):
            r1 = pick(rng, np_, (i,))
            r2 = pick(rng, np_, (i, r1))
            r3 = pick(rng, np_, (i, r1, r2))
            jrand = rng.below(d)
            draws = [rng.next_u64() for _ in range(d)]
            t = []
            for j in range(d):
                u, redraw = Xoshiro256pp.halves(draws[j])
                m = pop[r1][j] + f * (pop[r2][j] - pop[r3][j])
                if m < lo or m > hi:
                    m = lo + redraw * (hi - lo)
                t.append(m if (u < cr or j == jrand) else pop[i][j])
            trials.append(t)
        for i, t in enumerate(trials):
            acl = model.closed_loop(t)
            poles = np.linalg.eigvals(acl)
            v = obj(np.array(t))
            if v > 0:
                counts["infeasible"] += 1
            elif vals[i] < 0 and early_rejected(model, acl, poles, -1.0 / vals[i]):
                counts["early"] += 1
            else:
                counts["full"] += 1
                full.append(t)
            if not math.isnan(v) and v <= vals[i]:
                vals[i], pop[i] = v, t
        gen += 1
    b = int(np.argmin(vals))
    return {"iterations": gen, "evaluations": np_ * (gen + 1), "counts": counts,
            "gains": pop[b], "rc": -vals[b], "full_candidates": full}


def pick(rng, n, exclude):
    while True:
        r = rng.below(n)
        if r not in exclude:
            return r


# --------------------------------------------------------------------------------------------
# Part 2: per-call costs
# --------------------------------------------------------------------------------------------

def per_call_us(f, calls):
    """Median wall time of one call of f, µs (each call timed on its own)."""
    ts = []
    clock = time.perf_counter_ns
    for _ in range(calls):
        t0 = clock()
        f()
        ts.append(clock() - t0)
    return statistics.median(ts) / 1e3


def python_costs(model, calls, infeasible_set, full_set):
    """Per-call medians, µs. `full_set`: the candidates evoloop's seed-1 run took the full norm
    for (from the replay), `infeasible_set`: random infeasible gains."""
    acl = model.closed_loop(PAPER_DEFC)
    k9 = np.array(PAPER_DEFC)

    def candidate(gains):
        a = model.closed_loop(gains)
        poles = np.linalg.eigvals(a)
        f = model.wedge_distance(poles)
        if f > 0.0:
            return f
        return -1.0 / model.hinf_slycot(a)[0]

    def cycling(items, f):
        it = iter(range(10 ** 12))
        return lambda: f(items[next(it) % len(items)])

    out = {
        "slycot_norm": per_call_us(lambda: model.hinf_slycot(acl), calls),
        "slycot_norm_full": per_call_us(lambda: model.hinf_slycot(acl, full=True), calls),
        "control_norm": per_call_us(
            lambda: control.norm(control.ss(acl, model.e, model.h, 0), "inf"),
            max(calls // 4, 100)),
        "candidate_feasible": per_call_us(lambda: candidate(k9), calls),
        "candidate_infeasible": per_call_us(cycling(infeasible_set, candidate), calls),
    }
    if full_set:
        acls = [model.closed_loop(k) for k in full_set]
        out["slycot_norm_run"] = per_call_us(cycling(acls, model.hinf_slycot), calls)
        out["candidate_feasible_run"] = per_call_us(cycling(full_set, candidate), calls)
    return out


def evoloop_costs(evoloop, target, initial_np):
    d, wall = evoloop_tune(evoloop, 1, target, threads=1)
    if d["stopped_by"] != "target":
        sys.exit(f"error: evoloop's seed-1 run stopped by {d['stopped_by']}, not the target")
    # A target of -1e300 (f(X) <= 1e300) is met by any finite value: the run stops after the
    # initial population, evaluated in full (no thresholds before the first generation).
    init, _ = evoloop_tune(evoloop, 1, -1e300, threads=1, np_=initial_np)
    if init["evaluations"] != initial_np or init["iterations"] != 0:
        sys.exit(f"error: the initial-population run did {init['evaluations']} evaluations "
                 f"in {init['iterations']} iterations, expected {initial_np} in 0")
    if not init["f_x"] > 0.0:
        sys.exit("error: the initial population held a feasible candidate: it does not time "
                 "the infeasible path alone")
    # DE's own work per evaluation (breeding and selection on a trivial objective, one thread).
    p = subprocess.run([evoloop, "optim", "bench", "--dim", "5", "--population", "100",
                        "--algorithms", "de", "--evaluations", "200000", "--repeats", "3",
                        "--json"], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"error: `evoloop optim bench` exited {p.returncode}:\n{p.stderr.strip()}")
    de_own = 1e6 / json.loads(p.stdout)["evals_per_s"]["de"]
    return {
        "de_own": de_own,
        "de_per_eval": 1e6 * d["seconds"] / d["evaluations"],
        "de_seconds": d["seconds"], "de_evaluations": d["evaluations"], "de_wall": wall,
        "infeasible": 1e6 * init["seconds"] / init["evaluations"],
    }


# --------------------------------------------------------------------------------------------
# Part 3: the DE
# --------------------------------------------------------------------------------------------

class Dochm:
    """The paper's DOCHM objective as evoloop's `RobustProblem::objective`, r_c by slycot;
    counts its calls, the feasible ones and the time spent in it."""

    def __init__(self, model):
        self.m = model
        self.nfev = 0
        self.feasible = 0
        self.seconds = 0.0

    def __call__(self, gains):
        t0 = time.perf_counter()
        v = self.value(gains)
        self.seconds += time.perf_counter() - t0
        return v

    def value(self, gains):
        m = self.m
        self.nfev += 1
        acl = m.a_hat - np.outer(m.b_hat, gains)
        poles = np.linalg.eigvals(acl)
        f = m.wedge_distance(poles)
        if f > 0.0:
            return f
        self.feasible += 1
        try:
            g = slycot.ab13dd("C", "I", "N", "Z", 5, 2, 2, acl, m.eye, m.e_r, m.h_r, m.d_r,
                              1e-10)[0]
        except slycot.exceptions.SlycotError:
            return math.inf
        return -1.0 / g if g > 0 else -math.inf


def scipy_de(model, seed, target, bound, maxiter, timeout):
    obj = Dochm(model)
    t0 = time.perf_counter()
    state = {"timeout": False}

    def callback(intermediate_result):
        if intermediate_result.fun <= -target:
            return True
        if time.perf_counter() - t0 > timeout:
            state["timeout"] = True
            return True
        return False

    r = scipy.optimize.differential_evolution(
        obj, [(-bound, bound)] * 5, strategy="rand1bin", maxiter=maxiter, popsize=20,
        tol=0.0, atol=0.0, mutation=0.5, recombination=0.9, rng=seed, callback=callback,
        polish=False, init="random", updating="deferred", workers=1)
    wall = time.perf_counter() - t0
    rc = -r.fun if r.fun <= 0 else 0.0
    return {
        "seed": seed, "wall": wall, "rc": rc, "reached": bool(r.fun <= -target),
        "timeout": state["timeout"], "iterations": int(r.nit), "evaluations": int(r.nfev),
        "objective_calls": obj.nfev, "feasible_evaluations": obj.feasible,
        "objective_seconds": obj.seconds,
        "gains": [float(v) for v in r.x], "message": str(r.message),
    }


def de_comparison(model, evoloop, seeds, target, bound, maxiter, timeout):
    rows = []
    for s in seeds:
        sp = scipy_de(model, s, target, bound, maxiter, timeout)
        e2, w2 = evoloop_tune(evoloop, s, target)
        e1, w1 = evoloop_tune(evoloop, s, target, threads=1)
        print(f"  seed {s}: scipy+slycot {sp['wall']:.2f} s ({sp['iterations']} it, "
              f"r_c {sp['rc']:.6f}{'' if sp['reached'] else ', target NOT reached'}), "
              f"evoloop {e2['seconds']:.3f} s (2 threads), {e1['seconds']:.3f} s (1 thread)",
              file=sys.stderr, flush=True)
        ev = {}
        for key, d, wall in (("evoloop", e2, w2), ("evoloop_1t", e1, w1)):
            ev[key] = {
                "seconds": d["seconds"], "wall": wall, "iterations": d["iterations"],
                "evaluations": d["evaluations"], "rc": d["stability_radius"],
                "reached": d["stopped_by"] == "target", "stopped_by": d["stopped_by"],
                "gains": d["gains"],
            }
        rows.append({"seed": s, "scipy": sp, **ev})
    return rows


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------

def report(res):
    out = []
    p = out.append
    v = res["versions"]
    p(f"# evoloop beside slycot and scipy ({res['date']})\n")
    p(f"evoloop `{res['evoloop']}`; python {v['python']}, numpy {v['numpy']}, scipy {v['scipy']}, "
      f"slycot {v['slycot']}, python-control {v['control']}; {v['machine']}; BLAS threads "
      f"{v['blas_threads']}; load average (1, 5, 15 min) at the start "
      f"{', '.join(format(x, '.2f') for x in v['load_average_start'])}, at the end "
      f"{', '.join(format(x, '.2f') for x in v['load_average_end'])}.\n")

    p("## 1. r_c: slycot (AB13DD) and a frequency sweep against `evoloop robust radius`\n")
    p("| gains | Hurwitz | in wedge | r_c evoloop | r_c slycot | r_c sweep | rel slycot-evoloop "
      "| rel sweep-evoloop | rel sweep-slycot | F(X) evoloop / python | poles Δ |")
    p("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in res["agreement"]["rows"]:
        p(f"| {r['name']} `{','.join(format(x, '.6g') for x in r['gains'])}` | "
          f"{'yes' if r['hurwitz'] else 'no'} | {'yes' if r['in_wedge'] else 'no'} | "
          f"{r['rc_evoloop']:.15g} | {r['rc_slycot']:.15g} | {r['rc_sweep']:.15g} | "
          f"{r['rel_slycot_evoloop']:.1e} | {r['rel_sweep_evoloop']:.1e} | "
          f"{r['rel_sweep_slycot']:.1e} | {r['wedge_distance_evoloop']:.6g} / "
          f"{r['wedge_distance_python']:.6g} | {r['pole_mismatch']:.1e} |")
    a = res["agreement"]
    sc = a["scan"]
    if sc:
        p(f"\nScan of {sc['count']} random Hurwitz gain sets (box ±50): relative difference "
          f"slycot-evoloop median {sc['median_rel']:.1e}, 99th percentile {sc['p99_rel']:.1e}, "
          f"max {sc['max_rel']:.1e}; {sc['over_1e_12']} above 1e-12, {sc['over_1e_9']} above "
          f"1e-9. The three largest, with the sweep:\n")
        p("| gains | r_c evoloop | r_c slycot | r_c sweep | rel | sweep sides with |")
        p("|---|---|---|---|---|---|")
        for r in sc["worst"]:
            p(f"| `{','.join(format(x, '.6g') for x in r['gains'])}` | {r['rc_evoloop']:.15g} | "
              f"{r['rc_slycot']:.15g} | {r['rc_sweep']:.15g} | {r['rel']:.1e} | "
              f"{r['sweep_sides_with']} |")
    p(f"\nslycot and evoloop agree to {a['max_rel_slycot_evoloop']:.1e} relative over all "
      f"gain sets (named: {a['max_rel_named']:.1e}, {a['worst_named']}); tolerance "
      f"{a['tolerance']:.0e}: {'PASS' if a['pass'] else 'FAIL'}. The sweep (a lower bound on "
      f"the norm) is within {a['max_rel_sweep_evoloop']:.1e} of evoloop and "
      f"{a['max_rel_sweep_slycot']:.1e} of slycot on the named sets. evoloop's level-set "
      f"iteration stops when no crossing is left at (1 + 2e-9) times its lower bound "
      f"(HINF_TOL 1e-9), so its norm may sit up to 2e-9 below the true one (its r_c above); "
      f"slycot runs at tol 1e-10.\n")

    c = res["costs"]
    m = c["median"]
    rp = c["replay"]
    p(f"## 2. Cost per call, µs ({c['rounds']} interleaved rounds; Python medians of "
      f"{c['calls']} calls each, medians over rounds)\n")
    p(f"Replay of evoloop's `tune --seed 1 --target 0.3489` run in Python (its RNG, DE and "
      f"`value_below` shortcut, slycot's r_c): {rp['iterations']} iterations, "
      f"{rp['evaluations']} evaluations, final gains within {rp['gains_max_rel']:.0e} of "
      f"evoloop's ({rp['evoloop_iterations']} iterations, {rp['evoloop_evaluations']} "
      f"evaluations): {'the same run' if rp['matches'] else 'NOT the same run'}. Its "
      f"evaluations: {rp['counts']['infeasible']} infeasible, {rp['counts']['early']} feasible "
      f"and stopped by a one-frequency bound, {rp['counts']['full']} feasible with the full "
      f"norm.\n")
    p("| what | µs | rounds |")
    p("|---|---|---|")
    labels = [
        ("slycot_norm", "slycot ab13dd, norm call only, prebuilt A_cl (Table 9), Ê 5x2 / Ĥ 2x5"),
        ("slycot_norm_full", "slycot ab13dd, norm call only, full 5x5 Ê, Ĥ (Table 9)"),
        ("slycot_norm_run", "slycot ab13dd, norm call only, the replayed run's full-norm candidates"),
        ("control_norm", "python-control `control.norm(ss(A_cl, Ê, Ĥ, 0), 'inf')` (build + poles + AB13DD, Table 9)"),
        ("candidate_feasible", "Python per feasible candidate: build A_cl + eigvals + wedge + ab13dd (Table 9)"),
        ("candidate_feasible_run", "the same, the replayed run's full-norm candidates"),
        ("candidate_infeasible", "Python per infeasible candidate: build A_cl + eigvals + wedge"),
        ("evoloop_de_per_eval", "evoloop per DE evaluation: `tune --seed 1 --target 0.3489 --threads 1`, seconds / evaluations (all kinds + DE's own work)"),
        ("evoloop_infeasible", f"evoloop per infeasible candidate: `tune --np {c['initial_np']} --target=-1e300 --threads 1` (initial population only)"),
        ("evoloop_de_own", "evoloop DE's own work per evaluation, c_de: `optim bench --dim 5 --population 100 --algorithms de`"),
        ("evoloop_full_low", "evoloop per full feasible candidate, lower bound: (seconds - n c_de - n_inf c_inf) / (n_early + n_full)"),
        ("evoloop_full_high", "evoloop per full feasible candidate, upper bound: (seconds - n c_de - (n_inf + n_early) c_inf) / n_full"),
    ]
    for key, label in labels:
        if key in m:
            p(f"| {label} | {m[key]:.2f} | "
              f"{', '.join(format(x, '.1f') for x in c['rounds_values'][key])} |")
    p("\n| ratio | value | like for like? |")
    p("|---|---|---|")
    for r in c["ratios"]:
        val = f"{r['value']:.2f}"
        if "value_high" in r:
            val = f"{r['value']:.2f} to {r['value_high']:.2f}"
        p(f"| {r['what']} | {val} | {r['note']} |")
    p("")

    d = res["de"]
    if d is None:
        return "\n".join(out)
    p(f"## 3. DE/rand/1/bin to r_c >= {d['target']} (F 0.5, CR 0.9, NP 100, box ±{d['bound']:g}; "
      f"scipy capped at {d['maxiter']} generations and {d['timeout']:g} s)\n")
    p("| seed | scipy+slycot s | it | evals | feasible | r_c | evoloop s (2 thr) | process wall | it | "
      "evals | r_c | evoloop s (1 thr) | process wall | scipy / evoloop 2 thr | scipy / evoloop 1 thr |")
    p("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in d["rows"]:
        s, e2, e1 = r["scipy"], r["evoloop"], r["evoloop_1t"]
        mark = "" if s["reached"] else (" NOT reached (time cap)" if s["timeout"]
                                        else " NOT reached")
        p(f"| {r['seed']} | {s['wall']:.2f} | {s['iterations']} | {s['evaluations']} | "
          f"{s['feasible_evaluations']} | {s['rc']:.6f}{mark} | {e2['seconds']:.3f} | "
          f"{e2['wall']:.3f} | {e2['iterations']} | {e2['evaluations']} | {e2['rc']:.6f}"
          f"{'' if e2['reached'] else ' NOT reached'} | {e1['seconds']:.3f} | {e1['wall']:.3f} | "
          f"{s['wall'] / e2['seconds']:.1f} | {s['wall'] / e1['seconds']:.1f} |")
    sm = d["summary"]
    n = len(d["rows"])
    p(f"\nMedians: scipy+slycot {sm['scipy_wall']:.2f} s ({sm['scipy_reached']}/{n} reached "
      f"the target; {sm['scipy_per_eval_us']:.1f} µs per evaluation; "
      f"{100 * sm['scipy_feasible_fraction']:.0f} % of evaluations feasible, "
      f"{100 * sm['scipy_objective_share']:.0f} % of the time in the objective, the rest "
      f"scipy's own work), evoloop "
      f"{sm['evoloop_seconds']:.3f} s as reported, {sm['evoloop_wall']:.3f} s process wall "
      f"(2 threads, {sm['evoloop_reached']}/{n} reached, {sm['evoloop_per_eval_us']:.2f} µs per "
      f"evaluation), {sm['evoloop_1t_seconds']:.3f} s / {sm['evoloop_1t_wall']:.3f} s (1 thread, "
      f"{sm['evoloop_1t_per_eval_us']:.2f} µs per evaluation). Iterations to the target: scipy "
      f"median {sm['scipy_iterations']:g}, evoloop {sm['evoloop_iterations']:g}.\n")
    p("| ratio of medians | value |")
    p("|---|---|")
    p(f"| scipy+slycot wall / evoloop reported seconds, 2 threads (the issue's command) | {sm['ratio_2t']:.1f} |")
    p(f"| scipy+slycot wall / evoloop process wall, 2 threads | {sm['ratio_2t_wall']:.1f} |")
    p(f"| scipy+slycot wall / evoloop reported seconds, 1 thread | {sm['ratio_1t']:.1f} |")
    p(f"| scipy+slycot per evaluation / evoloop per evaluation, 1 thread | {sm['per_eval_ratio_1t']:.1f} |")
    return "\n".join(out)


def plain(o):
    """JSON-ready: NumPy scalars to Python, NaN and infinities to None."""
    if isinstance(o, dict):
        return {k: plain(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [plain(v) for v in o]
    if isinstance(o, np.generic):
        o = o.item()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return o


def median(xs):
    return statistics.median(xs) if xs else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="See the module docstring for what each part measures.")
    ap.add_argument("--evoloop", default="target/release/evoloop", help="the evoloop binary")
    ap.add_argument("--out", required=True, help="JSON file to write (its directory is created)")
    ap.add_argument("--tolerance", type=float, default=1e-6,
                    help="largest relative r_c difference slycot-evoloop accepted (default 1e-6)")
    ap.add_argument("--calls", type=int, default=2000,
                    help="timed calls per slycot measurement and round (>= 2000)")
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds of part 2")
    ap.add_argument("--initial-np", type=int, default=20000,
                    help="population of the evoloop run that times infeasible candidates")
    ap.add_argument("--seeds", default="1,2,3,4,5", help="DE seeds, comma-separated")
    ap.add_argument("--target", type=float, default=0.3489, help="r_c the DE runs stop at")
    ap.add_argument("--bound", type=float, default=50.0,
                    help="gain box +-bound (evoloop robust tune's --bound default: 50)")
    ap.add_argument("--de-maxiter", type=int, default=1000,
                    help="scipy generation limit (evoloop's --max-iter default: 1000)")
    ap.add_argument("--de-timeout", type=float, default=180.0,
                    help="seconds after which a scipy run is stopped and reported short")
    ap.add_argument("--scan", type=int, default=300,
                    help="random Hurwitz gain sets checked besides the named ones (0: none)")
    ap.add_argument("--skip-de", action="store_true", help="parts 1 and 2 only")
    args = ap.parse_args()

    evoloop = os.path.abspath(args.evoloop)
    if not os.path.isfile(evoloop):
        sys.exit(f"error: no evoloop binary at {evoloop} (build it with "
                 "`cargo build --release` or pass --evoloop PATH)")
    if not os.access(evoloop, os.X_OK):
        sys.exit(f"error: {evoloop} is not executable")
    try:
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    except ValueError:
        sys.exit(f"error: --seeds must be comma-separated integers (got {args.seeds!r})")
    if not seeds or any(s < 0 for s in seeds):
        sys.exit("error: --seeds needs at least one seed >= 0")
    if args.calls < 2000:
        sys.exit(f"error: --calls must be >= 2000 (got {args.calls})")
    if args.rounds < 1 or args.scan < 0 or args.initial_np < 4 or args.de_maxiter < 1 or args.de_timeout <= 0:
        sys.exit("error: --rounds, --de-maxiter >= 1, --scan >= 0, --initial-np >= 4, "
                 "--de-timeout > 0 needed")
    if not (0 < args.tolerance < 1) or not (args.target > 0) or not (args.bound > 0):
        sys.exit("error: --tolerance in (0, 1), --target > 0 and --bound > 0 needed")
    out_dir = os.path.dirname(os.path.abspath(args.out))
    os.makedirs(out_dir, exist_ok=True)
    p = subprocess.run([evoloop, "robust", "tune", "--help"], capture_output=True, text=True)
    if p.returncode != 0 or "--target" not in p.stdout:
        sys.exit(f"error: {evoloop} has no `robust tune --target` (too old a build?)")
    version = subprocess.run([evoloop, "--version"], capture_output=True, text=True).stdout.strip()

    model = Model()
    res = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "evoloop": f"{evoloop} ({version})",
        "versions": {
            "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "slycot": slycot.__version__,
            "control": control.__version__, "machine": f"{platform.machine()}, "
            f"{os.cpu_count()} logical CPUs", "blas_threads": os.environ["OPENBLAS_NUM_THREADS"],
            "load_average_start": os.getloadavg(),
        },
    }

    # Part 1
    print("part 1: r_c agreement ...", file=sys.stderr, flush=True)
    rows = agreement(model, evoloop)
    sc = scan(model, evoloop, args.scan, args.bound) if args.scan else None
    worst = max(rows, key=lambda r: r["rel_slycot_evoloop"])
    max_rel = max(worst["rel_slycot_evoloop"], sc["max_rel"] if sc else 0.0)
    res["agreement"] = {
        "rows": rows, "tolerance": args.tolerance, "scan": sc,
        "max_rel_named": worst["rel_slycot_evoloop"], "worst_named": worst["name"],
        "max_rel_slycot_evoloop": max_rel,
        "max_rel_sweep_evoloop": max(r["rel_sweep_evoloop"] for r in rows),
        "max_rel_sweep_slycot": max(r["rel_sweep_slycot"] for r in rows),
        "pass": max_rel <= args.tolerance,
    }

    # Part 2
    print("part 2: replaying evoloop's seed-1 run ...", file=sys.stderr, flush=True)
    ref, _ = evoloop_tune(evoloop, 1, args.target, threads=1)
    rep = replay_evoloop(model, 1, args.target, args.bound)
    gains_rel = max(rel(x, y) for x, y in zip(rep["gains"], ref["gains"]))
    rep_ok = (rep["iterations"] == ref["iterations"] and rep["evaluations"] == ref["evaluations"]
              and gains_rel < 1e-9)
    replay = {"iterations": rep["iterations"], "evaluations": rep["evaluations"],
              "counts": rep["counts"], "gains": rep["gains"], "rc": rep["rc"],
              "evoloop_iterations": ref["iterations"], "evoloop_evaluations": ref["evaluations"],
              "evoloop_gains": ref["gains"], "gains_max_rel": gains_rel, "matches": rep_ok}
    print(f"  replay: {rep['iterations']} iterations, {rep['evaluations']} evaluations "
          f"({rep['counts']}), evoloop {ref['iterations']} / {ref['evaluations']}: "
          f"{'identical run' if rep_ok else 'DIFFERENT run, no bracket'}",
          file=sys.stderr, flush=True)
    full_set = rep["full_candidates"] if rep_ok else []

    print("part 2: per-call costs ...", file=sys.stderr, flush=True)
    rng = np.random.default_rng(12345)
    pool = rng.uniform(-args.bound, args.bound, size=(4000, 5))
    infeasible = [x for x in pool
                  if model.wedge_distance(np.linalg.eigvals(model.closed_loop(x))) > 0]
    rv = {}
    for rnd in range(args.rounds):
        a = python_costs(model, args.calls, infeasible, full_set)
        b = evoloop_costs(evoloop, args.target, args.initial_np)
        for k, v in a.items():
            rv.setdefault(k, []).append(v)
        rv.setdefault("evoloop_de_per_eval", []).append(b["de_per_eval"])
        rv.setdefault("evoloop_infeasible", []).append(b["infeasible"])
        rv.setdefault("evoloop_de_own", []).append(b["de_own"])
        if rep_ok:
            # evoloop's seconds = n_inf c_inf + n_early c_early + n_full c_full + n c_de, with
            # c_inf <= c_early <= c_full: the mean over feasible evaluations bounds c_full
            # below, c_early = c_inf above.
            n = rep["counts"]
            t = 1e6 * b["de_seconds"] - rep["evaluations"] * b["de_own"]
            rest = t - n["infeasible"] * b["infeasible"]
            rv.setdefault("evoloop_full_low", []).append(rest / (n["early"] + n["full"]))
            rv.setdefault("evoloop_full_high", []).append(
                (rest - n["early"] * b["infeasible"]) / n["full"])
        print(f"  round {rnd + 1}: slycot {a['slycot_norm']:.1f} µs, Python feasible candidate "
              f"{a['candidate_feasible']:.1f} µs, evoloop per DE evaluation "
              f"{b['de_per_eval']:.2f} µs, infeasible {b['infeasible']:.2f} µs",
              file=sys.stderr, flush=True)
    med = {k: median(v) for k, v in rv.items()}
    ratios = [
        {"what": "slycot norm call (Table 9) / evoloop per DE evaluation",
         "value": med["slycot_norm"] / med["evoloop_de_per_eval"],
         "note": "no: evoloop's is an average over a DE run, most of it cheaper than one r_c"},
        {"what": "Python infeasible candidate / evoloop infeasible candidate",
         "value": med["candidate_infeasible"] / med["evoloop_infeasible"],
         "note": "yes: build + eigenvalues + wedge on both sides"},
    ]
    if rep_ok:
        ratios += [
            {"what": "Python full feasible candidate / evoloop full feasible candidate "
                     "(same candidates: the replayed run's)",
             "value": med["candidate_feasible_run"] / med["evoloop_full_high"],
             "value_high": med["candidate_feasible_run"] / med["evoloop_full_low"],
             "note": "yes (bracket: evoloop's cost is bounded, not timed alone)"},
            {"what": "slycot norm call / evoloop norm part (full feasible candidate - "
                     "infeasible candidate), same candidates",
             "value": med["slycot_norm_run"] / (med["evoloop_full_high"] - med["evoloop_infeasible"]),
             "value_high": med["slycot_norm_run"] / (med["evoloop_full_low"] - med["evoloop_infeasible"]),
             "note": "yes, for the norm alone (bracket)"},
        ]
    res["costs"] = {"calls": args.calls, "rounds": args.rounds, "initial_np": args.initial_np,
                    "replay": replay, "rounds_values": rv, "median": med, "ratios": ratios,
                    "unit": "microseconds per call"}

    # Part 3
    if not args.skip_de:
        print("part 3: DE runs ...", file=sys.stderr, flush=True)
        rows = de_comparison(model, evoloop, seeds, args.target, args.bound, args.de_maxiter,
                             args.de_timeout)
        sc = [r["scipy"] for r in rows]
        e2 = [r["evoloop"] for r in rows]
        e1 = [r["evoloop_1t"] for r in rows]
        summ = {
            "scipy_wall": median([s["wall"] for s in sc]),
            "scipy_reached": sum(s["reached"] for s in sc),
            "scipy_per_eval_us": median([1e6 * s["wall"] / s["evaluations"] for s in sc]),
            "scipy_iterations": median([s["iterations"] for s in sc]),
            "scipy_objective_share": median([s["objective_seconds"] / s["wall"] for s in sc]),
            "scipy_feasible_fraction": median([s["feasible_evaluations"] / s["objective_calls"]
                                               for s in sc]),
            "evoloop_seconds": median([e["seconds"] for e in e2]),
            "evoloop_wall": median([e["wall"] for e in e2]),
            "evoloop_reached": sum(e["reached"] for e in e2),
            "evoloop_per_eval_us": median([1e6 * e["seconds"] / e["evaluations"] for e in e2]),
            "evoloop_iterations": median([e["iterations"] for e in e2]),
            "evoloop_1t_seconds": median([e["seconds"] for e in e1]),
            "evoloop_1t_wall": median([e["wall"] for e in e1]),
            "evoloop_1t_per_eval_us": median([1e6 * e["seconds"] / e["evaluations"] for e in e1]),
        }
        summ["ratio_2t"] = summ["scipy_wall"] / summ["evoloop_seconds"]
        summ["ratio_2t_wall"] = summ["scipy_wall"] / summ["evoloop_wall"]
        summ["ratio_1t"] = summ["scipy_wall"] / summ["evoloop_1t_seconds"]
        summ["per_eval_ratio_1t"] = summ["scipy_per_eval_us"] / summ["evoloop_1t_per_eval_us"]
        res["de"] = {"target": args.target, "bound": args.bound, "maxiter": args.de_maxiter,
                     "timeout": args.de_timeout, "rows": rows, "summary": summ}
    else:
        res["de"] = None

    res["versions"]["load_average_end"] = os.getloadavg()
    text = report(res)
    print(text)
    with open(args.out, "w") as f:
        json.dump(plain(res), f, indent=1)
        f.write("\n")
    print(f"written: {args.out}", file=sys.stderr)
    sys.exit(0 if res["agreement"]["pass"] else 1)


if __name__ == "__main__":
    main()

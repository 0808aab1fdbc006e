#!/usr/bin/env python3
"""Reference values for evoloop's Kalman filter (`law::estimator`), from python-control (an
independent implementation): each continuous single-input single-output model's zero-order-hold
discretisation at the control period (`control.c2d`), the steady-state filter `control.dlqe`
designs for a disturbance entering with the input (G = B_d, variance QN = q^2; with a state
noise w, G = [B_d I] and QN = diag(q^2, w^2, ...)) and a measurement error of variance RN = r^2
(its gain L, the Riccati solution P and the error dynamics' poles E),
and that filter's one-step predictions x[k+1|k] = A x[k|k-1] + B u[k] + L (y[k] - C x[k|k-1])
over a seeded input and a noisy measured output of the model itself. tests/estimator.rs checks
evoloop against them.

    python3 -m pip install -r scripts/lti_reference.txt
    python3 scripts/kalman_reference.py            # writes tests/data/kalman.json
    python3 scripts/kalman_reference.py --check    # regenerates in memory, compares with the file
"""
import argparse
import json
import os
import sys

import control
import numpy as np

OUT = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "kalman.json")
STEPS = 400


def two_mass(k, m1, m2, sensor):
    """evoloop's two-mass state order x = [x_far, x_act, v_far, v_act] (src: plant/two_mass.rs)."""
    a = [[0, 0, 1, 0], [0, 0, 0, 1], [-k / m2, k / m2, 0, 0], [k / m1, -k / m1, 0, 0]]
    b = [[0], [0], [0], [1 / m1]]
    c = [[1, 0, 0, 0]] if sensor == "far" else [[0, 1, 0, 0]]
    return a, b, c


# name, (A, B, C), period, process noise std q, measurement noise std r[, state noise std w]
CASES = [
    # config/two_mass/two_mass.toml's plant and filter: the encoder's 1e-4 counts as a uniform error.
    ("two_mass_far", two_mass(1.0, 1.0, 1.0, "far"), 0.001, 1.0,
     float(np.sqrt(0.0005 ** 2 + 0.0001 ** 2 / 12))),
    ("two_mass_actuated", two_mass(1.2, 1.0, 1.0, "actuated"), 0.001, 0.3, 1e-3),
    # config/plants/pendulum.json upright: theta'' = 25 theta + u, angle measured.
    ("pendulum", ([[0, 1], [25, 0]], [[0], [1]], [[1, 0]]), 0.001, 2.0, 2e-4),
    ("double_integrator", ([[0, 1], [0, 0]], [[0], [1]], [[1, 0]]), 0.01, 1.0, 1e-3),
    # The collocated encoder whose filter, on the input's disturbance alone, has its error poles
    # on the antiresonance sqrt(k/m2); a state noise moves them off it (config/
    # two_mass_indirect_collocated.toml's design at k = 0.5).
    ("two_mass_actuated_state_noise", two_mass(0.5, 1.0, 1.0, "actuated"), 0.001, 1.0,
     float(np.sqrt(0.0005 ** 2 + 0.0001 ** 2 / 12)), 0.001),
]


def case(name, abc, period, q, r, w=0.0, *, seed):
    a, b, c = (np.array(m, dtype=float) for m in abc)
    sysd = control.c2d(control.ss(a, b, c, 0), period, method="zoh")
    ad, bd, cd = np.asarray(sysd.A), np.asarray(sysd.B), np.asarray(sysd.C)
    if w > 0.0:
        n = ad.shape[0]
        g = np.hstack([bd, np.eye(n)])
        qn = np.diag([q * q] + [w * w] * n)
        l, p, e = control.dlqe(ad, g, cd, qn, r * r)
    else:
        l, p, e = control.dlqe(ad, bd, cd, q * q, r * r)
    l = np.asarray(l)
    # The model's own motion under a seeded input, measured with noise.
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.0, 1.0, STEPS // 20 + 1), 20)[:STEPS]
    x = np.zeros(ad.shape[0])
    x[0] = 0.01
    y = np.zeros(STEPS)
    for k in range(STEPS):
        y[k] = (cd @ x)[0] + rng.normal(0.0, r)
        x = ad @ x + bd[:, 0] * u[k]
    # dlqe's predictor from a zero start.
    xp = np.zeros(ad.shape[0])
    predicted = []
    for k in range(STEPS):
        xp = ad @ xp + bd[:, 0] * u[k] + l[:, 0] * (y[k] - (cd @ xp)[0])
        predicted.append(xp.tolist())
    poles = sorted((complex(z) for z in np.atleast_1d(e)), key=lambda z: (z.real, z.imag))
    out = {
        "name": name,
        "a": a.tolist(),
        "b": b[:, 0].tolist(),
        "c": c[0].tolist(),
        "period": period,
        "process_noise": q,
        "measurement_noise": r,
        "ad": ad.tolist(),
        "bd": bd[:, 0].tolist(),
        "l": l[:, 0].tolist(),
        "p": np.asarray(p).tolist(),
        "poles": [[z.real, z.imag] for z in poles],
        "u": u.tolist(),
        "y": y.tolist(),
        "predicted": predicted,
    }
    if w > 0.0:
        out["state_noise"] = w
    return out


def generate():
    return {
        "generator": "scripts/kalman_reference.py, python-control %s" % control.__version__,
        "cases": [case(*c, seed=i + 1) for i, c in enumerate(CASES)],
    }


def close(a, b, rel):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and np.all(np.abs(a - b) <= rel * np.maximum(1.0, np.abs(b)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare with the file instead of writing it")
    args = ap.parse_args()
    fresh = generate()
    if not args.check:
        with open(OUT, "w", encoding="utf-8") as f:
            json.dump(fresh, f, indent=1)
            f.write("\n")
        print("wrote", os.path.normpath(OUT))
        return 0
    with open(OUT, encoding="utf-8") as f:
        filed = json.load(f)
    bad = []
    for got, want in zip(fresh["cases"], filed["cases"]):
        for key in ("ad", "bd", "l", "p", "poles", "u", "y", "predicted"):
            if not close(got[key], want[key], 1e-9):
                bad.append("%s: %s differs" % (want["name"], key))
    if len(fresh["cases"]) != len(filed["cases"]):
        bad.append("a different number of cases")
    for b in bad:
        print(b, file=sys.stderr)
    print("tests/data/kalman.json:", "differs" if bad else "agrees with python-control")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

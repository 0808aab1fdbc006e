#!/usr/bin/env python3
"""Reference vectors for evoloop's `plant.kind = "lti"`, from python-control (an independent
implementation): each system's zero-order-hold discretisation (`control.c2d`), its forced
response to a seeded input (`control.forced_response`) and, for single-input single-output
systems, whether state-feedback gains with integral action stabilise the sampled closed loop
(poles of the loop `control.feedback` builds). tests/lti.rs checks evoloop against them.

    python3 -m pip install -r scripts/lti_reference.txt
    python3 scripts/lti_reference.py            # writes tests/data/lti/
    python3 scripts/lti_reference.py --check    # regenerates in memory, compares with the files

Each case writes NAME.model.json (the model as a user would export it: the keys of
[plant.lti], loadable with `plant.lti.file`) and NAME.response.json (period, input delay,
inputs, python-control's states, outputs, c2d matrices, gain sets and verdicts).
"""
import argparse
import json
import os
import sys

import control
import numpy as np
import scipy.signal

OUT = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "lti")
STEPS = 300


def rows(m):
    return np.atleast_2d(np.asarray(m, dtype=float)).tolist()


def inputs(seed, m):
    """A seeded piecewise-constant input: a new level every 7 samples, in [-1, 1]."""
    rng = np.random.default_rng(seed)
    levels = rng.uniform(-1.0, 1.0, size=(STEPS // 7 + 1, m))
    return np.repeat(levels, 7, axis=0)[:STEPS]


def response(sysd, u, x0):
    """python-control's discrete forced response: y[k] = C x[k] + D u[k]."""
    t = np.arange(STEPS) * sysd.dt
    r = control.forced_response(sysd, T=t, U=u.T, X0=x0, return_x=True)
    return np.atleast_2d(r.states).T, np.atleast_2d(r.outputs).T


def held_plant(ad, bd, c, d, delay):
    """The sampled plant as the controller sees it: state s = [x; w_1..w_delay; v], where w is
    the input delay line (w_1 the oldest) and v the input that reached the plant over the last
    period, y_k = C x_k + D v_{k-1} (the sample is taken before the command it causes)."""
    n = ad.shape[0]
    nz = n + delay
    a = np.zeros((nz + 1, nz + 1))
    b = np.zeros((nz + 1, 1))
    a[:n, :n] = ad
    if delay:
        a[:n, n:n + 1] = bd
        for i in range(delay - 1):
            a[n + i, n + i + 1] = 1.0
        b[nz - 1, 0] = 1.0
        a[nz, n] = 1.0
    else:
        b[:n] = bd
        b[nz, 0] = 1.0
    cy = np.hstack([np.atleast_2d(c), np.zeros((1, delay)), np.atleast_2d(d)])
    return a, b, cy, nz


def gain_verdicts(ad, bd, c, d, period, seed, delay=0, count=40):
    """Gains [K_z, k_i] for u = -K_z z + I, I+ = I - k_i T (r - y) (evoloop's StateFeedback,
    z = [x; the delay line]), around a discrete LQR gain, each with whether the closed loop
    python-control builds is stable (every pole inside the unit circle, clear of it by 1e-6
    either way)."""
    a, b, cy, nz = held_plant(ad, bd, c, d, delay)
    # The LQR seed on [z; xi], xi+ = xi + T (r - y), y taken without the feedthrough:
    # u = -K [z; xi] is evoloop's law with I = -k_i xi, so its gain is a gain set as it stands.
    a_aug = np.block([[a[:nz, :nz], np.zeros((nz, 1))], [-period * cy[:, :nz], np.ones((1, 1))]])
    b_aug = np.vstack([b[:nz], np.zeros((1, 1))])
    k_lqr, _, _ = control.dlqr(a_aug, b_aug, np.eye(nz + 1), np.eye(1))
    k_lqr = np.asarray(k_lqr).ravel()
    # The plant's outputs: y and the law's state z.
    outputs = np.vstack([cy, np.hstack([np.eye(nz), np.zeros((nz, 1))])])
    plant = control.ss(a, b, outputs, np.zeros((nz + 1, 1)), period)
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        k = k_lqr * rng.uniform(-0.5, 3.0, size=nz + 1)
        kz, ki = k[:nz], k[nz]
        # The law as a discrete system from [y; z] to u (r = 0): state I,
        # I+ = I + ki T y, u = I - kz z.
        law = control.ss([[1.0]], np.hstack([[[ki * period]], np.zeros((1, nz))]),
                         [[1.0]], np.hstack([[[0.0]], -kz.reshape(1, nz)]), period)
        loop = control.feedback(plant, law, sign=+1)
        radius = max(abs(p) for p in loop.poles())
        if abs(radius - 1.0) < 1e-6:
            continue
        out.append({"gains": k.tolist(), "stable": bool(radius < 1.0), "radius": float(radius)})
    return out


def case_ss(name, a, b, c, d, period, x0, seed, gains=False, dt=None):
    a, b, c, d = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (a, b, c, d))
    model = {"a": rows(a), "b": rows(b), "c": rows(c), "d": rows(d)}
    if dt is None:
        sysd = control.c2d(control.ss(a, b, c, d), period, method="zoh")
    else:
        model["dt"] = dt
        sysd = control.ss(a, b, c, d, dt)
    u = inputs(seed, b.shape[1])
    x, y = response(sysd, u, np.asarray(x0, dtype=float))
    resp = {
        "period": period,
        "input_delay": 0.0,
        "x0": list(map(float, x0)),
        "u": u.tolist(),
        "x": x.tolist(),
        "y": y.tolist(),
        "phi": rows(sysd.A),
        "gamma": rows(sysd.B),
    }
    if gains:
        resp["verdicts"] = gain_verdicts(np.asarray(sysd.A), np.asarray(sysd.B),
                                         np.asarray(c), np.asarray(d), period, seed)
    return name, model, resp


def case_tf(name, num, den, period, seed, delay_periods=0, gains=False):
    model = {"num": list(map(float, num)), "den": list(map(float, den))}
    g = control.c2d(control.tf(num, den), period, method="zoh")
    if delay_periods:
        g = g * control.tf([1.0], [1.0] + [0.0] * delay_periods, period)
    u = inputs(seed, 1)
    _, y = response(control.ss(g), u, 0.0)
    resp = {
        "period": period,
        "input_delay": delay_periods * period,
        "u": u.tolist(),
        "y": y.tolist(),
    }
    if gains:
        # On SciPy's realisation of the continuous transfer function (the states the gains
        # multiply), discretised by python-control.
        a, b, c, d = scipy.signal.tf2ss(num, den)
        sysd = control.c2d(control.ss(a, b, c, d), period, method="zoh")
        resp["verdicts"] = gain_verdicts(np.asarray(sysd.A), np.asarray(sysd.B),
                                         np.asarray(c), np.asarray(d), period, seed,
                                         delay=delay_periods)
    return name, model, resp


def cases():
    return [
        # Stable: a lightly damped mass-spring-damper from rest off its equilibrium.
        case_ss("stable_msd", [[0, 1], [-4, -0.8]], [[0], [1]], [[1, 0]], [[0]], 0.01,
                [0.1, 0.0], 1, gains=True),
        # Marginal: an undamped oscillator (poles +-3j).
        case_ss("marginal_oscillator", [[0, 1], [-9, 0]], [[0], [1]], [[1, 0]], [[0]], 0.02,
                [0.0, 0.0], 2),
        # Unstable under feedback at high gain: 1/(s+1)^3 (unity feedback, K > 8).
        case_tf("third_order_lag", [1.0], [1.0, 3.0, 3.0, 1.0], 0.05, 3, gains=True),
        # Non-minimum phase: a right-half-plane zero, and a direct feedthrough.
        case_tf("nonminimum_phase", [-1.0, 2.0], [1.0, 3.0, 2.0], 0.01, 4),
        case_tf("biproper_lead", [2.0, 1.0], [1.0, 5.0], 0.01, 5, gains=True),
        # A delay of 3 periods on a first-order lag.
        case_tf("delayed_lag", [1.0], [0.5, 1.0], 0.02, 6, delay_periods=3, gains=True),
        # MIMO, with a direct feedthrough.
        case_ss("mimo_feedthrough",
                [[-1, 0.5, 0], [0, -2, 1], [0.3, 0, -0.5]],
                [[1, 0], [0, 1], [0.5, 0.5]],
                [[1, 0, 0], [0, 1, 1]],
                [[0.1, 0], [0, -0.2]], 0.01, [0.2, -0.1, 0.0], 7),
        # Discrete and open-loop unstable, given at the control period.
        case_ss("discrete_unstable", [[1.02, 0.1], [0, 0.95]], [[0], [0.1]], [[1, 0]], [[0]],
                0.01, [0.05, 0.0], 8, gains=True, dt=0.01),
    ]


def close(a, b, tol=1e-12):
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(close(a[k], b[k], tol) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(close(x, y, tol) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, (int, float)):
        return abs(a - b) <= tol * max(1.0, abs(a))
    return a == b


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true",
                    help="compare a fresh generation with the files instead of writing them")
    args = ap.parse_args()
    os.makedirs(OUT, exist_ok=True)
    bad = 0
    for name, model, resp in cases():
        for suffix, doc in (("model", model), ("response", resp)):
            path = os.path.join(OUT, f"{name}.{suffix}.json")
            if args.check:
                with open(path) as f:
                    if not close(doc, json.load(f)):
                        print(f"differs: {path}")
                        bad += 1
            else:
                with open(path, "w") as f:
                    json.dump(doc, f, indent=1)
                    f.write("\n")
    print(f"python-control {control.__version__}, numpy {np.__version__}, "
          f"scipy {scipy.__version__}: {len(cases())} systems "
          + ("checked" if args.check else f"written to {os.path.normpath(OUT)}"))
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()

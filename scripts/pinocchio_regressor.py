#!/usr/bin/env python3
"""Reference values from Pinocchio for evoloop's regressor test (tests/dynamics.rs).

For each robot file and a few seeded states, Pinocchio's computeJointTorqueRegressor, rnea,
crba (the joint-space inertia, made symmetric) and aba at the torque tau / 2 + 1 (so the forward
dynamics is not just the inverse of the case's own rnea); written to
tests/data/pinocchio_regressor.json. Needs the `pin` package (pip install pin).

    python3 scripts/pinocchio_regressor.py
"""

import json
import os

import numpy as np
import pinocchio as pin

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROBOTS = [
    "tests/robots/ur5_style.urdf",
    "tests/robots/panda_style.urdf",
    "config/robots/arm3.urdf",
    "config/robots/arm7.urdf",
    # `evoloop robot generate` arms (tests/robot_generate.rs checks the files are its output).
    "tests/robots/gen3_s11.urdf",
    "tests/robots/gen6_s12.urdf",
    "tests/robots/gen7_s13.urdf",
]


def main():
    rng = np.random.default_rng(7)
    out = {"pinocchio": pin.__version__, "cases": []}
    for rel in ROBOTS:
        model = pin.buildModelFromUrdf(os.path.join(ROOT, rel))
        data = model.createData()
        for _ in range(3):
            q = rng.uniform(-2, 2, model.nq)
            v = rng.uniform(-2, 2, model.nv)
            a = rng.uniform(-5, 5, model.nv)
            y = pin.computeJointTorqueRegressor(model, data, q, v, a)
            tau = pin.rnea(model, data, q, v, a)
            m = pin.crba(model, data, q)
            m = np.triu(m) + np.triu(m, 1).T
            tau_fd = np.asarray(tau) / 2 + 1
            qdd_aba = pin.aba(model, data, q, v, tau_fd)
            out["cases"].append(
                {
                    "robot": rel,
                    "joints": [model.names[i] for i in range(1, model.njoints)],
                    "q": q.tolist(),
                    "qd": v.tolist(),
                    "qdd": a.tolist(),
                    "Y": np.asarray(y).tolist(),
                    "tau": np.asarray(tau).tolist(),
                    "M": np.asarray(m).tolist(),
                    "tau_fd": tau_fd.tolist(),
                    "qdd_aba": np.asarray(qdd_aba).tolist(),
                }
            )
    path = os.path.join(ROOT, "tests/data/pinocchio_regressor.json")
    with open(path, "w") as f:
        json.dump(out, f, indent=1)
    print(f"wrote {path} (Pinocchio {pin.__version__}, {len(out['cases'])} cases)")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Two independent simulators of the same arm, given the same torques: replays a lockstep run of
evoloop's own arm plant (its run.csv: the torques u* the controller sent, the joint angles q* and
rates qd* the plant had) in MuJoCo (config/plants/mujoco_arm.py's model of the robot's URDF, RK4
at the same step) and prints how far apart the joint angles are, as JSON.

    python3 scripts/mujoco_crosscheck.py --run runs/arm3_ct --urdf config/robots/arm3.urdf \\
        --step 0.0005 [--seconds 5] [--no-coulomb]

MuJoCo starts from the run's first sample at rest and holds each torque for a period, as
evoloop's plant did (zero-order hold). `--no-coulomb` takes MuJoCo's dry friction (frictionloss)
out, for a run of a robot file without Coulomb friction: evoloop smooths Coulomb friction by
tanh(qd / 0.01 rad/s), MuJoCo enforces it as a constraint, and near zero speed the two differ."""
import argparse
import json
import os
import re
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "config", "plants"))
sys.path.insert(0, os.path.join(HERE, "..", "python"))

import mujoco  # noqa: E402
import mujoco_arm  # noqa: E402
from evoloop_plant import read_run  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", required=True, help="a lockstep run directory of evoloop's arm plant")
    ap.add_argument("--urdf", required=True)
    ap.add_argument("--step", type=float, default=0.0005, help="RK4 step, s (the run's plant.step)")
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--no-coulomb", action="store_true")
    a = ap.parse_args()
    run = read_run(a.run)
    n = len([c for c in run if re.fullmatch(r"u\d+", c)])
    t = run["t"]
    period = t[1] - t[0]
    samples = min(len(t), int(round(a.seconds / period)) + 1)
    u = np.stack([run[f"u{j}"] for j in range(n)], axis=1)
    q = np.stack([run[f"q{j}"] for j in range(n)], axis=1)
    m = mujoco_arm.load(a.urdf, a.step, coulomb=not a.no_coulomb)
    arm = mujoco_arm.MujocoArm(m, q[0])
    arm.reset()
    worst, worst_at = 0.0, 0.0
    errors = []
    for k in range(samples - 1):
        got = arm.step(u[k], period)
        e = float(np.max(np.abs(got - q[k + 1])))
        errors.append(e)
        if e > worst:
            worst, worst_at = e, t[k + 1]
    print(json.dumps({
        "mujoco": mujoco.__version__,
        "samples": samples,
        "seconds": float(t[samples - 1]),
        "step": a.step,
        "coulomb": not a.no_coulomb,
        "max_abs_q_error_rad": worst,
        "at_s": float(worst_at),
        # The difference at these instants (s), where the run reaches them.
        "at": {str(s): errors[int(round(s / period)) - 1]
               for s in (0.001, 0.01, 0.1, 1.0, 2.0, 5.0) if round(s / period) - 1 < len(errors)},
        "rms_q_error_rad": float(np.sqrt(np.mean(np.square(errors)))),
    }))


if __name__ == "__main__":
    main()

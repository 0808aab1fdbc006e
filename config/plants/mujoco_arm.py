#!/usr/bin/env python3
"""An arm simulated by MuJoCo as evoloop's plant (`plant.kind = "external"`): MuJoCo loads the
robot's URDF (masses, inertias, joint limits, effort limits, `<dynamics damping friction>` as
joint damping and frictionloss) and integrates it with its RK4 at `--step`; the process plays the
plant contract through the evoloop_plant package. Torques are clipped to the URDF's effort
limits, as evoloop's own arm plant clips them.

  mujoco_arm.py ROBOT.urdf --q0 Q1 Q2 ... [--step 0.0005] [--noise STD] [--wall Y] [--no-truth]

`--noise STD` adds Gaussian noise to the measured angles (seeded by EVOLOOP_SEED, so lockstep
reruns are identical). `--no-truth` sends NaN in every truth field, as a real arm has no
truth to send: the controller then runs on the encoders alone. `--wall X` adds what evoloop's rigid-body plant cannot simulate: a ball
of 4 cm radius at the URDF's last frame (the tool flange) and a stiff wall, the plane y = Y in the
world, that the ball touches (MuJoCo's default soft contact: the ball sinks a few mm into it).
Needs `pip install mujoco` and the evoloop_plant package (`pip install ./python`; run from the
repository, it is found there without installing)."""
import argparse
import os
import sys

try:
    import evoloop_plant
except ImportError:  # a checkout: the package beside config/
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
    import evoloop_plant

import mujoco
import numpy as np


def load(urdf, step, wall=None, coulomb=True):
    """The MuJoCo model of `urdf` with RK4 at `step`; with `wall`, a ball on the last frame and a
    wall at y = wall."""
    spec = mujoco.MjSpec.from_file(os.path.abspath(urdf))
    if wall is not None:
        last = spec.bodies[-1]
        last.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.04, 0, 0], contype=1,
                      conaffinity=1, mass=0.0)
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[2.0, 0.01, 2.0],
                                pos=[0, wall + 0.01, 0], contype=1, conaffinity=1)
    m = spec.compile()
    m.opt.timestep = step
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    if not coulomb:
        m.dof_frictionloss[:] = 0.0
    return m


class MujocoArm(evoloop_plant.Plant):
    def __init__(self, model, q0, noise=0.0, seed=1, truth=True):
        self.m, self.d = model, mujoco.MjData(model)
        self.truth = truth
        self.q0 = np.asarray(q0, dtype=float)
        self.step_size = model.opt.timestep
        hinge_or_slide = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        if model.njnt != model.nq or any(int(t) not in hinge_or_slide for t in model.jnt_type):
            raise SystemExit("mujoco_arm.py: only arms of hinge and slide joints (one value each)")
        # URDF effort limits; a joint without one (continuous, or no effort) is not clipped.
        self.limit = np.where(model.jnt_actfrclimited, model.jnt_actfrcrange[:, 1], np.inf)
        self.noise, self.rng = noise, np.random.default_rng(seed)

    def measured(self):
        """The joint angles as the encoders read them."""
        q = self.d.qpos.copy()
        return q + self.rng.normal(0.0, self.noise, q.shape) if self.noise > 0 else q

    def reset(self):
        mujoco.mj_resetData(self.m, self.d)
        self.d.qpos[:] = self.q0
        mujoco.mj_forward(self.m, self.d)
        return self.measured()

    def step(self, u, dt):
        self.d.qfrc_applied[:] = np.clip(np.asarray(u, dtype=float), -self.limit, self.limit)
        n = max(1, int(np.ceil(dt / self.step_size - 1e-9)))
        self.m.opt.timestep = dt / n
        for _ in range(n):
            mujoco.mj_step(self.m, self.d)
        self.m.opt.timestep = self.step_size
        return self.measured()

    def state(self):
        return np.concatenate([self.d.qpos, self.d.qvel])

    def joints(self, y):
        return self.d.qpos.copy(), self.d.qvel.copy()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("urdf")
    ap.add_argument("--q0", type=float, nargs="+", required=True, help="initial joint angles, rad")
    ap.add_argument("--step", type=float, default=0.0005, help="MuJoCo's RK4 step, s")
    ap.add_argument("--noise", type=float, default=0.0, help="encoder noise, rad (std)")
    ap.add_argument("--wall", type=float, help="a wall at y = WALL m that the tool's ball touches")
    ap.add_argument("--no-truth", action="store_true",
                    help="send NaN in every truth field (x_true, q_true, qd_true)")
    a = ap.parse_args()
    seed = int(os.environ.get("EVOLOOP_SEED", "1"))
    evoloop_plant.run(MujocoArm(load(a.urdf, a.step, a.wall), a.q0, a.noise, seed, not a.no_truth))


if __name__ == "__main__":
    main()

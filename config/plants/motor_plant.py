#!/usr/bin/env python3
"""The DC motor of config/lti_motor.toml written as a plant of the user's own, in Python:
theta/V = K / (s (tau s + 1)), K = 2 rad/(V s), tau = 50 ms, a +-12 V amplifier. RK4 at a tenth
of the step it is asked for. config/external_motor.toml starts it (`plant.kind = "external"`);
tests/python_plant.rs checks its run against the built-in lti plant's.

`--load-at T` couples a load at T s that triples the inertia (tau 50 ms -> 150 ms, K unchanged):
config/external_motor_indirect.toml tunes the PID through it with the general indirect scheme.

Needs the evoloop_plant package (`pip install ./python`); run from the repository, it is found
there without installing."""
import os
import sys

try:
    import evoloop_plant
except ImportError:  # a checkout: the package beside config/
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
    import evoloop_plant

import numpy as np

K, TAU, LIMIT = 2.0, 0.05, 12.0


class Motor(evoloop_plant.Plant):
    def __init__(self, load_at=None):
        self.load_at = load_at

    def reset(self):
        self.x = np.zeros(2)  # [theta, omega], sent as x_true
        self.t = 0.0
        return [self.x[0]]

    def state(self):
        return self.x

    def joints(self, y):
        return [self.x[0]], [self.x[1]]

    def step(self, u, dt):
        v = min(max(u[0], -LIMIT), LIMIT)
        # The load acts from the period that starts at load_at (to rounding of the time sum).
        loaded = self.load_at is not None and self.t + 1e-9 >= self.load_at
        tau = 3 * TAU if loaded else TAU
        self.t += dt
        f = lambda x: np.array([x[1], (K * v - x[1]) / tau])
        h = dt / 10
        for _ in range(10):
            k1 = f(self.x)
            k2 = f(self.x + h / 2 * k1)
            k3 = f(self.x + h / 2 * k2)
            k4 = f(self.x + h * k3)
            self.x = self.x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return [self.x[0]]


if __name__ == "__main__":
    load_at = None
    if "--load-at" in sys.argv:
        load_at = float(sys.argv[sys.argv.index("--load-at") + 1])
    evoloop_plant.run(Motor(load_at))

#!/usr/bin/env python3
"""The DC motor of config/linear/lti_motor.toml written as a plant of the user's own, in Python:
theta/V = K / (s (tau s + 1)), K = 2 rad/(V s), tau = 50 ms, a +-12 V amplifier. RK4 at a tenth
of the step it is asked for. config/external/external_motor.toml starts it (`plant.kind = "external"`);
tests/python_plant.rs checks its run against the built-in lti plant's.

`--load-at T` couples a load at T s that triples the inertia (tau 50 ms -> 150 ms, K unchanged):
config/external/external_motor_indirect.toml tunes the PID through it with the general indirect scheme.

Needs the evoloop_plant package (`pip install ./python`); run from the repository, it is found
there without installing."""
import os
import sys

try:
    import evoloop_plant
except ImportError:  # a checkout: the package beside config/
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
    import evoloop_plant

K, TAU, LIMIT = 2.0, 0.05, 12.0


class Motor(evoloop_plant.Plant):
    def __init__(self, load_at=None):
        self.load_at = load_at

    # A 2-state model on Python floats: NumPy's per-call overhead on 2-element arrays cost
    # about 15 times the arithmetic (338 us against 22 us a sample), with the same results bit
    # for bit (the same operations in the same order, in IEEE double).
    def reset(self):
        self.x = [0.0, 0.0]  # [theta, omega], sent as x_true
        self.t = 0.0
        return [0.0]

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
        kv = K * v
        h = dt / 10
        h2, h6 = h / 2, h / 6
        th, w = self.x
        for _ in range(10):
            # k_i = f(x) = (omega, (K v - omega) / tau), as in the NumPy original.
            a1, b1 = w, (kv - w) / tau
            a2, b2 = w + h2 * b1, (kv - (w + h2 * b1)) / tau
            a3, b3 = w + h2 * b2, (kv - (w + h2 * b2)) / tau
            a4, b4 = w + h * b3, (kv - (w + h * b3)) / tau
            th = th + h6 * (a1 + 2 * a2 + 2 * a3 + a4)
            w = w + h6 * (b1 + 2 * b2 + 2 * b3 + b4)
        self.x = [th, w]
        return [th]


if __name__ == "__main__":
    load_at = None
    if "--load-at" in sys.argv:
        load_at = float(sys.argv[sys.argv.index("--load-at") + 1])
    evoloop_plant.run(Motor(load_at))

#!/usr/bin/env python3
"""The Python binding's floor: a plant that computes nothing. It plays the plant contract through
the evoloop_plant package exactly as config/plants/motor_plant.py does (two states, one output,
one input) but its step returns at once, so a lockstep run of it costs what the package and
evoloop's processes cost per sample and nothing else. scripts/python_floor.sh runs it beside the
motor plant to show what a plant's own arithmetic adds to that floor.

Needs the evoloop_plant package (`pip install ./python`; run from the repository, it is found
there without installing)."""
import os
import sys

try:
    import evoloop_plant
except ImportError:  # a checkout: the package beside config/
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "python"))
    import evoloop_plant


class Nothing(evoloop_plant.Plant):
    def reset(self):
        self.x = [0.0, 0.0]
        self.y = [0.0]
        return self.y

    def state(self):
        return self.x

    def joints(self, y):
        return self.y, [0.0]

    def step(self, u, dt):
        return self.y


if __name__ == "__main__":
    evoloop_plant.run(Nothing())

"""Shared test helpers."""

import numpy as np


def random_state(robot, rng, scale=1.0):
    """A random configuration near the reference pose of ``robot`` and a random velocity of size ``scale``."""
    q = 0.3 * rng.normal(size=robot.nq)
    if robot.name == "fpr":
        q[robot.index["phi"]] += 5 * np.pi / 4
        q[robot.index["q21"]] += np.pi / 2
    else:
        q[robot.index["q1"]] += 0.3
        q[robot.index["q2"]] += 1.2
    return q, scale * rng.normal(size=robot.nq)
